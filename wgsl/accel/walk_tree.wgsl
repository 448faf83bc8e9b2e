// What every walk of the scene's trees shares (imported by accel/bvh.wgsl and the walk_scene modules,
// accel/walk_threaded.wgsl and accel/walk_wide.wgsl): a ray prepared for box and triangle tests, the
// tests, the state a walk carries, an instance's entry and the stackless walk of one threaded tree
// (walk_tree).
//
// Boxes: slab test with precomputed 1/dir, each plane's t as (plane − origin) · (1/dir): three
// roundings, which a far-plane slack after Ize ("Robust BVH Ray Traversal", JCGT 2013) covers, so a ray
// that meets a box only at its boundary still enters it (plane · (1/dir) − origin · (1/dir) cancels
// when the origin is far from the plane relative to the distance: 3 % of rays aimed at box edges
// missed, and rays through triangle edges on node boundaries slipped through both sides). Triangles
// use the watertight test of Woop, Benthin and Wald (JCGT 2013): the ray is sheared to run along +z,
// so whether it passes a shared edge depends only on that edge's two vertices and no ray slips between
// neighbouring triangles, whatever multiply-add contraction the driver applies (see edge_function).
// Triangles with collinear vertices never reach the GPU (wgpu_rt.accel.bvh leaves them out of every
// leaf): rounding into ray space can give them a sliver of area here. The shear is applied as three
// rows (products with one-hot and shear vectors) rather than by permuting vector components, which
// keeps the per-triangle code free of dynamic indexing. Both tests are branch-free: on SIMD drivers
// every branch body runs anyway.

// #import accel/geometry_bindings.wgsl
// #import accel/traversal_lanes.wgsl
// #import accel/cutouts_none.wgsl
// #import accel/panes_none.wgsl

const NO_HIT: u32 = 0xffffffffu;
const BVH_TINY_DIR: f32 = 1e-20;     // direction components below this are treated as this (no 1/0)
// A box's far plane is pushed out by the worst rounding of both planes' t: a subtraction and a product
// (½ ulp each) and 1/dir (WGSL allows 2.5 ulps), 2 × 3.5 ulps = 4.2e-7 (Ize's 1 + 2γ₃ for exact 1/dir).
const BVH_BOX_SLACK: f32 = 1.0000005;

// u, v: barycentric weights of vertices 1 and 2; prim: the triangle's number (a two-level scene numbers
// its placed triangles, instance after instance: accel/instances.wgsl), NO_HIT on a miss.
struct Hit { t: f32, u: f32, v: f32, prim: u32 }

// Everything about one ray that every box and triangle test reuses.
struct TraversalRay {
    origin: vec3f,
    inv_dir: vec3f,
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
    return TraversalRay(origin, inv_dir, axis_vector(kx) - sx * ez, axis_vector(ky) - sy * ez, ez / dz);
}

// Does the ray meet the box [lo, hi] within (0, t_max)? (Never when t_max is 0: an idle ray.)
fn box_hit(lo: vec3f, hi: vec3f, ray: TraversalRay, t_max: f32) -> bool {
    let t0 = (lo - ray.origin) * ray.inv_dir;
    let t1 = (hi - ray.origin) * ray.inv_dir;
    let near = min(t0, t1);
    let far = max(t0, t1);
    let t_near = max(max(near.x, near.y), max(near.z, 0.0));
    let t_far = min(min(far.x, far.y), min(far.z, t_max)) * BVH_BOX_SLACK;
    return t_near <= t_far && t_near < t_max;
}

// x and y of vertex v in ray space (v relative to the ray origin): every operation explicit, so the
// two triangles that share a vertex get the same coordinates for it bit for bit, however the driver
// would have contracted a dot product (the row's 1 and 0 components are exact).
fn ray_space_xy(ray: TraversalRay, v: vec3f) -> vec2f {
    return vec2f(fma(ray.shear_x.z, v.z, fma(ray.shear_x.y, v.y, ray.shear_x.x * v.x)),
                 fma(ray.shear_y.z, v.z, fma(ray.shear_y.y, v.y, ray.shear_y.x * v.x)));
}

// Twice p.x·q.y − p.y·q.x: which side of the edge p → q (ray space) the ray passes. Watertightness
// needs edge_function(q, p) == −edge_function(p, q) exactly, as the two triangles that share an edge
// evaluate it in opposite orders. Written as a*b − c*d, a driver may contract it into fma(a, b, −c*d)
// (WGSL allows it; the H100's leaks and its hits on point triangles say NVIDIA does), which rounds c*d
// but not a*b, so the mirrored order rounds the other product and the two signs can disagree, and
// x*y − y*x ≠ 0. Here both orders of the products are taken and subtracted: swapping p and q swaps
// the two fma calls operand for operand, so the result is exactly negated whether fma rounds once
// (NVIDIA) or twice (WGSL permits both; lavapipe does), as long as it is the same function both times;
// and nothing is left in the form a*b + c for a driver to contract. p == q gives exactly 0, so a point
// triangle has det == 0. Cost: 3 more operations per edge than a*b − c*d.
fn edge_function(p: vec2f, q: vec2f) -> f32 {
    return fma(p.x, q.y, -(p.y * q.x)) - fma(q.x, p.y, -(q.y * p.x));
}

// Watertight ray/triangle test: (t, u, v) of a hit with 0 < t < t_max, else t = t_max.
fn triangle_hit(ray: TraversalRay, p: TrianglePositions, t_max: f32) -> vec3f {
    let a = p.a - ray.origin;
    let b = p.b - ray.origin;
    let c = p.c - ray.origin;
    let a_xy = ray_space_xy(ray, a);
    let b_xy = ray_space_xy(ray, b);
    let c_xy = ray_space_xy(ray, c);
    let w0 = edge_function(c_xy, b_xy);   // edge functions = unnormalised barycentrics of a, b, c
    let w1 = edge_function(a_xy, c_xy);
    let w2 = edge_function(b_xy, a_xy);
    let miss_sign = (w0 < 0.0 || w1 < 0.0 || w2 < 0.0) && (w0 > 0.0 || w1 > 0.0 || w2 > 0.0);
    let det = w0 + w1 + w2;
    let t_scaled = w0 * dot(ray.shear_z, a) + w1 * dot(ray.shear_z, b) + w2 * dot(ray.shear_z, c);
    let flip = select(1.0, -1.0, det < 0.0);
    let in_range = t_scaled * flip > 0.0 && t_scaled * flip < t_max * det * flip;
    let inv_det = 1.0 / det;   // ±inf or NaN when det == 0, discarded by the select
    return select(vec3f(t_max, 0.0, 0.0), vec3f(t_scaled * inv_det, w1 * inv_det, w2 * inv_det),
                  !miss_sign && det != 0.0 && in_range);
}

// Unit normal of the plane of p, oriented by its winding (counter-clockwise = front); +z if degenerate.
fn triangle_normal(p: TrianglePositions) -> vec3f {
    let n = cross(p.b - p.a, p.c - p.a);
    let len2 = dot(n, n);
    return select(vec3f(0.0, 0.0, 1.0), n * inverseSqrt(len2), len2 > 0.0);
}

// What a walk has found so far: the closest hit (its triangle as stored and the instance it belongs
// to), whether the shadow ray is blocked, what it keeps of its light through the thin panes it crosses
// (pane_transmittance; 1 without them), and the loop passes spent.
struct WalkState {
    hit: Hit,
    hit_triangle: TrianglePositions,
    hit_instance: u32,
    occluded: bool,
    loop_passes: u32,
    shadow_tint: vec3f,
}

// Tests the stored triangles first .. end (fetched by bvh_triangle) against both rays; where a triangle is
// cut away at the point met (triangle_cut_away), the ray goes on.
fn test_triangles(state: ptr<function, WalkState>, ray: TraversalRay, shadow_ray: TraversalRay,
                  shadow_length: f32, first: u32, end: u32, instance: u32) {
    (*state).loop_passes += end - first + 1u;   // the triangle loop goes round once even when empty
    for (var prim = first; prim < end; prim += 1u) {
        let p = bvh_triangle(prim);
        let h = triangle_hit(ray, p, (*state).hit.t);
        if h.x < (*state).hit.t && !triangle_cut_away(prim, h.y, h.z) {
            (*state).hit = Hit(h.x, h.y, h.z, prim);
            (*state).hit_triangle = p;
            (*state).hit_instance = instance;
        }
        if !SHADOWS_CROSS_PANES {
            (*state).occluded = (*state).occluded || blocks(shadow_ray, p, shadow_length, prim);
        } else if !(*state).occluded && blocks(shadow_ray, p, shadow_length, prim) {
            (*state).shadow_tint *= pane_transmittance(prim, instance, p, 1.0 / shadow_ray.inv_dir);
            (*state).occluded = all((*state).shadow_tint == vec3f(0.0));
        }
    }
}

// Whether stored triangle `prim` (positions `p`) stops `ray` within (0, length).
fn blocks(ray: TraversalRay, p: TrianglePositions, length: f32, prim: u32) -> bool {
    let h = triangle_hit(ray, p, length);
    return h.x < length && !triangle_cut_away(prim, h.y, h.z);
}

// How the walk enters an instance: world → object, and where its bottom level's node copies are (copy
// k at first_node + node_count · k, `orderings` copies; a wide bottom level is one tree at first_node). Stored as two node slots after the top level's
// 8 copies (wgpu_rt.accel.geometry.InstancedGeometry.top_level) and fetched as nodes are, so a packet
// reads them once (a per-lane read of a storage record costs a loop over the lanes on SIMD drivers).
struct InstanceEntry { to_object: mat4x3f, first_node: u32, node_count: u32, orderings: u32 }

fn instance_entry(top_count: u32, instance: u32) -> InstanceEntry {
    let a = bvh_node(8u * top_count + 2u * instance);
    let b = bvh_node(8u * top_count + 2u * instance + 1u);
    return InstanceEntry(mat4x3f(a.lo, a.hi, b.lo, b.hi), a.skip, a.triangles, b.skip);
}

// Where the node copy of the top tree (the whole tree of a single-level scene) that suits rays along
// `dir` starts: the copy of its octant, or copy 0 when the buffer holds only one.
fn octant_copy_start(dir: vec3f, node_count: u32) -> u32 {
    return node_count * (packet_octant(dir) % bvh_orderings());
}

// Walks the tree whose (direction-ordered) copy holds nodes ordering .. ordering + node_count with
// `ray` and `shadow_ray` (in the space of its triangles; `instance` names it in hits), updating `state`.
fn walk_tree(state: ptr<function, WalkState>, ray: TraversalRay, shadow_ray: TraversalRay, shadow_length: f32,
             ordering: u32, node_count: u32, instance: u32) {
    var index = 0u;
    loop {
        (*state).loop_passes += 1u;
        if index >= node_count { break; }
        let node = bvh_node(ordering + index);
        let enter = packet_any(box_hit(node.lo, node.hi, ray, (*state).hit.t)
                               || (!(*state).occluded && box_hit(node.lo, node.hi, shadow_ray, shadow_length)));
        let first = node.triangles >> LEAF_COUNT_BITS;
        test_triangles(state, ray, shadow_ray, shadow_length, first,
                       first + select(0u, node.triangles & LEAF_COUNT_MASK, enter), instance);
        index = select(node.skip, index + 1u, enter);
    }
}
