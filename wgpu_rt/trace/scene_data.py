"""Packing the shading side of a scene for the kernel: materials, the emitter table and the frame
parameters (bind group 1; record layouts as in wgsl/trace/material.wgsl and wgsl/trace/trace_bindings.wgsl).

Emitters are sampled in proportion to their power through an alias table (Vose's method), so next-event
estimation picks a light in O(1): emissive triangles by luminance·area (uniform in area within one),
point lights by 4π·intensity, a directional light by its irradiance through a disc, the constant
background by its radiance over a sphere. The disc and the sphere have the radius of the region the
camera frames at its target's distance (``view_radius``), at most the scene's bounding radius (at least
VIEW_RADIUS_FLOOR of it, so that a sun is never dropped for a camera at its target): through
the bounding sphere, a large ground plane made a sun and a sky so powerful that a small point light
beside the objects was picked once in 200 picks and lit a frosted ball with fireflies, and the same
starved point lights filled a fifth of issue 12's held-out worlds with fireflies (BENCHMARKS.md §29).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.model import DirectionalLight, Material, PointLight, Scene

MATERIAL_KIND_CODES = {"diffuse": 0, "conductor": 1, "dielectric": 2}
EMITTER_TRIANGLE, EMITTER_POINT, EMITTER_DIRECTIONAL, EMITTER_BACKGROUND = range(4)
LUMINANCE = np.array([0.212671, 0.715160, 0.072169])
VIEW_RADIUS_FLOOR = 1e-6   # a framed region counts as at least this fraction of the bounding radius

MATERIAL_DTYPE = np.dtype([
    ("reflectance", "<f4", 3), ("kind", "<u4"), ("emission", "<f4", 3), ("roughness", "<f4"),
    ("eta", "<f4", 3), ("ior", "<f4"), ("k", "<f4", 3), ("is_emissive", "<u4")])

EMITTER_DTYPE = np.dtype([
    ("position", "<f4", 3), ("kind", "<u4"), ("edge1", "<f4", 3), ("pmf", "<f4"),
    ("edge2", "<f4", 3), ("area", "<f4"), ("radiance", "<f4", 3), ("alias_threshold", "<f4"),
    ("alias_index", "<u4"), ("pad", "<u4", 3)])

FRAME_PARAMS_DTYPE = np.dtype([
    ("camera_origin", "<f4", 3), ("width", "<u4"), ("camera_right", "<f4", 3), ("height", "<u4"),
    ("camera_up", "<f4", 3), ("seed", "<u4"), ("camera_forward", "<f4", 3), ("max_depth", "<u4"),
    ("previous_origin", "<f4", 3), ("sample_offset", "<u4"), ("previous_right", "<f4", 3),
    ("emitter_count", "<u4"), ("previous_up", "<f4", 3), ("tile_row_stride", "<u4"),
    ("previous_forward", "<f4", 3), ("background_pmf", "<f4"), ("background", "<f4", 3),
    ("chunk_start", "<u4"), ("chunk_size", "<u4"), ("pass_samples", "<u4"), ("pad", "<u4", 2)])


def pack_materials(materials: list[Material]) -> np.ndarray:
    """Material records in material-id order."""
    out = np.zeros(max(1, len(materials)), MATERIAL_DTYPE)
    for i, m in enumerate(materials):
        out[i] = (m.reflectance, MATERIAL_KIND_CODES[m.kind], m.emission, m.roughness, m.eta, m.ior, m.k,
                  int(m.is_emissive))
    return out


def alias_table(weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vose's alias table for ``weights`` (> 0): per slot, the threshold below which the slot keeps
    itself, and the slot it defers to otherwise. Picking slot floor(u·N) then testing frac(u·N) against
    the threshold selects index i with probability weights[i] / sum(weights)."""
    n = len(weights)
    scaled = np.asarray(weights, np.float64) * n / np.sum(weights)
    threshold = np.ones(n)
    alias = np.arange(n, dtype=np.uint32)
    small = [i for i in range(n) if scaled[i] < 1.0]
    large = [i for i in range(n) if scaled[i] >= 1.0]
    while small and large:
        s, g = small.pop(), large.pop()
        threshold[s], alias[s] = scaled[s], g
        scaled[g] -= 1.0 - scaled[s]
        (small if scaled[g] < 1.0 else large).append(g)
    return threshold.astype(np.float32), alias


def view_radius(camera) -> float:
    """The radius of the region the camera frames at its target's distance: that distance times the tan of
    half its field of view, times √2 for the corners (the aspect is not known here)."""
    distance = np.linalg.norm(np.asarray(camera.target, np.float64) - np.asarray(camera.origin, np.float64))
    return float(np.sqrt(2.0) * distance * np.tan(np.radians(camera.fov) / 2))


@dataclass
class EmitterTable:
    records: np.ndarray            # EMITTER_DTYPE, at least one record (a black one when there is none)
    triangle_density: np.ndarray   # (T,) f32: pmf / area of each triangle's record, 0 if not emissive
    background_pmf: float

    @property
    def count(self) -> int:
        return len(self.records)


def emissive_triangles(material_ids: np.ndarray, materials: list[Material]) -> np.ndarray:
    """The numbers of the triangles whose material emits (triangle t is made of
    ``materials[material_ids[t]]``; array work: an instanced scene places millions)."""
    emits = np.array([m.is_emissive for m in materials], bool)
    return np.flatnonzero(emits[np.asarray(material_ids, np.intp)]) if len(materials) else np.zeros(0, np.intp)


def build_emitter_table(scene: Scene, numbers: np.ndarray, triangles: np.ndarray, material_ids: np.ndarray,
                        materials: list[Material], scene_radius: float) -> EmitterTable:
    """The emitter table of ``scene``'s lights and of its emissive triangles ``numbers`` (from
    ``emissive_triangles``), whose world-space vertices are ``triangles`` (len(numbers), 3, 3); the
    scene has len(material_ids) triangles."""
    numbers = np.asarray(numbers, np.intp)
    tri = np.asarray(triangles, np.float64).reshape(-1, 3, 3)
    edge1, edge2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    area = 0.5 * np.linalg.norm(np.cross(edge1, edge2), axis=1)
    keep = area > 0
    numbers, tri, edge1, edge2, area = numbers[keep], tri[keep], edge1[keep], edge2[keep], area[keep]
    material_emission = np.array([m.emission for m in materials], np.float64).reshape(-1, 3)
    emission = material_emission[np.asarray(material_ids, np.intp)[numbers]].reshape(-1, 3)
    triangle_power = np.pi * area * (emission @ LUMINANCE)

    lights = []  # (kind, position, edge1, edge2, area, radiance, power)
    radius = min(scene_radius, max(view_radius(scene.camera), VIEW_RADIUS_FLOOR * scene_radius))
    for light in scene.lights:
        if isinstance(light, PointLight):
            intensity = np.asarray(light.intensity, np.float64)
            lights.append((EMITTER_POINT, light.position, 0, 0, 0, intensity, 4 * np.pi * LUMINANCE @ intensity))
        elif isinstance(light, DirectionalLight):
            irradiance = np.asarray(light.irradiance, np.float64)
            lights.append((EMITTER_DIRECTIONAL, 0, light.direction, 0, 0, irradiance,
                           np.pi * radius ** 2 * LUMINANCE @ irradiance))
    background = np.asarray(scene.background, np.float64)
    if np.any(background > 0):
        lights.append((EMITTER_BACKGROUND, 0, 0, 0, 0, background,
                       4 * np.pi ** 2 * radius ** 2 * max(float(LUMINANCE @ background), 1e-6)))
    lights = [light for light in lights if light[6] > 0]

    triangle_count = len(numbers)
    count = triangle_count + len(lights)
    records = np.zeros(max(1, count), EMITTER_DTYPE)
    triangle_density = np.zeros(len(material_ids), np.float32)
    background_pmf = 0.0
    if count:
        power = np.concatenate([triangle_power, [light[6] for light in lights]])
        pmf = power / power.sum()
        threshold, alias = alias_table(power)
        records["kind"][:triangle_count] = EMITTER_TRIANGLE
        records["position"][:triangle_count] = tri[:, 0]
        records["edge1"][:triangle_count], records["edge2"][:triangle_count] = edge1, edge2
        records["area"][:triangle_count], records["radiance"][:triangle_count] = area, emission
        for i, (kind, position, e1, e2, a, radiance, _) in enumerate(lights, start=triangle_count):
            for field, value in zip(("kind", "position", "edge1", "edge2", "area", "radiance"),
                                    (kind, position, e1, e2, a, radiance)):
                records[field][i] = value
            if kind == EMITTER_BACKGROUND:
                background_pmf = float(pmf[i])
        records["pmf"][:count], records["alias_threshold"][:count], records["alias_index"][:count] = pmf, threshold, alias
        triangle_density[numbers] = records["pmf"][:triangle_count] / records["area"][:triangle_count]
    return EmitterTable(records, triangle_density, background_pmf)


def camera_vectors(camera, width: int, height: int) -> dict[str, np.ndarray]:
    """origin, unit basis, right·tan_x, up·tan_y and the tans of ``camera`` for a width×height film."""
    right, up, forward = camera.basis()
    tan_x, tan_y = camera.tan_half_fov(width, height)
    return {"origin": camera.origin, "unit_right": right, "unit_up": up, "right": right * tan_x,
            "up": up * tan_y, "forward": forward, "tan": (tan_x, tan_y)}
