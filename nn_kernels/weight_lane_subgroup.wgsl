// The lane of the invocation that reads weight blocks, for weights_subgroup.wgsl; SUBGROUP_LANES is
// the adapter's subgroup width as probed by the engine (kernels.subgroup_lanes), 4 at least.
const SUBGROUP_LANES: u32 = {{SUBGROUP_LANES}}u;

struct WeightLane {
    @builtin(subgroup_invocation_id) id: u32,
}
