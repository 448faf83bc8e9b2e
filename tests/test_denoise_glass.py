"""The shipped denoiser on glass it never saw (issue 12's worst case): a smooth glass cube in front of
coloured blocks, a rough copper ball and a tilted rectangular light, a scene of none of the training
families. Each 1-spp path through the cube picks reflection or refraction at random, so the cube's
pixels are speckled; the network must not keep that speckle as texture. Scored against a gold render
of the same tracer (PSNR on the display mapping) over the pixels that see only glass (every one of
4×4 camera rays per pixel meets the cube first, `scene_scores.py`) and over the whole image.

The bounds sit between the model shipped before the worlds fine-tune (glass 20.02 dB, whole image
25.02 dB, means over these four seeds on lavapipe) and the one that followed it (20.96 / 26.26 dB): that
earlier model fails them; the shipped five-level model scores 21.62 / 26.98 (BENCHMARKS.md §9), 21.95 /
27.18 with twice the aux paths behind glass (§13) and 22.58 / 27.61 since the aux pass shares the first
glass bounce's lobes by Fresnel weight (§15); 22.65 / 27.76 today, an escape's albedo the background's
(§28). OIDN 2.5 (CPU) on the same inputs with the same noise-free
albedo: 21.44 / 27.13 dB (BENCHMARKS.md §5), 21.48 / 27.17 with today's aux pass (§15).
"""

from pathlib import Path

import numpy as np
import pytest

from scene_scores import denoised_psnr, first_materials
from wgpu_rt.scene.loader import parse_scene

SIZE = 96
GOLD_SPP = 512
GLASS_BOUND_DB = 20.5
IMAGE_BOUND_DB = 25.7

GLASS_SHOWCASE = {
    "camera": {"origin": [0.0, 0.35, 2.6], "target": [0.0, -0.35, 0.0], "fov": 38},
    "materials": {
        "floor": {"kind": "diffuse", "reflectance": [0.7, 0.68, 0.62]},
        "red": {"kind": "diffuse", "reflectance": [0.75, 0.12, 0.1]},
        "green": {"kind": "diffuse", "reflectance": [0.15, 0.6, 0.2]},
        "blue": {"kind": "diffuse", "reflectance": [0.12, 0.2, 0.7]},
        "copper": {"kind": "conductor", "roughness": 0.2, "eta": [0.27, 0.68, 1.32], "k": [3.61, 2.63, 2.29]},
        "glass": {"kind": "dielectric", "ior": 1.5},
        "light": {"kind": "diffuse", "reflectance": 0.5, "emission": [14, 13, 11]}},
    "meshes": [
        {"name": "floor", "shape": "rectangle", "material": "floor",
         "transform": {"rotate": {"axis": [1, 0, 0], "angle": -90}, "scale": 4, "translate": [0, -1, 0]}},
        {"name": "back", "shape": "rectangle", "material": "floor", "transform": {"scale": 4, "translate": [0, 0, -1.5]}},
        {"name": "red block", "shape": "cube", "material": "red",
         "transform": {"scale": [0.18, 0.35, 0.18], "translate": [-0.45, -0.65, -0.7]}},
        {"name": "green block", "shape": "cube", "material": "green",
         "transform": {"rotate": {"axis": [0, 1, 0], "angle": 30}, "scale": 0.2, "translate": [0.05, -0.8, -0.9]}},
        {"name": "blue block", "shape": "cube", "material": "blue",
         "transform": {"scale": [0.15, 0.5, 0.15], "translate": [0.5, -0.5, -0.8]}},
        {"name": "copper ball", "shape": "sphere", "material": "copper",
         "transform": {"scale": 0.25, "translate": [0.75, -0.75, 0.1]}},
        {"name": "glass cube", "shape": "cube", "material": "glass",   # 1 mm above the floor
         "transform": {"rotate": {"axis": [0, 1, 0], "angle": 35}, "scale": 0.32, "translate": [-0.1, -0.679, 0.1]}},
        {"name": "light", "shape": "rectangle", "material": "light",
         "transform": {"rotate": [{"axis": [1, 0, 0], "angle": 70}, {"axis": [0, 0, 1], "angle": 25}],
                       "scale": [0.5, 0.3, 1], "translate": [0.4, 1.4, 0.8]}}],
    "background": [0.03, 0.04, 0.06],
}


def glass_pixels(ctx, scene, size: int) -> np.ndarray:
    """(size, size) mask of the pixels whose camera rays all meet a dielectric first."""
    kinds = {name: material.kind for name, material in scene.materials.items()}
    met = first_materials(ctx, scene, size)
    return np.vectorize(lambda name: kinds.get(name) == "dielectric")(met).all(axis=-1)


@pytest.fixture(scope="module")
def showcase():
    return parse_scene(GLASS_SHOWCASE, "glass showcase", Path.cwd())


def test_the_mask_covers_the_cube_and_nothing_else(gpu, showcase):
    mask = glass_pixels(gpu, showcase, SIZE)
    assert 1500 < mask.sum() < 2100          # the cube fills about a fifth of the frame
    rows, cols = np.nonzero(mask)
    assert rows.min() > SIZE // 3 and cols.max() < SIZE * 3 // 4   # lower middle, left of the copper ball


def test_shipped_denoiser_cleans_glass_it_never_saw(gpu, showcase):
    mask = glass_pixels(gpu, showcase, SIZE)
    glass, image = denoised_psnr(gpu, showcase, SIZE, mask, GOLD_SPP)
    assert np.mean(glass) >= GLASS_BOUND_DB, f"glass region {np.round(glass, 2)} dB"
    assert np.mean(image) >= IMAGE_BOUND_DB, f"whole image {np.round(image, 2)} dB"
