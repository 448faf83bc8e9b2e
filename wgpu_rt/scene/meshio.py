"""Mesh files (OBJ, PLY, glTF/GLB, anything trimesh reads) → ``Mesh`` objects.

A file may hold several geometries placed by a scene graph (glTF nodes, OBJ groups); each placed
geometry becomes one ``Mesh`` whose ``transform`` is its node's world transform, so hierarchy survives.
A geometry placed at several nodes is read once: its placements are instances of one shape
(``Mesh.instance``), sharing their arrays, as a scene file's ``instances`` would make them. Vertex
normals are kept when the file has them (trimesh keeps loaded normals in its cache; without them we
leave ``normals`` None and the tracer shades flat), and so are its vertex colours or its colour texture
(image and per-vertex coordinates), which multiply the material's reflectance. Files are loaded with
``process=False`` so vertices are neither merged nor reordered. Every problem is a SceneError naming
the file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from ..errors import SceneError

MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")   # the files a scene spec or a folder is read as meshes


def _has_file_normals(mesh: trimesh.Trimesh) -> bool:
    """True when the loader supplied vertex normals (trimesh would otherwise compute them lazily)."""
    return "vertex_normals" in mesh._cache.cache


def validate_mesh_arrays(vertices: np.ndarray, faces: np.ndarray, where: str) -> None:
    """Raise SceneError (prefixed by ``where``) on no triangles, non-finite vertices or bad indices."""
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise SceneError(f"{where}: the mesh has no triangles")
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise SceneError(f"{where}: vertices must be an (N, 3) array, got shape {vertices.shape}")
    bad = ~np.all(np.isfinite(vertices), axis=1)
    if np.any(bad):
        raise SceneError(f"{where}: {int(bad.sum())} vertices are NaN or infinite "
                         f"(first: vertex {int(np.argmax(bad))})")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise SceneError(f"{where}: face index {int(faces.max() if faces.max() >= len(vertices) else faces.min())} "
                         f"out of range for {len(vertices)} vertices")


def file_vertex_colors(geometry: trimesh.Trimesh) -> np.ndarray | None:
    """A geometry's colour per vertex as linear RGB: the file's vertex (or face) colours; None where the
    file gives none (a material's single colour is not read: the scene file's material says that)."""
    from .model import linear_from_srgb8

    visual = geometry.visual
    if getattr(visual, "kind", None) not in ("vertex", "face"):
        return None
    rgba = np.asarray(visual.vertex_colors)
    if rgba.shape != (len(geometry.vertices), 4):
        return None
    return linear_from_srgb8(rgba[:, :3])


def file_texture(geometry: trimesh.Trimesh, where: str, decoded: dict,
                 folder: Path | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """A geometry's colour texture: ((H, W, 3) uint8 sRGB image, (V, 2) float32 coordinates per vertex),
    from an OBJ material's image or a glTF material's base colour texture; None where it has none or its
    coordinates are missing, misshapen or not finite. (H, W, 4), cutting the surface away (``with_cutout``),
    for a glTF MASK or BLEND material (1×1 where it has no base colour texture: ``_factor_cutout``) or an OBJ
    material with a ``map_d`` (``obj_cutout``, its file relative to ``folder``; white where it has no image
    of its own). ``decoded``: see ``_decode``; geometries that share an
    image share one array. An image that cannot be decoded is a SceneError naming ``where``."""
    visual = geometry.visual
    if getattr(visual, "kind", None) != "texture":
        return None
    material = getattr(visual, "material", None)
    image = getattr(material, "image", None)
    if image is None:
        image = getattr(material, "baseColorTexture", None)
    uvs = file_uvs(geometry)
    statements = getattr(material, "kwargs", None) or {}
    mask = obj_cutout(statements, folder, where, decoded) if folder is not None and "map_d" in statements else None
    if image is None and mask is None:      # a glTF material's own alpha may still cut it, everywhere alike
        solid = _factor_cutout(material)
        return None if solid is None else (solid, np.zeros((len(geometry.vertices), 2), np.float32))
    if uvs is None:
        return None
    pixels = None if image is None else _decode(image, decoded, f"{where}: cannot read its texture image")
    if mask is not None:
        if pixels is None:
            pixels = np.full((*mask.shape, 3), 255, np.uint8)
        key = ("obj cutout", id(mask), id(pixels))
        if key not in decoded:
            decoded[key] = (with_cutout(pixels, _resized(mask, pixels.shape[:2]), OBJ_CUTOFF), mask)
        pixels = decoded[key][0]
    elif pixels is not None and getattr(material, "alphaMode", None) in ("MASK", "BLEND"):
        pixels = _cutout_texture(image, pixels, material, decoded)
    return None if pixels is None else (pixels, uvs)


def _resized(alpha: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(H, W) ``alpha`` codes brought to ``shape`` (bilinearly), as float64."""
    from PIL import Image

    if alpha.shape == tuple(shape):
        return alpha.astype(np.float64)
    image = Image.fromarray(alpha.astype(np.float32), "F").resize((shape[1], shape[0]), Image.BILINEAR)
    return np.asarray(image, np.float64)


def _gltf_alpha(material) -> tuple[float, float | None]:
    """A glTF MASK or BLEND material's (trimesh's PBRMaterial) base colour factor's alpha (1 without one) and its
    cutoff: alphaCutoff (default ½) for MASK, None for BLEND."""
    factor = getattr(material, "baseColorFactor", None)
    scale = 1.0 if factor is None else float(np.asarray(factor, np.float64)[3]) / 255.0
    cutoff = getattr(material, "alphaCutoff", None)
    return scale, None if material.alphaMode == "BLEND" else 0.5 if cutoff is None else float(cutoff)


def _factor_cutout(material) -> np.ndarray | None:
    """For a glTF MASK or BLEND material without a base colour texture (trimesh's PBRMaterial), the 1×1 texture
    that its base colour factor's alpha gives (white: the factor's colour is the material's reflectance), read
    anywhere; None where that alpha cuts nothing away."""
    if getattr(material, "alphaMode", None) not in ("MASK", "BLEND"):
        return None
    scale, cutoff = _gltf_alpha(material)
    solid = with_cutout(np.full((1, 1, 3), 255, np.uint8), np.full((1, 1), 255.0 * scale), cutoff)
    return solid if solid.shape[2] == 4 else None


def _cutout_texture(image, pixels: np.ndarray, material, decoded: dict) -> np.ndarray:
    """The texture of a glTF MASK or BLEND material (trimesh's PBRMaterial) whose base colour ``image`` decoded
    to ``pixels``: ``with_cutout`` of its alpha (the image's times the base colour factor's) at the material's
    cutoff (``_gltf_alpha``)."""
    scale, cutoff = _gltf_alpha(material)
    key = ("cutout", id(image), scale, cutoff)
    if key not in decoded:
        alpha = np.asarray(image.convert("RGBA"), np.float64)[..., 3] * scale
        decoded[key] = (with_cutout(pixels, alpha, cutoff), image)
    return decoded[key][0]


def with_cutout(pixels: np.ndarray, alpha: np.ndarray, cutoff: float | None) -> np.ndarray:
    """The (H, W, 4) texture of (H, W, 3) ``pixels`` that cuts its surface away where the (H, W) ``alpha``
    (codes, 0–255) is below ``cutoff`` (in [0, 1]), as glTF's MASK mode does: the alpha shifted so that the
    cutoff falls at the tracer's CUTOUT_ALPHA, linearly, so a bilinear sample is kept exactly where glTF's
    would be. With ``cutoff`` None (a mesh of alpha_mode "blend"), the alpha as it is. ``pixels`` unchanged
    where no texel is cut away (none is below the cutoff, or, blending, below 1)."""
    from .model import CUTOUT_ALPHA

    shift = 0.0 if cutoff is None else 255.0 * (CUTOUT_ALPHA - cutoff)
    codes = np.clip(np.round(np.asarray(alpha, np.float64) + shift), 0, 255)
    kept_whole = np.all(codes >= 255) if cutoff is None else not np.any(codes < 255 * CUTOUT_ALPHA)
    if codes.shape != pixels.shape[:2] or kept_whole:
        return pixels
    return np.ascontiguousarray(np.dstack([pixels, codes.astype(np.uint8)]))


def _decode(image, decoded: dict, failure: str) -> np.ndarray | None:
    """A PIL image of a mesh file as (H, W, 3) uint8 codes (None where it is empty), decoded once per file:
    ``decoded`` maps images (by identity) to their arrays. An image that cannot be decoded is a SceneError
    that starts with ``failure``."""
    if id(image) not in decoded:
        try:
            pixels = np.ascontiguousarray(np.asarray(image.convert("RGB"), np.uint8))
        except Exception as err:   # PIL raises many types for an image it cannot decode
            raise SceneError(f"{failure} ({type(err).__name__}: {err})") from err
        decoded[id(image)] = (pixels if pixels.ndim == 3 and min(pixels.shape[:2]) > 0 else None, image)
    return decoded[id(image)][0]


def file_normal_map(geometry: trimesh.Trimesh, where: str, decoded: dict, scale: float = 1.0,
                    folder: Path | None = None) -> np.ndarray | None:
    """A geometry's normal map as (H, W, 3) uint8 codes, None where it has none: its glTF material's normal
    texture, its tilts scaled by ``scale`` as glTF's normal texture ``scale`` does (x and y times it, then
    normalized), or its OBJ material's (``obj_normal_map``, its files relative to ``folder``). ``decoded``
    shares one array among the geometries that use an image, as ``file_texture``."""
    material = getattr(geometry.visual, "material", None)
    image = getattr(material, "normalTexture", None)
    if image is not None:
        pixels = _decode(image, decoded, f"{where}: cannot read its normal map")
    elif folder is not None and getattr(material, "kwargs", None):
        pixels, scale = obj_normal_map(material.kwargs, folder, where, decoded)
    else:
        return None
    if pixels is None or scale == 1.0:
        return pixels
    key = ("scaled", id(pixels), scale)
    if key not in decoded:
        normals = pixels / 255.0 * 2.0 - 1.0
        normals[..., :2] *= scale
        normals /= np.maximum(np.linalg.norm(normals, axis=-1, keepdims=True), 1e-12)
        decoded[key] = (np.round((normals + 1.0) / 2.0 * 255.0).astype(np.uint8), pixels)
    return decoded[key][0]


def file_metal_rough_map(geometry: trimesh.Trimesh, where: str, decoded: dict, ior: float,
                         folder: Path | None = None) -> np.ndarray | None:
    """A geometry's glTF metallic-roughness texture as its ``Mesh.metal_rough_map``: (H, W, 3) uint8 codes, the
    roughness (green) and metalness (blue) times the material's roughnessFactor and metallicFactor (glTF's default
    1 where absent), red 0; or its OBJ material's (``obj_metal_rough_map``, its files relative to ``folder``); None
    where its material has none. ``decoded`` shares one array among the geometries whose materials have the same
    image, factors and ``ior`` (the coat of the plastic it is on)."""
    material = getattr(geometry.visual, "material", None)
    image = getattr(material, "metallicRoughnessTexture", None)
    if image is None:
        statements = getattr(material, "kwargs", None)
        return obj_metal_rough_map(statements, folder, where, decoded, ior) if folder and statements else None
    pixels = _decode(image, decoded, f"{where}: cannot read its metallic-roughness texture")
    if pixels is None:
        return None
    factors = tuple(1.0 if getattr(material, name, None) is None else float(getattr(material, name))
                    for name in ("roughnessFactor", "metallicFactor"))
    key = ("metal-rough", id(pixels), factors, float(ior))
    if key not in decoded:
        baked = np.zeros_like(pixels)
        baked[..., 1:] = np.clip(np.round(pixels[..., 1:] * np.asarray(factors)), 0, 255)
        decoded[key] = (baked, pixels)
    return decoded[key][0]


def obj_metal_rough_map(statements: dict, folder: Path, where: str, decoded: dict, ior: float) -> np.ndarray | None:
    """An OBJ material's ``map_Pr`` (roughness) and ``map_Pm`` (metalness) images, the MTL PBR extension's, as a
    ``Mesh.metal_rough_map`` (read raw, their first channel: grey images); where one of them is absent its scalar
    (``Pr``, else the roughness ``Ns`` gives where ``Ks`` is not black, else 1; ``Pm``, else 0) stands for it, and
    the metalness image is resized to the roughness image's size where they differ. None without either image."""
    from PIL import Image

    from .file_materials import FieldReader, obj_roughness

    names = {key: _mtl_texture(statements[key])[0] for key in ("map_pr", "map_pm")
             if isinstance(statements.get(key), (list, tuple))}
    names = {key: name for key, name in names.items() if name}
    if not names:
        return None
    key = ("metal-rough", tuple((folder / name).resolve() for name in names.values()), float(ior))
    if key not in decoded:
        fields = FieldReader(where, {k.lower(): v for k, v in statements.items()})
        images = {k: _mtl_image(folder / name, k.replace("map_p", "map_P"), where, decoded)[..., 0]
                  for k, name in names.items()}
        shape = images.get("map_pr", images.get("map_pm")).shape
        if "map_pm" in images and images["map_pm"].shape != shape:
            resized = Image.fromarray(images["map_pm"]).resize((shape[1], shape[0]), Image.BILINEAR)
            images["map_pm"] = np.asarray(resized, np.uint8)
        codes = np.zeros((*shape, 3), np.uint8)
        codes[..., 1] = images.get("map_pr", round(255 * obj_roughness(fields)))
        codes[..., 2] = images.get("map_pm", round(255 * fields.numbers("pm", 0.0)))
        decoded[key] = (codes, None)
    return decoded[key][0]


# MTL texture options and how many values each takes (the rest of a statement is the file's name).
MTL_OPTIONS = {"-bm": 1, "-clamp": 1, "-blendu": 1, "-blendv": 1, "-boost": 1, "-mm": 2, "-o": 3, "-s": 3, "-t": 3,
               "-texres": 1, "-imfchan": 1, "-cc": 1, "-type": 1}
OBJ_CUTOFF = 0.5   # a map_d's alpha below which the surface is cut away (as glTF's default alphaCutoff)


def _mtl_texture(tokens) -> tuple[str, dict[str, list[str]]]:
    """An MTL texture statement's file name and its options (each option's values)."""
    tokens, options, i = [str(t) for t in tokens], {}, 0
    while i < len(tokens) and tokens[i].lower() in MTL_OPTIONS:
        count = MTL_OPTIONS[tokens[i].lower()]
        options[tokens[i].lower()] = tokens[i + 1:i + 1 + count]
        i += 1 + count
    return " ".join(tokens[i:]), options


def obj_cutout(statements: dict, folder: Path, where: str, decoded: dict) -> np.ndarray | None:
    """An OBJ material's ``map_d`` (its file relative to ``folder``) as (H, W) uint8 alpha codes: the image's
    alpha channel where it has one that is not all opaque, else its grey level; None without one."""
    from PIL import Image

    tokens = statements.get("map_d")
    name = _mtl_texture(tokens)[0] if isinstance(tokens, (list, tuple)) else ""
    if not name:
        return None
    path = (folder / name).resolve()
    if ("alpha", path) not in decoded:
        if not path.is_file():
            raise SceneError(f"{where}: its material's map_d: {path}: texture image not found")
        try:
            with Image.open(path) as image:
                rgba = np.asarray(image.convert("RGBA"), np.uint8)
                grey = np.asarray(image.convert("L"), np.uint8)
        except Exception as err:   # Pillow raises many types for a file it cannot decode
            raise SceneError(f"{where}: its material's map_d: {path}: cannot read texture image "
                             f"({type(err).__name__}: {err})") from err
        alpha = rgba[..., 3] if np.any(rgba[..., 3] < 255) else grey
        decoded[("alpha", path)] = (np.ascontiguousarray(alpha), None)
    return decoded[("alpha", path)][0]


def obj_normal_map(statements: dict, folder: Path, where: str, decoded: dict) -> tuple[np.ndarray | None, float]:
    """An OBJ material's normal map and its ``-bm`` scale: its ``norm`` image, else a ``map_Bump``/``bump``
    image that is one (bluish on the mean, as tangent-space normal maps are; a grey height map is not read:
    the tracer does no bump mapping), its file relative to ``folder``; (None, 1) without one."""
    for key in ("norm", "map_bump", "bump"):
        tokens = statements.get(key)
        if not isinstance(tokens, (list, tuple)) or not tokens:
            continue
        name, options = _mtl_texture(tokens)
        scale = 1.0
        if options.get("-bm"):
            try:
                scale = float(options["-bm"][0])
            except ValueError:
                raise SceneError(f"{where}: {key} -bm {options['-bm'][0]!r}: expected a number") from None
        if not name:
            continue
        pixels = _mtl_image(folder / name, key, where, decoded)
        mean = pixels.reshape(-1, 3).mean(0) / 255.0
        if key == "norm" or (mean[2] > 0.6 and abs(mean[0] - 0.5) < 0.15 and abs(mean[1] - 0.5) < 0.15):
            return pixels, scale
    return None, 1.0


def read_texture_image(path: Path, alpha: bool = False) -> np.ndarray:
    """The image file at ``path`` (PNG, JPEG, anything Pillow reads) as an (H, W, 3) uint8 sRGB texture (an
    alpha dropped, grey expanded), or with ``alpha`` (H, W, 4) with its alpha (255 where it has none);
    SceneError naming the file if it is missing or cannot be decoded."""
    from PIL import Image

    path = Path(path)
    if not path.is_file():
        raise SceneError(f"{path}: texture image not found")
    try:
        with Image.open(path) as image:
            pixels = np.asarray(image.convert("RGBA" if alpha else "RGB"), np.uint8)
    except Exception as err:   # Pillow raises many types for a file it cannot decode
        raise SceneError(f"{path}: cannot read texture image ({type(err).__name__}: {err})") from err
    return np.ascontiguousarray(pixels)


def read_environment_image(path: Path) -> np.ndarray:
    """The latitude-longitude image at ``path`` as (H, W, 3) float32 linear radiance: an OpenEXR file's colour
    (its first three channels), or any image Pillow reads, decoded from sRGB. SceneError naming the file if it
    is missing, unreadable, smaller than 2×3 pixels or holds a negative, NaN or infinite value."""
    from ..errors import ImageError
    from ..io import read_exr
    from .model import linear_from_srgb8

    path = Path(path)
    if path.suffix.lower() == ".exr":
        try:
            layers = read_exr(path)
        except ImageError as err:
            raise SceneError(str(err)) from err
        color = layers.get("color")
        if color is None or color.shape[-1] < 3:
            raise SceneError(f"{path}: an environment map needs R, G and B channels")
        image = np.ascontiguousarray(color[..., :3], np.float32)
    else:
        image = linear_from_srgb8(read_texture_image(path))
    check_environment(image, str(path))
    return image


def check_environment(image: np.ndarray, where: str) -> None:
    """SceneError (prefixed by ``where``) unless ``image`` is an environment map the tracer can read: (H, W, 3)
    with H ≥ 3 and W ≥ 2 (Mitsuba's least), every value finite and not negative."""
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] != 3 or image.shape[0] < 3 or image.shape[1] < 2:
        raise SceneError(f"{where}: an environment map must be an (H, W, 3) image at least 2 pixels wide and 3 "
                         f"high, got shape {image.shape}")
    bad = ~np.isfinite(image) | (image < 0)
    if np.any(bad):
        row, column = np.argwhere(bad.any(-1))[0]
        raise SceneError(f"{where}: {int(bad.any(-1).sum())} pixels are negative, NaN or infinite "
                         f"(first: row {row}, column {column})")


def file_uvs(geometry: trimesh.Trimesh) -> np.ndarray | None:
    """A geometry's texture coordinates per vertex (float32), None where it has none (or not finite)."""
    uvs = getattr(geometry.visual, "uv", None)
    if uvs is None:
        return None
    uvs = np.asarray(uvs, np.float64)
    if uvs.shape != (len(geometry.vertices), 2) or not np.all(np.isfinite(uvs)):
        return None
    return uvs.astype(np.float32)


def file_emission_texture(geometry: trimesh.Trimesh, where: str, decoded: dict,
                          folder: Path | None = None) -> np.ndarray | None:
    """A geometry's emission texture as (H, W, 3) uint8 sRGB codes, None where it has none: its glTF material's
    emissive texture, or its OBJ material's ``map_Ke`` (its file relative to ``folder``). ``decoded`` shares one
    array among the geometries that use an image, as ``file_texture``."""
    material = getattr(geometry.visual, "material", None)
    image = getattr(material, "emissiveTexture", None)
    if image is not None:
        return _decode(image, decoded, f"{where}: cannot read its emissive texture")
    tokens = (getattr(material, "kwargs", None) or {}).get("map_ke")
    name = _mtl_texture(tokens)[0] if folder is not None and isinstance(tokens, (list, tuple)) else ""
    return _mtl_image(folder / name, "map_Ke", where, decoded) if name else None


def _mtl_image(path: Path, key: str, where: str, decoded: dict) -> np.ndarray:
    """The image file an MTL statement ``key`` names (``read_texture_image``), read once per file into
    ``decoded``; a SceneError naming ``where`` and the statement where it cannot be."""
    path = Path(path).resolve()
    if ("file", path) not in decoded:
        try:
            decoded[("file", path)] = (read_texture_image(path), None)
        except SceneError as err:
            raise SceneError(f"{where}: its material's {key}: {err}") from err
    return decoded[("file", path)][0]


def _is_open_smooth_glass(material, vertices: np.ndarray, faces: np.ndarray) -> bool:
    """Whether a smooth ``dielectric`` is on a surface with an open edge (an edge of one triangle only, once the
    vertices that a texture or normal seam splits are merged back): a pane or a shell of no thickness."""
    if material.kind != "dielectric" or material.roughness > 0:
        return False
    merged = trimesh.Trimesh(vertices, faces, process=False)
    merged.merge_vertices(merge_tex=True, merge_norm=True)
    return not merged.is_watertight


def load_mesh_file(path: Path, material: str | None, name: str | None = None, vertex_colors: bool = True,
                   texture: np.ndarray | None = None, materials: dict | None = None,
                   normal_map: np.ndarray | None = None, emission_texture: np.ndarray | None = None,
                   metal_rough_map: np.ndarray | None = None) -> list:
    """The meshes of the file at ``path``, all with ``material``, named ``name`` (default: file stem), with
    the file's vertex colours or texture (``file_vertex_colors``, ``file_texture``) unless ``vertex_colors``
    is False; ``texture`` (an (H, W, 3) uint8 image) replaces the file's images at the file's texture
    coordinates (a SceneError where a geometry has none). Where the dict ``materials`` is given, each geometry
    that has a material of its own in the file (glTF's, an OBJ file's MTL: ``file_materials``) takes it, added
    to ``materials`` under its name, and the others ``material`` (a SceneError where that is None). A geometry's
    normal map is the file's (a glTF material's normal texture), or ``normal_map`` in its place, and its emission
    texture likewise (``file_emission_texture``, or ``emission_texture``), read at the same coordinates; so is a
    geometry's metal-rough map (``metal_rough_map``, else ``file_metal_rough_map`` where it takes the file's
    plastic); where the file's own images are read, through the material's KHR_texture_transform."""
    from .file_materials import GLTF_SUFFIXES, FileMaterials, gltf_json, transformed_uvs
    from .model import Mesh

    path = Path(path)
    if not path.is_file():
        raise SceneError(f"{path}: mesh file not found")
    if path.suffix.lower() in GLTF_SUFFIXES:
        gltf_json(path)       # (refuses extensions it needs whose data trimesh would read as zeros)
    try:
        scene = trimesh.load(str(path), force="scene", process=False)
    except IndexError as err:
        raise SceneError(f"{path}: malformed mesh file: face index out of range ({err})") from err
    except ImportError as err:  # trimesh imports optional helpers lazily (charset_normalizer: non-UTF-8 text)
        raise SceneError(f"{path}: cannot read mesh file: trimesh needs a Python package that is not "
                         f"installed: {err.name or err}") from err
    except Exception as err:  # trimesh raises many types for bad input; all mean "unreadable"
        raise SceneError(f"{path}: cannot read mesh file ({type(err).__name__}: {err})") from err
    base = name or path.stem
    meshes = []
    first_placement: dict[str, Mesh] = {}      # geometry name → the Mesh of its first node
    decoded: dict = {}                          # the file's images, decoded (_decode)
    own = FileMaterials(path, base)     # the file's materials: taken where ``materials`` asks, else for scales
    for node in scene.graph.nodes_geometry:
        with np.errstate(over="ignore", invalid="ignore"):      # (trimesh's rigidity check on a huge matrix)
            transform, geometry_name = scene.graph[node]
        if not np.all(np.abs(np.asarray(transform, np.float64)) <= np.finfo(np.float32).max):
            raise SceneError(f"{path}: node {node!r}: its placement is not finite in float32")
        geometry = scene.geometry[geometry_name]
        if not isinstance(geometry, trimesh.Trimesh) or len(geometry.faces) == 0:
            continue
        label = base if not meshes and len(scene.graph.nodes_geometry) == 1 else f"{base}/{node}"
        if geometry_name in first_placement:
            meshes.append(first_placement[geometry_name].instance(label, transform=transform))
            continue
        vertices = np.asarray(geometry.vertices, np.float64)
        faces = np.asarray(geometry.faces, np.int64)
        where = f"{path} (geometry {geometry_name!r})"
        validate_mesh_arrays(vertices, faces, where)
        normals = None
        if _has_file_normals(geometry):
            normals = np.asarray(geometry.vertex_normals, np.float32)
            if normals.shape != vertices.shape or not np.all(np.isfinite(normals)):
                normals = None
        if texture is not None:
            image, uvs = texture, file_uvs(geometry)
            if uvs is None:
                raise SceneError(f"{where}: has no texture coordinates for the texture to be read at")
        else:
            textured = file_texture(geometry, where, decoded, path.parent) if vertex_colors else None
            image, uvs = textured or (None, None)
        colors = file_vertex_colors(geometry) if vertex_colors and image is None else None
        relief = normal_map if normal_map is not None else file_normal_map(geometry, where, decoded,
                                                                           own.normal_scale(geometry), path.parent)
        glow = emission_texture if emission_texture is not None else file_emission_texture(geometry, where, decoded,
                                                                                           path.parent)
        surface = (own.material_of(geometry, geometry_name) if materials is not None else None) or material
        if surface is None:
            raise SceneError(f"{where}: has no material of its own; give the mesh entry a 'material'")
        file_material = own.materials.get(surface)
        metal_rough = metal_rough_map
        if metal_rough is None and file_material is not None and file_material.kind == "plastic":
            metal_rough = file_metal_rough_map(geometry, where, decoded, file_material.ior, path.parent)
        maps = (relief, glow, metal_rough)
        uvs = file_uvs(geometry) if uvs is None and any(m is not None for m in maps) else uvs
        for what, image_read in zip(("normal map", "emission texture", "metallic-roughness texture"), maps):
            if image_read is not None and uvs is None:
                raise SceneError(f"{where}: has no texture coordinates for the {what} to be read at")
        file_images = ((texture is None and image is not None) or (normal_map is None and relief is not None)
                       or (emission_texture is None and glow is not None)
                       or (metal_rough_map is None and metal_rough is not None))
        if file_images and (second := own.texture_coordinates(geometry)) is not None:
            uvs = second              # (the material's textures read at another set than TEXCOORD_0)
        if file_images and (matrix := own.texture_transform(geometry)) is not None:
            uvs = transformed_uvs(uvs, matrix)
        if surface in own.materials and _is_open_smooth_glass(own.materials[surface], vertices, faces):
            surface = own.as_thin(surface)
        blended = texture is None and getattr(getattr(geometry.visual, "material", None), "alphaMode", None) == "BLEND"
        first_placement[geometry_name] = Mesh(label, vertices.astype(np.float32), faces.astype(np.uint32),
                                              surface, normals=normals,
                                              transform=np.asarray(transform, np.float32), colors=colors,
                                              texture=image, uvs=uvs, normal_map=relief, emission_texture=glow,
                                              alpha_mode="blend" if blended else "mask",
                                              metal_rough_map=metal_rough)
        meshes.append(first_placement[geometry_name])
    if not meshes:
        raise SceneError(f"{path}: the mesh file has no triangles")
    if materials is not None:
        materials.update(own.materials)
    return meshes
