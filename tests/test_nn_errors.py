"""User-caused problems with a model are ModelErrors naming the file/node; the CLI exits 2 with them."""

import numpy as np
import onnx
import pytest
from onnx import TensorProto, helper, numpy_helper

from wgpu_rt.cli import main
from wgpu_rt.errors import ModelError


def save(tmp_path, nodes, initializers=(), channels=3, name="model"):
    x = helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, channels, "H", "W"])
    y = helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, "C", "H", "W"])
    graph = helper.make_graph(nodes, name, [x], [y],
                              [numpy_helper.from_array(np.asarray(v, np.float32), k) for k, v in initializers])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    path = tmp_path / f"{name}.onnx"
    onnx.save(model, path)
    return path


def conv_model(tmp_path, **attributes):
    node = helper.make_node("Conv", ["x", "w"], ["y"], name="the_conv", **attributes)
    return save(tmp_path, [node], [("w", np.ones((4, 3, 3, 3)))])


def load(path):
    from wgpu_rt.nn.graph import load_graph

    return load_graph(path)


def test_missing_file(tmp_path):
    with pytest.raises(ModelError, match="missing.onnx: ONNX model file not found"):
        load(tmp_path / "missing.onnx")


def test_corrupt_file(tmp_path):
    path = tmp_path / "corrupt.onnx"
    path.write_bytes(b"\x08\x07 this is not a protobuf \xff\xfe" * 10)
    with pytest.raises(ModelError, match="corrupt.onnx: not a valid ONNX model"):
        load(path)


def test_unsupported_op_names_node_and_op(tmp_path):
    path = save(tmp_path, [helper.make_node("Tanh", ["x"], ["y"], name="squash")])
    with pytest.raises(ModelError, match=r"node 'squash' \(Tanh\): unsupported op"):
        load(path)


@pytest.mark.parametrize("attributes, message", [
    ({"group": 3, "kernel_shape": [3, 3]}, "grouped convolution"),
    ({"dilations": [2, 2]}, "dilated convolution"),
    ({"strides": [3, 3]}, r"strides \[3, 3\] are not supported"),
    ({"auto_pad": "SAME_UPPER"}, "auto_pad=SAME_UPPER"),
])
def test_unsupported_conv_attributes_name_the_node(tmp_path, attributes, message):
    if "group" in attributes:
        node = helper.make_node("Conv", ["x", "w"], ["y"], name="the_conv", **attributes)
        path = save(tmp_path, [node], [("w", np.ones((3, 1, 3, 3)))])
    else:
        path = conv_model(tmp_path, **attributes)
    with pytest.raises(ModelError, match=f"node 'the_conv' \\(Conv\\): {message}"):
        load(path)


def test_unsupported_pooling_names_the_node(tmp_path):
    node = helper.make_node("MaxPool", ["x"], ["y"], name="pool3", kernel_shape=[3, 3], strides=[2, 2])
    with pytest.raises(ModelError, match=r"node 'pool3' \(MaxPool\): only 2×2 stride-2"):
        load(save(tmp_path, [node]))


def test_resize_other_than_nearest_x2(tmp_path):
    node = helper.make_node("Resize", ["x", "", "s"], ["y"], name="up3", mode="nearest")
    with pytest.raises(ModelError, match=r"node 'up3' \(Resize\): only ×2"):
        load(save(tmp_path, [node], [("s", [1, 1, 3, 3])]))


@pytest.mark.gpu
def test_wrong_input_channel_count(tmp_path, gpu):
    from wgpu_rt.nn import WgslModel

    model = WgslModel(conv_model(tmp_path, pads=[1, 1, 1, 1]), ctx=gpu)
    with pytest.raises(ModelError, match="model.onnx: input 'x' expects 3 channels, got 5"):
        model(np.zeros((1, 5, 8, 8), np.float32))
    with pytest.raises(ModelError, match=r"must be \(N, C, H, W\)"):
        model(np.zeros((8, 8), np.float32))


@pytest.mark.gpu
def test_cli_infer_round_trip_and_errors(tmp_path, gpu, capsys):
    from wgpu_rt.nn import WgslModel

    path = conv_model(tmp_path, pads=[1, 1, 1, 1])
    x = np.random.default_rng(0).uniform(-1, 1, (1, 3, 9, 13)).astype(np.float32)
    np.save(tmp_path / "x.npy", x)
    out = tmp_path / "out" / "y.npy"
    assert main(["infer", str(path), "--input", str(tmp_path / "x.npy"), "--output", str(out)]) == 0
    np.testing.assert_array_equal(np.load(out), WgslModel(path, "auto", ctx=gpu)(x))   # the CLI's default
    assert sorted(p.name for p in out.parent.iterdir()) == ["y.npy"]  # no temporary left behind

    assert main(["infer", str(tmp_path / "nope.onnx"), "--input", str(tmp_path / "x.npy"),
                 "--output", str(tmp_path / "z.npy")]) == 2
    assert "nope.onnx: ONNX model file not found" in capsys.readouterr().err
    np.save(tmp_path / "bad.npy", np.zeros((1, 4, 5, 5), np.float32))
    assert main(["infer", str(path), "--input", str(tmp_path / "bad.npy"), "--output", str(tmp_path / "z.npy")]) == 2
    assert "expects 3 channels, got 4" in capsys.readouterr().err
    assert not (tmp_path / "z.npy").exists()
