"""Light through smooth glass against a deterministic float64 enumeration of the same paths.

Issue 15's glass block under a softbox (lifted 1 mm off the floor, see glass_block_scene)
with a black floor and a softbox that only emits, so that every path that carries light is specular
from the camera to the softbox or the background. Each camera ray then splits at every glass face into
its reflected and refracted branches with the exact Fresnel weights (total internal reflection
included, radiance scaled by 1/eta² on refraction) down to max_depth, so the image is a sum over a
finite tree rather than a sample of it: a branch that escapes adds the background, one that meets
the softbox's front its emission in full (a delta bounce cannot be light-sampled, so no MIS weight). A
segment that ends on the glass's back face ran inside it and keeps exp(−absorption · length) of its light.
The box filter is a midpoint rule over FILM_POINTS² film points per pixel.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from wgpu_rt.renderer import render
from wgpu_rt.scene.loader import parse_scene
from wgpu_rt.scene.model import Camera
from wgpu_rt.scene.transforms import transform_points
from wgpu_rt.trace.scene_data import camera_vectors

SIZE = 16
MAX_DEPTH = 8
FILM_POINTS = 8         # per pixel side
# From the side opposite the softbox, looking down at the block: the top face mirrors the softbox and
# the side faces show it refracted through the block (it gives 99% of the image, the background the rest).
CAMERA = Camera(origin=[-1.575, 0.5, 0.525], target=[-0.85, -0.7, 0.75], fov=20)

ISSUE_15_SCENE = {
    "camera": {"origin": [-0.85, 0.1, 1.6], "target": [-0.85, -0.8, 0.75], "fov": 30},
    "materials": {"floor": {"kind": "diffuse", "reflectance": [0.55, 0.5, 0.45]},
                  "glass": {"kind": "dielectric", "ior": 1.5},
                  "softbox": {"kind": "diffuse", "reflectance": 0.5, "emission": [18, 15, 11]}},
    "meshes": [{"name": "floor", "shape": "rectangle", "material": "floor",
                "transform": {"rotate": {"axis": [1, 0, 0], "angle": -90}, "scale": 4, "translate": [0, -1, 0]}},
               {"name": "block", "shape": "cube", "material": "glass",
                "transform": {"rotate": {"axis": [0, 1, 0], "angle": 25}, "scale": 0.2,
                              "translate": [-0.85, -0.8, 0.75]}},
               {"name": "softbox", "shape": "rectangle", "material": "softbox",
                "transform": {"rotate": {"axis": [1, 0, 0], "angle": 60}, "scale": [0.6, 0.35, 1],
                              "translate": [0.6, 1.6, 1.2]}}],
    "background": [0.05, 0.07, 0.1],
}


def glass_block_scene(lift: float = 0.001):
    """Issue 15's scene with the block raised by ``lift``; by default 1 mm, as the dataset's worlds lift
    their objects. Resting exactly on the floor (lift 0), the block's bottom face and the floor are
    coplanar: which of the two a ray inside the glass meets first is decided by rounding, differently
    in every renderer (one way it refracts out below the floor and sees the background, the other it
    lands on the floor from inside the glass), so that scene has no one right image."""
    scene = json.loads(json.dumps(ISSUE_15_SCENE))
    scene["meshes"][1]["transform"]["translate"][1] += lift
    return parse_scene(scene, "issue 15's glass block", Path.cwd())


class _Geometry:
    """The scene's triangles in float64, each with its unit normal (its winding's front) and material."""

    def __init__(self, scene):
        triangles, owners = [], []
        for mesh in scene.meshes:
            vertices = transform_points(mesh.transform, mesh.vertices).astype(np.float64)
            triangles.append(vertices[mesh.faces])
            owners += [mesh.material] * len(mesh.faces)
        self.triangles = np.concatenate(triangles)
        self.material = np.array(owners)
        self.edge1 = self.triangles[:, 1] - self.triangles[:, 0]
        self.edge2 = self.triangles[:, 2] - self.triangles[:, 0]
        cross = np.cross(self.edge1, self.edge2)
        self.normal = cross / np.linalg.norm(cross, axis=1, keepdims=True)
        self.materials = scene.materials
        self.background = np.asarray(scene.background, np.float64)

    def intersect(self, origins, dirs):
        """(distance, triangle) of each ray's nearest hit; triangle -1 where it escapes."""
        p = np.cross(dirs[:, None], self.edge2[None])
        det = np.einsum("rtk,tk->rt", p, self.edge1)
        safe = np.where(np.abs(det) > 1e-15, det, np.inf)
        s = origins[:, None] - self.triangles[None, :, 0]
        u = np.einsum("rtk,rtk->rt", s, p) / safe
        q = np.cross(s, self.edge1[None])
        v = np.einsum("rk,rtk->rt", dirs, q) / safe
        t = np.einsum("rtk,tk->rt", q, self.edge2) / safe
        t = np.where((u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9), t, np.inf)
        nearest = np.argmin(t, axis=1)
        distance = t[np.arange(len(t)), nearest]
        return distance, np.where(np.isfinite(distance), nearest, -1)


def _reference_image(scene) -> np.ndarray:
    """(SIZE, SIZE, 3) box-filtered radiance of the paths of at most MAX_DEPTH segments."""
    geo = _Geometry(scene)
    view = camera_vectors(scene.camera, SIZE, SIZE)
    g = (np.arange(SIZE * FILM_POINTS) + 0.5) / FILM_POINTS
    film_y, film_x = (x.ravel() for x in np.meshgrid(g, g, indexing="ij"))
    dirs = (view["forward"] + (2 * film_x / SIZE - 1)[:, None] * view["right"]
            + (1 - 2 * film_y / SIZE)[:, None] * view["up"]).astype(np.float64)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    origins = np.broadcast_to(np.asarray(scene.camera.origin, np.float64), dirs.shape)
    film_index = np.arange(len(dirs))
    weights = np.ones((len(dirs), 3))
    radiance = np.zeros((len(dirs), 3))
    ior = scene.materials["glass"].ior
    for segment in range(1, MAX_DEPTH + 1):
        distance, triangle = geo.intersect(origins, dirs)
        escaped = triangle < 0
        np.add.at(radiance, film_index[escaped], weights[escaped] * geo.background)
        keep = ~escaped
        origins, dirs, weights, film_index, triangle = (
            origins[keep], dirs[keep], weights[keep], film_index[keep], triangle[keep])
        points = origins + distance[keep, None] * dirs
        normals = geo.normal[triangle]
        cos_front = -np.einsum("rk,rk->r", normals, dirs)
        materials = [geo.materials[m] for m in geo.material[triangle]]
        inside = np.array([m.absorption for m in materials], np.float64) * (cos_front < 0)[:, None]
        weights = weights * np.exp(-inside * distance[keep, None])
        emission = np.array([m.emission for m in materials], np.float64) * (cos_front > 0)[:, None]
        np.add.at(radiance, film_index, weights * emission)
        glass = np.array([m.kind == "dielectric" for m in materials], bool)
        # the diffuse surfaces are black, so a path ends there
        assert all(m.kind == "dielectric" or not m.reflectance.any() for m in materials)
        if segment == MAX_DEPTH or not glass.any():
            break
        origins, dirs, weights, film_index = (x[glass] for x in (points, dirs, weights, film_index))
        normals, cos_i = normals[glass], cos_front[glass]
        eta = np.where(cos_i > 0, ior, 1 / ior)                  # transmitted / incident index
        facing = normals * np.sign(cos_i)[:, None]               # the normal on the incident side
        cos_i = np.abs(cos_i)
        cos_t2 = 1 - (1 - cos_i ** 2) / eta ** 2
        cos_t = np.sqrt(np.maximum(cos_t2, 0))
        r_s = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
        r_p = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
        fresnel = np.where(cos_t2 > 0, 0.5 * (r_s ** 2 + r_p ** 2), 1.0)
        reflected = dirs + 2 * cos_i[:, None] * facing
        refracted = dirs / eta[:, None] + (cos_i / eta - cos_t)[:, None] * facing
        passes = cos_t2 > 0
        origins = np.concatenate([origins + 1e-7 * facing, (origins - 1e-7 * facing)[passes]])
        dirs = np.concatenate([reflected, refracted[passes]])
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        weights = np.concatenate([weights * fresnel[:, None],
                                  (weights * ((1 - fresnel) / eta ** 2)[:, None])[passes]])
        film_index = np.concatenate([film_index, film_index[passes]])
    return radiance.reshape(SIZE, FILM_POINTS, SIZE, FILM_POINTS, 3).mean((1, 3))


@pytest.mark.parametrize("absorption", [0.0, (1.0, 4.0, 12.0)])
def test_glass_block_matches_path_enumeration(gpu, absorption):
    """Clear, and absorbing inside at rates that leave 67 / 20 / 1 % of the light crossing the block's 0.4
    width."""
    scene = glass_block_scene()
    scene.materials["glass"].absorption = np.float32(np.broadcast_to(absorption, 3))
    scene.materials["floor"].reflectance[:] = 0
    scene.materials["softbox"].reflectance[:] = 0
    scene.camera = CAMERA
    reference = _reference_image(scene)
    ours = render(scene, spp=4096, size=(SIZE, SIZE), max_depth=MAX_DEPTH, aovs=()).color
    assert np.all(np.isfinite(ours))
    ratio = ours.reshape(-1, 3).mean(0) / reference.reshape(-1, 3).mean(0)
    assert np.all(np.abs(ratio - 1) < 0.01), ratio
    # and where: 4×4-pixel blocks (single pixels straddle the softbox's sharp edges, which the film
    # midpoint rule only approximates)
    coarse = lambda im: im.reshape(4, 4, 4, 4, 3).mean((1, 3))
    error = np.abs(coarse(ours) - coarse(reference)) / (coarse(reference) + 0.1 * reference.mean())
    assert error.max() < 0.1, error.max()
