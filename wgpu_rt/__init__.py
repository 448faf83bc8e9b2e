"""wgpu-rt: a WebGPU path tracer whose neural denoiser, adaptive sampler and temporal filter run as
hand-written WGSL kernels on the same device."""

__version__ = "0.1.0"

__all__ = ["render"]


def __getattr__(name: str):
    # `render` pulls in wgpu and numpy; importing it lazily keeps `import wgpu_rt` (and `--help`) light.
    if name == "render":
        from .renderer import render

        globals()["render"] = render
        return render
    raise AttributeError(f"module 'wgpu_rt' has no attribute {name!r}")
