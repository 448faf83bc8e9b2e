"""The shipped denoiser along the horizon of open ground under a sky, where a pixel is part ground and
part sky. The network denoises colour divided by albedo; with an escaping path's albedo taken as 0 such
a pixel read as the ground's irradiance over its coverage plus the sky's radiance times 100, and the
output left a speckled dark seam along the horizon. The tracer and the aux pass now give an escape the
background's radiance as albedo (at most 1; `wgsl/trace/guide_albedo.wgsl`), so the quotient stays smooth
across the rim. (The glowing ball keeps its reflectance as albedo; its outline is scored with the image.)

Scored against a gold render of the same tracer (PSNR on the display mapping) over the horizon's pixels
(those whose 4×4 camera rays meet both the sky and something else, `scene_scores.py`) and over the whole
image, mean over four 1-spp seeds at 64² on lavapipe: with albedo 0 there 25.70 / 33.14 dB, now 35.63 /
33.72 (BENCHMARKS.md §28). The bounds sit between.
"""

from pathlib import Path

import numpy as np
import pytest

from scene_scores import denoised_psnr, first_materials
from wgpu_rt.scene.loader import parse_scene

SIZE = 64
GOLD_SPP = 1024
RIM_BOUND_DB = 30.0
IMAGE_BOUND_DB = 33.45

OPEN_GROUND = {
    "camera": {"origin": [0.0, 0.6, 3.0], "target": [0.0, 0.2, 0.0], "fov": 40},
    "materials": {
        "ground": {"kind": "diffuse", "reflectance": [0.75, 0.35, 0.5]},
        "stone": {"kind": "diffuse", "reflectance": [0.3, 0.5, 0.7]},
        "lamp": {"kind": "diffuse", "reflectance": 0.8, "emission": [2.5, 1.2, 0.4]}},
    "meshes": [
        {"name": "ground", "shape": "rectangle", "material": "ground",
         "transform": {"rotate": [{"axis": [1, 0, 0], "angle": -90}, {"axis": [0, 0, 1], "angle": 4}], "scale": 80,
                       "translate": [0, -0.5, -30]}},
        {"name": "stone", "shape": "cube", "material": "stone",
         "transform": {"rotate": {"axis": [0, 1, 0], "angle": 25}, "scale": 0.35, "translate": [-0.6, -0.15, 0]}},
        {"name": "lamp", "shape": "sphere", "material": "lamp",
         "transform": {"scale": 0.25, "translate": [0.6, 0.0, 0.3]}}],
    "lights": [{"type": "directional", "direction": [-0.5, -0.6, -0.4], "irradiance": [2.4, 2.2, 1.9]}],
    "background": [0.35, 0.45, 0.75],
}


@pytest.fixture(scope="module")
def open_ground():
    return parse_scene(OPEN_GROUND, "open ground", Path.cwd())


def rim_pixels(ctx, scene) -> np.ndarray:
    """(SIZE, SIZE) mask: the pixels whose camera rays meet the sky and also something else."""
    sky = first_materials(ctx, scene, SIZE) == ""
    return sky.any(axis=-1) & ~sky.all(axis=-1)


def test_the_rim_is_the_horizon(gpu, open_ground):
    mask = rim_pixels(gpu, open_ground)
    assert SIZE // 2 <= mask.sum() <= 2 * SIZE, mask.sum()
    # the horizon crosses the whole frame (a column whose edge falls between two pixels' subpixel rows has
    # no mixed pixel: a quarter of them)
    assert mask.any(axis=0).mean() >= 0.7


def test_the_denoised_horizon_has_no_seam(gpu, open_ground):
    mask = rim_pixels(gpu, open_ground)
    rim, image = denoised_psnr(gpu, open_ground, SIZE, mask, GOLD_SPP)
    assert np.mean(rim) >= RIM_BOUND_DB, f"rim {np.round(rim, 2)} dB"
    assert np.mean(image) >= IMAGE_BOUND_DB, f"whole image {np.round(image, 2)} dB"
