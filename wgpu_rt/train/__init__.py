"""Training the networks on a rendered dataset (CPU torch is enough; CUDA and several processes under
torchrun when present): samples and augmentation (``samples``), targets (``targets``), losses
(``losses``), device and data-parallel set-up (``context``) and the loop with export (``trainer``)."""

from .trainer import TrainConfig, TrainingError, train

__all__ = ["TrainConfig", "TrainingError", "train"]
