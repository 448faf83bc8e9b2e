"""A glTF file that brings its own camera as a whole scene: its meshes where its nodes place them, in its own
materials, seen through its first camera and lit by its ``KHR_lights_punctual`` lights.

A file without a camera stays an object to look at: ``load_scene`` sets it in the built-in ``mesh`` room. With one,
nothing is added or moved, as a scene exported from Blender expects:

- the camera: the first node of the default scene (depth first, in file order) that has a camera, or the one picked
  by its camera's index or name or its node's name (``--camera``); a ``perspective`` one;
  glTF's camera looks down its node's −z with +y up; ``yfov`` is the vertical field of view (the render's own size
  sets the aspect ratio, not ``aspectRatio``). An orthographic camera is refused by name.
- lights: glTF's are photometric (candela for point and spot lights, lux for directional ones) and the tracer's are
  radiometric, so each is divided by 683 lm/W (the luminous efficacy of 555 nm light; Blender's importer does the
  same), its ``color`` a per-channel factor. A spot's cone has glTF's outer angle as its cut-off and its inner angle
  as its beam width (the fall-off between is Mitsuba's, linear in angle, where glTF suggests one in the cosine); a
  directional or spot light points down its node's −z. ``range`` is not read (light falls off with distance
  squared, as glTF asks where it is absent).
- a file with no light of its own (no punctual light, no emissive material) is lit by a white sky of radiance 1, so
  that it does not render black; one with lights has a black background (glTF has no environment).
- animations: the nodes' translation, rotation and scale channels (``gltf_animation``) move the meshes and the camera,
  and the lights, a keyframe at every frame (FRAME_RATE a second to the last key); each mesh trimesh reads is the
  node whose world matrix at rest and vertex count are its (``_mesh_nodes``). Skins and morph targets bend the
  meshes (``gltf_skins``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from ..errors import SceneError
from .file_materials import FieldReader, gltf_json, shown
from .gltf_animation import FRAME_RATE, GltfBuffers, frame_count, local_matrix, node_primitives, read_animations
from .gltf_skins import Bending, bending, bends
from .meshio import load_mesh_file
from .model import Camera, DirectionalLight, Material, PointLight, Scene, SpotLight
from .transforms import WORLD_LIMIT, float32_placement

LUMENS_PER_WATT = 683.0     # glTF's candela and lux over the tracer's W·sr⁻¹ and W·m⁻²
UNLIT_SKY = 1.0             # the background's radiance for a file that brings no light
MOST_BENT_BYTES = 2 ** 30   # the bent meshes' vertices and normals held for all frames at most


def _node_matrix(node: dict, where: str) -> np.ndarray:
    """A node's local transform: its ``matrix`` (column-major), else translation · rotation · scale."""
    fields = FieldReader(where, node)
    if "matrix" in node:
        return fields.numbers("matrix", None, length=16, low=-np.inf, high=np.inf).reshape(4, 4).T
    translation = fields.numbers("translation", [0.0, 0.0, 0.0], length=3, low=-np.inf, high=np.inf)
    x, y, z, w = fields.numbers("rotation", [0.0, 0.0, 0.0, 1.0], length=4, low=-1.0, high=1.0)
    if not np.linalg.norm([x, y, z, w]) > 0:
        fields.fail(f"rotation must be a unit quaternion, got {[x, y, z, w]}")
    scale = fields.numbers("scale", [1.0, 1.0, 1.0], length=3, low=-np.inf, high=np.inf)
    matrix = trimesh.transformations.quaternion_matrix([w, x, y, z])    # (w first; normalized there)
    matrix[:3, :3] *= scale
    matrix[:3, 3] = translation
    return matrix


def _entry(entries: list, number, where: str, what: str) -> dict:
    """``entries[number]``: a SceneError naming ``where`` unless ``number`` picks one of the file's ``what``."""
    entries = entries if isinstance(entries, list) else []
    if not (isinstance(number, int) and 0 <= number < len(entries)) or not isinstance(entries[number], dict):
        raise SceneError(f"{where}: not one of the file's {len(entries)} {what}")
    return entries[number]


def _field(container: dict, key: str, kind: type, where: str):
    """``container[key]``, of type ``kind`` (an empty one where absent or null; a SceneError naming ``where``
    otherwise)."""
    value = container.get(key)
    if value is None:
        return kind()
    if not isinstance(value, kind):
        raise SceneError(f"{where}: {key} must be {'an object' if kind is dict else 'a list'}, got {shown(value)}")
    return value


def _placed_nodes(tree: dict, path: Path, channels: dict | None = None,
                  t: float = 0.0) -> list[tuple[int, np.ndarray]]:
    """(node index, world matrix) of every node of the file's default scene, depth first in file order (a node
    reached twice, or a cycle, is a SceneError); with ``channels`` (``gltf_animation.read_animations``) as they
    animate the nodes at time ``t``."""
    nodes = tree.get("nodes") or []
    if not isinstance(nodes, list):
        raise SceneError(f"{path}: the glTF file's nodes are not a list")
    scenes = tree.get("scenes")
    if scenes:
        chosen = tree.get("scene", 0)
        roots = _field(_entry(scenes, chosen, f"{path}: scene {chosen!r}", "scenes"), "nodes", list,
                       f"{path}: scene {chosen!r}")
    else:
        children = {child for node in nodes if isinstance(node, dict) and isinstance(node.get("children"), list)
                    for child in node["children"] if isinstance(child, int)}
        roots = [i for i in range(len(nodes)) if i not in children]
    placed, seen = [], set()
    stack = [(index, np.eye(4)) for index in reversed(roots)]
    while stack:
        index, parent = stack.pop()
        _entry(nodes, index, f"{path}: node {index!r}", "nodes")
        if index in seen:
            raise SceneError(f"{path}: node {index} is reached twice in the scene's hierarchy")
        seen.add(index)
        local = _node_matrix(nodes[index], f"{path}: node {index}")
        if channels:
            local = local_matrix(nodes[index], channels.get(index, []), t, local, f"{path}: node {index}")
        world = parent @ local
        placed.append((index, world))
        children = _field(nodes[index], "children", list, f"{path}: node {index}")
        stack.extend((child, world) for child in reversed(children))
    return placed


def _aimed(world: np.ndarray, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A node's position and its −z and +y directions in the world (a SceneError for a singular placement)."""
    if not np.all(np.abs(world) <= np.finfo(np.float32).max) or abs(np.linalg.det(world[:3, :3])) < 1e-12:
        raise SceneError(f"{where}: its node's transform is singular or not finite in float32")
    if np.any(np.abs(world[:3, 3]) > WORLD_LIMIT):
        raise SceneError(f"{where}: placed beyond ±{WORLD_LIMIT:g} (the tracer's float32 range)")
    forward, up = world[:3, :3] @ [0.0, 0.0, -1.0], world[:3, :3] @ [0.0, 1.0, 0.0]
    return world[:3, 3], forward / np.linalg.norm(forward), up / np.linalg.norm(up)


def _camera_node(tree: dict, placed: list, path: Path, choice: str | None) -> int | None:
    """The node whose camera the scene is seen through: the first placed node with a camera, or with ``choice`` the
    one whose camera's index or name, or node's name, it is (a SceneError listing them where none is); None where no
    node has a camera."""
    cameras, nodes = tree.get("cameras") or [], tree["nodes"]
    held = [index for index, _ in placed if nodes[index].get("camera") is not None]
    if choice is None or not held:
        return held[0] if held else None
    for index in held:
        number = nodes[index]["camera"]
        entry = _entry(cameras, number, f"{path}: camera {number!r} (node {index})", "cameras")
        if choice in (str(number), entry.get("name"), nodes[index].get("name")):
            return index
    names = ", ".join(f"{nodes[i]['camera']} ({nodes[i].get('name') or f'node {i}'})" for i in held)
    raise SceneError(f"{path}: no camera {choice!r}; its cameras: {names}")


def _camera(tree: dict, placed: list, path: Path, choice: str | None = None) -> Camera | None:
    """The view through the camera ``_camera_node`` picks (None where no node has a camera)."""
    index = _camera_node(tree, placed, path, choice)
    if index is None:
        return None
    number = tree["nodes"][index].get("camera")
    where = f"{path}: camera {number!r} (node {index})"
    entry = _entry(tree.get("cameras"), number, where, "cameras")
    if entry.get("type") != "perspective":
        raise SceneError(f"{where}: a {entry.get('type')!r} camera; only perspective cameras are rendered")
    perspective = FieldReader(where, entry.get("perspective") or {})
    if "yfov" not in perspective.data:
        perspective.fail("a perspective camera without a yfov")
    yfov = perspective.numbers("yfov", None, high=np.pi)
    origin, forward, up = _aimed(dict(placed)[index], where)
    try:
        return Camera(origin, origin + forward, up=up, fov=float(np.degrees(yfov)), fov_axis="y")
    except ValueError as err:
        raise SceneError(f"{where}: {err}") from err


def _lights(tree: dict, placed: list, path: Path) -> list:
    """The placed KHR_lights_punctual lights, in the tracer's units."""
    extension = _field(_field(tree, "extensions", dict, str(path)), "KHR_lights_punctual", dict, f"{path}: extensions")
    catalogue = _field(extension, "lights", list, f"{path}: KHR_lights_punctual")
    lights = []
    for index, world in placed:
        where = f"{path}: node {index}"
        own = _field(_field(tree["nodes"][index], "extensions", dict, where), "KHR_lights_punctual", dict, where)
        number = own.get("light")
        if number is None:
            continue
        where = f"{path}: light {number!r} (node {index})"
        entry = _entry(catalogue, number, where, "KHR_lights_punctual lights")
        fields = FieldReader(where, entry)
        power = (fields.numbers("color", [1.0, 1.0, 1.0], length=3)
                 * fields.numbers("intensity", 1.0, high=np.inf) / LUMENS_PER_WATT).astype(np.float32)
        kind = entry.get("type")
        position, aim, _ = (vector.astype(np.float32) for vector in _aimed(world, where))
        if kind == "point":
            lights.append(PointLight(position, power))
        elif kind == "directional":
            lights.append(DirectionalLight(aim, power))
        elif kind == "spot":
            cone = FieldReader(where, entry.get("spot") or {})
            outer = cone.numbers("outerConeAngle", np.pi / 4, high=np.pi / 2)
            inner = cone.numbers("innerConeAngle", 0.0, high=np.pi / 2)
            if not 0.0 <= inner < outer:
                raise SceneError(f"{where}: innerConeAngle must be below outerConeAngle, got {inner} and {outer}")
            lights.append(SpotLight(position, power, direction=aim, cutoff_angle=float(np.degrees(outer)),
                                    beam_width=float(np.degrees(inner))))
        else:
            raise SceneError(f"{where}: unknown light type {kind!r} (point, spot or directional)")
    return lights


def _mesh_nodes(buffers: GltfBuffers, placed: list, meshes: list) -> list[int | None]:
    """The node each of ``meshes`` (trimesh's reading of the file, one per placed primitive) stands for: a node
    with a mesh whose world matrix (``placed``, at rest) is the mesh's placement and one of whose primitives has
    as many vertices; among several alike, the ones whose primitive holds the very same vertices, each taken in turn
    (coinciding copies of one mesh). None where none is."""
    tree = buffers.tree
    accessors = tree.get("accessors") or []

    def vertex_counts(node: dict) -> set:
        found = [p.get("attributes") for p in node_primitives(tree, node) if isinstance(p, dict)]
        positions = [a.get("POSITION") for a in found if isinstance(a, dict)]
        return {accessors[a].get("count") for a in positions if isinstance(a, int) and 0 <= a < len(accessors)
                and isinstance(accessors[a], dict)}

    def holds(index: int, vertices: np.ndarray) -> bool:
        return buffers.primitive_holding(node_primitives(tree, tree["nodes"][index]), vertices) is not None

    counts = {index: vertex_counts(tree["nodes"][index]) for index, _ in placed}
    taken: dict[tuple, int] = {}    # the candidates → meshes matched among them so far
    found = []
    for mesh in meshes:
        alike = [index for index, world in placed if len(mesh.vertices) in counts[index]
                 and np.allclose(world, mesh.transform, rtol=1e-5, atol=1e-5)]
        if len(alike) > 1:
            alike = [index for index in alike if holds(index, np.asarray(mesh.vertices, np.float32))] or alike
        turn = taken.get(tuple(alike), 0)
        taken[tuple(alike)] = turn + 1
        found.append(alike[turn % len(alike)] if alike else None)
    return found


def node_animation(path, meshes: list, tree: dict | None = None,
                   animation: str | None = None) -> tuple[int, list[dict | None], list]:
    """A glTF file's node animations as they move ``meshes`` (``load_mesh_file``'s reading of the file): the frame
    count (1 without animations), each mesh's world matrix (float32, in the file's world) at every frame or None where
    its node does not move, and every node's (index, world matrix) at each frame (``_placed_nodes``; none without
    animations; ``animation`` picks the animation played, ``read_animations``). A mesh that a skin or morph targets
    bend (``gltf_skins``) is posed in place: its vertices and normals those of frame 0 and ``vertex_keyframes`` /
    ``normal_keyframes`` where it changes shape; a skinned one lies in the world (identity transform, None among the
    matrices)."""
    path = Path(path)
    tree = gltf_json(path) if tree is None else tree
    channels = read_animations(path, tree, animation)
    rest = _placed_nodes(tree, path)
    frames = frame_count(channels, str(path)) if channels else 1
    poses = [_placed_nodes(tree, path, channels, f / FRAME_RATE) for f in range(frames)] if channels else [rest]
    worlds = [dict(pose) for pose in poses]
    moves, buffers = [], GltfBuffers(path, tree)
    nodes = _mesh_nodes(buffers, rest, meshes)
    bent_bytes = frames * sum(24 * len(mesh.vertices) for mesh, node in zip(meshes, nodes)
                              if node is not None and bends(tree, tree["nodes"][node]))
    if bent_bytes > MOST_BENT_BYTES:
        raise SceneError(f"{path}: its skinned or morphed meshes would take {bent_bytes / 2 ** 30:.1f} GiB over its "
                         f"{frames} frames (a shape a frame; at most {MOST_BENT_BYTES / 2 ** 30:g} GiB are held)")
    for mesh, node in zip(meshes, nodes):
        weights = [channel for channel in channels.get(node, []) if channel.path == "weights"]
        bent = None if node is None else bending(buffers, node, mesh.vertices, mesh.normals, weights, worlds,
                                                 [f / FRAME_RATE for f in range(frames)])
        if bent is not None:
            _pose(mesh, bent)
            if bent.skinned:
                moves.append(None)
                continue
        keys = None if node is None or not channels else {f: worlds[f][node].astype(np.float32)
                                                            for f in range(frames)}
        still = keys is None or all(np.array_equal(matrix, mesh.transform) for matrix in keys.values())
        moves.append(None if still else keys)
    return frames, moves, poses if channels else []


def _pose(mesh, bent: Bending) -> None:
    """Give ``mesh`` the shapes ``bent`` holds (new arrays: another placement of its shape keeps its own)."""
    mesh.vertices = bent.vertices[0]
    if bent.normals is not None:
        mesh.normals = bent.normals[0]
    if any(not np.array_equal(shape, bent.vertices[0]) for shape in bent.vertices[1:]):
        mesh.vertex_keyframes = dict(enumerate(bent.vertices))
        mesh.normal_keyframes = {} if bent.normals is None else dict(enumerate(bent.normals))
    if bent.skinned:
        mesh.transform = np.eye(4, dtype=np.float32)


def placement_problem(mesh) -> str | None:
    """What keeps float32 from holding ``mesh``'s placement and every vertex it places, at rest and at every keyframe
    of its transform or its shape (``transforms.float32_placement``), naming the mesh and frame; None where nothing
    does."""
    frames = sorted({*mesh.keyframes, *mesh.vertex_keyframes})
    for frame in [None, *frames]:
        matrix = mesh.transform if frame is None else mesh.transform_at(frame)
        vertices = mesh.vertices if frame is None else mesh.vertices_at(frame)
        problem = float32_placement(matrix, vertices)[1]
        if problem:
            return f"mesh {mesh.name!r}{'' if frame is None else f' at frame {frame}'}: its placement {problem}"
    return None


def gltf_scene(path, camera: str | None = None, animation: str | None = None) -> Scene | None:
    """The scene of a glTF file with a camera (see the module's doc), seen through its first or the ``camera`` it
    names (an index into the file's cameras, a camera's or a node's name), playing ``animation`` (an index or a
    name; default: ``read_animations``'); None for a file without one."""
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"{path}: mesh file not found")
    tree = gltf_json(path)
    placed = _placed_nodes(tree, path)
    choice = camera
    camera = _camera(tree, placed, path, choice)
    if camera is None:
        return None
    materials = {"clay": Material("diffuse", reflectance=(0.7, 0.7, 0.7))}
    meshes = load_mesh_file(path, material="clay", materials=materials)
    lights = _lights(tree, placed, path)
    lit = bool(lights) or any(materials[mesh.material].is_emissive for mesh in meshes)
    background = np.zeros(3, np.float32) if lit else np.full(3, UNLIT_SKY, np.float32)
    frames, moves, poses = node_animation(path, meshes, tree, animation)
    for mesh, keys in zip(meshes, moves):
        mesh.keyframes = keys or {}
        if problem := placement_problem(mesh):        # as a scene file's placements are checked
            raise SceneError(f"{path}: {problem}")
    posed = [_lights(tree, pose, path) for pose in poses]
    for index, light in enumerate(lights):      # a light on an animated node follows it
        keys = {f: frame_lights[index] for f, frame_lights in enumerate(posed)}
        if any(key.state != light.state for key in keys.values()):
            light.keyframes = keys
    cameras = {f: _camera(tree, pose, path, choice) for f, pose in enumerate(poses)}
    if all(c.origin.tobytes() + c.target.tobytes() + c.up.tobytes()
           == camera.origin.tobytes() + camera.target.tobytes() + camera.up.tobytes() for c in cameras.values()):
        cameras = {}
    return Scene(cameras.get(0, camera), meshes, materials, lights=lights, background=background,
                 camera_keyframes=cameras, frame_count=frames, name=f"gltf:{path.name}")
