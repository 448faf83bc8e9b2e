"""Adaptive sampling: per-pixel extra samples from an importance map, for the tracer's targeted pass.

The tracer keeps its planes as running means over every sample a pixel has taken (its spp plane counts
them), so a targeted pass that adds ``extra`` samples on top of the 1-spp probe leaves radiance the
plain average of 1 + extra samples, weighted by count, with no extra bookkeeping here. (The counts are
chosen from the probe itself, as in every a-posteriori adaptive sampler; the averaging adds no bias of
its own.) See ``wgsl/frame/adaptive.wgsl`` for the kernels.

Samplers:
- ``heat``: the Error Predictor's heatmap, extra = floor(heat^k · 31), or with ``budget`` (mean spp
  including the probe) weights sqrt(p² + pooled p²), p = heat^k (``AdaptiveSettings.pool_sigma``),
  scaled so the total is exactly (budget − 1)·pixels, mixed with an even share
  (``AdaptiveSettings.uniform_share``). The
  remainder after rounding down is handed out deterministically (prefix ranks, not atomic races), so
  the same heatmap always gives the same sample map, bit for bit.
- ``uniform``: the same budget spread evenly (equal total rays baseline).
- ``variance``: Cycles' half-buffer error of a 2-spp probe as the weights (classic baseline).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import wgpu

from ..errors import WgpuRtError
from ..passes import RADIANCE, ComputePass, PlaneSpec
from .kernel import TILE, FrameKernel, ceil_div, nonnegative_finite

HEAT = PlaneSpec("heat", 1)
EXTRA_SAMPLES = PlaneSpec("extra_samples", 1, "u32")
SAMPLE_ERROR = PlaneSpec("sample_error", 1)
HALF_RADIANCE = PlaneSpec("half_radiance", 3)
CLAIM = PlaneSpec("sample_claim", 1)
SQUARED_IMPORTANCE = PlaneSpec("squared_importance", 1)
MAX_HEAT_SAMPLES = 31
SAMPLERS = ("heat", "uniform", "variance")
NO_BUDGET_EXPONENT = 3.0
# The importance's power under a budget, per sampler (AdaptiveSettings.exponent says why).
BUDGET_EXPONENT = {"heat": 2.0, "uniform": 1.0, "variance": 1.0}
# The share of a budget's extra samples spread evenly, per sampler (AdaptiveSettings.evenly_spread).
UNIFORM_SHARE = {"heat": 0.5, "variance": 0.5}
# The standard deviation (px) of the neighbourhood pooling of p² under a budget, per sampler
# (AdaptiveSettings.pooling); 0: none. Taps reach POOL_REACH standard deviations.
POOL_SIGMA = {"heat": 2.0, "variance": 0.0}
POOL_REACH = 2.0
SHADER = "frame/adaptive.wgsl"
# The bindings each entry point of frame/adaptive.wgsl uses (their indices are read from the WGSL).
ENTRY_BINDINGS = {
    "extra_from_heat": ("source", "extra"),
    "square_importance": ("source", "squared"),
    "weigh": ("claim", "tile_sums", "squared"),
    "sum_weights": ("tile_sums", "budget"),
    "assign": ("extra", "claim", "budget"),
    "count_candidates": ("extra", "claim", "tile_offsets"),
    "scan_candidates": ("budget", "tile_offsets", "spill_args"),
    "take": ("extra", "claim", "budget", "tile_offsets"),
    "half_buffer_error": ("source", "half_radiance", "error"),
}
# Entry points run by a single workgroup rather than one invocation per pixel.
SINGLE_WORKGROUP = ("sum_weights", "scan_candidates")
# Claim thresholds of the remainder rounds: round claims up (larger first), then spread what capped
# pixels could not take.
ROUNDING_THRESHOLDS = (0.5, 0.0)
SPILL_THRESHOLD = -2.0
SPILL_SLOT_BYTES = 24   # per spill round: workgroups of its count/take (3 u32), then of its scan (3 u32)


@dataclass(frozen=True)
class AdaptiveSettings:
    """``k`` is the power the importance is raised to; None picks ``exponent``'s default for the mode."""

    sampler: str = "heat"
    budget: float | None = None     # mean spp including the probe; None: floor(heat^k · 31) extra
    k: float | None = None
    cap: int = MAX_HEAT_SAMPLES     # most extra samples one pixel may take under a budget
    # Under a budget, the share of the extra samples spread evenly before the rest follows the importance
    # (a defensive mixture); None: UNIFORM_SHARE's default for the sampler.
    uniform_share: float | None = None
    # Under a budget, the standard deviation (px) of the Gaussian that pools p² = importance^2k over a
    # pixel's neighbourhood; None: POOL_SIGMA's default for the sampler, 0: no pooling.
    pool_sigma: float | None = None

    def __post_init__(self):
        if self.sampler not in SAMPLERS:
            raise WgpuRtError(f"adaptive sampler {self.sampler!r} is not one of {', '.join(SAMPLERS)}")
        if self.budget is None and self.sampler != "heat":
            raise WgpuRtError(f"the {self.sampler} sampler needs a budget (mean samples per pixel)")
        if self.uniform_share is not None and not 0.0 <= self.uniform_share <= 1.0:
            raise WgpuRtError(f"adaptive uniform_share {self.uniform_share} is outside [0, 1]")
        if self.pool_sigma is not None and not 0.0 <= self.pool_sigma <= 16.0:
            raise WgpuRtError(f"adaptive pool_sigma {self.pool_sigma} is outside [0, 16] px")
        low = self.probe_samples
        if self.budget is not None and not (low <= self.budget <= low + self.cap):
            raise WgpuRtError(f"adaptive budget {self.budget} spp is outside [{low}, {low + self.cap}] "
                              f"(the {low}-spp probe plus at most {self.cap} extra per pixel)")

    @property
    def exponent(self) -> float:
        """``k``, or the default of the mode: without a budget the issue's floor(heat^3 · 31), which maps
        only the hottest pixels to many samples. Under a budget the total is fixed and only the shares
        matter; relMSE, Σ σ_i² / (n_i (μ_i² + ε)), is least at a fixed Σ n_i when n_i ∝ σ_i / sqrt(μ_i² + ε),
        the per-sample relative error. The half-buffer error estimates that directly (power 1). The
        heatmap estimates it too, but through log1p and a per-image 99th-percentile scale clipped at 1,
        which compress exactly the largest errors; benchmarks/bench_adaptive.py --k 1 2 (96², 3 seeds,
        cornell, sun-room, cornell-glossy, budgets 2–16) measured power 2 better than 1 at every budget
        on relMSE (geometric mean of the savings 1.31× against 1.22×), so the heat sampler uses 2.
        Undoing the log1p instead, heat·(1 + μ)/sqrt(μ² + ε) with μ the probe's 3×3 box luminance,
        scores below heat^2 on the expected relMSE given the probe (computed from 64 independent 1-spp
        renders and the gold, seeds 0–2, the four scenes; geometric mean 1.25/1.14/1.08/1.05 against
        1.57/1.21/1.08/1.03 at budgets 2/4/8/16): it halves cornell-glossy's gain at budget 2, because
        the heat's error is the probe's own error δ, not σ (see ``pooling``), and a 1-spp μ is noisy."""
        if self.k is not None:
            return self.k
        return NO_BUDGET_EXPONENT if self.budget is None else BUDGET_EXPONENT[self.sampler]

    @property
    def evenly_spread(self) -> float:
        """``uniform_share``, or the sampler's default. The importance comes from one noisy probe, so
        some pixels that need samples look quiet; following it alone starves them, and the loss grows
        with the budget (benchmarks/bench_adaptive.py at 96², 3 seeds: heat alone saves 1.6× at budget
        2 but loses, 0.7–0.9×, at budgets 8 and 16). Spreading half evenly bounds every pixel's count
        from below, as defensive importance sampling does: ≈ 1.0× or better at every budget measured,
        for less gain at budget 2 (1.3×). With ``pooling`` a quarter spread evenly gains at budget 2 and
        loses a little at 4–16 and on display MSE (numbers there), so half stays."""
        if self.sampler == "uniform":
            return 1.0
        return UNIFORM_SHARE[self.sampler] if self.uniform_share is None else self.uniform_share

    @property
    def pooling(self) -> float:
        """``pool_sigma``, or the sampler's default. relMSE after n samples of a pixel whose probe missed
        by δ is (δ² + (n − 1)σ²)/(n²(μ² + ε)): at low budgets the probe's own error δ decides, at high
        budgets the per-sample σ (the optimum tends to n ∝ σ/sqrt(μ² + ε)). The heat predicts δ (its
        training target is one probe's error) and says little of σ: in expectation over fresh samples,
        weights ∝ heat^2 allocate no better than uniform for the σ term (σ from 64 independent 1-spp
        renders). σ is smooth where δ is not, so the local mean of p² estimates it, and
        sqrt(p² + pooled p²) keeps both terms. benchmarks/bench_adaptive.py --seeds 6 --uniform-share
        0.25 0.5 --pool-sigma 2 0 --oracle (96², 8192-spp gold), savings on relMSE at budgets 2/4/8/16,
        geometric mean of cornell, cornell-glossy, sun-room, bunny: pooled σ 2 px, half spread evenly
        1.55/1.25/1.08/1.08; unpooled (the previous default) 1.55/1.20/1.08/1.00; pooled, a quarter
        even 1.63/1.23/1.04/1.09; unpooled, a quarter 1.70/1.17/1.03/1.02. Display-space MSE: pooled
        half 1.06/1.05/1.00/0.96 against unpooled 1.03/0.99/0.92/0.90. (3 seeds: pooled 1.57/1.30/1.11/
        1.08 against 1.63/1.25/1.11/0.97; single scene–budget cells move by ±0.1–0.3 between runs,
        sun-room's uniform curve being flat from 8 to 16 spp.) The ceiling of this allocation is low at high budgets: fed the
        true σ term it saves 1.15/1.13/1.10/1.09, fed each run's true probe error as well (a perfect
        heat) 2.11/1.39/1.20/1.12. The variance sampler's half-buffer error already averages two
        samples, and stays Cycles' classic estimate (no pooling)."""
        if self.sampler == "uniform" or self.budget is None:
            return 0.0
        return POOL_SIGMA[self.sampler] if self.pool_sigma is None else self.pool_sigma

    @property
    def probe_samples(self) -> int:
        return 2 if self.sampler == "variance" else 1

    def extra_total(self, pixels: int) -> int:
        """Extra samples the budget leaves after the probe, over ``pixels``."""
        total = int(round((self.budget - self.probe_samples) * pixels))
        if total >= 2 ** 32:
            raise WgpuRtError(f"adaptive budget {self.budget} spp over {pixels} pixels exceeds 2^32 samples")
        return total

    @property
    def max_extra(self) -> int:
        """Upper bound of any pixel's extra samples."""
        return MAX_HEAT_SAMPLES if self.budget is None else self.cap

    def extra_bound(self, pixels: int) -> int:
        """Upper bound of the extra samples of a sample map over ``pixels``: the budget's exactly, else
        ``max_extra`` on every pixel (the targeted pass records as many batches as this could fill)."""
        return self.extra_total(pixels) if self.budget is not None else self.max_extra * pixels


# -- numpy references ---------------------------------------------------------------------------------
def extra_samples_from_heat(heat: np.ndarray, k: float = NO_BUDGET_EXPONENT) -> np.ndarray:
    """(H, W) heat → (H, W) uint32 extra samples floor(clip(heat, 0, 1)^k · 31)."""
    heat = np.clip(np.where(np.isfinite(heat), heat, 0.0), 0.0, 1.0).astype(np.float64)
    return np.floor(heat ** k * MAX_HEAT_SAMPLES).astype(np.uint32)


def pool_radius(sigma: float) -> int:
    """The pooling's reach in whole pixels (0 without pooling)."""
    return int(np.ceil(POOL_REACH * sigma)) if sigma > 0 else 0


def budget_weights(importance: np.ndarray, k: float = 1.0, pool_sigma: float = 0.0) -> np.ndarray:
    """(H, W) weights sqrt(p² + P), p = importance^k, P the Gaussian-weighted (``pool_sigma`` px) mean of
    p² over the taps within ``pool_radius`` that lie inside the frame (P = 0 without pooling)."""
    squared = np.minimum(nonnegative_finite(importance).astype(np.float64) ** k, 1e15) ** 2
    radius = pool_radius(pool_sigma)
    if radius == 0:
        return np.sqrt(squared)
    height, width = squared.shape
    total, norm = np.zeros_like(squared), np.zeros_like(squared)
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            inside = np.zeros_like(squared)
            inside[max(0, -dy): height - max(0, dy), max(0, -dx): width - max(0, dx)] = 1.0
            shifted = np.roll(squared, (-dy, -dx), axis=(0, 1)) * inside
            tap = np.exp(-(dx * dx + dy * dy) / (2 * pool_sigma ** 2))
            total += tap * shifted
            norm += tap * inside
    return np.sqrt(squared + total / norm)


def ideal_budget_samples(importance: np.ndarray, total: int, k: float = 1.0,
                         evenly_spread: float = 0.0, pool_sigma: float = 0.0) -> np.ndarray:
    """The real-valued share of ``total`` extra samples per pixel: ``evenly_spread`` of them evenly, the
    rest ∝ ``budget_weights`` (before the per-pixel cap and rounding; the device's integer counts sum to
    ``total`` exactly and stay within 1 of this wherever no pixel hits the cap)."""
    weights = budget_weights(importance, k, pool_sigma)
    even = np.full(importance.shape, total / importance.size)
    weight_sum = weights.sum()
    if weight_sum <= 0:
        return even
    return evenly_spread * even + (1.0 - evenly_spread) * weights * (total / weight_sum)


def half_buffer_error(full: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Cycles' per-pixel error estimate from the mean of all samples and of the first half, (H, W, 3)
    each: Σ_c |full − half| / (1e-4 + sqrt(Σ_c full))."""
    full, half = nonnegative_finite(full).astype(np.float64), nonnegative_finite(half).astype(np.float64)
    return (np.abs(full - half).sum(-1) / (1e-4 + np.sqrt(full.sum(-1)))).astype(np.float32)


# -- passes -------------------------------------------------------------------------------------------
class ExtraSamplesPass(ComputePass):
    """``source`` (heat, or the sample error for the variance sampler) → extra_samples (u32)."""

    outputs = (EXTRA_SAMPLES,)

    def __init__(self, ctx, width: int, height: int, settings: AdaptiveSettings, source: PlaneSpec = HEAT):
        self.settings, self.source = settings, source
        # The uniform sampler spreads every sample evenly: it binds the source but does not depend on it.
        self.inputs = () if settings.sampler == "uniform" else (source,)
        k = settings.exponent

        def kernel(entry, **constants):
            return FrameKernel(ctx, SHADER, entry, ENTRY_BINDINGS[entry], width, height, constants)

        if settings.budget is None:
            self.kernels, self.spill_rounds = [kernel("extra_from_heat", K=k)], []
            return
        target, cap = settings.extra_total(width * height), settings.cap
        tiles = ceil_div(width, TILE) * ceil_div(height, TILE)
        self.tile_sums = ctx.storage(4 * tiles, label="tile sums")
        self.tile_offsets = ctx.storage(4 * tiles, label="tile candidate offsets")
        self.budget = ctx.storage(16, label="sample budget")
        sigma = settings.pooling
        pooling = {"POOL_SIGMA": sigma, "POOL_RADIUS": pool_radius(sigma)} if sigma > 0 else {}
        self.kernels = [kernel("square_importance", K=k), kernel("weigh", **pooling),
                        kernel("sum_weights"),
                        kernel("assign", TARGET=target, CAP=cap, EVENLY_SPREAD=settings.evenly_spread)]

        def remainder_round(threshold, next_slot):
            return [kernel(entry, TARGET=target, CAP=cap, THRESHOLD=threshold, NEXT_SLOT=next_slot)
                    for entry in ("count_candidates", "scan_candidates", "take")]

        for threshold in ROUNDING_THRESHOLDS:
            self.kernels += remainder_round(threshold, next_slot=0)
        # Without capped pixels the two rounds above already hand out the whole remainder (it is the sum
        # of the claims, each < 1), so every count is its ideal share rounded down or up. What capped
        # pixels could not take is spread by rounds of at most one sample per pixel: cap + 1 rounds always
        # meet the budget. They run indirectly, from spill_args slot r (see frame/adaptive.wgsl), and
        # cost nothing once the budget is met.
        self.spill_rounds = [remainder_round(SPILL_THRESHOLD, next_slot=r + 1) for r in range(cap + 1)]
        # Two buffers, by round parity: a dispatch cannot read its arguments from a buffer it writes, so
        # round r runs from buffer r % 2 and its scan writes round r + 1's slot into the other one.
        self.spill_args = [ctx.storage(SPILL_SLOT_BYTES * (cap + 2), label=f"spill round dispatch args {i}",
                                       usage=wgpu.BufferUsage.INDIRECT) for i in range(2)]

    def execute(self, encoder, buffers) -> None:
        planes = {"source": buffers.get(self.source), "extra": buffers.get(EXTRA_SAMPLES)}
        if self.settings.budget is not None:
            planes |= {"claim": buffers.get(CLAIM), "tile_sums": self.tile_sums, "budget": self.budget,
                       "tile_offsets": self.tile_offsets, "squared": buffers.get(SQUARED_IMPORTANCE)}
            for arguments in self.spill_args:   # a spill round no scan switched on stays off
                encoder.clear_buffer(arguments)
            planes["spill_args"] = self.spill_args[0]   # the rounding rounds switch on spill round 0
        compute_pass = encoder.begin_compute_pass(label="extra samples")
        for kernel in self.kernels:
            kernel.record(compute_pass, planes, (1, 1) if kernel.entry in SINGLE_WORKGROUP else None)
        for slot, (count, scan, take) in enumerate(self.spill_rounds):
            arguments, grid = self.spill_args[slot % 2], slot * SPILL_SLOT_BYTES
            count.record_indirect(compute_pass, planes, arguments, grid)
            scan.record_indirect(compute_pass, planes | {"spill_args": self.spill_args[(slot + 1) % 2]},
                                 arguments, grid + 12)
            take.record_indirect(compute_pass, planes, arguments, grid)
        compute_pass.end()


class HalfBufferErrorPass(ComputePass):
    """radiance (mean of all probe samples), half_radiance (mean of the first half) → sample_error."""

    inputs = (RADIANCE, HALF_RADIANCE)
    outputs = (SAMPLE_ERROR,)

    def __init__(self, ctx, width: int, height: int):
        self.kernel = FrameKernel(ctx, SHADER, "half_buffer_error", ENTRY_BINDINGS["half_buffer_error"],
                                  width, height)

    def execute(self, encoder, buffers) -> None:
        self.kernel.dispatch(encoder, {"source": buffers.get(RADIANCE),
                                       "half_radiance": buffers.get(HALF_RADIANCE),
                                       "error": buffers.get(SAMPLE_ERROR)})
