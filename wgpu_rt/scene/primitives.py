"""Built-in shapes in object space, triangulated exactly as Mitsuba 3 triangulates its own.

``rectangle``: [-1, 1]² in the z = 0 plane facing +z (Mitsuba's rectangle as its scene turns it into a
mesh). ``cube``: [-1, 1]³ with four vertices per face so faces stay flat-shaded (Mitsuba's cube
plugin, same vertex order and diagonals). ``sphere``: a unit icosphere from trimesh.creation with smooth
normals (Mitsuba's sphere is analytic; ``to_mitsuba`` exports this tessellation, so both renderers see
the same surface).

``primitive_uvs``: texture coordinates for the flat-faced ones, each face seen from outside showing the
whole image upright ((0, 0) at its bottom left; the top and bottom faces with the image's top toward -z
and +z); the sphere has none (its icosphere has no seam to cut the image along).
"""

from __future__ import annotations

import numpy as np
import trimesh

# Each cube face as four corners in Mitsuba's order; triangles are (0, 1, 2) and (3, 0, 2) per face.
_CUBE_FACES = (
    ((1, -1, -1), (1, -1, 1), (-1, -1, 1), (-1, -1, -1)),   # -y
    ((1, 1, -1), (-1, 1, -1), (-1, 1, 1), (1, 1, 1)),       # +y
    ((1, -1, -1), (1, 1, -1), (1, 1, 1), (1, -1, 1)),       # +x
    ((1, -1, 1), (1, 1, 1), (-1, 1, 1), (-1, -1, 1)),       # +z
    ((-1, -1, 1), (-1, 1, 1), (-1, 1, -1), (-1, -1, -1)),   # -x
    ((1, 1, -1), (1, -1, -1), (-1, -1, -1), (-1, 1, -1)),   # -z
)

PRIMITIVES = ("rectangle", "cube", "sphere")


def rectangle() -> tuple[np.ndarray, np.ndarray, None]:
    vertices = np.array([[-1, -1, 0], [1, -1, 0], [-1, 1, 0], [1, 1, 0]], np.float32)
    faces = np.array([[1, 2, 0], [1, 3, 2]], np.uint32)
    return vertices, faces, None


def cube() -> tuple[np.ndarray, np.ndarray, None]:
    vertices = np.array(_CUBE_FACES, np.float32).reshape(-1, 3)
    quad = np.array([[0, 1, 2], [3, 0, 2]], np.uint32)
    faces = (quad[None] + 4 * np.arange(6, dtype=np.uint32)[:, None, None]).reshape(-1, 3)
    return vertices, faces, None


def sphere(subdivisions: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    vertices = np.asarray(mesh.vertices, np.float32)
    normals = vertices / np.linalg.norm(vertices, axis=1, keepdims=True)
    return vertices, np.asarray(mesh.faces, np.uint32), normals


def _face_uvs(vertices: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(V, 2) coordinates of a [-1, 1]² face's ``vertices`` with outward unit ``normal`` along an axis, seen
    from outside: u along its right, v along its up (+y, or -z on the top face and +z on the bottom one)."""
    up = np.array([0.0, 1.0, 0.0]) if abs(normal[1]) < 0.5 else np.array([0.0, 0.0, -normal[1]])
    right = np.cross(up, normal)
    return (np.stack([vertices @ right, vertices @ up], -1) + 1) / 2


def primitive_uvs(kind: str) -> np.ndarray | None:
    """(V, 2) float32 texture coordinates of ``primitive(kind)``'s vertices, or None (the sphere)."""
    vertices = primitive(kind)[0].astype(np.float64)
    if kind == "rectangle":
        return _face_uvs(vertices, np.array([0.0, 0.0, 1.0])).astype(np.float32)
    if kind == "cube":
        faces = vertices.reshape(-1, 4, 3)
        return np.concatenate([_face_uvs(face, face.mean(0)) for face in faces]).astype(np.float32)
    return None


def primitive(kind: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(vertices, faces, normals or None) of the primitive named ``kind`` (one of PRIMITIVES)."""
    return {"rectangle": rectangle, "cube": cube, "sphere": sphere}[kind]()
