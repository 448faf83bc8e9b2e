// The convolution's epilogue pools nothing (swapped in for pool_epilogue.wgsl by kernels.py where the
// layer's output is not max-pooled in its epilogue).
fn pool_tile(x0: i32, y0: i32, invocation: i32) {}
