"""Path-tracing WGSL modules (resource package: see wgpu_rt.shaders)."""
