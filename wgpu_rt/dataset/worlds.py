"""Procedurally generated training worlds: whole scenes built from a seed, for the truth engine.

``generate_world(seed, mesh_dir=None, frames=1)`` is a pure function of its arguments: the same seed
and the same mesh files give the same ``Scene`` on every machine. A world is

- a set-up (``SETUPS``): a closed room, a room open to the sky, open ground under a sky, or a studio
  sweep (a floor that curves up into the back wall);
- 1–10 objects: shapes from ``trimesh.creation`` (primitives, revolved and extruded profiles, noise-
  displaced surfaces, compounds of several parts) or meshes from ``mesh_dir``;
- materials across the whole material model: dark, bright and saturated diffuse; smooth and rough
  conductors with measured complex IORs (``METALS``); smooth and rough glass and thin glass panes;
  emissive objects;
- lighting (``LIGHTINGS``): tiny and very bright to large and soft area lights, point lights, a sun
  with a coloured sky, emissive objects, or lamps that face a wall or the ceiling so light reaches the
  view only after a bounce;
- a camera with a field of view of 20–90°, sometimes looking through a glass pane or at a mirror;
- in the training family only, sometimes small lamps in view (``LAMPS_IN_VIEW_SHARE``): emitters a few
  pixels to a few dozen across, seen directly, as ceiling lamps along a corridor are (BENCHMARKS.md §30);
  they come from a random stream of their own, so they leave every other choice, and the held-out
  family, as it was (``WORLDS_VERSION`` 2);
- in the training family only, sometimes painted surfaces (``PAINTED_SHARE``): set surfaces and objects
  given textures as vertex colours (checkers, stripes, blotches, fine mottling, ``paint_surfaces``) that
  tint their materials, so the denoiser sees albedos that vary across a surface, as every textured scene a
  user brings has; also from a stream of their own (``WORLDS_VERSION`` 3);
- in the training family only, sometimes a thin-lens camera (``LENS_SHARE``): depth of field, an aperture of
  0.3–3 % of the camera's distance to its target, focused near the target, so the denoiser sees the blur
  and the guides a lens gives (BENCHMARKS.md §47); from a stream of its own as well (``WORLDS_VERSION`` 4);
- in the training family only, half of the worlds with a sky see it as an environment map (``SKY_MAP_SHARE``,
  ``procedural_sky``): brighter toward the horizon, a glow around the sun, dark ground below, so the sky
  varies with direction as a photographed one does; from a stream of its own (``WORLDS_VERSION`` 5);
- in the training family only, a share of the matte materials coated (``PLASTIC_SHARE``: Mitsuba's smooth
  plastic, a clear coat of index 1.3–1.7 over the same colour), so the denoiser sees mirror images of lights
  and objects on painted and plastic things; from a stream of its own (``WORLDS_VERSION`` 6);
- in the training family only, sometimes flat set surfaces (floors, walls, the ground) with a normal map
  (``NORMAL_MAP_SHARE``, ``relief_normal_map``: tiles, planks, bumps or ripples a few centimetres to a metre
  across), so the denoiser sees shading detail that the albedo does not show but the normal plane does; from
  a stream of its own (``WORLDS_VERSION`` 7);
- in the training family only, a share of those coats rough (``ROUGH_COAT_SHARE``: Mitsuba's roughplastic, GGX
  alpha 0.02–0.6, log-uniform), so the denoiser sees blurred highlights on glossy non-metals, as most of a glTF
  file's non-metals now render (``file_materials``); from a stream of its own (``WORLDS_VERSION`` 8);
- in the training family only, some glass tinted (``TINTED_GLASS_SHARE``: a colour at each crossing of its
  surface, as glTF's transmission tints by the base colour), from a stream of its own (also version 8);
- in the training family only, sometimes a screen between the camera and its target, cut out by a procedural
  alpha (``SCREEN_SHARE``, ``screen_texture``: a lattice, a perforated sheet or leaves), so the denoiser sees
  the sharp edges of holes and what shows and shines through them, as foliage and fences in users' files give
  them; from a stream of its own (also version 8);
- in the training family only, some glass absorbing inside (``ABSORBING_GLASS_SHARE``: coloured deeper where it
  is thicker, as glTF's volume extension makes it), from a stream of its own (``WORLDS_VERSION`` 9);
- in the training family only, sometimes worn metal (``METAL_ROUGH_SHARE``, ``worn_metal_map``): matte and coated
  surfaces and objects made plastics under a metal-rough map — metal tiles among matte ones, metal stripes, or
  blotches of matte patina on metal — so the denoiser sees a surface turn from metal to non-metal from one texel to
  the next, as glTF files' metallic-roughness textures make most real objects; from a stream of its own
  (``WORLDS_VERSION`` 10).

Families. Seeds in ``[0, 2³¹)`` are the ``training`` family, ``[2³¹, 2³²)`` the ``held_out`` family.
Each family has its own procedural shapes (``FAMILY_SHAPES``) and its own share of a mesh folder (a
file's family is fixed by a hash of its name), so a held-out world shares no seed and no geometry with
a training world.

What the material model cannot express is not faked. It has no thin-walled (single-interface) glass
BSDF, so thin glass is geometry: a dielectric slab a few millimetres thick. Compounds are overlapping
closed parts, not boolean unions: no boolean engine (manifold3d, Blender) is a dependency, and using
one only where it happens to be installed would make a seed's world depend on the machine. Overlapping
opaque parts render exactly as their union; compounds are therefore never glass.
"""

from __future__ import annotations

import colorsys
import hashlib
from pathlib import Path

import numpy as np

from ..scene.builtin import GOLD_ETA, GOLD_K, mix_colors, sine_pattern
from ..scene.model import Camera, DirectionalLight, Material, Mesh, PointLight, Scene
from ..scene.primitives import primitive
from ..scene.transforms import compose, rotate, scale, transform_points, translate
from .variety import (HELD_OUT_SHAPES, TRAINING_SHAPES, blackbody_tint, load_mesh_file, load_mesh_folder,
                      make_shape, normalized)

FAMILIES = ("training", "held_out")
FAMILY_SIZE = 2 ** 31
FAMILY_SHAPES = {"training": TRAINING_SHAPES + ("vase", "star_prism", "blob", "compound"),
                 "held_out": HELD_OUT_SHAPES + ("bowl", "gear_prism", "ring")}
SETUPS = ("closed_room", "open_room", "ground", "studio")
LIGHTINGS = {"closed_room": ("ceiling_panel", "tiny_bright", "point", "indirect", "glowing_object"),
             "open_room": ("sun_and_sky",),
             "ground": ("sun_and_sky", "dusk"),
             "studio": ("softboxes", "spotlight")}

# Complex index of refraction (eta, k) at the R, G, B wavelengths of Mitsuba's RGB mode, from measured
# spectra (the data behind Mitsuba's and Tungsten's named conductors).
METALS = {
    "Au": (GOLD_ETA, GOLD_K),
    "Ag": ((0.155265, 0.116723, 0.138381), (4.82835, 3.12225, 2.14696)),
    "Cu": ((0.200438, 0.924033, 1.10221), (3.91295, 2.45285, 2.14219)),
    "Al": ((1.65746, 0.880369, 0.521229), (9.22387, 6.26952, 4.83700)),
    "Cr": ((4.36968, 2.91670, 1.65470), (5.20643, 4.23136, 3.75495)),
    "Ni": ((2.36728, 1.66336, 1.46706), (4.49883, 3.05016, 2.34543)),
}
UP = np.array([0.0, 1.0, 0.0])
CAMERA_MARGIN = 0.15    # closest the camera comes to a wall or the ceiling, metres
# What a world of a seed holds changes with this; datasets record it (truth.check_config). 2: training
# worlds may hold lamps in view; 3: painted surfaces; 4: a thin-lens camera; 5: skies as environment maps;
# 6: coated (plastic) materials; 7: normal maps on set surfaces; 8: rough coats, tinted glass, cut-out screens;
# 9: absorbing glass; 10: worn metal (metal-rough maps).
WORLDS_VERSION = 10
LAMPS_IN_VIEW_SHARE = 0.3   # of the training worlds (not those lit only indirectly)
PAINTED_SHARE = 0.5         # of the training worlds
LENS_SHARE = 0.25           # of the training worlds
LENS_APERTURES = (0.003, 0.03)   # aperture radius over the camera's distance to its target, log-uniform
SKY_MAP_SHARE = 0.5         # of the training worlds with a sky
SKY_MAP_SIZE = (32, 64)     # a procedural sky's rows and columns
PLASTIC_SHARE = 0.3         # of the training worlds' matte materials (not emitters)
ROUGH_COAT_SHARE = 0.5      # of those coats
ROUGH_COAT_ALPHAS = (0.02, 0.6)   # a rough coat's GGX alpha, log-uniform
TINTED_GLASS_SHARE = 0.4    # of the training worlds' glass materials
ABSORBING_GLASS_SHARE = 0.4   # of the training worlds' glass materials
ABSORPTION_DISTANCES = (0.05, 1.0)   # metres over which absorbing glass keeps its colour, log-uniform
SCREEN_SHARE = 0.5          # of the training worlds (about two in three of those have room for it clear of glass)
SCREENS = ("lattice", "perforated", "leaves")
SCREEN_SIZE = 64            # texels a side of a screen's texture (it repeats)
SET_RECTANGLES = ("ground", "floor", "ceiling", "back", "front", "left", "right")   # build_set's flat surfaces
PATTERNS = ("checker", "stripes", "blotches", "mottle")
NORMAL_MAP_SHARE = 0.4      # of the training worlds; each flat set surface of those then has one with odds 1/2
RELIEFS = ("tiles", "planks", "bumps", "ripples")
RELIEF_SIZE = 64            # texels a side of a normal map (it repeats)
RELIEF_PERIODS = (0.05, 1.0)   # metres one repeat of a normal map spans, log-uniform
METAL_ROUGH_SHARE = 0.35    # of the training worlds; each matte or coated surface of those then worn with odds 1/3
WORN_PATTERNS = ("tiles", "stripes", "blotches")
WORN_SIZE = 64              # texels a side of a metal-rough map (it repeats)
WORN_PERIODS = (0.1, 1.5)   # metres one repeat of a metal-rough map spans, log-uniform
# A worn metal's perceptual roughness (GGX alpha 0.06–0.56, as the objects' rough metals): smoother metal walls and
# floors under a sun or a tiny lamp throw glossy caustics over the room that 4096-spp golds leave speckled
WORN_METAL_ROUGHNESS = (0.25, 0.75)
PAINT_EDGE = 0.02           # surfaces are subdivided until their edges are at most this share of the set's size


def family_of(seed: int) -> str:
    """The family a world seed belongs to."""
    if not 0 <= int(seed) < 2 * FAMILY_SIZE:
        raise ValueError(f"a world seed is in [0, 2^32), got {seed}")
    return FAMILIES[int(seed) // FAMILY_SIZE]


def world_seed(family: str, number: int) -> int:
    """The seed of world ``number`` (any integer ≥ 0, taken modulo 2³¹) of ``family``."""
    return FAMILIES.index(family) * FAMILY_SIZE + int(number) % FAMILY_SIZE


def mesh_family(path: Path) -> str:
    """The family a mesh file belongs to: a fifth of the names, by hash, are held out."""
    digest = hashlib.sha256(Path(path).name.encode()).digest()
    return "held_out" if digest[0] % 5 == 0 else "training"


def generate_world(seed: int, mesh_dir: str | Path | None = None, frames: int = 1) -> Scene:
    """The world of ``seed`` (see the module docstring); ``frames`` > 1 adds a short camera and object
    motion for temporal sequences."""
    family = family_of(seed)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x3057]))
    mesh_files = [p for p in (load_mesh_folder(mesh_dir) if mesh_dir else []) if mesh_family(p) == family]
    setup = SETUPS[int(rng.integers(len(SETUPS)))]
    lighting = LIGHTINGS[setup][int(rng.integers(len(LIGHTINGS[setup])))]
    world = _World(rng, setup)
    world.build_set()
    world.add_objects(FAMILY_SHAPES[family], mesh_files)
    world.place_camera()
    world.add_view_features()
    world.light(lighting)
    if family == "training" and lighting != "indirect":
        world.add_lamps_in_view(np.random.default_rng(np.random.SeedSequence([int(seed), 0x1A4B])))
    if family == "training":
        world.paint_surfaces(np.random.default_rng(np.random.SeedSequence([int(seed), 0x9A17])))
    if frames > 1:
        world.animate(frames)
    if family == "training":
        world.add_lens(np.random.default_rng(np.random.SeedSequence([int(seed), 0x1E25])))
        world.add_sky_map(np.random.default_rng(np.random.SeedSequence([int(seed), 0x5C1E])))
        world.coat_materials(np.random.default_rng(np.random.SeedSequence([int(seed), 0xC0A7])),
                             np.random.default_rng(np.random.SeedSequence([int(seed), 0xC0A8])))
        world.tint_glass(np.random.default_rng(np.random.SeedSequence([int(seed), 0x71A7])))
        world.absorb_in_glass(np.random.default_rng(np.random.SeedSequence([int(seed), 0xAB50])))
        world.add_normal_maps(np.random.default_rng(np.random.SeedSequence([int(seed), 0xB0B5])))
        world.add_screen(np.random.default_rng(np.random.SeedSequence([int(seed), 0x5C2E])))
        world.wear_metal(np.random.default_rng(np.random.SeedSequence([int(seed), 0x3E7A])))
    return world.scene(f"world-{seed}/{setup}/{lighting}", frames)


class _World:
    """The state of one world while it is built; every random choice comes from ``rng`` in a fixed order."""

    def __init__(self, rng: np.random.Generator, setup: str):
        self.rng = rng
        self.setup = setup
        self.meshes: list[Mesh] = []
        self.materials: dict[str, Material] = {}
        self.lights: list = []
        self.background = np.zeros(3)
        self.environment: np.ndarray | None = None   # a sky map (add_sky_map), which background then scales
        self.objects: list[tuple[Mesh, np.ndarray, float]] = []   # (mesh, centre, radius) of each object
        self.camera: Camera | None = None
        self.keyframes: dict[int, Camera] = {}
        self.exposure = float(np.exp(rng.uniform(np.log(0.5), np.log(5.0))))    # target irradiance, W/m²
        # Half-extents of the set along x and z (y unused); the floor is y = 0.
        if setup in ("closed_room", "open_room"):
            self.half = np.array([rng.uniform(1.5, 3.0), 0.0, rng.uniform(1.5, 3.0)])
            self.height = float(rng.uniform(2.4, 3.5))
        else:
            self.half = np.array([rng.uniform(3.0, 6.0), 0.0, rng.uniform(3.0, 6.0)])
            self.height = 8.0

    # -- the set ---------------------------------------------------------------------------------
    def build_set(self) -> None:
        rng = self.rng
        if self.setup == "ground":
            self.add("ground", primitive("rectangle"), _diffuse(rng, "any"),
                     _placed([0, 0, 0], UP, (60, 60, 1)))
            return
        if self.setup == "studio":
            self.add("sweep", _sweep(self.half[0] * 1.5, self.half[2], 1.0, self.height),
                     _diffuse(rng, str(rng.choice(["bright", "any", "dark"]))), np.eye(4))
            self.background = np.full(3, rng.uniform(0.0, 0.05))
            return
        wall = _diffuse(rng, str(rng.choice(["bright", "bright", "any", "saturated"])))
        hx, hz, h = self.half[0], self.half[2], self.height
        panels = {"floor": ([0, 0, 0], [0, 1, 0], (hx, hz)), "ceiling": ([0, h, 0], [0, -1, 0], (hx, hz)),
                  "back": ([0, h / 2, -hz], [0, 0, 1], (hx, h / 2)), "front": ([0, h / 2, hz], [0, 0, -1], (hx, h / 2)),
                  "left": ([-hx, h / 2, 0], [1, 0, 0], (hz, h / 2)), "right": ([hx, h / 2, 0], [-1, 0, 0], (hz, h / 2))}
        if self.setup == "open_room":
            del panels[str(rng.choice(["back", "front", "left", "right"]))]
            if rng.uniform() < 0.5:
                del panels["ceiling"]
        floor = _diffuse(rng, "any")
        for name, (centre, normal, (hu, hv)) in panels.items():
            self.add(name, primitive("rectangle"), floor if name == "floor" else wall,
                     _placed(centre, normal, (hu, hv, 1)))

    def add(self, name: str, arrays, material: Material, transform) -> Mesh:
        vertices, faces, normals = arrays
        self.materials[name] = material
        mesh = Mesh(name, vertices, faces, name, normals, np.asarray(transform, np.float32))
        self.meshes.append(mesh)
        return mesh

    # -- objects ---------------------------------------------------------------------------------
    def add_objects(self, shapes: tuple[str, ...], mesh_files: list[Path]) -> None:
        rng = self.rng
        count = int(rng.integers(1, 11))
        spread = min(0.55 * min(self.half[0], self.half[2]), 0.3 + 0.3 * np.sqrt(count))
        for i in range(count):
            if mesh_files and rng.uniform() < 0.4:
                path = mesh_files[int(rng.integers(len(mesh_files)))]
                # A scanned mesh need not be closed, and glass needs an inside.
                label, arrays, closed = path.stem, load_mesh_file(path), False
            else:
                label = str(rng.choice(shapes))
                arrays, closed = procedural_shape(label, rng), label != "compound"
            size = float(rng.uniform(0.3, 1.1)) * (1.0 if count <= 3 else 0.7)
            placed = self._free_spot(size, spread)
            if placed is None:
                continue
            x, z = placed
            turn = rotate([0, 1, 0], rng.uniform(0, 360))
            if rng.uniform() < 0.25:    # knocked over: any orientation
                turn = compose(turn, rotate(rng.normal(size=3), rng.uniform(0, 180)))
            shape = compose(turn, scale(size))
            lowest = float(transform_points(shape, arrays[0])[:, 1].min())
            transform = compose(translate([x, 0.001 - lowest, z]), shape)
            mesh = self.add(f"{label}_{i}", arrays, self._object_material(glass_allowed=closed), transform)
            self.objects.append((mesh, np.array([x, size / 2, z]), size / 2))

    def _free_spot(self, size: float, spread: float) -> tuple[float, float] | None:
        """A floor position within ``spread`` of the centre whose footprint misses the objects so far."""
        for _ in range(40):
            x, z = self.rng.uniform(-spread, spread, 2)
            if all(np.hypot(x - c[0], z - c[2]) > 0.6 * size + r for _, c, r in self.objects):
                return float(x), float(z)
        return None

    def _object_material(self, glass_allowed: bool) -> Material:
        rng = self.rng
        kind = rng.choice(["diffuse", "conductor", "dielectric"], p=[0.45, 0.3, 0.25])
        if kind == "dielectric" and glass_allowed:
            return _glass(rng)
        if kind == "conductor":
            return _metal(rng, rough=bool(rng.uniform() < 0.6))
        return _diffuse(rng, str(rng.choice(["dark", "bright", "saturated", "any"])))

    # -- camera, glass panes and mirrors --------------------------------------------------------
    def cluster(self) -> tuple[np.ndarray, float]:
        middle = np.mean([c for _, c, _ in self.objects], axis=0)
        return middle, float(max(np.linalg.norm(c - middle) + r for _, c, r in self.objects))

    def place_camera(self) -> None:
        rng = self.rng
        target, radius = self.cluster()
        fov = float(rng.uniform(20, 90))
        distance = radius / np.sin(np.radians(fov) / 2) * rng.uniform(0.8, 1.4)
        azimuth = rng.uniform(-0.9, 0.9) if self.setup == "studio" else rng.uniform(0, 2 * np.pi)
        elevation = rng.uniform(np.radians(5), np.radians(45))
        direction = np.array([np.cos(elevation) * np.sin(azimuth), np.sin(elevation),
                              np.cos(elevation) * np.cos(azimuth)])
        self.camera = Camera(self._inside(target + direction * distance), target, [0, 1, 0], fov)

    def _inside(self, origin) -> np.ndarray:
        """``origin`` moved into the set if it is outside: a narrow view then sees less of the objects."""
        origin = np.array(origin, np.float64)
        if self.setup != "ground":
            inside = self.half[[0, 2]] - CAMERA_MARGIN
            origin[[0, 2]] = np.clip(origin[[0, 2]], -inside, inside)
            origin[1] = min(origin[1], self.height - CAMERA_MARGIN)
        origin[1] = max(origin[1], 0.2)
        return origin

    def add_view_features(self) -> None:
        """Sometimes a glass pane between the camera and the objects, sometimes a mirror behind them."""
        rng = self.rng
        origin, target = self.camera.origin.astype(np.float64), self.camera.target.astype(np.float64)
        view = target - origin
        distance = float(np.linalg.norm(view))
        view /= distance
        tan_half = np.tan(np.radians(self.camera.fov) / 2)
        if rng.uniform() < 0.2:
            along = distance * rng.uniform(0.25, 0.5)
            half = tan_half * along * rng.uniform(0.6, 1.3)
            normal = rotate(UP, rng.uniform(-20, 20))[:3, :3] @ -view
            self.add("pane", primitive("cube"), _glass(rng),
                     _placed(origin + view * along, normal, (half, half, half * rng.uniform(0.004, 0.02))))
        if rng.uniform() < 0.2:
            _, radius = self.cluster()
            behind = target + view * (radius + rng.uniform(0.2, 0.6))
            normal = rotate(UP, rng.uniform(-25, 25))[:3, :3] @ -view
            half = radius * rng.uniform(1.0, 2.0)
            self.add("mirror", primitive("rectangle"), _metal(rng, rough=bool(rng.uniform() < 0.3), mirror=True),
                     _placed(behind + [0, half * 0.5, 0], normal, (half, half, 1)))

    # -- lighting --------------------------------------------------------------------------------
    def light(self, lighting: str) -> None:
        rng = self.rng
        target, radius = self.cluster()
        hx, hz, h = self.half[0], self.half[2], self.height
        if lighting in ("sun_and_sky", "dusk"):
            low = lighting == "dusk"
            elevation = np.radians(rng.uniform(3, 12) if low else rng.uniform(15, 80))
            azimuth = rng.uniform(0, 2 * np.pi)
            toward_sun = np.array([np.cos(elevation) * np.cos(azimuth), np.sin(elevation),
                                   np.cos(elevation) * np.sin(azimuth)])
            sun = blackbody_tint(rng.uniform(2500, 4000) if low else rng.uniform(4500, 7500))
            self.lights.append(DirectionalLight((-toward_sun).astype(np.float32),
                                                (sun * self.exposure * (0.2 if low else 1.0)).astype(np.float32)))
            sky = np.array(colorsys.hsv_to_rgb(rng.uniform(0.5, 0.72), rng.uniform(0.1, 0.7), 1.0))
            self.background = sky * self.exposure * rng.uniform(0.03, 0.25)
            if low:
                for _ in range(int(rng.integers(1, 4))):
                    self._point(target + rng.uniform(-1.5, 1.5, 3) * [radius + 1, 0, radius + 1]
                                + [0, rng.uniform(0.5, 2.0), 0])
        elif lighting == "ceiling_panel":
            side = rng.uniform(0.3, 1.5)
            self._panel([rng.uniform(-0.5, 0.5) * hx, h - 0.01, rng.uniform(-0.5, 0.5) * hz], -UP, side, side)
        elif lighting == "tiny_bright":
            side = rng.uniform(0.01, 0.06)
            spot = [rng.uniform(-0.8, 0.8) * hx, h - 0.02, rng.uniform(-0.8, 0.8) * hz]
            self._panel(spot, rotate(rng.normal(size=3), rng.uniform(0, 40))[:3, :3] @ -UP, side, side)
        elif lighting == "point":
            for _ in range(int(rng.integers(1, 3))):
                self._point([rng.uniform(-0.7, 0.7) * hx, rng.uniform(0.6, 0.95) * h, rng.uniform(-0.7, 0.7) * hz])
        elif lighting == "indirect":
            self._bounce_lamps()
        elif lighting == "glowing_object":
            self._glowing_object()
            self._point([rng.uniform(-0.7, 0.7) * hx, 0.9 * h, rng.uniform(-0.7, 0.7) * hz], dim=0.2)
        elif lighting == "softboxes":
            for _ in range(int(rng.integers(1, 4))):
                self._aimed_panel(target, radius, rng.uniform(0.6, 2.0), rng.uniform(1.5, 4.0))
        elif lighting == "spotlight":
            self._aimed_panel(target, radius, rng.uniform(0.03, 0.12), rng.uniform(2.0, 5.0))
            self._point(self.camera.origin + [0, 0.5, 0], dim=0.15)
        if lighting not in ("glowing_object", "indirect") and len(self.objects) > 1 and rng.uniform() < 0.15:
            self._glowing_object()

    def _panel(self, centre, normal, width: float, depth: float) -> None:
        """A rectangular area light facing ``normal``, bright enough to give the target irradiance at the
        objects (radiance × area / distance² ≈ irradiance)."""
        target, _ = self.cluster()
        distance2 = max(float(np.sum((np.asarray(centre) - target) ** 2)), 0.25)
        radiance = self.exposure * distance2 / (width * depth)
        tint = blackbody_tint(self.rng.uniform(2700, 9000))
        self.add(f"light_{len(self.meshes)}", primitive("rectangle"), _emitter(tint * radiance),
                 _placed(centre, normal, (width / 2, depth / 2, 1)))

    def _aimed_panel(self, target, radius: float, side: float, distance: float) -> None:
        """A light aimed at ``target`` from the front half of the set, outside the camera's view (a
        frame-filling light is no use as training data)."""
        rng = self.rng
        origin = self.camera.origin.astype(np.float64)
        view = target - origin
        view /= np.linalg.norm(view)
        for _ in range(20):
            azimuth = rng.uniform(-1.6, 1.6)
            elevation = rng.uniform(np.radians(20), np.radians(70))
            direction = np.array([np.cos(elevation) * np.sin(azimuth), np.sin(elevation),
                                  np.cos(elevation) * np.cos(azimuth)])
            centre = target + direction * (radius + distance)
            seen = centre - origin
            if np.degrees(np.arccos(np.clip(seen @ view / np.linalg.norm(seen), -1, 1))) > 0.75 * self.camera.fov:
                break
        self._panel(centre, -direction, side, side)

    def add_lamps_in_view(self, rng: np.random.Generator) -> None:
        """With probability LAMPS_IN_VIEW_SHARE, 1–12 small lamps (cubes and spheres, some with a black
        reflectance, as area lights are often given) where the camera sees them: each in a random
        direction inside the view at a random depth, kept inside the set, 0.3–4 % of the frame's width
        across, with a radiance of 3–300 times what the objects' target irradiance over π would give."""
        if rng.uniform() >= LAMPS_IN_VIEW_SHARE:
            return
        origin, target = self.camera.origin.astype(np.float64), self.camera.target.astype(np.float64)
        right, up, forward = (axis.astype(np.float64) for axis in self.camera.basis())
        tan_half = np.tan(np.radians(self.camera.fov) / 2)   # both axes: world views are square
        distance = float(np.linalg.norm(target - origin))
        tint = blackbody_tint(rng.uniform(2200, 6500))
        for i in range(int(rng.integers(1, 13))):
            x, y = rng.uniform(-0.9, 0.9, 2)
            ray = forward + tan_half * (x * right + y * up)
            depth = distance * float(np.exp(rng.uniform(np.log(0.5), np.log(3.0))))
            centre = self._inside(origin + ray * depth)
            if self.setup != "ground":
                centre[1] = min(centre[1], self.height - 0.05)
            seen_at = float((centre - origin) @ forward)   # moved into the set, it may have left the view
            aside = max(abs((centre - origin) @ right), abs((centre - origin) @ up))
            if seen_at <= 0.1 or aside > 0.95 * seen_at * tan_half:
                continue
            size = 2 * seen_at * tan_half * rng.uniform(0.003, 0.04)
            radiance = self.exposure / np.pi * float(np.exp(rng.uniform(np.log(3), np.log(300))))
            material = Material("diffuse", reflectance=0.0 if rng.uniform() < 0.3 else 0.8,
                                emission=tint * radiance)
            shape = str(rng.choice(["cube", "sphere"]))
            self.add(f"lamp_in_view_{i}", primitive(shape), material, compose(translate(centre), scale(size / 2)))

    def paint_surfaces(self, rng: np.random.Generator) -> None:
        """With probability PAINTED_SHARE, each set surface and object that is neither glass nor an emitter
        is painted with probability one half: subdivided until its edges are at most PAINT_EDGE of the set's
        size, then given a colour per vertex from one of PATTERNS in its own coordinates (``painted_colors``),
        which tints its material."""
        if rng.uniform() >= PAINTED_SHARE:
            return
        extent = float(max(self.half[0], self.half[2], self.height / 2))
        for mesh in self.meshes:
            material = self.materials[mesh.material]
            if material.kind == "dielectric" or material.is_emissive or rng.uniform() >= 0.5:
                continue
            world_scale = float(np.cbrt(abs(np.linalg.det(mesh.transform[:3, :3].astype(np.float64)))))
            mesh.vertices, mesh.faces, mesh.normals = _subdivided(mesh.vertices, mesh.faces, mesh.normals,
                                                                  PAINT_EDGE * extent / max(world_scale, 1e-6))
            mesh.colors = painted_colors(rng, mesh.vertices * world_scale)

    def add_lens(self, rng: np.random.Generator) -> None:
        """With probability LENS_SHARE, the camera and its keyframes look through a thin lens: an aperture
        radius of LENS_APERTURES of the distance to the target, focused at 0.7–1.3 times that distance."""
        if rng.uniform() >= LENS_SHARE:
            return
        aperture = float(np.exp(rng.uniform(*np.log(LENS_APERTURES))))
        focus = float(rng.uniform(0.7, 1.3))
        for camera in [self.camera, *self.keyframes.values()]:
            distance = float(np.linalg.norm(camera.target.astype(np.float64) - camera.origin))
            camera.aperture_radius, camera.focus_distance = aperture * distance, focus * distance

    def add_sky_map(self, rng: np.random.Generator) -> None:
        """With probability SKY_MAP_SHARE, a world with a sky sees it as a procedural environment map around
        the sun (its directional light, which stays the sun), scaled by the sky colour it had."""
        if not np.any(np.asarray(self.background) > 0) or rng.uniform() >= SKY_MAP_SHARE:
            return
        sun = next((light for light in self.lights if isinstance(light, DirectionalLight)), None)
        self.environment = procedural_sky(rng, None if sun is None else -np.asarray(sun.direction, np.float64))

    def coat_materials(self, rng: np.random.Generator, roughness_rng: np.random.Generator) -> None:
        """Each matte material that does not emit becomes, with probability PLASTIC_SHARE, the same colour
        under a clear coat (plastic) of index 1.3–1.7; not one a painted mesh wears (Mitsuba's plastic, the
        golds' renderer, cannot read vertex colours). With probability ROUGH_COAT_SHARE, drawn from
        ``roughness_rng`` (so that the coats and their indices are version 7's), a coat is rough."""
        painted = {mesh.material for mesh in self.meshes if mesh.colors is not None}
        for name in sorted(self.materials):
            material = self.materials[name]
            if material.kind != "diffuse" or material.is_emissive:
                continue
            coat, ior = rng.uniform() < PLASTIC_SHARE, float(rng.uniform(1.3, 1.7))
            rough, alpha = roughness_rng.uniform() < ROUGH_COAT_SHARE, float(np.exp(roughness_rng.uniform(
                *np.log(ROUGH_COAT_ALPHAS))))
            if coat and name not in painted:
                self.materials[name] = Material("plastic", reflectance=material.reflectance, ior=ior,
                                                roughness=alpha if rough else 0.0)

    def tint_glass(self, rng: np.random.Generator) -> None:
        """Each glass material takes, with probability TINTED_GLASS_SHARE, a transmittance: a colour whose
        brightest channel is 0.75–1 and whose others are 0.25–1 of it (bottle green, amber, blue-grey, ...)."""
        for name in sorted(self.materials):
            material = self.materials[name]
            if material.kind != "dielectric":
                continue
            tinted, colour, peak = rng.uniform() < TINTED_GLASS_SHARE, rng.uniform(0.25, 1.0, 3), rng.uniform(0.75, 1)
            if tinted:
                material.transmittance = (colour / colour.max() * peak).astype(np.float32)

    def absorb_in_glass(self, rng: np.random.Generator) -> None:
        """Each glass material (glass is given to closed shapes and slabs only, which have an inside) absorbs,
        with probability ABSORBING_GLASS_SHARE, at a rate that leaves a colour whose channels are 0.05–0.9 after a
        distance drawn from ABSORPTION_DISTANCES: thin panes barely tinted, bulky objects deep in colour."""
        for name in sorted(self.materials):
            material = self.materials[name]
            if material.kind != "dielectric":
                continue
            absorbing, colour = rng.uniform() < ABSORBING_GLASS_SHARE, rng.uniform(0.05, 0.9, 3)
            distance = float(np.exp(rng.uniform(*np.log(ABSORPTION_DISTANCES))))
            if absorbing:
                material.absorption = (-np.log(colour) / distance).astype(np.float32)

    def add_normal_maps(self, rng: np.random.Generator) -> None:
        """With probability NORMAL_MAP_SHARE, each flat set surface (a rectangle: floor, ceiling, walls, the
        ground) that is not an emitter gets with odds one half a normal map (``relief_normal_map``) repeating
        every RELIEF_PERIODS metres, at coordinates from its own plane (painted ones too: their subdivided
        vertices stay in it)."""
        if rng.uniform() >= NORMAL_MAP_SHARE:
            return
        for mesh in self.meshes:
            if mesh.name not in SET_RECTANGLES or self.materials[mesh.material].is_emissive:
                continue
            taken, period = rng.uniform() < 0.5, float(np.exp(rng.uniform(*np.log(RELIEF_PERIODS))))
            image = relief_normal_map(rng)
            if not taken:
                continue
            half_sizes = np.linalg.norm(mesh.transform[:3, :2].astype(np.float64), axis=0)
            mesh.uvs = ((mesh.vertices[:, :2] + 1.0) * half_sizes / period).astype(np.float32)
            mesh.normal_map = image

    def wear_metal(self, rng: np.random.Generator) -> None:
        """With probability METAL_ROUGH_SHARE, each matte or coated surface (set surfaces, objects, a screen) that
        neither emits nor is painted (Mitsuba's plastic, the golds' renderer, cannot read vertex colours) becomes
        with odds one third worn metal: a plastic of its colour (its own coat, or one of index 1.5) under a metal-rough
        map (``worn_metal_map``) repeating every WORN_PERIODS metres, at coordinates (x + z, y) of its points scaled
        to the world (a surface with coordinates already, a normal map's or a screen's, keeps them)."""
        if rng.uniform() >= METAL_ROUGH_SHARE:
            return
        for mesh in self.meshes:
            material = self.materials[mesh.material]
            if material.kind not in ("diffuse", "plastic") or material.is_emissive or mesh.colors is not None:
                continue
            taken, period = rng.uniform() < 1 / 3, float(np.exp(rng.uniform(*np.log(WORN_PERIODS))))
            image = worn_metal_map(rng)
            if not taken:
                continue
            if mesh.uvs is None:
                points = mesh.vertices * np.linalg.norm(mesh.transform[:3, :3].astype(np.float64), axis=0)
                mesh.uvs = (np.stack([points[:, 0] + points[:, 2], points[:, 1]], -1) / period).astype(np.float32)
            mesh.metal_rough_map = image
            worn = f"{mesh.name}/worn"
            self.materials[worn] = Material("plastic", reflectance=material.reflectance,
                                            ior=material.ior if material.kind == "plastic" else 1.5)
            mesh.material = worn

    def add_screen(self, rng: np.random.Generator) -> None:
        """With probability SCREEN_SHARE, a screen between the camera and its target: 25–60 % of the way there,
        30–80 % of the view's half-width across, off the view's centre by up to half of it and turned by up to
        30° from facing the camera, its texture (``screen_texture``, repeated 2–6 times across) cutting it out; none
        where its bounds would meet a glass object's or a lamp's (a diffuse surface inside glass is a different
        scene to each renderer: one such world came out 15–25 % apart from its Mitsuba gold)."""
        if rng.uniform() >= SCREEN_SHARE:
            return
        origin, target = self.camera.origin.astype(np.float64), self.camera.target.astype(np.float64)
        right, up, forward = (axis.astype(np.float64) for axis in self.camera.basis())
        along = float(np.linalg.norm(target - origin)) * rng.uniform(0.25, 0.6)
        reach = along * np.tan(np.radians(self.camera.fov) / 2)      # the view's half-width there
        half_size, (x, y) = reach * rng.uniform(0.3, 0.8), rng.uniform(-0.5, 0.5, 2) * reach
        facing = np.eye(4)
        facing[:3, :3] = np.stack([right, up, -forward], 1)           # +z, the rectangle's normal, to the camera
        placement = compose(translate(origin + along * forward + x * right + y * up), facing,
                            rotate([0.0, 1.0, 0.0], rng.uniform(-30.0, 30.0)), scale(half_size))
        repeat = int(rng.integers(2, 7))
        image = screen_texture(rng)
        colour = np.array(colorsys.hsv_to_rgb(rng.uniform(), rng.uniform(0.1, 0.8), rng.uniform(0.3, 0.9)))
        rectangle = primitive("rectangle")
        corners = transform_points(placement, rectangle[0])
        low, high = corners.min(0), corners.max(0)
        for other in self.meshes:   # a screen through glass or a lamp would leave the renderers' media undefined
            material = self.materials[other.material]
            if material.kind == "dielectric" or material.is_emissive:
                points = transform_points(other.transform, other.vertices)
                if np.all(points.min(0) <= high) and np.all(low <= points.max(0)):
                    return
        mesh = self.add("screen", rectangle, Material("diffuse", reflectance=colour), placement)
        mesh.uvs = ((mesh.vertices[:, :2] + 1.0) / 2.0 * repeat).astype(np.float32)
        mesh.texture = image

    def _point(self, position, dim: float = 1.0) -> None:
        target, _ = self.cluster()
        distance2 = max(float(np.sum((np.asarray(position, np.float64) - target) ** 2)), 0.25)
        intensity = blackbody_tint(self.rng.uniform(2700, 9000)) * self.exposure * dim * distance2
        self.lights.append(PointLight(np.asarray(position, np.float32), intensity.astype(np.float32)))

    def _bounce_lamps(self) -> None:
        """Lamps that face the ceiling or a wall from close by: the camera never sees an emitting side, so
        all light reaches the view after at least one bounce (closer to the walls than CAMERA_MARGIN,
        the lamps' backs face the camera). Power is set so the room's bounce light gives the target
        irradiance."""
        rng = self.rng
        hx, hz, h = self.half[0], self.half[2], self.height
        room_area = 2 * (4 * hx * hz) + 2 * h * (2 * hx + 2 * hz)
        for _ in range(int(rng.integers(1, 3))):
            side = rng.uniform(0.2, 0.8)
            if rng.uniform() < 0.5:
                centre, normal = [rng.uniform(-0.6, 0.6) * hx, h - 0.1, rng.uniform(-0.6, 0.6) * hz], UP
            else:
                wall = rng.choice([-1.0, 1.0])
                centre, normal = [wall * (hx - 0.1), rng.uniform(0.4, 0.8) * h, rng.uniform(-0.6, 0.6) * hz], [wall, 0, 0]
            radiance = self.exposure * room_area / (np.pi * side * side)
            tint = blackbody_tint(rng.uniform(2700, 6500))
            self.add(f"lamp_{len(self.meshes)}", primitive("rectangle"), _emitter(tint * radiance),
                     _placed(centre, normal, (side / 2, side / 2, 1)))

    def _glowing_object(self) -> None:
        """One of the objects glows."""
        rng = self.rng
        mesh = self.objects[int(rng.integers(len(self.objects)))][0]
        colour = np.array(colorsys.hsv_to_rgb(rng.uniform(), rng.uniform(0, 1), 1.0))
        base = self.materials[mesh.material]
        self.materials[mesh.material] = Material("diffuse", base.reflectance,
                                                 emission=colour * self.exposure * rng.uniform(0.2, 3))

    # -- motion and the result ---------------------------------------------------------------------
    def animate(self, frames: int) -> None:
        """A slow orbit of the camera around its target and one object drifting across the floor."""
        rng = self.rng
        turn = rng.uniform(-2.0, 2.0)           # degrees per frame
        offset = self.camera.origin - self.camera.target
        for f in range(frames):
            origin = self._inside(self.camera.target + rotate(UP, turn * f)[:3, :3] @ offset)
            self.keyframes[f] = Camera(origin, self.camera.target, self.camera.up, self.camera.fov)
        mover = self.objects[int(rng.integers(len(self.objects)))][0]
        dx, dz = rng.uniform(-0.03, 0.03, 2)
        mover.keyframes = {f: compose(translate([dx * f, 0, dz * f]), mover.transform) for f in range(frames)}

    def scene(self, name: str, frames: int) -> Scene:
        return Scene(self.keyframes.get(0, self.camera), self.meshes, self.materials, self.lights,
                     np.asarray(self.background, np.float32), self.keyframes, max(frames, 1), name, self.environment)


def _subdivided(vertices, faces, normals, longest: float, most: int = 60_000):
    """A mesh split into four triangles a triangle until no edge is longer than ``longest`` (or the next
    split would pass ``most`` triangles), vertex normals interpolated (renormalised)."""
    import trimesh

    vertices, faces = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    normals = None if normals is None else np.asarray(normals, np.float64)
    while 4 * len(faces) <= most:
        edges = vertices[faces[:, [1, 2, 0]]] - vertices[faces]
        if np.sqrt((edges ** 2).sum(-1)).max() <= longest:
            break
        attributes = {} if normals is None else {"normals": normals}
        vertices, faces, attributes = trimesh.remesh.subdivide(vertices, faces, vertex_attributes=attributes)
        if normals is not None:
            normals = attributes["normals"] / np.linalg.norm(attributes["normals"], axis=1, keepdims=True)
    return (vertices.astype(np.float32), faces.astype(np.uint32),
            None if normals is None else normals.astype(np.float32))


def painted_colors(rng: np.random.Generator, points: np.ndarray) -> np.ndarray:
    """(V, 3) vertex colours in [0, 1] at ``points``: a pattern of PATTERNS in a random orientation whose
    cells are 2–25 % of the points' extent, mixing white (the material as it is) or a random colour with
    another, dark to bright."""
    kind = PATTERNS[int(rng.integers(len(PATTERNS)))]
    axes = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    extent = max(float(np.ptp(points, axis=0).max()), 1e-6)
    p = np.asarray(points, np.float64) @ axes / (extent * float(np.exp(rng.uniform(np.log(0.02), np.log(0.25)))))
    if kind == "checker":
        t = (np.floor(p[:, 0]) + np.floor(p[:, 1]) + np.floor(p[:, 2])) % 2
    elif kind == "stripes":
        t = (np.floor(p[:, 0] + 0.3 * np.sin(p[:, 1])) % 2)
    else:
        octaves = [(2.0 ** k, tuple(rng.uniform(0, 6.3, 3))) for k in range(4 if kind == "blotches" else 2)]
        t = 0.5 + (0.8 if kind == "blotches" else 2.5) * sine_pattern(p, octaves)
    colours = [np.array(colorsys.hsv_to_rgb(rng.uniform(), rng.uniform(0, 0.9), rng.uniform(0.05, 1.0)))
               for _ in range(2)]
    return mix_colors(t, np.ones(3) if rng.uniform() < 0.5 else colours[1], colours[0])


def _to_edge(t: np.ndarray) -> np.ndarray:
    """The distance from t to the nearest whole number (0 on a repeating pattern's cell edges, ½ mid-cell)."""
    return np.minimum(t % 1.0, 1.0 - t % 1.0)


def relief_normal_map(rng: np.random.Generator) -> np.ndarray:
    """A RELIEF_SIZE² tangent-space normal map (uint8 codes) of one of RELIEFS, seamless when repeated: the
    gradient of a periodic height field, scaled so that its steepest twentieth tilts by 10–45°."""
    kind = RELIEFS[int(rng.integers(len(RELIEFS)))]
    n = RELIEF_SIZE
    y, x = np.mgrid[0:n, 0:n] / n
    if kind == "tiles":          # square tiles, bevelled toward the grout
        count = int(rng.integers(1, 5))
        height = np.clip(np.minimum(_to_edge(x * count), _to_edge(y * count)) / 0.06, 0, 1)
    elif kind == "planks":       # boards side by side, each column's joints at its own height
        count = int(rng.integers(2, 7))
        shift = rng.uniform(0, 1, count)[np.floor(x * count).astype(int)]
        height = np.clip(np.minimum(_to_edge(x * count) / 0.08, _to_edge(y + shift) / 0.04), 0, 1)
    else:
        waves = int(rng.integers(2, 6)) if kind == "bumps" else 1
        height = np.zeros((n, n))
        for _ in range(waves):
            fx, fy = rng.integers(-4, 5, 2) if kind == "bumps" else rng.integers(1, 9, 2)
            height += np.sin(2 * np.pi * (fx * x + fy * y + rng.uniform())) / waves
    # x along u (columns), y along v (up the image: rows run down).
    dh_du = (np.roll(height, -1, axis=1) - np.roll(height, 1, axis=1)) / 2
    dh_dv = (np.roll(height, 1, axis=0) - np.roll(height, -1, axis=0)) / 2
    steepest = max(float(np.percentile(np.hypot(dh_du, dh_dv), 95)), 1e-9)
    slope = np.tan(np.radians(rng.uniform(10.0, 45.0))) / steepest     # the 95th percentile's tilt
    normal = np.stack([-slope * dh_du, -slope * dh_dv, np.ones((n, n))], -1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    return np.round((normal + 1.0) / 2.0 * 255.0).astype(np.uint8)


def worn_metal_map(rng: np.random.Generator) -> np.ndarray:
    """A WORN_SIZE² metal-rough map (uint8 codes: roughness in green, metalness in blue), seamless when repeated,
    of one of WORN_PATTERNS: square metal tiles among matte ones (a thin matte joint around each), metal stripes,
    or matte blotches (patina, paint) on metal covering 20–60 % of it. Metal texels are fully metal, of a roughness
    in WORN_METAL_ROUGHNESS that varies by tile or stripe and a little across; the matte ones share one roughness,
    0.3–1 (as Mitsuba's roughplastic has one, so that the golds can be Mitsuba's)."""
    kind = WORN_PATTERNS[int(rng.integers(len(WORN_PATTERNS)))]
    n = WORN_SIZE
    y, x = (np.mgrid[0:n, 0:n] + 0.5) / n
    count = int(rng.integers(2, 6))
    if kind == "tiles":
        row, column = np.floor(y * count).astype(int), np.floor(x * count).astype(int)
        metal = ((row + column) % 2 == 0) & (np.minimum(_to_edge(x * count), _to_edge(y * count)) > 0.04)
        rough = rng.uniform(*WORN_METAL_ROUGHNESS, (count, count))[row, column]
    elif kind == "stripes":
        along = x if rng.uniform() < 0.5 else y
        metal = _to_edge(along * count) > rng.uniform(0.1, 0.35)
        rough = rng.uniform(*WORN_METAL_ROUGHNESS, count)[np.floor(along * count).astype(int)]
    else:
        field = np.zeros((n, n))
        for _ in range(int(rng.integers(3, 7))):
            fx, fy = rng.integers(-4, 5, 2)
            field += np.sin(2 * np.pi * (fx * x + fy * y + rng.uniform()))
        metal = field > np.quantile(field, rng.uniform(0.2, 0.6))
        rough = np.full((n, n), rng.uniform(*WORN_METAL_ROUGHNESS))
    rough = np.clip(rough + rng.normal(0.0, 0.03, (n, n)), 0.02, 1.0)
    codes = np.zeros((n, n, 3), np.uint8)
    codes[..., 1] = np.round(np.where(metal, rough, rng.uniform(0.3, 1.0)) * 255)
    codes[..., 2] = np.where(metal, 255, 0)
    return codes


def screen_texture(rng: np.random.Generator) -> np.ndarray:
    """A SCREEN_SIZE² RGBA texture (uint8 codes), seamless when repeated, whose alpha cuts a screen out (kept at ½
    and above, a texel-wide soft edge): one of SCREENS — a lattice of bars (square or diagonal), a sheet
    perforated by round holes, or overlapping leaf shapes. Its colour varies a little around white (the
    material's reflectance tints it)."""
    kind = SCREENS[int(rng.integers(len(SCREENS)))]
    n = SCREEN_SIZE
    y, x = (np.mgrid[0:n, 0:n] + 0.5) / n
    count = int(rng.integers(2, 6))
    if kind == "lattice":            # distance inside a bar, positive where kept
        u, v = (x + y, x - y) if rng.uniform() < 0.5 else (x, y)
        width = rng.uniform(0.08, 0.3) / 2
        inside = width - np.minimum(_to_edge(u * count), _to_edge(v * count))
    elif kind == "perforated":
        radius = rng.uniform(0.15, 0.35)
        inside = np.hypot(_to_edge(x * count), _to_edge(y * count)) - radius
    else:                            # leaves: the union of rotated, pointed ellipses, wrapped around the tile
        inside = np.full((n, n), -1.0)
        for _ in range(int(rng.integers(25, 60))):
            (cx, cy), length, angle = rng.uniform(0, 1, 2), rng.uniform(0.12, 0.3), rng.uniform(0, np.pi)
            dx, dy = (x - cx + 0.5) % 1.0 - 0.5, (y - cy + 0.5) % 1.0 - 0.5
            a = dx * np.cos(angle) + dy * np.sin(angle)
            b = -dx * np.sin(angle) + dy * np.cos(angle)
            half = length * rng.uniform(0.2, 0.3) * np.sqrt(np.clip(1 - (2 * a / length) ** 2, 0, 1))
            inside = np.maximum(inside, np.where(np.abs(a) < length / 2, half - np.abs(b), -1.0))
    alpha = np.clip(0.5 + inside * n / count * (1 if kind != "leaves" else count), 0.0, 1.0)
    shade = 1.0 - 0.15 * rng.uniform(0, 1, (n, n, 1)) * np.ones(3)
    rgba = np.concatenate([shade, alpha[..., None]], -1)
    return np.round(rgba * 255).astype(np.uint8)


def procedural_sky(rng: np.random.Generator, toward_sun: np.ndarray | None) -> np.ndarray:
    """A (SKY_MAP_SIZE, 3) float32 latitude-longitude sky, about 1 on the mean above the horizon (a scale for
    the world's sky colour): from the zenith to a horizon 1.5–4 times as bright and warmer, a glow around
    ``toward_sun`` (unit, toward the sun; none without one), ground of 0.05–0.4 below, softened across the
    horizon."""
    height, width = SKY_MAP_SIZE
    theta = np.pi * np.arange(height) / (height - 1)
    phi = 2 * np.pi * (np.arange(width) + 0.5) / width
    t, p = np.meshgrid(theta, phi, indexing="ij")
    directions = np.stack([np.sin(p) * np.sin(t), np.cos(t), -np.cos(p) * np.sin(t)], -1)
    up = np.clip(directions[..., 1], 0.0, 1.0)
    horizon = np.array([1.0, rng.uniform(0.85, 1.0), rng.uniform(0.6, 0.9)]) * rng.uniform(1.5, 4.0)
    zenith = np.full(3, rng.uniform(0.4, 0.9))
    blend = (1 - up[..., None]) ** rng.uniform(2.0, 6.0)
    sky = zenith + (horizon - zenith) * blend
    if toward_sun is not None:
        cosine = np.clip(directions @ toward_sun, -1.0, 1.0)
        sky = sky + rng.uniform(0.5, 4.0) * np.exp((cosine - 1) * rng.uniform(4.0, 20.0))[..., None]
    ground = np.array(colorsys.hsv_to_rgb(rng.uniform(0.05, 0.15), rng.uniform(0.1, 0.5), rng.uniform(0.05, 0.4)))
    over = np.clip(directions[..., 1] * 20 + 0.5, 0.0, 1.0)[..., None]        # soft across the horizon
    return (over * sky + (1 - over) * ground).astype(np.float32)


# -- materials ----------------------------------------------------------------------------------------
def _emitter(radiance) -> Material:
    return Material("diffuse", reflectance=0.8, emission=radiance)


# (saturation, value) ranges of diffuse tones in HSV: value is the albedo of the brightest channel.
DIFFUSE_TONES = {"dark": ((0, 0.6), (0.02, 0.08)), "bright": ((0, 0.25), (0.7, 0.9)),
                 "saturated": ((0.8, 1.0), (0.4, 0.9)), "any": ((0, 0.8), (0.05, 0.85))}


def _diffuse(rng: np.random.Generator, tone: str) -> Material:
    """Lambertian of a ``DIFFUSE_TONES`` tone and a random hue."""
    saturation, value = (rng.uniform(*bounds) for bounds in DIFFUSE_TONES[tone])
    return Material("diffuse", reflectance=colorsys.hsv_to_rgb(rng.uniform(), saturation, value))


def _metal(rng: np.random.Generator, rough: bool, mirror: bool = False) -> Material:
    name = str(rng.choice(["Ag", "Al"] if mirror else sorted(METALS)))
    eta, k = METALS[name]
    roughness = float(rng.uniform(0.02, 0.15) if mirror else rng.uniform(0.05, 0.6)) if rough else 0.0
    return Material("conductor", reflectance=1.0, roughness=roughness, eta=eta, k=k)


def _glass(rng: np.random.Generator) -> Material:
    roughness = float(rng.uniform(0.03, 0.4)) if rng.uniform() < 0.4 else 0.0
    return Material("dielectric", roughness=roughness, ior=float(rng.uniform(1.33, 1.9)))


# -- geometry -------------------------------------------------------------------------------------------
def _placed(centre, normal, half_sizes) -> np.ndarray:
    """The transform that puts a primitive's local +z along ``normal`` at ``centre``, its local x and y
    axes scaled by ``half_sizes[:2]`` and z by ``half_sizes[2]`` (right-handed, so the winding and the
    front side follow the normal)."""
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    helper = UP if abs(n[1]) < 0.9 else np.array([0.0, 0.0, 1.0])
    u = np.cross(helper, n)
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    matrix = np.eye(4)
    matrix[:3, 0], matrix[:3, 1], matrix[:3, 2] = u * half_sizes[0], v * half_sizes[1], n * half_sizes[2]
    matrix[:3, 3] = centre
    return matrix.astype(np.float32)


def _sweep(half_width: float, depth: float, bend: float, height: float):
    """A studio backdrop: a floor from z = depth to the back, a quarter-circle bend of radius ``bend``,
    and a wall up to ``height`` at z = -depth; smooth normals point into the set."""
    arc = np.linspace(0, np.pi / 2, 12)
    profile = np.concatenate([[[0.0, depth]], np.stack([bend - bend * np.cos(arc), -depth + bend - bend * np.sin(arc)], 1),
                              [[height, -depth]]])           # (y, z)
    inward = np.concatenate([[[1.0, 0.0]], np.stack([np.cos(arc), np.sin(arc)], 1), [[0.0, 1.0]]])
    n = len(profile)
    vertices = np.array([[x, y, z] for y, z in profile for x in (-half_width, half_width)], np.float32)
    normals = np.array([[0.0, ny, nz] for ny, nz in inward for _ in range(2)], np.float32)
    faces = np.array([f for i in range(n - 1) for f in ((2 * i, 2 * i + 1, 2 * i + 3), (2 * i, 2 * i + 3, 2 * i + 2))],
                     np.uint32)
    return vertices, faces, normals


def procedural_shape(kind: str, rng: np.random.Generator):
    """(vertices, faces, normals) of a random instance of shape ``kind``, unit-sized and centred. Every
    kind may be stretched; any but the compounds may also be noise-displaced."""
    import trimesh
    import trimesh.graph

    builders = {"vase": _vase, "bowl": _bowl, "star_prism": _star_prism, "gear_prism": _gear_prism,
                "ring": _ring, "blob": _blob, "compound": _compound}
    if kind in builders:
        mesh = builders[kind](rng)
    else:
        vertices, faces, _ = make_shape(kind)
        mesh = trimesh.Trimesh(vertices, faces)
    mesh.apply_transform(scale(rng.uniform(0.6, 1.4, 3)))
    if kind == "blob" or (kind != "compound" and rng.uniform() < 0.3):
        mesh = _displaced(mesh, rng, 0.12 if kind == "blob" else 0.04)
    # Vertices split where faces meet at more than 30°: smooth normals, sharp creases (no facet search,
    # which costs a third of a world's time and changes nothing for these shapes).
    return normalized(trimesh.graph.smooth_shade(mesh, angle=np.radians(30), facet_minarea=None))


def _revolved(profile) -> object:
    """A solid of revolution about the y axis from an (r, y) profile that starts and ends on the axis."""
    import trimesh.creation

    mesh = trimesh.creation.revolve(np.asarray(profile, np.float64), sections=48)
    mesh.apply_transform(rotate([1, 0, 0], -90))         # trimesh revolves about z; our up is y
    return mesh


def _vase(rng: np.random.Generator):
    heights = np.linspace(0, 1, 12)
    waves = rng.uniform(0.05, 0.15, 2)
    radii = 0.3 + waves[0] * np.sin(np.pi * heights * rng.uniform(1, 3)) + waves[1] * np.cos(5 * heights)
    return _revolved([[0, 0], *np.stack([np.maximum(radii, 0.08), heights], 1), [0, 1]])


def _bowl(rng: np.random.Generator):
    wall, depth = rng.uniform(0.03, 0.08), rng.uniform(0.3, 0.8)
    outer = np.linspace(0, np.pi / 2, 10)
    outside = np.stack([0.5 * np.sin(outer), depth * (1 - np.cos(outer))], 1)
    inside = np.stack([(0.5 - wall) * np.sin(outer[::-1]), wall + (depth - wall) * (1 - np.cos(outer[::-1]))], 1)
    return _revolved([[0, 0], *outside[1:], *inside[:-1], [0, wall]])


def _prism(outline: np.ndarray, height: float):
    """An outline star-shaped about the origin (counter-clockwise), extruded along y."""
    import trimesh.creation

    vertices = np.concatenate([[[0.0, 0.0]], outline])
    n = len(outline)
    faces = np.array([[0, i + 1, (i + 1) % n + 1] for i in range(n)])
    mesh = trimesh.creation.extrude_triangulation(vertices, faces, height)
    mesh.apply_transform(rotate([1, 0, 0], -90))
    return mesh


def _star_prism(rng: np.random.Generator):
    points = int(rng.integers(4, 9))
    angles = np.linspace(0, 2 * np.pi, 2 * points, endpoint=False)
    radii = np.where(np.arange(2 * points) % 2 == 0, 0.5, rng.uniform(0.2, 0.4))
    return _prism(np.stack([radii * np.cos(angles), radii * np.sin(angles)], 1), rng.uniform(0.15, 0.8))


def _gear_prism(rng: np.random.Generator):
    teeth = int(rng.integers(6, 16))
    angles = np.linspace(0, 2 * np.pi, 4 * teeth, endpoint=False)
    radii = np.where((np.arange(4 * teeth) // 2) % 2 == 0, 0.5, rng.uniform(0.35, 0.45))
    return _prism(np.stack([radii * np.cos(angles), radii * np.sin(angles)], 1), rng.uniform(0.1, 0.5))


def _ring(rng: np.random.Generator):
    import trimesh.creation

    return trimesh.creation.annulus(r_min=rng.uniform(0.15, 0.4), r_max=0.5, height=rng.uniform(0.1, 0.6), sections=48)


def _blob(rng: np.random.Generator):
    import trimesh.creation

    return trimesh.creation.icosphere(subdivisions=3, radius=0.5)


def _compound(rng: np.random.Generator):
    """Two or three primitives overlapping (see the module docstring on booleans)."""
    import trimesh
    import trimesh.util

    parts = []
    for _ in range(int(rng.integers(2, 4))):
        vertices, faces, _ = make_shape(str(rng.choice(TRAINING_SHAPES)))
        part = trimesh.Trimesh(vertices, faces)
        part.apply_transform(compose(translate(rng.uniform(-0.35, 0.35, 3)), rotate(rng.normal(size=3), rng.uniform(0, 180)),
                                     scale(rng.uniform(0.4, 0.8))))
        parts.append(part)
    return trimesh.util.concatenate(parts)


def _displaced(mesh, rng: np.random.Generator, amount: float):
    """``mesh`` finely subdivided and pushed in or out from its centre by a smooth random field (a sum of
    plane waves). The offset depends on the position only, so seams stay closed."""
    import trimesh
    import trimesh.remesh

    vertices, faces = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, max_edge=0.06 * mesh.scale)
    waves = rng.normal(0, rng.uniform(3, 9), (6, 3)) / mesh.scale
    phases = rng.uniform(0, 2 * np.pi, 6)
    field = np.sin(vertices @ waves.T + phases).sum(1) / np.sqrt(6)
    centre = mesh.bounds.mean(0)
    outward = vertices - centre
    outward /= np.maximum(np.linalg.norm(outward, axis=1, keepdims=True), 1e-9)
    return trimesh.Trimesh(vertices + amount * mesh.scale * field[:, None] * outward, faces)
