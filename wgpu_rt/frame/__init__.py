"""On-device frame passes after the tracer: pack → (network) → unpack → temporal → tonemap, the
adaptive sampler, and the fused per-frame pipeline (``render_frames``)."""

from .pipeline import FramePipeline, RenderedFrame, make_pipeline, render_frames

__all__ = ["FramePipeline", "RenderedFrame", "make_pipeline", "render_frames"]
