"""Randomized variations of a scene, so a small set of scenes yields many different training views.

Everything here is a pure function of a ``numpy.random.Generator`` and a ``Scene``: a view's seed fixes
its scene exactly. Variations (all copies; the input scene is never mutated):

- materials: reflectance hue/brightness, roughness, dielectric IOR;
- lighting: emitter intensity, sun (directional light) angle and colour temperature, extra point lights;
- geometry: procedural shapes from ``trimesh.creation`` or meshes from a folder, placed near the
  camera's target, optionally moving (object motion for temporal sequences);
- camera: a random viewpoint around the scene's own camera, or a Catmull-Rom spline path through
  random control points (one keyframe per frame).
"""

from __future__ import annotations

import copy
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import SceneError
from ..scene.meshio import MESH_SUFFIXES
from ..scene.model import GLASS_KINDS, Camera, DirectionalLight, Material, Mesh, PointLight, Scene

# Shapes the training views use; HELD_OUT_SHAPES appear only in test views, so the benchmark sees
# geometry the networks never saw.
TRAINING_SHAPES = ("box", "icosphere", "capsule", "cylinder", "cone")
HELD_OUT_SHAPES = ("torus",)


def make_shape(kind: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices, faces, vertex normals) of a unit-sized procedural shape centred on the origin."""
    import trimesh.creation as creation

    builders = {
        "box": lambda: creation.box(extents=(1.0, 1.0, 1.0)),
        "icosphere": lambda: creation.icosphere(subdivisions=2, radius=0.5),
        "capsule": lambda: creation.capsule(height=0.5, radius=0.25, count=(16, 16)),
        "cylinder": lambda: creation.cylinder(radius=0.4, height=1.0, sections=24),
        "cone": lambda: creation.cone(radius=0.5, height=1.0, sections=24),
        "torus": lambda: creation.torus(major_radius=0.35, minor_radius=0.15, major_sections=32,
                                        minor_sections=16),
    }
    if kind not in builders:
        raise ValueError(f"unknown procedural shape {kind!r}; expected one of {sorted(builders)}")
    mesh = builders[kind]()
    return normalized(mesh)


def load_mesh_folder(folder: str | Path) -> list[Path]:
    """The mesh files of ``folder`` (sorted, so view seeds map to the same meshes on every machine)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise SceneError(f"{folder}: not a folder of mesh files")
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in MESH_SUFFIXES)


def load_mesh_file(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    import trimesh

    try:
        mesh = trimesh.load(path, force="mesh", process=True)
    except Exception as err:  # trimesh raises many types for unreadable files
        raise SceneError(f"{path}: cannot load mesh ({err})") from None
    if len(mesh.faces) == 0:
        raise SceneError(f"{path}: mesh has no triangles")
    return normalized(mesh)


def normalized(mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centre on the origin and scale the largest extent to 1."""
    vertices = np.asarray(mesh.vertices, np.float64)
    lo, hi = vertices.min(0), vertices.max(0)
    vertices = (vertices - 0.5 * (lo + hi)) / max(float((hi - lo).max()), 1e-9)
    return (vertices.astype(np.float32), np.asarray(mesh.faces, np.uint32),
            np.asarray(mesh.vertex_normals, np.float32))


def scene_bounds(scene: Scene, frame: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """World-space axis-aligned bounds of every mesh at ``frame``."""
    corners = []
    for mesh in scene.meshes:
        m = mesh.transform_at(frame)
        world = mesh.vertices @ m[:3, :3].T + m[:3, 3]
        corners += [world.min(0), world.max(0)]
    if not corners:
        c = scene.camera.target
        return c - 1.0, c + 1.0
    return np.min(corners, 0), np.max(corners, 0)


def blackbody_tint(kelvin: float) -> np.ndarray:
    """Approximate linear-RGB colour of a black body (Tanner Helland's fit), normalized to max 1."""
    t = kelvin / 100.0
    r = 255.0 if t <= 66 else 329.7 * (t - 60) ** -0.1332
    g = 99.47 * np.log(t) - 161.12 if t <= 66 else 288.12 * (t - 60) ** -0.0755
    b = 255.0 if t >= 66 else (0.0 if t <= 19 else 138.52 * np.log(t - 10) - 305.04)
    srgb = np.clip(np.array([r, g, b]) / 255.0, 0.0, 1.0)
    linear = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    return (linear / linear.max()).astype(np.float32)


def randomize_materials(scene: Scene, rng: np.random.Generator) -> None:
    """Jitter every non-emissive material in place: reflectance, roughness (a thin pane stays smooth) and a glass's
    IOR; the rest (a glass's tint and absorption, a metal's index) kept."""
    for name, mat in list(scene.materials.items()):
        if mat.is_emissive:
            continue
        tint = rng.uniform(0.6, 1.4, 3) * rng.uniform(0.7, 1.2)
        reflectance = np.clip(mat.reflectance * tint, 0.02, 0.95)
        # (drawn only where they were before thin panes, so a seed's views stay what they were)
        roughness = float(rng.uniform(0.02, 0.6)) if mat.kind != "diffuse" else mat.roughness
        ior = float(rng.uniform(1.3, 1.8)) if mat.kind in GLASS_KINDS else mat.ior
        scene.materials[name] = replace(mat, reflectance=reflectance, ior=ior,
                                        roughness=0.0 if mat.kind == "thin_dielectric" else roughness)


def random_material(rng: np.random.Generator) -> Material:
    kind = rng.choice(["diffuse", "diffuse", "conductor", "dielectric"])
    reflectance = rng.uniform(0.1, 0.9, 3)
    if kind == "conductor":
        return Material("conductor", reflectance, roughness=float(rng.uniform(0.05, 0.5)),
                        eta=rng.uniform(0.2, 1.5, 3), k=rng.uniform(2.0, 4.0, 3))
    if kind == "dielectric":
        return Material("dielectric", np.ones(3), roughness=float(rng.choice([0.0, rng.uniform(0.05, 0.3)])),
                        ior=float(rng.uniform(1.3, 1.8)))
    return Material("diffuse", reflectance)


def randomize_lighting(scene: Scene, rng: np.random.Generator) -> None:
    """Scale emitters, re-aim and re-colour directional lights (sun), maybe add point lights."""
    scale = float(np.exp(rng.uniform(np.log(0.4), np.log(2.5))))
    for name, mat in list(scene.materials.items()):
        if mat.is_emissive:
            scene.materials[name] = Material(mat.kind, mat.reflectance, mat.roughness, mat.ior, mat.eta,
                                             mat.k, mat.emission * scale)
    lights = []
    for light in scene.lights:
        if isinstance(light, DirectionalLight):
            elevation = np.radians(rng.uniform(15, 75))
            azimuth = rng.uniform(0, 2 * np.pi)
            toward_sun = np.array([np.cos(elevation) * np.cos(azimuth), np.sin(elevation),
                                   np.cos(elevation) * np.sin(azimuth)])
            strength = float(np.max(light.irradiance)) * scale
            lights.append(DirectionalLight((-toward_sun).astype(np.float32),
                                           blackbody_tint(rng.uniform(3500, 7500)) * strength))
        else:
            lights.append(light.scaled(scale))   # a spot stays a spot
    lo, hi = scene_bounds(scene)
    extent = float(np.max(hi - lo))
    for _ in range(int(rng.integers(0, 3))):
        position = rng.uniform(lo + 0.2 * (hi - lo), hi - 0.1 * (hi - lo)).astype(np.float32)
        power = extent ** 2 * float(rng.uniform(0.3, 2.0))
        lights.append(PointLight(position, blackbody_tint(rng.uniform(2700, 9000)) * power))
    scene.lights = lights


def add_objects(scene: Scene, rng: np.random.Generator, shapes: tuple[str, ...], mesh_files: list[Path],
                count: int, frames: int) -> None:
    """Place ``count`` objects near the camera target; in sequences each drifts linearly over ``frames``."""
    lo, hi = scene_bounds(scene)
    extent = float(np.max(hi - lo))
    target = scene.camera.target.astype(np.float64)
    for i in range(count):
        if mesh_files and rng.uniform() < 0.5:
            path = mesh_files[int(rng.integers(len(mesh_files)))]
            vertices, faces, normals = load_mesh_file(path)
            label = path.stem
        else:
            label = str(rng.choice(shapes))
            vertices, faces, normals = make_shape(label)
        size = extent * float(rng.uniform(0.12, 0.3))
        centre = target + rng.uniform(-0.25, 0.25, 3) * extent
        centre = np.clip(centre, lo + 0.5 * size, hi - 0.5 * size)
        angle = rng.uniform(0, 2 * np.pi)
        c, s = np.cos(angle), np.sin(angle)
        rotation = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
        transform = np.eye(4)
        transform[:3, :3] = rotation * size
        transform[:3, 3] = centre
        keyframes = {}
        if frames > 1:
            velocity = rng.uniform(-1, 1, 3) * extent * 0.02
            for f in range(frames):
                moved = transform.copy()
                moved[:3, 3] += velocity * f
                keyframes[f] = moved.astype(np.float32)
        material_name = f"dataset_object_{i}"
        scene.materials[material_name] = random_material(rng)
        scene.meshes.append(Mesh(f"{label}_{i}", vertices, faces, material_name, normals,
                                 transform.astype(np.float32), keyframes))


def _jittered_camera(base: Camera, rng: np.random.Generator, amount: float) -> Camera:
    offset = base.origin - base.target
    distance = float(np.linalg.norm(offset))
    direction = offset / distance + rng.normal(0, amount, 3)
    direction /= np.linalg.norm(direction)
    origin = base.target + direction * distance * float(rng.uniform(0.75, 1.15))
    target = base.target + rng.normal(0, amount * 0.5 * distance, 3)
    fov = float(np.clip(base.fov * rng.uniform(0.8, 1.2), 10.0, 100.0))
    # a lens keeps its aperture and focuses on the new target
    return Camera(origin.astype(np.float32), target.astype(np.float32), base.up, fov, base.fov_axis,
                  base.aperture_radius)


def catmull_rom(points: np.ndarray, samples: int) -> np.ndarray:
    """``samples`` points along the uniform Catmull-Rom spline through ``points`` (K, D), K ≥ 2."""
    padded = np.concatenate([points[:1], points, points[-1:]])
    segments = len(points) - 1
    result = []
    for t in np.linspace(0.0, segments, samples):
        i = min(int(t), segments - 1)
        u = t - i
        p0, p1, p2, p3 = padded[i:i + 4]
        result.append(0.5 * (2 * p1 + (p2 - p0) * u + (2 * p0 - 5 * p1 + 4 * p2 - p3) * u ** 2
                             + (3 * p1 - p0 - 3 * p2 + p3) * u ** 3))
    return np.asarray(result)


def randomize_camera(scene: Scene, rng: np.random.Generator, frames: int, jitter: float = 0.25) -> None:
    """A random viewpoint (stills) or a spline path over ``frames`` (sequences), around the scene camera."""
    base = scene.camera_at(0)
    if frames <= 1:
        scene.camera = _jittered_camera(base, rng, jitter)
        scene.camera_keyframes = {}
        return
    controls = [_jittered_camera(base, rng, jitter) for _ in range(3)]
    origins = catmull_rom(np.array([c.origin for c in controls]), frames)
    targets = catmull_rom(np.array([c.target for c in controls]), frames)
    # Keep per-frame motion small (a few pixels) so consecutive frames overlap as in real use.
    start_o, start_t = origins[0], targets[0]
    origins = start_o + (origins - start_o) * 0.15
    targets = start_t + (targets - start_t) * 0.15
    scene.camera_keyframes = {f: Camera(origins[f].astype(np.float32), targets[f].astype(np.float32),
                                        base.up, controls[0].fov, base.fov_axis, base.aperture_radius)
                              for f in range(frames)}
    scene.camera = scene.camera_keyframes[0]


def vary_scene(scene: Scene, rng: np.random.Generator, *, frames: int = 1, shapes=TRAINING_SHAPES,
               mesh_files: list[Path] = (), max_objects: int = 2) -> Scene:
    """A randomized copy of ``scene`` (materials, lighting, objects, camera), ``frames`` long."""
    varied = copy.deepcopy(scene)
    randomize_materials(varied, rng)
    randomize_lighting(varied, rng)
    add_objects(varied, rng, tuple(shapes), list(mesh_files), int(rng.integers(1, max_objects + 1)), frames)
    randomize_camera(varied, rng, frames)
    varied.frame_count = max(frames, 1)
    return varied
