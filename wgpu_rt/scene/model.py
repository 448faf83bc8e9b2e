"""The scene model: plain dataclasses that every loader produces and the GPU packers consume.

Units and conventions follow Mitsuba 3 so that scenes can be compared pixel for pixel: right-handed
world space, a look-at camera with a field of view in degrees measured along ``fov_axis``, linear RGB
reflectances in [0, 1], emitted radiance in W·sr⁻¹·m⁻² per channel. Animation is per integer frame:
``Camera``, object transforms and lights are given as keyframes and linearly interpolated (look-at vectors
for the camera, matrices element-wise for objects, a light's numbers each; keyframes are meant to be dense
enough for that).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

import numpy as np

MATERIAL_KINDS = ("diffuse", "conductor", "dielectric", "plastic", "thin_dielectric")
GLASS_KINDS = ("dielectric", "thin_dielectric")
FOV_AXES = ("x", "y", "smaller", "larger")
# Narrower than this, float32 ray directions no longer tell neighbouring pixels apart (tan(fov/2) / 128
# is float32's epsilon at 256 pixels); towards 0 the 1/tan(fov/2) of the motion vectors overflows.
MIN_FOV = 1e-3
CUTOUT_ALPHA = 0.5   # a texture's alpha below which its surface is cut away (wgsl/trace/cutouts.wgsl)
ALPHA_MODES = ("mask", "blend")   # how an (H, W, 4) texture's alpha cuts its surface (Mesh.alpha_mode)


def _rgb(value, what: str, highest: float = np.inf) -> np.ndarray:
    """``value`` (a number or 3) as float32 RGB, each channel finite and in [0, ``highest``]."""
    with np.errstate(over="ignore"):        # beyond float32 becomes inf, refused below
        arr = np.broadcast_to(np.asarray(value, dtype=np.float32), (3,)).copy()
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} must be finite, got {arr.tolist()}")
    if np.any(arr < 0) or np.any(arr > highest):
        bounds = "non-negative" if highest == np.inf else f"in [0, {highest:g}] per channel"
        raise ValueError(f"{what} must be {bounds}, got {arr.tolist()}")
    return arr


@dataclass
class Material:
    """A surface.

    - ``diffuse``: Lambertian with ``reflectance``.
    - ``conductor``: GGX microfacet metal, complex IOR ``eta`` + i·``k`` per channel, tinted by
      ``reflectance`` (Mitsuba's specular_reflectance); ``roughness`` is the GGX alpha (0 = mirror).
      The default eta=0, k=1 is a perfect mirror, as Mitsuba's material 'none'.
    - ``dielectric``: glass with interior ``ior`` over exterior 1.0; ``roughness`` 0 = smooth; light that
      crosses its surface (either way) is tinted by ``transmittance`` (Mitsuba's specular_transmittance: a
      closed glass object tints what passes through it twice), and inside it light is absorbed at the rate
      ``absorption`` per unit length (Beer–Lambert, per channel: Mitsuba's homogeneous interior medium of that
      sigma_t and albedo 0; the segments a path travels inside a closed glass mesh, ending on its back faces).
    - ``thin_dielectric``: a smooth pane of glass of ``ior`` with no thickness (Mitsuba's ``thindielectric``): light
      goes straight through it or is reflected, by the Fresnel reflectance summed over the reflections inside the
      pane, R + (1 − R)² R / (1 − R²); tinted by ``transmittance`` where it passes. For windows and films modelled
      as single surfaces (a closed solid is a ``dielectric``); it has no inside to absorb in, and no roughness.
    - ``plastic``: Lambertian ``reflectance`` under a dielectric coat of ``ior``, smooth at ``roughness`` 0
      (Mitsuba's ``plastic``, linear: Fresnel-weighted mirror reflection at the coat, the rest diffuse, each way
      through it), else a GGX coat of that alpha (Mitsuba's ``roughplastic``, linear).
    Any material may also emit ``emission`` (radiance, front side only, as Mitsuba's area emitter).
    """

    kind: str = "diffuse"
    reflectance: np.ndarray = field(default_factory=lambda: np.full(3, 0.5, np.float32))
    roughness: float = 0.0
    ior: float = 1.5
    eta: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))
    k: np.ndarray = field(default_factory=lambda: np.ones(3, np.float32))
    emission: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))
    transmittance: np.ndarray = field(default_factory=lambda: np.ones(3, np.float32))
    absorption: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))

    def __post_init__(self):
        if self.kind not in MATERIAL_KINDS:
            raise ValueError(f"unknown material kind {self.kind!r}; expected one of {MATERIAL_KINDS}")
        # A reflectance above 1 would create energy.
        self.reflectance = _rgb(self.reflectance, "reflectance", highest=1.0)
        self.transmittance = _rgb(self.transmittance, "transmittance", highest=1.0)
        self.eta = _rgb(self.eta, "eta")
        self.k = _rgb(self.k, "k")
        self.emission = _rgb(self.emission, "emission")
        self.absorption = _rgb(self.absorption, "absorption")
        if self.kind != "dielectric" and np.any(self.absorption > 0):
            raise ValueError(f"absorption is a dielectric's (inside its glass), not a {self.kind}'s")
        if self.kind == "thin_dielectric" and float(self.roughness) > 0:
            raise ValueError(f"a thin_dielectric is smooth (Mitsuba's thindielectric), got roughness {self.roughness}")
        if not (0.0 <= float(self.roughness) <= 1.0):
            raise ValueError(f"roughness must be in [0, 1], got {self.roughness}")
        if not float(self.ior) > 0.0:
            raise ValueError(f"ior must be positive, got {self.ior}")

    @property
    def is_emissive(self) -> bool:
        return bool(np.any(self.emission > 0))

    @property
    def absorbs(self) -> bool:
        return bool(np.any(self.absorption > 0))


@dataclass
class Camera:
    """A look-at camera with a box filter: a pinhole (Mitsuba's ``perspective`` sensor), or with an
    ``aperture_radius`` above 0 a thin lens (Mitsuba's ``thinlens``): rays leave a disc of that radius
    about ``origin`` across the view direction and meet where the pinhole's would on the plane
    ``focus_distance`` ahead of it (default: the target's distance), so only that plane is sharp."""

    origin: np.ndarray
    target: np.ndarray
    up: np.ndarray = field(default_factory=lambda: np.array([0, 1, 0], np.float32))
    fov: float = 39.3077
    fov_axis: str = "smaller"
    aperture_radius: float = 0.0
    focus_distance: float | None = None

    def __post_init__(self):
        self.origin = np.asarray(self.origin, np.float32)
        self.target = np.asarray(self.target, np.float32)
        self.up = np.asarray(self.up, np.float32)
        if self.fov_axis not in FOV_AXES:
            raise ValueError(f"unknown fov_axis {self.fov_axis!r}; expected one of {FOV_AXES}")
        if not (MIN_FOV <= float(self.fov) < 180.0):
            raise ValueError(f"fov must be in [{MIN_FOV:g}, 180) degrees, got {self.fov}")
        if not (np.isfinite(self.aperture_radius) and float(self.aperture_radius) >= 0.0):
            raise ValueError(f"aperture_radius must be finite and not negative, got {self.aperture_radius}")
        if self.focus_distance is None:
            self.focus_distance = float(np.linalg.norm(self.target.astype(np.float64) - self.origin))
        if not (np.isfinite(self.focus_distance) and float(self.focus_distance) > 0.0):
            raise ValueError(f"focus_distance must be finite and positive, got {self.focus_distance}")
        self.aperture_radius, self.focus_distance = float(self.aperture_radius), float(self.focus_distance)

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unit (right, up, forward) vectors. Image +x goes along ``right`` and image +y (rows, top
        to bottom) along ``-up``, which is how Mitsuba's perspective sensor lays out its film."""
        # float64: float32 squared norms overflow (or vanish) for distances beyond 1e19 (below 1e-19).
        forward = self.target.astype(np.float64) - self.origin
        forward = forward / np.linalg.norm(forward)
        right = np.cross(forward, self.up)
        right = right / np.linalg.norm(right)
        up = np.cross(right, forward)
        return right.astype(np.float32), up.astype(np.float32), forward.astype(np.float32)

    def tan_half_fov(self, width: int, height: int) -> tuple[float, float]:
        """tan of half the horizontal and vertical field of view for a width×height image."""
        t = float(np.tan(np.radians(self.fov) / 2))
        aspect = width / height
        axis = self.fov_axis
        if axis == "smaller":
            axis = "x" if width <= height else "y"
        elif axis == "larger":
            axis = "x" if width >= height else "y"
        return (t, t / aspect) if axis == "x" else (t * aspect, t)


@dataclass
class Mesh:
    """A triangle mesh in object space, placed by ``transform`` (4×4, object → world).

    ``keyframes`` maps frame → 4×4 transform for animated objects; between keyframes the matrix is
    interpolated element-wise, outside them the nearest keyframe holds.

    Instances: meshes that hold the very same vertex, face and normal arrays (one set of numpy objects,
    not equal copies: ``shape_key``) are placements of one shape. ``instance`` makes one; the scene
    loader gives each entry of a mesh's ``instances`` list one. Every placement is a Mesh of its own
    (name, material, transform, keyframes), so whatever walks ``Scene.meshes`` sees them all, while
    the triangles exist once and the two-level geometry builds one BVH for them (``Scene.shapes``).
    """

    name: str
    vertices: np.ndarray            # (V, 3) float32
    faces: np.ndarray               # (F, 3) uint32
    material: str                   # key into Scene.materials
    normals: np.ndarray | None = None  # (V, 3) per-vertex shading normals, or None for flat shading
    transform: np.ndarray = field(default_factory=lambda: np.eye(4, dtype=np.float32))
    keyframes: dict[int, np.ndarray] = field(default_factory=dict)
    # (V, 3) linear RGB in [0, 1] per vertex, interpolated across each triangle, multiplying the material's
    # reflectance (a mesh file's vertex or face colours); stored on the GPU as 8-bit sRGB (``srgb8``), so
    # every renderer of the scene reads ``vertex_colors_as_rendered``.
    colors: np.ndarray | None = None
    # A colour texture: (H, W, 3) uint8 sRGB codes, row 0 the image's top, and (V, 2) float32 coordinates
    # per vertex (trimesh's convention: v = 1 at the image's top; repeated outside [0, 1]), interpolated
    # across each triangle; its bilinear sample (texels decoded to linear first, ``sample_texture``)
    # multiplies the material's reflectance. A mesh has ``colors`` or a texture, not both. Meshes may share
    # one image array (it is stored once). An (H, W, 4) texture's alpha (codes, read raw and bilinearly,
    # ``sample_alpha``) cuts the surface away wherever it is below CUTOUT_ALPHA: leaves, fences; with
    # ``alpha_mode`` "blend", a point is there with probability alpha (stochastic transparency, glTF's BLEND).
    texture: np.ndarray | None = None
    uvs: np.ndarray | None = None
    # A tangent-space normal map at the same coordinates: (H, W, 3) uint8 codes of (n + 1) / 2, read raw
    # (not sRGB) and bilinearly as the texture is; x along the direction of increasing u, y along increasing
    # v, z along the interpolated normal (OpenGL's and glTF's convention; Mitsuba's ``normalmap``): the
    # shading normal there becomes ``mapped_normal``.
    normal_map: np.ndarray | None = None
    # An emission texture at the same coordinates: (H, W, 3) uint8 sRGB codes, sampled as ``texture`` is, whose
    # colour multiplies the emission of the mesh's material (glTF's emissiveTexture), seen and sampled alike.
    emission_texture: np.ndarray | None = None
    alpha_mode: str = "mask"
    # glTF's metallic-roughness texture at the same coordinates, its material's factors applied: (H, W, 3) uint8
    # codes read raw and bilinearly, the perceptual roughness r in green (GGX alpha r²) and the metalness in blue
    # (red unused). On a ``plastic`` (the base colour under a coat of its ior): at each point the surface is the
    # metal of glTF (a ``conductor`` of Fresnel 1 tinted by the reflectance) with probability its metalness, else
    # the plastic, either of the texel's roughness: glTF's blend of the two in expectation, as Mitsuba's
    # ``blendbsdf`` (wgsl/trace/metal_rough_maps.wgsl). On a ``conductor``: its roughness per point (the metalness
    # not read). On another kind, an error.
    metal_rough_map: np.ndarray | None = None
    # A deforming mesh (a glTF skin or morph targets): frame → its (V, 3) float32 vertices in its object space, and
    # where it has normals frame → its (V, 3) normals; blended linearly between keyframes (normals renormalized), the
    # nearest outside them, as ``keyframes``; placed by ``transform_at`` as ever. Empty: ``vertices`` at every frame.
    vertex_keyframes: dict[int, np.ndarray] = field(default_factory=dict)
    normal_keyframes: dict[int, np.ndarray] = field(default_factory=dict)

    def transform_at(self, frame: int) -> np.ndarray:
        return _interpolate(self.keyframes, frame, self.transform)

    def vertices_at(self, frame: int) -> np.ndarray:
        """(V, 3) float32: its vertices at ``frame``, in its object space."""
        return _interpolate(self.vertex_keyframes, frame, self.vertices)

    def normals_at(self, frame: int) -> np.ndarray | None:
        """(V, 3) float32 unit vertex normals at ``frame`` in its object space (None where it has none)."""
        if self.normals is None or not self.normal_keyframes:
            return self.normals
        normals = _interpolate(self.normal_keyframes, frame, self.normals)
        length = np.linalg.norm(normals, axis=1, keepdims=True)
        return np.where(length > 0, normals / np.maximum(length, 1e-30), self.normals).astype(np.float32)

    @property
    def deforms(self) -> bool:
        """Whether its vertex keyframes hold more than one shape (asked every frame: it stops at the first
        keyframe that differs from the first)."""
        shapes = iter(self.vertex_keyframes.values())
        first = next(shapes, None)
        return any(not np.array_equal(shape, first) for shape in shapes)

    def pose_key(self, frame: int) -> bytes:
        """Its placement, and a deforming mesh's shape, at ``frame``: equal for frames where it is the same."""
        key = self.transform_at(frame).tobytes()
        return key + self.vertices_at(frame).tobytes() if self.deforms else key

    @property
    def is_cut_out(self) -> bool:
        """Whether its texture's alpha cuts parts of it away."""
        return self.texture is not None and np.ndim(self.texture) == 3 and np.shape(self.texture)[2] == 4

    @property
    def is_animated(self) -> bool:
        return len({m.tobytes() for m in self.keyframes.values()}) > 1

    @property
    def shape_key(self) -> tuple[int, ...]:
        """Equal for meshes that share their arrays (instances of one shape), else different."""
        return (id(self.vertices), id(self.faces), id(self.normals), id(self.colors), id(self.texture), id(self.uvs),
                id(self.normal_map), id(self.emission_texture), hash(self.alpha_mode), id(self.metal_rough_map),
                id(self.vertex_keyframes) if self.vertex_keyframes else 0)

    def instance(self, name: str, material: str | None = None, transform=None, keyframes=None) -> Mesh:
        """Another placement of this mesh's shape (its arrays shared, not copied, and made read-only so
        that an edit cannot move every instance at once), with its own name, material (default: this
        mesh's), transform (default: identity) and keyframes (default: none)."""
        for array in (self.vertices, self.faces, self.normals, self.colors, self.texture, self.uvs, self.normal_map,
                      self.emission_texture, self.metal_rough_map):
            if array is not None:
                array.flags.writeable = False
        placement = np.eye(4) if transform is None else transform
        return Mesh(name, self.vertices, self.faces, self.material if material is None else material,
                    self.normals, np.asarray(placement, np.float32), dict(keyframes or {}), self.colors,
                    self.texture, self.uvs, self.normal_map, self.emission_texture, self.alpha_mode,
                    self.metal_rough_map, self.vertex_keyframes, self.normal_keyframes)


def srgb8(colors: np.ndarray) -> np.ndarray:
    """(..., 3) linear RGB in [0, 1] → the (..., 3) uint8 sRGB codes the GPU stores (the nearest)."""
    linear = np.clip(np.asarray(colors, np.float64), 0.0, 1.0)
    encoded = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055)
    return np.round(encoded * 255.0).astype(np.uint8)


def linear_from_srgb8(codes: np.ndarray) -> np.ndarray:
    """uint8 sRGB codes → linear RGB (float32), as wgsl/accel/bvh.wgsl's tri_color decodes them."""
    encoded = np.asarray(codes, np.float64) / 255.0
    return np.where(encoded <= 0.04045, encoded / 12.92, ((encoded + 0.055) / 1.055) ** 2.4).astype(np.float32)


def vertex_colors_as_rendered(mesh: "Mesh") -> np.ndarray | None:
    """``mesh.colors`` as the tracer reads them (through 8-bit sRGB), or None."""
    return None if mesh.colors is None else linear_from_srgb8(srgb8(mesh.colors))


def _bilinear(values: np.ndarray, uvs: np.ndarray) -> np.ndarray:
    """(N, C) float64: the (H, W, C) ``values`` at (N, 2) coordinates ``uvs`` as the tracer samples an image
    (wgsl/trace/surface_textures.wgsl) and Mitsuba's bitmap with bilinear filtering and repeat wrapping does:
    coordinates wrapped to [0, 1), v = 1 at the image's top, texel centres at half-integers."""
    height, width = values.shape[:2]
    uvs = np.asarray(uvs, np.float64)
    x = (uvs[:, 0] - np.floor(uvs[:, 0])) * width - 0.5
    y = (1.0 - uvs[:, 1] - np.floor(1.0 - uvs[:, 1])) * height - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0, y0 = x0.astype(np.int64), y0.astype(np.int64)
    texel = lambda col, row: values[row % height, col % width]  # noqa: E731
    top = (1 - fx) * texel(x0, y0) + fx * texel(x0 + 1, y0)
    bottom = (1 - fx) * texel(x0, y0 + 1) + fx * texel(x0 + 1, y0 + 1)
    return (1 - fy) * top + fy * bottom


def sample_texture(texture: np.ndarray, uvs: np.ndarray, srgb: bool = True) -> np.ndarray:
    """(N, 3) float32 linear RGB: the sRGB8 ``texture`` (its first three channels) at (N, 2) coordinates
    ``uvs``, texels decoded to linear and blended bilinearly (``_bilinear``). ``srgb=False`` reads the codes
    raw (code / 255: a normal map's)."""
    rgb = np.asarray(texture)[..., :3]
    linear = (linear_from_srgb8(rgb) if srgb else rgb / 255.0).astype(np.float64)
    return _bilinear(linear, uvs).astype(np.float32)


def sample_alpha(texture: np.ndarray, uvs: np.ndarray) -> np.ndarray:
    """(N,) float32: an (H, W, 4) ``texture``'s alpha (code / 255) at (N, 2) coordinates ``uvs``, bilinearly,
    as wgsl/trace/surface_textures.wgsl's sample_alpha; where it is below CUTOUT_ALPHA the surface is cut away."""
    return _bilinear(np.asarray(texture)[..., 3:] / 255.0, uvs)[:, 0].astype(np.float32)


def mapped_normal(normal: np.ndarray, dp_du: np.ndarray, texel: np.ndarray) -> np.ndarray:
    """(N, 3) unit shading normals where a normal map's (N, 3) raw samples ``texel`` (``sample_texture``, srgb
    False) tilt the (N, 3) unit interpolated ``normal``, as the tracer (wgsl/trace/surface_textures.wgsl) and
    Mitsuba's ``normalmap`` do: 2·texel − 1 in the frame of the normal, its tangent ``dp_du`` (the surface's
    derivative along u) made perpendicular to it, and their cross product n × s."""
    n = np.asarray(normal, np.float64)
    du = np.asarray(dp_du, np.float64)
    s = du - n * np.sum(n * du, axis=-1, keepdims=True)
    s = s / np.linalg.norm(s, axis=-1, keepdims=True)
    local = 2.0 * np.asarray(texel, np.float64) - 1.0
    mapped = local[:, :1] * s + local[:, 1:2] * np.cross(n, s) + local[:, 2:] * n
    return (mapped / np.linalg.norm(mapped, axis=-1, keepdims=True)).astype(np.float32)


def environment_uv(directions: np.ndarray) -> np.ndarray:
    """(N, 2) latitude-longitude coordinates of (N, 3) unit ``directions`` (Mitsuba's envmap convention, +y up):
    u = atan2(x, -z) / 2π, v = acos(y) / π (0 straight up)."""
    d = np.asarray(directions, np.float64)
    return np.stack([np.arctan2(d[:, 0], -d[:, 2]) / (2 * np.pi), np.arccos(np.clip(d[:, 1], -1, 1)) / np.pi], -1)


def sample_environment(image: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """(N, 3) float32: the (H, W, 3) linear latitude-longitude ``image`` seen along (N, 3) unit ``directions``,
    as the tracer (wgsl/trace/environment.wgsl) and Mitsuba's envmap read it: columns centred at
    u = (j + ½) / W and periodic, rows at v = i / (H − 1) (the first and last on the poles), bilinear."""
    image = np.asarray(image, np.float64)
    height, width = image.shape[:2]
    uv = environment_uv(directions)
    x = (uv[:, 0] - 0.5 / width) % 1.0 * width
    y = uv[:, 1] * (height - 1)
    x0 = np.minimum(np.floor(x), width - 1).astype(np.int64)
    y0 = np.minimum(np.floor(y), height - 2).astype(np.int64)
    wx, wy = (x - x0)[:, None], (y - y0)[:, None]
    x1 = (x0 + 1) % width
    top = (1 - wx) * image[y0, x0] + wx * image[y0, x1]
    bottom = (1 - wx) * image[y0 + 1, x0] + wx * image[y0 + 1, x1]
    return ((1 - wy) * top + wy * bottom).astype(np.float32)


@dataclass
class _Light:
    """What the light kinds share: ``keyframes`` (frame → the light's state there, a light of its kind without
    keyframes of its own). Between keyframes every number is interpolated linearly (a direction renormalized),
    outside them the nearest holds, as for meshes; the light's own fields are its state without keyframes."""

    keyframes: dict = field(default_factory=dict, kw_only=True)
    POWER = ""                      # the field that scales with the light's strength

    def at(self, frame: int):
        """The light's state at ``frame`` (without keyframes)."""
        if not self.keyframes:
            return self
        lo, hi, w = _bracket(sorted(self.keyframes), frame)
        start, end = self.keyframes[lo], self.keyframes[hi]
        if w == 0:
            return start
        state = {f.name: (1 - w) * np.asarray(getattr(start, f.name), np.float64)
                 + w * np.asarray(getattr(end, f.name), np.float64)
                 for f in fields(start) if f.name != "keyframes"}
        if "direction" in state:
            state["direction"] = state["direction"] / np.linalg.norm(state["direction"])
        return type(start)(**{name: value.astype(np.float32) if value.ndim else float(value)
                              for name, value in state.items()})

    def scaled(self, factor: float):
        """This light ``factor`` times as strong, at every keyframe."""
        return replace(self, **{self.POWER: getattr(self, self.POWER) * np.float32(factor)},
                       keyframes={f: key.scaled(factor) for f, key in self.keyframes.items()})

    @property
    def state(self) -> bytes:
        """Its fields but the keyframes: equal for lights that shine alike."""
        return b"".join(np.asarray(getattr(self, f.name), np.float64).tobytes()
                        for f in fields(self) if f.name != "keyframes")

    @property
    def moves(self) -> bool:
        """Whether its keyframes hold more than one state."""
        return len({key.state for key in self.keyframes.values()}) > 1


@dataclass
class PointLight(_Light):
    position: np.ndarray
    intensity: np.ndarray           # W·sr⁻¹ per channel
    POWER = "intensity"


@dataclass
class SpotLight(PointLight):
    """A point light shining into a cone (Mitsuba's ``spot``): ``intensity`` along ``direction`` and out to
    ``beam_width`` degrees from it, falling off linearly in angle to 0 at ``cutoff_angle`` degrees."""

    direction: np.ndarray = field(default_factory=lambda: np.array([0, 0, 1], np.float32))
    cutoff_angle: float = 20.0
    beam_width: float | None = None   # default: three quarters of cutoff_angle, as Mitsuba's

    def __post_init__(self):
        direction = np.asarray(self.direction, np.float64)
        if not (np.all(np.isfinite(direction)) and np.linalg.norm(direction) > 0):
            raise ValueError(f"direction must be finite and not zero, got {direction.tolist()}")
        self.direction = (direction / np.linalg.norm(direction)).astype(np.float32)
        if not 0.0 < float(self.cutoff_angle) <= 90.0:
            raise ValueError(f"cutoff_angle must be in (0, 90] degrees, got {self.cutoff_angle}")
        if self.beam_width is None:
            self.beam_width = 0.75 * float(self.cutoff_angle)
        if not 0.0 <= float(self.beam_width) < float(self.cutoff_angle):
            raise ValueError(f"beam_width must be in [0, cutoff_angle) degrees, got {self.beam_width}")
        self.cutoff_angle, self.beam_width = float(self.cutoff_angle), float(self.beam_width)

    def falloff(self, directions: np.ndarray) -> np.ndarray:
        """(N,) the share of ``intensity`` sent along (N, 3) unit ``directions`` from the light (numpy
        reference of wgsl/trace/emitters.wgsl's spot_falloff)."""
        angle = np.degrees(np.arccos(np.clip(np.asarray(directions, np.float64) @ self.direction, -1, 1)))
        ramp = np.clip((self.cutoff_angle - angle) / (self.cutoff_angle - self.beam_width), 0.0, 1.0)
        return np.where(angle <= self.beam_width, 1.0, ramp)


@dataclass
class DirectionalLight(_Light):
    direction: np.ndarray           # direction the light travels (from the light toward the scene)
    irradiance: np.ndarray          # W·m⁻² per channel on a surface facing it
    POWER = "irradiance"


@dataclass
class Scene:
    """Everything that is rendered. ``camera_keyframes`` animates the camera like Mesh.keyframes."""

    camera: Camera
    meshes: list[Mesh]
    materials: dict[str, Material]
    lights: list = field(default_factory=list)          # PointLight (or SpotLight) | DirectionalLight
    background: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))
    camera_keyframes: dict[int, Camera] = field(default_factory=dict)
    frame_count: int = 1
    name: str = "scene"
    # An environment map: an (H, W, 3) float32 linear latitude-longitude image (at least 2×3; row 0 straight
    # up, +y; ``sample_environment``), the sky's radiance along each direction times ``background`` (then a
    # per-channel scale). None: the sky is ``background`` everywhere.
    environment: np.ndarray | None = None
    environment_rotation: float = 0.0   # degrees the map is turned about +y (Mitsuba's envmap to_world)

    def background_mean(self) -> np.ndarray:
        """(3,) the sky's radiance averaged over all directions (``background`` itself without an environment)."""
        background = np.asarray(self.background, np.float64)
        if self.environment is None:
            return background
        height = self.environment.shape[0]
        weights = np.sin(np.pi * np.arange(height) / (height - 1))[:, None, None]
        weighted = (np.asarray(self.environment, np.float64) * weights).sum((0, 1))
        return background * weighted / (weights.sum() * self.environment.shape[1])

    def camera_at(self, frame: int) -> Camera:
        if not self.camera_keyframes:
            return self.camera
        lo, hi, w = _bracket(sorted(self.camera_keyframes), frame)
        a, b = self.camera_keyframes[lo], self.camera_keyframes[hi]
        if w == 0:
            return a
        mix = lambda x, y: ((1 - w) * x + w * y).astype(np.float32)  # noqa: E731
        return Camera(mix(a.origin, b.origin), mix(a.target, b.target), mix(a.up, b.up),
                      (1 - w) * a.fov + w * b.fov, a.fov_axis, (1 - w) * a.aperture_radius + w * b.aperture_radius,
                      (1 - w) * a.focus_distance + w * b.focus_distance)

    def textures(self) -> list[np.ndarray]:
        """The meshes' texture images, normal maps, emission textures and metal-rough maps, each distinct array once,
        in order of first appearance (a mesh's image's index in this list is the one the tracer stores for its
        triangles)."""
        images = [image for m in self.meshes
                  for image in (m.texture, m.normal_map, m.emission_texture, m.metal_rough_map) if image is not None]
        return list({id(image): image for image in images}.values())

    def metal_rough_iors(self) -> dict[int, float]:
        """Each metal-rough map on a plastic (by ``id``) → the plastic's ior, whose coat tables it carries on the
        device; a SceneError naming the mesh where a map is on a kind other than a plastic or a conductor, or one
        map on plastics of two iors."""
        from ..errors import SceneError

        iors: dict[int, float] = {}
        for mesh in self.meshes:
            if mesh.metal_rough_map is None:
                continue
            material = self.materials[mesh.material]
            if material.kind not in ("plastic", "conductor"):
                raise SceneError(f"mesh {mesh.name!r}: a metal-rough map needs a plastic (each point the plastic or "
                                 f"glTF's metal) or a conductor (roughened per point), got {material.kind!r} "
                                 f"({mesh.material!r})")
            if material.kind == "conductor":
                continue
            ior = iors.setdefault(id(mesh.metal_rough_map), float(material.ior))
            if ior != float(material.ior):
                raise SceneError(f"mesh {mesh.name!r}: its metal-rough map is on plastics of two iors ({ior:g} and "
                                 f"{material.ior:g}); give each its own copy of the image")
        return iors

    def shapes(self) -> list[list[int]]:
        """Indices into ``meshes`` grouped by shape (``Mesh.shape_key``), in order of first appearance:
        a group of several is one shape placed several times."""
        groups: dict[tuple, list[int]] = {}
        for index, mesh in enumerate(self.meshes):
            groups.setdefault(mesh.shape_key, []).append(index)
        return list(groups.values())

    @property
    def has_instances(self) -> bool:
        """Whether some shape is placed more than once."""
        return any(len(group) > 1 for group in self.shapes())

    @property
    def has_moving_lights(self) -> bool:
        """Whether a light's keyframes move it or change its strength or cone."""
        return any(light.moves for light in self.lights)

    @property
    def is_animated(self) -> bool:
        """Whether its frames differ (the camera, a mesh or a light moves)."""
        return self.has_motion or self.has_moving_lights

    def lights_at(self, frame: int) -> list:
        """Its lights as they are at ``frame`` (``_Light.at``)."""
        return [light.at(frame) for light in self.lights]

    def lights_key(self, frame: int) -> bytes:
        """Its lights' states at ``frame``: equal for frames they light alike."""
        return b"".join(light.state for light in self.lights_at(frame))

    @property
    def has_motion(self) -> bool:
        cams = {(c.origin.tobytes(), c.target.tobytes(), c.up.tobytes(), c.fov)
                for c in self.camera_keyframes.values()}
        return len(cams) > 1 or any(m.is_animated or m.deforms for m in self.meshes)

    @property
    def deforms(self) -> bool:
        """Whether a mesh changes shape from frame to frame (``Mesh.vertex_keyframes``)."""
        return any(m.deforms for m in self.meshes)

    def with_light_scaled(self, factor: float) -> Scene:
        """A copy whose every source (emission, point and sun lights, background) gives ``factor`` times the
        light: the same scene in other units, which renders as this one times ``factor``."""
        factor = np.float32(factor)
        materials = {name: replace(m, emission=m.emission * factor) for name, m in self.materials.items()}
        lights = [light.scaled(factor) for light in self.lights]
        return replace(self, materials=materials, lights=lights, background=self.background * factor)


def _bracket(keys: list[int], frame: int) -> tuple[int, int, float]:
    """The keyframes (sorted ``keys``) about ``frame`` and its weight between them: (lo, hi, w), the value at the
    frame (1 − w)·value(lo) + w·value(hi); w = 0 on a key and outside the keys (where the nearest holds)."""
    if frame <= keys[0]:
        return keys[0], keys[0], 0.0
    if frame >= keys[-1]:
        return keys[-1], keys[-1], 0.0
    lo = max(k for k in keys if k <= frame)
    hi = min(k for k in keys if k >= frame)
    return lo, hi, 0.0 if lo == hi else (frame - lo) / (hi - lo)


def _interpolate(keyframes: dict[int, np.ndarray], frame: int, default: np.ndarray) -> np.ndarray:
    if not keyframes:
        return np.asarray(default, np.float32)
    lo, hi, w = _bracket(sorted(keyframes), frame)
    return ((1 - w) * np.asarray(keyframes[lo]) + w * np.asarray(keyframes[hi])).astype(np.float32)
