"""Defined behaviour on hostile inputs (documented in wgpu_rt/nn/model.py): NaN inputs read as 0, ±Inf
as ± the largest finite value of the storage type, and every stored activation is clamped to that
range, so no NaN or Inf ever reaches the output, in fp32 or fp16."""

import numpy as np
import onnx
import onnxruntime as ort
import pytest
from onnx import TensorProto, helper, numpy_helper

from wgpu_rt.train.networks import ErrorPredictor, UNet, export_onnx

pytestmark = pytest.mark.gpu
PRECISIONS = ["fp32", "fp16"]
STORAGE_MAX = {"fp32": float(np.finfo(np.float32).max), "fp16": 65504.0}


@pytest.fixture(scope="module")
def error_predictor(tmp_path_factory):
    import torch

    torch.manual_seed(11)
    return export_onnx(ErrorPredictor(), tmp_path_factory.mktemp("stress") / "error.onnx")


@pytest.fixture(scope="module")
def unet(tmp_path_factory):
    import torch

    torch.manual_seed(12)
    return export_onnx(UNet(widths=(8, 16)), tmp_path_factory.mktemp("stress") / "unet.onnx")


def model_for(path, precision, gpu):
    from wgpu_rt.nn import WgslModel

    if precision == "fp16" and not gpu.has_f16:
        pytest.skip("adapter lacks shader-f16")
    return WgslModel(path, precision, ctx=gpu)


@pytest.mark.parametrize("precision", PRECISIONS)
def test_nan_reads_as_zero_and_inf_saturates(error_predictor, gpu, precision):
    model = model_for(error_predictor, precision, gpu)
    x = np.random.default_rng(0).uniform(0, 1, (1, 3, 24, 30)).astype(np.float32)
    hostile = x.copy()
    hostile[0, 0, 3:6, 4:9] = np.nan
    hostile[0, 1, 10, 10] = np.inf
    hostile[0, 2, 12, 20] = -np.inf
    ours = model(hostile)
    assert np.all(np.isfinite(ours))
    sanitized = np.nan_to_num(hostile, nan=0.0, posinf=STORAGE_MAX[precision], neginf=-STORAGE_MAX[precision])
    np.testing.assert_array_equal(ours, model(sanitized))
    # rows 16+ are beyond the receptive field (three 3×3 convs: 3 pixels) of every hostile pixel
    np.testing.assert_array_equal(ours[..., 16:, :], model(x)[..., 16:, :])


@pytest.mark.parametrize("precision", PRECISIONS)
def test_all_zero_input_matches_onnxruntime(unet, gpu, precision):
    model = model_for(unet, precision, gpu)
    x = np.zeros((1, model.input_channels, 16, 20), np.float32)
    reference = ort.InferenceSession(str(unet), providers=["CPUExecutionProvider"]).run(None, {"input": x})[0]
    np.testing.assert_allclose(model(x), reference, atol=1e-4 if precision == "fp32" else 1e-2)


@pytest.mark.parametrize("precision", PRECISIONS)
def test_huge_inputs_saturate_instead_of_overflowing(unet, gpu, precision):
    """1e30 overflows f16 and, through the convs, f32: outputs stay finite and at most the type's max."""
    model = model_for(unet, precision, gpu)
    x = np.full((1, model.input_channels, 12, 12), 1e30, np.float32)
    x[0, ::2] = -1e30
    out = model(x)
    assert np.all(np.isfinite(out))
    assert np.abs(out).max() <= STORAGE_MAX[precision]


def test_fp16_overflow_of_intermediate_activation_is_clamped(tmp_path, gpu):
    """x·1000·1000 exceeds 65504 inside the graph: fp16 stores ±65504, not Inf (fp32 keeps the value)."""
    x_info = helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 2, "H", "W"])
    y_info = helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 2, "H", "W"])
    nodes = [helper.make_node("Mul", ["x", "k"], ["t"], name="scale1"),
             helper.make_node("Mul", ["t", "k"], ["y"], name="scale2")]
    graph = helper.make_graph(nodes, "overflow", [x_info], [y_info],
                              [numpy_helper.from_array(np.array(1000.0, np.float32), "k")])
    model_proto = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model_proto.ir_version = 8
    path = tmp_path / "overflow.onnx"
    onnx.save(model_proto, path)
    x = np.array([0.5, -0.5, 1e-5, 0.0], np.float32).reshape(1, 2, 1, 2)
    np.testing.assert_allclose(model_for(path, "fp32", gpu)(x), x * 1e6, rtol=1e-6)
    half = model_for(path, "fp16", gpu)(x)
    np.testing.assert_array_equal(half[0, 0, 0], [65504.0, -65504.0])
    np.testing.assert_allclose(half[0, 1, 0], [10.0, 0.0], rtol=1e-2)
