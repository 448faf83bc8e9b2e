"""The frame after the tracer: pack → (network) → unpack → temporal → tonemap, the adaptive sampler,
``denoise()`` for one image off the frame loop, and the ``FramePipeline`` that records a whole frame
(``wgpu_rt.renderer`` sets one up)."""

from .pipeline import FramePipeline, RenderResult

__all__ = ["FramePipeline", "RenderResult"]
