// Ray queries against the scene geometry (bind group 0, wgsl/accel/geometry_bindings.wgsl).
//
// Traversal: a threaded binary BVH (wgpu_rt/bvh.py: nodes in depth-first order, each with the index
// just past its subtree), walked without a stack: enter a node whose box the ray meets (test the
// triangles it owns: a leaf's, or the one an interior node lifted from a leaf below; go on to the next
// node), else skip its subtree. The nodes come in one copy per direction octant, each with the child
// nearer along that octant first; a walk takes the copy of its ray's octant (packet_octant), so it
// mostly finds the closest hit early and culls more with it (a hit is final only at the end).
// trace_ray_pair walks two rays at once, a closest-hit ray and a shadow ray (any hit), so a path
// tracer fetches each node once for both; the fetches, the octant and the "any ray enters" test come
// from accel/traversal_lanes.wgsl (each invocation alone) or, swapped in on CPU drivers,
// accel/traversal_subgroup.wgsl (a subgroup as one packet). On lavapipe this replaced a per-lane
// walk with a 32-entry private stack, ordered by child distance: 3.5× the path-tracing throughput.
// The single-level walk is walk_scene, a two-level scene's walk of an instance's bottom level
// walk_bottom_level, both from accel/walk_threaded.wgsl; geometry laid out 4-wide swaps in
// accel/walk_wide.wgsl (a stack, four boxes a fetch: for GPUs). What every walk shares (the box and
// triangle tests, the walk state, the threaded walk of one tree, which a two-level scene's top level
// always takes) is accel/walk_tree.wgsl.

// #import accel/geometry_bindings.wgsl
// #import accel/traversal_lanes.wgsl
// #import accel/walk_tree.wgsl
// #import accel/instances_none.wgsl
// #import accel/walk_threaded.wgsl
// #import accel/motion_objects.wgsl

// geometric_normal: tri_geometric_normal(hit.prim), from the vertices the walk already fetched.
// loop_passes: how many times the walk's loops went round (see LOOP_BUDGET in trace/trace.wgsl).
// shadow_tint: what the shadow ray keeps of its light through thin panes (accel/panes_none.wgsl; 1 without any).
struct RayPairHit { hit: Hit, occluded: bool, geometric_normal: vec3f, loop_passes: u32, shadow_tint: vec3f }

// The closest hit of (origin, dir) in (0, t_max) (t_max = 0: no such ray) and whether anything lies
// in (0, shadow_length) along (shadow_origin, shadow_dir) (only when trace_shadow).
//
// Two-level scenes (HAS_INSTANCES, accel/instances.wgsl): the top level's leaves are instances. Entering
// one walks its bottom level (the node copy of the object-space direction's octant) with both rays
// moved into its object space, direction not normalized, so a ray's t means the same point in both
// spaces and hit.t and shadow_length carry over. A packet enters an instance together (the leaf and
// packet_any are the same for every lane); each lane moves its own rays. The instance step sits in a
// loop of its own, outside the bottom-level walk, because SIMD drivers run a branch's body under a
// mask on every pass of the loop that holds it.
fn trace_ray_pair(origin: vec3f, dir: vec3f, t_max: f32, shadow_origin: vec3f, shadow_dir: vec3f,
                  shadow_length: f32, trace_shadow: bool) -> RayPairHit {
    let ray = traversal_ray(origin, dir);
    let shadow_ray = traversal_ray(shadow_origin, shadow_dir);
    var state = WalkState(Hit(t_max, 0.0, 0.0, NO_HIT),
                          TrianglePositions(vec3f(0.0), vec3f(1.0, 0.0, 0.0), vec3f(0.0, 1.0, 0.0)),
                          NO_INSTANCE, !trace_shadow, 0u, vec3f(1.0));
    if !HAS_INSTANCES {
        walk_scene(&state, ray, shadow_ray, shadow_length, dir);
    } else {
        let node_count = bvh_node_count();
        let ordering = octant_copy_start(dir, node_count);
        var index = 0u;
        loop {
            state.loop_passes += 1u;
            if index >= node_count { break; }
            let node = bvh_node(ordering + index);
            let enter = packet_any(box_hit(node.lo, node.hi, ray, state.hit.t)
                                   || (!state.occluded && box_hit(node.lo, node.hi, shadow_ray, shadow_length)));
            index = select(node.skip, index + 1u, enter);
            if enter && (node.triangles & LEAF_COUNT_MASK) != 0u {   // a leaf: one instance
                let instance = node.triangles >> LEAF_COUNT_BITS;
                let entry = instance_entry(node_count, instance);
                let object_dir = entry.to_object * vec4f(dir, 0.0);
                walk_bottom_level(&state, traversal_ray(entry.to_object * vec4f(origin, 1.0), object_dir),
                                  traversal_ray(entry.to_object * vec4f(shadow_origin, 1.0),
                                                entry.to_object * vec4f(shadow_dir, 0.0)),
                                  shadow_length, entry, object_dir, instance);
            }
        }
        if state.hit_instance != NO_INSTANCE {   // the stored triangle hit → its placed number
            let record = instance_record(state.hit_instance);
            state.hit_triangle = instance_triangle_to_world(record, state.hit_triangle);
            state.hit.prim = state.hit.prim - record.first_triangle + record.first_prim;
            remember_hit(state.hit.prim, state.hit_instance);
        }
    }
    return RayPairHit(state.hit, state.occluded, triangle_normal(state.hit_triangle), state.loop_passes,
                      state.shadow_tint);
}

// A triangle of an instance's bottom level (`record`) in world space.
fn instance_triangle_to_world(record: Instance, p: TrianglePositions) -> TrianglePositions {
    let to_world = record.to_world;
    return TrianglePositions(to_world * vec4f(p.a, 1.0), to_world * vec4f(p.b, 1.0), to_world * vec4f(p.c, 1.0));
}

// The triangle's vertices as stored (world space, or its instance's object space), by this invocation.
fn stored_triangle(stored: u32) -> TrianglePositions {
    return TrianglePositions(triangle_vertex(stored, 0u), triangle_vertex(stored, 1u), triangle_vertex(stored, 2u));
}

// A hit's triangle (its `prim`) as the tri_* queries find it: the stored triangle and the record of the
// instance that places it. A single-level scene numbers its triangles as stored (a zero record).
struct PlacedTriangle { stored: u32, record: Instance }

fn placed_triangle(prim: u32) -> PlacedTriangle {
    let record = instance_record(placed_instance(prim));
    return PlacedTriangle(prim - record.first_prim + record.first_triangle, record);
}

fn world_triangle(prim: u32) -> TrianglePositions {
    let placed = placed_triangle(prim);
    if HAS_INSTANCES {
        return instance_triangle_to_world(placed.record, stored_triangle(placed.stored));
    }
    return stored_triangle(placed.stored);
}

fn scene_intersect(origin: vec3f, dir: vec3f, tmax: f32) -> Hit {
    return trace_ray_pair(origin, dir, tmax, origin, dir, 0.0, false).hit;
}

fn scene_occluded(origin: vec3f, dir: vec3f, tmax: f32) -> bool {
    return trace_ray_pair(origin, dir, 0.0, origin, dir, tmax, true).occluded;
}

fn tri_vertices(prim: u32) -> array<vec3f, 3> {
    let p = world_triangle(prim);
    return array<vec3f, 3>(p.a, p.b, p.c);
}

// Unit normal of the triangle's plane in world space, oriented by its winding (counter-clockwise = front).
fn tri_geometric_normal(prim: u32) -> vec3f {
    return triangle_normal(world_triangle(prim));
}

// Interpolated vertex normal (the file's normals, else the face normal); falls back to the geometric
// normal where the interpolation cancels out.
fn tri_shading_normal(prim: u32, u: f32, v: f32) -> vec3f {
    return tri_shading_normal_or(prim, u, v, tri_geometric_normal(prim));
}

// tri_shading_normal for a caller that already holds the geometric normal (it is not fetched again).
fn tri_shading_normal_or(prim: u32, u: f32, v: f32, geometric_normal: vec3f) -> vec3f {
    let placed = placed_triangle(prim);
    let a = tri_attributes[placed.stored];
    var n = (1.0 - u - v) * a.n0 + u * a.n1 + v * a.n2;
    if HAS_INSTANCES {
        n = placed.record.normal_to_world * n;
    }
    let len2 = dot(n, n);
    return select(geometric_normal, n * inverseSqrt(len2), len2 > 1e-12);
}

// The vertex colour at (u, v) of a triangle: its three 8-bit sRGB codes (the bits of its positions' w words)
// decoded to linear (as wgpu_rt.scene.model.linear_from_srgb8) and interpolated.
fn tri_color(prim: u32, u: f32, v: f32) -> vec3f {
    let at = TRIANGLE_WORDS * placed_triangle(prim).stored + 3u;
    return (1.0 - u - v) * srgb8_to_linear(bitcast<u32>(position_word(at)))
        + u * srgb8_to_linear(bitcast<u32>(position_word(at + 4u)))
        + v * srgb8_to_linear(bitcast<u32>(position_word(at + 8u)));
}

fn srgb8_to_linear(word: u32) -> vec3f {
    let encoded = unpack4x8unorm(word).xyz;
    return select(pow((encoded + 0.055) / 1.055, vec3f(2.4)), encoded / 12.92, encoded <= vec3f(0.04045));
}

// The material and object of a triangle: its instance's, else (single level, world-space level) its own.
fn tri_material(prim: u32) -> u32 {
    let placed = placed_triangle(prim);
    let own = placed.record.material;
    return select(tri_attributes[placed.stored].material, own, HAS_INSTANCES && own != FROM_TRIANGLE);
}

fn tri_object(prim: u32) -> u32 {
    let placed = placed_triangle(prim);
    let own = placed.record.object;
    return select(tri_attributes[placed.stored].object, own, HAS_INSTANCES && own != FROM_TRIANGLE);
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
