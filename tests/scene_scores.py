"""The denoiser's scene tests: what each pixel's camera rays meet first, by the tracer's own ray queries
(SUBPIXELS² rays a pixel on a regular grid), to pick the pixels a test scores (those that see only glass;
those on the horizon), and the shipped denoiser's PSNR there and over the whole image."""

import numpy as np

from wgpu_rt.accel.geometry import GeometryBuffers, scene_material_names
from wgpu_rt.accel.ray_query import NO_HIT, RayQuery, query_rays
from wgpu_rt.metrics import psnr
from wgpu_rt.renderer import render
from wgpu_rt.trace.scene_data import camera_vectors

SUBPIXELS = 4
SEEDS = (0, 1, 2, 3)   # the 1-spp renders a test scores, a mean over them


def camera_rays(camera, size: int, subpixels: int = 1) -> np.ndarray:
    """(size·subpixels, size·subpixels, 3) unit directions of a pinhole ``camera``'s rays through the centres
    of a square image's pixels (or of their subpixels × subpixels parts), rows from the top, as
    wgsl/trace/camera.wgsl aims them."""
    view = camera_vectors(camera, size, size)
    film = (np.arange(size * subpixels) + 0.5) / subpixels
    film_y, film_x = np.meshgrid(film, film, indexing="ij")
    dirs = (view["forward"] + (2 * film_x / size - 1)[..., None] * view["right"]
            + (1 - 2 * film_y / size)[..., None] * view["up"])
    return dirs / np.linalg.norm(dirs, axis=-1, keepdims=True)


def first_materials(ctx, scene, size: int) -> np.ndarray:
    """(size, size, SUBPIXELS²) names of the material each camera ray meets first, "" where it escapes."""
    dirs = camera_rays(scene.camera, size, SUBPIXELS).reshape(-1, 3)
    geometry = GeometryBuffers.build(scene, 0)
    origins = np.broadcast_to(scene.camera.origin, dirs.shape)
    hits, surfaces = RayQuery(ctx, geometry).intersect(query_rays(origins, dirs))
    names = np.array(scene_material_names(scene) + [""])
    met = np.where(hits["prim"] != NO_HIT, np.minimum(surfaces["material"], len(names) - 2), len(names) - 1)
    per_subpixel = names[met].reshape(size, SUBPIXELS, size, SUBPIXELS).transpose(0, 2, 1, 3)
    return per_subpixel.reshape(size, size, -1)


def denoised_psnr(ctx, scene, size: int, mask: np.ndarray, gold_spp: int, seeds=SEEDS) -> tuple[list, list]:
    """PSNR of ``render(..., denoise=True)`` at 1 spp against a gold render at ``gold_spp`` (seed 1000), over
    ``mask`` and over the whole image, one of each per seed; every denoised image must be finite."""
    gold = render(scene, gold_spp, (size, size), seed=1000, ctx=ctx).color
    region, image = [], []
    for seed in seeds:
        denoised = render(scene, 1, (size, size), seed=seed, denoise=True, ctx=ctx).color
        assert np.isfinite(denoised).all()
        region.append(psnr(gold[mask], denoised[mask]))
        image.append(psnr(gold, denoised))
    return region, image
