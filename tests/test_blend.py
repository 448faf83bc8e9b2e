"""`wgpu-rt blend`: a model between a network and its fine-tune (wgpu_rt.train.blend), without torch."""

import numpy as np
import onnx
import pytest
from onnx import helper, numpy_helper
from test_nn_ops import conv, make_model, onnxruntime_fn

from wgpu_rt.cli import main


def conv_model(path, seed, out_channels=4, relu=False):
    """A 3→``out_channels`` 3×3 conv model (then a ReLU with ``relu``: another graph) at ``path``, its
    weights drawn from ``seed``, a card beside it; returns its weights."""
    nodes, inits = conv("conv", "x", "h" if relu else "y", 3, out_channels, 3, seed=seed)
    if relu:
        nodes.append(helper.make_node("Relu", ["h"], ["y"], name="relu"))
    make_model(path.parent, path.stem, nodes, 3, inits)
    path.with_suffix(".md").write_text(f"# {path.name}\n\nseed {seed}\n")
    return dict(inits)


def test_a_blend_is_the_weighted_mean_of_the_weights_and_its_card_names_both(tmp_path, capsys):
    base, tuned = conv_model(tmp_path / "base.onnx", 1), conv_model(tmp_path / "tuned.onnx", 2)
    out = tmp_path / "out" / "denoiser.onnx"
    assert main(["blend", str(tmp_path / "base.onnx"), str(tmp_path / "tuned.onnx"), "--weight", "0.25",
                 "--out", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    blended = {i.name: numpy_helper.to_array(i) for i in onnx.load(str(out)).graph.initializer}
    for name in base:
        np.testing.assert_allclose(blended[name], 0.75 * base[name] + 0.25 * tuned[name], rtol=1e-6, atol=1e-7)
    # a conv is linear in its weights, so the blended model's output is the same mix of the two outputs
    x = np.random.default_rng(3).normal(size=(1, 3, 8, 8)).astype(np.float32)
    expected = 0.75 * onnxruntime_fn(tmp_path / "base.onnx")(x) + 0.25 * onnxruntime_fn(tmp_path / "tuned.onnx")(x)
    np.testing.assert_allclose(onnxruntime_fn(out)(x), expected, rtol=1e-5, atol=1e-5)
    card = out.with_suffix(".md").read_text()
    assert "--weight 0.25" in card and "seed 1" in card and "seed 2" in card
    assert "## Fine-tune" in card and "## Base" in card and "\n## base.onnx" in card   # headings one level down


def test_a_base_card_the_fine_tunes_card_already_holds_is_not_repeated(tmp_path):
    import hashlib

    conv_model(tmp_path / "base.onnx", 1)
    conv_model(tmp_path / "tuned.onnx", 2)
    digest = hashlib.sha256((tmp_path / "base.onnx").read_bytes()).hexdigest()[:12]
    card = f"# tuned\n\nfine-tuned from base (sha256 {digest}…)\n\n## Base model\n\nseed 1\n"
    (tmp_path / "tuned.md").write_text(card)
    assert main(["blend", str(tmp_path / "base.onnx"), str(tmp_path / "tuned.onnx"), "--weight", "0.5",
                 "--out", str(tmp_path / "out.onnx")]) == 0
    card = (tmp_path / "out.md").read_text()
    assert card.count("seed 1") == 1 and "## Base (" not in card and "'Base model' below" in card


def test_the_fine_tunes_history_stays_and_the_bases_is_left_out(tmp_path):
    conv_model(tmp_path / "base.onnx", 1)
    conv_model(tmp_path / "tuned.onnx", 2)
    for name in ("base", "tuned"):
        (tmp_path / f"{name}.md").write_text(f"# {name}\n\n## History\n\n| epoch |\n| {name} row |\n")
    assert main(["blend", str(tmp_path / "base.onnx"), str(tmp_path / "tuned.onnx"), "--weight", "0.5",
                 "--out", str(tmp_path / "out.onnx")]) == 0
    card = (tmp_path / "out.md").read_text()
    assert "| tuned row |" in card and "| base row |" not in card and "history tables left out" in card


@pytest.mark.parametrize("weight, expected", [("0", "base"), ("1", "tuned")])
def test_the_ends_of_the_line_are_the_two_models(tmp_path, weight, expected):
    weights = {"base": conv_model(tmp_path / "base.onnx", 1), "tuned": conv_model(tmp_path / "tuned.onnx", 2)}
    out = tmp_path / "end.onnx"
    assert main(["blend", str(tmp_path / "base.onnx"), str(tmp_path / "tuned.onnx"), "--weight", weight,
                 "--out", str(out)]) == 0
    for init in onnx.load(str(out)).graph.initializer:
        np.testing.assert_array_equal(numpy_helper.to_array(init), weights[expected][init.name])


def test_a_blend_of_two_models_trained_with_the_exposure_step_says_so(tmp_path):
    """Both read their input brought to one key: so does the blend, and its ONNX file says it (as `wgpu-rt
    train` writes it), so that `--auto-exposure auto` runs it that way."""
    for name, seed in (("base", 1), ("tuned", 2)):
        conv_model(tmp_path / f"{name}.onnx", seed)
        model = onnx.load(tmp_path / f"{name}.onnx")
        model.metadata_props.add(key="wgpu_rt.auto_exposure", value="on")
        onnx.save(model, tmp_path / f"{name}.onnx")
    out = tmp_path / "out.onnx"
    assert main(["blend", str(tmp_path / "base.onnx"), str(tmp_path / "tuned.onnx"), "--weight", "0.5",
                 "--out", str(out)]) == 0
    assert {p.key: p.value for p in onnx.load(out).metadata_props} == {"wgpu_rt.auto_exposure": "on"}


@pytest.mark.parametrize("case, named", [
    ("other_shape", "initializer 'conv_w'"),
    ("other_graph", "its graph is not the base's"),
    ("weight", "--weight must be in [0, 1]"),
    ("overwrite", "would overwrite"),
    ("missing", "not found"),
    ("not_onnx", "not a valid ONNX model"),
    ("suffix", "name an .onnx file"),
    ("exposure", "trained with the exposure step on, the base"),
])
def test_bad_input_is_one_line_naming_it_and_nothing_is_written(tmp_path, capsys, case, named):
    conv_model(tmp_path / "base.onnx", 1)
    tuned = tmp_path / "tuned.onnx"
    if case == "other_shape":
        conv_model(tuned, 2, out_channels=8)
    elif case == "other_graph":
        conv_model(tuned, 2, relu=True)
    elif case == "not_onnx":
        tuned.write_bytes(b"not a model")
    elif case != "missing":
        conv_model(tuned, 2)
    if case == "exposure":   # a fine-tune that learned to read its input brought to one key
        model = onnx.load(tuned)
        model.metadata_props.add(key="wgpu_rt.auto_exposure", value="on")
        onnx.save(model, tuned)
    out = {"overwrite": tmp_path / "base.onnx", "suffix": tmp_path / "out.bin"}.get(case, tmp_path / "out.onnx")
    weight = "1.5" if case == "weight" else "0.5"
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert main(["blend", str(tmp_path / "base.onnx"), str(tuned), "--weight", weight, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert named in err and len(err.strip().splitlines()) == 1, err
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
