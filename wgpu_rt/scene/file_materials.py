"""A mesh file's own materials → ``Material``: glTF's metallic-roughness model (with its transmission, volume, ior,
emissive-strength and clearcoat extensions) and OBJ's MTL statements, mapped onto the tracer's kinds.

Both formats describe a surface by a base colour, how metallic it is, a perceptual roughness ``r`` (the GGX
alpha is r², as glTF defines it), how much light it transmits and what it emits. The tracer has no blend of
them, so each material becomes the one kind that carries most of its look:

- transmission ≥ 0.5: ``dielectric`` of the file's ior, its transmittance the base colour (glTF tints what the
  surface transmits by it; the tracer, as Mitsuba's specular_transmittance, at each crossing); with a volume
  (``KHR_materials_volume`` of a thickness above 0; 0 is glTF's thin wall, which has no inside) light inside it is
  absorbed at −ln(attenuationColor) / attenuationDistance per unit of the file's world (Beer–Lambert, as glTF
  defines it: what crosses that distance keeps the attenuation colour); smooth glass on a geometry with an open
  edge (a window pane or a shell modelled as one surface) becomes a ``thin_dielectric`` of the same ior and
  tint (``FileMaterials.as_thin``; a solid dielectric there would bend the world behind it for good);
- else metallic ≥ 0.5: ``conductor`` whose Fresnel term is 1, tinted by the base colour (glTF's metals reflect
  their base colour head-on and rise to white only at grazing angles, which this leaves out);
- else ``plastic``: the base colour under a coat of the file's ior and GGX alpha r² (glTF's non-metals are a
  diffuse base under a specular layer of ior 1.5, F0 = 0.04; smooth at r = 0, Mitsuba's roughplastic above); with
  ``KHR_materials_clearcoat`` of a factor ≥ 0.5 (lacquer, varnish, a car's paint over a non-metal) the coat is the
  clear coat, of its ``clearcoatRoughnessFactor`` (its textures are not read; a metal keeps its own roughness);
- an OBJ material that names no specular colour (black or absent ``Ks``) and no ``Pr``: ``diffuse``; one with a
  ``map_Pr`` or ``map_Pm`` image (the MTL PBR extension's roughness and metalness per texel) that is not glass: the
  ``plastic`` of its ``Kd`` under the metal-rough map of them (``meshio.obj_metal_rough_map``).

Emission is the emissive colour times its strength (its emissive texture, read per texel, tints it:
``meshio.file_emission_texture``). A material's metallic-roughness texture is read per texel: the material becomes
the ``plastic`` of its base colour and ior, and its meshes carry the texture with the factors applied
(``meshio.file_metal_rough_map``, ``Mesh.metal_rough_map``), which makes each point that plastic or the metal
above, of the texel's roughness; on glass its roughness counts by its mean (a dielectric keeps one). The base colour
texture is read per texel (``meshio.file_texture``).
Values outside glTF's ranges are a SceneError naming the file and the material.
"""

from __future__ import annotations

import json
import struct
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import SceneError
from .model import Material

# OBJ illumination models that mean refraction (4: glass, 6, 7: refraction with Fresnel, 9: glass, no ray trace).
OBJ_GLASS_ILLUMS = {4, 6, 7, 9}
OBJ_METAL_ROUGH_MAPS = ("map_pr", "map_pm")   # the MTL PBR extension's roughness and metalness images
GLTF_SUFFIXES = (".glb", ".gltf")
# Extensions a glTF file may require that encode its data in a way not decoded here (trimesh would read zeros)
UNREAD_EXTENSIONS = {"KHR_draco_mesh_compression": "Draco-compressed meshes",
                     "EXT_meshopt_compression": "meshoptimizer-compressed buffers",
                     "KHR_texture_basisu": "KTX2 / Basis Universal textures"}


def pbr_material(base_color, metallic: float, roughness: float, transmission: float = 0.0, ior: float = 1.5,
                 emission=(0.0, 0.0, 0.0), specular: bool = True, transmittance=None,
                 absorption=(0.0, 0.0, 0.0)) -> Material:
    """The tracer's material for a metallic-roughness description (see the module's doc); without
    ``specular`` a non-metal has no specular layer; glass is tinted by ``transmittance`` (default: the base
    colour, as glTF's transmission is) and absorbs inside at ``absorption`` per unit length."""
    alpha, emission = float(roughness) ** 2, np.asarray(emission, np.float32)
    if transmission >= 0.5:
        tint = base_color if transmittance is None else transmittance
        return Material("dielectric", ior=ior, roughness=alpha, transmittance=tint, emission=emission,
                        absorption=absorption)
    if metallic >= 0.5:
        return Material("conductor", reflectance=base_color, roughness=alpha, eta=0.0, k=1.0, emission=emission)
    if specular:
        return Material("plastic", reflectance=base_color, ior=ior, roughness=alpha, emission=emission)
    return Material("diffuse", reflectance=base_color, emission=emission)


def shown(value) -> str:
    """``value``'s repr, cut to 60 characters (a field may hold anything)."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


class FieldReader:
    """The fields of one entry of a glTF or MTL file (a material, a node, a light), each checked against its range,
    errors naming the file and the entry ("where")."""

    def __init__(self, where: str, data: dict):
        if not isinstance(data, dict):
            raise SceneError(f"{where}: expected an object, got {shown(data)}")
        self.where, self.data = where, data

    def fail(self, message: str):
        raise SceneError(f"{self.where}: {message}")

    def numbers(self, key: str, default, length: int | None = None, low: float = 0.0, high: float = 1.0):
        """The field ``key`` (``default`` where absent): one number, or with ``length`` the first ``length`` of
        at least that many (a single one stands for all); each finite and in [low, high]."""
        value = self.data.get(key, default)
        try:
            array = np.asarray(value, np.float64).reshape(-1)
        except (TypeError, ValueError, OverflowError):
            self.fail(f"{key} must be numbers, got {shown(value)}")
        wanted = length or 1
        if len(array) == 1:
            array = np.broadcast_to(array, (wanted,))
        if len(array) < wanted or (length is None and len(array) != 1):
            wanted_text = "a number" if length is None else f"1 or {length} numbers"
            self.fail(f"{key} must be {wanted_text}, got {shown(value)}")
        array = array[:wanted]
        if not np.all(np.isfinite(array)) or np.any(array < low) or np.any(array > high):
            self.fail(f"{key} must be in [{low:g}, {high:g}], got {shown(value)}")
        return array if length is not None else float(array[0])


def _texture_mean(image, where: str) -> np.ndarray:
    """The mean of a PIL image's RGB codes over 255 (read raw, as glTF's metallic-roughness texture is), as
    float64."""
    try:
        pixels = np.asarray(image.convert("RGB"), np.uint8).reshape(-1, 3)
    except Exception as err:   # PIL raises many types for an image it cannot decode
        raise SceneError(f"{where}: cannot read a texture image ({type(err).__name__}: {err})") from err
    if len(pixels) == 0:
        return np.ones(3)
    return pixels.mean(axis=0) / 255.0


def _uv_matrix(transform: FieldReader) -> np.ndarray:
    """glTF's KHR_texture_transform as a 3×3 matrix: offset · rotation · scale, the rotation turning the
    coordinates counter-clockwise in glTF's frame (v down), so that the image turns clockwise."""
    offset = transform.numbers("offset", [0.0, 0.0], length=2, low=-np.inf, high=np.inf)
    scale = transform.numbers("scale", [1.0, 1.0], length=2, low=-np.inf, high=np.inf)
    angle = transform.numbers("rotation", 0.0, low=-np.inf, high=np.inf)
    cos, sin = np.cos(angle), np.sin(angle)
    return np.array([[cos * scale[0], sin * scale[1], offset[0]],
                     [-sin * scale[0], cos * scale[1], offset[1]],
                     [0.0, 0.0, 1.0]])


def transformed_uvs(uvs: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Texture coordinates in the tracer's convention (v up, as trimesh reads them) through a glTF texture
    transform (``_uv_matrix``, which works in glTF's, v down)."""
    gltf = np.stack([uvs[:, 0], 1.0 - uvs[:, 1], np.ones(len(uvs))], -1).astype(np.float64)
    moved = gltf @ matrix.T
    return np.stack([moved[:, 0], 1.0 - moved[:, 1]], -1).astype(np.float32)


def gltf_json(path: Path) -> dict:
    """The JSON of a .gltf file or of a .glb's first chunk."""
    data = Path(path).read_bytes()
    try:
        if data[:4] == b"glTF":
            length, kind = struct.unpack_from("<I4s", data, 12)
            if kind != b"JSON":
                raise ValueError("its first chunk is not JSON")
            data = data[20:20 + length]
        tree = json.loads(data)
    except (ValueError, struct.error, UnicodeDecodeError) as err:
        raise SceneError(f"{path}: cannot read the glTF file's JSON ({err})") from err
    if not isinstance(tree, dict):
        raise SceneError(f"{path}: the glTF file's JSON is not an object")
    required = tree.get("extensionsRequired") or []
    unread = [name for name in (required if isinstance(required, list) else []) if name in UNREAD_EXTENSIONS]
    if unread:
        raise SceneError(f"{path}: it needs the glTF extension {unread[0]} ({UNREAD_EXTENSIONS[unread[0]]}), which "
                         f"is not read; export the file without it")
    return tree


def gltf_material(entry: dict, where: str, trimesh_material=None) -> Material:
    """The tracer's material for one entry of a glTF file's ``materials`` list; ``trimesh_material`` (trimesh's
    PBRMaterial of it) lends its decoded textures for their means."""
    if not isinstance(entry, dict):
        raise SceneError(f"{where}: expected an object, got {entry!r}")
    pbr = FieldReader(where, entry.get("pbrMetallicRoughness") or {})
    extensions = entry.get("extensions") or {}
    base = pbr.numbers("baseColorFactor", [1.0, 1.0, 1.0, 1.0], length=4)[:3]
    metallic = pbr.numbers("metallicFactor", 1.0)
    roughness = pbr.numbers("roughnessFactor", 1.0)
    top = FieldReader(where, entry)
    emission = top.numbers("emissiveFactor", [0.0, 0.0, 0.0], length=3)
    strength = FieldReader(where, extensions.get("KHR_materials_emissive_strength") or {})
    emission = emission * strength.numbers("emissiveStrength", 1.0, high=np.inf)
    transmission = FieldReader(where, extensions.get("KHR_materials_transmission") or {})
    transmission = transmission.numbers("transmissionFactor", 0.0)
    ior = FieldReader(where, extensions.get("KHR_materials_ior") or {}).numbers("ior", 1.5, low=1.0, high=np.inf)
    absorption = _volume_absorption(FieldReader(where, extensions.get("KHR_materials_volume") or {}))
    coat = FieldReader(where, extensions.get("KHR_materials_clearcoat") or {})
    if coat.numbers("clearcoatFactor", 0.0) >= 0.5 and metallic < 0.5 and transmission < 0.5:
        roughness = coat.numbers("clearcoatRoughnessFactor", 0.0)     # a lacquered non-metal: the coat's gloss
    textures = trimesh_material
    if getattr(textures, "metallicRoughnessTexture", None) is not None:
        if transmission < 0.5:     # a plastic its meshes' metal-rough map turns to metal and roughens per point
            return pbr_material(base, 0.0, roughness, ior=ior, emission=emission)
        # glass keeps one roughness: glTF's roughness in the green channel (linear), by its mean
        roughness *= _texture_mean(textures.metallicRoughnessTexture, where)[1]
    return pbr_material(base, metallic, roughness, transmission, ior, emission, absorption=absorption)


# An attenuation colour of 0 would absorb all at once; below this it absorbs as this does (e⁻²³ per distance).
LEAST_ATTENUATION_COLOR = 1e-10


def _volume_absorption(volume: FieldReader) -> np.ndarray:
    """The absorption per unit length of a glTF ``KHR_materials_volume`` (0 without one, or for a thin wall)."""
    thickness = volume.numbers("thicknessFactor", 0.0, high=np.inf)
    colour = volume.numbers("attenuationColor", [1.0, 1.0, 1.0], length=3)
    if "attenuationDistance" not in volume.data or thickness == 0.0:      # glTF's default distance: infinite
        return np.zeros(3, np.float32)
    distance = volume.numbers("attenuationDistance", None, high=np.inf)
    if distance == 0.0:
        volume.fail("attenuationDistance must be above 0, got 0")
    return (np.log(1.0 / np.maximum(colour, LEAST_ATTENUATION_COLOR)) / distance).astype(np.float32)


def placed_absorption(own: dict[str, Material], transform: np.ndarray) -> dict[str, Material]:
    """A mesh file's own materials as ``transform`` places the file in a scene: its absorbing glass's absorption (per
    unit of the file's world, as glTF's attenuationDistance is given) divided by the transform's scale (the cube root
    of its determinant's size), so that a model scaled from centimetres to metres keeps its colour."""
    factor = float(abs(np.linalg.det(np.asarray(transform, np.float64)[:3, :3]))) ** (1.0 / 3.0)
    if factor == 1.0 or not 0.0 < factor < np.inf:     # (a singular transform is refused where it is placed)
        return own
    return {name: replace(m, absorption=(m.absorption / factor).astype(np.float32)) if m.absorbs else m
            for name, m in own.items()}


def obj_roughness(fields: FieldReader) -> float:
    """An MTL material's perceptual roughness (its statements lower-cased in ``fields``): ``Pr``, else the one
    Blender writes as ``Ns`` (r = 1 − √(Ns/1000)) where ``Ks`` is not black, else 1."""
    if "pr" in fields.data:
        return fields.numbers("pr", 1.0)
    if np.any(fields.numbers("ks", 0.0, length=3) > 0):
        return float(1.0 - np.sqrt(min(fields.numbers("ns", 0.0, high=np.inf), 1000.0) / 1000.0))
    return 1.0


def obj_material(simple, where: str) -> Material:
    """The tracer's material for an OBJ file's MTL material (trimesh's SimpleMaterial): ``Kd`` the base
    colour, ``Ke`` emission, ``Pm``/``Pr`` (the MTL PBR extension) metalness and roughness, else the roughness
    Blender writes as ``Ns`` (r = 1 − √(Ns/1000)) where ``Ks`` is not black; without either, diffuse; glass, tinted
    by the transmission filter ``Tf`` (not by ``Kd``), where
    ``illum`` is 4, 6, 7 or 9 or the dissolve ``d`` is below 1 (``Tr`` above 0), of index ``Ni``. A material that
    is not glass with a ``map_Pr`` or ``map_Pm`` image is the plastic of its ``Kd`` that its meshes' metal-rough map
    (``meshio.obj_metal_rough_map``) makes metal or not per point."""
    fields = FieldReader(where, {key.lower(): value for key, value in (getattr(simple, "kwargs", None) or {}).items()})
    base = fields.numbers("kd", 0.8, length=3)
    specular = "pr" in fields.data or bool(np.any(fields.numbers("ks", 0.0, length=3) > 0))
    roughness = obj_roughness(fields)
    dissolve = fields.numbers("d", 1.0) if "d" in fields.data else 1.0 - fields.numbers("tr", 0.0)
    glass = int(fields.numbers("illum", 2, high=10)) in OBJ_GLASS_ILLUMS or dissolve < 1.0
    ior = fields.numbers("ni", 1.5, low=1.0, high=np.inf) if glass else 1.5
    if not glass and any(key in fields.data for key in OBJ_METAL_ROUGH_MAPS):
        # a plastic that its meshes' metal-rough map (meshio.obj_metal_rough_map) turns to metal and roughens per point
        return pbr_material(base, 0.0, roughness, ior=ior, emission=fields.numbers("ke", 0.0, length=3, high=np.inf))
    return pbr_material(base, fields.numbers("pm", 0.0), roughness, float(glass), ior,
                        fields.numbers("ke", 0.0, length=3, high=np.inf), specular,
                        transmittance=fields.numbers("tf", 1.0, length=3))


class FileMaterials:
    """The materials of one mesh file, named ``<base>/<material name>`` (``<base>/material<i>`` when unnamed),
    each made once however many geometries use it. ``material_of(geometry)`` is a geometry's material's name
    (None where it has none); ``materials`` maps every name used to its Material."""

    def __init__(self, path: Path, base: str):
        self.path, self.base = Path(path), base
        self.gltf = self.path.suffix.lower() in GLTF_SUFFIXES
        self._entries: list | None = None
        self._buffers = None     # (gltf_animation.GltfBuffers, when a texture coordinate set is read)
        self.materials: dict[str, Material] = {}

    @property
    def entries(self) -> list:
        """A glTF file's ``materials`` list (read when first asked for)."""
        if self._entries is None:
            entries = (gltf_json(self.path).get("materials") or []) if self.gltf else []
            if not isinstance(entries, list):
                raise SceneError(f"{self.path}: the glTF file's materials are not a list")
            self._entries = entries
        return self._entries

    def _gltf_index(self, trimesh_material) -> int | None:
        """The index in the file's materials list of trimesh's reading of one: by name, else by its factors."""
        name = getattr(trimesh_material, "name", None)
        name = name if isinstance(name, str) else None       # (a name that is not a string names nothing)
        named = [i for i, entry in enumerate(self.entries) if isinstance(entry, dict) and entry.get("name") == name]
        if name and named:
            return named[0]
        for i, entry in enumerate(self.entries):
            if isinstance(entry, dict) and not entry.get("name") and self._same_factors(entry, trimesh_material):
                return i
        return None

    @staticmethod
    def _same_factors(entry: dict, trimesh_material) -> bool:
        """Whether trimesh's reading has an unnamed entry's factors (the first such entry is taken: two unnamed
        materials alike in them but not in their extensions are not told apart)."""
        try:
            return FileMaterials._factors_match(entry, trimesh_material)
        except (TypeError, ValueError, IndexError):   # a malformed entry: gltf_material names what is wrong
            return False

    @staticmethod
    def _factors_match(entry: dict, trimesh_material) -> bool:
        pbr = entry.get("pbrMetallicRoughness") or {}
        ours = (pbr.get("metallicFactor"), pbr.get("roughnessFactor"))
        theirs = (getattr(trimesh_material, "metallicFactor", None), getattr(trimesh_material, "roughnessFactor", None))
        if any((a is None) != (b is None) or (a is not None and abs(float(a) - float(b)) > 1e-6)
               for a, b in zip(ours, theirs)):
            return False
        colour = getattr(trimesh_material, "baseColorFactor", None)
        factor = pbr.get("baseColorFactor")
        if (colour is None) != (factor is None):
            return False
        # trimesh keeps the colour as 8-bit codes of the linear factor.
        return colour is None or np.allclose(np.asarray(colour[:3]) / 255.0, np.asarray(factor[:3], float),
                                             atol=0.6 / 255)

    def _texture_info(self, geometry, key: str) -> tuple[dict | None, str]:
        """The textureInfo ``key`` (e.g. "normalTexture") of ``geometry``'s glTF material, None where it has none,
        and the material's label for errors."""
        trimesh_material = getattr(geometry.visual, "material", None)
        index = self._gltf_index(trimesh_material) if self.gltf and trimesh_material is not None else None
        if index is None:
            return None, ""
        entry = self.entries[index]
        pbr = key in ("baseColorTexture", "metallicRoughnessTexture")
        info = (entry.get("pbrMetallicRoughness") or {}).get(key) if pbr else entry.get(key)
        return (info if isinstance(info, dict) else None), entry.get("name") or f"material{index}"

    def normal_scale(self, geometry) -> float:
        """The ``scale`` of the normal texture of ``geometry``'s glTF material (1 where it gives none)."""
        if getattr(getattr(geometry.visual, "material", None), "normalTexture", None) is None:
            return 1.0
        texture, label = self._texture_info(geometry, "normalTexture")
        if texture is None:
            return 1.0
        return FieldReader(f"{self.path}: material {label!r}: normalTexture", texture).numbers("scale", 1.0, high=np.inf)

    def texture_transform(self, geometry) -> np.ndarray | None:
        """The 3×3 matrix (of glTF's texture coordinates, v down) of the ``KHR_texture_transform`` on
        ``geometry``'s glTF material's base colour, normal, emissive and metallic-roughness textures, None where none
        has one. The tracer reads them at one set of coordinates, so two different transforms are a SceneError."""
        matrices = {}
        for key in ("baseColorTexture", "normalTexture", "emissiveTexture", "metallicRoughnessTexture"):
            texture, label = self._texture_info(geometry, key)
            transform = ((texture or {}).get("extensions") or {}).get("KHR_texture_transform")
            if transform is None:
                continue
            where = f"{self.path}: material {label!r}: {key}'s KHR_texture_transform"
            if not isinstance(transform, dict):
                raise SceneError(f"{where}: expected an object, got {transform!r}")
            matrices[key] = _uv_matrix(FieldReader(where, transform))
        if any(not np.allclose(matrix, next(iter(matrices.values()))) for matrix in matrices.values()):
            raise SceneError(f"{self.path}: material {label!r}: its textures have different KHR_texture_transforms "
                             f"({', '.join(matrices)}); the tracer reads them at one set of coordinates")
        return next(iter(matrices.values()), None)

    def texture_coordinates(self, geometry) -> np.ndarray | None:
        """(V, 2) float32: the glTF texture coordinate set ``TEXCOORD_n`` that ``geometry``'s material reads its base
        colour, normal, emissive and metallic-roughness textures at, where that is not the first (trimesh reads
        ``TEXCOORD_0`` alone), v = 1 at the image's top as trimesh has it; None where they read the first. Textures
        at two sets are a SceneError (the tracer reads them at one)."""
        sets, label = {}, ""
        for key in ("baseColorTexture", "normalTexture", "emissiveTexture", "metallicRoughnessTexture"):
            texture, named = self._texture_info(geometry, key)
            if texture is not None:
                label = named
                sets[key] = texture.get("texCoord", 0)
        if not any(sets.values()):
            return None
        if len(set(map(repr, sets.values()))) > 1:
            raise SceneError(f"{self.path}: material {label!r}: its textures are read at texture coordinate sets "
                             f"{', '.join(f'{key} {n!r}' for key, n in sets.items())}; the tracer reads one set")
        number = next(iter(sets.values()))
        if not isinstance(number, int) or isinstance(number, bool) or number < 0:
            raise SceneError(f"{self.path}: material {label!r}: texCoord must be a set's number, got {shown(number)}")
        coordinates = self._primitive_attribute(geometry, f"TEXCOORD_{number}", label)
        if coordinates.shape != (len(geometry.vertices), 2) or not np.all(np.isfinite(coordinates)):
            raise SceneError(f"{self.path}: material {label!r}: its TEXCOORD_{number} is not one finite VEC2 a vertex")
        return np.column_stack([coordinates[:, 0], 1.0 - coordinates[:, 1]]).astype(np.float32)

    def _primitive_attribute(self, geometry, name: str, label: str) -> np.ndarray:
        """The attribute ``name`` of the glTF primitive trimesh read as ``geometry`` (the one whose POSITION values
        are its vertices); a SceneError where none has one."""
        from .gltf_animation import GltfBuffers

        if self._buffers is None:
            self._buffers = GltfBuffers(self.path, gltf_json(self.path))
        meshes = self._buffers.tree.get("meshes") or []
        primitives = [p for mesh in (meshes if isinstance(meshes, list) else []) if isinstance(mesh, dict)
                      and isinstance(mesh.get("primitives"), list) for p in mesh["primitives"]]
        primitive = self._buffers.primitive_holding(primitives, geometry.vertices, name)
        if primitive is None:
            raise SceneError(f"{self.path}: material {label!r}: its textures are read at {name}, which its mesh has "
                             f"not")
        return self._buffers.accessor(primitive["attributes"][name], f"{self.path}: material {label!r}: {name}")

    def material_of(self, geometry, geometry_name: str) -> str | None:
        """The name of ``geometry``'s material in the file, None where the file gives it none."""
        trimesh_material = getattr(geometry.visual, "material", None)
        if trimesh_material is None:
            return None
        if self.gltf:
            index = self._gltf_index(trimesh_material)
            if index is None:
                raise SceneError(f"{self.path} (geometry {geometry_name!r}): its material is not among the file's")
            entry = self.entries[index]
            label = entry.get("name") or f"material{index}"
            return self._add(label, lambda: gltf_material(entry, f"{self.path}: material {label!r}", trimesh_material))
        if not hasattr(trimesh_material, "kwargs"):
            return None
        label = trimesh_material.name or "material"
        return self._add(label, lambda: obj_material(trimesh_material, f"{self.path}: material {label!r}"))

    def as_thin(self, name: str) -> str:
        """The name of a thin, smooth pane of the file's smooth glass material ``name`` (``name``/thin, made once): for
        geometry with an open edge, which has no inside for a solid ``dielectric`` to refract into and out of."""
        glass = self.materials[name]
        thin = f"{name}/thin"
        if thin not in self.materials:
            self.materials[thin] = Material("thin_dielectric", ior=glass.ior, transmittance=glass.transmittance,
                                            emission=glass.emission)
        return thin

    def _add(self, label: str, make) -> str:
        name = f"{self.base}/{label}"
        if name not in self.materials:
            self.materials[name] = make()
        return name
