"""A thin dielectric (a pane of no thickness, Mitsuba's thindielectric): light through it goes straight on, dimmed by
what its two faces reflect together, 2R / (1 + R), and tinted by its transmittance; from either side alike."""

from pathlib import Path

import numpy as np
import pytest

from wgpu_rt.errors import SceneError
from wgpu_rt.renderer import render
from wgpu_rt.scene.loader import parse_scene

TILT_DEG = 50.0
TINT = [0.9, 0.7, 0.5]


def _pane_scene(turn: float = 0.0, kind: str = "thin_dielectric") -> dict:
    """A glowing backdrop (radiance 1) seen head-on through a pane tilted TILT_DEG about +y (turned ``turn`` degrees
    more, 180 showing its back), nothing else: what the pane reflects is black."""
    return {
        "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "fov": 8},
        "materials": {"pane": {"kind": kind, "ior": 1.5, "transmittance": TINT},
                      "backdrop": {"reflectance": 0.0, "emission": 1.0}},
        "meshes": [{"name": "backdrop", "shape": "rectangle", "material": "backdrop",
                    "transform": {"scale": 3, "translate": [0, 0, -2]}},
                   {"name": "pane", "shape": "rectangle", "material": "pane",
                    "transform": {"rotate": {"axis": [0, 1, 0], "angle": TILT_DEG + turn}, "scale": 1.5}}],
    }


def _pane_transmittance(cos_i: float) -> float:
    cos_t = np.sqrt(1 - (1 - cos_i ** 2) / 1.5 ** 2)
    r = 0.5 * (((cos_i - 1.5 * cos_t) / (cos_i + 1.5 * cos_t)) ** 2
               + ((1.5 * cos_i - cos_t) / (1.5 * cos_i + cos_t)) ** 2)
    return 1 - 2 * r / (1 + r)


@pytest.mark.parametrize("turn", [0.0, 180.0])
def test_light_through_a_thin_pane_goes_straight_on_dimmed_by_both_faces(gpu, turn):
    """The backdrop through the pane, from its front and from its back: the pane's transmittance at 50° (0.885,
    where a single face would let 0.940 through) times its tint, with no shift (a pane of no thickness), at every
    pixel of the view (the reflected side is black)."""
    scene = parse_scene(_pane_scene(turn), "pane", Path("."))
    color = render(scene, spp=256, size=(8, 8), max_depth=4, aovs=()).color
    expected = _pane_transmittance(np.cos(np.radians(TILT_DEG))) * np.array(TINT)
    np.testing.assert_allclose(color.reshape(-1, 3).mean(0), expected, rtol=0.01)
    np.testing.assert_allclose(color, np.broadcast_to(expected, color.shape), rtol=0.1)


def test_the_aux_albedo_behind_a_thin_pane_is_its_transmittance_noise_free(gpu):
    """Behind the pane the albedo the denoiser sees is what lies behind it (a grey wall) times the pane's
    transmittance and tint, its two lobes shared by the pixel's samples (no speckle)."""
    data = _pane_scene()
    data["materials"]["backdrop"] = {"reflectance": 0.6}
    data["lights"] = [{"type": "point", "position": [0, 2, 2], "intensity": 1}]
    scene = parse_scene(data, "pane", Path("."))
    albedo = render(scene, spp=1, size=(8, 8), max_depth=4, aovs=("albedo",), aux_samples=4).aovs["albedo"]
    expected = 0.6 * _pane_transmittance(np.cos(np.radians(TILT_DEG))) * np.array(TINT)
    np.testing.assert_allclose(albedo, np.broadcast_to(expected, albedo.shape), rtol=0.03)


@pytest.mark.parametrize("field, value, message", [
    ("roughness", 0.1, "a thin_dielectric is smooth"),
    ("absorption", 1.0, "absorption is a dielectric's .*not a thin_dielectric's"),
])
def test_a_thin_pane_has_no_roughness_and_no_inside(field, value, message):
    data = _pane_scene()
    data["materials"]["pane"][field] = value
    with pytest.raises(SceneError, match=r"materials\.pane: " + message):
        parse_scene(data, "pane", Path("."))


def _skylight(pane: str | None, light: dict) -> dict:
    """A grey floor seen from above (from under the skylight), lit by ``light`` through a horizontal skylight pane
    at height 1.5 (``pane``: its kind, or None for no pane)."""
    data = {"camera": {"origin": [0, 1, 0.001], "target": [0, 0, 0], "fov": 30},
            "materials": {"floor": {"reflectance": 0.5}},
            "meshes": [{"name": "floor", "shape": "rectangle", "material": "floor",
                        "transform": {"rotate": {"axis": [1, 0, 0], "angle": -90}, "scale": 3}}],
            "lights": [light]}
    if pane is not None:
        data["materials"]["pane"] = {"kind": pane, "ior": 1.5 if pane == "thin_dielectric" else 1.0,
                                     "transmittance": TINT}
        data["meshes"].append({"name": "pane", "shape": "rectangle", "material": "pane",
                               "transform": {"rotate": {"axis": [1, 0, 0], "angle": 90}, "scale": 4,
                                             "translate": [0, 1.5, 0]}})
    return data


@pytest.mark.parametrize("instanced", [False, True])
def test_a_sun_shines_through_a_thin_pane_dimmed_and_tinted(gpu, instanced):
    """A sun 40° from the zenith lights the floor through the skylight (direct light only): the shadow ray of its
    sample crosses the pane and keeps the pane's transmittance at 40° times its tint; a solid glass sheet there
    would leave the floor black (a path cannot meet the sun by chance). The same with the pane an instance whose
    material is the instance's (a two-level scene)."""
    sun = {"type": "directional", "direction": [np.sin(np.radians(40)), -np.cos(np.radians(40)), 0], "irradiance": 2}
    options = dict(spp=4, size=(8, 8), max_depth=2, aovs=())
    bare = render(parse_scene(_skylight(None, sun), "bare", Path(".")), **options).color
    data = _skylight("thin_dielectric", sun)
    if instanced:
        pane = data["meshes"][-1]
        pane["material"] = "floor"
        pane["instances"] = [{"transform": pane.pop("transform"), "material": "pane"},
                             {"transform": {"translate": [0, -5, 0]}}]
    paned = render(parse_scene(data, "paned", Path(".")), **options).color
    expected = _pane_transmittance(np.cos(np.radians(40))) * np.array(TINT)
    np.testing.assert_allclose(paned / bare, np.broadcast_to(expected, paned.shape), rtol=1e-4)


def test_a_lamp_through_a_thin_pane_is_counted_once(gpu):
    """An area lamp above the skylight, at max depth 3: its light reaches the floor both by light samples through
    the pane and by paths that cross the pane and meet it, weighed against each other as if the pane were not
    there; a pane of index 1 and white tint (it reflects nothing) then changes nothing but the noise, where counting
    the lamp twice would add up to half again."""
    data_bare = _skylight(None, {"type": "point", "position": [5, 5, 5], "intensity": 0})
    data_pane = _skylight("dielectric", {"type": "point", "position": [5, 5, 5], "intensity": 0})
    data_pane["materials"]["pane"] = {"kind": "thin_dielectric", "ior": 1.0}
    for data in (data_bare, data_pane):
        data["lights"] = []
        data["materials"]["lamp"] = {"reflectance": 0.0, "emission": 4.0}
        data["meshes"].append({"name": "lamp", "shape": "rectangle", "material": "lamp",
                               "transform": {"rotate": {"axis": [1, 0, 0], "angle": 90}, "scale": 0.5,
                                             "translate": [0.3, 2.5, 0]}})
    options = dict(spp=512, size=(8, 8), max_depth=3, aovs=())
    bare = render(parse_scene(data_bare, "bare", Path(".")), **options).color
    paned = render(parse_scene(data_pane, "paned", Path(".")), **options).color
    np.testing.assert_allclose(paned.mean(), bare.mean(), rtol=0.01)
