// The 3×3 convolution's epilogue stores the layer's own output (no head folded into it; kernels.py
// swaps in head_epilogue.wgsl where one is).
