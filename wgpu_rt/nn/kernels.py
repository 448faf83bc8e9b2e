"""One class per nn_kernels shader: it declares the shader's bindings, specializes the WGSL to the
shapes of one layer at one resolution (every size is a constant of the pipeline, so loops have fixed
trip counts and index arithmetic folds) and returns the dispatches to record.

Internal layout: NC4HW4. A tensor of C channels is ceil(C/4) blocks; block b is an H×W plane of
vec4 holding channels 4b..4b+3 of each pixel. Why this layout: a single vec4 load fetches four input
channels of one pixel, which against a mat4x4 weight block (4 input × 4 output channels) feeds 16
multiply-adds, and a row of a block is contiguous, so a tile of adjacent pixels loads adjacent vec4s.
Planar NCHW would need four loads for the same four channels, and NHWC makes a channel slice (a concat
input) strided instead of a contiguous range of planes. Blocks also make concat free: an input that
starts on a 4-channel boundary is just a range of planes of the concatenated tensor. The pipeline's
planar NCHW f32 is converted on entry (load_planar.wgsl: in the first conv, or pack.wgsl) and exit
(store_planar.wgsl: in the last layer, or unpack.wgsl); the convolutions' input and output go through
swappable modules (load_blocks.wgsl / load_planar.wgsl, store_blocks.wgsl / store_planar.wgsl) and
their epilogues can max-pool the output (pool_epilogue.wgsl) or run a 1×1 head (head_epilogue.wgsl):
see ConvFamilyKernel.modules and model.WgslModel for when.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import wgpu

from .. import shaders
from ..errors import DeviceLimitError
from .graph import FLOAT_MAX, NO_ACTIVATION, Activation, Layer

UNIFORM_WINDOW_LIMIT = 65536  # bytes; larger weight windows are bound as read-only storage


@dataclass(frozen=True)
class Precision:
    """Storage type of activations. Math and accumulation are f32 in both precisions: f16 storage halves
    activation memory and traffic, while f16 accumulation over up to 9·128 terms would break the 1e-2
    bound (and lavapipe, on AVX2, has no f16 ALU to gain from). The one exception is asked for: with f16
    activations the 3×3 tile kernels can sum each kernel row's 12 products per output in f16 before
    adding them to the f32 tile (Conv3x3Kernel's ``half_math``). Max pooling, resizing and copies move
    storage values without converting."""

    name: str
    storage: str
    vec4_bytes: int
    storage_max: float
    enable: str


FP32 = Precision("fp32", "f32", 16, FLOAT_MAX, "")
FP16 = Precision("fp16", "f16", 8, 65504.0, "enable f16;")
PRECISIONS = {"fp32": FP32, "fp16": FP16}


@dataclass
class TensorView:
    """A tensor inside an activation buffer: ``channels`` channels starting at block ``block``.
    ``buffer`` is what a kernel binds: a buffer, or a window (buffer, offset, size) of one too large for a
    single storage binding (``block`` then counts from the window's start). A convolution's input too
    large for one window is two: its blocks from ``split_block`` on are read through ``upper``
    (load_blocks_split.wgsl)."""

    buffer: object
    block: int
    channels: int
    height: int
    width: int
    upper: tuple | None = None
    split_block: int = 0

    @property
    def blocks(self) -> int:
        return math.ceil(self.channels / 4)


def dihedral_strides(transform: int, height: int, width: int) -> tuple[int, int, int]:
    """Where pixel (r, c) of an image seen under dihedral ``transform`` lies in the stored image: at
    flat index ``origin + r · row_stride + c · col_stride`` of each channel plane, returned as
    (row_stride, col_stride, origin). ``height`` × ``width`` is the image as seen (the stored one is
    width × height for odd transforms). Transform t is ``np.rot90(image, t % 4)``, mirrored left to
    right for t ≥ 4: the 8 flips and 90° turns the networks are trained under."""
    turns, mirrored = transform % 4, transform >= 4
    stored_width = height if turns % 2 else width

    def stored_pixel(r: int, c: int) -> int:
        rows, cols = height, width
        if mirrored:
            c = cols - 1 - c
        for _ in range(turns):  # np.rot90 of a rows × cols array B gave A: A[i, j] = B[j, rows - 1 - i]
            r, c, rows, cols = c, rows - 1 - r, cols, rows
        return r * stored_width + c

    origin = stored_pixel(0, 0)
    return stored_pixel(1, 0) - origin, stored_pixel(0, 1) - origin, origin


@dataclass(frozen=True)
class ImageRows:
    """Where a canvas of one pass of the network lies in a planar NCHW f32 image ``height`` × ``width``:
    canvas rows ``from_row`` .. ``from_row + rows - 1`` (their first ``width`` columns) are image rows
    ``first_row`` onwards (the whole image, or a band's kept rows; see model.Band). The image is seen
    under dihedral ``transform`` (see dihedral_strides; ``height`` × ``width`` as seen). An output image
    is written scaled by ``weight``, and with ``accumulate`` added to what it holds (an ensemble's passes)."""

    height: int
    width: int
    first_row: int
    from_row: int
    rows: int
    transform: int = 0
    weight: float = 1.0
    accumulate: bool = False

    def _layout(self, channels: int) -> dict:
        row_stride, col_stride, origin = dihedral_strides(self.transform, self.height, self.width)
        return {"CHANNELS": channels, "IMAGE_H": self.height, "IMAGE_W": self.width, "ROW_STRIDE": row_stride,
                "COL_STRIDE": col_stride, "ORIGIN": origin}

    def store_constants(self, channels: int) -> dict:
        """store_planar.wgsl's substitutions for an image of ``channels`` channels."""
        return {**self._layout(channels), "OUT_ROW0": self.first_row, "ROW_FROM": self.from_row,
                "ROWS": self.rows, "WEIGHT": wgsl_float(self.weight),
                "ACCUMULATE": "true" if self.accumulate else "false"}

    def load_constants(self, channels: int) -> dict:
        """load_planar.wgsl's substitutions for an image of ``channels`` channels (the canvas starts at
        image row ``first_row``: ``from_row`` is 0)."""
        return {**self._layout(channels), "IN_ROW0": self.first_row, "ROWS": self.rows}


@dataclass
class Dispatch:
    """One recorded compute dispatch. ``kernel`` (the shader), ``output`` (C, H, W of what this dispatch
    writes) and ``flops`` (multiply-adds ×2) describe it for the benchmark and the profiler."""

    label: str
    pipeline: object
    bind_group: object
    workgroups: tuple[int, int, int]
    kernel: str
    output: tuple[int, int, int]
    flops: int = 0


def record_dispatches(encoder, dispatches: list[Dispatch], query_set=None) -> None:
    """Record ``dispatches`` in order into one compute pass of ``encoder``. With a timestamp
    ``query_set`` (2 queries per dispatch) each dispatch gets its own timed pass instead (profiling)."""
    if query_set is None:
        compute = encoder.begin_compute_pass(label="wgpu-rt nn")
    for index, dispatch in enumerate(dispatches):
        if query_set is not None:
            compute = encoder.begin_compute_pass(label=dispatch.label, timestamp_writes={
                "query_set": query_set, "beginning_of_pass_write_index": 2 * index,
                "end_of_pass_write_index": 2 * index + 1})
        compute.set_pipeline(dispatch.pipeline)
        compute.set_bind_group(0, dispatch.bind_group)
        compute.dispatch_workgroups(*dispatch.workgroups)
        if query_set is not None:
            compute.end()
    if query_set is None:
        compute.end()


def wgsl_float(value: float) -> str:
    """A WGSL float literal (Python's repr always has a '.' or an exponent; infinities are clamped)."""
    return repr(float(np.clip(value, -FLOAT_MAX, FLOAT_MAX)))


def groups_of(count: int, size: int) -> int:
    return (count + size - 1) // size


def subgroup_lanes(ctx) -> int:
    """The subgroup width kernels may rely on: the smallest the context's probe saw
    (GpuContext.subgroup_sizes; lavapipe: 8, one AVX2 register). A driver may pick the width per
    pipeline; the answer only decides between the 4-lane and the ≥ 8-lane weight fetch
    (weights_subgroup.wgsl), which assumes that an adapter running the probe on ≥ 8 lanes never runs a
    kernel on 4 (true of the documented widths: Intel 8–32, AMD 32/64, NVIDIA and Apple 32)."""
    return max(4, int(ctx.subgroup_sizes.min()))


class NnKernel:
    """Base: ``shader`` names the .wgsl file, ``bindings`` its bind group 0 in binding order."""

    shader: str = ""
    bindings: tuple[str, ...] = ()

    def __init__(self, ctx, precision: Precision):
        self.ctx, self.precision = ctx, precision
        self.subgroup_lanes = subgroup_lanes(ctx) if ctx.has_subgroups else None

    def pipeline(self, activation: Activation = NO_ACTIVATION, replacements: dict | None = None, **constants):
        """The shader specialized by ``constants``; ``replacements`` swaps imported modules (see
        shaders.compose)."""
        substitutions = {"ENABLE_F16": self.precision.enable, "STORAGE": self.precision.storage,
                         "STORAGE_MAX": wgsl_float(self.precision.storage_max),
                         "ACTIVATION": activation.kind, "ALPHA": wgsl_float(activation.alpha),
                         "CLIP_LO": wgsl_float(activation.lo), "CLIP_HI": wgsl_float(activation.hi),
                         **constants}
        code = shaders.compose(self.shader, shaders.NN_KERNELS, substitutions, replacements)
        return self.ctx.compute_pipeline(code, label=self.shader)

    def bind(self, pipeline, resources: dict) -> object:
        """A bind group from ``resources`` (binding name -> buffer or (buffer, offset, size)); names the
        pipeline does not use (dropped by the auto layout) are skipped."""
        entries = []
        layout = pipeline.get_bind_group_layout(0)
        for index, name in enumerate(self.bindings):
            resource = resources.get(name)
            if resource is None:
                continue
            buffer, offset, size = resource if isinstance(resource, tuple) else (resource, 0, resource.size)
            entries.append({"binding": index, "resource": {"buffer": buffer, "offset": offset, "size": size}})
        return self.ctx.device.create_bind_group(layout=layout, entries=entries)


# Binding names of a group's windows (see PackedWeights); conv3x3's pair windows use all four.
WINDOW_BINDINGS = ("weights", "pair1_weights", "pair2_weights", "pair3_weights")
# weight fetch -> (its weight-block function, the WeightLane it takes); see ConvFamilyKernel.weight_constants
WEIGHT_FETCH_CODE = {"subgroup": ("weights_subgroup.wgsl", "weight_lane_subgroup.wgsl"),
                     "direct": ("weights_uniform.wgsl", "weight_lane_invocation.wgsl"),
                     "workgroup": ("weights_workgroup.wgsl", "weight_lane_invocation.wgsl")}


class WindowLayout:
    """How a conv-family layer's weights are cut into windows per output-block group and bound (sizes
    only; PackedWeights uploads them).

    Window g holds, for each input block, tap and output block t of the group, a mat4x4 whose column j
    is the 4 output channels' weights for input channel j; the group's header holds its bias and its
    first output block (relative to the output tensor, the view's block is added per plan). With
    ``splits=k`` a group's output blocks are split evenly over k windows, so conv3x3's groups of 4 or 8
    blocks over 128 input channels (73 or 147 KiB) still fit 64 KiB uniform bindings, one per pair of
    output blocks (a uniform load is the fast one on lavapipe, see weights_subgroup.wgsl).

    ``one_dispatch``: the layer runs as one dispatch with the group in workgroup_id.z, all windows in one
    binding (layer_bindings.wgsl), so that a low-resolution layer fills a GPU with G× the workgroups of
    one group. It is chosen where all windows fit one uniform binding, or one storage binding unless
    ``uniform_windows`` prefers per-group dispatches of uniform windows to one dispatch of storage
    (lavapipe: model.default_uniform_windows, or measured: wgpu_rt.nn.autotune); a layer too big for
    one storage binding always falls back to one dispatch per group, its windows bound one by one
    (uniform when each fits, else storage), and so does one with more groups' headers than one uniform
    binding holds (over 2048 output blocks). ``half`` (blocks as mat4x4<f16>, see PackedWeights): always
    storage, whose layout takes matrices of 8-byte columns on every Vulkan driver (a uniform block needs
    16-byte columns unless the driver has the standard uniform layout)."""

    def __init__(self, ctx, layer: Layer, tile_c: int, splits: int = 1, uniform_windows: bool = False,
                 half: bool = False):
        cout, cin, kh, kw = layer.weight.shape
        self.half = half
        self.out_blocks, self.in_blocks = groups_of(cout, 4), groups_of(cin, 4)
        self.tile_c = max(t for t in range(1, tile_c + 1) if self.out_blocks % t == 0)
        self.groups = self.out_blocks // self.tile_c
        self.splits = splits
        self.taps = kh * kw
        self.mats = self.in_blocks * self.taps * self.tile_c // splits
        window_bytes, limits = self.mats * 64, ctx.limits
        uniform_limit = min(UNIFORM_WINDOW_LIMIT, limits.get("max-uniform-buffer-binding-size", UNIFORM_WINDOW_LIMIT))
        header_limit = uniform_limit   # the group headers are f32: uniform either way
        uniform_limit = 0 if half else uniform_limit
        storage_limit = limits.get("max-storage-buffer-binding-size", 2**27)
        layer_bytes = window_bytes * self.groups * splits  # windows back to back: one binding
        headers_fit = self.groups * (16 * self.tile_c + 16) <= header_limit  # all GroupHeaders, one binding
        self.one_dispatch = headers_fit and (layer_bytes <= uniform_limit or (
            layer_bytes <= storage_limit and not (uniform_windows and window_bytes <= uniform_limit)))
        fits_uniform = (layer_bytes if self.one_dispatch else window_bytes) <= uniform_limit
        self.weight_space = "uniform" if fits_uniform else "storage, read"
        alignment = 64 if self.one_dispatch else limits.get(
            "min-uniform-buffer-offset-alignment" if fits_uniform else "min-storage-buffer-offset-alignment", 256)
        self.window_bytes, self.window_stride = window_bytes, -(-window_bytes // alignment) * alignment
        self.window_mats = self.window_stride // 64
        self.buffer_mats = self.groups * splits * self.window_mats


class PackedWeights(WindowLayout):
    """A conv-family layer's weights, uploaded once, in the windows of its WindowLayout; with ``half``
    each block's 16 values as halves in the first 32 bytes of its 64-byte slot (the layout stays the f32
    one; a half-precision kernel reads only what it multiplies)."""

    def __init__(self, ctx, layer: Layer, tile_c: int, splits: int = 1, uniform_windows: bool = False,
                 half: bool = False):
        super().__init__(ctx, layer, tile_c, splits, uniform_windows, half)
        cout, cin, kh, kw = layer.weight.shape
        padded = np.zeros((self.out_blocks * 4, self.in_blocks * 4, kh, kw), np.float32)
        padded[:cout, :cin] = layer.weight
        blocks = padded.reshape(self.groups, splits, self.tile_c // splits, 4, self.in_blocks, 4, kh, kw)
        windows = blocks.transpose(0, 1, 4, 6, 7, 2, 5, 3).reshape(self.groups * splits, -1)
        data = np.zeros((self.groups * splits, self.window_stride // 4), np.float32)
        if half:   # slot = the block's 16 halves, then 32 bytes of padding
            halves = windows.reshape(len(windows), -1, 16).astype(np.float16)
            slots = np.zeros((len(windows), halves.shape[1], 32), np.float16)
            slots[:, :, :16] = halves
            windows = slots.reshape(len(windows), -1).view(np.float32)
        data[:, : windows.shape[1]] = windows
        self.buffer = ctx.upload(data, usage=wgpu.BufferUsage.UNIFORM, label=f"{layer.name} weights")
        bias = np.zeros(self.out_blocks * 4, np.float32)
        bias[:cout] = layer.bias
        self.header_bytes = 16 * self.tile_c + 16  # GroupHeader's size, and its stride in an array
        header_alignment = 16 if self.one_dispatch else ctx.limits.get("min-uniform-buffer-offset-alignment", 256)
        self.header_stride = -(-self.header_bytes // header_alignment) * header_alignment
        self.bias = bias.reshape(self.groups, self.tile_c * 4)
        self.ctx, self.label = ctx, layer.name
        self._headers: dict[int, object] = {}

    def headers(self, out_block: int) -> object:
        """The header buffer for an output tensor starting at ``out_block`` (cached per offset)."""
        if out_block not in self._headers:
            data = np.zeros((self.groups, self.header_stride // 4), np.float32)
            data[:, : self.tile_c * 4] = self.bias
            data.view(np.int32)[:, self.tile_c * 4] = out_block + np.arange(self.groups) * self.tile_c
            self._headers[out_block] = self.ctx.device.create_buffer_with_data(
                data=data.tobytes(), usage=wgpu.BufferUsage.UNIFORM, label=f"{self.label} headers")
        return self._headers[out_block]

    def windows(self, group: int) -> dict:
        """Weight bindings of ``group``'s dispatch (of the layer's one dispatch: ``group`` is None)."""
        if group is None:
            return {WINDOW_BINDINGS[0]: self.buffer}
        return {name: (self.buffer, (group * self.splits + split) * self.window_stride, self.window_bytes)
                for split, name in enumerate(WINDOW_BINDINGS[: self.splits])}

    def header(self, out_block: int, group: int | None) -> tuple:
        """Header binding of ``group``'s dispatch (of the layer's one dispatch: ``group`` is None)."""
        if group is None:
            return self.headers(out_block)
        return (self.headers(out_block), group * self.header_stride, self.header_bytes)


class ConvFamilyKernel(NnKernel):
    """Shared by conv, gemm and conv_transpose: one dispatch per layer with the output-block group in
    workgroup_id.z, or one per group with its windows (see PackedWeights). Each can write the planar
    output image instead of an activation tensor (the network's last layer); the convolutions can also
    read the planar input image (the first layer) and max-pool their output in the epilogue (see
    ``modules``)."""

    bindings = ("src", "dst", "weights", "header", "pooled", "src_upper", "residual")
    tile_c_default = 1
    reads_through_load_blocks = False  # its shader reads the input via load_blocks.wgsl (can split it)

    stages_weights = False  # its shader can stage weight blocks in workgroup memory (weights_workgroup.wgsl)
    multiplies_in_half = False  # its shader can run its multiply-adds in f16 (conv3x3_tile.wgsl's MATH)
    half_accumulate = False     # its tile sums in f16 too (Conv3x3Kernel)

    def __init__(self, ctx, precision: Precision, tile_x: int, uniform_windows: bool = False,
                 weight_fetch: str | None = None, half_math: bool = False):
        super().__init__(ctx, precision)
        self.tile_x, self.uniform_windows, self.half_math = tile_x, uniform_windows, half_math
        if half_math and not (self.multiplies_in_half and precision.storage == "f16"):
            raise ValueError(f"{self.shader} cannot multiply in f16 with {precision.storage} activations")
        self.weight_fetch = weight_fetch or ("subgroup" if ctx.has_subgroups else "direct")
        if self.weight_fetch == "subgroup" and not ctx.has_subgroups:
            raise DeviceLimitError(f"weights fetched by subgroups need the subgroup feature, which {ctx.label} lacks")
        if (self.weight_fetch not in WEIGHT_FETCH_CODE
                or (self.weight_fetch == "workgroup" and not self.stages_weights)):
            raise ValueError(f"{self.shader} cannot fetch weights by {self.weight_fetch!r}")
        if half_math and self.weight_fetch != "direct":
            raise ValueError(f"f16 multiply-adds read their weights directly, not by {self.weight_fetch!r}")

    @property
    def math_label(self) -> str:
        """The dispatch label's suffix for what its multiply-adds run in: none for f32."""
        return "+f16-acc" if self.half_accumulate else "+f16-math" if self.half_math else ""

    def weight_constants(self, packed: PackedWeights, names: tuple[str, ...] = ("weight",)) -> dict:
        """Substitutions of layer_bindings.wgsl choosing how conv-family kernels read ``packed``'s weight
        blocks (see weights_*.wgsl): window p of a group is read by ``{names[p]}_block(index, lane)``
        (``lane: WeightLane`` is a parameter of the kernels' entry points). One dispatch per layer binds
        every window as ``weights`` and each group starts at its ``weight_window``; one dispatch per group
        binds the group's windows, one binding each (WINDOW_BINDINGS). By ``weight_fetch``: each
        invocation reads a block itself ("direct": weights_uniform.wgsl), the lanes of a subgroup share
        its loads ("subgroup": weights_subgroup.wgsl), or the workgroup stages an input block's blocks
        in workgroup memory ("workgroup": weights_workgroup.wgsl, STAGED_MATS blocks a window); with
        ``half_math`` as halves, directly (weights_uniform_f16.wgsl: a mat4x4<f16> in each 64-byte slot)."""
        fetch, lane = WEIGHT_FETCH_CODE[self.weight_fetch]
        if self.half_math:   # always a direct fetch (see __init__)
            fetch = "weights_uniform_f16.wgsl"
        code = [shaders.compose(lane, shaders.NN_KERNELS, {"SUBGROUP_LANES": self.subgroup_lanes})]
        if self.weight_fetch == "workgroup":
            code.append(f"const STAGED_MATS: i32 = {packed.taps * packed.tile_c // packed.splits};")

        def binding(weights: str, index: int, mats: int) -> str:
            return shaders.compose("weight_binding.wgsl", shaders.NN_KERNELS, {
                "WEIGHT_SPACE": packed.weight_space, "WEIGHT_MATS": mats, "WEIGHTS": weights,
                "WEIGHT_SLOT": "array<mat4x4<f16>, 2>" if packed.half else "mat4x4f",
                "WEIGHT_BINDING": self.bindings.index(WINDOW_BINDINGS[index])})

        if packed.one_dispatch:
            code.append(binding("weights", 0, packed.buffer_mats))
        for split, name in enumerate(names):
            if packed.one_dispatch:
                weights, base = "weights", f"weight_window + {split * packed.window_mats}"
            else:
                weights, base = f"{name}s", "0"
                code.append(binding(weights, split, packed.mats))
            code.append(shaders.compose(fetch, shaders.NN_KERNELS,
                                        {"WEIGHT": name, "WEIGHTS": weights, "WINDOW_BASE": base}))
        return {"WEIGHT_FETCH": "\n".join(code), "GROUPS": packed.groups if packed.one_dispatch else 1,
                "GROUP_MATS": packed.splits * packed.window_mats if packed.one_dispatch else 0}

    def packing(self, layer: Layer) -> tuple[int, int]:
        """(output blocks per group, windows per group) of ``layer``'s weights for this kernel."""
        return self.tile_c_default, 1

    def layout(self, layer: Layer) -> WindowLayout:
        return WindowLayout(self.ctx, layer, *self.packing(layer), uniform_windows=self.uniform_windows,
                            half=self.half_math)

    def prepare(self, layer: Layer) -> PackedWeights:
        return PackedWeights(self.ctx, layer, *self.packing(layer), uniform_windows=self.uniform_windows,
                             half=self.half_math)

    def modules(self, src: TensorView, dst: TensorView, pooled: TensorView | None = None,
                input_image: ImageRows | None = None, output_image: ImageRows | None = None) -> tuple[dict, dict]:
        """(substitutions, module replacements) choosing where the input comes from and where the
        output goes: NC4HW4 tensors (load_blocks.wgsl, store_blocks.wgsl) or, with ``input_image``, the
        planar input image (load_planar.wgsl: ``src`` is then the image buffer) and, with
        ``output_image``, the planar output image (store_planar.wgsl: ``dst`` likewise); with
        ``pooled`` the epilogue writes the output's 2×2 max pool too (pool_epilogue.wgsl, else
        pool_epilogue_none.wgsl); an input split over two bindings (TensorView.upper) is read through
        load_blocks_split.wgsl."""
        substitutions, replacements = {}, {}
        if src.upper is not None:
            if not self.reads_through_load_blocks or input_image is not None:
                raise ValueError(f"{self.shader} cannot read an input split over two bindings")
            substitutions.update(IN_SPLIT=src.split_block, UPPER_BINDING=self.bindings.index("src_upper"))
            replacements["load_blocks.wgsl"] = "load_blocks_split.wgsl"
        if input_image is not None:
            substitutions.update(input_image.load_constants(src.channels))
            replacements["load_blocks.wgsl"] = "load_planar.wgsl"
        if output_image is not None:
            substitutions.update(output_image.store_constants(dst.channels))
            replacements["store_blocks.wgsl"] = "store_planar.wgsl"
        if pooled is None:
            replacements["pool_epilogue.wgsl"] = "pool_epilogue_none.wgsl"
        else:
            substitutions.update(POOL_BINDING=self.bindings.index("pooled"),
                                 POOL_BLOCK_SHIFT=pooled.block - dst.block)
        return substitutions, replacements

    @staticmethod
    def kernel_label(kernel: str, pooled: TensorView | None = None, input_image: ImageRows | None = None,
              output_image: ImageRows | None = None, head: bool = False) -> str:
        """A dispatch's kernel label: the shader plus what it does besides reading and storing tensors."""
        return (("pack+" if input_image is not None else "") + kernel + ("+maxpool" if pooled is not None else "")
                + ("+head" if head else "") + ("+unpack" if output_image is not None else ""))

    def grouped(self, layer, packed, pipeline, src, dst, workgroups, flops, kernel=None,
                pooled: TensorView | None = None, head=None, residual: TensorView | None = None) -> list[Dispatch]:
        """The layer's dispatches over ``workgroups`` (x, y) per group: one with the groups in z, or one
        per group, each with the share of ``flops`` of the real (unpadded) channels it writes, so the
        dispatches add up to the layer's FLOPs exactly. ``kernel``: the label (default: the shader;
        "+direct-weights" is added where weights are read directly on an adapter with subgroups,
        "+staged-weights" where they are staged in workgroup memory);
        ``pooled``, ``head`` (kernels.Head) and ``residual``: bound where the epilogue writes or reads them."""
        channels = dst.channels
        fetch_label = {"subgroup": "", "workgroup": "+staged-weights",
                       "direct": "+direct-weights" if self.ctx.has_subgroups else ""}[self.weight_fetch]
        kernel = (kernel or self.shader) + fetch_label
        kernel += self.math_label
        tensors = {"src": src.buffer, "dst": dst.buffer, **({"pooled": pooled.buffer} if pooled else {}),
                   **({"head": head.buffer} if head else {}), **({"src_upper": src.upper} if src.upper else {}),
                   **({"residual": residual.buffer} if residual else {})}
        label = layer.name + (f" + {head.layer.name}" if head else "")
        if packed.one_dispatch:
            resources = {**tensors, **packed.windows(None), "header": packed.header(dst.block, None)}
            return [Dispatch(label, pipeline, self.bind(pipeline, resources), (*workgroups, packed.groups),
                             kernel, (channels, dst.height, dst.width), flops)]
        dispatches = []
        for g in range(packed.groups):
            first = g * packed.tile_c * 4
            written = min(channels, first + packed.tile_c * 4) - first
            dispatches.append(Dispatch(
                f"{label}[{g}]", pipeline,
                self.bind(pipeline, {**tensors, **packed.windows(g), "header": packed.header(dst.block, g)}),
                (*workgroups, 1), kernel, (written, dst.height, dst.width), flops * written // channels))
        return dispatches


class ConvKernel(ConvFamilyKernel):
    """conv.wgsl: k×k convolution, stride 1–2, zero padding, fused bias + activation."""

    shader = "conv.wgsl"
    reads_through_load_blocks = True

    def dispatches(self, layer: Layer, packed: PackedWeights, src: TensorView, dst: TensorView, *,
                   pooled: TensorView | None = None, input_image: ImageRows | None = None,
                   output_image: ImageRows | None = None):
        """``pooled``, ``input_image``, ``output_image``: see ConvFamilyKernel.modules."""
        _, _, kh, kw = layer.weight.shape
        top, left, _, _ = layer.pads
        modules, replacements = self.modules(src, dst, pooled, input_image, output_image)
        pipeline = self.pipeline(
            layer.activation, replacements, IN_H=src.height, IN_W=src.width, IN_BLOCK=src.block,
            IN_BLOCKS=packed.in_blocks, OUT_H=dst.height, OUT_W=dst.width, KH=kh, KW=kw, STRIDE=layer.stride,
            PAD_TOP=top, PAD_LEFT=left, TILE_X=self.tile_x, TILE_C=packed.tile_c, **modules,
            **self.weight_constants(packed))
        workgroups = (groups_of(groups_of(dst.width, self.tile_x), 8), groups_of(dst.height, 8))  # 8×8 tiles
        flops = layer.flops_per_pixel * dst.height * dst.width
        return self.grouped(layer, packed, pipeline, src, dst, workgroups, flops,
                            self.kernel_label(self.shader, pooled, input_image, output_image), pooled)


def tile_blocks_code(blocks: int, head: bool = False, half: bool = False,
                     half_accumulate: bool = False) -> dict[str, str]:
    """conv3x3_tile_blocks.wgsl's placeholders for a tile of ``blocks`` output blocks, written out (one
    template instead of a hand-unrolled file per width; the code is the same as written out by hand).
    ``head``: the tile's pixels go through head_epilogue.wgsl's 1×1 head instead of being stored;
    ``half``: a row's products are summed in f16 and the sum added to the f32 tile; with
    ``half_accumulate`` too, the tile itself is f16 (bias, sums and all), converted to f32 only to store."""
    def accumulate(t: int) -> str:
        pair, odd = divmod(t, 2)
        taps = [f"pair{pair}_weight_block(tap{f' + {odd + 2 * kx}' if odd + 2 * kx else ''}, lane) * x.x{kx}"
                for kx in range(3)]
        if half and not half_accumulate:
            return f"    (*tile).block{t} += mat4x4f({taps[0]} + {taps[1]}\n        + {taps[2]});"
        return f"    (*tile).block{t} += {taps[0]} + {taps[1]}\n        + {taps[2]};"

    def block(t: int) -> str:   # block t of the tile as f32
        return f"mat4x4f(tile.block{t})" if half_accumulate else f"tile.block{t}"

    return {"TILE_C": blocks,
            "TILE_FIELDS": "\n".join(f"    block{t}: {'mat4x4<f16>' if half_accumulate else 'mat4x4f'},"
                                     for t in range(blocks)),
            "TILE_BIAS": ", ".join(f"mat4x4<f16>(bias_pixels({t}))" if half_accumulate else f"bias_pixels({t})"
                                   for t in range(blocks)),
            "TILE_ACCUMULATE": "\n".join(accumulate(t) for t in range(blocks)),
            "TILE_STORE": head_store_code(blocks, block) if head
            else "\n".join(f"    store_pixels({t}, oy, ox0, {block(t)});" for t in range(blocks))}


def head_store_code(blocks: int, block=lambda t: f"tile.block{t}") -> str:
    """The tile's store with a head (head_epilogue.wgsl): its blocks' activations as named 4-pixel
    matrices (``block(t)``: tile block t as an f32 matrix in WGSL), then per head block the bias plus one
    matrix product per tile block, written out.
    Written out, the denoiser with its head folded takes the CPU time it takes with the head's own
    dispatch on lavapipe (256², median of 30 runs: 232.2 vs 231.6 ms); a per-pixel loop over an array of
    the tile's blocks instead took 1.3% more (loop-indexed arrays go to scratch memory)."""
    inputs = "\n".join(f"    let a{t} = head_input({block(t)});" for t in range(blocks))
    terms = " + ".join(f"head.blocks[w + {t}] * a{t}" if t else "head.blocks[w] * a0" for t in range(blocks))
    return (f"{inputs}\n    for (var k = 0; k < HEAD_BLOCKS; k++) {{\n        let w = k * TILE_C;\n"
            f"        store_head_pixels(k, oy, ox0, head_bias(k) + {terms});\n    }}")


@dataclass
class Head:
    """A 1×1 convolution without activation folded into a 3×3 convolution's epilogue (head_epilogue.wgsl):
    its layer and its weight blocks and bias, uploaded once as one uniform block."""

    layer: Layer
    buffer: object

    @classmethod
    def upload(cls, ctx, layer: Layer) -> Head:
        cout, cin = layer.weight.shape[:2]
        out_blocks, in_blocks = groups_of(cout, 4), groups_of(cin, 4)
        padded = np.zeros((out_blocks * 4, in_blocks * 4), np.float32)
        padded[:cout, :cin] = layer.weight[:, :, 0, 0]
        # block (k, t), column j, row i: weight of output channel 4k + i for input channel 4t + j
        blocks = padded.reshape(out_blocks, 4, in_blocks, 4).transpose(0, 2, 3, 1)
        bias = np.zeros(out_blocks * 4, np.float32)
        bias[:cout] = layer.bias
        data = np.concatenate([blocks.ravel(), bias])
        return cls(layer, ctx.upload(data, usage=wgpu.BufferUsage.UNIFORM, label=f"{layer.name} head"))

    @staticmethod
    def nbytes(layer: Layer) -> int:
        cout, cin = layer.weight.shape[:2]
        return groups_of(cout, 4) * (groups_of(cin, 4) * 64 + 16)


class Conv3x3Kernel(ConvFamilyKernel):
    """The hot path — 3×3 stride-1 convolutions whose output has a multiple of 8 channels, with a
    written-out register tile of 4 pixels × 16 or 32 channels per invocation (conv3x3_tile.wgsl), or 8
    where 16 do not divide the output (a narrow network's 8, 24 or 40 channels), in one of two variants
    that differ only in where the input pixels come from:

    * conv3x3.wgsl (``staged=False``) reads each invocation's 3 × 6 input pixels from device memory;
    * conv3x3_staged.wgsl (``staged=True``) first copies the workgroup's input tile and halo into
      workgroup memory (cooperative, coalesced loads and a barrier per input block) and reads them from
      there, cutting device-memory reads of the input ≈ 3.4× (1.33 instead of 4.5 per output pixel and
      input block).

    Staging pays where workgroup memory is on-chip and device memory is the bottleneck: discrete GPUs,
    where it is the engine's default (``default_conv_tiling``). On lavapipe (CPU) workgroup memory is
    ordinary memory that a load reads lane by lane exactly like a storage buffer, so staging only adds
    the copy and the barriers (coroutine switches): the U-Net takes ≈ 1.3× the CPU time with it there
    (benchmarks/bench_nn.py, steps reg-tiled and staged), so CPU adapters keep the direct variant, and
    so do integrated GPUs (their workgroup memory is on-chip too, but the trade is unmeasured there).
    Both variants are tested for parity whatever the adapter (tests/test_nn_ops.py).

    The staged variant can also stage each input block's weight blocks beside its pixels (``weight_fetch=
    "workgroup"``, conv tiling "staged-weights": weights_workgroup.wgsl), loaded once per workgroup
    instead of by (or shared between the lanes of) each subgroup, as tfjs and onnxruntime's WebGPU
    convolutions keep a weight tile in workgroup memory: a candidate for GPUs, where 16 subgroup
    broadcasts per weight block compete with the tile's 64 multiply-adds per lane for issue slots. On
    lavapipe it takes 2.6× the staged kernel's time (the shipped denoiser at 256²: 657 against 249 ms,
    `wgpu-rt profile --conv-tiling`).

    With f16 activations either variant can multiply in half precision (``half_math``, model math "f16"):
    a kernel row's three weight blocks (read directly as mat4x4<f16> from storage, weights_uniform_f16.wgsl)
    times its three 4-pixel matrices are summed in f16 — 12 products per output, where an adapter with packed f16
    arithmetic does two per instruction — and the sum is added to the f32 tile, so accumulation over
    input channels stays f32 (the shipped denoiser: max |error| 1.4e-3 against onnxruntime, f32 math
    with f16 storage 0.7e-3, the bound 1e-2). On lavapipe (no f16 ALU on AVX2) it takes 4–5× the time
    (751–794 against 147–197 ms at 256² with the register tiling); a candidate for GPUs.
    With ``half_accumulate`` as well (model math "f16-acc") the tile itself is f16: the bias, every row's
    sum and the sum over input channels (up to 9 · 128 products) stay in half precision, converted to f32
    only for the epilogue. It needs half the tile's registers (a 16-channel tile: 64 halves, 32 registers
    of packed pairs instead of 64) and no conversion per row step. What it costs the denoiser's images
    (`benchmarks/bench_half_math.py --size 256x256`, ten scenes, lavapipe): 70.7–83.6 dB from
    onnxruntime's (f16 math 75.4–87.7, f32 math 85.1–98.4), three orders of magnitude below the
    denoising error itself; random-input parity holds within the fp16 bound. A GPU candidate, not timed on
    one yet (the autotuner weighs it where ``half_math_agrees(ctx, "f16-acc")``).

    Tile width (``tile_blocks``, unrolled into conv3x3_tile_blocks.wgsl by ``tile_blocks_code``): 32
    channels in the direct variant wherever the output has a multiple of 32 channels, else 16. On
    lavapipe input loads are costly (a storage load is a scalar loop over the lanes; with them replaced by constants the
    16-channel tile runs 1.6× as fast), and the 32-channel tile does twice the multiply-adds per loaded
    pixel: on every 3×3 shape of the U-Net (3–32 input blocks, 128²–512²) it took 3–12% less CPU time
    in same-process A/Bs, the most at 16–32 input blocks, and no shape was slower; the whole U-Net ≈ 3%
    less (256² and 512²).
    Its price is compilation: ≈ 0.5 s instead of 0.25 s of CPU per pipeline on lavapipe. Where the input
    lies does not matter there: a layer runs at the same rate per CPU second at 128², 256² and 512²
    (inputs of 1–64 MiB), so ordering dispatches to keep input rows in cache has nothing to win. The
    staged variant keeps 16 channels: it already makes its input loads cheap (its adapters' workgroup
    memory is on-chip), and on a GPU 32 accumulator vec4s per invocation would cost occupancy (unmeasured:
    lavapipe is the only adapter here). What is left on lavapipe is mostly the weight fetch: with it
    replaced by 8 matrices fetched once before the loop, the 32-channel tile runs 2.2× as fast (2 gathers
    and 16 broadcasts per block against its 64 multiply-adds per lane; the 4-lane fetch is 14% slower,
    the direct one of weights_uniform.wgsl 1.9×).

    Tried on lavapipe and not kept (same-process A/B, CPU time): (1) the row steps written out in
    straight-line code with literal (cb, ky), so every weight offset is a constant outside any loop and the
    windows are read directly: 2.1× slower at 8 input blocks, no faster at 1, and pipeline compilation grows
    from 0.07 s to 3.4 s at 24 input blocks; (2) an 8-pixel × 16-channel tile (each weight block serves
    8 pixels, 10 loads per 8 pixels): 3% slower than 4 × 16 at 8 input blocks; (3) sharing the halo
    pixels between the 8 lanes of a row through subgroupShuffleUp/Down (5 loads per row step instead of
    6): within 1% (on lavapipe a shuffle is a per-lane loop too); (4) other workgroup shapes: 2 × 32
    tiles of 4 pixels no faster, 64 × 1 1.7× slower (idle lanes on the narrow layers); (5) f16 inputs
    read as packed vec2<u32> (half the scalar loads per pixel): 4% faster on one fp16 layer, not worth a
    second storage layout.

    With a ``head`` (a 1×1 conv without activation reading this layer's output, the network's last
    layer), the epilogue runs the head on the tile and stores its output instead (head_epilogue.wgsl),
    where one tile holds all the layer's output channels (``takes_head``: 8 or 16, or 32 in the direct
    variant): the denoiser's last 3×3 conv and its head are one dispatch."""

    bindings = ConvFamilyKernel.bindings + WINDOW_BINDINGS[1:] + ("head",)
    tile_x = 4
    reads_through_load_blocks = True

    multiplies_in_half = True

    def __init__(self, ctx, precision: Precision, staged: bool = False, uniform_windows: bool = False,
                 weight_fetch: str | None = None, half_math: bool = False, narrow_tile: bool = False,
                 half_accumulate: bool = False):
        """``narrow_tile``: 8 channels a tile on every layer (conv tiling "staged-narrow", see tile_blocks);
        ``half_accumulate`` (with ``half_math``): the tile is f16 as well (model math "f16-acc")."""
        if half_accumulate and not half_math:
            raise ValueError("an f16 tile needs f16 multiply-adds (half_math)")
        self.staged = self.stages_weights = staged
        self.narrow_tile, self.half_accumulate = narrow_tile, half_accumulate
        self.shader = "conv3x3_staged.wgsl" if staged else "conv3x3.wgsl"
        super().__init__(ctx, precision, self.tile_x, uniform_windows, weight_fetch, half_math)

    def tile_blocks(self, layer: Layer) -> int:
        """Output blocks per invocation: 8 (32 channels) in the direct variant where they divide the
        output's blocks, else 4 where they do, else 2. The 8-channel tile does half the multiply-adds per
        input pixel loaded, yet on an H200 the loop kernel (conv.wgsl), which took 8-, 12- and 24-channel
        layers before, ran them at 5.6 TFLOP/s against the 16-channel staged tile's 22–25 (BENCHMARKS.md
        §25). With ``narrow_tile`` always 2: twice the invocations of the 16-channel tile, for layers too
        small to fill a GPU (the autotuner's candidate "staged-narrow")."""
        blocks = groups_of(layer.weight.shape[0], 4)
        if self.narrow_tile:
            return 2
        if not self.staged and blocks % 8 == 0:
            return 8
        return 4 if blocks % 4 == 0 else 2

    def packing(self, layer: Layer) -> tuple[int, int]:
        """One window per pair of output blocks of a group (``pair{p}_weights`` in the shader)."""
        tile = self.tile_blocks(layer)
        return tile, tile // 2

    @staticmethod
    def handles(layer: Layer) -> bool:
        return (layer.kind == "conv" and layer.weight.shape[2:] == (3, 3) and layer.stride == 1
                and groups_of(layer.weight.shape[0], 4) % 2 == 0)

    def takes_head(self, layer: Layer, head: Layer) -> bool:
        """Whether ``head`` (a 1×1 conv reading ``layer``'s output) can run in ``layer``'s epilogue: one
        tile holds all of ``layer``'s output channels and the head's weights fit one uniform binding."""
        uniform_limit = min(UNIFORM_WINDOW_LIMIT, self.ctx.limits.get("max-uniform-buffer-binding-size",
                                                                      UNIFORM_WINDOW_LIMIT))
        return (self.tile_blocks(layer) == groups_of(layer.weight.shape[0], 4)
                and Head.nbytes(head) <= uniform_limit)

    def dispatches(self, layer: Layer, packed: PackedWeights, src: TensorView, dst: TensorView, *,
                   pooled: TensorView | None = None, input_image: ImageRows | None = None,
                   output_image: ImageRows | None = None, head: Head | None = None):
        """``pooled``, ``input_image``, ``output_image``: see ConvFamilyKernel.modules; ``head``: run it
        on the output in the epilogue (``dst`` is then the head's output; see takes_head)."""
        top, left, _, _ = layer.pads
        modules, replacements = self.modules(src, dst, pooled, input_image, output_image)
        label = self.kernel_label(f"{self.shader}+tile{4 * packed.tile_c}", pooled, input_image, output_image,
                           head is not None)
        flops = layer.flops_per_pixel * dst.height * dst.width
        if head is not None:
            replacements["head_epilogue_none.wgsl"] = "head_epilogue.wgsl"
            modules.update(HEAD_BLOCKS=groups_of(head.layer.weight.shape[0], 4),
                           HEAD_BINDING=self.bindings.index("head"))
            flops += head.layer.flops_per_pixel * dst.height * dst.width
        pipeline = self.pipeline(
            layer.activation, replacements,
            **tile_blocks_code(packed.tile_c, head is not None, self.half_math, self.half_accumulate),
            MATH="f16" if self.half_math else "f32",
            IN_H=src.height, IN_W=src.width, IN_BLOCK=src.block, IN_BLOCKS=packed.in_blocks,
            OUT_H=dst.height, OUT_W=dst.width, PAD_TOP=top, PAD_LEFT=left, **modules,
            STAGE_WEIGHTS="\n".join(f"        stage_pair{p}_weights(cb, invocation);" for p in range(packed.splits))
            if self.weight_fetch == "workgroup" else "",
            **self.weight_constants(packed, tuple(f"pair{p}_weight" for p in range(packed.splits))))
        workgroups = (groups_of(groups_of(dst.width, self.tile_x), 8), groups_of(dst.height, 8))  # 8×8 tiles
        return self.grouped(layer, packed, pipeline, src, dst, workgroups, flops, label, pooled, head)


class GemmKernel(ConvFamilyKernel):
    """gemm.wgsl: 1×1 stride-1 unpadded convolution over flattened pixels."""

    shader = "gemm.wgsl"

    def dispatches(self, layer: Layer, packed: PackedWeights, src: TensorView, dst: TensorView, *,
                   output_image: ImageRows | None = None):
        """``output_image``: write the planar output image (see ConvFamilyKernel.modules)."""
        pixels = dst.height * dst.width
        modules, replacements = self.modules(src, dst, output_image=output_image)
        pipeline = self.pipeline(
            layer.activation, replacements, PIXELS=pixels, OUT_W=dst.width, IN_BLOCK=src.block,
            IN_BLOCKS=packed.in_blocks, TILE_X=self.tile_x, TILE_C=packed.tile_c, **modules,
            **self.weight_constants(packed))
        workgroups = (groups_of(groups_of(pixels, self.tile_x), 64), 1)
        return self.grouped(layer, packed, pipeline, src, dst, workgroups, layer.flops_per_pixel * pixels,
                            self.kernel_label(self.shader, output_image=output_image))


class ConvTransposeKernel(ConvFamilyKernel):
    """conv_transpose.wgsl: 2×2 stride-2 transposed convolution, fused bias + activation; one output
    block per group (workgroup_id.z, or one dispatch each), 4 input pixels per invocation so that each
    weight block serves 4 pixels (the U-Net's upsampling convolutions took 2–3× less time than with one
    pixel per invocation on lavapipe, and the whole 256² U-Net ≈ 9% less CPU time)."""

    shader = "conv_transpose.wgsl"
    tile_x = 4  # input pixels per invocation, written out in the shader

    def __init__(self, ctx, precision: Precision, uniform_windows: bool = False, weight_fetch: str | None = None):
        super().__init__(ctx, precision, self.tile_x, uniform_windows, weight_fetch)

    def dispatches(self, layer: Layer, packed: PackedWeights, src: TensorView, dst: TensorView, *,
                   output_image: ImageRows | None = None, residual: TensorView | None = None):
        """``output_image``: write the planar output image (see ConvFamilyKernel.modules); ``residual``:
        store the output plus this tensor (an Add folded in, store_blocks_residual.wgsl)."""
        modules, replacements = self.modules(src, dst, output_image=output_image)
        if residual is not None:
            replacements["store_blocks.wgsl"] = "store_blocks_residual.wgsl"
            modules.update(RESIDUAL_BINDING=self.bindings.index("residual"), RESIDUAL_SHIFT=residual.block - dst.block)
        pipeline = self.pipeline(
            layer.activation, replacements, IN_H=src.height, IN_W=src.width, IN_BLOCK=src.block,
            IN_BLOCKS=packed.in_blocks, **modules, **self.weight_constants(packed))
        workgroups = (groups_of(groups_of(src.width, self.tile_x), 8), groups_of(src.height, 8))
        flops = layer.flops_per_pixel * dst.height * dst.width
        label = self.kernel_label(self.shader, output_image=output_image) + ("+add" if residual else "")
        return self.grouped(layer, packed, pipeline, src, dst, workgroups, flops, label, residual=residual)


class SpatialKernel(NnKernel):
    """Kernels with one invocation per output pixel and block: 8×8 workgroups, z over blocks."""

    bindings = ("src", "dst")

    def one(self, label: str, pipeline, resources: dict, width: int, height: int, blocks: int,
            channels: int) -> Dispatch:
        """The dispatch over ``blocks`` blocks of a height×width output holding ``channels`` channels."""
        return Dispatch(label, pipeline, self.bind(pipeline, resources),
                        (groups_of(width, 8), groups_of(height, 8), blocks), self.shader, (channels, height, width))


class MaxPoolKernel(SpatialKernel):
    shader = "maxpool.wgsl"

    def dispatches(self, layer: Layer, src: TensorView, dst: TensorView) -> list[Dispatch]:
        pipeline = self.pipeline(IN_H=src.height, IN_W=src.width, IN_BLOCK=src.block, OUT_H=dst.height,
                                 OUT_W=dst.width, OUT_BLOCK=dst.block)
        return [self.one(layer.name, pipeline, {"src": src.buffer, "dst": dst.buffer}, dst.width, dst.height,
                         dst.blocks, dst.channels)]


class ResizeKernel(SpatialKernel):
    shader = "resize_nearest.wgsl"

    def dispatches(self, layer: Layer, src: TensorView, dst: TensorView) -> list[Dispatch]:
        pipeline = self.pipeline(IN_H=src.height, IN_W=src.width, IN_BLOCK=src.block, OUT_BLOCK=dst.block)
        return [self.one(layer.name, pipeline, {"src": src.buffer, "dst": dst.buffer}, dst.width, dst.height,
                         dst.blocks, dst.channels)]


class ElementwiseKernel(SpatialKernel):
    """elementwise.wgsl: Add/Mul (tensor or per-channel constant) and standalone activations."""

    shader = "elementwise.wgsl"
    bindings = ("src", "dst", "b_tensor", "b_constant")

    def __init__(self, ctx, precision: Precision):
        super().__init__(ctx, precision)
        self.unused_operand = ctx.storage(16, label="unused elementwise operand")

    def prepare(self, layer: Layer, channels: int):
        """The per-channel constant operand as whole vec4 blocks (a scalar is repeated over the
        channels, padding channels get 0), uploaded once; None for tensor operands."""
        if layer.constant is None:
            return None
        values = np.zeros(groups_of(channels, 4) * 4, np.float32)
        values[:channels] = np.broadcast_to(layer.constant, (channels,))
        return self.ctx.upload(values, label=f"{layer.name} constant")

    def dispatches(self, layer: Layer, constant, sources: list[TensorView], dst: TensorView):
        operand = 0 if len(layer.inputs) == 1 and constant is None else (2 if constant is not None else 1)
        b_block = sources[1].block if operand == 1 else 0
        pipeline = self.pipeline(layer.activation, H=dst.height, W=dst.width, A_BLOCK=sources[0].block,
                                 B_BLOCK=b_block, OUT_BLOCK=dst.block, OPERAND=operand, OP=layer.op)
        # Both operand bindings are declared whatever OPERAND is; the unused one gets a 16-byte stand-in.
        resources = {"src": sources[0].buffer, "dst": dst.buffer,
                     "b_tensor": sources[1].buffer if operand == 1 else self.unused_operand,
                     "b_constant": constant if operand == 2 else self.unused_operand}
        return [self.one(layer.name, pipeline, resources, dst.width, dst.height, dst.blocks,
                         dst.channels)]


class CopyChannelsKernel(SpatialKernel):
    shader = "copy_channels.wgsl"

    def dispatches(self, label: str, src: TensorView, dst: TensorView, offset: int) -> list[Dispatch]:
        """Copy ``src`` into channels [offset, offset + C) of ``dst`` (``dst`` is the whole concat)."""
        pipeline = self.pipeline(H=dst.height, W=dst.width, CHANNELS=src.channels, OFFSET=offset,
                                 IN_BLOCK=src.block, OUT_BLOCK=dst.block)
        blocks = (offset + src.channels - 1) // 4 - offset // 4 + 1
        return [self.one(label, pipeline, {"src": src.buffer, "dst": dst.buffer}, dst.width, dst.height,
                         blocks, src.channels)]


class PackKernel(SpatialKernel):
    """pack.wgsl: rows of a planar NCHW f32 image → NC4HW4 canvas (edge padded, sanitized)."""

    shader = "pack.wgsl"

    def dispatches(self, planar, image: ImageRows, dst: TensorView) -> list[Dispatch]:
        pipeline = self.pipeline(CANVAS_H=dst.height, CANVAS_W=dst.width, OUT_BLOCK=dst.block,
                                 **image.load_constants(dst.channels))
        return [self.one("pack", pipeline, {"src": planar, "dst": dst.buffer}, dst.width, dst.height,
                         dst.blocks, dst.channels)]


class UnpackKernel(SpatialKernel):
    """unpack.wgsl: NC4HW4 canvas rows → rows of a planar NCHW f32 image (cropped)."""

    shader = "unpack.wgsl"

    def dispatches(self, src: TensorView, planar, image: ImageRows) -> list[Dispatch]:
        pipeline = self.pipeline(CANVAS_H=src.height, CANVAS_W=src.width, IN_BLOCK=src.block,
                                 **image.store_constants(src.channels))
        return [self.one("unpack", pipeline, {"src": src.buffer, "dst": planar}, image.width, image.rows,
                         src.blocks, src.channels)]
