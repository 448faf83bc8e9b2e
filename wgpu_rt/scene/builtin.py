"""The built-in scenes, by name (``BUILTIN_SCENES``; ``builtin_scene(name, mesh=None)`` builds one).

- ``cornell``: Mitsuba 3's ``mi.cornell_box()`` exactly: same rectangles and cubes, transforms,
  reflectances, one-sided emitter (radiance 18.387, 13.9873, 6.75357) over a white diffuse BSDF, camera.
- ``cornell-glossy``: the same box; the tall box is rough gold (GGX, alpha 0.2) and the short box is
  replaced by a glass sphere (IOR 1.5).
- ``sun-room``: a dark room lit by one tiny, very bright source (radiance 5·10⁴), so images span about
  nine orders of magnitude: a hot spot, a sunlit floor, and a box that opens away from the light, whose
  inside sees light only after several dark bounces (~10⁻⁴).
- ``mesh``: any mesh file (``mesh=PATH``), centred, scaled to fit and set on the floor of a lit room.
- ``moving``: the Cornell box over 16 frames: the camera orbits slightly and the short box slides and
  turns, for temporal filtering and motion vectors.
- ``painted``: the Cornell box with textures as vertex colours (none in any training world): a checkered
  floor, a blotched back wall, a striped and a marbled sphere in place of the boxes.
- ``textured``: the Cornell box with colour textures detailed to the pixel: tiles with thin grout on the
  floor, stripes over blotches on the back wall, wood grain on the two boxes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import SceneError
from .file_materials import GLTF_SUFFIXES, placed_absorption
from .gltf_scene import node_animation, placement_problem
from .meshio import load_mesh_file
from .model import Camera, Material, Mesh, Scene
from .primitives import primitive, primitive_uvs
from .transforms import compose, rotate, scale, transform_points, translate

CORNELL_WHITE = (0.885809, 0.698859, 0.666422)
CORNELL_GREEN = (0.105421, 0.37798, 0.076425)
CORNELL_RED = (0.570068, 0.0430135, 0.0443706)
CORNELL_LIGHT_RADIANCE = (18.387, 13.9873, 6.75357)
GOLD_ETA = (0.143119, 0.374957, 1.44248)     # Mitsuba's 'Au' conductor data at its RGB wavelengths
GOLD_K = (3.98316, 2.38572, 1.60322)


def shape(name: str, kind: str, material: str, transform) -> Mesh:
    """A built-in primitive (see primitives.py) placed by ``transform``."""
    vertices, faces, normals = primitive(kind)
    return Mesh(name, vertices, faces, material, normals=normals, transform=np.asarray(transform, np.float32))


def _cornell_camera() -> Camera:
    return Camera(origin=[0, 0, 3.9], target=[0, 0, 0], up=[0, 1, 0], fov=39.3077, fov_axis="smaller")


def _cornell_room() -> tuple[dict[str, Material], list[Mesh]]:
    """Materials and the six rectangles (light, floor, ceiling, back, side walls) of mi.cornell_box()."""
    materials = {
        "white": Material("diffuse", reflectance=CORNELL_WHITE),
        "green": Material("diffuse", reflectance=CORNELL_GREEN),
        "red": Material("diffuse", reflectance=CORNELL_RED),
        "light": Material("diffuse", reflectance=CORNELL_WHITE, emission=CORNELL_LIGHT_RADIANCE),
    }
    meshes = [
        shape("light", "rectangle", "light",
              compose(translate([0, 0.99, 0.01]), rotate([1, 0, 0], 90), scale([0.23, 0.19, 0.19]))),
        shape("floor", "rectangle", "white", compose(translate([0, -1, 0]), rotate([1, 0, 0], -90))),
        shape("ceiling", "rectangle", "white", compose(translate([0, 1, 0]), rotate([1, 0, 0], 90))),
        shape("back", "rectangle", "white", compose(translate([0, 0, -1]))),
        shape("green-wall", "rectangle", "green", compose(translate([1, 0, 0]), rotate([0, 1, 0], -90))),
        shape("red-wall", "rectangle", "red", compose(translate([-1, 0, 0]), rotate([0, 1, 0], 90))),
    ]
    return materials, meshes


SMALL_BOX = compose(translate([0.335, -0.7, 0.38]), rotate([0, 1, 0], -17), scale(0.3))
LARGE_BOX = compose(translate([-0.33, -0.4, -0.28]), rotate([0, 1, 0], 18.25), scale([0.3, 0.61, 0.3]))


def cornell() -> Scene:
    materials, meshes = _cornell_room()
    meshes += [shape("small-box", "cube", "white", SMALL_BOX), shape("large-box", "cube", "white", LARGE_BOX)]
    return Scene(_cornell_camera(), meshes, materials, name="cornell")


def cornell_glossy() -> Scene:
    materials, meshes = _cornell_room()
    materials["gold"] = Material("conductor", reflectance=1.0, roughness=0.2, eta=GOLD_ETA, k=GOLD_K)
    materials["glass"] = Material("dielectric", ior=1.5, roughness=0.0)
    meshes += [shape("glass-sphere", "sphere", "glass", compose(translate([0.335, -0.67, 0.38]), scale(0.33))),
               shape("gold-box", "cube", "gold", LARGE_BOX)]
    return Scene(_cornell_camera(), meshes, materials, name="cornell-glossy")


def sun_room() -> Scene:
    materials = {
        "wall": Material("diffuse", reflectance=0.05),
        "floor": Material("diffuse", reflectance=0.6),
        "box": Material("diffuse", reflectance=0.05),
        "sun": Material("diffuse", reflectance=0.0, emission=5e4),
    }
    meshes = [
        # A 2 cm square sun near the ceiling's left corner, facing down and tilted toward the room.
        shape("sun", "rectangle", "sun",
              compose(translate([-0.85, 0.9, 0.2]), rotate([0, 0, 1], -35), rotate([1, 0, 0], 90), scale(0.01))),
        shape("floor", "rectangle", "floor", compose(translate([0, -1, 0]), rotate([1, 0, 0], -90))),
        shape("ceiling", "rectangle", "wall", compose(translate([0, 1, 0]), rotate([1, 0, 0], 90))),
        shape("back", "rectangle", "wall", compose(translate([0, 0, -1]))),
        shape("right-wall", "rectangle", "wall", compose(translate([1, 0, 0]), rotate([0, 1, 0], -90))),
        shape("left-wall", "rectangle", "wall", compose(translate([-1, 0, 0]), rotate([0, 1, 0], 90))),
        shape("pillar", "cube", "box", compose(translate([-0.2, -0.45, -0.1]), scale([0.12, 0.55, 0.12]))),
    ]
    # An open crate: four sides and a bottom, its opening toward the camera and away from the sun.
    crate = [("crate-bottom", [0.5, -0.99, 0.25], [1, 0, 0], -90), ("crate-top", [0.5, -0.59, 0.25], [1, 0, 0], 90),
             ("crate-left", [0.3, -0.79, 0.25], [0, 1, 0], 90), ("crate-right", [0.7, -0.79, 0.25], [0, 1, 0], -90),
             ("crate-back", [0.5, -0.79, 0.05], [0, 1, 0], 0)]
    for name, position, axis, degrees in crate:
        meshes.append(shape(name, "rectangle", "box",
                            compose(translate(position), rotate(axis, degrees), scale(0.2))))
    return Scene(_cornell_camera(), meshes, materials, name="sun-room")


def mesh_room(path, animation: str | None = None) -> Scene:
    """The Cornell room (without its boxes) with the mesh at ``path`` standing on the floor (fitted by its rest
    pose), in the file's own materials where it has them (glTF's, an OBJ file's MTL), grey clay elsewhere; a glTF
    file's animation plays (``animation`` picks one), its skins and morph targets bending its meshes
    (``gltf_scene.node_animation``)."""
    if path is None:
        raise SceneError("the 'mesh' scene needs a mesh file: load_scene('mesh', mesh=PATH) or --mesh PATH")
    materials, meshes = _cornell_room()
    materials["clay"] = Material("diffuse", reflectance=(0.7, 0.7, 0.7))
    own: dict = {}
    loaded = load_mesh_file(Path(path), material="clay", materials=own)
    frames, moves = 1, [None] * len(loaded)
    if Path(path).suffix.lower() in GLTF_SUFFIXES:      # its animation plays (skins and morph targets bend in place)
        frames, moves, _ = node_animation(path, loaded, animation=animation)
    placed = [transform_points(m.transform, m.vertices) for m in loaded]   # a file's nodes place its parts
    lo = np.min([v.min(axis=0) for v in placed], axis=0).astype(np.float64)
    hi = np.max([v.max(axis=0) for v in placed], axis=0).astype(np.float64)
    size = float(np.max(hi - lo))
    if not size > 0:
        raise SceneError(f"{path}: the mesh has no extent (all vertices coincide)")
    fit = 1.2 / size
    center = (lo + hi) / 2
    place = compose(translate([0, -1 + fit * (hi[1] - lo[1]) / 2, 0]), scale(fit), translate(-center))
    for item, keys in zip(loaded, moves):
        item.transform = compose(place, item.transform)
        item.keyframes = {frame: compose(place, world).astype(np.float32) for frame, world in (keys or {}).items()}
        if problem := placement_problem(item):
            raise SceneError(f"{path}: {problem}")
    materials.update(placed_absorption(own, place))
    return Scene(_cornell_camera(), meshes + loaded, materials, frame_count=frames, name=f"mesh:{Path(path).name}")


MOVING_FRAMES = 16


def moving() -> Scene:
    scene = cornell()
    scene.name = "moving"
    scene.frame_count = MOVING_FRAMES
    for frame in range(MOVING_FRAMES):
        phase = frame / (MOVING_FRAMES - 1)
        angle = np.radians(-6 + 12 * phase)
        origin = [3.9 * np.sin(angle), 0.05 * np.sin(2 * np.pi * phase), 3.9 * np.cos(angle)]
        scene.camera_keyframes[frame] = Camera(origin=origin, target=[0, 0, 0], up=[0, 1, 0], fov=39.3077)
    small_box = next(m for m in scene.meshes if m.name == "small-box")
    for frame in range(MOVING_FRAMES):
        phase = frame / (MOVING_FRAMES - 1)
        small_box.keyframes[frame] = compose(
            translate([0.335 - 0.25 * phase, -0.7, 0.38 + 0.1 * phase]), rotate([0, 1, 0], -17 + 40 * phase),
            scale(0.3))
    return scene


def _grid(cells: int) -> tuple[np.ndarray, np.ndarray]:
    """The rectangle primitive ([-1, 1]² at z = 0, facing +z) as cells × cells quads."""
    u, v = np.meshgrid(np.linspace(-1, 1, cells + 1), np.linspace(-1, 1, cells + 1))
    vertices = np.stack([u.ravel(), v.ravel(), np.zeros(u.size)], -1).astype(np.float32)
    index = np.arange((cells + 1) ** 2).reshape(cells + 1, cells + 1)
    a, b, c, d = index[:-1, :-1].ravel(), index[:-1, 1:].ravel(), index[1:, 1:].ravel(), index[1:, :-1].ravel()
    return vertices, np.concatenate([np.stack([a, b, c], -1), np.stack([a, c, d], -1)]).astype(np.uint32)


def sine_pattern(points: np.ndarray, octaves) -> np.ndarray:
    """A smooth pattern of (N, 3) ``points``: over ``octaves`` [(frequency, (phase x, phase y, phase z)), …], the
    sum of the products of sines of the coordinates (frequencies along y and z 1.3 and 0.7 times x's), the k-th
    octave weighed 1 / (k + 1)."""
    total = np.zeros(len(points))
    for octave, (f, (phase_x, phase_y, phase_z)) in enumerate(octaves):
        total += (np.sin(f * points[:, 0] + phase_x) * np.sin(1.3 * f * points[:, 1] + phase_y)
                  * np.sin(0.7 * f * points[:, 2] + phase_z)) / (octave + 1)
    return total


def _waves(points: np.ndarray, frequency: float) -> np.ndarray:
    """``painted``'s pattern, in about [-1.3, 1.3]: four octaves of ``sine_pattern`` with fixed phases."""
    return sine_pattern(points, [(frequency * scale_, (phase, 2 * phase, phase))
                                 for scale_, phase in [(1.0, 0.3), (2.1, 1.7), (4.3, 2.9), (8.7, 0.8)]])


def mix_colors(t: np.ndarray, one, other) -> np.ndarray:
    """(N,) weights → (N, 3) colours: ``one`` where t is 1, ``other`` where 0 (t clipped to [0, 1]), float32."""
    t = np.clip(t, 0.0, 1.0)[:, None]
    return (t * np.asarray(one) + (1 - t) * np.asarray(other)).astype(np.float32)


def painted() -> Scene:
    import trimesh

    materials, meshes = _cornell_room()
    materials["white-base"] = Material("diffuse", reflectance=(1.0, 1.0, 1.0))
    for mesh in meshes:
        if mesh.name in ("floor", "back"):
            mesh.vertices, mesh.faces = _grid(192 if mesh.name == "floor" else 160)
            mesh.material = "white-base"
            if mesh.name == "floor":
                cell = (np.floor(mesh.vertices[:, 0] * 6) + np.floor(mesh.vertices[:, 1] * 6)) % 2
                mesh.colors = mix_colors(cell, (0.85, 0.8, 0.7), (0.12, 0.16, 0.3))
            else:
                mesh.colors = mix_colors(0.5 + 0.6 * _waves(mesh.vertices * 2.5, 3.0), (0.8, 0.65, 0.35),
                                         (0.18, 0.4, 0.22))
    sphere = trimesh.creation.icosphere(subdivisions=5)
    vertices, faces = np.asarray(sphere.vertices, np.float32), np.asarray(sphere.faces, np.uint32)
    normals = np.asarray(sphere.vertex_normals, np.float32)
    stripes = (np.floor((vertices[:, 1] + 0.5 * vertices[:, 0]) * 5) % 2)
    marble = 0.5 + 0.5 * np.sin(4.5 * vertices[:, 0] + 4 * _waves(vertices, 2.0))
    meshes += [Mesh("striped-sphere", vertices, faces, "white-base", normals,
                    compose(translate([0.4, -0.65, 0.3]), scale(0.35)),
                    colors=mix_colors(stripes, (0.75, 0.08, 0.08), (0.85, 0.85, 0.8))),
               Mesh("marbled-sphere", vertices, faces, "white-base", normals,
                    compose(translate([-0.4, -0.55, -0.3]), scale(0.45)),
                    colors=mix_colors(marble, (0.8, 0.8, 0.85), (0.08, 0.08, 0.12)))]
    return Scene(_cornell_camera(), meshes, materials, name="painted")


def _image(t: np.ndarray, one, other) -> np.ndarray:
    """(H, W) weights → an (H, W, 3) uint8 sRGB image: linear colour ``one`` where t is 1, ``other`` where 0."""
    from .model import srgb8

    return srgb8(mix_colors(t.ravel(), one, other)).reshape(*t.shape, 3)


def textured() -> Scene:
    """The Cornell box with colour textures detailed down to the pixel (at 512², the default render size's
    scale): tiles with thin grout on the floor, fine stripes over blotches on the back wall, wood grain on
    the boxes (each face the whole image, upright: primitives.primitive_uvs)."""
    scene = cornell()
    scene.materials["white-base"] = Material("diffuse", reflectance=(1.0, 1.0, 1.0))
    rows, columns = np.meshgrid(np.arange(512) + 0.5, np.arange(512) + 0.5, indexing="ij")
    points = np.stack([columns / 512, rows / 512, np.zeros_like(rows)], -1).reshape(-1, 3)
    tile = np.minimum(columns % 128, rows % 128)
    floor = _image((tile >= 3) * (0.75 + 0.25 * np.sin(0.7 * np.floor(columns / 128) + np.floor(rows / 128))),
                   (0.8, 0.72, 0.6), (0.05, 0.05, 0.06))
    blotches = 0.5 + 0.6 * _waves(points * 6, 3.0).reshape(rows.shape)
    stripes = (columns % 16 < 2) * 0.35
    wall = _image(np.clip(blotches - stripes, 0, 1), (0.75, 0.6, 0.35), (0.1, 0.25, 0.3))
    grain = 0.5 + 0.5 * np.sin(columns / 512 * 60 + 3 * _waves(points * 4, 2.5).reshape(rows.shape))
    wood = _image(grain, (0.75, 0.5, 0.28), (0.42, 0.24, 0.1))
    for mesh in scene.meshes:
        if mesh.name in ("floor", "back"):
            mesh.material = "white-base"
            mesh.texture = floor if mesh.name == "floor" else wall
            mesh.uvs = primitive_uvs("rectangle") * (3.0 if mesh.name == "floor" else 1.0)
        elif mesh.name.endswith("box"):
            mesh.material = "white-base"
            mesh.texture, mesh.uvs = wood, primitive_uvs("cube")
    scene.name = "textured"
    return scene


BUILTIN_SCENES = {"cornell": cornell, "cornell-glossy": cornell_glossy, "sun-room": sun_room,
                  "mesh": mesh_room, "moving": moving, "painted": painted, "textured": textured}


def builtin_scene(name: str, mesh=None, animation: str | None = None) -> Scene:
    """The built-in scene ``name``; ``mesh`` is the mesh file of the 'mesh' scene (``animation``: which of a glTF
    file's animations it plays)."""
    if name not in BUILTIN_SCENES:
        raise SceneError(f"unknown built-in scene {name!r}; expected one of {sorted(BUILTIN_SCENES)}")
    return mesh_room(mesh, animation) if name == "mesh" else BUILTIN_SCENES[name]()
