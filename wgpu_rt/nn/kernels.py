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
planar NCHW f32 is converted on entry (pack.wgsl) and exit (unpack.wgsl).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import wgpu

from .. import shaders
from .graph import FLOAT_MAX, NO_ACTIVATION, Activation, Layer

UNIFORM_WINDOW_LIMIT = 65536  # bytes; larger weight windows are bound as read-only storage


@dataclass(frozen=True)
class Precision:
    """Storage type of activations. Math and accumulation are f32 in both precisions: f16 storage halves
    activation memory and traffic, while f16 accumulation over up to 9·128 terms would break the 1e-2
    bound (and lavapipe, on AVX2, has no f16 ALU to gain from). Max pooling, resizing and copies move
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
    """A tensor inside an activation buffer: ``channels`` channels starting at block ``block``."""

    buffer: object
    block: int
    channels: int
    height: int
    width: int

    @property
    def blocks(self) -> int:
        return math.ceil(self.channels / 4)


@dataclass
class Dispatch:
    """One recorded compute dispatch (``flops`` counts multiply-adds ×2, for the benchmark)."""

    label: str
    pipeline: object
    bind_group: object
    workgroups: tuple[int, int, int]
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


class NnKernel:
    """Base: ``shader`` names the .wgsl file, ``bindings`` its bind group 0 in binding order."""

    shader: str = ""
    bindings: tuple[str, ...] = ()

    def __init__(self, ctx, precision: Precision):
        self.ctx, self.precision = ctx, precision

    def pipeline(self, activation: Activation = NO_ACTIVATION, **constants):
        substitutions = {"ENABLE_F16": self.precision.enable, "STORAGE": self.precision.storage,
                         "STORAGE_MAX": wgsl_float(self.precision.storage_max),
                         "ACTIVATION": activation.kind, "ALPHA": wgsl_float(activation.alpha),
                         "CLIP_LO": wgsl_float(activation.lo), "CLIP_HI": wgsl_float(activation.hi),
                         **constants}
        if "WEIGHT_SPACE" in constants:
            substitutions.update(self.weight_fetch(constants["WEIGHT_SPACE"], constants["WEIGHT_MATS"]))
        code = shaders.compose(self.shader, shaders.NN_KERNELS, substitutions)
        return self.ctx.compute_pipeline(code, label=self.shader)

    def weight_fetch(self, space: str, mats: int) -> dict:
        """Substitutions choosing how conv-family kernels read weight blocks (see weights_*.wgsl)."""
        if self.ctx.has_subgroups:
            return {"WEIGHT_FETCH": shaders.compose("weights_subgroup.wgsl", shaders.NN_KERNELS),
                    "LANE": "@builtin(subgroup_invocation_id) lane: u32"}
        return {"WEIGHT_FETCH": shaders.compose("weights_uniform.wgsl", shaders.NN_KERNELS,
                                                {"WEIGHT_SPACE": space, "WEIGHT_MATS": mats}),
                "LANE": "@builtin(local_invocation_index) lane: u32"}

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


class PackedWeights:
    """A conv-family layer's weights, uploaded once, cut into one window per output-block group.

    Window g holds, for each input block, tap and output block t of the group, a mat4x4 whose column j
    is the 4 output channels' weights for input channel j; the group's header holds its bias and its
    first output block (relative to the output tensor, the view's block is added per plan)."""

    def __init__(self, ctx, layer: Layer, tile_c: int):
        cout, cin, kh, kw = layer.weight.shape
        self.out_blocks, self.in_blocks = groups_of(cout, 4), groups_of(cin, 4)
        self.tile_c = max(t for t in range(1, tile_c + 1) if self.out_blocks % t == 0)
        self.groups = self.out_blocks // self.tile_c
        self.taps = kh * kw
        padded = np.zeros((self.out_blocks * 4, self.in_blocks * 4, kh, kw), np.float32)
        padded[:cout, :cin] = layer.weight
        blocks = padded.reshape(self.groups, self.tile_c, 4, self.in_blocks, 4, kh, kw)
        windows = blocks.transpose(0, 3, 5, 6, 1, 4, 2).reshape(self.groups, -1)
        self.mats = self.in_blocks * self.taps * self.tile_c
        window_bytes = self.mats * 64
        limits = ctx.limits
        fits_uniform = window_bytes <= min(UNIFORM_WINDOW_LIMIT, limits.get("max-uniform-buffer-binding-size",
                                                                            UNIFORM_WINDOW_LIMIT))
        self.weight_space = "uniform" if fits_uniform and not ctx.has_subgroups else "storage, read"
        alignment = limits.get("min-uniform-buffer-offset-alignment" if self.weight_space == "uniform"
                               else "min-storage-buffer-offset-alignment", 256)
        self.window_bytes, self.window_stride = window_bytes, -(-window_bytes // alignment) * alignment
        data = np.zeros((self.groups, self.window_stride // 4), np.float32)
        data[:, : windows.shape[1]] = windows
        self.buffer = ctx.upload(data, usage=wgpu.BufferUsage.UNIFORM, label=f"{layer.name} weights")
        bias = np.zeros(self.out_blocks * 4, np.float32)
        bias[:cout] = layer.bias
        self.header_bytes = 16 * self.tile_c + 16
        header_alignment = limits.get("min-uniform-buffer-offset-alignment", 256)
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
        return {"weights": (self.buffer, group * self.window_stride, self.window_bytes)}

    def header(self, out_block: int, group: int) -> tuple:
        return (self.headers(out_block), group * self.header_stride, self.header_bytes)


class ConvFamilyKernel(NnKernel):
    """Shared by conv, gemm and conv_transpose: per output-block group one dispatch with its windows."""

    bindings = ("src", "dst", "weights", "header")
    tile_c_default = 1

    def __init__(self, ctx, precision: Precision, tile_x: int):
        super().__init__(ctx, precision)
        self.tile_x = tile_x

    def prepare(self, layer: Layer) -> PackedWeights:
        return PackedWeights(self.ctx, layer, self.tile_c_default)

    def grouped(self, layer, packed, pipeline, src, dst, workgroups, flops) -> list[Dispatch]:
        return [Dispatch(f"{layer.name}[{g}]", pipeline,
                         self.bind(pipeline, {"src": src.buffer, "dst": dst.buffer, **packed.windows(g),
                                              "header": packed.header(dst.block, g)}),
                         workgroups, flops // packed.groups) for g in range(packed.groups)]


class ConvKernel(ConvFamilyKernel):
    """conv.wgsl: k×k convolution, stride 1–2, zero padding, fused bias + activation."""

    shader = "conv.wgsl"

    def dispatches(self, layer: Layer, packed: PackedWeights, src: TensorView, dst: TensorView):
        cout, _, kh, kw = layer.weight.shape
        top, left, _, _ = layer.pads
        pipeline = self.pipeline(
            layer.activation, IN_H=src.height, IN_W=src.width, IN_BLOCK=src.block, IN_BLOCKS=packed.in_blocks,
            OUT_H=dst.height, OUT_W=dst.width, KH=kh, KW=kw, STRIDE=layer.stride, PAD_TOP=top, PAD_LEFT=left,
            TILE_X=self.tile_x, TILE_C=packed.tile_c, WEIGHT_SPACE=packed.weight_space, WEIGHT_MATS=packed.mats)
        workgroups = (groups_of(groups_of(dst.width, self.tile_x), 8), groups_of(dst.height, 8), 1)  # 8×8 tiles
        flops = layer.flops_per_pixel * dst.height * dst.width
        return self.grouped(layer, packed, pipeline, src, dst, workgroups, flops)


class Conv3x3Kernel(ConvFamilyKernel):
    """conv3x3.wgsl: the hot path — 3×3 stride-1 convolutions whose output has a multiple of 16
    channels, with a written-out 4-pixel × 4-block register tile."""

    shader = "conv3x3.wgsl"
    tile_c_default = 4
    tile_x = 4

    def __init__(self, ctx, precision: Precision):
        super().__init__(ctx, precision, self.tile_x)

    @staticmethod
    def handles(layer: Layer) -> bool:
        return (layer.kind == "conv" and layer.weight.shape[2:] == (3, 3) and layer.stride == 1
                and groups_of(layer.weight.shape[0], 4) % Conv3x3Kernel.tile_c_default == 0)

    def dispatches(self, layer: Layer, packed: PackedWeights, src: TensorView, dst: TensorView):
        top, left, _, _ = layer.pads
        pipeline = self.pipeline(
            layer.activation, IN_H=src.height, IN_W=src.width, IN_BLOCK=src.block, IN_BLOCKS=packed.in_blocks,
            OUT_H=dst.height, OUT_W=dst.width, PAD_TOP=top, PAD_LEFT=left,
            WEIGHT_SPACE=packed.weight_space, WEIGHT_MATS=packed.mats)
        workgroups = (groups_of(groups_of(dst.width, self.tile_x), 8), groups_of(dst.height, 8), 1)  # 8×8 tiles
        flops = layer.flops_per_pixel * dst.height * dst.width
        return self.grouped(layer, packed, pipeline, src, dst, workgroups, flops)


class GemmKernel(ConvFamilyKernel):
    """gemm.wgsl: 1×1 stride-1 unpadded convolution over flattened pixels."""

    shader = "gemm.wgsl"

    def dispatches(self, layer: Layer, packed: PackedWeights, src: TensorView, dst: TensorView):
        pixels = dst.height * dst.width
        pipeline = self.pipeline(
            layer.activation, PIXELS=pixels, IN_BLOCK=src.block, IN_BLOCKS=packed.in_blocks,
            TILE_X=self.tile_x, TILE_C=packed.tile_c, WEIGHT_SPACE=packed.weight_space, WEIGHT_MATS=packed.mats)
        workgroups = (groups_of(groups_of(pixels, self.tile_x), 64), 1, 1)
        return self.grouped(layer, packed, pipeline, src, dst, workgroups, layer.flops_per_pixel * pixels)


class ConvTransposeKernel(ConvFamilyKernel):
    """conv_transpose.wgsl: 2×2 stride-2 transposed convolution, fused bias + activation."""

    shader = "conv_transpose.wgsl"

    def dispatches(self, layer: Layer, packed: PackedWeights, src: TensorView, dst: TensorView):
        pipeline = self.pipeline(
            layer.activation, IN_H=src.height, IN_W=src.width, IN_BLOCK=src.block, IN_BLOCKS=packed.in_blocks,
            TILE_C=packed.tile_c, WEIGHT_SPACE=packed.weight_space, WEIGHT_MATS=packed.mats)
        workgroups = (groups_of(src.width, 8), groups_of(src.height, 8), 1)
        flops = layer.flops_per_pixel * dst.height * dst.width
        return self.grouped(layer, packed, pipeline, src, dst, workgroups, flops)


class SpatialKernel(NnKernel):
    """Kernels with one invocation per output pixel and block: 8×8 workgroups, z over blocks."""

    bindings = ("src", "dst")

    def one(self, label: str, pipeline, resources: dict, width: int, height: int, blocks: int) -> Dispatch:
        return Dispatch(label, pipeline, self.bind(pipeline, resources),
                        (groups_of(width, 8), groups_of(height, 8), blocks))


class MaxPoolKernel(SpatialKernel):
    shader = "maxpool.wgsl"

    def dispatches(self, layer: Layer, src: TensorView, dst: TensorView) -> list[Dispatch]:
        pipeline = self.pipeline(IN_H=src.height, IN_W=src.width, IN_BLOCK=src.block, OUT_H=dst.height,
                                 OUT_W=dst.width, OUT_BLOCK=dst.block)
        return [self.one(layer.name, pipeline, {"src": src.buffer, "dst": dst.buffer}, dst.width, dst.height,
                         dst.blocks)]


class ResizeKernel(SpatialKernel):
    shader = "resize_nearest.wgsl"

    def dispatches(self, layer: Layer, src: TensorView, dst: TensorView) -> list[Dispatch]:
        pipeline = self.pipeline(IN_H=src.height, IN_W=src.width, IN_BLOCK=src.block, OUT_BLOCK=dst.block)
        return [self.one(layer.name, pipeline, {"src": src.buffer, "dst": dst.buffer}, dst.width, dst.height,
                         dst.blocks)]


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
        return [self.one(layer.name, pipeline, resources, dst.width, dst.height, dst.blocks)]


class CopyChannelsKernel(SpatialKernel):
    shader = "copy_channels.wgsl"

    def dispatches(self, label: str, src: TensorView, dst: TensorView, offset: int) -> list[Dispatch]:
        """Copy ``src`` into channels [offset, offset + C) of ``dst`` (``dst`` is the whole concat)."""
        pipeline = self.pipeline(H=dst.height, W=dst.width, CHANNELS=src.channels, OFFSET=offset,
                                 IN_BLOCK=src.block, OUT_BLOCK=dst.block)
        blocks = (offset + src.channels - 1) // 4 - offset // 4 + 1
        return [self.one(label, pipeline, {"src": src.buffer, "dst": dst.buffer}, dst.width, dst.height,
                         blocks)]


class PackKernel(SpatialKernel):
    """pack.wgsl: rows of a planar NCHW f32 image → NC4HW4 canvas (zero padded, sanitized)."""

    shader = "pack.wgsl"

    def dispatches(self, planar, image_height: int, width: int, first_row: int, rows: int,
                   dst: TensorView) -> list[Dispatch]:
        pipeline = self.pipeline(CHANNELS=dst.channels, H=rows, W=width,
                                 IMAGE_H=image_height, IN_ROW0=first_row, CANVAS_H=dst.height,
                                 CANVAS_W=dst.width, OUT_BLOCK=dst.block)
        return [self.one("pack", pipeline, {"src": planar, "dst": dst.buffer}, dst.width, dst.height,
                         dst.blocks)]


class UnpackKernel(SpatialKernel):
    """unpack.wgsl: NC4HW4 canvas rows → rows of a planar NCHW f32 image (cropped)."""

    shader = "unpack.wgsl"

    def dispatches(self, src: TensorView, planar, image_height: int, width: int, first_row: int,
                   from_row: int, rows: int) -> list[Dispatch]:
        pipeline = self.pipeline(CHANNELS=src.channels, H=rows, W=width, IMAGE_H=image_height,
                                 OUT_ROW0=first_row, ROW_FROM=from_row, CANVAS_H=src.height,
                                 CANVAS_W=src.width, IN_BLOCK=src.block)
        return [self.one("unpack", pipeline, {"src": src.buffer, "dst": planar}, width, rows, src.blocks)]
