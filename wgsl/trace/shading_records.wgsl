// The shading tables' record types (materials and emitters), as packed by wgpu_rt/trace/scene_data.py.
// Where the tables live is up to trace/shading_tables_storage.wgsl or trace/shading_tables_uniform.wgsl.

// #import trace/material.wgsl

const EMITTER_TRIANGLE: u32 = 0u;
const EMITTER_POINT: u32 = 1u;
const EMITTER_DIRECTIONAL: u32 = 2u;
const EMITTER_BACKGROUND: u32 = 3u;

// One entry of the emitter table. Within its group (first, count) an entry is picked through its
// alias-table fields in O(1): take i = floor(u·count); keep first + i if frac(u·count) < alias_threshold,
// else use alias_index.
struct Emitter {
    position: vec3f,      // triangle: vertex 0; point light: position
    kind: u32,
    edge1: vec3f,         // triangle: v1 - v0; directional light: direction of travel; spot light: its axis
    share: f32,           // probability that a pick within its group takes this entry
    edge2: vec3f,         // triangle: v2 - v0; spot light: cutoff angle, beam width (radians)
    area: f32,
    radiance: vec3f,      // radiance, intensity or irradiance by kind
    alias_threshold: f32,
    alias_index: u32,
    group: u32,           // the emitter group it belongs to
    triangle: u32,        // triangle: the placed triangle it is
    emission_image: u32,  // triangle: its mesh's emission texture (trace/surface_textures.wgsl), or NO_TEXTURE
}

const GROUP_CONSTANT: u32 = 0u;   // a sun, a sky, or the one group of everything
const GROUP_POINT: u32 = 1u;
const GROUP_SOLID: u32 = 2u;      // emissive triangles of one mesh not all in one plane, or a cluster
const GROUP_FLAT: u32 = 3u;       // emissive triangles of one mesh in one plane, facing `normal`

// A group of the emitter table's entries, [first, first + count): next-event estimation picks a group by
// an estimate of the irradiance it gives at the shading point (emitters.wgsl's group_importance), then
// an entry within it. Packed by wgpu_rt/trace/scene_data.py (EMITTER_GROUP_DTYPE).
struct EmitterGroup {
    center: vec3f,        // point light: its position; area light: its area-weighted centroid
    kind: u32,
    normal: vec3f,        // GROUP_FLAT: the side its triangles emit to
    radius: f32,          // of the bounding sphere about `center`
    power: f32,           // the importance's scale: see group_importance
    pmf: f32,             // probability that a pick by power alone takes this group
    first: u32,
    count: u32,
}
