// The material and emitter tables (bind group 1, bindings 1 and 2) as storage buffers: any size. The
// portable choice; wgpu_rt/trace/trace_pass.py swaps in trace/shading_tables_uniform.wgsl when the tables
// fit its capacities.

// #import trace/shading_records.wgsl

@group(1) @binding(1) var<storage, read> materials: array<Material>;
@group(1) @binding(2) var<storage, read> emitters: array<Emitter>;
