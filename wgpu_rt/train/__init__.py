"""Training the networks on a rendered dataset (CPU torch is enough): samples and augmentation
(``samples``), targets (``targets``), losses (``losses``) and the loop with export (``trainer``)."""

from .trainer import TrainConfig, TrainingError, train

__all__ = ["TrainConfig", "TrainingError", "train"]
