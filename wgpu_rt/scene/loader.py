"""Scene files (JSON or TOML, same structure; see docs/scene-format.md) → ``Scene``.

Parsing is strict: every key is checked against the format, every value's type and shape is checked,
and any problem raises a SceneError that names the file and the field path, e.g.
``scene.json: meshes[2].material: unknown material 'gold'``.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np

from ..errors import SceneError
from .meshio import load_mesh_file
from .model import FOV_AXES, MATERIAL_KINDS, Camera, DirectionalLight, Material, Mesh, PointLight, Scene
from .primitives import PRIMITIVES, primitive
from .transforms import compose, rotate, scale, translate

SCENE_SUFFIXES = (".json", ".toml")
TRANSFORM_KEYS = ("translate", "rotate", "scale", "matrix")
_MISSING = object()


class _Fields:
    """One table of the file: typed access by key with the field path in every error, and a check
    that no key was left unread (an unknown key is a typo the user wants to hear about)."""

    def __init__(self, data, path: str, source: str):
        self.source, self.path = source, path
        if not isinstance(data, dict):
            self.fail(f"expected a table/object, got {type(data).__name__}")
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

    def number(self, key: str, default=_MISSING) -> float:
        value = self.raw(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(f"expected a number, got {value!r}", key)
        if not np.isfinite(value):
            self.fail(f"expected a finite number, got {value!r}", key)
        return float(value)

    def integer(self, key: str, default=_MISSING) -> int:
        value = self.raw(key, default)
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(f"expected an integer, got {value!r}", key)
        return value

    def string(self, key: str, default=_MISSING, choices=None) -> str:
        value = self.raw(key, default)
        if not isinstance(value, str):
            self.fail(f"expected a string, got {value!r}", key)
        if choices is not None and value not in choices:
            self.fail(f"expected one of {list(choices)}, got {value!r}", key)
        return value

    def vector(self, key: str, default=_MISSING, length: int = 3, broadcast: bool = False) -> np.ndarray:
        """A list of ``length`` finite numbers (a single number too when ``broadcast``)."""
        value = self.raw(key, default)
        if broadcast and isinstance(value, (int, float)) and not isinstance(value, bool):
            value = [value] * length
        if (not isinstance(value, (list, tuple)) or len(value) != length
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in value)):
            kind = f"a number or a list of {length} numbers" if broadcast else f"a list of {length} numbers"
            self.fail(f"expected {kind}, got {value!r}", key)
        array = np.asarray(value, np.float64)
        if not np.all(np.isfinite(array)):
            self.fail(f"expected finite numbers, got {value!r}", key)
        return array

    def table(self, key: str, default=_MISSING) -> "_Fields | None":
        value = self.raw(key, default)
        return None if value is None else _Fields(value, self.where(key), self.source)

    def tables(self, key: str) -> list["_Fields"]:
        value = self.raw(key, [])
        if not isinstance(value, list):
            self.fail(f"expected a list, got {type(value).__name__}", key)
        return [_Fields(item, f"{self.where(key)}[{i}]", self.source) for i, item in enumerate(value)]

    def done(self) -> None:
        unknown = sorted(set(self.data) - self.read, key=str)
        if unknown:
            self.fail(f"unknown key{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))}")


def _transform(fields: _Fields) -> np.ndarray:
    """translate/rotate/scale (applied scale, then rotations in order, then translation) or a matrix."""
    if fields.has("matrix"):
        for key in ("translate", "rotate", "scale"):
            if fields.has(key):
                fields.fail("give either 'matrix' or translate/rotate/scale, not both", key)
        value = fields.raw("matrix")
        matrix = np.asarray(value, dtype=object)
        if matrix.shape != (4, 4) or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                             for x in matrix.ravel()):
            fields.fail(f"expected a 4×4 list of numbers, got {value!r}", "matrix")
        matrix = matrix.astype(np.float64)
        if not np.all(np.isfinite(matrix)) or abs(np.linalg.det(matrix[:3, :3])) < 1e-12:
            fields.fail("the matrix must be finite and invertible", "matrix")
        return matrix.astype(np.float32)
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
    return compose(*parts)


def _material(fields: _Fields) -> Material:
    kind = fields.string("kind", "diffuse", choices=MATERIAL_KINDS)
    options = {"kind": kind}
    for key in ("reflectance", "eta", "k", "emission"):
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
    def pick(key, reader):
        return reader(key) if fields.has(key) or base is None else getattr(base, key)

    origin = pick("origin", fields.vector)
    target = pick("target", fields.vector)
    up = fields.vector("up") if fields.has("up") else (base.up if base else np.array([0.0, 1.0, 0.0]))
    fov = fields.number("fov") if fields.has("fov") else (base.fov if base else 39.3077)
    fov_axis = (fields.string("fov_axis", choices=FOV_AXES) if fields.has("fov_axis")
                else (base.fov_axis if base else "smaller"))
    forward = np.asarray(target, np.float64) - np.asarray(origin, np.float64)
    if not np.linalg.norm(forward) > 0:
        fields.fail("origin and target must differ")
    if not np.linalg.norm(np.cross(forward, up)) > 1e-9 * np.linalg.norm(forward) * max(np.linalg.norm(up), 1e-30):
        fields.fail("up must not be parallel to the view direction", "up")
    try:
        return Camera(origin, target, up, fov, fov_axis)
    except ValueError as err:
        fields.fail(str(err))


def _frame_of(fields: _Fields) -> int:
    frame = fields.integer("frame")
    if frame < 0:
        fields.fail(f"frames are numbered from 0, got {frame}", "frame")
    return frame


def _meshes(fields: _Fields, materials: dict, folder: Path) -> list[Mesh]:
    material = fields.string("material")
    if material not in materials:
        fields.fail(f"unknown material {material!r}", "material")
    has_file, has_shape = fields.has("file"), fields.has("shape")
    if has_file == has_shape:
        fields.fail("give exactly one of 'file' (a mesh file) or 'shape' (" + ", ".join(PRIMITIVES) + ")")
    name = fields.string("name", "")
    placement = fields.table("transform", {})
    transform = _transform(placement)
    placement.done()
    keyframes = {}
    for key in fields.tables("keyframes"):
        frame = _frame_of(key)
        keyframes[frame] = _transform(key)
        key.done()
    if has_shape:
        kind = fields.string("shape", choices=PRIMITIVES)
        vertices, faces, normals = primitive(kind)
        parts = [Mesh(name or kind, vertices, faces, material, normals=normals)]
    else:
        file = fields.string("file")
        path = Path(file) if Path(file).is_absolute() else folder / file
        try:
            parts = load_mesh_file(path, material, name or None)
        except SceneError as err:
            fields.fail(str(err), "file")
    fields.done()
    for part in parts:
        node = part.transform
        part.transform = compose(transform, node)
        part.keyframes = {frame: compose(matrix, node) for frame, matrix in keyframes.items()}
    return parts


def _light(fields: _Fields):
    kind = fields.string("type", choices=("point", "directional"))
    if kind == "point":
        light = PointLight(fields.vector("position").astype(np.float32),
                           fields.vector("intensity", broadcast=True).astype(np.float32))
    else:
        direction = fields.vector("direction")
        if not np.linalg.norm(direction) > 0:
            fields.fail("the direction must not be zero", "direction")
        light = DirectionalLight((direction / np.linalg.norm(direction)).astype(np.float32),
                                 fields.vector("irradiance", broadcast=True).astype(np.float32))
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
    background = top.vector("background", [0.0, 0.0, 0.0], broadcast=True)
    if np.any(background < 0):
        top.fail("background radiance must be non-negative", "background")
    last_key = max([*camera_keyframes, *(f for m in meshes for f in m.keyframes)], default=0)
    frame_count = top.integer("frame_count", last_key + 1)
    if frame_count < 1:
        top.fail(f"expected at least 1 frame, got {frame_count}", "frame_count")
    name = top.string("name", Path(source).stem)
    top.done()
    return Scene(camera, meshes, materials, lights=lights, background=background.astype(np.float32),
                 camera_keyframes=camera_keyframes, frame_count=frame_count, name=name)


def load_scene_file(path) -> Scene:
    """Read and parse the JSON or TOML scene file at ``path``."""
    path = Path(path)
    source = str(path)
    if path.suffix.lower() not in SCENE_SUFFIXES:
        raise SceneError(f"{source}: scene files must end in .json or .toml")
    if not path.is_file():
        raise SceneError(f"{source}: scene file not found")
    try:
        text = path.read_text(encoding="utf-8")
        data = json.loads(text) if path.suffix.lower() == ".json" else tomllib.loads(text)
    except (UnicodeDecodeError, json.JSONDecodeError, tomllib.TOMLDecodeError) as err:
        raise SceneError(f"{source}: cannot parse the file: {err}") from err
    return parse_scene(data, source, path.parent)
