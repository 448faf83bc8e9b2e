// The shading tables' record types (materials and emitters), as packed by wgpu_rt/trace/scene_data.py.
// Where the tables live is up to trace/shading_tables_storage.wgsl or trace/shading_tables_uniform.wgsl.

// #import trace/material.wgsl

const EMITTER_TRIANGLE: u32 = 0u;
const EMITTER_POINT: u32 = 1u;
const EMITTER_DIRECTIONAL: u32 = 2u;
const EMITTER_BACKGROUND: u32 = 3u;

// One entry of the emitter table. Sampling picks an entry through its alias-table fields in O(1):
// take i = floor(u·N); keep i if frac(u·N) < alias_threshold, else use alias_index.
struct Emitter {
    position: vec3f,      // triangle: vertex 0; point light: position
    kind: u32,
    edge1: vec3f,         // triangle: v1 - v0; directional light: direction of travel
    pmf: f32,             // probability that sampling picks this entry
    edge2: vec3f,         // triangle: v2 - v0
    area: f32,
    radiance: vec3f,      // radiance, intensity or irradiance by kind
    alias_threshold: f32,
    alias_index: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

