// The material and emitter tables (bind group 1, bindings 1 and 2) as uniform buffers of fixed
// capacity (wgpu_rt.trace.trace_pass.UNIFORM_TABLE_CAPACITY; each within the 64 KiB uniform binding
// limit), zero-padded past the scene's records. Why: on lavapipe a read at a per-invocation index
// costs a scalar loop over the SIMD lanes for every 32-bit word, about half as long from a uniform
// buffer as from a storage buffer, and shading reads ~25 such words per path vertex (the material,
// the picked emitter and its alias entry). Scenes with larger tables keep trace/shading_tables_storage.wgsl.

// #import trace/shading_records.wgsl

@group(1) @binding(1) var<uniform> materials: array<Material, 256>;
@group(1) @binding(2) var<uniform> emitters: array<Emitter, 512>;
