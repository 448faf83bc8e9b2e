"""A rough plastic's coat tables (wgpu_rt/trace/coat.py) as the kernel gets them. That they are Mitsuba's is
tests/test_mitsuba.py's test_rough_coat_tables_are_mitsubas; here: their smooth limit, and the packing."""

import numpy as np
import pytest

from wgpu_rt.scene.model import Material
from wgpu_rt.trace.coat import COAT_KNOTS, TABLE_ANGLES, coat_tables, coat_transmittance, coat_words
from wgpu_rt.trace.scene_data import pack_materials

TABLE_COSINES = np.arange(TABLE_ANGLES) / (TABLE_ANGLES - 1)


def _fresnel(cos_i: np.ndarray, eta: float) -> np.ndarray:
    cos_t = np.sqrt(np.maximum(0.0, 1 - (1 - cos_i ** 2) / eta ** 2))
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (rs ** 2 + rp ** 2)


@pytest.mark.parametrize("ior", [1.33, 1.5, 2.0])
def test_a_nearly_smooth_coat_is_fresnels(ior):
    """As alpha → 0 the coat becomes a smooth boundary: t → 1 − F away from grazing, and the internal
    reflectance → the diffuse Fresnel reflectance from inside (the fit Mitsuba's plastic uses)."""
    transmittance, internal = coat_tables(1e-3, ior)
    away = TABLE_COSINES > 0.2
    np.testing.assert_allclose(transmittance[away], 1 - _fresnel(TABLE_COSINES[away], ior), rtol=2e-3)
    mu = np.maximum(1e-6, TABLE_COSINES)
    inside = np.where((1 - mu ** 2) * ior ** 2 >= 1, 1.0, _fresnel(mu, 1 / ior))   # total internal reflection
    assert internal == pytest.approx(2 * np.mean(inside * mu), abs=2e-3)


@pytest.mark.parametrize("alpha, ior", [(0.01, 1.5), (0.3, 1.4), (1.0, 2.2)])
def test_the_packed_knots_read_back_as_the_table(alpha, ior):
    """Eleven half-float knots in √μ stand for Mitsuba's 64-entry table: within 0.3 % weighted by cos θ (what
    the base's light is weighted by), the internal reflectance in the twelfth half; no word is a float32
    NaN, infinity or denormal, which a device need not carry through unchanged."""
    words = coat_words(alpha, ior)
    transmittance, internal = coat_tables(alpha, ior)
    assert words.dtype == np.float32 and words.shape == (6,)
    assert np.all(np.isfinite(words)) and np.all(np.abs(words) >= np.finfo(np.float32).tiny)
    cosines = np.linspace(0, 1, 1001)
    table = np.interp(cosines, TABLE_COSINES, transmittance)
    error = np.sum(np.abs(coat_transmittance(words, cosines) - table) * cosines) / np.sum(table * cosines)
    assert error < 3e-3
    assert float(words.view(np.float16)[COAT_KNOTS]) == pytest.approx(internal, rel=1e-3)


def test_only_a_rough_plastic_record_carries_a_table():
    """The table goes into a rough plastic's eta and k; a smooth plastic and a metal keep theirs."""
    metal = Material("conductor", eta=[0.2, 0.4, 1.4], k=[3.9, 2.4, 1.6], roughness=0.3)
    smooth, rough = Material("plastic", ior=1.4), Material("plastic", ior=1.4, roughness=0.3)
    records = pack_materials([metal, smooth, rough])
    np.testing.assert_array_equal(records["eta"][0], metal.eta)
    np.testing.assert_array_equal(records["k"][1], smooth.k)
    packed = np.concatenate([records["eta"][2], records["k"][2]])
    np.testing.assert_array_equal(packed.view(np.uint32), coat_words(0.3, 1.4).view(np.uint32))
