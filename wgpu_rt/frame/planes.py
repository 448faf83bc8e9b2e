"""The planes the frame passes read and write (names from ARCHITECTURE.md's planar-buffer contract).

Conventions of this package: numpy references take and return images as (H, W, C) arrays and network
tensors as planar (C, H, W) arrays, the layouts their callers (training, tests, image files) hold.
"""

import numpy as np

from ..models import CONFIDENCE, DENOISER, ERROR_PREDICTOR
from ..passes import NUMPY_DTYPE, PlaneSpec

# The networks' inputs take their channel counts from the registry of networks (models/__init__.py).
DENOISER_INPUT = PlaneSpec("denoiser_input", DENOISER.input_channels)
ERROR_INPUT = PlaneSpec("error_input", ERROR_PREDICTOR.input_channels)
CONFIDENCE_INPUT = PlaneSpec("confidence_input", CONFIDENCE.input_channels)
DENOISED = PlaneSpec("denoised", 3)
SAMPLES_PLANE = 10   # DENOISER_INPUT's 1/sqrt(spp) plane, its last (frame/pack.wgsl)
INVERSE_SQRT_SPP = PlaneSpec("inverse_sqrt_spp", 1)   # that plane alone, for a frame denoised in bands


def to_planar(image: np.ndarray) -> np.ndarray:
    """(H, W[, C]) image → contiguous (C, H, W), the device layout."""
    image = np.asarray(image)
    return np.ascontiguousarray((image[..., None] if image.ndim == 2 else image).transpose(2, 0, 1))


def write_plane(buffers, spec: PlaneSpec, image: np.ndarray) -> None:
    """Upload an (H, W[, C]) image into ``buffers``' plane ``spec`` (for tests, benchmarks and feeding
    recorded G-buffers; a rendered frame never needs it)."""
    data = to_planar(image).astype(NUMPY_DTYPE[spec.dtype])
    expected = (spec.channels, buffers.height, buffers.width)
    if data.shape != expected:
        raise ValueError(f"plane {spec.name!r} wants shape {expected}, got {data.shape}")
    buffers.ctx.device.queue.write_buffer(buffers.get(spec), 0, data.tobytes())
