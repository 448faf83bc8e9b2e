"""The path tracer: scene features, shading data packing and the TracePass (bind groups 1 and 2)."""

from .features import SceneFeatures
from .trace_pass import ALBEDO, DEPTH, MOTION, NORMAL, RADIANCE, SPP, SampleSchedule, TracePass

__all__ = ["ALBEDO", "DEPTH", "MOTION", "NORMAL", "RADIANCE", "SPP", "SampleSchedule", "SceneFeatures",
           "TracePass"]
