// How the wide walk (accel/walk_wide.wgsl) fetches a node of layout "wide8" (wgpu_rt.accel.bvh.
// quantized_wide_nodes): 64 bytes, four rows. Row 0: the origin and the three axes' biased exponents of
// the grid step; rows 1 and 2: each coordinate of the four children's boxes as four bytes (child k in
// byte k), then the four references. A coordinate decodes as origin + q · 2^e (one rounding: q · 2^e is
// exact), which contains the child's box by construction. Each invocation fetches its own rows.

// #import accel/geometry_bindings.wgsl

fn wide_bytes(word: u32) -> vec4f {
    return vec4f((vec4u(word) >> vec4u(0u, 8u, 16u, 24u)) & vec4u(255u));
}

fn fetch_wide(base: u32, index: u32) -> WideNode {
    let at = (NODE_WORDS / 4u) * base + 4u * index;   // QUANTIZED_WIDE_NODE_WORDS / 4 rows a node
    let head = bvh_row(at);
    let low = bvh_row(at + 1u);    // lo x, lo y, lo z, hi x
    let high = bvh_row(at + 2u);   // hi y, hi z, references 0 and 1
    let tail = bvh_row(at + 3u);   // references 2 and 3
    let origin = bitcast<vec3f>(head.xyz);
    let step = bitcast<vec3f>(((vec3u(head.w) >> vec3u(0u, 8u, 16u)) & vec3u(255u)) << vec3u(23u));
    return WideNode(origin.x + wide_bytes(low.x) * step.x, origin.y + wide_bytes(low.y) * step.y,
                    origin.z + wide_bytes(low.z) * step.z, origin.x + wide_bytes(low.w) * step.x,
                    origin.y + wide_bytes(high.x) * step.y, origin.z + wide_bytes(high.y) * step.z,
                    vec4u(high.z, high.w, tail.x, tail.y));
}
