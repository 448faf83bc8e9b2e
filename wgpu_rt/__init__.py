"""wgpu-rt: a WebGPU path tracer whose neural denoiser, adaptive sampler and temporal filter run as
hand-written WGSL kernels on the same device."""

__version__ = "0.1.0"
