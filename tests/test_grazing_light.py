"""Direct lighting at grazing emission angles, against a numpy quadrature of the direct-lighting integral.

sun-room's 2 cm sun is tilted so that its plane passes ~4 mm from the corner of the left wall and the
ceiling: the top of the wall sees the sun's front face at cosines of 0.02–0.15. A shadow ray from there
must not be stopped by the sun itself (it was, while shadow rays kept the direction taken from the
un-offset hit point: this view's top rows came out ~1% of the reference). A narrow camera looks straight at the strip; each pixel's box-filtered direct lighting
(max_depth 2) is integrated in float64: 4×4 film points per pixel, their hit on the wall plane x = -1,
and a 48×48 midpoint rule over each of the sun's two triangles. Nothing stands between the strip and
the sun (it hangs in the open room, 0.15 from the wall), so visibility is 1 there.
"""

import numpy as np

from wgpu_rt.renderer import render
from wgpu_rt.scene import load_scene
from wgpu_rt.scene.model import Camera
from wgpu_rt.scene.transforms import transform_points
from wgpu_rt.trace.scene_data import camera_vectors

SIZE = 8
# Looking along -x at the left wall just below the ceiling, beside the sun (z 0.19–0.21): the view
# spans y 0.966–0.994 (cosines 0.03–0.15 at the sun) and z 0.086–0.114.
STRIP_CAMERA = Camera(origin=[0.0, 0.98, 0.1], target=[-1.0, 0.98, 0.1], up=[0, 1, 0], fov=1.6)


def _midpoint_rule_on_triangle(triangle: np.ndarray, n: int) -> tuple[np.ndarray, float, np.ndarray]:
    """n² points of equal weight covering ``triangle`` (the unit square's midpoints folded onto it),
    the area each stands for, and the triangle's unit normal (its winding's front)."""
    g = (np.arange(n) + 0.5) / n
    a, b = (x.ravel() for x in np.meshgrid(g, g))
    folded = a + b > 1
    a, b = np.where(folded, 1 - a, a), np.where(folded, 1 - b, b)
    edge1, edge2 = triangle[1] - triangle[0], triangle[2] - triangle[0]
    cross = np.cross(edge1, edge2)
    area = 0.5 * np.linalg.norm(cross)
    points = triangle[0] + a[:, None] * edge1 + b[:, None] * edge2
    return points, area / n ** 2, cross / (2 * area)


def _direct_lighting_reference(scene) -> np.ndarray:
    """(SIZE, SIZE) box-filtered direct lighting of the diffuse wall x = -1 seen by STRIP_CAMERA."""
    sun = next(m for m in scene.meshes if m.name == "sun")
    radiance = float(scene.materials[sun.material].emission[0])
    albedo = float(scene.materials["wall"].reflectance[0])
    triangles = transform_points(sun.transform, sun.vertices).astype(np.float64)[sun.faces]
    quadrature = [_midpoint_rule_on_triangle(t, 48) for t in triangles]

    view = camera_vectors(STRIP_CAMERA, SIZE, SIZE)
    sub = (np.arange(4) + 0.5) / 4
    # film points as (row, sub-row, column, sub-column): film x runs along columns, film y down rows
    pixel = np.arange(SIZE)
    film_y = (pixel[:, None, None, None] + sub[None, :, None, None]) * np.ones((1, 1, SIZE, 4))
    film_x = (pixel[None, None, :, None] + sub[None, None, None, :]) * np.ones((SIZE, 4, 1, 1))
    ndc_x, ndc_y = 2 * film_x / SIZE - 1, 1 - 2 * film_y / SIZE
    dirs = (view["forward"] + ndc_x[..., None] * view["right"] + ndc_y[..., None] * view["up"]).astype(np.float64)
    origin = np.asarray(view["origin"], np.float64)
    hits = origin + dirs * ((-1.0 - origin[0]) / dirs[..., :1])       # on the wall x = -1
    wall_normal = np.array([1.0, 0.0, 0.0])

    irradiance = np.zeros(hits.shape[:-1])
    for points, weight, light_normal in quadrature:
        to_light = points - hits[..., None, :]
        dist2 = np.einsum("...i,...i->...", to_light, to_light)
        unit = to_light / np.sqrt(dist2)[..., None]
        cos_wall = np.clip(unit @ wall_normal, 0, None)
        cos_light = np.clip(-(unit @ light_normal), 0, None)
        irradiance += (cos_wall * cos_light / dist2).sum(-1) * weight
    return (radiance * albedo / np.pi * irradiance).mean((1, 3))


def test_wall_beside_grazing_sun_matches_quadrature(gpu):
    scene = load_scene("sun-room")
    scene.camera = STRIP_CAMERA
    reference = _direct_lighting_reference(scene)
    ours = render(scene, spp=256, size=(SIZE, SIZE), max_depth=2, aovs=()).color[..., 0]
    assert reference.min() > 0.2, reference   # the whole view is lit, at cosines down to 0.03
    ratio = ours / reference
    assert np.all(np.abs(ratio - 1) < 0.02), ratio
    assert abs(ours.sum() / reference.sum() - 1) < 0.003, ours.sum() / reference.sum()
