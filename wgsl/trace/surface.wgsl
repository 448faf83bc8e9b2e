// Where a path meets a surface: the shading normal the BSDFs are evaluated about (the interpolated
// vertex normal where the mesh has them, tilted by its normal map where it has one; two-sided diffuse and
// metal surfaces face it toward the incoming ray, glass keeps its outward normal to tell inside from out),
// and the ray that leaves the surface along a sampled direction. Shared by the path tracer and the
// auxiliary-feature pass.

// #import trace/features.wgsl
// #import accel/bvh.wgsl
// #import trace/material.wgsl
// #import trace/surface_textures.wgsl
// #import trace/metal_rough_none.wgsl

// A hit's material (its triangle's) as its point has it: the reflectance tinted by its mesh's vertex colours or
// texture there (each white where the mesh has none), the kind and roughness its metal-rough map gives it there.
fn surface_material(material: Material, hit: Hit) -> Material {
    var tinted = metal_rough_mapped(material, hit);
    if HAS_SURFACE_COLORS {
        tinted.reflectance *= tri_color(hit.prim, hit.u, hit.v) * texture_color(hit.prim, hit.u, hit.v);
    }
    return tinted;
}

// The normal the BSDF is evaluated about (`mapped`) and the interpolated one it was tilted from, both
// facing as the BSDF needs, for a ray along `dir`. As Mitsuba's normalmap does, a tilt that puts the ray's
// origin on the other side of the tilted normal than of the interpolated one is mirrored about the latter.
struct ShadingNormals { mapped: vec3f, interpolated: vec3f }

fn shading_normals_at(hit: Hit, geometric_normal: vec3f, material: Material, dir: vec3f) -> ShadingNormals {
    var interpolated = geometric_normal;
    if HAS_VERTEX_NORMALS {
        interpolated = tri_shading_normal_or(hit.prim, hit.u, hit.v, geometric_normal);
    }
    var mapped = interpolated;
    if HAS_NORMAL_MAPS {
        mapped = normal_mapped(hit.prim, hit.u, hit.v, interpolated);
        if dot(dir, mapped) * dot(dir, interpolated) < 0.0 {
            mapped = 2.0 * dot(mapped, interpolated) * interpolated - mapped;
        }
    }
    let is_glass = HAS_DIELECTRIC && material.kind == MATERIAL_DIELECTRIC;
    let side = select(1.0, -1.0, !is_glass && dot(geometric_normal, dir) > 0.0);
    return ShadingNormals(side * mapped, side * interpolated);
}

fn shading_normal_at(hit: Hit, geometric_normal: vec3f, material: Material, dir: vec3f) -> vec3f {
    return shading_normals_at(hit, geometric_normal, material, dir).mapped;
}

// What a normal map lets through of light leaving along `direction`, as Mitsuba's normalmap: nothing where it
// leaves on different sides of the tilted and the interpolated normal, else the shadowing of a microfacet
// surface whose roughness follows the tilt (Conty Estevez et al. 2019, for the shadow terminator):
// G1 = 2 / (1 + sqrt(1 + a² tan²θ)), a² = tan²(tilt) / 8, θ from the interpolated normal; 1 without a tilt.
fn normal_map_weight(normals: ShadingNormals, direction: vec3f) -> f32 {
    if !HAS_NORMAL_MAPS {
        return 1.0;
    }
    let cos_out = dot(direction, normals.interpolated);
    if dot(direction, normals.mapped) * cos_out <= 0.0 {
        return 0.0;
    }
    let cos_tilt = dot(normals.mapped, normals.interpolated);
    let cos_tilt2 = max(cos_tilt * cos_tilt, 1e-12);
    let a2 = (1.0 - cos_tilt2) / (8.0 * cos_tilt2);
    let cos_out2 = max(cos_out * cos_out, 1e-12);
    return 2.0 / (1.0 + sqrt(1.0 + a2 * (1.0 - cos_out2) / cos_out2));
}
