"""Convert any ``Scene`` to a Mitsuba 3 scene dict, to cross-validate the tracer against Mitsuba.

Every mesh becomes an ``mi.Mesh`` built from its world-space arrays at ``frame`` (so primitives,
loaded files, animation and instances, each placement one mesh, all go through one path), with the
BSDF its material maps to:

- diffuse → ``diffuse``; plastic → ``plastic`` (roughness 0) or ``roughplastic`` (GGX, alpha = roughness),
  int_ior = ior, ext_ior = 1, linear; conductor →
  ``conductor`` (roughness 0) or ``roughconductor`` (GGX, alpha = roughness) with eta, k and
  specular_reflectance; dielectric → ``dielectric`` or
  ``roughdielectric`` (GGX) with int_ior = ior, ext_ior = 1, specular_transmittance = transmittance
  (thin_dielectric → ``thindielectric``, likewise, whose shadow rays stop at it where the tracer's cross it: a sun or
  point light shining through a pane lights Mitsuba's image only by paths that meet it, never, so such a scene has
  no Mitsuba gold: ``lights_through_panes``); an absorbing
  one's mesh has a ``homogeneous`` interior medium of sigma_t = absorption and albedo 0.
- a plastic with a metal-rough map is a ``blendbsdf`` of it and glTF's metal weighted by the map's metalness
  (``metal_rough_bsdf``; only where the plastic's texels share one roughness); a conductor with one a
  ``roughconductor`` whose alpha is a bitmap of the map's (``mapped_alpha``), likewise;
- a cut-out mesh's BSDF is wrapped in ``mask`` (``cutout_opacity``);
- with a cut-out or an interior medium the integrator is ``volpath``, else ``path``;
- a mesh's vertex colours become a "vertex_color" mesh attribute its BSDF's reflectance reads, a texture a
  ``bitmap`` (bilinear, repeat) of the image times the reflectance, read at the mesh's texture coordinates, a
  normal map a ``normalmap`` around the BSDF (inside ``twosided``: on a back face Mitsuba mirrors the tilt
  through the surface where the tracer turns it round, as a thin sheet's far side would be).
- diffuse and conductor BSDFs are wrapped in ``twosided``: our tracer shades both faces of them alike
  (wgsl/trace/trace.wgsl), while Mitsuba's are black seen from behind. Back faces show wherever a one-sided
  rectangle is seen from outside, e.g. the outer sides of sun-room's crate.
- emissive materials add a one-sided ``area`` emitter (its radiance a ``bitmap`` of a mesh's emission texture times
  the emission); point, spot and directional lights and a non-black
  background (``constant``, or ``envmap`` of the environment map times the background) map to their Mitsuba
  plugins.

The sensor is a ``perspective`` camera (``thinlens`` with an aperture) with a box pixel filter and an
``independent`` sampler seeded with ``seed``; the integrator (above) has the same ``max_depth``. Needs the
``bench`` extra.

``load_mitsuba`` sets Mitsuba to the fastest variant this machine has (``variant_choice``: cuda_ad_rgb where
Dr.Jit finds a CUDA GPU, else llvm_ad_rgb when Debian's LLVM 19 is installed (`apt-get install -y libllvm19`;
LLVM 15 crashes Dr.Jit) or DRJIT_LIBLLVM_PATH names an LLVM, else scalar_rgb); ``render_in_passes`` renders
a gold of any sample count with it (the benchmarks' ``--gold-renderer mitsuba`` and ``wgpu-rt dataset``'s).
"""

from __future__ import annotations

import os
import re
import time
from functools import partial
from pathlib import Path

import numpy as np

from ..errors import SceneError
from .model import (CUTOUT_ALPHA, GLASS_KINDS, DirectionalLight, Material, PointLight, Scene, SpotLight,
                    linear_from_srgb8, sample_alpha, sample_texture, vertex_colors_as_rendered)
from .transforms import transform_normals, transform_points


def lights_through_panes(scene: Scene) -> bool:
    """Whether ``scene`` has a thin pane and a point, spot or directional light: light Mitsuba cannot render
    (its shadow rays stop at the pane, where the tracer's cross it, and no path meets such a light by chance)."""
    return bool(scene.lights) and any(scene.materials[m.material].kind == "thin_dielectric" for m in scene.meshes)


def _rgb(value) -> dict:
    return {"type": "rgb", "value": [float(x) for x in np.asarray(value, np.float64)]}


# The per-vertex reflectance of a mesh with vertex colours (the colours times its material's reflectance), as
# the mesh attribute its BSDF reads.
VERTEX_REFLECTANCE = {"type": "mesh_attribute", "name": "vertex_color"}


def textured_reflectance(mi, texture: np.ndarray, reflectance: np.ndarray) -> dict:
    """A ``bitmap`` texture of ``texture`` (sRGB8, as the tracer decodes it) times ``reflectance``, filtered and
    wrapped as the tracer samples it (wgpu_rt.scene.model.sample_texture): the product is linear already,
    so the bitmap is read raw."""
    linear = linear_from_srgb8(np.asarray(texture)[..., :3]) * np.asarray(reflectance, np.float32)
    return {"type": "bitmap", "bitmap": mi.Bitmap(np.ascontiguousarray(linear, np.float32)), "raw": True,
            "filter_type": "bilinear", "wrap_mode": "repeat"}


CUTOUT_OVERSAMPLING = 4   # cutout_opacity's and mapped_alpha's grid per texel and axis


def _texel_grid(height: int, width: int, factor: int) -> np.ndarray:
    """(height · factor · width · factor, 2) coordinates of the centres of a grid ``factor`` times finer than an
    image's texels, row by row from the image's top (v = 1)."""
    rows, columns = np.meshgrid((np.arange(height * factor) + 0.5) / (height * factor),
                                (np.arange(width * factor) + 0.5) / (width * factor), indexing="ij")
    return np.stack([columns.ravel(), 1.0 - rows.ravel()], -1)


def cutout_opacity(mi, texture: np.ndarray, alpha_mode: str = "mask") -> dict:
    """Mitsuba's ``mask`` opacity for a cut-out (H, W, 4) ``texture``. Mode "blend": the alpha itself, bilinear
    (the mask's opacity is the probability of a surface there, as the tracer's). Mode "mask": 1 where the tracer
    keeps the surface (its bilinear alpha at least CUTOUT_ALPHA), 0 where it cuts it away, on a grid up to
    CUTOUT_OVERSAMPLING times finer than the texture's, read nearest (an opacity between would be a
    probability, where the tracer's edge is sharp)."""
    if alpha_mode == "blend":
        alpha = np.ascontiguousarray(np.asarray(texture)[..., 3:], np.float32) / 255.0
        return {"type": "bitmap", "bitmap": mi.Bitmap(alpha), "raw": True, "filter_type": "bilinear",
                "wrap_mode": "repeat"}
    shape, uvs = _cutout_grid(texture)
    kept = (sample_alpha(texture, uvs) >= CUTOUT_ALPHA).astype(np.float32).reshape(shape)
    return {"type": "bitmap", "bitmap": mi.Bitmap(kept[..., None]), "raw": True, "filter_type": "nearest",
            "wrap_mode": "repeat"}


def _cutout_grid(texture: np.ndarray) -> tuple[tuple[int, int], np.ndarray]:
    """The (rows, columns) of a grid up to CUTOUT_OVERSAMPLING times finer than a cut-out ``texture``'s texels, and
    the (N, 2) coordinates of its cells' centres, row by row (``_texel_grid``)."""
    height, width = texture.shape[:2]
    factor = max(1, min(CUTOUT_OVERSAMPLING, 4096 // max(height, width)))
    return (height * factor, width * factor), _texel_grid(height, width, factor)


def cut_out_radiance(mi, mesh, emission: np.ndarray) -> dict:
    """The radiance of a cut-out emitter: ``emission`` (times the mesh's emission texture) where the tracer keeps the
    surface and 0 in its holes ("blend": times the alpha, the share of crossings that meet it), baked on
    ``_cutout_grid`` and read nearest. Mitsuba's area emitter ignores its shape's mask; the tracer's light samples
    and paths find no light in a hole."""
    shape, uvs = _cutout_grid(mesh.texture)
    alpha = sample_alpha(mesh.texture, uvs).astype(np.float64)
    share = alpha if mesh.alpha_mode == "blend" else (alpha >= CUTOUT_ALPHA).astype(np.float64)
    colour = 1.0 if mesh.emission_texture is None else sample_texture(mesh.emission_texture, uvs)
    radiance = (share[:, None] * colour * np.asarray(emission, np.float64)).reshape(*shape, 3)
    return {"type": "bitmap", "bitmap": mi.Bitmap(np.ascontiguousarray(radiance, np.float32)), "raw": True,
            "filter_type": "nearest", "wrap_mode": "repeat"}


def normal_mapped_bsdf(mi, normal_map: np.ndarray, bsdf: dict) -> dict:
    """``bsdf`` under Mitsuba's ``normalmap`` of ``normal_map`` (raw 8-bit codes), filtered and wrapped as the
    tracer samples it (wgsl/trace/surface_textures.wgsl's normal_mapped)."""
    raw = np.ascontiguousarray(np.asarray(normal_map, np.float32) / 255.0)
    return {"type": "normalmap", "bsdf": bsdf,
            "normalmap": {"type": "bitmap", "bitmap": mi.Bitmap(raw), "raw": True, "filter_type": "bilinear",
                          "wrap_mode": "repeat"}}


def _raw_bitmap(mi, values: np.ndarray) -> dict:
    """A ``bitmap`` of (H, W) or (H, W, C) float ``values`` read raw, filtered and wrapped as the tracer samples."""
    values = np.asarray(values, np.float32)
    values = values[..., None] if values.ndim == 2 else values
    return {"type": "bitmap", "bitmap": mi.Bitmap(np.ascontiguousarray(values)), "raw": True,
            "filter_type": "bilinear", "wrap_mode": "repeat"}


LEAST_MAPPED_ALPHA = 1e-4    # a metal-rough map's metal is at least this rough in Mitsuba (GGX of alpha 0 is not)


def mapped_alpha(mi, metal_rough_map: np.ndarray) -> dict:
    """A ``bitmap`` of the GGX alpha a metal-rough map gives, the square of its bilinear roughness as the tracer
    takes it, on a grid up to CUTOUT_OVERSAMPLING times finer than the map's (Mitsuba's bilinear alpha between
    texels would be the mean of their squares, rougher than the tracer's between a smooth and a rough texel)."""
    height, width = metal_rough_map.shape[:2]
    factor = max(1, min(CUTOUT_OVERSAMPLING, 4096 // max(height, width)))
    roughness = sample_texture(metal_rough_map, _texel_grid(height, width, factor), srgb=False)[:, 1]
    alpha = np.maximum(roughness.astype(np.float64) ** 2, LEAST_MAPPED_ALPHA)
    return _raw_bitmap(mi, alpha.reshape(height * factor, width * factor))


def metal_rough_bsdf(mi, mesh, material: Material, vertex_colored: bool = False,
                     reflectance: dict | None = None) -> dict:
    """Mitsuba's BSDF for a mesh with a metal-rough map (``Mesh.metal_rough_map``). On a conductor ``material``: its
    ``roughconductor`` of alpha ``mapped_alpha``. On a plastic: a ``blendbsdf`` weighted by the map's metalness
    (blue) of the plastic and glTF's metal (``roughconductor``, eta 0 and k 1, alpha ``mapped_alpha``), as the tracer
    picks between them. Mitsuba's ``roughplastic`` has one roughness, so a map whose roughness varies over its
    plastic texels (metalness below 1) is a SceneError; where a plastic texel meets a metal one of another roughness
    the tracer's plastic takes the roughness between them, Mitsuba's its own."""
    if material.kind == "conductor":
        return {**material_to_bsdf(material, vertex_colored, reflectance), "type": "roughconductor",
                "distribution": "ggx", "alpha": mapped_alpha(mi, mesh.metal_rough_map)}
    codes = np.asarray(mesh.metal_rough_map, np.float64)
    roughness, metalness = codes[..., 1] / 255.0, codes[..., 2] / 255.0
    plastic = roughness[metalness < 1.0]
    if plastic.size and np.ptp(plastic) > 0:
        raise SceneError(f"mesh {mesh.name!r}: its metal-rough map's roughness varies where it is plastic "
                         f"({plastic.min():.3f} to {plastic.max():.3f}); Mitsuba's roughplastic has one")
    coat = Material("plastic", reflectance=material.reflectance, ior=material.ior,
                    roughness=float(plastic[0] ** 2) if plastic.size else 0.0)
    metal = {"type": "roughconductor", "distribution": "ggx", "eta": 0.0, "k": 1.0,
             "alpha": mapped_alpha(mi, mesh.metal_rough_map),
             "specular_reflectance": reflectance or _rgb(material.reflectance)}
    return {"type": "blendbsdf", "weight": _raw_bitmap(mi, metalness),
            "bsdf_0": material_to_bsdf(coat, reflectance=reflectance), "bsdf_1": metal}


def material_to_bsdf(material: Material, vertex_colored: bool = False, reflectance: dict | None = None) -> dict:
    """The Mitsuba BSDF dict for ``material``, as seen from its front face; ``vertex_colored``: its
    reflectance read from the mesh's "vertex_color" attribute (VERTEX_REFLECTANCE); ``reflectance``: a
    texture dict that replaces it (``textured_reflectance``)."""
    if reflectance is None:
        reflectance = VERTEX_REFLECTANCE if vertex_colored else _rgb(material.reflectance)
    if material.kind == "diffuse":
        return {"type": "diffuse", "reflectance": reflectance}
    if material.kind == "plastic":
        bsdf = {"type": "plastic", "diffuse_reflectance": reflectance, "int_ior": float(material.ior),
                "ext_ior": 1.0, "nonlinear": False}
        if material.roughness > 0:
            bsdf.update(type="roughplastic", distribution="ggx", alpha=float(material.roughness))
        return bsdf
    if material.kind == "conductor":
        bsdf = {"type": "conductor", "eta": _rgb(material.eta), "k": _rgb(material.k),
                "specular_reflectance": reflectance}
        if material.roughness > 0:
            bsdf.update(type="roughconductor", distribution="ggx", alpha=float(material.roughness))
        return bsdf
    bsdf = {"type": "thindielectric" if material.kind == "thin_dielectric" else "dielectric",
            "int_ior": float(material.ior), "ext_ior": 1.0, "specular_transmittance": _rgb(material.transmittance)}
    if material.roughness > 0:
        bsdf.update(type="roughdielectric", distribution="ggx", alpha=float(material.roughness))
    return bsdf


def surface_bsdf(material: Material, vertex_colored: bool = False, reflectance: dict | None = None,
                 wrap=None, bsdf: dict | None = None) -> dict:
    """``material_to_bsdf`` (or ``bsdf`` in its place) made two-sided where our tracer is (every kind but glass),
    after ``wrap`` (a function of a BSDF dict, e.g. a normal map's) wraps it: inside ``twosided``, which flips a
    back face's directions first, the normal map tilts the normal as the tracer does on a front face."""
    bsdf = bsdf or material_to_bsdf(material, vertex_colored, reflectance)
    bsdf = bsdf if wrap is None else wrap(bsdf)
    return bsdf if material.kind in GLASS_KINDS else {"type": "twosided", "bsdf": bsdf}   # (thindielectric is both)


def _mitsuba_mesh(mi, name: str, vertices, faces, normals, bsdf: dict, emission, vertex_reflectance=None,
                  uvs=None, interior: dict | None = None):
    """An ``mi.Mesh``; ``uvs`` in our convention (v = 1 at the image's top) become Mitsuba's (row 0 at v = 0);
    ``interior`` a medium dict inside it."""
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    if interior is not None:
        props["interior"] = mi.load_dict(interior)
    if emission is not None:
        props["emitter"] = mi.load_dict({"type": "area", "radiance": emission if isinstance(emission, dict)
                                         else _rgb(emission)})
    mesh = mi.Mesh(name, len(vertices), len(faces), props=props, has_vertex_normals=normals is not None,
                   has_vertex_texcoords=uvs is not None)
    params = mi.traverse(mesh)
    params["vertex_positions"] = np.ascontiguousarray(vertices, np.float32).ravel()
    params["faces"] = np.ascontiguousarray(faces, np.uint32).ravel()
    if normals is not None:
        params["vertex_normals"] = np.ascontiguousarray(normals, np.float32).ravel()
    if uvs is not None:
        flipped = np.asarray(uvs, np.float64) * [1, -1] + [0, 1]
        params["vertex_texcoords"] = np.ascontiguousarray(flipped, np.float32).ravel()
    params.update()
    if vertex_reflectance is not None:
        mesh.add_attribute("vertex_color", 3, np.ascontiguousarray(vertex_reflectance, np.float32).ravel())
    return mesh


# The variants the cross-validation can use, the CPU's scalar one first: the Mitsuba staged for the lent
# GPUs is built with cuda_ad_rgb and llvm_ad_rgb alone, and llvm_ad_rgb needs an LLVM that loads
CROSS_CHECK_VARIANTS = ("scalar_rgb", "cuda_ad_rgb", "llvm_ad_rgb")


def use_variant(mi, variants=CROSS_CHECK_VARIANTS) -> str | None:
    """Keep ``mi``'s variant if one is set, else set the first of ``variants`` that this Mitsuba build can
    load (``mi.variants()`` lists those it was configured with, which a trimmed install may lack).
    Returns the variant in use, or None where none loads."""
    if mi.variant() is not None:
        return mi.variant()
    for variant in variants:
        if variant not in mi.variants():
            continue
        try:
            mi.set_variant(variant)
        except (ImportError, RuntimeError):
            continue
        return variant
    return None


def to_mitsuba(scene: Scene, width: int, height: int, spp: int, max_depth: int, frame: int = 0,
               seed: int = 0) -> dict:
    """A dict for ``mi.load_dict`` that renders ``scene`` at ``frame`` like our tracer should.

    Uses the current Mitsuba variant (``use_variant`` picks one if none is set yet).
    """
    import mitsuba as mi

    if use_variant(mi) is None:
        raise RuntimeError(f"no Mitsuba variant of {CROSS_CHECK_VARIANTS} loads in this build")
    scene.metal_rough_iors()      # (refuses a metal-rough map on anything but a plastic, naming the mesh)
    camera = scene.camera_at(frame)
    lens = {"type": "thinlens", "aperture_radius": camera.aperture_radius,
            "focus_distance": camera.focus_distance} if camera.aperture_radius > 0 else {"type": "perspective"}
    result = {
        "type": "scene",
        # volpath passes paths and shadow rays through a mask's holes without counting a bounce; path would
        # neither (its shadow rays stop at a mask); and path ignores media
        "integrator": {"type": "volpath" if any(m.is_cut_out or scene.materials[m.material].absorbs
                                                for m in scene.meshes) else "path",
                       "max_depth": int(max_depth)},
        "sensor": {
            **lens, "fov": float(camera.fov), "fov_axis": camera.fov_axis,
            "near_clip": 1e-4, "far_clip": 1e7,
            "to_world": mi.ScalarTransform4f().look_at(origin=[float(x) for x in camera.origin],
                                                       target=[float(x) for x in camera.target],
                                                       up=[float(x) for x in camera.up]),
            "sampler": {"type": "independent", "sample_count": int(spp), "seed": int(seed)},
            "film": {"type": "hdrfilm", "width": int(width), "height": int(height),
                     "rfilter": {"type": "box"}, "pixel_format": "rgb", "component_format": "float32"},
        },
    }
    for index, mesh in enumerate(scene.meshes):
        material = scene.materials[mesh.material]
        transform = mesh.transform_at(frame)
        normals = mesh.normals_at(frame)
        normals = None if normals is None else transform_normals(transform, normals)
        key = f"mesh{index:04d}-" + re.sub(r"[^A-Za-z0-9_-]", "_", mesh.name)
        colors = vertex_colors_as_rendered(mesh)
        if colors is not None and material.kind == "plastic":
            raise SceneError(f"mesh {mesh.name!r}: Mitsuba's plastic cannot read vertex colours (its sampling "
                             f"weight needs a texture's mean); give the mesh a texture or another material")
        textured = None if mesh.texture is None else textured_reflectance(mi, mesh.texture, material.reflectance)
        tilted = None if mesh.normal_map is None else partial(normal_mapped_bsdf, mi, mesh.normal_map)
        mapped = (None if mesh.metal_rough_map is None
                  else metal_rough_bsdf(mi, mesh, material, colors is not None, textured))
        bsdf = surface_bsdf(material, colors is not None, textured, tilted, mapped)
        if mesh.is_cut_out:
            bsdf = {"type": "mask", "opacity": cutout_opacity(mi, mesh.texture, mesh.alpha_mode), "bsdf": bsdf}
        emission = material.emission if material.is_emissive else None
        if emission is not None and mesh.is_cut_out:
            emission = cut_out_radiance(mi, mesh, emission)
        elif emission is not None and mesh.emission_texture is not None:
            emission = textured_reflectance(mi, mesh.emission_texture, emission)   # radiance, tinted alike
        interior = None
        if material.absorbs:      # its sigma_t holds values of at most 1, as a reflectance: a scale carries the rest
            peak = float(material.absorption.max())
            interior = {"type": "homogeneous", "sigma_t": _rgb(material.absorption / peak), "scale": peak,
                        "albedo": 0.0}
        result[key] = _mitsuba_mesh(mi, key, transform_points(transform, mesh.vertices_at(frame)), mesh.faces, normals,
                                    bsdf, emission,
                                    None if colors is None else colors * material.reflectance, mesh.uvs, interior)
    for index, light in enumerate(scene.lights_at(frame)):
        if isinstance(light, SpotLight):
            axis = np.asarray(light.direction, np.float64)
            up = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
            result[f"light{index:03d}"] = {
                "type": "spot", "intensity": _rgb(light.intensity), "cutoff_angle": light.cutoff_angle,
                "beam_width": light.beam_width,
                "to_world": mi.ScalarTransform4f().look_at(origin=[float(x) for x in light.position],
                                                           target=[float(x) for x in light.position + axis],
                                                           up=[float(x) for x in up])}
        elif isinstance(light, PointLight):
            result[f"light{index:03d}"] = {"type": "point", "position": [float(x) for x in light.position],
                                           "intensity": _rgb(light.intensity)}
        elif isinstance(light, DirectionalLight):
            result[f"light{index:03d}"] = {"type": "directional",
                                           "direction": [float(x) for x in light.direction],
                                           "irradiance": _rgb(light.irradiance)}
        else:
            raise TypeError(f"unknown light type {type(light).__name__}")
    if scene.environment is not None:
        scaled = np.asarray(scene.environment, np.float32) * np.asarray(scene.background, np.float32)
        turn = mi.ScalarTransform4f().rotate([0, 1, 0], float(scene.environment_rotation))
        result["background"] = {"type": "envmap", "bitmap": mi.Bitmap(np.ascontiguousarray(scaled)), "to_world": turn}
    elif np.any(np.asarray(scene.background) > 0):
        result["background"] = {"type": "constant", "radiance": _rgb(scene.background)}
    return result


LLVM19 = Path("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1")
PASS_SPP = 512   # a gold renders in passes of at most this many samples (the wavefront's memory)


def variant_choice() -> tuple[str, list[str]]:
    """(the fastest variant here, a "Mitsuba VARIANT: skipped (why)" line for each faster one that is
    not). Imports drjit and mitsuba, pointing Dr.Jit at LLVM 19 first unless DRJIT_LIBLLVM_PATH is set."""
    if LLVM19.exists():
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", str(LLVM19))
    import drjit as dr
    import mitsuba as mi

    skipped = []
    if "cuda_ad_rgb" not in mi.variants():
        skipped.append("Mitsuba cuda_ad_rgb: skipped (this Mitsuba build has no CUDA variants)")
    elif not dr.has_backend(dr.JitBackend.CUDA):
        skipped.append("Mitsuba cuda_ad_rgb: skipped (Dr.Jit finds no CUDA device)")
    else:
        return "cuda_ad_rgb", skipped
    if "DRJIT_LIBLLVM_PATH" in os.environ:
        return "llvm_ad_rgb", skipped
    skipped.append(f"Mitsuba llvm_ad_rgb: skipped (no LLVM 19 at {LLVM19} and DRJIT_LIBLLVM_PATH unset; "
                   "apt-get install -y libllvm19)")
    return "scalar_rgb", skipped


def load_mitsuba(variant: str | None = None):
    """The mitsuba module set to ``variant`` (default: ``variant_choice``'s)."""
    if variant is None:
        variant = variant_choice()[0]
    import mitsuba as mi

    mi.set_variant(variant)
    return mi


def timed_render(mi, scene: Scene, size, spp: int, max_depth: int, seed: int = 0, frame: int = 0):
    """(image (H, W, 3) float32, seconds) of Mitsuba's path tracer on our ``scene`` at ``frame``; the scene
    load is not timed, the copy of the image to numpy (which waits for the JIT variants' kernels) is."""
    loaded = mi.load_dict(to_mitsuba(scene, size[0], size[1], spp, max_depth, frame, seed=seed))
    started = time.perf_counter()
    image = np.array(mi.render(loaded, spp=spp, seed=seed), np.float32)[..., :3]
    return image, time.perf_counter() - started


def render_in_passes(mi, scene: Scene, size, spp: int, max_depth: int, seed: int, frame: int = 0) -> np.ndarray:
    """(H, W, 3) float32: Mitsuba's render of ``scene`` at ``frame`` in passes of at most PASS_SPP samples
    seeded ``seed``, ``seed`` + 1, …, averaged by their sample counts."""
    passes = -(-spp // PASS_SPP)
    counts = [spp // passes + (k < spp % passes) for k in range(passes)]
    total = sum(count * timed_render(mi, scene, size, count, max_depth, seed + k, frame)[0].astype(np.float64)
                for k, count in enumerate(counts))
    return (total / spp).astype(np.float32)
