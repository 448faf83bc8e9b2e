// A hit's material as its metal-rough map makes it, for kernels of scenes without one: as it is, so that the map's
// lookup folds away. A scene with a metal-rough map swaps in trace/metal_rough_maps.wgsl
// (wgpu_rt/trace/trace_pass.py).

// #import trace/material.wgsl
// #import accel/bvh.wgsl

fn metal_rough_mapped(material: Material, hit: Hit) -> Material {
    return material;
}
