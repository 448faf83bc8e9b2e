"""Training data: scene variety (``variety``), generated worlds (``worlds``), the truth engine that
renders them (``truth``) and the reader that loads it back (``store``)."""

from .store import Frame, View, load_views, read_manifest
from .truth import DatasetConfig, DatasetError, TruthEngine, plan_views, write_manifest
from .worlds import generate_world, world_seed

__all__ = ["DatasetConfig", "DatasetError", "Frame", "TruthEngine", "View", "generate_world", "load_views",
           "plan_views", "read_manifest", "world_seed", "write_manifest"]
