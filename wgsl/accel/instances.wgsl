// A two-level scene (wgpu_rt.accel.geometry.InstancedGeometry): bvh_nodes starts with the top level,
// a tree over the instances' world boxes whose leaves name an instance, then the instances' entries
// (how the walk moves into one: accel/bvh.wgsl, instance_entry) and each bottom level (triangles in
// its own space). The records here carry what a hit needs to come back to world space, and number
// the placed triangles (a bottom level placed by many instances has its triangles stored once).

// #import accel/geometry_bindings.wgsl

const HAS_INSTANCES: bool = true;

@group(0) @binding(4) var<storage, read> instances: array<Instance>;

fn instance_record(instance: u32) -> Instance {
    return instances[instance];
}

// The closest hit this invocation found last (trace_ray_pair calls remember_hit): the queries about a
// hit's triangle that follow it find its instance here rather than by a search.
var<private> remembered_prim: u32 = 0xffffffffu;
var<private> remembered_instance: u32 = 0u;

fn remember_hit(prim: u32, instance: u32) {
    remembered_prim = prim;
    remembered_instance = instance;
}

// The instance that places triangle number `prim`: the last record whose first_prim is at most `prim`
// (records are in first_prim order, each with at least one triangle).
fn placed_instance(prim: u32) -> u32 {
    if prim == remembered_prim {
        return remembered_instance;
    }
    var lo = 0u;
    var hi = arrayLength(&instances);
    while hi - lo > 1u {
        let middle = (lo + hi) / 2u;
        let below = instances[middle].first_prim <= prim;
        lo = select(lo, middle, below);
        hi = select(middle, hi, below);
    }
    return lo;
}
