// How the wide walk (accel/walk_wide.wgsl) fetches a node of layout "wide": 112 bytes of f32 boxes, through
// the traversal module (a packet's lanes fetch it together on CPU drivers). Geometry laid out "wide8"
// swaps in accel/wide_node_quantized.wgsl.

// #import accel/traversal_lanes.wgsl

fn fetch_wide(base: u32, index: u32) -> WideNode {
    return wide_node(base, index);
}
