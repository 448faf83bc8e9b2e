"""wgpu-rt: a WebGPU path tracer whose neural denoiser, adaptive sampler and temporal filter run as
hand-written WGSL kernels on the same device."""

__version__ = "0.1.0"

__all__ = ["denoise", "render"]


def __getattr__(name: str):
    # `render` and `denoise` pull in wgpu and numpy; importing them lazily keeps `import wgpu_rt` (and `--help`)
    # light.
    if name in __all__:
        from . import renderer

        globals()[name] = getattr(renderer, name)
        return globals()[name]
    raise AttributeError(f"module 'wgpu_rt' has no attribute {name!r}")
