// Shadow rays through thin panes: a thin_dielectric lets light through without bending it, so the shadow ray of a
// light sample may cross it and carry what the pane transmits, (1 − 2R / (1 + R)) times its tint, R the Fresnel
// reflectance at the crossing's angle (trace/bsdf_dielectric.wgsl); any other surface stops it. Without this a sun
// or a point light behind a window lights nothing through it (paths cannot meet a delta light by chance). A path
// that crosses a pane by its transmission lobe goes on as if the pane were not there for multiple importance
// sampling (trace/trace.wgsl), so the light it meets is weighed against the sample that reached it through the
// pane. The cosine is taken in the triangle's own space (exact but for instances scaled unevenly). Swapped in for
// accel/panes_none.wgsl by wgpu_rt/trace/trace_pass.py where a scene has a thin pane.

// #import accel/geometry_bindings.wgsl
// #import accel/instances_none.wgsl
// #import trace/trace_bindings.wgsl
// #import trace/bsdf_dielectric.wgsl

const SHADOWS_CROSS_PANES: bool = true;

fn pane_transmittance(stored: u32, instance: u32, p: TrianglePositions, dir: vec3f) -> vec3f {
    var id = tri_attributes[stored].material;
    if HAS_INSTANCES && instance != NO_INSTANCE {
        let own = instance_record(instance).material;
        id = select(id, own, own != FROM_TRIANGLE);
    }
    let m = materials[id];
    if m.kind != MATERIAL_THIN_DIELECTRIC {
        return vec3f(0.0);
    }
    let normal = cross(p.b - p.a, p.c - p.a);
    let cos_i = dot(normal, dir) * inverseSqrt(dot(normal, normal) * dot(dir, dir));
    return (1.0 - thin_dielectric_reflectance(cos_i, m.ior)) * dielectric_transmittance(m);
}
