// Scene geometry (bind group 0) and ray queries against it.
//
// Traversal: a binary BVH (wgpu_rt/bvh.py: 32-byte nodes, children adjacent, leaves own a contiguous
// range of triangles in BVH order) walked with a short private stack. At an interior node both
// children's boxes are slab-tested (with precomputed 1/dir and origin/dir, and a far-plane slack that
// keeps grazing hits conservative); the nearer child is visited next and the farther one pushed, and a
// child whose box starts beyond the closest hit so far is skipped. scene_occluded stops at the first
// hit. Triangles use the watertight test of Woop, Benthin and Wald (JCGT 2013): the ray is sheared to
// run along +z, so whether it passes a shared edge depends only on that edge's two vertices and no ray
// slips between neighbouring triangles; zero-area triangles have a zero determinant and never hit.
// The shear is applied as three rows (dot products with one-hot and shear vectors) rather than by
// permuting vector components, which keeps the per-triangle code free of dynamic indexing.

const NO_HIT: u32 = 0xffffffffu;
const BVH_STACK_SIZE: u32 = 32u;     // == wgpu_rt.bvh.MAX_DEPTH, so the stack cannot overflow
const BVH_TINY_DIR: f32 = 1e-20;     // direction components below this are treated as this (no 1/0)
const BVH_BOX_SLACK: f32 = 1.0000004; // 1 + 2γ₃: a box's far plane is pushed out by rounding's worst case

struct Hit { t: f32, u: f32, v: f32, prim: u32 }   // u, v: barycentric weights of vertices 1 and 2

struct BvhNode { lo: vec3f, first: u32, hi: vec3f, count: u32 }
struct TriAttributes { n0: vec3f, material: u32, n1: vec3f, object: u32, n2: vec3f, _pad: u32 }

@group(0) @binding(0) var<storage, read> bvh_nodes: array<BvhNode>;
@group(0) @binding(1) var<storage, read> tri_positions: array<vec4f>;     // 3 per triangle, w unused
@group(0) @binding(2) var<storage, read> tri_attributes: array<TriAttributes>;
@group(0) @binding(3) var<storage, read> object_motion: array<mat4x4f>;   // world now → world previous frame

// Everything about one ray that every box and triangle test reuses.
struct TraversalRay {
    origin: vec3f,
    inv_dir: vec3f,
    origin_inv_dir: vec3f,   // origin * inv_dir, so a slab is one fma per axis
    shear_x: vec3f,          // rows of the Woop shear: (x, y, z) of (p - origin) in ray space
    shear_y: vec3f,
    shear_z: vec3f,
}

fn axis_vector(k: u32) -> vec3f {
    return vec3f(f32(k == 0u), f32(k == 1u), f32(k == 2u));
}

fn traversal_ray(origin: vec3f, dir: vec3f) -> TraversalRay {
    let safe_dir = select(dir, vec3f(BVH_TINY_DIR), abs(dir) < vec3f(BVH_TINY_DIR));
    let inv_dir = 1.0 / safe_dir;
    let a = abs(dir);
    let kz = select(select(2u, 1u, a.y >= a.z), 0u, a.x >= a.y && a.x >= a.z);
    var kx = (kz + 1u) % 3u;
    var ky = (kx + 1u) % 3u;
    let dz = dot(dir, axis_vector(kz));
    if (dz < 0.0) { let swap = kx; kx = ky; ky = swap; }   // keep the winding of the sheared triangle
    let ez = axis_vector(kz);
    let sx = dot(dir, axis_vector(kx)) / dz;
    let sy = dot(dir, axis_vector(ky)) / dz;
    return TraversalRay(origin, inv_dir, origin * inv_dir,
                        axis_vector(kx) - sx * ez, axis_vector(ky) - sy * ez, ez / dz);
}

// Entry distance of the ray into a node's box, or a value ≥ t_max when it misses within (0, t_max).
fn box_entry(node: BvhNode, ray: TraversalRay, t_max: f32) -> f32 {
    let t0 = node.lo * ray.inv_dir - ray.origin_inv_dir;
    let t1 = node.hi * ray.inv_dir - ray.origin_inv_dir;
    let near = min(t0, t1);
    let far = max(t0, t1);
    let t_near = max(max(near.x, near.y), max(near.z, 0.0));
    let t_far = min(min(far.x, far.y), min(far.z, t_max)) * BVH_BOX_SLACK;
    return select(t_max, t_near, t_near <= t_far);
}

// Watertight ray/triangle test: (t, u, v) of a hit with 0 < t < t_max, else t = t_max.
fn triangle_hit(ray: TraversalRay, prim: u32, t_max: f32) -> vec3f {
    let a = tri_positions[3u * prim] .xyz - ray.origin;
    let b = tri_positions[3u * prim + 1u].xyz - ray.origin;
    let c = tri_positions[3u * prim + 2u].xyz - ray.origin;
    let ax = dot(ray.shear_x, a);
    let ay = dot(ray.shear_y, a);
    let bx = dot(ray.shear_x, b);
    let by = dot(ray.shear_y, b);
    let cx = dot(ray.shear_x, c);
    let cy = dot(ray.shear_y, c);
    let w0 = cx * by - cy * bx;   // edge functions = unnormalised barycentrics of a, b, c
    let w1 = ax * cy - ay * cx;
    let w2 = bx * ay - by * ax;
    let miss_sign = (w0 < 0.0 || w1 < 0.0 || w2 < 0.0) && (w0 > 0.0 || w1 > 0.0 || w2 > 0.0);
    let det = w0 + w1 + w2;
    let t_scaled = w0 * dot(ray.shear_z, a) + w1 * dot(ray.shear_z, b) + w2 * dot(ray.shear_z, c);
    let flip = select(1.0, -1.0, det < 0.0);
    let in_range = t_scaled * flip > 0.0 && t_scaled * flip < t_max * det * flip;
    if (miss_sign || det == 0.0 || !in_range) {
        return vec3f(t_max, 0.0, 0.0);
    }
    let inv_det = 1.0 / det;
    return vec3f(t_scaled * inv_det, w1 * inv_det, w2 * inv_det);
}

// Closest hit in (0, t_max), or with any_hit the first one found (then only prim != NO_HIT matters).
fn bvh_traverse(origin: vec3f, dir: vec3f, t_max: f32, any_hit: bool) -> Hit {
    let ray = traversal_ray(origin, dir);
    var hit = Hit(t_max, 0.0, 0.0, NO_HIT);
    var stack: array<u32, BVH_STACK_SIZE>;
    var depth = 0u;
    var index = 0u;
    loop {
        let node = bvh_nodes[index];
        if (node.count == 0u) {
            let left = node.first;
            let t_left = box_entry(bvh_nodes[left], ray, hit.t);
            let t_right = box_entry(bvh_nodes[left + 1u], ray, hit.t);
            let hit_left = t_left < hit.t;
            let hit_right = t_right < hit.t;
            if (hit_left && hit_right) {
                let right_first = t_right < t_left;
                stack[depth] = select(left + 1u, left, right_first);
                depth += 1u;
                index = select(left, left + 1u, right_first);
                continue;
            }
            if (hit_left || hit_right) {
                index = select(left + 1u, left, hit_left);
                continue;
            }
        } else {
            for (var prim = node.first; prim < node.first + node.count; prim += 1u) {
                let h = triangle_hit(ray, prim, hit.t);
                if (h.x < hit.t) {
                    hit = Hit(h.x, h.y, h.z, prim);
                    if (any_hit) { return hit; }
                }
            }
        }
        if (depth == 0u) { break; }
        depth -= 1u;
        index = stack[depth];
    }
    return hit;
}

fn scene_intersect(origin: vec3f, dir: vec3f, tmax: f32) -> Hit {
    return bvh_traverse(origin, dir, tmax, false);
}

fn scene_occluded(origin: vec3f, dir: vec3f, tmax: f32) -> bool {
    return bvh_traverse(origin, dir, tmax, true).prim != NO_HIT;
}

fn tri_vertices(prim: u32) -> array<vec3f, 3> {
    return array<vec3f, 3>(tri_positions[3u * prim].xyz, tri_positions[3u * prim + 1u].xyz,
                           tri_positions[3u * prim + 2u].xyz);
}

// Unit normal of the triangle's plane, oriented by its winding (counter-clockwise = front).
fn tri_geometric_normal(prim: u32) -> vec3f {
    let p = tri_vertices(prim);
    let n = cross(p[1] - p[0], p[2] - p[0]);
    let len2 = dot(n, n);
    return select(vec3f(0.0, 0.0, 1.0), n * inverseSqrt(len2), len2 > 0.0);
}

// Interpolated vertex normal (the file's normals, else the face normal); falls back to the geometric
// normal where the interpolation cancels out.
fn tri_shading_normal(prim: u32, u: f32, v: f32) -> vec3f {
    let a = tri_attributes[prim];
    let n = (1.0 - u - v) * a.n0 + u * a.n1 + v * a.n2;
    let len2 = dot(n, n);
    if (len2 > 1e-12) { return n * inverseSqrt(len2); }
    return tri_geometric_normal(prim);
}

fn tri_material(prim: u32) -> u32 {
    return tri_attributes[prim].material;
}

fn tri_object(prim: u32) -> u32 {
    return tri_attributes[prim].object;
}

fn object_to_previous(object: u32) -> mat4x4f {
    return object_motion[object];
}

// A ray origin for leaving the surface at p (geometric normal n) toward side sign(dot(n, dir)),
// pushed off by an amount that scales with |p| so the ray cannot re-hit its own surface through
// rounding (after Wächter and Binder, "A Fast and Robust Method for Avoiding Self-Intersection",
// Ray Tracing Gems 2019, integer-ulp offsets replaced by a relative float offset).
fn offset_ray_origin(p: vec3f, n: vec3f, dir: vec3f) -> vec3f {
    let side = select(-n, n, dot(n, dir) >= 0.0);
    let scale = max(max(abs(p.x), abs(p.y)), max(abs(p.z), 1.0));
    return p + side * (scale * 1e-5);
}
