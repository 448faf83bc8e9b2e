"""4×4 affine transforms (column vectors, object → world), built the way Mitsuba's ScalarTransform4f
chains them: ``compose(translate(t), rotate(axis, deg), scale(s))`` applies the scale first; and what the tracer
needs of a placement (``float32_placement``)."""

from __future__ import annotations

import numpy as np

FLOAT32_MAX = float(np.finfo(np.float32).max)
# Positions (camera, point lights, placed vertices) stay within ±1e9: the tracer squares squared edge
# lengths (triangle normals) in float32, so surfaces lose their normals beyond about 4e9 (measured: a
# cube of half-size 3e9 renders without its emission, one of 1e9 exactly as one of 1).
WORLD_LIMIT = 1e9


def translate(offset) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, 3] = np.asarray(offset, dtype=np.float64)
    return matrix


def scale(factors) -> np.ndarray:
    return np.diag([*np.broadcast_to(np.asarray(factors, dtype=np.float64), (3,)), 1.0])


def rotate(axis, degrees: float) -> np.ndarray:
    """Right-handed rotation by ``degrees`` about ``axis`` (Rodrigues' formula, as Mitsuba's rotate)."""
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    angle = np.radians(degrees)
    cos, sin = np.cos(angle), np.sin(angle)
    cross = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    matrix = np.eye(4)
    matrix[:3, :3] = cos * np.eye(3) + sin * cross + (1 - cos) * np.outer(axis, axis)
    return matrix


def compose(*matrices, dtype=np.float32) -> np.ndarray:
    """The product left to right (the rightmost transform is applied first), computed in float64 and
    returned as ``dtype``."""
    result = np.eye(4)
    for matrix in matrices:
        result = result @ np.asarray(matrix, dtype=np.float64)
    return result.astype(dtype)


def transform_points(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``points`` (N, 3) mapped by the affine ``matrix``, computed in float64, returned as float32."""
    matrix = np.asarray(matrix, dtype=np.float64)
    return (np.asarray(points, dtype=np.float64) @ matrix[:3, :3].T + matrix[:3, 3]).astype(np.float32)


def transform_normals(matrix: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Unit ``normals`` (N, 3) mapped by the inverse transpose of ``matrix``'s linear part."""
    linear = np.asarray(matrix, dtype=np.float64)[:3, :3]
    mapped = np.asarray(normals, dtype=np.float64) @ np.linalg.inv(linear)
    length = np.linalg.norm(mapped, axis=1, keepdims=True)
    return (mapped / np.where(length > 0, length, 1.0)).astype(np.float32)


def invertible32(matrix: np.ndarray) -> bool:
    """Whether float32 holds the inverse of ``matrix`` (shading normals and motion vectors use it)."""
    try:
        return bool(np.all(np.abs(np.linalg.inv(np.asarray(matrix, np.float64))) <= FLOAT32_MAX))
    except np.linalg.LinAlgError:
        return False


def float32_placement(matrix: np.ndarray, vertices: np.ndarray | None = None) -> tuple[np.ndarray, str | None]:
    """``matrix`` (float64, object → world) as float32, and what keeps the tracer from using it (None where nothing):
    float32 must hold it and its inverse and, given ``vertices``, put each of them within ±WORLD_LIMIT (so does every
    element-wise blend of two such matrices: it stays under the larger bound)."""
    with np.errstate(over="ignore"):        # an overflow becomes inf, which is refused below
        placed = np.asarray(matrix, np.float64).astype(np.float32)
    if not np.all(np.isfinite(placed)):
        return placed, "overflows float32 (±3.4e38)"
    if not invertible32(placed):
        return placed, "is singular in float32 (a zero or vanishing scale)"
    if vertices is not None:
        reach = np.abs(placed[:3, :3].astype(np.float64)) @ np.abs(vertices).max(axis=0) + np.abs(placed[:3, 3])
        if not np.all(reach <= WORLD_LIMIT):
            return placed, f"puts vertices beyond ±{WORLD_LIMIT:g} (the tracer's float32 range)"
    return placed, None
