"""A glTF file's node animations, sampled at the scene's frames: what moves its meshes, its camera and its lights.

glTF animates a node by channels, each a sampler's keyframe times (seconds) and values for the node's translation,
rotation (a unit quaternion) or scale, interpolated STEP, LINEAR (rotations by slerp) or CUBICSPLINE (Hermite, each
key with its in- and out-tangent). ``read_animations`` reads them (accessors from the .glb's binary chunk, a
.gltf's buffer files or data URIs; floats, or normalized integers as glTF allows for rotations); ``local_matrix``
is a node's transform at a time, its animated parts in place of the node's own. Frames are FRAME_RATE a second from
time 0 to the last key. A ``weights`` channel is read as a channel of its node's morph-target weights, which
``gltf_skins`` mixes.
"""

from __future__ import annotations

import base64
import struct
from pathlib import Path
from urllib.parse import unquote

import numpy as np
import trimesh

from ..errors import SceneError

FRAME_RATE = 24.0      # frames a second: glTF's times are seconds, a scene's frames are numbered
MOST_ELEMENTS = 1 << 26   # an accessor's elements read at most (a count beyond is a malformed file)
PATHS = {"translation": 3, "rotation": 4, "scale": 3}
COMPONENTS = {5120: ("<i1", 127.0), 5121: ("<u1", 255.0), 5122: ("<i2", 32767.0), 5123: ("<u2", 65535.0),
              5125: ("<u4", None), 5126: ("<f4", None)}
WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def node_primitives(tree: dict, node: dict) -> list:
    """The primitives of glTF node ``node``'s mesh ([] where it has none, or they are not a list)."""
    meshes, number = tree.get("meshes") or [], node.get("mesh")
    if not (isinstance(number, int) and 0 <= number < len(meshes) and isinstance(meshes[number], dict)):
        return []
    primitives = meshes[number].get("primitives")
    return primitives if isinstance(primitives, list) else []


class GltfBuffers:
    """A glTF file's buffers, read when first asked for: a .glb's binary chunk, a .gltf's files or data URIs."""

    def __init__(self, path: Path, tree: dict):
        self.path, self.tree, self._data, self._positions = path, tree, {}, {}

    def primitive_holding(self, primitives, vertices: np.ndarray, attribute: str = "POSITION") -> dict | None:
        """The first of ``primitives`` (a glTF mesh's list) with ``attribute`` whose POSITION values are
        ``vertices`` (trimesh's reading of it: in the file's order), None where none is."""
        vertices = np.asarray(vertices, np.float32)
        accessors = self.tree.get("accessors") or []
        for primitive in primitives if isinstance(primitives, list) else []:
            attributes = primitive.get("attributes") if isinstance(primitive, dict) else None
            position = attributes.get("POSITION") if isinstance(attributes, dict) else None
            if not (isinstance(position, int) and 0 <= position < len(accessors) and attribute in attributes
                    and isinstance(accessors[position], dict)
                    and accessors[position].get("count") == len(vertices)):
                continue
            if position not in self._positions:
                self._positions[position] = self.accessor(position, str(self.path)).astype(np.float32)
            if np.array_equal(self._positions[position], vertices):
                return primitive
        return None

    def buffer(self, index: int) -> bytes:
        if index not in self._data:
            entries = self.tree.get("buffers") or []
            if not (isinstance(index, int) and 0 <= index < len(entries)):
                raise SceneError(f"{self.path}: buffer {index!r} is not one of the file's {len(entries)}")
            uri = entries[index].get("uri")
            if uri is None:
                self._data[index] = self._binary_chunk()
            elif not isinstance(uri, str):
                raise SceneError(f"{self.path}: buffer {index}: its uri must be a string, got {uri!r}")
            elif uri.startswith("data:"):
                try:
                    self._data[index] = base64.b64decode(uri.split(",", 1)[1], validate=True)
                except (IndexError, ValueError) as err:
                    raise SceneError(f"{self.path}: buffer {index}: its data URI is not base64 ({err})") from err
            else:
                file = self.path.parent / unquote(uri)
                if not file.is_file():
                    raise SceneError(f"{self.path}: buffer {index}: {file} not found")
                self._data[index] = file.read_bytes()
        return self._data[index]

    def _binary_chunk(self) -> bytes:
        data = self.path.read_bytes()
        if data[:4] != b"glTF":
            raise SceneError(f"{self.path}: a buffer without a uri needs a .glb's binary chunk")
        offset = 12 + 8 + struct.unpack_from("<I", data, 12)[0]
        if offset + 8 > len(data) or data[offset + 4:offset + 8] != b"BIN\0":
            raise SceneError(f"{self.path}: the .glb has no binary chunk")
        return data[offset + 8:offset + 8 + struct.unpack_from("<I", data, offset)[0]]

    def accessor(self, index, where: str) -> np.ndarray:
        """(count, width) float64 values of accessor ``index`` (normalized integers as glTF maps them; a sparse
        accessor's values put over its bufferView's, or over zeros where it has none; a MAT4 column by column)."""
        accessors = self.tree.get("accessors") or []
        if not (isinstance(index, int) and 0 <= index < len(accessors)):
            raise SceneError(f"{where}: accessor {index!r} is not one of the file's {len(accessors)}")
        entry = accessors[index]
        if not isinstance(entry, dict):
            raise SceneError(f"{where}: accessor {index} is not an object")
        kind, width = COMPONENTS.get(entry.get("componentType")), WIDTHS.get(entry.get("type"))
        sparse = entry.get("sparse")
        if kind is None or width is None or ("bufferView" not in entry and sparse is None):
            raise SceneError(f"{where}: accessor {index} holds {entry.get('type')!r} of component type "
                             f"{entry.get('componentType')!r} (or has neither a bufferView nor sparse values): "
                             f"not read")
        dtype, scale = np.dtype(kind[0]), kind[1]
        try:
            count = int(entry.get("count", 0))
        except (TypeError, ValueError) as err:
            raise SceneError(f"{where}: accessor {index} has a malformed count ({err})") from err
        if count < 1 or count > MOST_ELEMENTS:
            raise SceneError(f"{where}: accessor {index} holds {count!r} elements (1 to {MOST_ELEMENTS:,} are read)")
        values = (self._view_values(entry, entry["bufferView"], dtype, width, count, where, index)
                  if "bufferView" in entry else np.zeros((count, width)))
        if sparse is not None:
            self._put_sparse(values, sparse, dtype, width, where, index)
        if scale is not None and entry.get("normalized"):
            values = np.maximum(values / scale, -1.0)
        return values

    def _view_values(self, entry: dict, number, dtype: np.dtype, width: int, count: int, where: str,
                     index: int) -> np.ndarray:
        """(count, width) float64: ``count`` elements of ``width`` ``dtype`` values from bufferView ``number``,
        starting at ``entry``'s byteOffset."""
        views = self.tree.get("bufferViews") or []
        if not (isinstance(number, int) and 0 <= number < len(views)) or not isinstance(views[number], dict):
            raise SceneError(f"{where}: accessor {index}'s bufferView {number!r} is not one of the file's")
        view = views[number]
        try:
            stride = int(view.get("byteStride") or dtype.itemsize * width)
            start = int(view.get("byteOffset", 0)) + int(entry.get("byteOffset", 0))
        except (AttributeError, TypeError, ValueError) as err:
            raise SceneError(f"{where}: accessor {index} or its bufferView has a malformed field ({err})") from err
        data = self.buffer(view.get("buffer"))
        if start < 0 or stride < 1 or start + stride * (count - 1) + dtype.itemsize * width > len(data):
            raise SceneError(f"{where}: accessor {index} lies outside its buffer")
        rows = np.ndarray((count, width), dtype, data, start, (stride, dtype.itemsize))
        return rows.astype(np.float64)

    def _put_sparse(self, values: np.ndarray, sparse, dtype: np.dtype, width: int, where: str, index: int) -> None:
        """Write a sparse accessor's substituted elements into ``values``."""
        if not (isinstance(sparse, dict) and isinstance(sparse.get("indices"), dict)
                and isinstance(sparse.get("values"), dict)):
            raise SceneError(f"{where}: accessor {index}'s sparse field needs indices and values objects")
        try:
            count = int(sparse.get("count", 0))
        except (TypeError, ValueError) as err:
            raise SceneError(f"{where}: accessor {index}'s sparse count is malformed ({err})") from err
        kind = COMPONENTS.get(sparse["indices"].get("componentType"))
        if not 1 <= count <= len(values) or kind is None or kind[0] not in ("<u1", "<u2", "<u4"):
            raise SceneError(f"{where}: accessor {index}'s sparse count or index type is not valid")
        at = self._view_values(sparse["indices"], sparse["indices"].get("bufferView"), np.dtype(kind[0]), 1, count,
                               where, index)[:, 0].astype(np.int64)
        if np.any(at >= len(values)):
            raise SceneError(f"{where}: accessor {index}'s sparse indices reach past its {len(values)} elements")
        values[at] = self._view_values(sparse["values"], sparse["values"].get("bufferView"), dtype, width, count,
                                       where, index)


def _slerp(a: np.ndarray, b: np.ndarray, w: float) -> np.ndarray:
    """Unit quaternions (x, y, z, w) ``a`` → ``b`` at ``w`` along the shorter arc."""
    if np.dot(a, b) < 0:
        b = -b
    cos = float(np.clip(np.dot(a, b), -1.0, 1.0))
    if cos > 0.9995:
        q = a + w * (b - a)
    else:
        angle = np.arccos(cos)
        q = (np.sin((1 - w) * angle) * a + np.sin(w * angle) * b) / np.sin(angle)
    return q / np.linalg.norm(q)


class Channel:
    """One animated property of one node: keyframe ``times``, their ``values`` (CUBICSPLINE: in-tangent, value,
    out-tangent per key) and the interpolation."""

    def __init__(self, path: str, times: np.ndarray, values: np.ndarray, interpolation: str, where: str,
                 width: int | None = None):
        """``width``: the numbers in each value (default: its path's; the morph targets' count for weights)."""
        if times.shape[1] != 1:
            raise SceneError(f"{where}: its key times must be one number each, got {times.shape[1]}")
        times = times[:, 0]
        keys = len(times)
        if interpolation not in ("LINEAR", "STEP", "CUBICSPLINE"):
            raise SceneError(f"{where}: unknown interpolation {interpolation!r} (LINEAR, STEP or CUBICSPLINE)")
        width = width or PATHS[path]
        if path == "weights" and values.shape[1] == 1 and values.size % width == 0:
            values = values.reshape(-1, width)       # (weights come as scalars, a key's targets in turn)
        if values.shape != ((3 if interpolation == "CUBICSPLINE" else 1) * keys, width):
            raise SceneError(f"{where}: {keys} key times but {len(values)} values of {values.shape[1]} for its "
                             f"{interpolation.lower()} {path}")
        if not (np.all(np.isfinite(times)) and np.all(np.isfinite(values)) and np.all(np.diff(times) > 0)):
            raise SceneError(f"{where}: key times must rise and every value be finite")
        self.path, self.times, self.values, self.interpolation = path, times, values, interpolation

    def at(self, t: float) -> np.ndarray:
        times, cubic = self.times, self.interpolation == "CUBICSPLINE"
        value = (lambda k: self.values[3 * k + 1]) if cubic else (lambda k: self.values[k])   # noqa: E731
        if t <= times[0] or len(times) == 1:
            result = value(0)
        elif t >= times[-1]:
            result = value(len(times) - 1)
        else:
            k = int(np.searchsorted(times, t, side="right")) - 1
            span = times[k + 1] - times[k]
            w = (t - times[k]) / span
            if self.interpolation == "STEP":
                result = value(k)
            elif cubic:
                out_tangent, in_tangent = self.values[3 * k + 2] * span, self.values[3 * (k + 1)] * span
                w2, w3 = w * w, w * w * w
                result = ((2 * w3 - 3 * w2 + 1) * value(k) + (w3 - 2 * w2 + w) * out_tangent
                          + (-2 * w3 + 3 * w2) * value(k + 1) + (w3 - w2) * in_tangent)
            elif self.path == "rotation":
                result = _slerp(value(k), value(k + 1), w)
            else:
                result = (1 - w) * value(k) + w * value(k + 1)
        if self.path == "rotation":
            result = result / max(np.linalg.norm(result), 1e-12)
        return result


def read_animations(path: Path, tree: dict, choice: str | None = None) -> dict[int, list[Channel]]:
    """The animated channels (node index → its channels) of the animations played: the one ``choice`` names (its
    index in the file's animations or its name), else every animation where no two move the same property of the
    same node (as a scene exported object by object has them), else the first (a character's clips, walk and run,
    each moving the same bones, are alternatives: ``--animation`` picks another)."""
    buffers = GltfBuffers(path, tree)
    nodes = tree.get("nodes") or []
    animations = tree.get("animations") or []
    if not isinstance(animations, list):
        raise SceneError(f"{path}: the glTF file's animations are not a list")
    channels: dict[int, list[Channel]] = {}
    for a in _played(path, animations, choice):       # (only those played are read)
        for node, kept in _animation_channels(buffers, a, animations[a], nodes).items():
            channels.setdefault(node, []).extend(kept)
    return channels


def _played(path: Path, animations: list, choice: str | None) -> list[int]:
    """The indices of the animations ``read_animations`` plays, told from what their channels target."""
    if choice is not None:
        names = [a.get("name") if isinstance(a, dict) else None for a in animations]
        picked = [a for a, name in enumerate(names) if choice in (str(a), name)]
        if not picked:
            listed = ", ".join(f"{a} ({name})" if name else str(a) for a, name in enumerate(names)) or "none"
            raise SceneError(f"{path}: no animation {choice!r}; its animations: {listed}")
        return picked[:1]
    seen: set = set()
    for animation in animations:
        listed = animation.get("channels") if isinstance(animation, dict) else None
        aims = [c.get("target") for c in (listed if isinstance(listed, list) else []) if isinstance(c, dict)]
        targets = {repr((aim.get("node"), aim.get("path"))) for aim in aims
                   if isinstance(aim, dict) and aim.get("path") in (*PATHS, "weights")}
        if targets & seen:
            return [0]           # alternatives moving the same property of a node: the first
        seen |= targets
    return list(range(len(animations)))


def _animation_channels(buffers: GltfBuffers, a: int, animation, nodes: list) -> dict[int, list[Channel]]:
    """The channels of animation ``a`` of the file ``buffers`` reads, by node (the paths read: translation,
    rotation, scale, and morph-target weights of a node with targets)."""
    samplers, listed = (animation.get("samplers") or [], animation.get("channels") or []) \
        if isinstance(animation, dict) else (None, None)
    if not (isinstance(samplers, list) and isinstance(listed, list)):
        raise SceneError(f"{buffers.path}: animation {a} is not an object with lists of samplers and channels")
    channels: dict[int, list[Channel]] = {}
    for c, channel in enumerate(listed):
        where = f"{buffers.path}: animation {a} channel {c}"
        target = channel.get("target") if isinstance(channel, dict) else None
        if not isinstance(target, dict):
            raise SceneError(f"{where}: expected an object with a target")
        node, kind = target.get("node"), target.get("path")
        if not isinstance(kind, str) or kind not in (*PATHS, "weights"):
            continue                  # (extensions' paths are not read)
        if not (isinstance(node, int) and 0 <= node < len(nodes)):
            raise SceneError(f"{where}: target node {node!r} is not one of the file's {len(nodes)} nodes")
        width = morph_target_count(buffers.tree, node, where) if kind == "weights" else None
        if width == 0:
            continue                  # weights of a node without morph targets move nothing
        number = channel.get("sampler")
        if not (isinstance(number, int) and 0 <= number < len(samplers)) or not isinstance(samplers[number], dict):
            raise SceneError(f"{where}: sampler {number!r} is not one of the animation's {len(samplers)}")
        sampler = samplers[number]
        times = buffers.accessor(sampler.get("input"), where)
        values = buffers.accessor(sampler.get("output"), where)
        channels.setdefault(node, []).append(Channel(kind, times, values, sampler.get("interpolation", "LINEAR"),
                                                     where, width))
    return channels


def morph_target_count(tree: dict, node: int, where: str) -> int:
    """How many morph targets the mesh of node ``node`` has (0 without a mesh or targets; a SceneError where its
    primitives disagree, as glTF requires them to agree)."""
    entry = (tree.get("nodes") or [])[node]
    number, meshes = entry.get("mesh") if isinstance(entry, dict) else None, tree.get("meshes") or []
    if not (isinstance(number, int) and 0 <= number < len(meshes) and isinstance(meshes[number], dict)):
        return 0
    primitives = meshes[number].get("primitives") or []
    targets = [p.get("targets") or [] if isinstance(p, dict) else [] for p in
               (primitives if isinstance(primitives, list) else [])]
    if not all(isinstance(t, list) for t in targets):
        raise SceneError(f"{where}: mesh {number}'s morph targets must be lists")
    counts = {len(t) for t in targets}
    if len(counts) > 1:
        raise SceneError(f"{where}: mesh {number}'s primitives have different numbers of morph targets "
                         f"{sorted(counts)}")
    return counts.pop() if counts else 0


LONGEST = 3600.0       # seconds: an animation whose keys run longer is refused (each frame is a keyframe)


def frame_count(channels: dict[int, list[Channel]], where: str) -> int:
    """Frames at FRAME_RATE from time 0 through the last key of any channel (1 without animation)."""
    last = max((channel.times[-1] for node in channels.values() for channel in node), default=0.0)
    if last > LONGEST:
        raise SceneError(f"{where}: its animations run {last:g} s, longer than the {LONGEST:g} s read")
    return int(np.floor(max(last, 0.0) * FRAME_RATE + 1e-6)) + 1


def local_matrix(node: dict, channels: list[Channel], t: float, fixed: np.ndarray, where: str) -> np.ndarray:
    """A node's transform at time ``t``: ``fixed`` (its own) where no channel animates it, else translation ·
    rotation · scale with the animated parts at ``t`` and the rest the node's own (a node's matrix taken apart into
    them: glTF animates only nodes without one, but trimesh writes every node's as a matrix); errors name ``where``."""
    channels = [channel for channel in channels if channel.path in PATHS]
    if not channels:
        return fixed
    if "matrix" in node:     # (glTF animates TRS nodes; a matrix, as trimesh writes them, is taken apart into one)
        try:
            with np.errstate(divide="raise", invalid="raise", over="raise"):
                scale, _, angles, translation, _ = trimesh.transformations.decompose_matrix(fixed)
        except (ValueError, FloatingPointError) as err:
            raise SceneError(f"{where}: an animated node's matrix must be a translation, rotation and scale ({err})") \
                from err
        w, x, y, z = trimesh.transformations.quaternion_from_euler(*angles)
        parts = {"translation": translation, "rotation": np.array([x, y, z, w]), "scale": scale}
    else:
        parts = {"translation": np.asarray(node.get("translation", [0.0, 0.0, 0.0]), np.float64),
                 "rotation": np.asarray(node.get("rotation", [0.0, 0.0, 0.0, 1.0]), np.float64),
                 "scale": np.asarray(node.get("scale", [1.0, 1.0, 1.0]), np.float64)}
    for channel in channels:
        parts[channel.path] = channel.at(t)
    x, y, z, w = parts["rotation"]
    matrix = trimesh.transformations.quaternion_matrix([w, x, y, z])
    matrix[:3, :3] *= parts["scale"]
    matrix[:3, 3] = parts["translation"]
    return matrix
