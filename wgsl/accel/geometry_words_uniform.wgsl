// The BVH nodes and triangle positions of bind group 0 (wgsl/accel/geometry_bindings.wgsl) as uniform
// buffers of 64 KiB each (2048 nodes, 1365 triangles; wgpu_rt.scene.geometry.UNIFORM_GEOMETRY_BYTES),
// zero-padded. Uniform arrays need 16-byte elements, so a word is a component of a vec4.
// Why: on lavapipe a read at a per-invocation address costs a scalar loop over the SIMD lanes for
// every 32-bit word, about half as long from a uniform buffer as from a storage buffer, and the
// walk's node and triangle fetches are such reads (one lane per word, then broadcast).

@group(0) @binding(0) var<uniform> bvh_nodes: array<vec4u, 4096>;
@group(0) @binding(1) var<uniform> tri_positions: array<vec4f, 4096>;

fn bvh_word(i: u32) -> u32 {
    return bvh_nodes[i >> 2u][i & 3u];
}

fn position_word(i: u32) -> f32 {
    return tri_positions[i >> 2u][i & 3u];
}

fn bvh_row(r: u32) -> vec4u {
    return bvh_nodes[r];
}

fn position_row(r: u32) -> vec4f {
    return tri_positions[r];
}

// The root's skip: the index past the whole tree.
fn bvh_node_count() -> u32 {
    return bvh_word(3u);
}

// Geometry small enough for uniform buffers always has every direction-ordered copy.
fn bvh_orderings() -> u32 {
    return 8u;
}
