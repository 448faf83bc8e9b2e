"""The path tracer: scene features, shading data packing and the TracePass (bind groups 1 and 2)."""

from .features import SceneFeatures
from .trace_pass import SampleSchedule, TracePass

__all__ = ["SampleSchedule", "SceneFeatures", "TracePass"]
