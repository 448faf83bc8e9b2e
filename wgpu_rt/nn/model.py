"""``WgslModel``: an ONNX network run as WGSL compute kernels.

Weights are uploaded once, at load. Everything that depends on the resolution — shapes, the canvas
(H and W edge-padded up to the network's pooling multiple when the graph needs it, e.g. a U-Net at 37×53),
the activation buffers and the specialized pipelines — is planned once per resolution and cached.

Dispatches: the network's entry (converting the planar f32 input), its layers, its exit (writing the
planar f32 output). Conversions and small ops are folded into neighbouring kernels where they can be:
the first conv reads the input image itself, a conv's epilogue max-pools its output (the pool is not
dispatched), the last layer writes the output image itself, with a 1×1 head run in the epilogue of
the 3×3 conv before it where that conv's tile holds all its channels, and a transposed conv's epilogue
adds the skip tensor an Add sums it with (pack and unpack remain for the graphs where no layer can). The
shipped denoiser (five levels, the deepest added to the skip above it) is 20 dispatches in the GPU plan
(staged tiles, one dispatch per layer) and 36 on lavapipe; the four-level model before it was 17 and 27
(23 and 48 with every conversion and pool dispatched).

Buffer planning: every tensor lives in its root's buffer (a concat's inputs live inside the concat);
a root is live from the first dispatch that writes it to the last that reads it; roots are packed,
largest first, into a pool of buffers (into the smallest buffer free over the root's whole lifetime
that fits it, else the largest free one, grown, else a new one). ``Plan.peak_bytes`` is the pool's
total size, ``Plan.unplanned_bytes`` what one buffer per tensor would take. A buffer larger than one
storage binding (the U-Net's 32-channel full-resolution concat at 1080p in fp32 is 255 MiB, lavapipe
binds 128 MiB) is bound in windows: each kernel binds just the blocks of the tensor it reads or writes,
and a convolution whose input alone is over the limit reads it through two windows
(load_blocks_split.wgsl). Only a frame that cannot be bound so (a buffer over max-buffer-size, or a
window over the binding limit or off its offset alignment) runs as bands of rows with receptive-field
context, with the same result; at 1080p on lavapipe windows took the shipped denoiser from 8.5 s in
five bands to 4.0 s whole (BENCHMARKS.md §10).

Numerics (both precisions): inputs are sanitized on entry (NaN → 0, ±Inf and out-of-range values →
± the largest finite value of the storage type) and every kernel clamps what it stores the same way, so
outputs are always finite: an all-zero input gives the network's response to zeros, huge inputs
saturate at ±3.4e38 (fp32) or ±65504 (fp16) instead of overflowing, and a NaN born inside a kernel
(Inf − Inf from saturated values) is stored as 0. Accumulation is always f32;
fp16 stores activations as f16 (relative error ≲ 1e-2 on the seed networks, see tests/test_nn_networks.py).
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import wgpu

from ..errors import DeviceLimitError, ModelError
from . import autotune as autotuning
from .graph import Layer, NetworkGraph, Shape, ShapeMismatch, load_graph
from .kernels import (PRECISIONS, Conv3x3Kernel, ConvKernel, ConvTransposeKernel, CopyChannelsKernel,
                      Dispatch, ElementwiseKernel, GemmKernel, Head, ImageRows, MaxPoolKernel, PackKernel,
                      ResizeKernel, TensorView, UnpackKernel, groups_of, record_dispatches)

# conv_tiling -> pixels per invocation of the loop kernels (conv.wgsl, gemm.wgsl); "register" also runs
# 3×3 stride-1 convs with 8k output channels on conv3x3.wgsl's written-out tile of 4 pixels, "staged" on
# conv3x3_staged.wgsl's (the same tile, input staged in workgroup memory; see Conv3x3Kernel),
# "staged-weights" there with each input block's weight blocks staged too (weights_workgroup.wgsl),
# "staged-narrow" there with 8 channels a tile wherever the layer has more: twice the invocations for
# the same work, for the low-resolution layers whose 16-channel tiles fill a GPU with less than one wave
# (the denoiser's deepest level at 1080p: 288 workgroups on an H200's 132 SMs, BENCHMARKS.md §25); the
# autotuner weighs it per layer.
CONV_TILINGS = {"none": 1, "loop": 4, "register": 4, "staged": 4, "staged-weights": 4, "staged-narrow": 4}
# suffix of an autotuned variant that prefers one dispatch per group of uniform windows (kernels.WindowLayout)
UNIFORM_WINDOWS = "+uniform-windows"
# How conv-family kernels read weight blocks: "subgroup" (the lanes of a subgroup split a block's loads
# and broadcast them: weights_subgroup.wgsl) or "direct" (each invocation loads the block: weights_uniform.wgsl)
WEIGHT_FETCHES = ("subgroup", "direct")
# suffix of an autotuned variant whose weights are read directly on an adapter with subgroups
DIRECT_WEIGHTS = "+direct-weights"
# What the 3×3 tile kernels multiply in: "f32", or with fp16 activations "f16" (each kernel row's products
# summed in packed half precision, then added to the f32 tile) or "f16-acc" (the tile summed in f16 too,
# converted to f32 only to store); see Conv3x3Kernel
MATHS = ("f32", "f16", "f16-acc")
# suffixes of an autotuned variant whose 3×3 kernels multiply in f16, and sum their tile in f16 as well
HALF_MATH = "+f16-math"
HALF_ACCUMULATE = "+f16-acc"
# What a precision argument may say: a storage type, or "auto" (``default_precision``)
PRECISION_CHOICES = ("auto", *PRECISIONS)
# Passes of a self-ensemble: the image under the first k of the 8 dihedral transforms (the flips and
# turns the networks are trained under), the outputs turned back and averaged.
ENSEMBLES = (1, 2, 4, 8)


def default_conv_tiling(ctx) -> str:
    """"staged" on discrete GPUs (on-chip workgroup memory), else "register" (see Conv3x3Kernel)."""
    return "staged" if ctx.adapter.info.get("adapter_type") == "DiscreteGPU" else "register"


def default_precision(ctx) -> str:
    """"fp16" on discrete GPUs with the shader-f16 feature, else "fp32". The shipped denoiser at 1080p on an
    H200 (BENCHMARKS.md §21): 8.5 ms in fp16 with f16 multiply-adds against 10.3 ms in fp32, outputs
    within 1.4e-3 of onnxruntime's; on lavapipe fp16 is 4–5× slower (no half-precision ALU)."""
    discrete = ctx.adapter.info.get("adapter_type") == "DiscreteGPU"
    return "fp16" if discrete and ctx.has_f16 else "fp32"


def default_math(ctx, precision: str) -> str:
    """For fp16 activations on discrete GPUs, the most half-precision math whose kernels that GPU's
    compiler gets right (``half_math_agrees``): "f16-acc" (the H200 profile of the shipped denoiser at
    1080p: 6.5 ms, BENCHMARKS.md §31; its denoised images 71–84 dB from onnxruntime's on lavapipe, §26),
    else "f16" (7.5 ms; 8.8 with f32 math, §25), else "f32"; "f32" everywhere else."""
    discrete = ctx.adapter.info.get("adapter_type") == "DiscreteGPU"
    if precision != "fp16" or not discrete:
        return "f32"
    return next((math for math in ("f16-acc", "f16") if half_math_agrees(ctx, math)), "f32")


# a context's device -> {math: bool}
_half_math_checked: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
HALF_MATH_CHECK_TOLERANCE = 1e-2   # the fp16 bound of the parity tests, over max(1, max |f32 math|)


def half_math_agrees(ctx, math: str = "f16") -> bool:
    """Whether the 3×3 tile kernels multiplying in f16 (``math``: "f16", or "f16-acc") give what they give
    in f32 on ``ctx``'s adapter, within the fp16 bound, on a random 32→32-channel convolution (fp16
    activations both ways; checked once per context and math, a fraction of a second). A default, or an
    autotuner's candidate, may not rest on a kernel no test has run on that driver: where the two
    disagree (or the f16 kernel fails to compile), default_math keeps f32 and the autotuner leaves it out."""
    checked = _half_math_checked.setdefault(ctx.device, {})
    if math not in checked:
        import tempfile

        import onnx
        from onnx import helper, numpy_helper

        rng = np.random.default_rng(0)
        weight = rng.normal(0, 0.1, (32, 32, 3, 3)).astype(np.float32)
        node = helper.make_node("Conv", ["x", "w"], ["y"], pads=[1, 1, 1, 1])
        graph = helper.make_graph([node], "half_math_check",
                                  [helper.make_tensor_value_info("x", onnx.TensorProto.FLOAT, [1, 32, "H", "W"])],
                                  [helper.make_tensor_value_info("y", onnx.TensorProto.FLOAT, [1, 32, "H", "W"])],
                                  [numpy_helper.from_array(weight, "w")])
        model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
        model.ir_version = 8
        x = rng.uniform(0, 1, (1, 32, 24, 40)).astype(np.float32)
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "half_math_check.onnx"
            onnx.save(model, path)
            try:
                f32, f16 = (WgslModel(path, "fp16", ctx=ctx, math=m)(x) for m in ("f32", math))
                agrees = bool(np.abs(f16 - f32).max() <= HALF_MATH_CHECK_TOLERANCE * max(1.0, np.abs(f32).max()))
            except (wgpu.GPUError, ModelError, DeviceLimitError):
                agrees = False
        checked[math] = agrees
    return checked[math]


def default_weight_fetch(ctx) -> str:
    """"subgroup" where the adapter has subgroups, else "direct". On lavapipe the shared loads take about
    half the time of direct ones (the shipped denoiser at 256²: 124–129 against 239 ms with the register
    tiling, 184 against 285–297 staged); on a GPU each shared block costs 16 subgroup broadcasts per
    invocation, which the autotuner weighs against direct loads (WgslModel(autotune=True))."""
    return "subgroup" if ctx.has_subgroups else "direct"


def default_uniform_windows(ctx) -> bool:
    """Whether conv-family layers whose weights exceed one uniform binding run as one dispatch per
    output-block group with that group's uniform windows (True) rather than as one dispatch reading
    storage (see kernels.PackedWeights). True on CPU adapters: on lavapipe a uniform load is a vector
    gather and a storage load a loop over the lanes, and one dispatch per layer has nothing to fill
    there (2 cores); GPUs take the single dispatch, which fills them at low resolution."""
    return ctx.adapter.info.get("adapter_type") == "CPU"


def shape_view(shape: Shape, buffer=None) -> TensorView:
    """A tensor of ``shape`` from the start of ``buffer``: the planar image an exit layer writes, or with
    no buffer the shape alone (autotuning times a layer on scratch tensors of its shapes)."""
    return TensorView(buffer, 0, shape.channels, shape.height, shape.width)


class _BandsNeeded(Exception):
    """A whole-frame plan would bind a tensor over the device's storage binding limit (see
    WgslModel._bound_view): the frame runs in bands instead."""


@dataclass(frozen=True)
class Band:
    """One pass of the network over part of a frame: it reads ``valid_rows`` image rows from
    ``source_row`` (zeros below them) and keeps its rows ``keep_from`` .. ``keep_from + keep_rows - 1``,
    which are image rows ``source_row + keep_from`` onwards."""

    source_row: int
    valid_rows: int
    keep_from: int
    keep_rows: int


@dataclass
class NetworkPlan:
    """The network's dispatches and activation buffers for one canvas size. ``dispatches`` run between
    the entry, which reads the planar f32 input (``entry(input buffer, rows)``: pack.wgsl), and the
    exit, which writes the planar f32 output (``exit(output buffer, rows)``: the last layer itself where
    its kernel can, else unpack.wgsl); both are made per band, for ``ImageRows`` of the image."""

    canvas: tuple[int, int]
    dispatches: list[Dispatch]
    entry: Callable[[object, ImageRows], list[Dispatch]]
    exit: Callable[[object, ImageRows], list[Dispatch]]
    peak_bytes: int
    unplanned_bytes: int


@dataclass
class Plan:
    """Everything for one input resolution: the network plan and the bands it runs over (one band
    unless the frame's activations exceed the device's largest storage binding)."""

    height: int
    width: int
    output_shape: tuple[int, int, int]  # (C, H, W) of the cropped output
    network: NetworkPlan
    bands: list[Band]
    flops: int  # of the whole frame in one pass (bands recompute their context rows on top of this)
    output_buffer: object = None  # planar f32 output, made with the first inference at this size
    input_buffer: object = None  # staging for __call__
    _passes: dict = field(default_factory=dict)  # id(input buffer) -> (buffer, every dispatch of an inference)

    @property
    def canvas(self) -> tuple[int, int]:
        return self.network.canvas

    @property
    def peak_bytes(self) -> int:
        return self.network.peak_bytes

    @property
    def unplanned_bytes(self) -> int:
        return self.network.unplanned_bytes

    @property
    def dispatches(self) -> list[Dispatch]:
        """The network's dispatches for one band (without entry and exit)."""
        return self.network.dispatches


class WgslModel:
    """``WgslModel(path, precision="fp32"|"fp16"|"auto")`` (auto: ``default_precision``): call on NCHW
    float32 numpy, or ``record`` on GPU buffers. ``conv_tiling`` exists for the benchmark's steps, the
    profiler and the tests: "none" (one output pixel per invocation), "loop" (4-pixel tiles in loops),
    "register" (plus the written-out 3×3 tile kernel), "staged" (that tile with its input staged in
    workgroup memory), "staged-weights" (and its weights: the 3×3 layers then ignore ``weight_fetch``),
    "staged-narrow" (the staged tile 8 channels wide everywhere); default: ``default_conv_tiling``.
    ``weight_fetch``: how those kernels read weights ("subgroup" or "direct", see WEIGHT_FETCHES);
    default: ``default_weight_fetch``. ``math``: "f32", or with precision "fp16" also
    "f16", the 3×3 tile kernels' multiply-adds in half precision, or "f16-acc", their sums too (see
    MATHS); default: ``default_math``.

    ``autotune``: choose the tiling (and window preference) per layer shape by timing the candidates on
    this adapter once and caching the choice (see ``wgpu_rt.nn.autotune``; True, or an ``Autotuner``).
    Off by default (the first run of a new shape pays for compiling and timing every candidate) unless
    $WGPU_RT_AUTOTUNE=1; $WGPU_RT_AUTOTUNE=0 turns it off everywhere. A ``conv_tiling`` given here wins
    over autotuning; so do a ``weight_fetch`` and a ``math``.

    ``ensemble`` (1, 2, 4 or 8): run the network on the input as given and turned / flipped (dihedral
    transforms 0 .. k−1, see kernels.dihedral_strides) and average the outputs turned back, k times the
    work for a cleaner result (the denoiser's "high" quality). The first conv reads the input turned and
    the last layer writes and accumulates its output turned back, so a pass costs no extra dispatch."""

    def __init__(self, path: str | Path, precision: str = "fp32", ctx=None, conv_tiling: str | None = None,
                 autotune: bool | autotuning.Autotuner | None = None, ensemble: int = 1,
                 weight_fetch: str | None = None, math: str | None = None):
        from ..gpu import get_context

        if precision not in PRECISION_CHOICES:
            raise ModelError(f"precision {precision!r}: choose one of {', '.join(PRECISION_CHOICES)}")
        if ensemble not in ENSEMBLES:
            raise ModelError(f"ensemble {ensemble!r}: choose one of {', '.join(map(str, ENSEMBLES))}")
        self.ensemble = ensemble
        self.ctx = ctx or get_context()
        given = isinstance(autotune, autotuning.Autotuner)
        self.autotuner = None
        if (conv_tiling is None and weight_fetch is None and math is None
                and autotuning.enabled(True if given else autotune)):
            self.autotuner = autotune if given else autotuning.Autotuner(self.ctx)
        conv_tiling = conv_tiling or default_conv_tiling(self.ctx)
        if conv_tiling not in CONV_TILINGS:
            raise ModelError(f"conv_tiling {conv_tiling!r}: choose one of {', '.join(CONV_TILINGS)}")
        weight_fetch = weight_fetch or default_weight_fetch(self.ctx)
        if weight_fetch not in WEIGHT_FETCHES:
            raise ModelError(f"weight_fetch {weight_fetch!r}: choose one of {', '.join(WEIGHT_FETCHES)}")
        if weight_fetch == "subgroup" and not self.ctx.has_subgroups:
            raise ModelError(f"weight_fetch subgroup needs the subgroup feature, which {self.ctx.label} lacks; "
                             "use direct")
        if precision == "auto":
            precision = default_precision(self.ctx)
        math = math or default_math(self.ctx, precision)
        if math not in MATHS:
            raise ModelError(f"math {math!r}: choose one of {', '.join(MATHS)}")
        if math != "f32" and precision != "fp16":
            raise ModelError(f"math {math} needs precision fp16 (f16 activations), not {precision}")
        if precision == "fp16" and not self.ctx.has_f16:
            raise ModelError(f"precision fp16 needs the shader-f16 feature, which {self.ctx.label} lacks; "
                             "use fp32")
        self.path, self.precision = str(path), PRECISIONS[precision]
        self.graph: NetworkGraph = load_graph(path)
        self.conv_tiling, self.weight_fetch, self.math = conv_tiling, weight_fetch, math
        kernel_args = (self.ctx, self.precision)
        self.uniform_windows = default_uniform_windows(self.ctx)
        self._tiled_kernels: dict[tuple, object] = {}
        self.kernels = {"maxpool": MaxPoolKernel(*kernel_args), "resize": ResizeKernel(*kernel_args),
                        "elementwise": ElementwiseKernel(*kernel_args),
                        "concat": CopyChannelsKernel(*kernel_args), "pack": PackKernel(*kernel_args),
                        "unpack": UnpackKernel(*kernel_args)}
        channels = self.graph.infer_channels()
        self.prepared = {}  # layer name -> its weights as kernel_for(layer) (the defaults) packs them
        self._packed_for: dict[tuple[str, int], object] = {}  # (layer, id(kernel)) -> weights, tuned kernels
        for layer in self.graph.layers:
            if layer.weight is not None:
                self.prepared[layer.name] = self.kernel_for(layer).prepare(layer)
            elif layer.kind == "elementwise" and layer.constant is not None:
                if layer.constant.size not in (1, channels[layer.output]):
                    raise ModelError(f"{self.path}: node {layer.name!r}: constant of {layer.constant.size} "
                                     f"values for {channels[layer.output]} channels")
                self.prepared[layer.name] = self.kernels["elementwise"].prepare(layer, channels[layer.output])
        self._plans: dict[tuple[int, int], Plan] = {}
        self._networks: dict[tuple[int, int], NetworkPlan] = {}
        self._heads: dict[str, Head] = {}  # head layer name -> its weights, where one is folded (_exit_layers)

    def kernel_for(self, layer, tiling: str | None = None, uniform_windows: bool | None = None,
                   weight_fetch: str | None = None, math: str | None = None):
        """The kernel running ``layer`` under ``tiling``, window preference, weight fetch and math
        (defaults: the model's ``conv_tiling``, ``uniform_windows``, ``weight_fetch`` and ``math``);
        tilings that run a layer the same way share one kernel object. Weights staged in workgroup memory
        are multiplied in f32 whatever ``math`` says, and f16 multiply-adds read their weights directly."""
        tiling = tiling or self.conv_tiling
        windows = self.default_windows(layer) if uniform_windows is None else uniform_windows
        fetch = weight_fetch or self.weight_fetch
        args = (self.ctx, self.precision)
        if tiling in ("register", "staged", "staged-weights", "staged-narrow") and Conv3x3Kernel.handles(layer):
            fetch = "workgroup" if tiling == "staged-weights" else fetch
            half = (math or self.math) != "f32" and tiling != "staged-weights"
            accumulate = half and (math or self.math) == "f16-acc"
            fetch = "direct" if half else fetch   # see weights_uniform_f16.wgsl
            key, make = ("conv3x3", tiling, windows, fetch, half, accumulate), lambda: Conv3x3Kernel(
                *args, staged=tiling != "register", uniform_windows=windows, weight_fetch=fetch, half_math=half,
                narrow_tile=tiling == "staged-narrow", half_accumulate=accumulate)
        elif layer.kind in ("conv", "gemm"):
            kernel_class = ConvKernel if layer.kind == "conv" else GemmKernel
            key, make = (layer.kind, CONV_TILINGS[tiling], windows, fetch), lambda: kernel_class(
                *args, CONV_TILINGS[tiling], windows, fetch)
        elif layer.kind == "conv_transpose":
            key, make = (layer.kind, windows, fetch), lambda: ConvTransposeKernel(
                *args, uniform_windows=windows, weight_fetch=fetch)
        else:
            return self.kernels[layer.kind]
        if key not in self._tiled_kernels:
            self._tiled_kernels[key] = make()
        return self._tiled_kernels[key]

    def default_windows(self, layer) -> bool:
        """The model's window preference for ``layer``: ``uniform_windows``, except that transposed
        convolutions run as one dispatch everywhere. On lavapipe the denoiser's 128 → 64 upsampling at
        32² alone took the same CPU time as one dispatch reading storage (medians of 4 × 40 alternating
        runs: 4.6–6.0 ms) as in 16 per-group dispatches of uniform windows (4.3–5.9 ms); its other two
        fit one uniform binding anyway."""
        return self.uniform_windows and layer.kind != "conv_transpose"

    def packed(self, layer, kernel):
        """``layer``'s weights as ``kernel`` reads them (uploaded once per layer and kernel)."""
        if kernel is self.kernel_for(layer):
            return self.prepared[layer.name]
        key = (layer.name, id(kernel))
        if key not in self._packed_for:
            self._packed_for[key] = kernel.prepare(layer)
        return self._packed_for[key]

    def tuned_kernel(self, layer, src: TensorView, dst: TensorView, pooled: TensorView | None = None):
        """The kernel for ``layer`` reading ``src`` (and max-pooling its output into ``pooled``, if given):
        the model's tiling, window preference, weight fetch and math, or with autotuning the fastest
        combination measured on this adapter (cached per layer shape; see wgpu_rt.nn.autotune). Variants
        are named by tiling, plus UNIFORM_WINDOWS where uniform windows change how the layer is
        dispatched (kernels.WindowLayout), plus DIRECT_WEIGHTS where weights are read directly on an
        adapter with subgroups, plus HALF_MATH where a 3×3 kernel multiplies in f16 (fp16 models only)."""
        if self.autotuner is None:
            return self.kernel_for(layer)
        fetches = WEIGHT_FETCHES if self.ctx.has_subgroups else ("direct",)
        maths = ["f32"] + [m for m in MATHS[1:] if self.precision.storage == "f16" and half_math_agrees(self.ctx, m)]
        candidates, seen = {}, set()  # one variant per distinct kernel and dispatch layout
        for math in maths:
            for fetch in fetches:
                for tiling in CONV_TILINGS:
                    for windows in (False, True):
                        kernel = self.kernel_for(layer, tiling, windows, fetch, math)
                        layout = kernel.layout(layer)
                        distinct = (id(self.kernel_for(layer, tiling, False, fetch, math)), layout.one_dispatch,
                                    layout.weight_space)
                        if distinct not in seen:
                            seen.add(distinct)
                            candidates[self._variant(tiling, windows, kernel)] = self._trial(
                                layer, kernel, src, dst, pooled)
        default = self._variant(self.conv_tiling, self.default_windows(layer), self.kernel_for(layer))
        key = self.autotuner.key(layer, src, self.precision.name, pooled is not None)
        variant = self.autotuner.choose(key, candidates, default)
        fetch = "direct" if variant.endswith(DIRECT_WEIGHTS) or not self.ctx.has_subgroups else "subgroup"
        math = "f16-acc" if HALF_ACCUMULATE in variant else "f16" if HALF_MATH in variant else "f32"
        return self.kernel_for(layer, variant.split("+")[0], UNIFORM_WINDOWS in variant, fetch, math)

    def _variant(self, tiling: str, uniform_windows: bool, kernel) -> str:
        """An autotuned variant's name (see tuned_kernel): the tiling, window preference and ``kernel``'s
        weight fetch and math."""
        direct = kernel.weight_fetch == "direct" and self.ctx.has_subgroups
        return tiling + UNIFORM_WINDOWS * uniform_windows + kernel.math_label + DIRECT_WEIGHTS * direct

    def _trial(self, layer, kernel, src: TensorView, dst: TensorView, pooled: TensorView | None):
        """The dispatches of ``kernel`` on scratch tensors shaped like ``src``, ``dst`` (and ``pooled``),
        made when called."""

        def dispatches():
            def scratch(view: TensorView, split: bool = False) -> TensorView:
                size = view.blocks * view.height * view.width * self.precision.vec4_bytes
                buffer = self.ctx.storage(size, label="autotune scratch", windowed=True)
                return self._bound_view(buffer, 0, Shape(view.channels, view.height, view.width), split)
            extra = {"pooled": scratch(pooled)} if pooled is not None else {}
            return kernel.dispatches(layer, kernel.prepare(layer), scratch(src, kernel.reads_through_load_blocks),
                                     scratch(dst), **extra)
        return dispatches

    @property
    def input_channels(self) -> int:
        return self.graph.input_channels

    # -- planning -------------------------------------------------------------------------------------
    def plan(self, height: int, width: int) -> Plan:
        """The cached plan for height×width inputs."""
        key = (int(height), int(width))
        if key not in self._plans:
            self._plans[key] = self._build_plan(*key)
        return self._plans[key]

    def _canvas_shapes(self, height: int, width: int) -> tuple[tuple[int, int], dict[str, Shape]]:
        try:
            return (height, width), self.graph.infer_shapes(height, width)
        except ShapeMismatch as direct:
            multiple = self.graph.multiple
            canvas = (groups_of(height, multiple) * multiple, groups_of(width, multiple) * multiple)
            try:
                return canvas, self.graph.infer_shapes(*canvas)
            except ShapeMismatch as padded:
                raise ModelError(f"{self.path}: cannot run at {height}×{width} ({direct}; padded to "
                                 f"{canvas[0]}×{canvas[1]}: {padded})") from None

    def _root_bytes(self, shapes: dict[str, Shape]) -> dict[str, int]:
        """Bytes of every root tensor (a buffer-sharing unit: a concat and the inputs inside it)."""
        roots = {self.graph.placement(name)[0] for name in shapes}
        return {root: groups_of(shapes[root].channels, 4) * shapes[root].height * shapes[root].width
                * self.precision.vec4_bytes for root in roots}

    def _build_plan(self, height: int, width: int) -> Plan:
        canvas, shapes = self._canvas_shapes(height, width)
        out_shape = shapes[self.graph.output_name]
        crop = (out_shape.channels, out_shape.height * height // canvas[0], out_shape.width * width // canvas[1])
        bands = [Band(0, height, 0, crop[1])]
        try:
            network = self._network_plan(canvas, shapes)
        except _BandsNeeded:
            limit = self.ctx.binding_limit
            largest = max(self._root_bytes(shapes).values())
            # A conv reads a tensor wider than one binding through two windows (_bound_view), so bands sized
            # for half the largest activation in one binding mostly run; where they do not, bands for all of it.
            for share in (2, 1):
                bands, rows = self._bands(height, canvas[0], largest / share, limit, out_shape)
                try:
                    network = self._network_plan(*self._canvas_shapes(rows, width))
                    break
                except _BandsNeeded:
                    if share == 1:
                        raise
        flops = sum(layer.flops_per_pixel * shapes[layer.output].height * shapes[layer.output].width
                    for layer in self.graph.layers)
        return Plan(height, width, crop, network, bands, flops)

    def _fitting_rows(self, canvas_rows: int, largest: float, limit: int) -> int:
        """The rows (a multiple of the pooling multiple) of a band whose largest activation, ``largest``
        bytes on a canvas ``canvas_rows`` high, takes at most 95 % of ``limit``."""
        multiple = self.graph.multiple
        return int(limit * 0.95 * canvas_rows / largest) // multiple * multiple

    def rows_in_one_pass(self, width: int) -> int:
        """About the most rows of a frame ``width`` pixels wide that the network runs in one pass, without
        bands of its own (the first size its bands try), for a caller that cuts a frame into bands itself."""
        rows = 64 * self.graph.multiple   # activations grow with the rows, so any height gives the ratio
        canvas, shapes = self._canvas_shapes(rows, width)
        limit = self.ctx.binding_limit
        return self._fitting_rows(canvas[0], max(self._root_bytes(shapes).values()) / 2, limit)

    def _bands(self, height: int, canvas_rows: int, largest: float, limit: int, out_shape: Shape):
        """Split a frame whose largest activation exceeds one storage binding into bands of rows that
        fit, each with ``receptive_radius`` rows of context above and below (rounded up to the pooling
        multiple so the pooling grid stays aligned): the kept rows then equal the whole-frame result."""
        multiple = self.graph.multiple
        if out_shape.height != canvas_rows:
            raise DeviceLimitError(f"{self.path}: a {largest / 2**20:.0f} MiB activation exceeds this "
                                   f"device's {limit / 2**20:.0f} MiB storage binding, and a network whose "
                                   "output is resized cannot be split into bands")
        halo = groups_of(self.graph.receptive_radius, multiple) * multiple
        fitting_rows = self._fitting_rows(canvas_rows, largest, limit)
        if fitting_rows - 2 * halo < multiple:
            raise DeviceLimitError(f"{self.path}: even a band of {fitting_rows} rows leaves no room inside "
                                   f"the {limit / 2**20:.0f} MiB storage binding limit ({halo} rows of context)")
        count = groups_of(height, fitting_rows - 2 * halo)  # fewest bands, then equal heights
        keep = groups_of(groups_of(height, count), multiple) * multiple
        rows = min(keep + 2 * halo, canvas_rows)
        bands = []
        for first in range(0, height, keep):
            # the last band ends where the whole-frame canvas ends, so the activations beyond the frame's
            # bottom are the same (none) as in one pass, not the network's response to zero rows
            source = max(min(first - halo, canvas_rows - rows), 0)
            bands.append(Band(source, min(rows, height - source), first - source, min(keep, height - first)))
        return bands, rows

    def _exit_layer(self):
        """The layer that writes the planar output image itself (store_planar.wgsl in its epilogue, no
        unpack dispatch): the weighted layer producing the graph output, unless another layer reads that
        output, it lies inside a concat, or the layer's epilogue also pools; else None."""
        graph = self.graph
        producer = next((layer for layer in graph.layers if layer.output == graph.output_name), None)
        if (producer is None or producer.weight is None or producer.name in graph.epilogue_pools
                or graph.placement(graph.output_name)[0] != graph.output_name
                or any(graph.output_name in layer.inputs for layer in graph.layers)):
            return None
        return producer

    def _exit_layers(self, shapes: dict[str, Shape]) -> tuple[Layer | None, Head | None]:
        """What runs at the exit and writes the image: (the exit layer, None), or (the conv before it,
        the exit layer as a Head in that conv's epilogue) where the kernel chosen for the conv takes it;
        (None, None) where unpack writes the image."""
        last = self._exit_layer()
        body = self.graph.head_body(last) if last is not None else None
        if body is not None:
            kernel = self.tuned_kernel(body, shape_view(shapes[body.inputs[0]]), shape_view(shapes[body.output]))
            if isinstance(kernel, Conv3x3Kernel) and kernel.takes_head(body, last):
                if last.name not in self._heads:
                    self._heads[last.name] = Head.upload(self.ctx, last)
                return body, self._heads[last.name]
        return last, None

    def _entry_layer(self, at_exit: list[Layer]) -> Layer | None:
        """The layer that reads the planar input image itself (load_planar.wgsl, no pack dispatch): the
        graph input's only reader, if it is a conv that does not also run at the exit; else None (pack).
        On lavapipe the denoiser with its first conv reading the image took the same CPU time as with
        pack + that conv (256², median of 40 alternating runs each: fp32 232.1 vs 232.6 ms, fp16 258.3
        vs 256.9 ms), with one dispatch and one canvas-sized buffer less; on a GPU it saves a round trip
        of the input through memory. In fp16 that conv reads the input unrounded (load_planar.wgsl)."""
        graph = self.graph
        readers = [layer for layer in graph.layers if graph.input_name in layer.inputs]
        if len(readers) != 1 or readers[0].kind != "conv" or any(readers[0] is layer for layer in at_exit):
            return None
        return readers[0]

    def _bound_view(self, buffer, block: int, shape: Shape, split: bool = False) -> TensorView:
        """The tensor of ``shape`` at ``block`` of ``buffer`` as a kernel binds it: the whole buffer where
        that fits one storage binding, else a window of just the tensor's blocks, or for a convolution's
        input (``split``) two windows where one is too large. Raises _BandsNeeded where the device cannot
        bind it so (a window over the limit, or one starting off the offset alignment)."""
        limit = self.ctx.limits["max-storage-buffer-binding-size"]
        if buffer.size <= limit:
            return TensorView(buffer, block, shape.channels, shape.height, shape.width)
        alignment = self.ctx.limits["min-storage-buffer-offset-alignment"]
        plane = shape.height * shape.width * self.precision.vec4_bytes
        blocks = groups_of(shape.channels, 4)

        def window(first: int, count: int) -> tuple:
            if count * plane > limit or first * plane % alignment:
                raise _BandsNeeded
            return buffer, first * plane, count * plane

        if blocks * plane <= limit or not split:
            return TensorView(window(block, blocks), 0, shape.channels, shape.height, shape.width)
        lower = min(blocks - 1, limit // plane)
        return TensorView(window(block, lower), 0, shape.channels, shape.height, shape.width,
                          upper=window(block + lower, blocks - lower), split_block=lower)

    def _network_plan(self, canvas: tuple[int, int], shapes: dict[str, Shape]) -> NetworkPlan:
        """Buffers (liveness-planned) and dispatches of the network on ``canvas``; cached per canvas."""
        if canvas in self._networks:
            return self._networks[canvas]
        graph = self.graph
        exit_layer, head = self._exit_layers(shapes)
        at_exit = [exit_layer, head.layer] if head else [exit_layer] if exit_layer else []
        entry_layer = self._entry_layer(at_exit)
        elsewhere = {id(layer) for layer in (*at_exit, entry_layer)}  # dispatched at the exit or entry
        # steps: 0 = entry, 1..n = layers, n+1 = exit; root -> [first write, last read]. A max pool
        # computed in its conv's epilogue is written at the conv's step; layers at the exit run there and
        # their outputs need no activation buffer, nor does the input where the entry layer reads the image.
        lifetime: dict[str, list[int]] = {}

        def touch(tensor: str, step: int) -> None:
            span = lifetime.setdefault(graph.placement(tensor)[0], [step, step])
            span[0], span[1] = min(span[0], step), max(span[1], step)

        exit_step = len(graph.layers) + 1
        touch(graph.input_name, 0)
        for step, layer in enumerate(graph.layers, start=1):
            if any(layer is other for other in (*at_exit, *graph.epilogue_adds.values())):
                continue  # (the entry layer runs at its own step; a folded Add at its producer's)
            touch(graph.stored_output(layer), step)
            for name in (*layer.inputs, *filter(None, [graph.residual(layer)])):
                touch(name, step)
            if layer.name in graph.epilogue_pools:
                touch(graph.epilogue_pools[layer.name].output, step)
        touch(exit_layer.inputs[0] if exit_layer else graph.output_name, exit_step)  # weighted: one input
        if entry_layer is not None:
            del lifetime[graph.input_name]
        root_bytes = self._root_bytes(shapes)

        pool: list[dict] = []
        assignment: dict[str, dict] = {}
        for root in sorted(lifetime, key=lambda r: (-root_bytes[r], lifetime[r][0])):
            first, last = lifetime[root]
            need = root_bytes[root]
            free = [b for b in pool if all(last < start or end < first for start, end in b["spans"])]
            fitting = [b for b in free if b["size"] >= need]
            if fitting:
                slot = min(fitting, key=lambda b: b["size"])
            elif free:
                slot = max(free, key=lambda b: b["size"])
            else:
                slot = {"size": 0, "spans": []}
                pool.append(slot)
            slot["size"] = max(slot["size"], need)
            slot["spans"].append((first, last))
            assignment[root] = slot
        if max(slot["size"] for slot in pool) > self.ctx.limits["max-buffer-size"]:
            raise _BandsNeeded
        for index, slot in enumerate(pool):
            slot["buffer"] = self.ctx.storage(slot["size"], label=f"nn activations {index}", windowed=True)

        def view(tensor: str, split: bool = False) -> TensorView:
            root, offset = graph.placement(tensor)
            return self._bound_view(assignment[root]["buffer"], offset // 4, shapes[tensor], split)

        def weighted(layer: Layer, src: TensorView | str, dst: TensorView, **modules):
            """``layer``'s dispatches reading ``src`` (a view, or the tensor's name) into ``dst``, its
            epilogue pool included, by the kernel chosen for it; ``modules``: the planar images it reads
            or writes, a head."""
            pooled = graph.epilogue_pools.get(layer.name)
            if pooled is not None:
                modules["pooled"] = view(pooled.output)
            if graph.residual(layer) is not None:
                modules["residual"] = view(graph.residual(layer))
            kernel = self.tuned_kernel(layer, shape_view(shapes[layer.inputs[0]]),
                                       shape_view(shapes[layer.output]), modules.get("pooled"))
            if isinstance(src, str):
                src = view(src, split=kernel.reads_through_load_blocks)
            return kernel.dispatches(layer, self.packed(layer, kernel), src, dst, **modules)

        dispatches = []
        for layer in graph.layers:
            if graph.in_epilogue(layer) or id(layer) in elsewhere:
                continue
            kernel = self.kernel_for(layer)
            if layer.kind == "concat":  # its inputs live inside it, but for those copied in
                offsets = np.cumsum([0] + [shapes[name].channels for name in layer.inputs])
                for name, offset in zip(layer.inputs, offsets):
                    if name in graph.concat_copies[layer.name]:
                        dispatches += kernel.dispatches(f"{layer.name} <- {name}", view(name),
                                                        view(layer.output), int(offset))
                continue
            dst = view(graph.stored_output(layer))
            if layer.weight is not None:
                dispatches += weighted(layer, layer.inputs[0], dst)
            elif layer.kind == "elementwise":
                dispatches += kernel.dispatches(layer, self.prepared.get(layer.name),
                                                [view(name) for name in layer.inputs], dst)
            else:
                dispatches += kernel.dispatches(layer, view(layer.inputs[0]), dst)

        input_shape, output_shape = shapes[graph.input_name], shapes[graph.output_name]
        if entry_layer is None:
            input_view = view(graph.input_name)

            def entry(buffer, image: ImageRows) -> list[Dispatch]:
                return self.kernels["pack"].dispatches(buffer, image, input_view)
        else:
            def entry(buffer, image: ImageRows) -> list[Dispatch]:
                return weighted(entry_layer, shape_view(input_shape, buffer), view(entry_layer.output),
                                input_image=image)
        if exit_layer is None:
            output_view = view(graph.output_name)

            def exit(buffer, image: ImageRows) -> list[Dispatch]:
                return self.kernels["unpack"].dispatches(output_view, buffer, image)
        else:
            extra = {"head": head} if head else {}

            def exit(buffer, image: ImageRows) -> list[Dispatch]:
                return weighted(exit_layer, exit_layer.inputs[0], shape_view(output_shape, buffer),
                                output_image=image, **extra)
        network = NetworkPlan(canvas, dispatches, entry, exit, peak_bytes=sum(slot["size"] for slot in pool),
                              unplanned_bytes=sum(root_bytes[root] for root in lifetime))
        self._networks[canvas] = network
        return network

    # -- running --------------------------------------------------------------------------------------
    def record(self, encoder, input_buffer, height: int, width: int, query_set=None):
        """Record the whole network into ``encoder``; ``input_buffer`` holds planar NCHW f32
        (C×height×width). Returns the planar f32 output buffer (owned by the model, reused per call).
        ``query_set``: time every dispatch (2 timestamps each, in ``dispatches(height, width)`` order)."""
        record_dispatches(encoder, self.dispatches(height, width, input_buffer), query_set)
        return self.plan(height, width).output_buffer

    def prepare(self, input_buffer, height: int, width: int) -> None:
        """Build what the first ``record`` at height×width from ``input_buffer`` would build on its way (the
        plan, its kernels and bind groups), so that recording is all that is left for a frame to do."""
        self.dispatches(height, width, input_buffer)

    def dispatches(self, height: int, width: int, input_buffer) -> list[Dispatch]:
        """Every dispatch of one inference: per pass of the ensemble and per band, entry conversion, the
        network, exit conversion."""
        plan = self.plan(height, width)
        if plan.output_buffer is None:
            plan.output_buffer = self.ctx.storage(4 * int(np.prod(plan.output_shape)), label="nn output")
        key = id(input_buffer)
        if key not in plan._passes:
            if len(plan._passes) >= 8:
                plan._passes.clear()
            plan._passes[key] = (input_buffer, [
                dispatch for transform in range(self.ensemble)
                for dispatch in self._pass(height, width, transform, input_buffer, plan.output_buffer)])
        return plan._passes[key][1]

    def _pass(self, height: int, width: int, transform: int, input_buffer, output_buffer) -> list[Dispatch]:
        """The dispatches of one pass of the ensemble: the network on the input seen under dihedral
        ``transform`` (kernels.dihedral_strides; 0: as stored), its output written back as stored, weighted
        1/ensemble and, but in the first pass, added to the passes before it. A turned image runs on the
        plan of its turned size."""
        rows, cols = (width, height) if transform % 2 else (height, width)
        seen = self.plan(rows, cols)
        weight = 1.0 / self.ensemble
        dispatches = []
        for band in seen.bands:
            dispatches += seen.network.entry(input_buffer, ImageRows(rows, cols, band.source_row, 0, band.valid_rows,
                                                                     transform))
            dispatches += seen.dispatches
            dispatches += seen.network.exit(output_buffer, ImageRows(
                *seen.output_shape[1:], band.source_row + band.keep_from, band.keep_from, band.keep_rows,
                transform, weight, accumulate=transform > 0))
        return dispatches

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Run on a numpy (N, C, H, W) or (C, H, W) array; returns float32 of the same rank."""
        x = np.asarray(x)
        if x.ndim not in (3, 4):
            raise ModelError(f"{self.path}: input must be (N, C, H, W) or (C, H, W), got shape {x.shape}")
        batch = x if x.ndim == 4 else x[None]
        if batch.shape[1] != self.input_channels:
            raise ModelError(f"{self.path}: input {self.graph.input_name!r} expects {self.input_channels} "
                             f"channels, got {batch.shape[1]} (shape {x.shape})")
        height, width = batch.shape[2:]
        plan = self.plan(height, width)
        if plan.input_buffer is None:
            plan.input_buffer = self.ctx.storage(4 * self.input_channels * height * width, label="nn input")
        outputs = []
        for image in batch:
            self.ctx.device.queue.write_buffer(plan.input_buffer, 0, np.ascontiguousarray(image, np.float32))
            encoder = self.ctx.device.create_command_encoder(label="wgpu-rt nn")
            output_buffer = self.record(encoder, plan.input_buffer, height, width)
            self.ctx.device.queue.submit([encoder.finish()])
            outputs.append(self.ctx.read(output_buffer, np.float32, plan.output_shape))
        result = np.stack(outputs)
        return result if x.ndim == 4 else result[0]

