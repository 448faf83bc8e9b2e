"""A rough plastic's coat, reduced to the two things its diffuse base needs (wgsl/trace/bsdf_plastic.wgsl):

- t(μ), the share of light arriving at cos θ = μ that passes the rough coat into the base: over the coat's
  visible microfacets (GGX, alpha), what is refracted (1 − Fresnel) and not shadowed on its way down (Smith's
  G1 of the refracted direction). The masking loss is what makes t fall off towards grazing angles faster than
  1 − F (at alpha 0.3, t(cos 80°) / t(1) is 0.80 where 1 − F gives 0.92): Mitsuba 3's roughplastic counts it so.
- the coat's internal reflectance, twice the cosine-weighted mean over μ of what the coat reflects back down
  from inside (index 1 / ior), unshadowed.

Both are integrals over the visible-normal distribution, evaluated here by a midpoint rule in its two sample
coordinates on Mitsuba's 64 angles (μ = j / 63), which reproduces Mitsuba's own tables to 0.03 %. The kernel
reads t at COAT_KNOTS angles μ = (i / (COAT_KNOTS − 1))², linearly between them in √μ, from half-floats packed
into the six words a plastic's record does not otherwise use (its conductor fields), the internal reflectance
in the twelfth half.

A plastic whose roughness varies over its surface (a metal-rough map, wgsl/trace/metal_rough_maps.wgsl) has these
six words at COAT_LEVELS perceptual roughnesses r = i / (COAT_LEVELS − 1) (alpha r²; ``coat_levels``), and a point
of roughness r takes each half linearly between the two levels about it (``coat_words_between``).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

COAT_KNOTS = 11                 # t(μ) at μ = (i / 10)², i = 0 … 10
TABLE_ANGLES = 64               # as Mitsuba's MI_ROUGH_TRANSMITTANCE_RES
QUADRATURE = 64                 # midpoints per sample coordinate of the visible normals
# The least value a knot is stored as: a half-float below 2^-14 would sit in the high half of a word as a
# denormal float32, which a device may flush to zero on the way; the loss at μ ≈ 0 weighs nothing.
LEAST_KNOT = 1e-4
COAT_LEVELS = 17                # a varying coat's tables at r = i / 16 (alpha r²)
LEVEL_FLOOR = 1e-3              # the alpha of level 0 (a coat smoother than DELTA_ROUGHNESS is shaded as smooth)


def _fresnel(cos_i: np.ndarray, eta: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unpolarized Fresnel reflectance of a boundary of relative index ``eta`` for cos θi (negative: from
    inside), with cos θt (0 under total internal reflection) and the relative index crossed."""
    inside = cos_i < 0
    crossed = np.where(inside, 1.0 / eta, eta)
    cos_i = np.abs(cos_i)
    sin2_t = (1.0 - cos_i * cos_i) / (crossed * crossed)
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    rs = (cos_i - crossed * cos_t) / (cos_i + crossed * cos_t)
    rp = (crossed * cos_i - cos_t) / (crossed * cos_i + cos_t)
    return np.where(sin2_t >= 1.0, 1.0, 0.5 * (rs * rs + rp * rp)), cos_t, crossed


def _smith_g1(v: np.ndarray, m: np.ndarray, alpha: float) -> np.ndarray:
    """GGX's Smith G1 of direction v (last axis xyz) over microfacet normal m, 0 where m faces away."""
    tan2 = alpha * alpha * (v[..., 0] ** 2 + v[..., 1] ** 2) / np.maximum(v[..., 2] ** 2, 1e-300)
    g1 = 2.0 / (1.0 + np.sqrt(1.0 + tan2))
    return np.where(np.sum(v * m, -1) * v[..., 2] <= 0, 0.0, g1)


def _visible_normals(wi: np.ndarray, alpha: float) -> np.ndarray:
    """(angles, QUADRATURE², 3) microfacet normals spread over GGX's visible normals for each of ``wi``
    ((angles, 3), in the x-z plane), at the midpoints of a QUADRATURE² grid of Heitz's (2018) mapping."""
    grid = (np.arange(QUADRATURE) + 0.5) / QUADRATURE
    u1, u2 = (a.ravel() for a in np.meshgrid(grid, grid))
    stretched = wi * np.array([alpha, alpha, 1.0])
    stretched /= np.linalg.norm(stretched, axis=-1, keepdims=True)
    tilted = stretched[:, 0] > 0
    t1 = np.where(tilted[:, None], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0])
    t2 = np.cross(stretched, t1)
    r, phi = np.sqrt(u1), 2.0 * np.pi * u2
    p1 = r * np.cos(phi)
    s = 0.5 * (1.0 + stretched[:, 2:3])
    p2 = (1.0 - s) * np.sqrt(np.maximum(0.0, 1.0 - p1 * p1)) + s * (r * np.sin(phi))
    p3 = np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))
    n = p1[None, :, None] * t1[:, None] + p2[..., None] * t2[:, None] + p3[..., None] * stretched[:, None]
    m = np.stack([alpha * n[..., 0], alpha * n[..., 1], np.maximum(1e-7, n[..., 2])], -1)
    return m / np.linalg.norm(m, axis=-1, keepdims=True)


def _through_and_back(mu: np.ndarray, alpha: float, eta: float) -> tuple[np.ndarray, np.ndarray]:
    """For light arriving at cos θ = ``mu`` on a rough boundary of relative index ``eta``: the share refracted
    across it and unshadowed, and the share reflected and unshadowed."""
    wi = np.stack([np.sqrt(1.0 - mu * mu), np.zeros_like(mu), mu], -1)
    m = _visible_normals(wi, alpha)
    cos_m = np.sum(m * wi[:, None], -1)
    fresnel, cos_t, crossed = _fresnel(cos_m, eta)
    reflected = 2.0 * cos_m[..., None] * m - wi[:, None]
    refracted = -wi[:, None] / crossed[..., None] + (cos_m / crossed - cos_t)[..., None] * m
    through = np.where(refracted[..., 2] < 0, (1.0 - fresnel) * _smith_g1(refracted, m, alpha), 0.0)
    back = np.where(reflected[..., 2] > 0, fresnel * _smith_g1(reflected, m, alpha), 0.0)
    return through.mean(-1), back.mean(-1)


@lru_cache(maxsize=256)
def coat_tables(alpha: float, ior: float) -> tuple[np.ndarray, float]:
    """(t at TABLE_ANGLES cosines j / 63, the internal reflectance) of a GGX coat of ``alpha`` and index
    ``ior`` over 1."""
    mu = np.maximum(1e-6, np.arange(TABLE_ANGLES) / (TABLE_ANGLES - 1))
    transmittance, _ = _through_and_back(mu, alpha, ior)
    _, inner = _through_and_back(mu, alpha, 1.0 / ior)
    return transmittance, float(2.0 * np.mean(inner * mu))


def coat_words(alpha: float, ior: float) -> np.ndarray:
    """The six float32 words (a plastic record's eta and k) holding the coat's COAT_KNOTS values of t and its
    internal reflectance as half-floats, two to a word, the lower-numbered in the low half."""
    transmittance, internal = coat_tables(float(alpha), float(ior))
    cosines = (np.arange(COAT_KNOTS) / (COAT_KNOTS - 1)) ** 2
    knots = np.interp(cosines, np.arange(TABLE_ANGLES) / (TABLE_ANGLES - 1), transmittance)
    halves = np.maximum(np.append(knots, internal), LEAST_KNOT).astype(np.float16)
    return halves.view(np.uint32).view(np.float32)


def coat_transmittance(words: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """t(μ) as the kernel reads it from ``coat_words`` (the numpy reference of bsdf_plastic.wgsl's)."""
    knots = np.asarray(words, np.float32).view(np.float16).astype(np.float64)[:COAT_KNOTS]
    return np.interp(np.sqrt(np.clip(mu, 0.0, 1.0)), np.arange(COAT_KNOTS) / (COAT_KNOTS - 1), knots)


def coat_levels(ior: float) -> np.ndarray:
    """(COAT_LEVELS, 6) float32: ``coat_words`` at perceptual roughnesses r = i / (COAT_LEVELS − 1), alpha r²
    (LEVEL_FLOOR at r = 0), for a coat of index ``ior``."""
    roughness = np.arange(COAT_LEVELS) / (COAT_LEVELS - 1)
    return np.stack([coat_words(max(r * r, LEVEL_FLOOR), ior) for r in roughness])


def coat_words_between(levels: np.ndarray, roughness: float) -> np.ndarray:
    """The six words a point of perceptual ``roughness`` takes from ``coat_levels``: each half-float linearly
    between the two levels about it (the numpy reference of wgsl/trace/metal_rough_maps.wgsl's)."""
    x = float(np.clip(roughness, 0.0, 1.0)) * (COAT_LEVELS - 1)
    i = min(int(x), COAT_LEVELS - 2)
    halves = np.asarray(levels, np.float32).view(np.float16).astype(np.float32)
    mixed = halves[i] + (x - i) * (halves[i + 1] - halves[i])
    return mixed.astype(np.float16).view(np.float32)
