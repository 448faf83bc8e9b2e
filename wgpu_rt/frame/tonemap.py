"""Display transform: exposure, tone curve (none, Reinhard, ACES fitted), sRGB OETF, RGBA8 or f32.

The RGBA8 output is one packed u32 per pixel (bytes R, G, B, A in memory order) so that the final
readback is W·H·4 bytes and reads straight into an (H, W, 4) uint8 image; the f32 output is four
planar RGBA planes (linear HDR when the operator is ``none`` and sRGB is off, for EXR files).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from ..errors import WgpuRtError
from ..passes import ComputePass, PlaneSpec
from .kernel import FrameKernel, nonnegative_finite

OPERATORS = ("none", "reinhard", "aces")
FORMATS = ("rgba8", "f32")
DISPLAY_RGBA8 = PlaneSpec("display", 1, "u32")
DISPLAY_F32 = PlaneSpec("display_f32", 4)
# The shader clamps Reinhard's input to this (CURVE_INPUT_MAX in wgsl/frame/tonemap.wgsl) so that its
# divisor stays within WGSL's accurate range (≤ 2^126); the curve is 1 in float32 long before.
CURVE_INPUT_MAX = 1e30
# Beyond ±126 stops 2^exposure is not a normal float32, which GPUs may flush to 0 (or overflow to
# inf, and 0·inf is NaN); ±64 is far past any useful exposure.
MAX_EXPOSURE_STOPS = 64

ACES_INPUT = np.array([[0.59719, 0.35458, 0.04823],
                       [0.07600, 0.90834, 0.01566],
                       [0.02840, 0.13383, 0.83777]], np.float64)
ACES_OUTPUT = np.array([[1.60475, -0.53108, -0.07367],
                        [-0.10208, 1.10813, -0.00605],
                        [-0.00327, -0.07276, 1.07602]], np.float64)


def aces_fitted(linear: np.ndarray) -> np.ndarray:
    """Stephen Hill's fit of the ACES RRT+ODT for sRGB displays; (..., 3) linear → [0, 1]."""
    v = np.minimum(linear @ ACES_INPUT.T, 1e6)
    curve = (v * (v + 0.0245786) - 0.000090537) / (v * (0.983729 * v + 0.4329510) + 0.238081)
    return np.clip(curve @ ACES_OUTPUT.T, 0.0, 1.0)


def srgb_oetf(v: np.ndarray) -> np.ndarray:
    v = np.maximum(v, 0.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055)


def tonemap(image: np.ndarray, operator: str = "aces", exposure: float = 0.0, srgb: bool = True,
            output: str = "rgba8") -> np.ndarray:
    """(H, W, 3) linear radiance → (H, W, 4) uint8 (``rgba8``) or float32 (``f32``) display image."""
    check_settings(operator, output, exposure)
    v = np.minimum(nonnegative_finite(image).astype(np.float64) * 2.0 ** exposure, 3e38)
    if operator == "reinhard":
        v = np.minimum(v, CURVE_INPUT_MAX)
        v = v / (1.0 + v)
    elif operator == "aces":
        v = aces_fitted(v)
    if srgb:
        v = srgb_oetf(v)
    rgba = np.concatenate([v, np.ones(v.shape[:2] + (1,))], axis=-1)
    if output == "f32":
        return rgba.astype(np.float32)
    return np.floor(np.clip(rgba, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def check_settings(operator: str, output: str, exposure: float = 0.0) -> None:
    if (not isinstance(exposure, numbers.Real) or isinstance(exposure, bool) or not math.isfinite(exposure)
            or abs(exposure) > MAX_EXPOSURE_STOPS):
        raise WgpuRtError(f"exposure {exposure!r} must be a number of stops within ±{MAX_EXPOSURE_STOPS}")
    if operator not in OPERATORS:
        raise WgpuRtError(f"tone-mapping operator {operator!r} is not one of {', '.join(OPERATORS)}")
    if output not in FORMATS:
        raise WgpuRtError(f"display format {output!r} is not one of {', '.join(FORMATS)}")


class TonemapPass(ComputePass):
    """``source`` (3 planes of linear radiance) → display (RGBA8 packed, or 4 f32 planes)."""

    def __init__(self, ctx, width: int, height: int, source: PlaneSpec, operator: str = "aces",
                 exposure: float = 0.0, srgb: bool = True, output: str = "rgba8"):
        check_settings(operator, output, exposure)
        self.source, self.output = source, output
        self.display = DISPLAY_RGBA8 if output == "rgba8" else DISPLAY_F32
        self.inputs, self.outputs = (source,), (self.display,)
        self.kernel = FrameKernel(
            ctx, "frame/tonemap.wgsl", "to_rgba8" if output == "rgba8" else "to_rgba32f",
            ("color", "display"), width, height,
            constants={"OPERATOR": OPERATORS.index(operator), "EXPOSURE": exposure, "SRGB": srgb})

    def execute(self, encoder, buffers) -> None:
        self.kernel.dispatch(encoder, {"color": buffers.get(self.source),
                                       "display": buffers.get(self.display)})

    def image(self, raw: np.ndarray, width: int, height: int) -> np.ndarray:
        """The (H, W, 4) display image from this pass's output bytes as read back."""
        if self.output == "rgba8":
            return np.frombuffer(raw, np.uint8, count=width * height * 4).reshape(height, width, 4).copy()
        planes = np.frombuffer(raw, np.float32, count=width * height * 4).reshape(4, height, width)
        return planes.transpose(1, 2, 0).copy()
