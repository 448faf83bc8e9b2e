"""What each pixel's camera rays meet first, by the tracer's own ray queries: SUBPIXELS² rays a pixel on
a regular grid. The denoiser's scene tests pick the pixels they score with it (those that see only
glass; those on a rim between sky and ground or around an emitter)."""

import numpy as np

from wgpu_rt.accel.geometry import GeometryBuffers, scene_material_names
from wgpu_rt.accel.ray_query import NO_HIT, RayQuery, query_rays
from wgpu_rt.trace.scene_data import camera_vectors

SUBPIXELS = 4


def first_materials(ctx, scene, size: int) -> np.ndarray:
    """(size, size, SUBPIXELS²) names of the material each camera ray meets first, "" where it escapes."""
    view = camera_vectors(scene.camera, size, size)
    film = (np.arange(size * SUBPIXELS) + 0.5) / SUBPIXELS
    film_y, film_x = (f.ravel() for f in np.meshgrid(film, film, indexing="ij"))
    dirs = (view["forward"] + (2 * film_x / size - 1)[:, None] * view["right"]
            + (1 - 2 * film_y / size)[:, None] * view["up"])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    geometry = GeometryBuffers.build(scene, 0)
    origins = np.broadcast_to(scene.camera.origin, dirs.shape)
    hits, surfaces = RayQuery(ctx, geometry).intersect(query_rays(origins, dirs))
    names = np.array(scene_material_names(scene) + [""])
    met = np.where(hits["prim"] != NO_HIT, np.minimum(surfaces["material"], len(names) - 2), len(names) - 1)
    per_subpixel = names[met].reshape(size, SUBPIXELS, size, SUBPIXELS).transpose(0, 2, 1, 3)
    return per_subpixel.reshape(size, size, -1)
