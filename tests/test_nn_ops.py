"""Every op the ONNX → WGSL engine lowers, alone (and fused), and every fold of a conversion, pool or
head into a neighbouring kernel in every plan variant, against onnxruntime via check_parity.

Graphs are built with onnx.helper (dynamic H and W), so each test names exactly the node it checks.
Channel counts are deliberately not multiples of 4 (the engine packs channels in blocks of 4) and sizes
are odd (37×53) and degenerate (1×1) where the op allows.
"""

import numpy as np
import onnx
import onnxruntime as ort
import pytest
from onnx import TensorProto, helper, numpy_helper

from parity import check_parity

FP32_ATOL = 1e-4
FP16_ATOL = 1e-2  # documented fp16 bound: |Δ| ≤ 1e-2·max(1, max|ref|)
SIZES = {"odd": (37, 53), "tiny": (1, 1)}
TINIEST = {"maxpool": (2, 2), "conv2x2_stride2_unpadded": (2, 2),  # at 1×1 these have no output
           "conv5x5_asymmetric_pads_no_bias": (3, 3)}

pytestmark = pytest.mark.gpu


def make_model(tmp_path, name, nodes, in_channels, initializers=(), opset=17):
    """An ONNX file with input 'x' (1, C, H, W), output 'y' (the last node's output)."""
    x = helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, in_channels, "H", "W"])
    y = helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, "C", "OH", "OW"])
    graph = helper.make_graph(nodes, name, [x], [y],
                              [numpy_helper.from_array(np.asarray(v, np.float32), k) for k, v in initializers])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", opset)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    path = tmp_path / f"{name}.onnx"
    onnx.save(model, path)
    return path


def every_dispatch(model, height, width):
    """Every dispatch of one inference at height×width: entry, network and exit."""
    return model.dispatches(height, width, model.ctx.storage(4 * model.input_channels * height * width))


def onnxruntime_fn(path):
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    return lambda x: session.run(None, {"x": x})[0]


def weights(shape, seed=1):
    return np.random.default_rng(seed).normal(0, 0.3, shape).astype(np.float32)


def conv(name, x, y, cin, cout, k, pads=None, stride=1, bias=True, seed=1):
    inputs = [x, f"{name}_w"] + ([f"{name}_b"] if bias else [])
    node = helper.make_node("Conv", inputs, [y], name=name, kernel_shape=[k, k], strides=[stride, stride],
                            pads=pads if pads is not None else [k // 2] * 4)
    inits = [(f"{name}_w", weights((cout, cin, k, k), seed))]
    if bias:
        inits.append((f"{name}_b", weights((cout,), seed + 100)))
    return [node], inits


GRAPHS = {
    "conv3x3": (5, lambda: conv("conv", "x", "y", 5, 10, 3)),  # 3 output blocks: conv.wgsl
    "conv3x3_register_tile": (5, lambda: conv("conv", "x", "y", 5, 16, 3)),  # conv3x3.wgsl (8k outputs)
    "conv3x3_stride2": (5, lambda: conv("conv", "x", "y", 5, 7, 3, stride=2)),
    "conv5x5_asymmetric_pads_no_bias": (3, lambda: conv("conv", "x", "y", 3, 4, 5, pads=[2, 1, 0, 2],
                                                        bias=False)),
    "conv2x2_stride2_unpadded": (4, lambda: conv("conv", "x", "y", 4, 8, 2, pads=[0, 0, 0, 0], stride=2)),
    "conv1x1_gemm": (7, lambda: conv("conv", "x", "y", 7, 9, 1, pads=[0, 0, 0, 0])),
    "relu": (3, lambda: ([helper.make_node("Relu", ["x"], ["y"], name="relu")], [])),
    "leaky_relu": (3, lambda: ([helper.make_node("LeakyRelu", ["x"], ["y"], name="leaky", alpha=0.2)], [])),
    "sigmoid": (3, lambda: ([helper.make_node("Sigmoid", ["x"], ["y"], name="sigmoid")], [])),
    "clip": (3, lambda: ([helper.make_node("Clip", ["x", "lo", "hi"], ["y"], name="clip")],
                         [("lo", -0.3), ("hi", 0.4)])),
    "add_tensors": (3, lambda: ([helper.make_node("Add", ["x", "x"], ["y"], name="add")], [])),
    "add_per_channel_constant": (3, lambda: ([helper.make_node("Add", ["x", "c"], ["y"], name="add")],
                                             [("c", weights((3, 1, 1)))])),
    "mul_scalar_constant": (5, lambda: ([helper.make_node("Mul", ["c", "x"], ["y"], name="mul")],
                                        [("c", np.float32(-1.5))])),
}

POOLING_GRAPHS = {
    "maxpool": (6, lambda: ([helper.make_node("MaxPool", ["x"], ["y"], name="pool", kernel_shape=[2, 2],
                                              strides=[2, 2])], [])),
    "conv_transpose": (6, lambda: ([helper.make_node("ConvTranspose", ["x", "w", "b"], ["y"], name="up",
                                                     kernel_shape=[2, 2], strides=[2, 2])],
                                   [("w", weights((6, 5, 2, 2))), ("b", weights((5,), 7))])),
    "resize_nearest": (5, lambda: ([helper.make_node("Resize", ["x", "", "scales"], ["y"], name="resize",
                                                     mode="nearest")],
                                   [("scales", np.array([1, 1, 2, 2], np.float32))])),
}


def fused(activation_node):
    """Conv followed by an activation: the engine folds it into the conv's epilogue."""
    def build():
        nodes, inits = conv("conv", "x", "t", 5, 6, 3)
        node, extra = activation_node
        return nodes + [node], inits + extra
    return 5, build


FUSED = {
    "conv_relu": fused((helper.make_node("Relu", ["t"], ["y"], name="relu"), [])),
    "conv_sigmoid": fused((helper.make_node("Sigmoid", ["t"], ["y"], name="sigmoid"), [])),
    "conv_leaky_relu": fused((helper.make_node("LeakyRelu", ["t"], ["y"], name="leaky", alpha=0.1), [])),
    "conv_clip": fused((helper.make_node("Clip", ["t", "lo", "hi"], ["y"], name="clip"),
                        [("lo", 0.0), ("hi", 0.5)])),
}


def concat_graph(aligned: bool):
    """Aligned: 8 + 4 + 3 channels from convs (all written in place). Misaligned: the graph input (3)
    then convs of 5 and 6 channels (copied by copy_channels)."""
    def build():
        widths = (8, 4, 3) if aligned else (5, 6)
        nodes, inits, names = [], [], [] if aligned else ["x"]
        for i, width in enumerate(widths):
            n, w = conv(f"c{i}", "x", f"t{i}", 3, width, 3, seed=i + 1)
            nodes += n
            inits += w
            names.append(f"t{i}")
        nodes.append(helper.make_node("Concat", names, ["cat"], name="concat", axis=1))
        n, w = conv("mix", "cat", "y", sum(widths) + (0 if aligned else 3), 5, 3, seed=9)
        return nodes + n, inits + w
    return 3, build


CONCATS = {"concat_aligned": concat_graph(True), "concat_misaligned": concat_graph(False)}


@pytest.fixture(scope="module")
def models(tmp_path_factory, gpu):
    """name -> (onnx path, {precision: WgslModel}); built lazily and shared by the tests."""
    from wgpu_rt.nn import WgslModel

    built = {}
    folder = tmp_path_factory.mktemp("ops")

    def get(name, spec, precision):
        if name not in built:
            channels, build = spec
            nodes, inits = build()
            built[name] = (make_model(folder, name, nodes, channels, inits), channels, {})
        path, channels, per_precision = built[name]
        if precision not in per_precision:
            per_precision[precision] = WgslModel(path, precision, ctx=gpu)
        return path, channels, per_precision[precision]
    return get


ALL = {**GRAPHS, **POOLING_GRAPHS, **FUSED, **CONCATS}


@pytest.mark.parametrize("size", list(SIZES))
@pytest.mark.parametrize("name", list(ALL))
def test_op_fp32(models, name, size):
    path, channels, model = models(name, ALL[name], "fp32")
    height, width = TINIEST.get(name, SIZES[size]) if size == "tiny" else SIZES[size]
    check_parity([(1, channels, height, width)], onnxruntime_fn(path), model, atol=FP32_ATOL, name=name)


@pytest.mark.parametrize("width", [5, 6, 7, 32, 33])
def test_conv_transpose_pixel_tiles_cover_every_width(models, width):
    """conv_transpose.wgsl takes 4 input pixels per invocation and 32 per workgroup row: widths leaving
    1, 2 and 3 pixels in the last tile, exactly one workgroup, and one pixel past it; 9 rows cut the
    8-row workgroups."""
    path, channels, model = models("conv_transpose", POOLING_GRAPHS["conv_transpose"], "fp32")
    ours, _ = check_parity([(1, channels, 9, width)], onnxruntime_fn(path), model, atol=FP32_ATOL)
    assert ours.shape == (1, 5, 18, 2 * width)


def test_maxpool_fp32_floor_mode(models):
    """37×53 pools to 18×26 (ONNX floor mode: the odd row and column are dropped)."""
    path, channels, model = models("maxpool", POOLING_GRAPHS["maxpool"], "fp32")
    ours, _ = check_parity([(1, channels, 37, 53)], onnxruntime_fn(path), model, atol=FP32_ATOL)
    assert ours.shape == (1, 6, 18, 26)


@pytest.mark.parametrize("name", list(ALL))
def test_op_fp16(models, gpu, name):
    if not gpu.has_f16:
        pytest.skip("adapter lacks shader-f16")
    path, channels, model = models(name, ALL[name], "fp16")
    check_parity([(1, channels, 37, 53)], onnxruntime_fn(path), model, atol=FP16_ATOL, name=name)


def test_activation_is_fused_into_conv(models):
    """Conv+ReLU and Conv+Sigmoid are one layer, so one dispatch (which also writes the planar output:
    the network's last layer needs no unpack; its input is packed, as it is the exit layer)."""
    for name in ("conv_relu", "conv_sigmoid"):
        _, _, model = models(name, FUSED[name], "fp32")
        assert [layer.kind for layer in model.graph.layers] == ["conv"]
        assert model.graph.layers[0].activation.kind in (1, 3)
        dispatches = every_dispatch(model, 8, 8)
        # 6 outputs: two blocks, the 3×3 tile kernel's 8-channel tile
        assert [(d.label, d.kernel) for d in dispatches] == [("pack", "pack.wgsl"),
                                                             ("conv", "conv3x3.wgsl+tile8+unpack")]


def test_aligned_concat_is_free(models):
    _, _, model = models("concat_aligned", CONCATS["concat_aligned"], "fp32")
    assert model.graph.concat_copies["concat"] == []
    assert not any(d.label.startswith("concat") for d in every_dispatch(model, 8, 8))


def test_misaligned_concat_copies(models):
    _, _, model = models("concat_misaligned", CONCATS["concat_misaligned"], "fp32")
    # x: a graph input; t0: starts at channel 3; t1 starts at 8 and is last, so it is written in place
    assert model.graph.concat_copies["concat"] == ["x", "t0"]


def test_register_tile_kernel_is_used_for_3x3_with_8k_outputs(models):
    _, _, tiled = models("conv3x3_register_tile", GRAPHS["conv3x3_register_tile"], "fp32")
    _, _, plain = models("conv3x3", GRAPHS["conv3x3"], "fp32")
    assert type(tiled.kernel_for(tiled.graph.layers[0])).__name__ == "Conv3x3Kernel"
    assert type(plain.kernel_for(plain.graph.layers[0])).__name__ == "ConvKernel"


@pytest.mark.parametrize("tiling", ["none", "loop"])
def test_benchmark_baseline_tilings_agree(tmp_path, gpu, tiling):
    """The benchmark's naive and loop-tiled steps are real engine configurations: check them too."""
    from wgpu_rt.nn import WgslModel

    channels, build = FUSED["conv_relu"]
    nodes, inits = build()
    path = make_model(tmp_path, "conv_relu", nodes, channels, inits)
    model = WgslModel(path, ctx=gpu, conv_tiling=tiling)
    check_parity([(1, channels, 37, 53)], onnxruntime_fn(path), model, atol=FP32_ATOL)


@pytest.mark.parametrize("tiling", ["register", "staged", "staged-weights", "staged-narrow"])
@pytest.mark.parametrize("pads", [[1, 1, 1, 1], [0, 1, 2, 0]], ids=["same", "asymmetric"])
@pytest.mark.parametrize("precision", ["fp32", "fp16"])
@pytest.mark.parametrize("outputs", [8, 24, 48, 64])
def test_conv3x3_tile_variants(tmp_path, gpu, tiling, pads, precision, outputs):
    """Both 3×3 tile kernels, whichever the adapter's default: conv3x3.wgsl and conv3x3_staged.wgsl
    (workgroup-memory halo tiles; with "staged-weights" each input block's weights staged beside them),
    and every tile width: 48 outputs = 12 blocks, three 16-channel groups;
    64 = two 32-channel groups in conv3x3.wgsl, four 16-channel groups in the staged kernel (which keeps
    16); 8 and 24, which 16 does not divide, one and three 8-channel groups, as every width in
    "staged-narrow". 9 input channels = 3 blocks, one padded; 37×71 cuts the 8-row × 32-pixel workgroup
    tiles on both edges; asymmetric pads shift the halo."""
    from wgpu_rt.nn import WgslModel

    if precision == "fp16" and not gpu.has_f16:
        pytest.skip(f"{gpu.label} has no shader-f16")
    nodes, inits = conv("conv", "x", "y", 9, outputs, 3, pads=pads)
    path = make_model(tmp_path, "conv3x3_tiles", nodes, 9, inits)
    model = WgslModel(path, precision, ctx=gpu, conv_tiling=tiling)
    kernel = model.kernel_for(model.graph.layers[0])
    assert kernel.shader == ("conv3x3.wgsl" if tiling == "register" else "conv3x3_staged.wgsl")
    assert (kernel.weight_fetch == "workgroup") == (tiling == "staged-weights")
    wide = outputs == 64 and tiling == "register"
    narrow = outputs % 16 or tiling == "staged-narrow"
    assert model.prepared["conv"].tile_c == (8 if wide else 2 if narrow else 4)   # output blocks per invocation
    check_parity([(1, 9, 37, 71)], onnxruntime_fn(path), model,
                 atol=FP32_ATOL if precision == "fp32" else FP16_ATOL)


@pytest.mark.parametrize("math", ["f16", "f16-acc"])
@pytest.mark.parametrize("tiling", ["register", "staged"])
@pytest.mark.parametrize("cin,outputs", [(9, 48), (9, 64), (128, 48)], ids=["tile16", "tile32", "windows"])
def test_conv3x3_multiplies_in_half(tmp_path, gpu, tiling, cin, outputs, math):
    """``math="f16"`` (fp16 activations): the 3×3 tile kernels sum each kernel row's products in packed
    half precision and add them to the f32 tile, weights read directly as halves from their slots in
    storage, never uniform (both tile widths; 128 input channels too); ``math="f16-acc"``: the tile is
    summed in f16 as well (over 9 · 128 products here). Within the fp16 bound of onnxruntime, and
    labelled so. f16 multiply-adds need f16 activations."""
    from wgpu_rt.errors import ModelError
    from wgpu_rt.nn import WgslModel

    if not gpu.has_f16:
        pytest.skip(f"{gpu.label} has no shader-f16")
    nodes, inits = conv("conv", "x", "y", cin, outputs, 3)
    path = make_model(tmp_path, "conv3x3_half", nodes, cin, inits)
    model = WgslModel(path, "fp16", ctx=gpu, conv_tiling=tiling, math=math)
    kernel = model.kernel_for(model.graph.layers[0])
    assert kernel.half_math and kernel.weight_fetch == "direct" and model.prepared["conv"].half
    assert kernel.half_accumulate == (math == "f16-acc")
    assert model.prepared["conv"].weight_space == "storage, read"
    label = "+f16-acc" if math == "f16-acc" else "+f16-math"
    assert all(d.kernel.endswith(label) for d in every_dispatch(model, 37, 71) if d.flops)
    check_parity([(1, cin, 37, 71)], onnxruntime_fn(path), model, atol=FP16_ATOL)
    with pytest.raises(ModelError, match=f"math {math} needs precision fp16"):
        WgslModel(path, ctx=gpu, math=math)
    with pytest.raises(ModelError, match="math 'f8': choose one of f32, f16, f16-acc"):
        WgslModel(path, "fp16", ctx=gpu, math="f8")


def test_staged_tiles_are_the_default_on_discrete_gpus(gpu):
    from types import SimpleNamespace

    from wgpu_rt.nn.model import default_conv_tiling

    def adapter(kind):
        return SimpleNamespace(adapter=SimpleNamespace(info={"adapter_type": kind}))
    assert default_conv_tiling(adapter("DiscreteGPU")) == "staged"
    assert [default_conv_tiling(adapter(k)) for k in ("IntegratedGPU", "CPU", "Unknown")] == ["register"] * 3


@pytest.mark.parametrize("kind, has_f16, agrees, precision, math", [
    ("DiscreteGPU", True, {"f16", "f16-acc"}, "fp16", "f16-acc"), ("DiscreteGPU", True, {"f16"}, "fp16", "f16"),
    ("DiscreteGPU", True, set(), "fp16", "f32"), ("DiscreteGPU", False, {"f16", "f16-acc"}, "fp32", "f32"),
    ("CPU", True, {"f16", "f16-acc"}, "fp32", "f32"), ("IntegratedGPU", True, {"f16", "f16-acc"}, "fp32", "f32")])
def test_discrete_gpus_default_to_half_precision_and_half_math(monkeypatch, kind, has_f16, agrees, precision, math):
    """precision "auto" is fp16 on a discrete GPU with shader-f16 (8.5 against 10.3 ms on an H200,
    BENCHMARKS.md §21), its 3×3 tiles summed in f16 where those kernels agree with f32 math there (6.5
    against 7.5 ms, §31), else multiplying in f16 where those agree, else in f32; fp32 elsewhere (lavapipe
    has no half ALU); an fp32 model multiplies in f32 everywhere."""
    from types import SimpleNamespace

    from wgpu_rt.nn import model as nn_model

    monkeypatch.setattr(nn_model, "half_math_agrees", lambda ctx, math="f16": math in agrees)
    ctx = SimpleNamespace(adapter=SimpleNamespace(info={"adapter_type": kind}), has_f16=has_f16)
    assert nn_model.default_precision(ctx) == precision and nn_model.default_math(ctx, precision) == math
    assert nn_model.default_math(ctx, "fp32") == "f32"


@pytest.mark.parametrize("math", ["f16", "f16-acc"])
def test_half_math_is_checked_against_f32_math_on_the_device(gpu, monkeypatch, math):
    """The check behind the f16 default (and the autotuner's f16 candidates) runs both kernels on the
    adapter and compares them: it holds on lavapipe, once per device and math, and fails where the
    outputs differ by more than its tolerance, leaving that math out of the autotuner's candidates."""
    from wgpu_rt.nn import model as nn_model

    if not gpu.has_f16:
        pytest.skip(f"{gpu.label} has no shader-f16")
    monkeypatch.setattr(nn_model, "_half_math_checked", nn_model.weakref.WeakKeyDictionary())
    assert nn_model.half_math_agrees(gpu, math) and nn_model._half_math_checked[gpu.device] == {math: True}
    monkeypatch.setattr(nn_model, "_half_math_checked", nn_model.weakref.WeakKeyDictionary())
    monkeypatch.setattr(nn_model, "HALF_MATH_CHECK_TOLERANCE", -1.0)
    assert not nn_model.half_math_agrees(gpu, math)


def test_auto_precision_resolves_on_the_adapter(gpu, tmp_path):
    from wgpu_rt.errors import ModelError
    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn.model import default_math, default_precision

    nodes, inits = conv("conv", "x", "y", 4, 8, 3)
    path = make_model(tmp_path, "conv_auto", nodes, 4, inits)
    model = WgslModel(path, "auto", ctx=gpu)
    assert model.precision.name == default_precision(gpu) and model.math == default_math(gpu, model.precision.name)
    with pytest.raises(ModelError, match="precision 'fp8': choose one of auto, fp32, fp16"):
        WgslModel(path, "fp8", ctx=gpu)


@pytest.mark.parametrize("lanes", [8, 4, 0], ids=["subgroup8_fetch", "subgroup4_fetch", "direct_fetch"])
@pytest.mark.parametrize("cin", [5, 128, 256], ids=["uniform_window", "uniform_pairs", "storage_window"])
@pytest.mark.parametrize("outputs", [48, 64], ids=["tile16", "tile32"])
@pytest.mark.parametrize("uniform_windows", [True, False], ids=["uniform_preferred", "one_dispatch_preferred"])
def test_weights_come_from_uniform_or_storage_windows(tmp_path, gpu, monkeypatch, cin, lanes, outputs,
                                                      uniform_windows):
    """Weight blocks come from a uniform window when it fits 64 KiB, else from read-only storage (256
    input channels × 3×3 × 8 outputs per pair window: 73 KiB; 128 channels still fit; the 32-channel tile
    binds four such windows, the 16-channel one two), read cooperatively
    (weights_subgroup.wgsl: two floats per lane on ≥ 8-lane subgroups, a column per lane on 4-lane ones;
    the 4-lane fetch is forced here, it is correct on wider subgroups) or, on adapters without subgroups,
    directly (weights_uniform.wgsl). The layer is one dispatch with its output-block groups (48 outputs:
    three 16-channel groups, 64: two 32-channel ones) in workgroup_id.z, all windows in one binding,
    except where its windows only fit uniform bindings one by one and uniform windows are preferred
    (128 input channels on lavapipe's default): then one dispatch per group."""
    from wgpu_rt.gpu import GpuContext
    from wgpu_rt.nn import WgslModel, kernels
    from wgpu_rt.nn import model as nn_model

    if lanes and not gpu.has_subgroups:
        pytest.skip(f"{gpu.label} has no subgroups")
    if lanes and kernels.subgroup_lanes(gpu) < lanes:
        pytest.skip(f"{gpu.label} has {kernels.subgroup_lanes(gpu)}-lane subgroups")
    monkeypatch.setattr(kernels, "subgroup_lanes", lambda ctx: lanes)
    monkeypatch.setattr(nn_model, "default_uniform_windows", lambda ctx: uniform_windows)
    features = gpu.features if lanes else gpu.features - {"subgroup"}
    ctx = GpuContext(gpu.adapter, gpu.device, frozenset(features))
    nodes, inits = conv("conv", "x", "y", cin, outputs, 3)
    path = make_model(tmp_path, f"conv{cin}", nodes, cin, inits)
    model = WgslModel(path, ctx=ctx, conv_tiling="register")  # the kernel with both tile widths
    packed = model.prepared["conv"]
    assert (packed.tile_c, packed.groups, packed.splits) == ((4, 3, 2) if outputs == 48 else (8, 2, 4))
    per_group = cin == 128 and uniform_windows
    one_binding_space = "uniform" if cin == 5 else "storage, read"
    assert packed.weight_space == ("uniform" if per_group else one_binding_space)
    assert packed.one_dispatch == (not per_group)
    workgroups = [d.workgroups[2] for d in every_dispatch(model, 19, 23) if d.flops]
    assert workgroups == ([1] * packed.groups if per_group else [packed.groups])
    check_parity([(1, cin, 19, 23)], onnxruntime_fn(path), model, atol=FP32_ATOL)


@pytest.mark.parametrize("uniform_windows", [True, False], ids=["group_dispatches", "one_dispatch"])
def test_staged_weights_from_every_kind_of_window(tmp_path, gpu, monkeypatch, uniform_windows):
    """Weights staged in workgroup memory (conv tiling "staged-weights") from per-group uniform windows
    (one dispatch per group) and from one storage binding for the whole layer (the groups in
    workgroup_id.z): 128 input channels, 48 outputs, as onnxruntime."""
    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn import model as nn_model

    monkeypatch.setattr(nn_model, "default_uniform_windows", lambda ctx: uniform_windows)
    nodes, inits = conv("conv", "x", "y", 128, 48, 3)
    path = make_model(tmp_path, "conv128", nodes, 128, inits)
    model = WgslModel(path, ctx=gpu, conv_tiling="staged-weights")
    packed = model.prepared["conv"]
    assert packed.one_dispatch != uniform_windows
    assert packed.weight_space == ("uniform" if uniform_windows else "storage, read")
    assert all(d.kernel.endswith("+staged-weights") for d in every_dispatch(model, 19, 23) if d.flops)
    check_parity([(1, 128, 19, 23)], onnxruntime_fn(path), model, atol=FP32_ATOL)


def test_weight_fetch_is_checked(tmp_path, gpu):
    """An unknown weight fetch, or subgroup fetches on an adapter without subgroups, are refused by name."""
    from wgpu_rt.errors import ModelError
    from wgpu_rt.gpu import GpuContext
    from wgpu_rt.nn import WgslModel

    nodes, inits = conv("conv", "x", "y", 4, 16, 3)
    path = make_model(tmp_path, "conv4", nodes, 4, inits)
    with pytest.raises(ModelError, match="weight_fetch 'shared': choose one of subgroup, direct"):
        WgslModel(path, ctx=gpu, weight_fetch="shared")
    without = GpuContext(gpu.adapter, gpu.device, gpu.features - {"subgroup"})
    with pytest.raises(ModelError, match="weight_fetch subgroup needs the subgroup feature"):
        WgslModel(path, ctx=without, weight_fetch="subgroup")
    assert WgslModel(path, ctx=without).weight_fetch == "direct"


def test_subgroup_probe_sees_a_valid_width(gpu):
    from wgpu_rt.nn.kernels import subgroup_lanes

    if not gpu.has_subgroups:
        pytest.skip(f"{gpu.label} has no subgroups")
    assert gpu.subgroup_sizes.shape == (64,) and gpu.subgroup_sizes.min() >= 1
    lanes = subgroup_lanes(gpu)
    assert 4 <= lanes <= 128 and lanes & (lanes - 1) == 0


def test_tile_template_writes_out_each_block():
    """conv3x3_tile_blocks.wgsl's unrolled parts name every block once (fields, bias, accumulation from
    pair window t // 2 with taps t % 2 + 0/2/4, stores)."""
    from wgpu_rt.nn.kernels import tile_blocks_code

    code = tile_blocks_code(8)
    assert code["TILE_C"] == 8 and code["TILE_FIELDS"].count("mat4x4f") == 8
    assert code["TILE_BIAS"] == ", ".join(f"bias_pixels({t})" for t in range(8))
    assert "(*tile).block7 += pair3_weight_block(tap + 1, lane) * x.x0 + pair3_weight_block(tap + 3, lane)" \
        in code["TILE_ACCUMULATE"]
    assert code["TILE_STORE"].count("store_pixels(") == 8


# -- folds: pooling, the entry and exit conversions and a 1×1 head run inside neighbouring kernels ----

def relu(name, x, y):
    return [helper.make_node("Relu", [x], [y], name=name)]


def maxpool(name, x, y):
    return [helper.make_node("MaxPool", [x], [y], name=name, kernel_shape=[2, 2], strides=[2, 2])]


def pool_skip_graph(width):
    """A U-Net level: conv (the pooled layer, and the input's only reader) → max pool → conv → ×2
    resize, concatenated with the pre-pool output (a skip: the pooled tensor is not its only
    consumer) → conv to 6 channels. ``width`` picks the pooling kernel: 16 conv3x3's 16-channel tile,
    32 its 32-channel one (register tiling), 6 its 8-channel one."""
    def build():
        first, w1 = conv("c1", "x", "t1", 5, width, 3)
        second, w2 = conv("c2", "p", "t2", width, width, 3, seed=2)
        last, w3 = conv("mix", "cat", "y", 2 * width, 6, 3, seed=3)
        nodes = [*first, *relu("r1", "t1", "a1"), *maxpool("pool", "a1", "p"), *second, *relu("r2", "t2", "a2"),
                 helper.make_node("Resize", ["a2", "", "scales"], ["u"], name="up", mode="nearest"),
                 helper.make_node("Concat", ["u", "a1"], ["cat"], name="concat", axis=1), *last]
        return nodes, [*w1, *w2, *w3, ("scales", np.array([1, 1, 2, 2], np.float32))]
    return 5, build


def pool_into_concat_graph():
    """The pooled tensor lies inside a concat, 16 channels in (its block is not the conv output's):
    conv → pool → conv (which reads the concat's buffer, so it is copied in) → concat(conv, pool)."""
    def build():
        first, w1 = conv("c1", "x", "a1", 5, 16, 3)
        second, w2 = conv("c2", "p", "a2", 16, 16, 3, seed=2)
        last, w3 = conv("mix", "cat", "y", 32, 6, 3, seed=3)
        nodes = [*first, *maxpool("pool", "a1", "p"), *second,
                 helper.make_node("Concat", ["a2", "p"], ["cat"], name="concat", axis=1), *last]
        return nodes, [*w1, *w2, *w3]
    return 5, build


def two_pools_graph():
    """Two max pools of one conv output: the first runs in the conv's epilogue, the second is dispatched."""
    def build():
        first, w1 = conv("c1", "x", "a1", 5, 16, 3)
        nodes = [*first, *maxpool("pool1", "a1", "p1"), *maxpool("pool2", "a1", "p2"),
                 helper.make_node("Add", ["p1", "p2"], ["y"], name="add")]
        return nodes, w1
    return 5, build


def head_graph(width, head_activation=False):
    """conv 5 → 16 (the input's reader) → conv 16 → ``width`` + ReLU → 1×1 head to 10 channels (three
    output blocks, the last part-filled), optionally + sigmoid: the head folds into the second conv's
    epilogue where that conv's one tile holds all its outputs and the head has no activation."""
    def build():
        first, w1 = conv("c1", "x", "a1", 5, 16, 3)
        second, w2 = conv("c2", "a1", "t2", 16, width, 3, seed=2)
        head, w3 = conv("head", "a2", "h" if head_activation else "y", width, 10, 1, pads=[0, 0, 0, 0], seed=3)
        tail = [helper.make_node("Sigmoid", ["h"], ["y"], name="sigmoid")] if head_activation else []
        return [*first, *second, *relu("r2", "t2", "a2"), *head, *tail], [*w1, *w2, *w3]
    return 5, build


FOLDS = {"pool_skip16": pool_skip_graph(16), "pool_skip32": pool_skip_graph(32), "pool_skip6": pool_skip_graph(6),
         "pool_into_concat": pool_into_concat_graph(), "two_pools": two_pools_graph(),
         "head8": head_graph(8), "head16": head_graph(16), "head32": head_graph(32),
         "head_with_sigmoid": head_graph(16, True)}
# plan variant -> (conv tiling, uniform windows preferred): lavapipe's plan, the staged kernels, the GPU
# plan (staged, one dispatch per layer) and the loop kernels (conv.wgsl everywhere)
PLANS = {"register": ("register", True), "staged": ("staged", True), "gpu": ("staged", False),
         "loop": ("loop", True)}


def fold_model(tmp_path, gpu, monkeypatch, name, plan, precision):
    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn import model as nn_model

    if precision == "fp16" and not gpu.has_f16:
        pytest.skip(f"{gpu.label} has no shader-f16")
    tiling, uniform_windows = PLANS[plan]
    monkeypatch.setattr(nn_model, "default_uniform_windows", lambda ctx: uniform_windows)
    channels, build = FOLDS[name]
    nodes, inits = build()
    path = make_model(tmp_path, name, nodes, channels, inits)
    return path, WgslModel(path, precision, ctx=gpu, conv_tiling=tiling)


def canvas_onnxruntime_fn(path, model):
    """onnxruntime on the input edge-padded to ``model``'s canvas, cropped back to its output: the
    engine's semantics where a graph does not fit together at the input's size (a pool, then a ×2
    resize, of an odd size)."""
    from wgpu_rt.frame.denoise import pad_to_multiple

    run = onnxruntime_fn(path)

    def reference(x):
        plan = model.plan(*x.shape[2:])
        padded = x if plan.canvas == x.shape[2:] else pad_to_multiple(x, model.graph.multiple)
        return run(padded)[..., : plan.output_shape[1], : plan.output_shape[2]]
    return reference


@pytest.mark.parametrize("precision", ["fp32", "fp16"])
@pytest.mark.parametrize("plan", list(PLANS))
@pytest.mark.parametrize("name", list(FOLDS))
def test_folds_match_onnxruntime(tmp_path, gpu, monkeypatch, name, plan, precision):
    """Every fold in every plan variant and precision at 37×53 (odd: the pooled convs' tiles and the
    pools' floor mode are cut at both edges, the canvas is edge-padded to 38×54 where the graph needs
    it), against onnxruntime."""
    path, model = fold_model(tmp_path, gpu, monkeypatch, name, plan, precision)
    reference = canvas_onnxruntime_fn(path, model)
    check_parity([(1, 5, 37, 53)], reference, model, atol=FP32_ATOL if precision == "fp32" else FP16_ATOL,
                 name=f"{name} {plan} {precision}")


def kernels_of(model, height=37, width=53):
    return [d.kernel for d in every_dispatch(model, height, width)]


@pytest.mark.parametrize("plan", list(PLANS))
def test_pool_runs_in_the_conv_epilogue(tmp_path, gpu, monkeypatch, plan):
    """No max pool dispatch and no pack: the first conv reads the input image and pools its output."""
    _, model = fold_model(tmp_path, gpu, monkeypatch, "pool_skip16", plan, "fp32")
    assert [pool.name for pool in model.graph.epilogue_pools.values()] == ["pool"]
    kernels = kernels_of(model)
    assert not any(k.startswith(("maxpool", "pack.wgsl", "unpack.wgsl")) for k in kernels), kernels
    assert kernels[0].startswith("pack+conv") and kernels[0].endswith("+maxpool")
    # the last conv (6 outputs) in the 3×3 kernels' 8-channel tile, or the loop plan's conv.wgsl
    assert kernels[-1] == "conv.wgsl+unpack" if plan == "loop" else kernels[-1].endswith("+tile8+unpack")


def test_second_pool_of_one_output_is_dispatched(tmp_path, gpu, monkeypatch):
    _, model = fold_model(tmp_path, gpu, monkeypatch, "two_pools", "register", "fp32")
    assert [pool.name for pool in model.graph.epilogue_pools.values()] == ["pool1"]
    assert kernels_of(model) == ["pack+conv3x3.wgsl+tile16+maxpool", "maxpool.wgsl", "elementwise.wgsl",
                                 "unpack.wgsl"]


@pytest.mark.parametrize("name,plan,folded", [
    ("head16", "register", True), ("head16", "gpu", True), ("head32", "register", True), ("head8", "gpu", True),
    ("head32", "staged", False),  # the staged kernel's 16-channel tile holds half of the 32 outputs
    ("head16", "loop", False),  # conv.wgsl takes no head
    ("head_with_sigmoid", "register", False)])
def test_head_runs_in_the_last_conv_epilogue(tmp_path, gpu, monkeypatch, name, plan, folded):
    """A 1×1 head folds into the preceding 3×3 conv where one tile holds all that conv's outputs and the
    head has no activation; else the head alone writes the image."""
    _, model = fold_model(tmp_path, gpu, monkeypatch, name, plan, "fp32")
    kernels = kernels_of(model)
    assert kernels[0].startswith("pack+conv") and not any(k.startswith("unpack") for k in kernels)
    if folded:
        assert len(kernels) == 2 and kernels[1].endswith("+head+unpack"), kernels
    else:
        assert kernels[-1] in ("gemm.wgsl+unpack", "unpack.wgsl") and len(kernels) >= 3, kernels
