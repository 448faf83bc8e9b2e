"""``wgpu-rt denoise``: clear errors for bad input files; with the WGSL engine, output equal to the same
model under onnxruntime; exported models in the WGSL engine match onnxruntime (parity)."""

import gc
import re

import numpy as np
import pytest
import torch
from exr_files import write_blender_exr

from wgpu_rt.cli import main
from wgpu_rt.io import read_exr, write_exr
from wgpu_rt.train.networks import ConfidencePredictor, ErrorPredictor, UNet, export_onnx


# A file whose albedo our aux pass averaged over each pixel's area: `wgpu-rt denoise` reads it as it is.
AUX_ALBEDO = {"wgpuRtAuxSamples": 4}


def _render_like(h=20, w=28, seed=0):
    rng = np.random.default_rng(seed)
    color = rng.gamma(0.5, 2.0, size=(h, w, 3)).astype(np.float32)
    normal = rng.normal(size=(h, w, 3)).astype(np.float32)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    return color, {"albedo": rng.uniform(size=(h, w, 3)), "normal": normal,
                   "depth": rng.uniform(1, 5, size=(h, w, 1)), "motion": np.zeros((h, w, 2))}


def test_missing_input_file_is_named(tmp_path, capsys):
    missing = tmp_path / "nope.exr"
    assert main(["denoise", str(missing), "--out", str(tmp_path / "o.exr")]) == 2
    assert f"{missing}: no such file" in capsys.readouterr().err


def test_corrupt_input_file_is_named(tmp_path, capsys):
    bad = tmp_path / "bad.exr"
    bad.write_bytes(b"not an exr at all")
    assert main(["denoise", str(bad), "--out", str(tmp_path / "o.exr")]) == 2
    assert f"{bad}: not a readable OpenEXR" in capsys.readouterr().err


def test_missing_layer_is_named(tmp_path, capsys):
    color, layers = _render_like()
    path = tmp_path / "in.exr"
    write_exr(path, color, {k: v for k, v in layers.items() if k != "normal"})
    assert main(["denoise", str(path), "--out", str(tmp_path / "o.exr")]) == 2
    err = capsys.readouterr().err
    assert f"{path}: missing layer 'normal'" in err
    assert not (tmp_path / "o.exr").exists()


def test_missing_model_is_named(tmp_path, capsys):
    pytest.importorskip("wgpu_rt.nn")
    color, layers = _render_like()
    write_exr(tmp_path / "in.exr", color, layers)
    model = tmp_path / "absent.onnx"
    assert main(["denoise", str(tmp_path / "in.exr"), "--out", str(tmp_path / "o.exr"), "--model", str(model)]) == 2
    assert f"{model}: no such model file" in capsys.readouterr().err


def _packed_for_a_model_without_exposure(color, layers):
    """The (1, 11, H, W) input `wgpu-rt denoise` packs for a model whose ONNX file does not say it was
    trained with the exposure step (frame/denoise_chain.py's INPUT_EXPOSURE)."""
    from wgpu_rt.frame.pack import pack_denoiser_input, white_balance_gains

    gains = white_balance_gains(color, layers["albedo"], exposure=False)
    return pack_denoiser_input(color, layers["albedo"], layers["normal"], layers["depth"], balance=gains)[None]


def _chain_after_the_network(output, color, layers):
    """What `wgpu-rt denoise` makes of the network's (3, H, W) ``output`` by the numpy references: unpacked
    with the frame's gains (no exposure step, as ``_packed_for_a_model_without_exposure``), then the colour
    balance and the post filter (frame/chroma.py, frame/atrous.py), on by default."""
    from wgpu_rt.frame.atrous import atrous_filter
    from wgpu_rt.frame.chroma import match_sample_chroma
    from wgpu_rt.frame.pack import frame_exposure, white_balance_gains
    from wgpu_rt.frame.unpack import unpack_denoiser_output

    gains = white_balance_gains(color, layers["albedo"], exposure=False)
    exposure = frame_exposure(color, layers["albedo"])   # which the chroma hold and post filter read
    network = unpack_denoiser_output(output, layers["albedo"], gains)
    return atrous_filter(match_sample_chroma(network, color, exposure), layers["albedo"], layers["normal"],
                         layers["depth"], exposure=exposure)


@pytest.mark.parametrize("precision, tolerance", [("fp32", 1e-3), ("fp16", 3e-2)])
def test_denoise_matches_onnxruntime(precision, tolerance, gpu, tmp_path):
    pytest.importorskip("wgpu_rt.nn")
    if precision == "fp16" and not gpu.has_f16:
        pytest.skip("no shader-f16 on this adapter")
    import onnxruntime

    torch.manual_seed(0)
    model = export_onnx(UNet(widths=(4, 8)), tmp_path / "tiny.onnx")
    color, layers = _render_like()
    write_exr(tmp_path / "in.exr", color, layers, attributes=AUX_ALBEDO)
    assert main(["denoise", str(tmp_path / "in.exr"), "--out", str(tmp_path / "out.exr"), "--model", str(model),
                 "--precision", precision]) == 0
    written = read_exr(tmp_path / "out.exr")
    np.testing.assert_allclose(written["depth"], layers["depth"], rtol=1e-6)
    x = _packed_for_a_model_without_exposure(color, layers)
    session = onnxruntime.InferenceSession(str(model), providers=["CPUExecutionProvider"])
    expected = _chain_after_the_network(session.run(None, {"input": x})[0][0, :, :20, :28], color, layers)
    np.testing.assert_allclose(written["color"], expected, rtol=tolerance, atol=tolerance / 10)


def test_a_point_sampled_albedo_is_smoothed_by_a_gaussian_narrowing_with_its_samples():
    """area_averaged_albedo: a Gaussian of 0.9/sqrt(N) px, normalised (a flat albedo stays flat), symmetric
    about a step, and the identity for N = 0 (an aux-pass albedo) or N large enough to make it negligible."""
    from wgpu_rt.frame.area_albedo import area_averaged_albedo

    step = np.zeros((9, 12, 3), np.float32)
    step[:, 6:] = 1.0
    one, four = area_averaged_albedo(step, 1), area_averaged_albedo(step, 4)
    np.testing.assert_allclose(one[:, 5] + one[:, 6], 1.0, rtol=1e-6)            # symmetric about the step
    # beside the step, the taps past it: 0.28 of a sampled Gaussian of 0.9 px, 0.07 of one of 0.45 px
    assert 0.26 < one[0, 5, 0] < 0.30 and 0.06 < four[0, 5, 0] < 0.09
    np.testing.assert_allclose(area_averaged_albedo(np.full((5, 7, 3), 0.3, np.float32), 1), 0.3, rtol=1e-6)
    for samples in (0, 100):
        assert area_averaged_albedo(step, samples) is step


def test_the_sky_of_another_renderer_gets_our_albedo_there():
    """Nothing hit (depth 0) and a black albedo: the albedo becomes the colour clamped to 1, what our tracer
    writes for escaped paths; hit pixels, and misses that already have an albedo, keep theirs."""
    from wgpu_rt.frame.denoise import escaped_albedo

    color = np.array([[[0.2, 0.5, 3.0], [0.4, 0.4, 0.4], [0.9, 0.1, 0.1]]], np.float32)
    albedo = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.3, 0.3, 0.3]]], np.float32)
    depth = np.array([[[0.0], [2.0], [0.0]]], np.float32)
    expected = [[0.2, 0.5, 1.0], [0, 0, 0], [0.3] * 3]
    np.testing.assert_allclose(escaped_albedo(albedo, color, depth)[0], expected, rtol=1e-6)
    assert escaped_albedo(albedo, color, depth + 1) is albedo


def test_the_albedo_is_smoothed_unless_the_aux_pass_averaged_it(gpu, tmp_path, monkeypatch, capfd):
    """`wgpu-rt denoise` smooths the albedo by the colour's samples (another renderer's file) or by
    --albedo-samples, and leaves an albedo that our aux pass averaged (the file's wgpuRtAuxSamples) as it is.
    A file without an 'spp' layer, and no --spp, is taken as 1 sample a pixel, with a warning saying so."""
    import wgpu_rt.frame.denoise as frame_denoise
    from wgpu_rt.frame.area_albedo import area_averaged_albedo

    seen = []   # the albedo each run hands the denoiser
    monkeypatch.setattr(frame_denoise, "denoise", lambda model, color, albedo, *rest, **options: seen.append(albedo)
                        or color)
    torch.manual_seed(0)
    model = export_onnx(UNet(widths=(4, 8)), tmp_path / "tiny.onnx")
    color, layers = _render_like()
    for name, attributes in (("theirs.exr", None), ("ours.exr", AUX_ALBEDO)):
        write_exr(tmp_path / name, color, {**layers, "spp": np.full((20, 28), 4.0)}, attributes=attributes)
    run = lambda name, *flags: main(["denoise", str(tmp_path / name), "--out", str(tmp_path / "o.exr"),  # noqa: E731
                                     "--model", str(model), *flags])
    assert run("theirs.exr") == 0 and run("theirs.exr", "--albedo-samples", "1") == 0
    assert run("theirs.exr", "--albedo-samples", "0") == 0 and run("ours.exr") == 0
    assert run("ours.exr", "--albedo-samples", "4") == 0
    by_four, by_one = (area_averaged_albedo(np.float32(layers["albedo"]), n) for n in (4, 1))
    np.testing.assert_allclose(seen[0], by_four, rtol=1e-6)
    np.testing.assert_allclose(seen[1], by_one, rtol=1e-6)
    np.testing.assert_array_equal(seen[2], np.float32(layers["albedo"]))
    np.testing.assert_array_equal(seen[3], np.float32(layers["albedo"]))
    np.testing.assert_allclose(seen[4], by_four, rtol=1e-6)
    assert run("theirs.exr", "--albedo-samples", "-1") == 2
    capfd.readouterr()
    write_exr(tmp_path / "no_spp.exr", color, layers)
    assert run("no_spp.exr") == 0
    assert capfd.readouterr().err == (f"wgpu-rt denoise: warning: {tmp_path / 'no_spp.exr'}: no 'spp' layer; taken "
                                      "as 1 sample a pixel (--spp N to say how many)\n")
    assert run("no_spp.exr", "--spp", "2") == 0 and capfd.readouterr().err == ""


def _write_other_renderers_exr(path, color, layers):
    """An EXR as another renderer writes one: layers under names of its own, an alpha beside the colour,
    channels stored in whatever order the writer's dictionary had (alphabetical here)."""
    import OpenEXR

    h, w = color.shape[:2]
    planes = {"ViewLayer.Combined": np.dstack([color, np.full((h, w), 0.5)]), "ViewLayer.Denoising Albedo":
              layers["albedo"], "ViewLayer.Denoising Normal": layers["normal"], "ViewLayer.Z": layers["depth"],
              "ViewLayer.Diffuse": layers["albedo"][..., ::-1]}
    names = {"ViewLayer.Combined": "RGBA", "ViewLayer.Denoising Normal": "XYZ", "ViewLayer.Z": "V"}
    channels = {f"{layer}.{c}": np.ascontiguousarray(planes[layer][..., i], np.float32)
                for layer in planes for i, c in enumerate(names.get(layer, "RGB"))}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, dict(sorted(channels.items()))) as exr:
        exr.write(str(path))
    return channels


def test_another_renderers_layers_are_read_by_role_and_kept_in_the_output(gpu, tmp_path):
    """`--layer ROLE=NAME` reads each input from the layer another renderer named; the result equals our own
    file's, and the output keeps every layer and channel name of the input, the colour's alpha included,
    with the denoised colour in that layer's R, G, B."""
    torch.manual_seed(0)
    model = export_onnx(UNet(widths=(4, 8)), tmp_path / "tiny.onnx")
    color, layers = _render_like()
    write_exr(tmp_path / "ours.exr", color, layers)
    assert main(["denoise", str(tmp_path / "ours.exr"), "--out", str(tmp_path / "ours_out.exr"),
                 "--model", str(model)]) == 0
    channels = _write_other_renderers_exr(tmp_path / "theirs.exr", color, layers)
    assert main(["denoise", str(tmp_path / "theirs.exr"), "--out", str(tmp_path / "theirs_out.exr"),
                 "--model", str(model), "--layer", "color=ViewLayer.Combined",
                 "--layer", "albedo=ViewLayer.Denoising Albedo", "--layer", "normal=ViewLayer.Denoising Normal",
                 "--layer", "depth=ViewLayer.Z"]) == 0
    ours, theirs = read_exr(tmp_path / "ours_out.exr"), read_exr(tmp_path / "theirs_out.exr")
    combined = theirs["ViewLayer.Combined"]
    np.testing.assert_allclose(combined[..., :3], ours["color"], rtol=1e-5, atol=1e-6)
    np.testing.assert_array_equal(combined[..., 3], 0.5)
    np.testing.assert_allclose(theirs["color"], ours["color"], rtol=1e-5, atol=1e-6)   # none of its own
    np.testing.assert_array_equal(theirs["ViewLayer.Diffuse"], np.float32(layers["albedo"][..., ::-1]))
    assert set(theirs.channels) == {"color", *(name.rpartition(".")[0] for name in channels)}
    assert {f"{layer}.{c}" for layer, names in theirs.channels.items() if layer != "color"
            for c in names} == set(channels)


@pytest.mark.parametrize("flags, says", [
    (["--layer", "albedo"], "--layer 'albedo': expected ROLE=NAME"),
    (["--layer", "shadow=ViewLayer.Z"], "--layer 'shadow=ViewLayer.Z': expected ROLE=NAME with ROLE one of color"),
    (["--layer", "depth=ViewLayer.Z", "--layer", "depth=ViewLayer.Combined"], "depth is already read from"),
    (["--layer", "depth=Mist"], "theirs.exr: no layer 'Mist' (--layer depth=Mist); layers present: ViewLayer"),
    (["--layer", "albedo=ViewLayer.Diffuse", "--layer", "normal=ViewLayer.Denoising Normal",
      "--layer", "depth=ViewLayer.Combined"], "layer 'ViewLayer.Combined' has 4 channel(s); depth needs exactly one"),
    ([], "theirs.exr: no layer 'ViewLayer.Denoising Depth': Blender writes the Denoising Data passes when View "
         "Layer Properties ▸ Passes ▸ Data ▸ Denoising Data is on (--layer depth=NAME reads it from another layer)"),
    (["--layer", "depth=ViewLayer.Z", "--layer", "albedo=Diffuse"], "theirs.exr: no layer 'Diffuse' (--layer "
     "albedo=Diffuse); layers present: ViewLayer.Combined, ViewLayer.Denoising Albedo, ViewLayer.Denoising Normal, "
     "ViewLayer.Diffuse, ViewLayer.Z"),
])
def test_bad_layer_flags_are_one_line_before_any_output(flags, says, tmp_path, capfd):
    color, layers = _render_like()
    _write_other_renderers_exr(tmp_path / "theirs.exr", color, layers)
    assert main(["denoise", str(tmp_path / "theirs.exr"), "--out", str(tmp_path / "o.exr"),
                 "--layer", "color=ViewLayer.Combined", *flags]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and says in err, err
    assert not (tmp_path / "o.exr").exists()


def test_a_blender_file_is_denoised_without_flags(gpu, tmp_path, capfd):
    """Blender's multilayer EXR (a part per pass): its view layer's Combined, Denoising Albedo/Normal/Depth passes
    and the header's sample count are found by their names, so `wgpu-rt denoise FILE` gives what our own file
    of the same planes gives with --spp; its Z pass (1e10 where nothing was hit) read as depth is the same
    as its Denoising Depth (0 there); the output keeps the file's passes, the Combined pass denoised, and its
    header's attributes, less those that laid out the input's parts."""
    torch.manual_seed(0)
    model = export_onnx(UNet(widths=(4, 8)), tmp_path / "tiny.onnx")
    color, layers = _render_like()
    layers["depth"][:3] = 0   # sky
    write_exr(tmp_path / "ours.exr", color, layers)
    write_blender_exr(tmp_path / "blender.exr", color, layers, samples=4)

    def run(name, *flags):
        return main(["denoise", str(tmp_path / name), "--out", str(tmp_path / f"{name}.out.exr"), "--model", str(model),
                     *flags])
    assert run("ours.exr", "--spp", "4") == 0 and run("blender.exr") == 0
    assert run("blender.exr", "--layer", "depth=ViewLayer.Depth", "--out", str(tmp_path / "z.exr")) == 0
    assert capfd.readouterr().err == ""   # no "no 'spp' layer" warning: the header said 4
    ours, blender = read_exr(tmp_path / "ours.exr.out.exr"), read_exr(tmp_path / "blender.exr.out.exr")
    np.testing.assert_allclose(blender["ViewLayer.Combined"][..., :3], ours["color"], rtol=1e-5, atol=1e-6)
    np.testing.assert_array_equal(blender["ViewLayer.Combined"][..., 3], 1.0)
    np.testing.assert_array_equal(read_exr(tmp_path / "z.exr")["ViewLayer.Combined"], blender["ViewLayer.Combined"])
    assert {"ViewLayer.Depth", "ViewLayer.Normal", "ViewLayer.Denoising Albedo"} <= set(blender)
    assert blender.attributes == {"BlenderMultiChannel": "Blender V2.55.1 and newer", "cycles.ViewLayer.samples": "4"}


@pytest.mark.parametrize("write, flags, says", [
    (dict(view_layers=("Front", "Back")), [], "blender.exr: view layers Back, Front: --layer color=VL.Combined picks one"),
    (dict(), ["--layer", "color=Side.Combined"], "blender.exr: no layer 'Side.Combined' (--layer color=Side.Combined); "
                                                 "layers present: ViewLayer.Combined, "),
    (dict(denoising_data=False), [], "blender.exr: no layer 'ViewLayer.Denoising Albedo': Blender writes the "
                                     "Denoising Data passes when View Layer Properties ▸ Passes ▸ Data ▸ Denoising "
                                     "Data is on (--layer albedo=NAME reads it from another layer)"),
])
def test_blender_files_without_one_view_layers_denoising_passes_are_one_line(write, flags, says, tmp_path, capfd):
    color, layers = _render_like()
    write_blender_exr(tmp_path / "blender.exr", color, layers, **write)
    assert main(["denoise", str(tmp_path / "blender.exr"), "--out", str(tmp_path / "o.exr"), *flags]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and says in err, err
    assert not (tmp_path / "o.exr").exists()


def test_a_view_layer_is_picked_by_its_combined_pass(gpu, tmp_path, capfd):
    """With several view layers, --layer color=VL.Combined picks VL's passes and its header sample count."""
    torch.manual_seed(0)
    model = export_onnx(UNet(widths=(4, 8)), tmp_path / "tiny.onnx")
    color, layers = _render_like()
    write_blender_exr(tmp_path / "two.exr", color, layers, view_layers=("Front", "Back"), samples=2)
    write_blender_exr(tmp_path / "one.exr", color, layers, samples=2)
    for name, flags in (("two.exr", ["--layer", "color=Back.Combined"]), ("one.exr", [])):
        assert main(["denoise", str(tmp_path / name), "--out", str(tmp_path / f"{name}.out.exr"), "--model",
                     str(model), *flags]) == 0
    assert capfd.readouterr().err == ""
    picked = read_exr(tmp_path / "two.exr.out.exr")
    np.testing.assert_array_equal(picked["Back.Combined"], read_exr(tmp_path / "one.exr.out.exr")["ViewLayer.Combined"])
    np.testing.assert_array_equal(picked["Front.Combined"][..., :3], np.float32(color))   # the other left as it was


def test_quality_high_averages_four_turned_passes(gpu, tmp_path, capsys):
    """`--quality high`: the mean of the network over the image as given and turned 90°, 180°, 270°."""
    import onnxruntime

    torch.manual_seed(0)
    model = export_onnx(UNet(widths=(4, 8)), tmp_path / "tiny.onnx")
    color, layers = _render_like()
    write_exr(tmp_path / "in.exr", color, layers, attributes=AUX_ALBEDO)
    assert main(["denoise", str(tmp_path / "in.exr"), "--out", str(tmp_path / "out.exr"), "--model", str(model),
                 "--quality", "high"]) == 0
    assert ", high, " in capsys.readouterr().out
    x = _packed_for_a_model_without_exposure(color, layers)
    session = onnxruntime.InferenceSession(str(model), providers=["CPUExecutionProvider"])
    turned = [np.rot90(session.run(None, {"input": np.ascontiguousarray(np.rot90(x, k, axes=(2, 3)))})[0], -k,
                       axes=(2, 3)) for k in range(4)]
    expected = _chain_after_the_network(np.mean(turned, axis=0)[0], color, layers)
    np.testing.assert_allclose(read_exr(tmp_path / "out.exr")["color"], expected, rtol=1e-3, atol=1e-4)


def test_a_png_output_is_the_denoised_exr_tone_mapped_for_display(gpu, tmp_path, capsys):
    """`--out x.png` writes the colour the EXR output holds, through ACES and sRGB as `render --out x.png` does."""
    from PIL import Image

    from wgpu_rt.frame.tonemap import tonemap

    torch.manual_seed(0)
    model = export_onnx(UNet(widths=(4, 8)), tmp_path / "tiny.onnx")
    color, layers = _render_like()
    write_exr(tmp_path / "in.exr", color, layers, attributes=AUX_ALBEDO)
    for out in ("out.exr", "out.png"):
        assert main(["denoise", str(tmp_path / "in.exr"), "--out", str(tmp_path / out), "--model", str(model)]) == 0
    assert "out.png" in capsys.readouterr().out
    png = np.asarray(Image.open(tmp_path / "out.png"), dtype=np.float32) / 255
    expected = tonemap(read_exr(tmp_path / "out.exr")["color"], "aces", output="f32")[..., :3]
    assert png.shape == color.shape and np.abs(png - expected).max() <= 0.5 / 255 + 1e-6
    assert main(["denoise", str(tmp_path / "in.exr"), "--out", str(tmp_path / "out.png"), "--model", str(model),
                 "--tonemap", "reinhard", "--exposure", "2"]) == 0
    png = np.asarray(Image.open(tmp_path / "out.png"), dtype=np.float32) / 255
    expected = tonemap(read_exr(tmp_path / "out.exr")["color"], "reinhard", 2.0, output="f32")[..., :3]
    assert np.abs(png - expected).max() <= 0.5 / 255 + 1e-6


def test_the_python_call_gives_what_the_command_writes(gpu, tmp_path):
    """`wgpu_rt.denoise(color, albedo, normal, depth, spp)` on arrays equals `wgpu-rt denoise` on the same layers
    in a file (another renderer's: its albedo smoothed by the colour's samples), with a sample-count map and
    the half layers; a second call loads nothing again."""
    import wgpu_rt
    from wgpu_rt import renderer

    torch.manual_seed(0)
    model = export_onnx(UNet(widths=(4, 8)), tmp_path / "tiny.onnx")
    color, layers = _render_like()
    spp = np.random.default_rng(1).integers(2, 9, size=color.shape[:2] + (1,)).astype(np.float32)
    half = color * np.float32(0.9)
    write_exr(tmp_path / "in.exr", color, {**layers, "spp": spp, "half_radiance": half, "half_spp": spp // 2})
    assert main(["denoise", str(tmp_path / "in.exr"), "--out", str(tmp_path / "out.exr"), "--model", str(model)]) == 0
    given = [layers["albedo"], layers["normal"], layers["depth"][..., 0]]
    called = wgpu_rt.denoise(color, *given, spp[..., 0], half=(half, spp[..., 0] // 2), model=model)
    np.testing.assert_allclose(called, read_exr(tmp_path / "out.exr")["color"], rtol=1e-5, atol=1e-6)
    loaded = len(renderer._DENOISERS)
    again = wgpu_rt.denoise(color, *given, spp, half=(half, spp // 2), model=model)
    assert len(renderer._DENOISERS) == loaded and np.array_equal(again, called)


def test_a_file_without_depth_is_denoised_with_one_warning(gpu, tmp_path, capfd):
    """OIDN's three inputs (colour, albedo, normal) are enough: the command says once that it reads no depth, and
    writes what `wgpu_rt.denoise(..., depth=None)` gives, which is not what it gives with the file's depth."""
    import wgpu_rt

    torch.manual_seed(0)
    model = export_onnx(UNet(widths=(4, 8)), tmp_path / "tiny.onnx")
    color, layers = _render_like()
    write_exr(tmp_path / "in.exr", color, {"albedo": layers["albedo"], "normal": layers["normal"]})
    assert main(["denoise", str(tmp_path / "in.exr"), "--out", str(tmp_path / "out.exr"), "--model", str(model),
                 "--spp", "2"]) == 0
    err = capfd.readouterr().err
    assert err.count("warning") == 1 and f"{tmp_path / 'in.exr'}: no 'depth' layer; denoised without one" in err
    without = wgpu_rt.denoise(color, layers["albedo"], layers["normal"], None, 2, model=model)
    np.testing.assert_allclose(read_exr(tmp_path / "out.exr")["color"], without, rtol=1e-5, atol=1e-6)
    with_depth = wgpu_rt.denoise(color, layers["albedo"], layers["normal"], layers["depth"], 2, model=model)
    assert not np.allclose(with_depth, without, atol=1e-4)


def test_several_inputs_are_denoised_with_the_model_loaded_once(gpu, tmp_path, capfd, monkeypatch):
    """A sequence's frames in one command: each output ({name}: the input's stem) equals the file denoised alone,
    the model is loaded once, and a warning that holds for every input is said once."""
    from wgpu_rt.commands import denoise as command
    from wgpu_rt.frame import denoise as frame_denoise

    torch.manual_seed(0)
    model = export_onnx(UNet(widths=(4, 8)), tmp_path / "tiny.onnx")
    for k in range(3):
        color, layers = _render_like(seed=k)
        write_exr(tmp_path / f"f{k}.exr", color, layers)
    loads = []
    load_model = frame_denoise.load_model
    monkeypatch.setattr(frame_denoise, "load_model", lambda *a, **k: loads.append(1) or load_model(*a, **k))
    inputs = [str(tmp_path / f"f{k}.exr") for k in range(3)]
    assert main(["denoise", *inputs, "--out", str(tmp_path / "out" / "{name}_clean.exr"), "--model", str(model)]) == 0
    err = capfd.readouterr().err
    assert len(loads) == 1 and err.count("no 'spp' layer") == 1 and "and for any other input like it" in err
    for k in (0, 2):
        assert main(["denoise", inputs[k], "--out", str(tmp_path / "alone.exr"), "--model", str(model)]) == 0
        np.testing.assert_array_equal(read_exr(tmp_path / "out" / f"f{k}_clean.exr")["color"],
                                      read_exr(tmp_path / "alone.exr")["color"])
    assert command.output_paths(["a/x.exr"], "{name}.png")[0].name == "x.png"


@pytest.mark.parametrize("outputs, says", [
    (["OUT/clean.exr"], "several inputs need a {name} field"),
    (["OUT/{name}.exr"], "two inputs would both write"),
    (["IN/{name}.exr"], "would overwrite its input"),
    (["OUT/{name}{nam}.exr"], "bad format field"),
])
def test_several_inputs_refuse_outputs_that_clash_before_any_work(outputs, says, tmp_path, capfd):
    color, layers = _render_like()
    (tmp_path / "a").mkdir()
    for path in (tmp_path / "x.exr", tmp_path / "a" / "x.exr"):
        write_exr(path, color, layers)
    inputs = [str(tmp_path / "x.exr"), str(tmp_path / "a" / "x.exr")]
    out = outputs[0].replace("OUT", str(tmp_path / "out")).replace("IN", str(tmp_path))
    assert main(["denoise", *inputs, "--out", out]) == 2
    assert says in capfd.readouterr().err and not (tmp_path / "out").exists()


def test_a_missing_input_among_several_stops_before_any_output(tmp_path, capfd):
    color, layers = _render_like()
    write_exr(tmp_path / "f0.exr", color, layers)
    assert main(["denoise", str(tmp_path / "f0.exr"), str(tmp_path / "f1.exr"), "--out",
                 str(tmp_path / "out" / "{name}.exr")]) == 2
    assert f"{tmp_path / 'f1.exr'}: no such file" in capfd.readouterr().err and not (tmp_path / "out").exists()


@pytest.mark.parametrize("change, says", [
    ({"color": np.zeros((4, 4))}, "color must be (H, W, 3), got shape (4, 4)"),
    ({"albedo": np.zeros((5, 4, 3))}, "albedo is 4×5, the colour 28×20"),
    ({"depth": "deep"}, "depth must be an image"),
    ({"spp": 0}, "spp must be a sample count ≥ 1"),
    ({"spp": np.ones((20, 27))}, "spp must be a sample count or an (H, W) map"),
    ({"half": np.zeros((20, 28, 3))}, "half must be (mean, counts)"),
    ({"quality": "best"}, "quality 'best'"),
    ({"albedo_samples": -1}, "albedo_samples must be"),
])
def test_the_python_call_names_a_bad_argument_before_any_work(change, says):
    import wgpu_rt
    from wgpu_rt.errors import WgpuRtError

    color, layers = _render_like()
    arguments = {"color": color, "albedo": layers["albedo"], "normal": layers["normal"], "depth": layers["depth"],
                 **change}
    with pytest.raises(WgpuRtError, match=re.escape(says)):
        wgpu_rt.denoise(**arguments)


def test_the_python_call_turns_nan_and_inf_into_a_finite_image(gpu, tmp_path):
    import wgpu_rt

    torch.manual_seed(0)
    model = export_onnx(UNet(widths=(4, 8)), tmp_path / "tiny.onnx")
    color, layers = _render_like()
    color[2, 3], color[5, 6, 1], layers["normal"][1, 1] = np.nan, np.inf, -np.inf
    out = wgpu_rt.denoise(color, layers["albedo"], layers["normal"], layers["depth"], 4, model=model)
    assert out.shape == color.shape and out.dtype == np.float32 and np.all(np.isfinite(out)) and out.min() >= 0


class NumpyPath:
    """The same network without ``record``: ``denoise`` then takes the numpy references of every pass."""

    def __init__(self, model):
        self.model, self.input_channels, self.graph = model, model.input_channels, model.graph

    def __call__(self, x):
        return self.model(x)


def test_white_balance_setting_on_the_device_and_the_command(gpu, tmp_path):
    """``wgpu-rt denoise --white-balance on|off`` writes what ``denoise()`` gives with that setting, on the
    device as by the numpy references; on a frame with a colour cast the two differ. ``render`` refuses the
    flag without --denoise, before writing anything."""
    from wgpu_rt.frame.denoise import denoise, load_model

    color, layers = _render_like(h=17, w=22, seed=8)
    color *= np.array([0.2, 1.5, 0.5], np.float32)                      # a green cast
    write_exr(tmp_path / "in.exr", color, layers, attributes=AUX_ALBEDO)
    aux = (layers["albedo"], layers["normal"], layers["depth"])
    model = load_model("denoiser", "fp32", ctx=gpu)
    written = {}
    for setting in ("on", "off"):
        out = tmp_path / f"{setting}.exr"
        assert main(["denoise", str(tmp_path / "in.exr"), "--out", str(out), "--white-balance", setting,
                     "--precision", "fp32"]) == 0
        written[setting] = read_exr(out)["color"]
        expected = denoise(model, color, *aux, white_balance=setting == "on")
        np.testing.assert_allclose(written[setting], expected, rtol=1e-4, atol=1e-5)
        np.testing.assert_allclose(expected, denoise(NumpyPath(model), color, *aux, white_balance=setting == "on"),
                                   rtol=1e-4, atol=1e-5)
    assert not np.allclose(written["on"], written["off"], rtol=1e-3, atol=1e-4)
    assert main(["render", "cornell", "--size", "8x8", "--white-balance", "off", "--out", str(tmp_path / "x.exr")]) == 2
    assert not (tmp_path / "x.exr").exists()


def test_auto_exposure_denoises_a_frame_alike_at_any_scale_of_its_light(gpu, tmp_path):
    """With the exposure step a frame at 2^-6 or 2^5 of its light denoises to that scale of the frame's
    own result (the chroma hold and the post filter read the frame at one key either way); without it the
    shipped network reads each scale differently. By default the step runs as the model's ONNX file says it
    was trained (the shipped one says on; a file that says nothing runs without it); ``wgpu-rt denoise
    --auto-exposure on|off|auto`` writes
    what ``denoise()`` gives so, on the device as by the numpy references; ``render`` refuses the flag
    without --denoise."""
    from wgpu_rt.frame.denoise_chain import INPUT_EXPOSURE
    from wgpu_rt.frame.denoise import denoise, load_model

    color, layers = _render_like(h=24, w=30, seed=9)
    aux = (layers["albedo"], layers["normal"], layers["depth"])
    model = load_model("denoiser", "fp32", ctx=gpu)
    for auto in (True, False):
        base = denoise(model, color, *aux, 4, auto_exposure=auto)
        np.testing.assert_allclose(base, denoise(NumpyPath(model), color, *aux, 4, auto_exposure=auto),
                                   rtol=1e-4, atol=1e-5)
        moved = max(np.abs(denoise(model, 2.0 ** stops * color, *aux, 4, auto_exposure=auto) / 2.0 ** stops
                           - base).max() for stops in (-6, 5))
        if auto:
            assert moved < 1e-5 * base.max()
        else:
            assert moved > 0.02 * base.max()
    write_exr(tmp_path / "in.exr", color, layers, attributes=AUX_ALBEDO)
    torch.manual_seed(1)
    tiny = export_onnx(UNet(widths=(4, 8)), tmp_path / "tiny.onnx", metadata={INPUT_EXPOSURE: "on"})
    silent = export_onnx(UNet(widths=(4, 8)), tmp_path / "silent.onnx")   # trained before the step existed
    for path, flag, auto in ((None, "off", False), (None, "auto", True), (tiny, "auto", True), (tiny, "off", False),
                             (silent, "auto", False)):
        chosen = model if path is None else load_model("denoiser", "fp32", path=path, ctx=gpu)
        expected = denoise(chosen, color, *aux, auto_exposure=auto)
        if flag == "auto":
            np.testing.assert_array_equal(denoise(chosen, color, *aux), expected)
        out = tmp_path / "out.exr"
        assert main(["denoise", str(tmp_path / "in.exr"), "--out", str(out), "--auto-exposure", flag,
                     "--precision", "fp32", *(["--model", str(path)] if path else [])]) == 0
        np.testing.assert_allclose(read_exr(out)["color"], expected, rtol=1e-4, atol=1e-5)
    assert not np.allclose(denoise(chosen, color, *aux, auto_exposure=True), expected, rtol=1e-3, atol=1e-4)
    assert main(["render", "cornell", "--size", "8x8", "--auto-exposure", "off", "--out", str(tmp_path / "x.exr")]) == 2
    assert not (tmp_path / "x.exr").exists()
    # the small networks read their input at a key too: the flag goes with --adaptive (or --temporal) alone
    assert main(["render", "cornell", "--size", "8x8", "--adaptive", "2", "--auto-exposure", "on",
                 "--out", str(tmp_path / "x.exr")]) == 0


def test_denoise_runs_on_the_device_as_the_numpy_references_do(gpu, tmp_path):
    """A WGSL model denoises on the device (the frame loop's passes, the low band included at 256² and
    up, a sample-count map), equal to the numpy references of those passes; counts the u32 plane
    cannot hold exactly (fractional ones) take the numpy path."""
    from wgpu_rt.frame import denoise as denoise_module
    from wgpu_rt.frame.denoise import DenoiseOnDevice, denoise, device_sample_counts, load_model

    torch.manual_seed(3)
    path = export_onnx(UNet(widths=(4, 8)), tmp_path / "on_device.onnx")
    model = load_model("denoiser", "fp32", path=path, ctx=gpu)
    color, layers = _render_like(h=256, w=264, seed=5)
    aux = (layers["albedo"], layers["normal"], layers["depth"])
    counts = np.random.default_rng(1).integers(1, 9, (256, 264, 1))
    on_device = denoise(model, color, *aux, counts)
    made = DenoiseOnDevice._made[model]
    assert [key[2] for key in made] == [1]   # one coarser level: the low band ran
    np.testing.assert_allclose(on_device, denoise(NumpyPath(model), color, *aux, counts), rtol=1e-4, atol=1e-5)
    default = load_model("denoiser", path=path, ctx=gpu)
    if default.precision is not model.precision:   # fp16 activations, a GPU's default: within fp16's rounding
        np.testing.assert_allclose(denoise(default, color, *aux, counts),
                                   denoise(NumpyPath(default), color, *aux, counts), rtol=1e-2, atol=1e-3)
    del default
    assert device_sample_counts(2.5, (4, 4)) is None and device_sample_counts(np.nan, (4, 4)) is None
    assert device_sample_counts(4, (2, 3)).tolist() == [[4] * 3] * 2
    half = (color * 0.9, np.maximum(counts[..., 0] // 2, 1))   # a first part of the samples to hand over to
    handed_over = denoise(model, color, *aux, counts, half=half)
    np.testing.assert_allclose(handed_over, denoise(NumpyPath(model), color, *aux, counts, half=half),
                               rtol=1e-4, atol=1e-5)
    assert not np.allclose(handed_over, on_device, atol=1e-3)
    made.clear()
    small = [image[:20, :28] for image in (color, *aux)]
    np.testing.assert_allclose(denoise(model, *small, 2.5), denoise(NumpyPath(model), *small, 2.5),
                               rtol=1e-4, atol=1e-5)
    assert not denoise_module.DenoiseOnDevice._made[model]
    denoise(model, *small, 2)
    assert len(DenoiseOnDevice._made[model]) == 1
    for size in range(4, 4 + denoise_module.KEPT_SIZES + 1):   # only the sizes used last stay set up
        denoise(model, *[image[:size, :size] for image in (color, *aux)], 2)
    assert [key[:2] for key in made] == [(size, size) for size in range(5, 5 + denoise_module.KEPT_SIZES)]
    denoise(model, *[image[:5, :5] for image in (color, *aux)], 2)   # used again: now the last to go
    assert list(made)[-1][:2] == (5, 5)
    del model, made
    gc.collect()
    assert not [m for m in DenoiseOnDevice._made if m.path.endswith("on_device.onnx")]   # the cache let it go


def test_the_sample_count_comes_from_the_spp_layer_or_the_flag(gpu, tmp_path, capsys):
    """The network is told the colour's spp: the input's 'spp' layer (what `wgpu-rt render` writes), which
    --spp overrides; a 10-input denoiser (trained before the plane existed) still runs. A malformed layer
    is one line naming the file."""
    pytest.importorskip("wgpu_rt.nn")
    from wgpu_rt.frame.denoise import denoise, load_model

    torch.manual_seed(1)
    model_path = export_onnx(UNet(widths=(4, 8)), tmp_path / "tiny.onnx")
    model = load_model("denoiser", path=model_path)
    color, layers = _render_like()
    counts = np.random.default_rng(0).integers(1, 300, (20, 28, 1))
    write_exr(tmp_path / "in.exr", color, layers | {"spp": counts.astype(np.float32)}, attributes=AUX_ALBEDO)
    out = lambda *flags: main(["denoise", str(tmp_path / "in.exr"), "--out", str(tmp_path / "o.exr"),  # noqa: E731
                               "--model", str(model_path), *flags]) or read_exr(tmp_path / "o.exr")["color"]
    aux = (layers["albedo"], layers["normal"], layers["depth"])
    np.testing.assert_allclose(out(), denoise(model, color, *aux, counts), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(out("--spp", "16"), denoise(model, color, *aux, 16), rtol=1e-5, atol=1e-6)
    assert not np.allclose(denoise(model, color, *aux, 1), denoise(model, color, *aux, 16), atol=1e-4)

    ten = export_onnx(UNet(in_channels=10, widths=(4, 8)), tmp_path / "ten.onnx")
    assert main(["denoise", str(tmp_path / "in.exr"), "--out", str(tmp_path / "o10.exr"), "--model", str(ten)]) == 0

    write_exr(tmp_path / "bad.exr", color, layers | {"spp": np.full((20, 28, 1), -1, np.float32)})
    capsys.readouterr()
    assert main(["denoise", str(tmp_path / "bad.exr"), "--out", str(tmp_path / "b.exr"), "--model", str(model_path)]) == 2
    assert f"{tmp_path / 'bad.exr'}: layer 'spp' must be one channel" in capsys.readouterr().err
    assert not (tmp_path / "b.exr").exists()


def test_a_render_with_half_layers_hands_over_as_the_fused_frame_does(gpu, tmp_path, capsys):
    """`wgpu-rt render --aov …,half_radiance,half_spp` writes the mean after the first half of the
    samples; `wgpu-rt denoise` then blends per pixel with the converge reference, as a denoised render of
    that many spp does on the device. One half layer without the other is one line naming the file."""
    pytest.importorskip("wgpu_rt.nn")
    from wgpu_rt.frame.converge import converge
    from wgpu_rt.frame.area_albedo import area_averaged_albedo
    from wgpu_rt.frame.denoise import denoise, load_model
    from wgpu_rt.renderer import render

    torch.manual_seed(2)
    model_path = export_onnx(UNet(widths=(4, 8)), tmp_path / "tiny.onnx")
    noisy = tmp_path / "noisy.exr"
    assert main(["render", "cornell", "--spp", "8", "--size", "16x12", "--seed", "4", "--out", str(noisy),
                 "--aov", "albedo,normal,depth,spp,half_radiance,half_spp"]) == 0
    layers = read_exr(noisy)
    assert (layers["half_spp"] == 4).all() and (layers["spp"] == 8).all()
    half = render("cornell", spp=4, size=(16, 12), seed=4, aovs=()).color   # the same first 4 samples
    np.testing.assert_allclose(layers["half_radiance"], half, rtol=1e-5, atol=1e-6)
    assert main(["denoise", str(noisy), "--out", str(tmp_path / "o.exr"), "--model", str(model_path)]) == 0
    model = load_model("denoiser", path=model_path)
    assert read_exr(noisy).attributes["wgpuRtAuxSamples"] == 0   # the albedo of the colour's 8 samples: smoothed
    aux = [area_averaged_albedo(layers["albedo"], 8), layers["normal"], layers["depth"]]
    denoised = denoise(model, layers["color"], *aux, layers["spp"])
    expected = converge(denoised, layers["color"], np.full((12, 16), 8), half, np.full((12, 16), 4))
    np.testing.assert_allclose(read_exr(tmp_path / "o.exr")["color"], expected, rtol=1e-5, atol=1e-6)
    assert not np.allclose(expected, denoised, atol=1e-4)

    write_exr(tmp_path / "one.exr", layers["color"], {k: v for k, v in layers.items() if k not in ("color", "half_spp")})
    capsys.readouterr()
    assert main(["denoise", str(tmp_path / "one.exr"), "--out", str(tmp_path / "b.exr"), "--model", str(model_path)]) == 2
    assert f"{tmp_path / 'one.exr'}: layer 'half_radiance' needs layer 'half_spp' too" in capsys.readouterr().err
    assert not (tmp_path / "b.exr").exists()


def test_nan_and_inf_in_the_layers_are_zeroed_with_one_warning_each(gpu, tmp_path, capfd):
    pytest.importorskip("wgpu_rt.nn")
    import OpenEXR

    torch.manual_seed(0)
    model = export_onnx(UNet(widths=(4, 8)), tmp_path / "tiny.onnx")
    color, layers = _render_like()
    layers["albedo"][:2, :3] = np.nan                  # 18 values
    layers["normal"][0, 0, 1] = np.inf                 # 1 value
    layers["depth"][5, :4] = np.inf                    # 4 values: what a miss can leave
    channels = {f"{name}.{c}": np.ascontiguousarray(layers[name][..., i], np.float32)
                for name, letters in (("albedo", "RGB"), ("normal", "XYZ"), ("depth", "Z"))
                for i, c in enumerate(letters)}
    channels.update({c: np.ascontiguousarray(color[..., i]) for i, c in enumerate("RGB")})
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels) as exr:
        exr.write(str(tmp_path / "in.exr"))     # write_exr refuses NaN, as it should for our own output
    capfd.readouterr()
    assert main(["denoise", str(tmp_path / "in.exr"), "--out", str(tmp_path / "out.exr"),
                 "--model", str(model), "--spp", "1"]) == 0
    warnings = capfd.readouterr().err.splitlines()
    assert sorted(line.split(": ", 3)[-1] for line in warnings) == [
        "layer 'albedo' holds 18 NaN/Inf values; treated as 0",
        "layer 'depth' holds 4 NaN/Inf values; treated as 0",
        "layer 'normal' holds 1 NaN/Inf values; treated as 0"]
    written = read_exr(tmp_path / "out.exr")
    assert all(np.isfinite(plane).all() for plane in written.values())
    assert written["depth"][5, :4].tolist() == [[0.0]] * 4
    np.testing.assert_array_equal(written["depth"][6:], layers["depth"][6:].astype(np.float32))


def _residual_unet_with_a_nonzero_correction():
    net = UNet(widths=(8, 16), residual=True)
    torch.nn.init.normal_(net.head.weight, std=0.1)   # a zero head would hide the correction's path
    return net


@pytest.mark.parametrize("network", ["denoiser", "residual-denoiser", "error-predictor", "confidence"])
def test_exported_models_run_in_the_wgsl_engine_with_parity(network, gpu, tmp_path):
    pytest.importorskip("wgpu_rt.nn")
    import onnxruntime
    from parity import check_parity

    from wgpu_rt.nn import WgslModel

    torch.manual_seed(1)
    net = {"denoiser": lambda: UNet(widths=(8, 16)), "error-predictor": ErrorPredictor,
           "residual-denoiser": _residual_unet_with_a_nonzero_correction,
           "confidence": ConfidencePredictor}[network]()
    path = export_onnx(net, tmp_path / "m.onnx")
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    channels = session.get_inputs()[0].shape[1]
    ours = WgslModel(path)
    check_parity([(1, channels, 16, 24)], lambda x: session.run(None, {"input": x})[0], ours,
                 atol=1e-4, low=0.0, high=2.0, name=network)


def test_shipped_models_have_cards_and_the_default_model_denoises(gpu, tmp_path):
    pytest.importorskip("wgpu_rt.nn")
    from importlib import resources

    from wgpu_rt import metrics

    shipped = resources.files("wgpu_rt.models")
    for name in ("denoiser", "error_predictor", "confidence"):
        assert shipped.joinpath(f"{name}.onnx").is_file(), name
        assert "## Validation" in shipped.joinpath(f"{name}.md").read_text(), name
    # A flat grey wall seen at 1 spp: the shipped denoiser must bring it closer to the clean value.
    rng = np.random.default_rng(4)
    clean = np.full((32, 32, 3), 0.5, np.float32)
    noisy = (clean * rng.gamma(1.0, 1.0, size=clean.shape)).astype(np.float32)
    layers = {"albedo": np.full((32, 32, 3), 0.6), "normal": np.dstack([np.zeros((32, 32, 2)), np.ones((32, 32))]),
              "depth": np.full((32, 32, 1), 3.0)}
    write_exr(tmp_path / "in.exr", noisy, layers)
    assert main(["denoise", str(tmp_path / "in.exr"), "--out", str(tmp_path / "out.exr")]) == 0
    denoised = read_exr(tmp_path / "out.exr")["color"]
    assert metrics.rel_mse(clean, denoised) < metrics.rel_mse(clean, noisy)
