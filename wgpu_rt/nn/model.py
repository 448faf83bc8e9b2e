"""``WgslModel``: an ONNX network run as WGSL compute kernels.

Weights are uploaded once, at load. Everything that depends on the resolution — shapes, the canvas
(H and W edge-padded up to the network's pooling multiple when the graph needs it, e.g. a U-Net at 37×53),
the activation buffers and the specialized pipelines — is planned once per resolution and cached.

Buffer planning: every tensor lives in its root's buffer (a concat's inputs live inside the concat);
a root is live from the first dispatch that writes it to the last that reads it; roots are packed
greedily into a pool of buffers (a free buffer is reused, smallest fit first, else grown, else a new
one). ``Plan.peak_bytes`` is the pool's total size, ``Plan.unplanned_bytes`` what one buffer per
tensor would take. A frame whose largest activation would not fit one storage binding (the U-Net at
1080p on lavapipe's 128 MiB) runs as bands of rows with receptive-field context, with the same result.

Numerics (both precisions): inputs are sanitized on entry (NaN → 0, ±Inf and out-of-range values →
± the largest finite value of the storage type) and every kernel clamps what it stores the same way, so
outputs are always finite: an all-zero input gives the network's response to zeros, huge inputs
saturate at ±3.4e38 (fp32) or ±65504 (fp16) instead of overflowing, and a NaN born inside a kernel
(Inf − Inf from saturated values) is stored as 0. Accumulation is always f32;
fp16 stores activations as f16 (relative error ≲ 1e-2 on the seed networks, see tests/test_nn_networks.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import DeviceLimitError, ModelError
from . import autotune as autotuning
from .graph import NetworkGraph, Shape, ShapeMismatch, load_graph
from .kernels import (PRECISIONS, Conv3x3Kernel, ConvKernel, ConvTransposeKernel, CopyChannelsKernel,
                      Dispatch, ElementwiseKernel, GemmKernel, MaxPoolKernel, PackKernel, ResizeKernel,
                      TensorView, UnpackKernel, groups_of, record_dispatches)

# conv_tiling -> pixels per invocation of the loop kernels (conv.wgsl, gemm.wgsl); "register" also runs
# 3×3 stride-1 convs with 16k output channels on conv3x3.wgsl's written-out 4×4 tile, "staged" on
# conv3x3_staged.wgsl's (the same tile, input staged in workgroup memory; see Conv3x3Kernel).
CONV_TILINGS = {"none": 1, "loop": 4, "register": 4, "staged": 4}
# suffix of an autotuned variant that prefers one dispatch per group of uniform windows (kernels.WindowLayout)
UNIFORM_WINDOWS = "+uniform-windows"


def default_conv_tiling(ctx) -> str:
    """"staged" on discrete GPUs (on-chip workgroup memory), else "register" (see Conv3x3Kernel)."""
    return "staged" if ctx.adapter.info.get("adapter_type") == "DiscreteGPU" else "register"


def default_uniform_windows(ctx) -> bool:
    """Whether conv-family layers whose weights exceed one uniform binding run as one dispatch per
    output-block group with that group's uniform windows (True) rather than as one dispatch reading
    storage (see kernels.PackedWeights). True on CPU adapters: on lavapipe a uniform load is a vector
    gather and a storage load a loop over the lanes, and one dispatch per layer has nothing to fill
    there (2 cores); GPUs take the single dispatch, which fills them at low resolution."""
    return ctx.adapter.info.get("adapter_type") == "CPU"


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
    """The network's dispatches and activation buffers for one canvas size."""

    canvas: tuple[int, int]
    dispatches: list[Dispatch]
    input_view: TensorView
    output_view: TensorView
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
    output_buffer: object
    flops: int  # of the whole frame in one pass (bands recompute their context rows on top of this)
    input_buffer: object = None  # staging for __call__
    _entries: dict = field(default_factory=dict)  # id(input buffer) -> (buffer, pack dispatches)
    _exits: list = field(default_factory=list)

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
        """The network's dispatches for one band (without entry/exit conversion)."""
        return self.network.dispatches



class WgslModel:
    """``WgslModel(path, precision="fp32"|"fp16")``: call on NCHW float32 numpy, or ``record`` on GPU
    buffers. ``conv_tiling`` exists for the benchmark's steps, the profiler and the tests: "none" (one
    output pixel per invocation), "loop" (4-pixel tiles in loops), "register" (plus the written-out 3×3
    tile kernel), "staged" (that tile with its input staged in workgroup memory); default:
    ``default_conv_tiling``.

    ``autotune``: choose the tiling (and window preference) per layer shape by timing the candidates on
    this adapter once and caching the choice (see ``wgpu_rt.nn.autotune``; True, or an ``Autotuner``).
    Off by default (the first run of a new shape pays for compiling and timing every candidate) unless
    $WGPU_RT_AUTOTUNE=1; $WGPU_RT_AUTOTUNE=0 turns it off everywhere. A ``conv_tiling`` given here wins
    over autotuning."""

    def __init__(self, path: str | Path, precision: str = "fp32", ctx=None, conv_tiling: str | None = None,
                 autotune: bool | autotuning.Autotuner | None = None):
        from ..gpu import get_context

        if precision not in PRECISIONS:
            raise ModelError(f"precision {precision!r}: choose one of {', '.join(PRECISIONS)}")
        self.ctx = ctx or get_context()
        given = isinstance(autotune, autotuning.Autotuner)
        self.autotuner = None
        if conv_tiling is None and autotuning.enabled(True if given else autotune):
            self.autotuner = autotune if given else autotuning.Autotuner(self.ctx)
        conv_tiling = conv_tiling or default_conv_tiling(self.ctx)
        if conv_tiling not in CONV_TILINGS:
            raise ModelError(f"conv_tiling {conv_tiling!r}: choose one of {', '.join(CONV_TILINGS)}")
        if precision == "fp16" and not self.ctx.has_f16:
            raise ModelError(f"precision fp16 needs the shader-f16 feature, which {self.ctx.label} lacks; "
                             "use fp32")
        self.path, self.precision = str(path), PRECISIONS[precision]
        self.graph: NetworkGraph = load_graph(path)
        self.conv_tiling = conv_tiling
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

    def kernel_for(self, layer, tiling: str | None = None, uniform_windows: bool | None = None):
        """The kernel running ``layer`` under ``tiling`` and window preference (defaults: the model's
        ``conv_tiling`` and ``uniform_windows``); tilings that run a layer the same way share one kernel
        object."""
        tiling = tiling or self.conv_tiling
        windows = self.uniform_windows if uniform_windows is None else uniform_windows
        args = (self.ctx, self.precision)
        if tiling in ("register", "staged") and Conv3x3Kernel.handles(layer):
            key, make = ("conv3x3", tiling, windows), lambda: Conv3x3Kernel(
                *args, staged=tiling == "staged", uniform_windows=windows)
        elif layer.kind in ("conv", "gemm"):
            kernel_class = ConvKernel if layer.kind == "conv" else GemmKernel
            key, make = (layer.kind, CONV_TILINGS[tiling], windows), lambda: kernel_class(
                *args, CONV_TILINGS[tiling], windows)
        elif layer.kind == "conv_transpose":
            key, make = (layer.kind, windows), lambda: ConvTransposeKernel(*args, uniform_windows=windows)
        else:
            return self.kernels[layer.kind]
        if key not in self._tiled_kernels:
            self._tiled_kernels[key] = make()
        return self._tiled_kernels[key]

    def packed(self, layer, kernel):
        """``layer``'s weights as ``kernel`` reads them (uploaded once per layer and kernel)."""
        if kernel is self.kernel_for(layer):
            return self.prepared[layer.name]
        key = (layer.name, id(kernel))
        if key not in self._packed_for:
            self._packed_for[key] = kernel.prepare(layer)
        return self._packed_for[key]

    def tuned_kernel(self, layer, src: TensorView, dst: TensorView):
        """The kernel for ``layer`` reading ``src``: the model's tiling and window preference, or with
        autotuning the fastest pair measured on this adapter (cached per layer shape; see
        wgpu_rt.nn.autotune). Variants are named by tiling, plus UNIFORM_WINDOWS where uniform windows
        change how the layer is dispatched (kernels.WindowLayout)."""
        if self.autotuner is None:
            return self.kernel_for(layer)
        candidates, seen = {}, set()  # one variant per distinct kernel and dispatch layout
        for tiling in CONV_TILINGS:
            for windows in (False, True):
                kernel = self.kernel_for(layer, tiling, windows)
                layout = kernel.layout(layer)
                distinct = (id(self.kernel_for(layer, tiling, False)), layout.one_dispatch, layout.weight_space)
                if distinct not in seen:
                    seen.add(distinct)
                    candidates[tiling + UNIFORM_WINDOWS * windows] = self._trial(layer, kernel, src, dst)
        default = self.conv_tiling + UNIFORM_WINDOWS * self.uniform_windows
        variant = self.autotuner.choose(self.autotuner.key(layer, src, self.precision.name), candidates, default)
        tiling, windows = variant.removesuffix(UNIFORM_WINDOWS), variant.endswith(UNIFORM_WINDOWS)
        return self.kernel_for(layer, tiling, windows)

    def _trial(self, layer, kernel, src: TensorView, dst: TensorView):
        """The dispatches of ``kernel`` on scratch tensors shaped like ``src`` and ``dst``, made when called."""

        def dispatches():
            def scratch(view: TensorView) -> TensorView:
                size = view.blocks * view.height * view.width * self.precision.vec4_bytes
                return TensorView(self.ctx.storage(size, label="autotune scratch"), 0, view.channels,
                                  view.height, view.width)
            return kernel.dispatches(layer, kernel.prepare(layer), scratch(src), scratch(dst))
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
        limit = min(self.ctx.limits["max-storage-buffer-binding-size"], self.ctx.limits["max-buffer-size"])
        largest = max(self._root_bytes(shapes).values())
        if largest <= limit:
            bands, rows = [Band(0, height, 0, crop[1])], height
        else:
            bands, rows = self._bands(height, canvas[0], largest, limit, out_shape)
        network = self._network_plan(*self._canvas_shapes(rows, width))
        output_buffer = self.ctx.storage(4 * int(np.prod(crop)), label="nn output")
        flops = sum(layer.flops_per_pixel * shapes[layer.output].height * shapes[layer.output].width
                    for layer in self.graph.layers)
        plan = Plan(height, width, crop, network, bands, output_buffer, flops)
        unpack = self.kernels["unpack"]
        for band in bands:
            plan._exits += unpack.dispatches(network.output_view, output_buffer, crop[1], crop[2],
                                             band.source_row + band.keep_from, band.keep_from, band.keep_rows)
        return plan

    def _bands(self, height: int, canvas_rows: int, largest: int, limit: int, out_shape: Shape):
        """Split a frame whose largest activation exceeds one storage binding into bands of rows that
        fit, each with ``receptive_radius`` rows of context above and below (rounded up to the pooling
        multiple so the pooling grid stays aligned): the kept rows then equal the whole-frame result."""
        multiple = self.graph.multiple
        if out_shape.height != canvas_rows:
            raise DeviceLimitError(f"{self.path}: a {largest / 2**20:.0f} MiB activation exceeds this "
                                   f"device's {limit / 2**20:.0f} MiB storage binding, and a network whose "
                                   "output is resized cannot be split into bands")
        halo = groups_of(self.graph.receptive_radius, multiple) * multiple
        fitting_rows = int(limit * 0.95 * canvas_rows / largest) // multiple * multiple
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

    def _network_plan(self, canvas: tuple[int, int], shapes: dict[str, Shape]) -> NetworkPlan:
        """Buffers (liveness-planned) and dispatches of the network on ``canvas``; cached per canvas."""
        if canvas in self._networks:
            return self._networks[canvas]
        graph = self.graph
        # steps: 0 = pack, 1..n = layers, n+1 = unpack; root -> [first write, last read]
        lifetime: dict[str, list[int]] = {}

        def touch(tensor: str, step: int) -> None:
            span = lifetime.setdefault(graph.placement(tensor)[0], [step, step])
            span[0], span[1] = min(span[0], step), max(span[1], step)

        touch(graph.input_name, 0)
        for step, layer in enumerate(graph.layers, start=1):
            touch(layer.output, step)
            for name in layer.inputs:
                touch(name, step)
        touch(graph.output_name, len(graph.layers) + 1)
        root_bytes = self._root_bytes(shapes)

        pool: list[dict] = []
        assignment: dict[str, dict] = {}
        for root in sorted(lifetime, key=lambda r: lifetime[r][0]):
            first, last = lifetime[root]
            need = root_bytes[root]
            free = [b for b in pool if b["free_after"] < first]
            fitting = [b for b in free if b["size"] >= need]
            if fitting:
                slot = min(fitting, key=lambda b: b["size"])
            elif free:
                slot = max(free, key=lambda b: b["size"])
            else:
                slot = {"size": 0, "free_after": -1}
                pool.append(slot)
            slot["size"], slot["free_after"] = max(slot["size"], need), last
            assignment[root] = slot
        for index, slot in enumerate(pool):
            slot["buffer"] = self.ctx.storage(slot["size"], label=f"nn activations {index}")

        def view(tensor: str) -> TensorView:
            root, offset = graph.placement(tensor)
            shape = shapes[tensor]
            return TensorView(assignment[root]["buffer"], offset // 4, shape.channels, shape.height, shape.width)

        dispatches = []
        for layer in graph.layers:
            kernel = self.kernel_for(layer)
            sources = [view(name) for name in layer.inputs]
            dst = view(layer.output)
            if layer.weight is not None:
                kernel = self.tuned_kernel(layer, sources[0], dst)
                dispatches += kernel.dispatches(layer, self.packed(layer, kernel), sources[0], dst)
            elif layer.kind == "elementwise":
                dispatches += kernel.dispatches(layer, self.prepared.get(layer.name), sources, dst)
            elif layer.kind == "concat":
                offsets = np.cumsum([0] + [s.channels for s in sources])
                for name, source, offset in zip(layer.inputs, sources, offsets):
                    if name in graph.concat_copies[layer.name]:
                        dispatches += kernel.dispatches(f"{layer.name} <- {name}", source, dst, int(offset))
            else:
                dispatches += kernel.dispatches(layer, sources[0], dst)
        network = NetworkPlan(canvas, dispatches, view(graph.input_name), view(graph.output_name),
                              peak_bytes=sum(slot["size"] for slot in pool),
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

    def dispatches(self, height: int, width: int, input_buffer) -> list[Dispatch]:
        """Every dispatch of one inference: per band, entry conversion, the network, exit conversion."""
        plan = self.plan(height, width)
        key = id(input_buffer)
        if key not in plan._entries:
            if len(plan._entries) >= 8:
                plan._entries.clear()
            pack, view = self.kernels["pack"], plan.network.input_view
            plan._entries[key] = (input_buffer, [
                pack.dispatches(input_buffer, height, width, band.source_row, band.valid_rows, view)[0]
                for band in plan.bands])
        entries = plan._entries[key][1]
        return [d for entry, exit in zip(entries, plan._exits) for d in (entry, *plan.dispatches, exit)]

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

