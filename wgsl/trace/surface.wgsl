// Where a path meets a surface: the shading normal the BSDFs are evaluated about (the interpolated
// vertex normal where the mesh has them; two-sided diffuse and metal surfaces face it toward the
// incoming ray, glass keeps its outward normal to tell inside from out), and the ray that leaves the
// surface along a sampled direction. Shared by the path tracer and the auxiliary-feature pass.

// #import trace/features.wgsl
// #import accel/bvh.wgsl
// #import trace/material.wgsl
// #import trace/surface_textures.wgsl

// A hit's material (its triangle's) with the reflectance tinted by its mesh's vertex colours or texture
// there (each white where the mesh has none).
fn surface_colored(material: Material, hit: Hit) -> Material {
    var tinted = material;
    if HAS_SURFACE_COLORS {
        tinted.reflectance *= tri_color(hit.prim, hit.u, hit.v) * texture_color(hit.prim, hit.u, hit.v);
    }
    return tinted;
}

fn shading_normal_at(hit: Hit, geometric_normal: vec3f, material: Material, cos_front: f32) -> vec3f {
    var shading_normal = geometric_normal;
    if HAS_VERTEX_NORMALS {
        shading_normal = tri_shading_normal_or(hit.prim, hit.u, hit.v, geometric_normal);
    }
    let is_glass = HAS_DIELECTRIC && material.kind == MATERIAL_DIELECTRIC;
    if !is_glass && cos_front < 0.0 {
        shading_normal = -shading_normal;
    }
    return shading_normal;
}
