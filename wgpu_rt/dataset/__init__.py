"""Training data: scene variety (``variety``), the truth engine that renders it (``truth``) and the
reader that loads it back (``store``)."""

from .store import Frame, View, load_views, read_manifest
from .truth import DatasetConfig, DatasetError, TruthEngine, plan_views, write_manifest

__all__ = ["DatasetConfig", "DatasetError", "Frame", "TruthEngine", "View", "load_views", "plan_views",
           "read_manifest", "write_manifest"]
