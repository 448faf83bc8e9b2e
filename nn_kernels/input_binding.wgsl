// A weighted layer's input: an NC4HW4 activation tensor (vec4 channel blocks of T).
@group(0) @binding(0) var<storage, read> src: array<vec4<T>>;
