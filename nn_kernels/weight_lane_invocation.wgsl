// The lane of the invocation that reads weight blocks, for weights_uniform.wgsl (which does not use it).
struct WeightLane {
    @builtin(local_invocation_index) id: u32,
}
