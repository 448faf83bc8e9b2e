"""WGSL kernels of the neural-network engine (resource package: see wgpu_rt.shaders)."""
