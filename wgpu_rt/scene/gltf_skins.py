"""What bends a glTF file's meshes: morph targets and skins, posed at each frame of the file's animation.

A primitive's vertices are its POSITION (and NORMAL) plus Σ w_k · the offsets of its morph target k, the weights
``w`` its node's ``weights`` (else its mesh's, else 0) as the node's ``weights`` channel animates them. A node with
a ``skin`` then moves each vertex by the blend Σ u_i · world(joint_i) · inverseBindMatrix_i over its JOINTS_n /
WEIGHTS_n pairs (linear blend skinning; the weights brought to sum 1), into the world: glTF ignores a skinned mesh's
own node transform. A normal follows its vertex's blend by the blend's inverse transpose. trimesh reads a
primitive's vertices in the file's order; each mesh is matched to its primitive by them
(``GltfBuffers.primitive_holding``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SceneError
from .file_materials import FieldReader
from .gltf_animation import Channel, GltfBuffers, node_primitives


@dataclass
class Bending:
    """A mesh's shape at every frame: (V, 3) vertices and normals (None where the mesh has none), in the world
    where ``skinned``, else in its node's space."""

    vertices: list[np.ndarray]
    normals: list[np.ndarray] | None
    skinned: bool


def bends(tree: dict, node: dict) -> bool:
    """Whether ``node`` has a skin or its mesh morph targets."""
    return node.get("skin") is not None or any(isinstance(p, dict) and p.get("targets")
                                               for p in node_primitives(tree, node))


def _morph(tree: dict, buffers: GltfBuffers, node: dict, primitive: dict, count: int, where: str):
    """(position offsets (K, V, 3), normal offsets (K, V, 3) or None, rest weights (K,)) of the primitive's morph
    targets (``count`` vertices); None without targets."""
    targets = primitive.get("targets") or []
    if not targets:
        return None
    if not isinstance(targets, list) or not all(isinstance(t, dict) for t in targets):
        raise SceneError(f"{where}: its morph targets must be a list of objects")
    positions = np.stack([buffers.accessor(t["POSITION"], f"{where}: target {k}") if "POSITION" in t
                          else np.zeros((count, 3)) for k, t in enumerate(targets)])
    normals = None
    if "NORMAL" in primitive["attributes"]:
        normals = np.stack([buffers.accessor(t["NORMAL"], f"{where}: target {k}") if "NORMAL" in t
                            else np.zeros((count, 3)) for k, t in enumerate(targets)])
    if positions.shape[1:] != (count, 3) or (normals is not None and normals.shape[1:] != (count, 3)):
        raise SceneError(f"{where}: a morph target's offsets must be {count} VEC3s, one a vertex")
    mesh = tree["meshes"][node["mesh"]]
    holder = node if "weights" in node else mesh       # (a node's weights stand in for its mesh's)
    weights = FieldReader(where, holder).numbers("weights", 0.0, length=len(targets), low=-np.inf, high=np.inf)
    return positions, normals, weights


def _skin(tree: dict, buffers: GltfBuffers, node: dict, primitive: dict, count: int, where: str):
    """(joint nodes (J,), inverse bind matrices (J, 4, 4), per vertex its joints (V, I) and their weights (V, I)
    summing to 1) of a skinned node; None for a node without a skin."""
    number, skins = node.get("skin"), tree.get("skins") or []
    if number is None:
        return None
    if not (isinstance(number, int) and 0 <= number < len(skins) and isinstance(skins[number], dict)):
        raise SceneError(f"{where}: skin {number!r} is not one of the file's {len(skins)}")
    skin, nodes = skins[number], tree.get("nodes") or []
    joints = skin.get("joints")
    if not (isinstance(joints, list) and joints and all(isinstance(j, int) and 0 <= j < len(nodes) for j in joints)):
        raise SceneError(f"{where}: skin {number}'s joints must be a list of the file's nodes")
    if "inverseBindMatrices" in skin:
        inverse_binds = buffers.accessor(skin["inverseBindMatrices"], f"{where}: skin {number}")
        if inverse_binds.shape != (len(joints), 16) or not np.all(np.isfinite(inverse_binds)):
            raise SceneError(f"{where}: skin {number}'s inverseBindMatrices must be {len(joints)} finite MAT4s")
        inverse_binds = inverse_binds.reshape(-1, 4, 4).transpose(0, 2, 1)     # (column-major)
    else:
        inverse_binds = np.broadcast_to(np.eye(4), (len(joints), 4, 4))
    attributes, influences, weights = primitive.get("attributes") or {}, [], []
    for n in range(8):
        if f"JOINTS_{n}" not in attributes:
            break
        influences.append(buffers.accessor(attributes[f"JOINTS_{n}"], f"{where}: JOINTS_{n}"))
        weights.append(buffers.accessor(attributes.get(f"WEIGHTS_{n}"), f"{where}: WEIGHTS_{n}"))
    if not influences:
        raise SceneError(f"{where}: a skinned mesh without JOINTS_0 and WEIGHTS_0")
    influences, weights = np.concatenate(influences, axis=1), np.concatenate(weights, axis=1)
    if influences.shape != (count, weights.shape[1]) or weights.shape[0] != count:
        raise SceneError(f"{where}: JOINTS_n and WEIGHTS_n must be VEC4s, one a vertex")
    if np.any(influences < 0) or np.any(influences >= len(joints)) or np.any(influences != np.floor(influences)):
        raise SceneError(f"{where}: a vertex's JOINTS_n name joints beyond its skin's {len(joints)}")
    if not np.all(np.isfinite(weights)) or np.any(weights < 0):
        raise SceneError(f"{where}: WEIGHTS_n must be finite and not negative")
    total = weights.sum(axis=1, keepdims=True)
    if np.any(total <= 0):
        raise SceneError(f"{where}: a vertex has no weight on any joint")
    return np.asarray(joints), inverse_binds, influences.astype(np.int64), weights / total


def _blend_normals(linear: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(V, 3) ``normals`` mapped by the inverse transpose of each vertex's (V, 3, 3) ``linear`` map (its cofactor
    matrix, signed by its determinant), normalized; a normal mapped to nothing stays as it was."""
    a0, a1, a2 = linear[:, :, 0], linear[:, :, 1], linear[:, :, 2]
    mapped = (np.cross(a1, a2) * normals[:, :1] + np.cross(a2, a0) * normals[:, 1:2]
              + np.cross(a0, a1) * normals[:, 2:])
    mapped *= np.sign(np.einsum("vi,vi->v", a0, np.cross(a1, a2)))[:, None]
    length = np.linalg.norm(mapped, axis=1, keepdims=True)
    return np.where(length > 1e-30, mapped / np.maximum(length, 1e-30), normals)


def bending(buffers: GltfBuffers, node_index: int, vertices: np.ndarray, normals: np.ndarray | None,
            weight_channels: list[Channel], poses: list[dict], times: list[float]) -> Bending | None:
    """The shape at each of ``times`` (the frames' seconds; ``poses`` the nodes' world matrices at each) of the mesh
    trimesh read as ``vertices`` and ``normals`` from the primitive of node ``node_index`` of the file ``buffers``
    reads, bent by its morph targets (``weight_channels``: the node's weights channels) and skin; None where neither
    bends it."""
    tree = buffers.tree
    node = tree["nodes"][node_index]
    if not bends(tree, node):
        return None
    where = f"{buffers.path}: node {node_index}"
    primitive = buffers.primitive_holding(node_primitives(tree, node), vertices)
    if primitive is None:
        return None
    morph = _morph(tree, buffers, node, primitive, len(vertices), where)
    skin = _skin(tree, buffers, node, primitive, len(vertices), where)
    if morph is None and skin is None:
        return None
    base = np.asarray(vertices, np.float64)
    rest_normals = None if normals is None else np.asarray(normals, np.float64)
    shapes, turned = [], None if normals is None else []
    for t, pose in zip(times, poses):
        points, directions = base, rest_normals
        if morph is not None:
            offsets, normal_offsets, weights = morph
            for channel in weight_channels:
                weights = channel.at(t)
            points = points + np.einsum("k,kvc->vc", weights, offsets)
            if directions is not None and normal_offsets is not None:
                directions = directions + np.einsum("k,kvc->vc", weights, normal_offsets)
        if skin is not None:
            joints, inverse_binds, influences, shares = skin
            try:
                matrices = np.stack([pose[j] for j in joints]) @ inverse_binds          # (J, 4, 4)
            except KeyError as err:
                raise SceneError(f"{where}: joint node {err.args[0]} of its skin is not in the scene") from None
            blend = np.einsum("vi,vijk->vjk", shares, matrices[influences])             # (V, 4, 4)
            points = np.einsum("vjk,vk->vj", blend[:, :3, :3], points) + blend[:, :3, 3]
            if directions is not None:
                directions = _blend_normals(blend[:, :3, :3], directions)
        elif directions is not None:
            length = np.linalg.norm(directions, axis=1, keepdims=True)
            directions = np.where(length > 1e-30, directions / np.maximum(length, 1e-30), rest_normals)
        if not np.all(np.isfinite(points)):
            raise SceneError(f"{where}: its skin or morph targets bend it to vertices that are not finite")
        shapes.append(points.astype(np.float32))
        if turned is not None:
            turned.append(directions.astype(np.float32))
    return Bending(shapes, turned, skin is not None)
