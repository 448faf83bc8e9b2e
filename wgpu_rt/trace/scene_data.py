"""Packing the shading side of a scene for the kernel: materials, the emitter table, the frame
parameters, the surface textures and the environment map (bind group 1; record layouts as in
wgsl/trace/material.wgsl, wgsl/trace/trace_bindings.wgsl, wgsl/trace/surface_textures.wgsl and
wgsl/trace/environment.wgsl).

Next-event estimation picks a light in two steps. The table's entries fall into *emitter groups*: the
emissive triangles of one mesh, each point light, the sun, the background. At each shading point a
group is picked in proportion to an estimate of the irradiance it gives there (``group_probabilities``,
the numpy reference of wgsl/trace/emitters.wgsl: a point light's intensity over the squared distance, an
area light's radiance times its area over the squared distance to its bounding sphere, times a bound on
the cosine at the light for a flat one, which gives nothing behind its plane; a sun's irradiance; π
times a sky's radiance), mixed with DEFENSIVE_SHARE of picks by power, so that a light the estimate
misjudges (an occluded one, say) is never starved. Within its group an entry is picked in proportion to
its power through an alias table (Vose's method; triangles by luminance·area, uniform in area within
one). A scene of more than MAX_EMITTER_GROUPS groups has its lights other than suns and skies clustered
in space (``_clustered``); a kernel with one group is compiled without the group code
(``emitter_group_count``, trace/features.py). BENCHMARKS.md §30 measures all this.

Power: point lights 4π·intensity (a spot light its cone's solid angle, to halfway through its fall-off,
times its intensity), a directional light its irradiance through a disc, the constant background its
radiance over a sphere. The disc and the sphere have the radius of the region the camera
frames at its target's distance (``view_radius``), at most the scene's bounding radius (at least
VIEW_RADIUS_FLOOR of it, so that a sun is never dropped for a camera at its target): through
the bounding sphere, a large ground plane made a sun and a sky so powerful that a small point light
beside the objects was picked once in 200 picks and lit a frosted ball with fireflies, and the same
starved point lights filled a fifth of issue 12's held-out worlds with fireflies (BENCHMARKS.md §29).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..accel.geometry import NO_TEXTURE
from ..scene.model import GLASS_KINDS, DirectionalLight, Material, PointLight, Scene, SpotLight, linear_from_srgb8
from .coat import coat_levels, coat_words

MATERIAL_KIND_CODES = {"diffuse": 0, "conductor": 1, "dielectric": 2, "plastic": 3, "thin_dielectric": 4}
EMITTER_TRIANGLE, EMITTER_POINT, EMITTER_DIRECTIONAL, EMITTER_BACKGROUND = range(4)
# how a group's irradiance estimate is reckoned (wgsl/trace/emitters.wgsl's group_importance)
GROUP_CONSTANT, GROUP_POINT, GROUP_SOLID, GROUP_FLAT = range(4)
MAX_EMITTER_GROUPS = 16       # the FrameParams array's length (wgsl/trace/trace_bindings.wgsl)
DEFENSIVE_SHARE = 0.1         # of a shading point's picks, made by power alone
FLAT_TOLERANCE = 1e-5         # a group is flat if its normals and vertices deviate less (relative)
LUMINANCE = np.array([0.212671, 0.715160, 0.072169])
DELTA_ROUGHNESS = 1e-4        # below it a lobe is a Dirac delta (wgsl/trace/material.wgsl)
VIEW_RADIUS_FLOOR = 1e-6   # a framed region counts as at least this fraction of the bounding radius
# A light of an animated scene that is dark at a frame keeps its record, picked by this power (never in practice,
# and it gives nothing when it is): the table keeps one layout across the frames (TracePass.set_frame).
DARK_LIGHT_POWER = 1e-30

MATERIAL_DTYPE = np.dtype([
    ("reflectance", "<f4", 3), ("kind", "<u4"), ("emission", "<f4", 3), ("roughness", "<f4"),
    ("eta", "<f4", 3), ("ior", "<f4"), ("k", "<f4", 3), ("is_emissive", "<u4")])

EMITTER_DTYPE = np.dtype([
    ("position", "<f4", 3), ("kind", "<u4"), ("edge1", "<f4", 3), ("share", "<f4"),
    ("edge2", "<f4", 3), ("area", "<f4"), ("radiance", "<f4", 3), ("alias_threshold", "<f4"),
    ("alias_index", "<u4"), ("group", "<u4"), ("triangle", "<u4"), ("emission_image", "<u4")])

EMITTER_GROUP_DTYPE = np.dtype([
    ("center", "<f4", 3), ("kind", "<u4"), ("normal", "<f4", 3), ("radius", "<f4"),
    ("power", "<f4"), ("pmf", "<f4"), ("first", "<u4"), ("count", "<u4")])

FRAME_PARAMS_DTYPE = np.dtype([
    ("camera_origin", "<f4", 3), ("width", "<u4"), ("camera_right", "<f4", 3), ("height", "<u4"),
    ("camera_up", "<f4", 3), ("seed", "<u4"), ("camera_forward", "<f4", 3), ("max_depth", "<u4"),
    ("previous_origin", "<f4", 3), ("sample_offset", "<u4"), ("previous_right", "<f4", 3),
    ("emitter_count", "<u4"), ("previous_up", "<f4", 3), ("tile_row_stride", "<u4"),
    ("previous_forward", "<f4", 3), ("background_share", "<f4"), ("background", "<f4", 3),
    ("chunk_start", "<u4"), ("chunk_size", "<u4"), ("pass_samples", "<u4"), ("emitter_group_count", "<u4"),
    ("background_group", "<u4"), ("lens_radius", "<f4"), ("focus_distance", "<f4"),
    ("environment_turn", "<f4", 2),
    ("emitter_groups", EMITTER_GROUP_DTYPE, MAX_EMITTER_GROUPS)])


def pack_materials(materials: list[Material]) -> np.ndarray:
    """Material records in material-id order."""
    out = np.zeros(max(1, len(materials)), MATERIAL_DTYPE)
    for i, m in enumerate(materials):
        eta, k = m.eta, m.k
        if m.kind == "plastic" and m.roughness >= DELTA_ROUGHNESS:     # a rough coat's table in their words
            eta, k = np.split(coat_words(m.roughness, m.ior), 2)
        if m.kind in GLASS_KINDS:                       # glass: its tint in eta's words, its absorption in k's
            eta, k = m.transmittance, m.absorption
        out[i] = (m.reflectance, MATERIAL_KIND_CODES[m.kind], m.emission, m.roughness, eta, m.ior, k,
                  int(m.is_emissive))
    return out


TEXTURE_HEADER_WORDS = 4   # where the triangle records start, the texture count, two spare words
TEXTURE_ENTRY_WORDS = 4    # per texture: its first texel's word, width, height, its coat levels' first word


def pack_textures(textures: list[np.ndarray], records: np.ndarray | None,
                  coat_iors: dict[int, float] | None = None) -> np.ndarray:
    """The surface-texture buffer (bind group 1, binding 5; wgsl/trace/surface_textures.wgsl) as u32 words:
    a header (where the triangle records start, the image count), an entry per image of ``textures``
    ((H, W, 3) uint8 codes: sRGB textures, raw normal and metal-rough maps; (H, W, 4): a texture with alpha, in the
    top byte), the per-triangle ``records``
    (wgpu_rt.accel.geometry's texture records, in the geometry's stored order), then every image's codes
    packed (R in the low byte), row 0 the image's top, a metal-rough map's followed by the coat tables of its
    plastic (``coat_iors``: image index → the coat's ior; wgpu_rt.trace.coat.coat_levels), which its entry's fourth
    word points at. Without records (no texture or map), a header alone."""
    header = np.zeros(TEXTURE_HEADER_WORDS, np.uint32)
    if records is None:
        return header
    coat_iors = coat_iors or {}
    entries = np.zeros((len(textures), TEXTURE_ENTRY_WORDS), np.uint32)
    header[0] = TEXTURE_HEADER_WORDS + entries.size
    header[1] = len(textures)
    start = header[0] + records.size
    texels = []
    for index, (entry, image) in enumerate(zip(entries, textures)):
        codes = np.asarray(image, np.uint32)
        entry[:3] = start, image.shape[1], image.shape[0]
        alpha = codes[..., 3] << 24 if codes.shape[2] == 4 else 0
        texels.append((codes[..., 0] | codes[..., 1] << 8 | codes[..., 2] << 16 | alpha).ravel())
        start += texels[-1].size
        if index in coat_iors:
            entry[3] = start
            texels.append(coat_levels(coat_iors[index]).view(np.uint32).ravel())
            start += texels[-1].size
    return np.concatenate([header, entries.ravel(), np.asarray(records, np.uint32).ravel(), *texels])


def metal_rough_coats(scene: Scene) -> dict[int, float]:
    """For ``pack_textures``: each metal-rough map's image index in ``scene.textures()`` → the ior of the plastic it
    is on (``Scene.metal_rough_iors``, which refuses a map on another kind)."""
    numbers = {id(image): i for i, image in enumerate(scene.textures())}
    return {numbers[key]: ior for key, ior in scene.metal_rough_iors().items()}


ENVIRONMENT_HEADER_WORDS = 4   # width, height, the sampling weights' total, a spare word


def environment_cells(image: np.ndarray) -> np.ndarray:
    """(H − 1, W) float64 sampling weights of an environment map's cells, the patches of the sphere between
    two neighbouring rows and columns of texels (wgsl/trace/environment.wgsl blends those four corners
    there): the corners' mean luminance times the sine of the cell's middle polar angle, so that a direction
    is drawn about in proportion to its radiance per unit solid angle, and never with probability 0 where
    the map is not black."""
    luminance = np.asarray(image, np.float64) @ LUMINANCE
    corners = luminance[:-1] + luminance[1:]
    corners = corners + np.roll(corners, -1, axis=1)
    height = len(luminance)
    return 0.25 * corners * np.sin(np.pi * (np.arange(height - 1) + 0.5) / (height - 1))[:, None]


def pack_environment(image: np.ndarray | None, importance: bool = True) -> np.ndarray:
    """The environment buffer (bind group 1, binding 6; wgsl/trace/environment.wgsl) as u32 words: a header
    (width, height, the cells' total weight), the texels as float32 RGB bits row by row from the top, then
    for importance sampling (``environment_cells``) each cell's weight, the rows' cumulative distribution and
    each row's cumulative distribution over its cells (float32). Without an environment a header of zeros
    (the kernels then read the constant background); with a total of 0 (a black map, or ``importance``
    False, which measures what the sampling buys) the sky is sampled uniformly over the sphere."""
    header = np.zeros(ENVIRONMENT_HEADER_WORDS, np.uint32)
    if image is None:
        return header
    height, width = image.shape[:2]
    header[0], header[1] = width, height
    weights = environment_cells(image)
    rows = weights.sum(1)
    total = float(rows.sum())
    header[2] = np.float32(total if importance else 0.0).view(np.uint32)
    row_cdf = np.cumsum(rows) / (total if total > 0 else 1.0)
    within = np.cumsum(weights, axis=1) / np.where(rows > 0, rows, 1.0)[:, None]
    row_cdf[-1], within[:, -1] = 1.0, 1.0
    floats = [np.asarray(image, np.float32).ravel(), weights.astype(np.float32).ravel(),
              row_cdf.astype(np.float32), within.astype(np.float32).ravel()]
    return np.concatenate([header, *(part.view(np.uint32) for part in floats)])


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
    records: np.ndarray            # EMITTER_DTYPE, at least one record (a black one when there is none);
                                   # each group's records contiguous, alias indices absolute
    groups: np.ndarray             # EMITTER_GROUP_DTYPE, 1 to MAX_EMITTER_GROUPS records
    triangle_entry: np.ndarray     # (T,) u32: 1 + the index of each triangle's record, 0 if not emissive
    background_group: int = 0
    background_share: float = 0.0  # the background's share of its group (0: no background in the table)

    @property
    def count(self) -> int:
        return len(self.records)

    def power_pmf(self) -> np.ndarray:
        """Per record, the probability that a pick by power alone takes it."""
        pmf = np.zeros(len(self.records))
        for group in self.groups:
            span = slice(int(group["first"]), int(group["first"] + group["count"]))
            pmf[span] = group["pmf"] * self.records["share"][span]
        return pmf


def emissive_triangles(material_ids: np.ndarray, materials: list[Material]) -> np.ndarray:
    """The numbers of the triangles whose material emits (triangle t is made of
    ``materials[material_ids[t]]``; array work: an instanced scene places millions)."""
    emits = np.array([m.is_emissive for m in materials], bool)
    return np.flatnonzero(emits[np.asarray(material_ids, np.intp)]) if len(materials) else np.zeros(0, np.intp)


def emitter_group_count(scene: Scene) -> int:
    """How many emitter groups ``scene``'s emitter table will have, at most (an emitting mesh whose
    triangles all have zero area, or a light of zero power, makes none; clusters may stop short)."""
    emitting = [mesh for mesh in scene.meshes if scene.materials[mesh.material].is_emissive]
    sky = int(np.any(np.asarray(scene.background) > 0))
    constant = sum(isinstance(light, DirectionalLight) for light in scene.lights) + sky
    count = len(emitting) + len(scene.lights) + sky
    if count > MAX_EMITTER_GROUPS and _no_room_for_clusters(constant):
        return 1      # one group of everything (_clustered)
    return min(count, MAX_EMITTER_GROUPS)


def _no_room_for_clusters(constant: int) -> bool:
    """Whether ``constant`` suns and skies, each a group of its own, leave no group for the other lights
    (then every light is in one group, picked by power)."""
    return constant + 1 > MAX_EMITTER_GROUPS


def _triangle_group(tri: np.ndarray, edge1: np.ndarray, edge2: np.ndarray, area: np.ndarray,
                    power: np.ndarray) -> tuple:
    """(kind, center, normal, radius, importance power) of the emitter group of triangles ``tri``: flat
    (one normal, every vertex in its plane) or solid, around their area-weighted centroid (which lies in
    a flat group's plane)."""
    center = (area[:, None] * tri.mean(axis=1)).sum(0) / area.sum()
    radius = float(np.sqrt(np.max(np.sum((tri.reshape(-1, 3) - center) ** 2, axis=1))))
    normals = np.cross(edge1, edge2)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    normal = normals[np.argmax(area)]
    flat = (np.all(normals @ normal >= 1 - FLAT_TOLERANCE)
            and np.all(np.abs((tri.reshape(-1, 3) - center) @ normal) <= FLAT_TOLERANCE * max(radius, 1e-30)))
    # radiance·area (a flat light seen face on), a quarter of it for a solid (its mean projected area)
    lit = power.sum() / np.pi
    return (GROUP_FLAT, center, normal, radius, lit) if flat else (GROUP_SOLID, center, 0, radius, lit / 4)


def _clustered(groups: list[tuple]) -> tuple[list[tuple], np.ndarray]:
    """More groups than MAX_EMITTER_GROUPS, (first, count, kind, center, normal, radius, importance power)
    each, made into at most that many: suns and skies stay as they are, the rest are split into spatial
    clusters by repeated median cuts of the largest cluster along its longest axis (if suns and skies
    leave no room, one group of everything, picked by power). A cluster of several groups is
    solid (a flat member counts with a quarter of its power, its mean projected area), around the
    power-weighted centroid. Returns the new groups and the order of the records that makes each one's
    contiguous."""
    constant = [g for g, group in enumerate(groups) if group[2] == GROUP_CONSTANT]
    finite = [g for g in range(len(groups)) if g not in constant]
    if _no_room_for_clusters(len(constant)):
        everything = sum(group[1] for group in groups)
        return [(0, everything, GROUP_CONSTANT, 0, 0, 0, 1.0)], np.arange(everything)
    centers = np.array([np.broadcast_to(groups[g][3], 3) for g in range(len(groups))], np.float64)
    parts = [finite]
    while len(parts) + len(constant) < MAX_EMITTER_GROUPS:
        extent = [np.ptp(centers[part], axis=0).max() if len(part) > 1 else -1.0 for part in parts]
        largest = int(np.argmax(extent))
        if extent[largest] <= 0:
            break
        part = parts.pop(largest)
        axis = int(np.argmax(np.ptp(centers[part], axis=0)))
        ranked = [part[i] for i in np.argsort(centers[part, axis], kind="stable")]
        parts += [ranked[:len(ranked) // 2], ranked[len(ranked) // 2:]]
    clusters = parts + [[g] for g in constant]

    merged, order = [], []
    for members in clusters:
        first = len(order)
        for g in members:
            order.extend(range(groups[g][0], groups[g][0] + groups[g][1]))
        if len(members) == 1:
            merged.append((first, len(order) - first, *groups[members[0]][2:]))
        else:
            lit = np.array([groups[g][6] * (0.25 if groups[g][2] == GROUP_FLAT else 1.0) for g in members])
            centers = np.array([np.broadcast_to(groups[g][3], 3) for g in members], np.float64)
            center = (lit[:, None] * centers).sum(0) / lit.sum()
            reach = max(np.linalg.norm(centers[i] - center) + groups[g][5] for i, g in enumerate(members))
            merged.append((first, len(order) - first, GROUP_SOLID, center, 0, reach, lit.sum()))
    return merged, np.array(order, np.intp)


def build_emitter_table(scene: Scene, numbers: np.ndarray, triangles: np.ndarray, material_ids: np.ndarray,
                        materials: list[Material], scene_radius: float,
                        object_ids: np.ndarray | None = None, frame: int = 0) -> EmitterTable:
    """The emitter table of ``scene``'s lights as they are at ``frame`` and of its emissive triangles ``numbers``
    (from ``emissive_triangles``), whose world-space vertices are ``triangles`` (len(numbers), 3, 3); the
    scene has len(material_ids) triangles, triangle t of mesh ``object_ids[t]`` (default: all of one)."""
    numbers = np.asarray(numbers, np.intp)
    tri = np.asarray(triangles, np.float64).reshape(-1, 3, 3)
    edge1, edge2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    area = 0.5 * np.linalg.norm(np.cross(edge1, edge2), axis=1)
    keep = area > 0
    numbers, tri, edge1, edge2, area = numbers[keep], tri[keep], edge1[keep], edge2[keep], area[keep]
    triangle_object = (np.zeros(len(numbers), np.intp) if object_ids is None
                       else np.asarray(object_ids, np.intp)[numbers])
    order = np.argsort(triangle_object, kind="stable")   # each mesh's triangles contiguous
    numbers, tri, edge1, edge2, area = numbers[order], tri[order], edge1[order], edge2[order], area[order]
    triangle_object = triangle_object[order]
    triangle_material = np.asarray(material_ids, np.intp)[numbers]
    material_emission = np.array([m.emission for m in materials], np.float64).reshape(-1, 3)
    emission = material_emission[triangle_material].reshape(-1, 3)
    # an emission texture: its image's number, and its mean colour in the triangle's power (a pick's weight);
    # per mesh that emits (a moving one's table is rebuilt every frame), each image's mean once
    object_image = np.full(max(1, len(scene.meshes)), NO_TEXTURE, np.uint32)
    object_colour = np.ones((len(object_image), 3))
    if object_ids is not None and any(mesh.emission_texture is not None for mesh in scene.meshes):
        image_numbers = {id(image): i for i, image in enumerate(scene.textures())}
        means: dict[int, np.ndarray] = {}
        for o in np.unique(triangle_object):
            image = scene.meshes[o].emission_texture
            if image is not None:
                object_image[o] = image_numbers[id(image)]
                object_colour[o] = means.setdefault(id(image), srgb8_mean(image))
    if object_ids is not None:      # a cut-out emitter gives light where it is there: its share of the texels
        for o in np.unique(triangle_object):
            if scene.meshes[o].is_cut_out:
                object_colour[o] *= cut_out_coverage(scene.meshes[o])
    triangle_image = object_image[triangle_object]
    triangle_power = np.pi * area * ((emission * object_colour[triangle_object]) @ LUMINANCE)

    lights = []  # (kind, position, edge1, radiance, power, group kind, importance power, edge2)
    radius = min(scene_radius, max(view_radius(scene.camera), VIEW_RADIUS_FLOOR * scene_radius))
    for light in scene.lights_at(frame):
        if isinstance(light, PointLight):
            intensity = np.asarray(light.intensity, np.float64)
            spot = isinstance(light, SpotLight)
            # a spot's power: its cone's solid angle to halfway through the fall-off
            solid_angle = (2 * np.pi * (1 - np.cos(np.radians((light.cutoff_angle + light.beam_width) / 2)))
                           if spot else 4 * np.pi)
            lights.append((EMITTER_POINT, light.position, light.direction if spot else 0, intensity,
                           solid_angle * LUMINANCE @ intensity, GROUP_POINT, LUMINANCE @ intensity,
                           np.radians([light.cutoff_angle, light.beam_width, 0]) if spot else 0))
        elif isinstance(light, DirectionalLight):
            irradiance = np.asarray(light.irradiance, np.float64)
            lights.append((EMITTER_DIRECTIONAL, 0, light.direction, irradiance,
                           np.pi * radius ** 2 * LUMINANCE @ irradiance, GROUP_CONSTANT, LUMINANCE @ irradiance, 0))
    background = scene.background_mean()   # an environment map's mean over the sphere
    if np.any(np.asarray(scene.background) > 0):
        luminance = max(float(LUMINANCE @ background), 1e-6)
        lights.append((EMITTER_BACKGROUND, 0, 0, background, 4 * np.pi ** 2 * radius ** 2 * luminance,
                       GROUP_CONSTANT, np.pi * luminance, 0))
    if scene.has_moving_lights:     # every light keeps its record, dark or not
        lights = [(*light[:4], max(light[4], DARK_LIGHT_POWER), *light[5:]) for light in lights]
    lights = [light for light in lights if light[4] > 0]

    triangle_count = len(numbers)
    count = triangle_count + len(lights)
    records = np.zeros(max(1, count), EMITTER_DTYPE)
    records["kind"][:triangle_count] = EMITTER_TRIANGLE
    records["position"][:triangle_count] = tri[:, 0]
    records["edge1"][:triangle_count], records["edge2"][:triangle_count] = edge1, edge2
    records["area"][:triangle_count], records["radiance"][:triangle_count] = area, emission
    records["triangle"][:triangle_count] = numbers
    records["emission_image"] = NO_TEXTURE
    records["emission_image"][:triangle_count] = triangle_image
    for i, (kind, position, direction, value, *_, cone) in enumerate(lights, start=triangle_count):
        records["kind"][i], records["position"][i], records["edge1"][i], records["radiance"][i] = (
            kind, position, direction, value)
        records["edge2"][i] = cone
    power = np.concatenate([triangle_power, [light[4] for light in lights]])

    # groups: (first, count, kind, center, normal, radius, importance power)
    groups = []
    _, firsts, counts = np.unique(triangle_object, return_index=True, return_counts=True)
    for first, n in zip(firsts, counts):
        span = slice(first, first + n)
        groups.append((first, n, *_triangle_group(tri[span], edge1[span], edge2[span], area[span],
                                                  triangle_power[span])))
    for i, (kind, position, *_, group_kind, lit, _) in enumerate(lights, start=triangle_count):
        groups.append((i, 1, group_kind, position if kind == EMITTER_POINT else 0, 0, 0, lit))
    record_triangle = np.concatenate([numbers, np.full(len(lights), -1)])   # scene triangle of each record
    if count == 0:
        groups = [(0, 1, GROUP_CONSTANT, 0, 0, 0, 1.0)]
    elif len(groups) > MAX_EMITTER_GROUPS:
        groups, order = _clustered(groups)
        records, power, record_triangle = records[order], power[order], record_triangle[order]

    table = np.zeros(len(groups), EMITTER_GROUP_DTYPE)
    for g, (first, n, kind, center, normal, group_radius, lit) in enumerate(groups):
        span = slice(first, first + n)
        table[g] = (center, kind, normal, group_radius, lit, power[span].sum() / power.sum() if count else 1.0,
                    first, n)
        if count:
            threshold, alias = alias_table(power[span])
            records["share"][span] = power[span] / power[span].sum()
            records["alias_threshold"][span], records["alias_index"][span] = threshold, alias + first
            records["group"][span] = g
    triangle_entry = np.zeros(len(material_ids), np.uint32)
    is_triangle = record_triangle >= 0
    triangle_entry[record_triangle[is_triangle]] = np.flatnonzero(is_triangle) + 1
    background = np.flatnonzero((records["kind"][:count] == EMITTER_BACKGROUND) & ~is_triangle)
    if not len(background):
        return EmitterTable(records, table, triangle_entry)
    return EmitterTable(records, table, triangle_entry, int(records["group"][background[0]]),
                        float(records["share"][background[0]]))


LEAST_COVERAGE = 1e-3     # a cut-out emitter's power counts at least this share of its area (never 0)


def cut_out_coverage(mesh) -> float:
    """The share of a cut-out mesh's texels that are there: those of alpha at least one half (glTF's MASK), or the
    mean alpha (BLEND); at least LEAST_COVERAGE. An estimate for picking lights by power (the texture's repeats
    and the triangles' coordinates are not followed)."""
    alpha = np.asarray(mesh.texture)[..., 3]
    share = float(np.mean(alpha) / 255.0) if mesh.alpha_mode == "blend" else float(np.mean(alpha >= 128))
    return max(share, LEAST_COVERAGE)


def srgb8_mean(image: np.ndarray) -> np.ndarray:
    """(3,) the mean linear colour of an (H, W, 3) sRGB8 image, from each channel's count of its 256 codes (a
    4-megapixel image in tens of milliseconds, where decoding every texel takes a second)."""
    codes = np.asarray(image, np.uint8).reshape(-1, 3)
    decoded = linear_from_srgb8(np.arange(256, dtype=np.uint8)).astype(np.float64)
    counts = np.stack([np.bincount(codes[:, c], minlength=256) for c in range(3)], -1)
    return (decoded[:, None] * counts).sum(0) / max(1, len(codes))


def group_importance(groups: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(G,) the irradiance each emitter group is estimated to give at point ``x`` (as
    wgsl/trace/emitters.wgsl's group_importance): constant for a sun, a sky or the group of everything;
    intensity / d² for a point light; radiance·area / max(d², radius²) for an area light, a quarter of
    that for a solid one, and for a flat one times the cosine at the light bounded over its bounding
    sphere (0 behind its plane)."""
    offset = np.asarray(x, np.float64) - groups["center"]
    d2 = np.sum(offset * offset, axis=1)
    power = groups["power"].astype(np.float64)
    near = np.maximum(d2, groups["radius"].astype(np.float64) ** 2)
    height = np.sum(offset * groups["normal"], axis=1)
    distance = np.sqrt(np.maximum(d2, 1e-30))
    cos_light = np.clip(height / distance, -1, 1)
    sin_bound = np.minimum(groups["radius"] / distance, 1)
    cos_bound = np.sqrt(1 - sin_bound ** 2)
    cos_tilted = cos_light * cos_bound + np.sqrt(1 - cos_light ** 2) * sin_bound
    flat = np.where(height <= 0, 0.0, np.where(cos_light >= cos_bound, 1.0, cos_tilted)) * power / near
    kind = groups["kind"]
    return np.select([kind == GROUP_POINT, kind == GROUP_SOLID, kind == GROUP_FLAT],
                     [power / np.maximum(d2, 1e-20), power / near, flat], power)


def group_probabilities(groups: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(G,) the probability that next-event estimation at ``x`` picks each group: by ``group_importance``,
    mixed with DEFENSIVE_SHARE of picks by power (all by power where every estimate is 0)."""
    if len(groups) == 1:
        return np.ones(1)
    importance = group_importance(groups, x)
    total = importance.sum()
    by_power = groups["pmf"].astype(np.float64)
    if total <= 0:
        return by_power
    return (1 - DEFENSIVE_SHARE) * importance / total + DEFENSIVE_SHARE * by_power


def camera_vectors(camera, width: int, height: int) -> dict[str, np.ndarray]:
    """origin, unit basis, right·tan_x, up·tan_y and the tans of ``camera`` for a width×height film."""
    right, up, forward = camera.basis()
    tan_x, tan_y = camera.tan_half_fov(width, height)
    return {"origin": camera.origin, "unit_right": right, "unit_up": up, "right": right * tan_x,
            "up": up * tan_y, "forward": forward, "tan": (tan_x, tan_y)}
