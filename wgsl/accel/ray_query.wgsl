// Batch ray queries for tests and benchmarks: one invocation per ray runs scene_intersect (entry
// `intersect`, which also reports the surface attributes at the hit through the accel/bvh.wgsl helpers) or
// scene_occluded (entry `occluded`). A ray with `offset` set starts at offset_ray_origin(origin,
// normal, dir), as a path tracer spawns rays from a surface. Invocations past the last ray trace the
// last ray again without writing it: a subgroup traverses together (accel/traversal_subgroup.wgsl).
// #import accel/bvh.wgsl

struct QueryRay { origin: vec3f, t_max: f32, dir: vec3f, offset: u32, normal: vec3f, _pad: u32 }
struct HitSurface {
    shading_normal: vec3f, material: u32,
    geometric_normal: vec3f, object: u32,
    previous_position: vec3f, _pad: u32,   // where the hit point was at the frame before (previous_position)
}

@group(1) @binding(0) var<storage, read> rays: array<QueryRay>;
@group(1) @binding(1) var<storage, read_write> hits: array<Hit>;
@group(1) @binding(2) var<storage, read_write> surfaces: array<HitSurface>;
@group(1) @binding(3) var<storage, read_write> occlusion: array<u32>;

fn query_origin(ray: QueryRay) -> vec3f {
    return select(ray.origin, offset_ray_origin(ray.origin, ray.normal, ray.dir), ray.offset != 0u);
}

@compute @workgroup_size(64)
fn intersect(@builtin(global_invocation_id) id: vec3u, @builtin(local_invocation_index) local_index: u32) {
    begin_traversal(local_index);
    let ray = rays[min(id.x, arrayLength(&rays) - 1u)];
    let origin = query_origin(ray);
    let hit = scene_intersect(origin, ray.dir, ray.t_max);
    if (id.x >= arrayLength(&rays)) { return; }
    hits[id.x] = hit;
    var surface = HitSurface(vec3f(0.0), NO_HIT, vec3f(0.0), NO_HIT, vec3f(0.0), 0u);
    if (hit.prim != NO_HIT) {
        let object = tri_object(hit.prim);
        let p = tri_vertices(hit.prim);
        let position = (1.0 - hit.u - hit.v) * p[0] + hit.u * p[1] + hit.v * p[2];
        surface = HitSurface(tri_shading_normal(hit.prim, hit.u, hit.v), tri_material(hit.prim),
                             tri_geometric_normal(hit.prim), object,
                             previous_position(hit.prim, hit.u, hit.v, position), 0u);
    }
    surfaces[id.x] = surface;
}

@compute @workgroup_size(64)
fn occluded(@builtin(global_invocation_id) id: vec3u, @builtin(local_invocation_index) local_index: u32) {
    begin_traversal(local_index);
    let ray = rays[min(id.x, arrayLength(&rays) - 1u)];
    let occluded = scene_occluded(query_origin(ray), ray.dir, ray.t_max);
    if (id.x < arrayLength(&rays)) { occlusion[id.x] = u32(occluded); }
}
