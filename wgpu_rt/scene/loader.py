"""Scene files (JSON or TOML, same structure; see docs/scene-format.md) → ``Scene``.

Parsing is strict: every key is checked against the format, every value's type and shape is checked,
and any problem raises a SceneError that names the file and the field path, e.g.
``scene.json: meshes[2].material: unknown material 'gold'``.
"""

from __future__ import annotations

import itertools
import json
import reprlib
import tomllib
from functools import partial
from pathlib import Path

import numpy as np

from ..errors import SceneError
from .file_materials import GLTF_SUFFIXES, placed_absorption
from .gltf_scene import node_animation, placement_problem
from .meshio import load_mesh_file, read_environment_image, read_texture_image, with_cutout
from .model import (ALPHA_MODES, FOV_AXES, MATERIAL_KINDS, Camera, DirectionalLight, Material, Mesh, PointLight,
                    Scene, SpotLight)
from .primitives import PRIMITIVES, primitive, primitive_uvs
from .transforms import WORLD_LIMIT, compose, float32_placement, invertible32, rotate, scale, translate

SCENE_SUFFIXES = (".json", ".toml")
TRANSFORM_KEYS = ("translate", "rotate", "scale", "matrix")
MAX_TEXTURE_REPEAT = 1e4   # beyond it float32 coordinates (24-bit mantissa) no longer resolve a texel of a 1k image
_MISSING = object()


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _show(value) -> str:
    """``value`` for an error message, shortened (huge integers, deep nesting) to keep it one line."""
    return reprlib.repr(value)


class _Fields:
    """One table of the file: typed access by key with the field path in every error, and a check
    that no key was left unread (an unknown key is a typo the user wants to hear about)."""

    def __init__(self, data, path: str, source: str):
        self.source, self.path = source, path
        if not isinstance(data, dict):
            self.fail(f"expected a table/object, got {_show(data)}")
        self.data, self.read = data, set()

    def where(self, key=None) -> str:
        if key is None:
            return self.path or "(top level)"
        return f"{self.path}.{key}" if self.path else str(key)

    def fail(self, message: str, key=None):
        raise SceneError(f"{self.source}: {self.where(key)}: {message}")

    def has(self, key: str) -> bool:
        return key in self.data

    def raw(self, key: str, default=_MISSING):
        self.read.add(key)
        if key not in self.data:
            if default is _MISSING:
                self.fail("required field is missing", key)
            return default
        return self.data[key]

    def finite32(self, value, key=None) -> np.ndarray:
        """The numbers ``value`` (already checked to be numbers) as float64, after checking that their
        cast to float32, which is what the GPU gets, is finite: NaN, infinities, magnitudes beyond
        3.4e38 and integers too large for any float are refused, naming the field."""
        try:
            array = np.asarray(value, np.float64)
        except OverflowError:       # an integer beyond float64
            array = np.array(np.inf)
        with np.errstate(over="ignore"):        # an overflow becomes inf, which is refused below
            finite = bool(np.all(np.isfinite(array.astype(np.float32))))
        if not finite:
            self.fail(f"expected finite numbers within float32 range (±3.4e38), got {_show(value)}", key)
        return array

    def number(self, key: str, default=_MISSING) -> float:
        value = self.raw(key, default)
        if not _is_number(value):
            self.fail(f"expected a number, got {_show(value)}", key)
        return float(self.finite32(value, key))

    def integer(self, key: str, default=_MISSING) -> int:
        value = self.raw(key, default)
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(f"expected an integer, got {_show(value)}", key)
        return value

    def string(self, key: str, default=_MISSING, choices=None) -> str:
        value = self.raw(key, default)
        if not isinstance(value, str):
            self.fail(f"expected a string, got {_show(value)}", key)
        if choices is not None and value not in choices:
            self.fail(f"expected one of {list(choices)}, got {_show(value)}", key)
        return value

    def vector(self, key: str, default=_MISSING, length: int = 3, broadcast: bool = False,
               non_negative: bool = False, position: bool = False) -> np.ndarray:
        """A list of ``length`` finite numbers (a single number too when ``broadcast``); a ``position``
        within ±WORLD_LIMIT."""
        value = self.raw(key, default)
        if broadcast and _is_number(value):
            value = [value] * length
        if not isinstance(value, (list, tuple)) or len(value) != length or not all(map(_is_number, value)):
            kind = f"a number or a list of {length} numbers" if broadcast else f"a list of {length} numbers"
            self.fail(f"expected {kind}, got {_show(value)}", key)
        array = self.finite32(value, key)
        if non_negative and np.any(array < 0):
            self.fail(f"must not be negative, got {_show(value)}", key)
        if position and np.any(np.abs(array) > WORLD_LIMIT):
            self.fail(f"positions must lie within ±{WORLD_LIMIT:g} (the tracer's float32 range), "
                      f"got {_show(value)}", key)
        return array

    def table(self, key: str, default=_MISSING) -> _Fields:
        return _Fields(self.raw(key, default), self.where(key), self.source)

    def tables(self, key: str) -> list[_Fields]:
        value = self.raw(key, [])
        if not isinstance(value, list):
            self.fail(f"expected a list, got {_show(value)}", key)
        return [_Fields(item, f"{self.where(key)}[{i}]", self.source) for i, item in enumerate(value)]

    def done(self) -> None:
        unknown = sorted(set(self.data) - self.read, key=str)
        if unknown:
            self.fail(f"unknown key{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))}")


def _transform(fields: _Fields) -> np.ndarray:
    """translate/rotate/scale (applied scale, then rotations in order, then translation) or a matrix.
    Whether the result is usable (invertible, within float32) is checked once placed: _check_placement."""
    if fields.has("matrix"):
        for key in ("translate", "rotate", "scale"):
            if fields.has(key):
                fields.fail("give either 'matrix' or translate/rotate/scale, not both", key)
        value = fields.raw("matrix")
        if not (isinstance(value, (list, tuple)) and len(value) == 4 and all(
                isinstance(row, (list, tuple)) and len(row) == 4 and all(map(_is_number, row)) for row in value)):
            fields.fail(f"expected a 4×4 list of numbers, got {_show(value)}", "matrix")
        matrix = fields.finite32(value, "matrix")
        if not np.array_equal(matrix[3], [0, 0, 0, 1]):
            fields.fail(f"the last row must be [0, 0, 0, 1] (an affine transform), got {_show(value[3])}",
                        "matrix")
        return matrix
    parts = []
    if fields.has("translate"):
        parts.append(translate(fields.vector("translate")))
    rotations = fields.raw("rotate", [])
    if isinstance(rotations, dict):
        rotations = [rotations]
    if not isinstance(rotations, list):
        fields.fail(f"expected a rotation {{axis, angle}} or a list of them, got {rotations!r}", "rotate")
    turns = []
    for i, item in enumerate(rotations):
        rotation = _Fields(item, fields.where(f"rotate[{i}]"), fields.source)
        axis, angle = rotation.vector("axis"), rotation.number("angle")
        if not np.linalg.norm(axis) > 0:
            rotation.fail("the rotation axis must not be zero", "axis")
        rotation.done()
        turns.append(rotate(axis, angle))
    parts.extend(reversed(turns))     # the first listed rotation is applied first
    if fields.has("scale"):
        factors = fields.vector("scale", broadcast=True)
        if np.any(factors == 0):
            fields.fail("scale factors must be non-zero", "scale")
        parts.append(scale(factors))
    return compose(*parts, dtype=np.float64)


def _check_matrix(fields: _Fields, key: str, matrix: np.ndarray, what: str, vertices=None) -> np.ndarray:
    """``matrix`` (float64) as float32, refused naming the field unless float32 holds it and its inverse (and with
    ``vertices``, every placed vertex: ``float32_placement``)."""
    placed, problem = float32_placement(matrix, vertices)
    if problem:
        fields.fail(f"{what} {problem}", key)
    return placed


def _check_placement(fields: _Fields, key: str, matrix: np.ndarray, mesh: Mesh) -> np.ndarray:
    """``matrix`` (float64, object → world) as the float32 transform of ``mesh``, refused naming the field
    unless float32 holds it, its inverse and every placed vertex (for every frame between keyframes too)."""
    return _check_matrix(fields, key, matrix, f"the transform of mesh {mesh.name!r}", mesh.vertices)


def _check_blends(fields: _Fields, mesh: Mesh) -> None:
    """Between two keyframes the matrices blend element-wise, which can pass through a singular one (a
    scale from 1 to -1): the determinant of the blend is a cubic in the blend weight, so check the
    frames on either side of each of its roots."""
    keys = sorted(mesh.keyframes)
    for lo, hi in itertools.pairwise(keys):
        start, end = (mesh.keyframes[k][:3, :3].astype(np.float64) for k in (lo, hi))
        weights = np.linspace(0, 1, 4)
        cubic = np.polyfit(weights, [np.linalg.det(start + w * (end - start)) for w in weights], 3)
        for root in np.roots(cubic):
            if abs(root.imag) < 1e-6 and 0 < root.real < 1:     # a double root can come out complex
                for frame in {lo + int(np.floor(root.real * (hi - lo))), lo + int(np.ceil(root.real * (hi - lo)))}:
                    if not invertible32(mesh.transform_at(frame)):
                        fields.fail(f"the transform of mesh {mesh.name!r} blends to a singular one at frame "
                                    f"{frame}, between keyframes {lo} and {hi}: add keyframes", "keyframes")


def _material_name(fields: _Fields, materials: dict) -> str:
    material = fields.string("material")
    if material not in materials:
        fields.fail(f"unknown material {material!r}", "material")
    return material


def _material(fields: _Fields) -> Material:
    kind = fields.string("kind", "diffuse", choices=MATERIAL_KINDS)
    options = {"kind": kind}
    for key in ("reflectance", "eta", "k", "emission", "transmittance", "absorption"):
        if fields.has(key):
            options[key] = fields.vector(key, broadcast=True)
    for key in ("roughness", "ior"):
        if fields.has(key):
            options[key] = fields.number(key)
    fields.done()
    try:
        return Material(**options)
    except ValueError as err:
        fields.fail(str(err))


def _camera(fields: _Fields, base: Camera | None = None) -> Camera:
    def position(key):      # the keyframe's own, else the base camera's
        return fields.vector(key, position=True) if fields.has(key) or base is None else getattr(base, key)

    origin, target = position("origin"), position("target")
    up = fields.vector("up") if fields.has("up") else (base.up if base else np.array([0.0, 1.0, 0.0]))
    fov = fields.number("fov") if fields.has("fov") else (base.fov if base else 39.3077)
    fov_axis = (fields.string("fov_axis", choices=FOV_AXES) if fields.has("fov_axis")
                else (base.fov_axis if base else "smaller"))
    # float64: squared norms of float32-range vectors overflow float32 (a keyframe inherits float32 up).
    forward = np.asarray(target, np.float64) - np.asarray(origin, np.float64)
    up = np.asarray(up, np.float64)
    if not np.linalg.norm(forward) > 0:
        fields.fail("origin and target must differ")
    if not np.linalg.norm(np.cross(forward, up)) > 1e-9 * np.linalg.norm(forward) * max(np.linalg.norm(up), 1e-30):
        fields.fail("up must not be parallel to the view direction", "up")
    aperture = fields.number("aperture_radius") if fields.has("aperture_radius") else (
        base.aperture_radius if base else 0.0)
    focus = fields.number("focus_distance") if fields.has("focus_distance") else None
    if focus is None and base is not None and not (fields.has("origin") or fields.has("target")):
        focus = base.focus_distance   # a keyframe that keeps the base camera's place keeps its focus
    try:
        return Camera(origin, target, up, fov, fov_axis, aperture, focus)
    except ValueError as err:
        fields.fail(str(err), "aperture_radius" if "aperture" in str(err) else
                    "focus_distance" if "focus" in str(err) else None)


def _frame_of(fields: _Fields) -> int:
    frame = fields.integer("frame")
    if frame < 0:
        fields.fail(f"frames are numbered from 0, got {frame}", "frame")
    return frame


def _placement(fields: _Fields) -> tuple[np.ndarray, dict[int, tuple[str, np.ndarray]]]:
    """An entry's ``transform`` (float64; identity if absent) and ``keyframes`` (frame → (the keyframe's
    field name, its float64 matrix))."""
    table = fields.table("transform", {})
    transform = _transform(table)
    table.done()
    keyframes = {}
    for i, key in enumerate(fields.tables("keyframes")):
        frame = _frame_of(key)
        keyframes[frame] = (f"keyframes[{i}]", _transform(key))
        key.done()
    return transform, keyframes


def _place(mesh: Mesh, fields: _Fields, transform: np.ndarray, keyframes: dict,
           keyframe_fields: _Fields | None = None) -> None:
    """Place ``mesh`` by ``transform`` and ``keyframes`` (as from _placement) applied after its own node
    transform, each placement checked (errors name the fields of ``fields``; blends between keyframes
    name those of ``keyframe_fields``, default ``fields``)."""
    node = mesh.transform
    mesh.transform = _check_placement(fields, "transform", compose(transform, node, dtype=np.float64), mesh)
    mesh.keyframes = {frame: _check_placement(fields, key, compose(matrix, node, dtype=np.float64), mesh)
                      for frame, (key, matrix) in keyframes.items()}
    _check_blends(keyframe_fields or fields, mesh)


def _image_file(fields: _Fields, key: str, folder: Path, read) -> np.ndarray | None:
    """The image that ``key`` names (a path relative to the scene file) as ``read`` (a meshio reader) gives
    it, or None without the key; its SceneError names the field."""
    if not fields.has(key):
        return None
    file = fields.string(key)
    try:
        return read(Path(file) if Path(file).is_absolute() else folder / file)
    except SceneError as err:
        fields.fail(str(err), key)


def _meshes(fields: _Fields, materials: dict, folder: Path) -> list[Mesh]:
    """A mesh entry's meshes. A file's entry without 'material' takes the file's own materials (glTF's or an OBJ
    file's MTL), added to ``materials`` as '<name>/<material>'."""
    has_file, has_shape = fields.has("file"), fields.has("shape")
    if has_file == has_shape:
        fields.fail("give exactly one of 'file' (a mesh file) or 'shape' (" + ", ".join(PRIMITIVES) + ")")
    material = _material_name(fields, materials) if has_shape or fields.has("material") else None
    name = fields.string("name", "")
    transform, keyframes = _placement(fields)
    instances = fields.tables("instances") if fields.has("instances") else None
    alpha_mode = fields.string("alpha_mode", "mask" if fields.has("alpha_cutoff") else "opaque",
                               choices=("opaque", *ALPHA_MODES))
    texture = _image_file(fields, "texture", folder, partial(read_texture_image, alpha=alpha_mode != "opaque"))
    if fields.has("alpha_cutoff") and alpha_mode != "mask":
        fields.fail("a cutoff is for alpha_mode \"mask\"", "alpha_cutoff")
    if alpha_mode != "opaque":
        cutoff = fields.number("alpha_cutoff", 0.5) if alpha_mode == "mask" else None
        if cutoff is not None and not 0.0 <= cutoff <= 1.0:
            fields.fail(f"expected a number in [0, 1], got {cutoff:g}", "alpha_cutoff")
        if texture is None:
            fields.fail("a cutout needs a 'texture', whose alpha says where the surface is", "alpha_mode")
        texture = with_cutout(texture[..., :3], texture[..., 3], cutoff)
    normal_map = _image_file(fields, "normal_map", folder, read_texture_image)
    glow = _image_file(fields, "emission_texture", folder, read_texture_image)
    moves: list = []                # a glTF file's node animation of each part (gltf_scene.node_animation)
    metal_rough = _image_file(fields, "metal_rough_map", folder, read_texture_image)
    if metal_rough is not None and (material is None or materials[material].kind not in ("plastic", "conductor")):
        fields.fail("a metal-rough map makes each point of a plastic that plastic or a metal, or roughens a "
                    "conductor per point: give the entry a plastic or conductor 'material'", "metal_rough_map")
    if has_shape:
        kind = fields.string("shape", choices=PRIMITIVES)
        vertices, faces, normals = primitive(kind)
        base = name or kind
        parts = [Mesh(base, vertices, faces, material, normals=normals)]
        images = {"texture": texture, "normal_map": normal_map, "emission_texture": glow,
                  "metal_rough_map": metal_rough}
        if any(image is not None for image in images.values()):
            uvs = primitive_uvs(kind)
            if uvs is None:
                key = next(key for key, image in images.items() if image is not None)
                fields.fail(f"a {kind} has no texture coordinates; give a mesh file that has them", key)
            parts[0].texture, parts[0].normal_map, parts[0].emission_texture = texture, normal_map, glow
            parts[0].metal_rough_map, parts[0].uvs = metal_rough, uvs
    else:
        file = fields.string("file")
        path = Path(file) if Path(file).is_absolute() else folder / file
        base = name or path.stem
        colors = fields.raw("vertex_colors", True)
        animation = fields.raw("animation", None)     # which of a glTF file's animations plays (index or name)
        if animation is not None and (not isinstance(animation, (str, int)) or isinstance(animation, bool)
                                      or path.suffix.lower() not in GLTF_SUFFIXES):
            fields.fail(f"expected the index or name of one of a glTF file's animations, got {_show(animation)}",
                        "animation")
        animation = None if animation is None else str(animation)
        if not isinstance(colors, bool):
            fields.fail(f"expected true or false, got {_show(colors)}", "vertex_colors")
        own: dict = {}      # the file's materials, where the entry names none
        try:
            parts = load_mesh_file(path, material, base, vertex_colors=colors, texture=texture,
                                   materials=own if material is None else None, normal_map=normal_map,
                                   emission_texture=glow, metal_rough_map=metal_rough)
            if path.suffix.lower() in GLTF_SUFFIXES:
                moves = node_animation(path, parts, animation=animation)[1]
        except SceneError as err:
            fields.fail(str(err), "file")
        for taken in own:
            if taken in materials:
                fields.fail(f"the file's material {taken!r} has the name of another material: name the mesh", "file")
        materials.update(placed_absorption(own, transform))
    if alpha_mode == "blend":
        for part in parts:
            part.alpha_mode = "blend"
    if fields.has("texture_repeat"):
        repeat = fields.vector("texture_repeat", length=2, broadcast=True)
        if np.any(repeat <= 0) or np.any(repeat > MAX_TEXTURE_REPEAT):
            fields.fail(f"expected counts in (0, {MAX_TEXTURE_REPEAT:g}], got {repeat.tolist()}", "texture_repeat")
        if all(part.uvs is None for part in parts):
            fields.fail("the mesh has no texture to repeat (give 'texture', 'normal_map', 'emission_texture' or "
                        "'metal_rough_map', or a mesh file with one)", "texture_repeat")
        for part in parts:
            if part.uvs is not None:
                part.uvs = (part.uvs * repeat).astype(np.float32)
    fields.done()
    if instances is None:
        for part, keys in zip(parts, moves or [None] * len(parts)):
            _place(part, fields, transform, keyframes)
            if keys and not keyframes:       # the file's animation, where the entry has no keyframes of its own
                part.keyframes = {frame: _check_placement(fields, "file", compose(transform, world, dtype=np.float64),
                                                          part) for frame, world in keys.items()}
                _check_blends(fields, part)
        placed = parts
    else:
        placed = _instances(fields, instances, parts, base, (transform, keyframes), materials, moves)
    for part in placed:       # the shapes a skin or morph targets bend it to, placed
        if part.vertex_keyframes and (problem := placement_problem(part)):
            fields.fail(problem, "file")
    return placed


def _instances(fields: _Fields, entries: list[_Fields], parts: list[Mesh], base: str, placement: tuple,
               materials: dict, file_moves: list) -> list[Mesh]:
    """The ``parts`` of a mesh entry placed once per entry of its ``instances`` list, sharing their
    arrays. An instance is placed by its own transform (or keyframes) applied after the entry's own
    ``placement`` (transform, keyframes), which poses the shape for all of them; only one of the two
    may be animated. Where neither is, the file's own animation (``file_moves``: each part's world matrices by
    frame, or None) moves each instance's parts under its placement. Instances are named ``base[i]`` unless
    named."""
    transform, keyframes = placement
    if not entries:
        fields.fail("expected at least one instance (leave 'instances' out to place the mesh once)", "instances")
    what = f"the transform of mesh {base!r}"
    _check_matrix(fields, "transform", transform, what)
    for key, matrix in keyframes.values():
        _check_matrix(fields, key, matrix, what)
    placed = []
    for i, entry in enumerate(entries):
        material = _material_name(entry, materials) if entry.has("material") else None   # None: each part's own
        label = entry.string("name", f"{base}[{i}]")
        where, moves = _placement(entry)
        if moves and keyframes:
            entry.fail("the mesh has keyframes too: animate either the mesh or its instances", "keyframes")
        entry.done()
        if moves:       # the instance's keyframes, each after the entry's pose
            frames = {frame: (key, compose(matrix, transform, dtype=np.float64))
                      for frame, (key, matrix) in moves.items()}
        else:           # the entry's keyframes, each followed by the instance's placement
            frames = {frame: ("transform", compose(where, matrix, dtype=np.float64))
                      for frame, (_, matrix) in keyframes.items()}
        for part, keys in zip(parts, file_moves or [None] * len(parts)):
            mesh = part.instance(label + part.name[len(base):], material, part.transform)
            pose = compose(where, transform, dtype=np.float64)
            _place(mesh, entry, pose, frames, keyframe_fields=entry if moves else fields)
            if keys and not frames:      # the file's animation, where neither the entry nor the instance has keys
                mesh.keyframes = {frame: _check_placement(fields, "file", compose(pose, world, dtype=np.float64), mesh)
                                  for frame, world in keys.items()}
                _check_blends(fields, mesh)
            placed.append(mesh)
    return placed


LIGHT_TURN_LIMIT = 120.0    # degrees a light may turn between two keyframes (its direction is blended between them)


def _light(fields: _Fields):
    """A light entry, with its ``keyframes`` (each the light's fields that change there)."""
    light = _light_state(fields)
    for key in fields.tables("keyframes"):
        frame = _frame_of(key)
        if frame in light.keyframes:
            key.fail(f"a second keyframe for frame {frame}", "frame")
        light.keyframes[frame] = _light_state(key, base=light)
    for lo, hi in itertools.pairwise(sorted(light.keyframes)):
        if hasattr(light, "direction"):
            start, end = light.keyframes[lo].direction, light.keyframes[hi].direction
            turn = np.degrees(np.arccos(np.clip(np.dot(start, end), -1.0, 1.0)))
            if turn > LIGHT_TURN_LIMIT:
                fields.fail(f"turns {turn:.0f}° between frames {lo} and {hi} (its direction is blended between "
                            f"keyframes: at most {LIGHT_TURN_LIMIT:g}°); add keyframes between them", "keyframes")
    fields.done()
    return light


def _light_state(fields: _Fields, base=None):
    """A light of the entry's ``type`` from its fields, or with ``base`` a keyframe of ``base`` (its frame read
    already): its fields where the keyframe gives them, else the base light's."""
    def given(key, **checks):
        if base is not None and not fields.has(key):
            return np.asarray(getattr(base, key), np.float64)
        return fields.vector(key, **checks)

    if base is None:
        kind = fields.string("type", choices=("point", "spot", "directional"))
    else:
        kind = {DirectionalLight: "directional", SpotLight: "spot", PointLight: "point"}[type(base)]
    if kind == "point":
        light = PointLight(given("position", position=True).astype(np.float32),
                           given("intensity", broadcast=True, non_negative=True).astype(np.float32))
    elif kind == "spot":
        position = given("position", position=True).astype(np.float32)
        if fields.has("direction") and fields.has("target") or base is None and not (
                fields.has("direction") or fields.has("target")):
            fields.fail("give exactly one of 'direction' (3 numbers) or 'target' (a point the spot aims at)")
        aim = "target" if fields.has("target") else "direction"
        direction = (fields.vector("target", position=True) - position if aim == "target" else given("direction"))
        if not np.linalg.norm(direction) > 0:
            fields.fail("must not be zero" if aim == "direction" else "must differ from the position", aim)
        intensity = given("intensity", broadcast=True, non_negative=True).astype(np.float32)
        cutoff = fields.number("cutoff_angle", 20.0 if base is None else base.cutoff_angle)
        beam = (fields.number("beam_width") if fields.has("beam_width")
                else None if base is None or fields.has("cutoff_angle") else base.beam_width)
        try:
            light = SpotLight(position, intensity, direction, cutoff, beam)
        except ValueError as err:
            fields.fail(str(err), "cutoff_angle" if str(err).startswith("cutoff") else "beam_width")
    else:
        direction = given("direction")
        if not np.linalg.norm(direction) > 0:
            fields.fail("the direction must not be zero", "direction")
        light = DirectionalLight((direction / np.linalg.norm(direction)).astype(np.float32),
                                 given("irradiance", broadcast=True, non_negative=True).astype(np.float32))
    if base is not None:
        fields.done()
    return light


def parse_scene(data, source: str, folder: Path) -> Scene:
    """A Scene from the parsed file contents ``data``; ``source`` names the file in errors and
    ``folder`` is where relative mesh paths start."""
    top = _Fields(data, "", source)
    camera_fields = top.table("camera")
    camera = _camera(camera_fields)
    camera_keyframes = {}
    for key in camera_fields.tables("keyframes"):
        frame = _frame_of(key)
        camera_keyframes[frame] = _camera(key, base=camera)
        key.done()
    camera_fields.done()

    materials = {}
    material_table = top.table("materials")
    for name in list(material_table.data):
        materials[str(name)] = _material(material_table.table(name))
    material_table.done()
    if not materials:
        top.fail("at least one material is required", "materials")

    meshes = [part for entry in top.tables("meshes") for part in _meshes(entry, materials, folder)]
    if not meshes:
        top.fail("at least one mesh is required", "meshes")
    lights = [_light(entry) for entry in top.tables("lights")]
    environment = _image_file(top, "environment", folder, read_environment_image)
    rotation = top.number("environment_rotate", 0.0)
    if rotation and environment is None:
        top.fail("turns an environment map: give 'environment' too", "environment_rotate")
    background = top.vector("background", [0.0, 0.0, 0.0] if environment is None else [1.0, 1.0, 1.0],
                            broadcast=True, non_negative=True)
    last_key = max([*camera_keyframes, *(f for m in meshes for f in m.keyframes),
                    *(f for light in lights for f in light.keyframes)], default=0)
    frame_count = top.integer("frame_count", last_key + 1)
    if frame_count < 1:
        top.fail(f"expected at least 1 frame, got {frame_count}", "frame_count")
    name = top.string("name", Path(source).stem)
    top.done()
    return Scene(camera, meshes, materials, lights=lights, background=background.astype(np.float32),
                 camera_keyframes=camera_keyframes, frame_count=frame_count, name=name, environment=environment,
                 environment_rotation=rotation)


def read_scene_file(path) -> dict:
    """The JSON or TOML document of the scene file at ``path``, unchecked; SceneError names what is wrong
    with the file itself."""
    path = Path(path)
    source = str(path)
    if path.suffix.lower() not in SCENE_SUFFIXES:
        raise SceneError(f"{source}: scene files must end in .json or .toml")
    if not path.is_file():
        raise SceneError(f"{source}: scene file not found")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise SceneError(f"{source}: cannot read the file: {err}") from err
    try:
        return json.loads(text) if path.suffix.lower() == ".json" else tomllib.loads(text)
    except (ValueError, RecursionError) as err:     # syntax errors, integers over 4300 digits, deep nesting
        raise SceneError(f"{source}: cannot parse the file: {err}") from err


def load_scene_file(path) -> Scene:
    """Read and parse the JSON or TOML scene file at ``path``."""
    path = Path(path)
    data = read_scene_file(path)
    return parse_scene(data, str(path), path.parent)
