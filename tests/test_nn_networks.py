"""The three seed networks (random weights) through the WGSL engine vs onnxruntime, fp32 and fp16.

The U-Net needs H and W to be multiples of 4; at other sizes the engine edge-pads the canvas and crops,
so its reference is onnxruntime on the same edge-padded input (``pad_to_multiple``), cropped. Big sizes of the U-Net
are marked slow (run with -m slow).
"""

import math

import numpy as np
import onnxruntime as ort
import pytest
import torch

from parity import check_parity
from test_nn_ops import every_dispatch
from wgpu_rt.frame.denoise import pad_to_multiple
from wgpu_rt.models import DENOISER
from wgpu_rt.train.networks import ConfidencePredictor, ErrorPredictor, UNet, export_onnx

FP32_ATOL = 1e-4
FP16_ATOL = 1e-2
LOG1P_HALF_MAX = math.log1p(65504.0)

pytestmark = pytest.mark.gpu

NETWORKS = {"unet": UNet, "error_predictor": ErrorPredictor, "confidence_predictor": ConfidencePredictor,
            # a deepest level added to the skip above it (an Add of two activations) instead of merged
            "unet_bottom_add": lambda: UNet(widths=(16, 32, 32, 32), bottom_merge="add")}
SMALL_NET_SIZES = [(37, 53), (1, 1), (255, 257), (256, 256), (512, 512)]
UNET_SIZES = [(37, 53), (1, 1), pytest.param((256, 256), marks=pytest.mark.slow),
              pytest.param((255, 257), marks=pytest.mark.slow), pytest.param((512, 512), marks=pytest.mark.slow)]


@pytest.fixture(scope="module")
def networks(tmp_path_factory, gpu):
    """name -> (onnx path, onnxruntime session, {precision: WgslModel}), random weights, built lazily."""
    from wgpu_rt.nn import WgslModel

    folder = tmp_path_factory.mktemp("networks")
    cache = {}

    def get(name, precision):
        if name not in cache:
            torch.manual_seed(list(NETWORKS).index(name))
            path = export_onnx(NETWORKS[name](), folder / f"{name}.onnx")
            cache[name] = (path, ort.InferenceSession(str(path), providers=["CPUExecutionProvider"]), {})
        path, session, models = cache[name]
        if precision not in models:
            models[precision] = WgslModel(path, precision, ctx=gpu)
        return session, models[precision]
    return get


def padded_reference(session, multiple):
    """onnxruntime on the input edge-padded to ``multiple``, cropped back (the engine's semantics)."""
    def run(x):
        _, _, h, w = x.shape
        return session.run(None, {"input": pad_to_multiple(x, multiple)})[0][:, :, :h, :w]
    return run


def check_network(networks, name, size, precision, low=0.0, high=1.0, seed=0):
    session, model = networks(name, precision)
    if precision == "fp16" and not model.ctx.has_f16:
        pytest.skip("adapter lacks shader-f16")
    reference = padded_reference(session, model.graph.multiple)
    atol = FP32_ATOL if precision == "fp32" else FP16_ATOL
    return check_parity([(1, model.input_channels, *size)], reference, model, atol=atol, low=low, high=high,
                        seed=seed, name=f"{name} {precision} {size}")


@pytest.mark.parametrize("precision", ["fp32", "fp16"])
@pytest.mark.parametrize("size", SMALL_NET_SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
@pytest.mark.parametrize("name", ["error_predictor", "confidence_predictor"])
def test_small_networks(networks, name, size, precision):
    check_network(networks, name, size, precision)


@pytest.mark.parametrize("precision", ["fp32", "fp16"])
@pytest.mark.parametrize("size", UNET_SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
@pytest.mark.parametrize("name", ["unet", "unet_bottom_add"])
def test_unet(networks, name, size, precision):
    check_network(networks, name, size, precision)


@pytest.mark.parametrize("name", list(NETWORKS))
def test_fp16_over_the_whole_log1p_half_range(networks, name):
    """Inputs anywhere in [0, log1p(65504)] (the denoiser's log1p radiance range) stay within the fp16
    bound and never produce NaN/Inf; includes an image that is at the top of the range everywhere."""
    ours, _ = check_network(networks, name, (40, 44), "fp16", low=0.0, high=LOG1P_HALF_MAX, seed=3)
    _, model = networks(name, "fp16")
    saturated = np.full((1, model.input_channels, 40, 44), LOG1P_HALF_MAX, np.float32)
    assert np.all(np.isfinite(model(saturated)))


def test_unet_plan_reuses_memory_and_concat_is_free(networks):
    _, model = networks("unet", "fp32")
    plan = model.plan(64, 64)
    assert all(copies == [] for copies in model.graph.concat_copies.values())
    assert not any(d.label.startswith("/Concat") for d in plan.dispatches)
    # 0.525: the pools computed in the convs' epilogues keep a conv's input, output and pooled output
    # live at once (this U-Net's plan takes 3% more than with pool dispatches: 1.94 → 2.03 MiB at 64²)
    assert plan.peak_bytes < 0.55 * plan.unplanned_bytes, (plan.peak_bytes, plan.unplanned_bytes)
    assert model.plan(64, 64) is plan  # planned once per resolution
    assert plan.canvas == (64, 64) and model.plan(37, 53).canvas == (40, 56)


def test_an_add_after_a_transposed_conv_runs_in_its_epilogue(networks, tmp_path, gpu):
    """The add-merge U-Net's Add (deepest level + skip) is stored by the transposed conv's epilogue: no
    elementwise dispatch, no buffer for the transposed conv's own output (parity: test_unet). An Add whose
    transposed-conv input is read elsewhere too stays a dispatch of its own, with the same result as
    onnxruntime."""
    from wgpu_rt.nn import WgslModel

    _, model = networks("unet_bottom_add", "fp32")
    (up, add), = model.graph.epilogue_adds.items()
    assert up.endswith("ConvTranspose") and add.kind == "elementwise"
    dispatches = model.plan(64, 64).dispatches
    assert not any(d.kernel.startswith("elementwise") for d in dispatches)
    assert sum(d.kernel == "conv_transpose.wgsl+add" for d in dispatches) >= 1

    class TwoReaders(torch.nn.Module):
        def __init__(self):
            super().__init__()
            self.up = torch.nn.ConvTranspose2d(DENOISER.input_channels, 8, 2, stride=2)
            self.skip = torch.nn.Conv2d(DENOISER.input_channels, 8, 3, padding=1)
            self.out = torch.nn.Conv2d(16, 3, 1)

        def forward(self, x):
            up = self.up(torch.nn.functional.max_pool2d(x, 2))
            return self.out(torch.cat([up + self.skip(x), up], 1))

    torch.manual_seed(9)
    path = export_onnx(TwoReaders(), tmp_path / "two_readers.onnx")
    shared = WgslModel(path, ctx=gpu)
    assert shared.graph.epilogue_adds == {}
    assert any(d.kernel.startswith("elementwise") for d in shared.plan(20, 24).dispatches)
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    check_parity([(1, DENOISER.input_channels, 20, 24)], padded_reference(session, shared.graph.multiple), shared,
                 atol=FP32_ATOL, low=0.0, high=1.0, name="Add not folded")


def test_record_on_gpu_buffers_matches_numpy_call(networks, gpu):
    """The frame pipeline's path: planar input buffer in, planar output buffer out, one encoder."""
    _, model = networks("error_predictor", "fp32")
    x = np.random.default_rng(5).uniform(0, 1, (3, 21, 34)).astype(np.float32)
    encoder = gpu.device.create_command_encoder()
    output = model.record(encoder, gpu.upload(x), 21, 34)
    gpu.device.queue.submit([encoder.finish()])
    np.testing.assert_array_equal(gpu.read(output, np.float32, (1, 21, 34)), model(x))


def test_batch_of_two(networks):
    session, model = networks("confidence_predictor", "fp32")
    x = np.random.default_rng(6).uniform(0, 1, (2, 8, 9, 11)).astype(np.float32)
    np.testing.assert_allclose(model(x), session.run(None, {"input": x})[0], atol=FP32_ATOL)


@pytest.mark.parametrize("height,width", [(3, 5), (4, 4), (1, 7)])
def test_dihedral_strides_address_numpys_flips_and_turns(height, width):
    from wgpu_rt.nn.kernels import dihedral_strides

    stored = np.arange(height * width).reshape(height, width)
    for transform in range(8):
        seen = np.rot90(stored, transform % 4)[:, ::-1 if transform >= 4 else 1]
        row_stride, col_stride, origin = dihedral_strides(transform, *seen.shape)
        rows, cols = np.indices(seen.shape)
        np.testing.assert_array_equal(origin + rows * row_stride + cols * col_stride, seen, err_msg=str(transform))


def ensemble_reference(run, k):
    """The mean of ``run`` over the first ``k`` dihedral transforms of its (N, C, H, W) input, turned back."""
    def averaged(x):
        outputs = []
        for transform in range(k):
            seen = np.rot90(x, transform % 4, axes=(2, 3))[..., ::-1 if transform >= 4 else 1]
            output = run(np.ascontiguousarray(seen))[..., ::-1 if transform >= 4 else 1]
            outputs.append(np.rot90(output, -(transform % 4), axes=(2, 3)))
        return np.mean(outputs, axis=0)
    return averaged


@pytest.mark.parametrize("k", [2, 8])
def test_ensemble_averages_the_flipped_and_turned_passes(networks, gpu, k):
    """``ensemble=k``: each pass's first conv reads the input turned, its last layer writes the output turned
    back and adds it up; 37×53 turns into a 53×37 plan of its own (canvas padding on the other side)."""
    from wgpu_rt.nn import WgslModel

    session, model = networks("unet", "fp32")
    ensemble = WgslModel(model.path, ctx=gpu, ensemble=k)
    reference = ensemble_reference(padded_reference(session, model.graph.multiple), k)
    check_parity([(1, model.input_channels, 37, 53)], reference, ensemble, atol=FP32_ATOL, low=0.0, high=1.0,
                 name=f"ensemble of {k}")
    image = ensemble.plan(37, 53).input_buffer
    assert len(ensemble.dispatches(37, 53, image)) == k * len(model.dispatches(37, 53, image))


def test_ensemble_in_bands_and_bad_sizes(tmp_path, gpu):
    """An ensemble of a frame in bands (its turned pass in more bands of its own) equals the same
    ensemble run whole; an ensemble size other than 1, 2, 4, 8 is a clear error."""
    from wgpu_rt.errors import ModelError
    from wgpu_rt.gpu import GpuContext
    from wgpu_rt.nn import WgslModel

    torch.manual_seed(4)
    path = export_onnx(UNet(widths=(16, 32)), tmp_path / "unet.onnx")
    small = GpuContext(gpu.adapter, gpu.device, gpu.features)
    small.__dict__["limits"] = {**gpu.limits, "max-storage-buffer-binding-size": 10**6, "max-buffer-size": 10**6}
    x = np.random.default_rng(8).uniform(0, 1, (1, DENOISER.input_channels, 203, 45)).astype(np.float32)
    banded = WgslModel(path, ctx=small, ensemble=2)
    assert 1 < len(banded.plan(203, 45).bands) < len(banded.plan(45, 203).bands)  # 2 and 4
    np.testing.assert_allclose(banded(x), WgslModel(path, ctx=gpu, ensemble=2)(x), rtol=0, atol=1e-6)
    with pytest.raises(ModelError, match="ensemble 3: choose one of 1, 2, 4, 8"):
        WgslModel(path, ctx=gpu, ensemble=3)


@pytest.mark.parametrize("widths,limit,tiling,first,last", [
    ((8, 16, 32), 820_000, "loop", "pack+conv.wgsl", "gemm.wgsl+unpack"),
    ((8, 16, 32), 820_000, "register", "pack+conv3x3.wgsl+tile8", "conv3x3.wgsl+tile8+head+unpack"),
    ((16, 32), 1_000_000, "register", "pack+conv3x3.wgsl+tile16", "conv3x3.wgsl+tile16+head+unpack")],
    ids=["conv", "conv3x3_tile8_head", "conv3x3_head"])
def test_frames_over_the_buffer_limit_run_in_bands_with_identical_results(tmp_path, gpu, widths, limit, tiling,
                                                                          first, last):
    """A frame whose activations exceed max-buffer-size runs as bands of rows with receptive-field
    context; shrink the limits to force that at a small size. Each band's first conv reads its rows of
    the input image and its last layer writes its kept rows of the output image: conv.wgsl and the 1×1
    head (the loop plan), conv3x3 with the head in its epilogue (8 and 16 channels)."""
    from wgpu_rt.gpu import GpuContext
    from wgpu_rt.nn import WgslModel

    torch.manual_seed(4)
    path = export_onnx(UNet(widths=widths), tmp_path / "unet.onnx")
    small = GpuContext(gpu.adapter, gpu.device, gpu.features)
    small.__dict__["limits"] = {**gpu.limits, "max-storage-buffer-binding-size": limit, "max-buffer-size": limit}
    x = np.random.default_rng(7).uniform(0, 1, (1, DENOISER.input_channels, 403, 45)).astype(np.float32)
    banded = WgslModel(path, ctx=small, conv_tiling=tiling)
    bands = len(banded.plan(403, 45).bands)
    assert bands == 3
    kernels = [d.kernel for d in every_dispatch(banded, 403, 45)]
    assert kernels.count(first) == bands and kernels.count(last) == bands, kernels
    np.testing.assert_array_equal(banded(x), WgslModel(path, ctx=gpu, conv_tiling=tiling)(x))


def test_bands_past_the_binding_limit_alone_take_two_bindings_for_the_largest_activation(tmp_path, gpu,
                                                                                          monkeypatch):
    """Where only one storage binding is too small (max-buffer-size is not), a conv reads its largest input
    through two windows, so the bands are sized for half the largest activation in one binding: fewer, taller
    bands than for all of it (the size ``rows_in_one_pass`` gives a caller that bands a frame itself), and
    they still equal the whole frame."""
    from wgpu_rt.gpu import GpuContext
    from wgpu_rt.nn import WgslModel, model

    torch.manual_seed(4)
    path = export_onnx(UNet(widths=(16, 32)), tmp_path / "unet.onnx")
    small = GpuContext(gpu.adapter, gpu.device, gpu.features)
    small.__dict__["limits"] = {**gpu.limits, "max-storage-buffer-binding-size": 850_000}
    tried = []
    bands = model.WgslModel._bands
    monkeypatch.setattr(model.WgslModel, "_bands", lambda self, *args: tried.append(args[2]) or bands(self, *args))
    banded = WgslModel(path, ctx=small)
    plan = banded.plan(403, 45)
    assert len(plan.bands) == 2 and len(tried) == 1   # the first size tried ran (sized for all of it: 4 bands)
    assert max(band.valid_rows for band in plan.bands) <= banded.rows_in_one_pass(45)
    x = np.random.default_rng(9).uniform(0, 1, (1, DENOISER.input_channels, 403, 45)).astype(np.float32)
    np.testing.assert_array_equal(banded(x), WgslModel(path, ctx=gpu)(x))


@pytest.mark.parametrize("tiling", ["register", "staged", "loop"])
def test_frames_over_the_binding_limit_bind_windows_and_split_inputs(tmp_path, gpu, monkeypatch, tiling):
    """A frame whose tensors fit max-buffer-size but not one storage binding (the 1080p U-Net on
    lavapipe's 128 MiB) runs whole: each tensor is bound as a window of its buffer, and the merge conv
    reading the full-resolution concat (over the limit by itself) reads it through two windows
    (load_blocks_split.wgsl), in conv3x3.wgsl (register), its staged variant and conv.wgsl (loop). The
    result equals the unconstrained plan's bit for bit."""
    from wgpu_rt.gpu import GpuContext
    from wgpu_rt.nn import WgslModel, kernels

    torch.manual_seed(4)
    path = export_onnx(UNet(widths=(16, 32)), tmp_path / "unet.onnx")
    small = GpuContext(gpu.adapter, gpu.device, gpu.features)
    plane = 404 * 46 * 16  # one fp32 block of the 403×45 frame's 404×46 canvas
    small.__dict__["limits"] = {**gpu.limits, "max-storage-buffer-binding-size": 6 * plane}  # concat: 8 blocks
    split_reads = []
    modules = kernels.ConvFamilyKernel.modules

    def spy(self, src, *args, **kwargs):
        split_reads.append((src.split_block, src.upper[2]) if src.upper else None)
        return modules(self, src, *args, **kwargs)

    monkeypatch.setattr(kernels.ConvFamilyKernel, "modules", spy)
    x = np.random.default_rng(7).uniform(0, 1, (1, DENOISER.input_channels, 403, 45)).astype(np.float32)
    windowed = WgslModel(path, ctx=small, conv_tiling=tiling)
    plan = windowed.plan(403, 45)
    assert plan.canvas == (404, 46) and len(plan.bands) == 1 and plan.peak_bytes > 6 * plane
    assert [read for read in split_reads if read] == [(6, 2 * plane)]  # the merge conv: blocks 6, 7 upper
    whole = WgslModel(path, ctx=gpu, conv_tiling=tiling)
    np.testing.assert_array_equal(windowed(x), whole(x))
    assert whole.plan(403, 45).peak_bytes == plan.peak_bytes


@pytest.mark.parametrize("tiling,precision,fetch,math", [
    ("register", "fp32", None, None), ("staged", "fp32", None, None), ("loop", "fp32", None, None),
    ("register", "fp16", None, None), ("staged", "fp32", "direct", None), ("staged-weights", "fp32", None, None),
    ("register", "fp16", None, "f16"), ("staged", "fp16", None, "f16"), ("register", "fp16", None, "f16-acc")])
def test_unet_one_dispatch_per_layer(tmp_path, gpu, monkeypatch, tiling, precision, fetch, math):
    """With one dispatch per layer preferred (discrete GPUs), every weighted layer of the U-Net is one
    dispatch whose z dimension runs over its output-block groups, the big layers reading all their
    windows from one storage binding, and nothing else is dispatched: the first conv reads the input
    image, the pools run in the convs' epilogues, the concats are free and the head writes the output
    image (in the register tiling from the last 3×3 conv's epilogue, whose 32 outputs fit one tile):
    the same output as onnxruntime; also with weights read directly by every invocation (a choice of
    its own where the adapter has subgroups), and with the 3×3 kernels' multiply-adds in f16 (their sums
    too, the head folded into an f16 tile)."""
    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn import model as nn_model

    if precision == "fp16" and not gpu.has_f16:
        pytest.skip("adapter lacks shader-f16")
    monkeypatch.setattr(nn_model, "default_uniform_windows", lambda ctx: False)
    torch.manual_seed(0)
    path = export_onnx(UNet(), tmp_path / "unet.onnx")
    model = WgslModel(path, precision, ctx=gpu, conv_tiling=tiling, weight_fetch=fetch, math=math)
    weighted = [layer for layer in model.graph.layers if layer.weight is not None]
    packed = [model.prepared[layer.name] for layer in weighted]
    assert all(p.one_dispatch for p in packed) and any(p.weight_space == "storage, read" for p in packed)
    assert any(p.groups > 1 for p in packed)
    dispatches = every_dispatch(model, 37, 53)
    head_folded = tiling == "register"
    assert all(d.flops for d in dispatches) and len(dispatches) == len(weighted) - head_folded
    dispatched = packed[:-1] if head_folded else packed  # the head is the last weighted layer
    assert sorted(d.workgroups[2] for d in dispatches) == sorted(p.groups for p in dispatched)
    math_label = {"f16": "+f16-math", "f16-acc": "+f16-acc"}.get(model.math, "")
    labels = [d.kernel.removesuffix(math_label) if math_label else d.kernel for d in dispatches]
    assert labels[-1].removesuffix("+direct-weights").endswith("+head+unpack" if head_folded else "gemm.wgsl+unpack")
    for label in labels:   # f16 multiply-adds read their weights directly
        reads_directly = fetch == "direct" or (model.math != "f32" and "conv3x3" in label)
        assert label.endswith("+direct-weights") == (reads_directly and gpu.has_subgroups), label
    assert any(bool(math_label) and d.kernel.endswith(math_label) for d in dispatches) == (model.math != "f32")
    assert any(d.kernel.endswith("+staged-weights") for d in dispatches) == (tiling == "staged-weights")
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    check_parity([(1, model.input_channels, 37, 53)], padded_reference(session, model.graph.multiple), model,
                 atol=FP32_ATOL if precision == "fp32" else FP16_ATOL, name=f"unet {tiling} {precision} {fetch} {math}")
