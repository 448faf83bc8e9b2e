"""``wgpu-rt render``: outputs for good arguments, one clear error, exit 2 and no file for bad ones."""

import re

import numpy as np
import pytest

from wgpu_rt.cli import main
from wgpu_rt.io import read_exr
from wgpu_rt.scene import BUILTIN_SCENES


def test_exr_holds_color_and_requested_aovs(gpu, tmp_path):
    out = tmp_path / "c.exr"
    assert main(["render", "cornell", "--spp", "2", "--size", "20x12", "--aov", "albedo,depth",
                 "--out", str(out)]) == 0
    layers = read_exr(out)
    assert layers["color"].shape == (12, 20, 3) and np.all(np.isfinite(layers["color"]))
    assert layers["albedo"].shape == (12, 20, 3) and layers["depth"].shape[:2] == (12, 20)
    assert "normal" not in layers


@pytest.mark.parametrize("flags, aux", [([], 0), (["--aux-samples", "3"], 3), (["--denoise", "--spp", "1"], 4)])
def test_exr_says_whether_its_albedo_came_from_the_aux_pass(flags, aux, gpu, tmp_path):
    """The header's wgpuRtAuxSamples: the aux pass's samples behind the albedo layer (0: the colour's own), which
    `wgpu-rt denoise` reads to know whether the albedo is already averaged over each pixel's area."""
    out = tmp_path / "a.exr"
    assert main(["render", "cornell", "--size", "8x8", "--aov", "albedo", *flags, "--out", str(out)]) == 0
    assert read_exr(out).attributes["wgpuRtAuxSamples"] == aux
    assert main(["render", "cornell", "--size", "8x8", "--aov", "depth", *flags, "--out", str(out)]) == 0
    assert "wgpuRtAuxSamples" not in read_exr(out).attributes


def test_png_preview_and_frame_pattern(gpu, tmp_path):
    assert main(["render", "moving", "--spp", "1", "--size", "8x8", "--frames", "2:4",
                 "--out", str(tmp_path / "f{frame:03d}.png")]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f002.png", "f003.png"]


def test_one_frame_by_its_number(gpu, tmp_path):
    """--frames N renders frame N alone (no {frame} field needed): frame 5 of `moving`, as 5:6 renders it."""
    for frames, name in (("5", "one.exr"), ("5:6", "range_{frame}.exr"), ("0", "first.exr")):
        assert main(["render", "moving", "--spp", "1", "--size", "8x8", "--frames", frames, "--aov", "",
                     "--out", str(tmp_path / name)]) == 0
    one = read_exr(tmp_path / "one.exr")["color"]
    np.testing.assert_array_equal(one, read_exr(tmp_path / "range_5.exr")["color"])
    assert not np.array_equal(one, read_exr(tmp_path / "first.exr")["color"])


def test_frames_into_a_new_folder(gpu, tmp_path):
    """As the README shows: --out out/{frame:04d}.exr creates the folder."""
    assert main(["render", "moving", "--spp", "1", "--size", "8x8", "--frames", "0:2",
                 "--out", str(tmp_path / "out" / "{frame:04d}.exr")]) == 0
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["0000.exr", "0001.exr"]


def test_output_under_a_file_is_refused(tmp_path, capsys):
    (tmp_path / "taken").write_text("")
    assert main(["render", "cornell", "--size", "8x8", "--spp", "1", "--out", str(tmp_path / "taken" / "x.exr")]) == 2
    assert "is a file, not a folder" in capsys.readouterr().err


@pytest.mark.parametrize("args, message", [
    (["--size", "12"], "WIDTHxHEIGHT"),
    (["--size", "0x10"], "1..16384"),
    (["--spp", "0"], "--spp"),
    (["--max-depth", "0"], "--max-depth"),
    (["--aov", "albedo,velocity"], "velocity"),
    (["--frames", "3.5"], "--frames '3.5': expected a frame number N or A:B"),
    (["--frames", "-1"], "frames are numbered from 0"),
    (["--frames", "4:2"], "--frames"),
    (["--frames", "0:3"], "{frame}"),
    (["--animation", "walk"], "an animation choice (animation=/--animation walk) is for a glTF file"),
    (["--out", "OUT.jpg"], ".exr or .png"),
])
def test_bad_arguments(tmp_path, capsys, args, message):
    argv = ["render", "cornell", "--size", "8x8", "--spp", "1", "--out", str(tmp_path / "x.exr")] + args
    argv = [a.replace("OUT", str(tmp_path / "x")) for a in argv]
    assert main(argv) == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_malformed_scene_file(tmp_path, capsys):
    scene = tmp_path / "bad.json"
    scene.write_text('{"camera": {"origin": [0, 0, 1]}, "meshes": [')
    out = tmp_path / "x.exr"
    assert main(["render", str(scene), "--size", "8x8", "--out", str(out)]) == 2
    assert "bad.json" in capsys.readouterr().err
    assert not out.exists()


def test_unknown_scene_name(tmp_path, capsys):
    out = tmp_path / "x.exr"
    assert main(["render", "no-such-scene", "--out", str(out)]) == 2
    assert "no-such-scene" in capsys.readouterr().err
    assert not out.exists()


def test_help_names_every_built_in_scene(capsys):
    with pytest.raises(SystemExit):
        main(["render", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    for name in BUILTIN_SCENES:
        assert re.search(rf"[( ]{re.escape(name)}[,)]", help_text), name


@pytest.mark.parametrize("args, message", [
    (["--denoise", "--max-depth", "0"], "--max-depth"),
    (["--denoise", "--seed", "-1"], "--seed"),
    (["--adaptive", "4", "--spp", "2"], "--spp"),
    (["--frames", "0:2", "--out", "x_{frame.foo}.exr"], "--out"),
    (["--frames", "0:2", "--out", "x_{frame[0]}.exr"], "--out"),
    (["--frames", "0:2", "--out", "x_{frame:q}.exr"], "--out"),
    (["--frames", "0:3000000", "--out", "f/{frame:07d}.exr"], "3,000,000"),
    (["--denoise", "--models", "nowhere"], "--models nowhere: no such folder"),
    (["--exposure", "1", "--out", "x.exr"], "--exposure is for a .png output"),
    (["--tonemap", "reinhard", "--out", "x.exr"], "--tonemap is for a .png output"),
    (["--exposure", "100", "--out", "x.png"], "--exposure 100.0: exposure 100.0 must be a number of stops"),
    (["--models", "."], "no network runs without --denoise"),
])
def test_every_path_checks_its_flags_before_work(tmp_path, capsys, monkeypatch, args, message):
    """The same flags are checked the same way with or without --denoise, before anything is loaded or
    written (relative --out patterns land in the empty tmp_path, which must stay empty)."""
    monkeypatch.chdir(tmp_path)
    assert main(["render", "cornell", "--size", "8x8"] + args) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_a_png_shows_the_radiance_through_the_exposure_and_tone_curve_asked_for(gpu, tmp_path):
    from PIL import Image

    from wgpu_rt.frame.tonemap import tonemap

    options = ["render", "cornell", "--size", "16x16", "--spp", "2"]
    assert main([*options, "--aov", "", "--out", str(tmp_path / "c.exr")]) == 0
    radiance = read_exr(tmp_path / "c.exr")["color"]
    for flags, operator, stops in (([], "aces", 0.0), (["--exposure", "1.5"], "aces", 1.5),
                                   (["--tonemap", "reinhard", "--exposure", "-1"], "reinhard", -1.0)):
        assert main([*options, *flags, "--out", str(tmp_path / "c.png")]) == 0
        shown = np.asarray(Image.open(tmp_path / "c.png"), np.float32)[..., :3] / 255
        expected = tonemap(radiance, operator, stops, output="f32")[..., :3]
        assert np.abs(shown - expected).max() <= 1.01 / 255, flags


def test_models_from_a_folder_replace_the_shipped_ones(gpu, tmp_path, capsys):
    """`--models DIR` runs DIR's networks, as `wgpu-rt train --out DIR` writes them: a denoiser of its own there
    changes the image; a network the render needs that DIR lacks is named, before anything is written."""
    import torch

    from wgpu_rt.train.networks import UNet, export_onnx

    torch.manual_seed(0)
    export_onnx(UNet(widths=(4, 8)), tmp_path / "denoiser.onnx")
    images = {}
    for name, flags in (("shipped", []), ("own", ["--models", str(tmp_path)])):
        out = tmp_path / f"{name}.exr"
        assert main(["render", "cornell", "--size", "16x16", "--denoise", "--aov", "", *flags, "--out", str(out)]) == 0
        images[name] = read_exr(out)["color"]
    assert not np.allclose(images["own"], images["shipped"], atol=1e-3)
    capsys.readouterr()
    out = tmp_path / "adaptive.exr"
    assert main(["render", "cornell", "--size", "16x16", "--adaptive", "2", "--models", str(tmp_path),
                 "--out", str(out)]) == 2
    assert f"{tmp_path / 'error_predictor.onnx'}: no such model file" in capsys.readouterr().err
    assert not out.exists()


def test_frames_beyond_an_animated_scene_are_refused(tmp_path, capsys):
    out = tmp_path / "{frame}.exr"
    assert main(["render", "moving", "--size", "8x8", "--spp", "1", "--frames", "14:18", "--out", str(out)]) == 2
    assert "beyond the scene's 16 frames" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_denoise_honours_spp_and_aovs(gpu, tmp_path):
    """--spp and --aov mean the same with --denoise: the EXR carries the requested layers and the spp
    layer reads the samples asked for (the denoised colour is of a 3-spp render)."""
    out = tmp_path / "d.exr"
    assert main(["render", "cornell", "--denoise", "--spp", "3", "--size", "16x8", "--aov", "albedo,spp",
                 "--out", str(out)]) == 0
    layers = read_exr(out)
    assert set(layers) == {"color", "albedo", "spp"}
    assert (layers["spp"] == 3).all() and np.all(np.isfinite(layers["color"]))


def test_console_holds_only_the_summary(gpu, tmp_path):
    """A plain render prints one summary line on stdout and, piped, nothing on stderr: no progress bar
    (that is for a terminal), no driver chatter (XDG_RUNTIME_DIR), no warnings."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "XDG_RUNTIME_DIR"}
    out = tmp_path / "c.exr"
    done = subprocess.run([sys.executable, "-m", "wgpu_rt", "render", "cornell", "--size", "16x16", "--spp", "2",
                           "--out", str(out)], capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.count("\n") == 1 and done.stdout.startswith(str(out))
    assert done.stderr.strip() == "", done.stderr


def test_the_progress_bar_is_for_a_terminal(monkeypatch):
    """The renderer's bar (and the waits for the device that feed it) only where stderr is a terminal."""
    import sys
    from types import SimpleNamespace

    from wgpu_rt.renderer import Renderer

    renderer = SimpleNamespace(progress=True, scene=SimpleNamespace(name="cornell"))
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)
    assert Renderer._progress_bar(renderer, 4, "spp") is None
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    bar = Renderer._progress_bar(renderer, 4, "spp")
    assert bar is not None and bar.total == 4
    bar.close()
    assert Renderer._progress_bar(SimpleNamespace(progress=False), 4, "spp") is None


def test_png_reads_back_no_hdr_colour_and_exr_still_does(gpu, tmp_path, monkeypatch):
    """A PNG render reads back the display image alone (no colour, no AOVs), and its pixels are the
    tone-mapped colour that the same render written as EXR carries."""
    from PIL import Image

    from wgpu_rt.frame.pipeline import FramePipeline
    from wgpu_rt.frame.tonemap import tonemap

    results, finish = [], FramePipeline.finish

    def recorded_finish(self, pending):
        results.append(finish(self, pending))
        return results[-1]

    monkeypatch.setattr(FramePipeline, "finish", recorded_finish)
    args = ["render", "cornell", "--spp", "2", "--size", "20x12", "--seed", "3"]
    assert main(args + ["--out", str(tmp_path / "c.png")]) == 0
    assert main(args + ["--aov", "", "--out", str(tmp_path / "c.exr")]) == 0
    png_frame, exr_frame = results
    assert png_frame.color is None and png_frame.aovs == {} and png_frame.image.shape == (12, 20, 4)
    assert exr_frame.color is not None and exr_frame.image is None
    color = read_exr(tmp_path / "c.exr")["color"]
    assert color.shape == (12, 20, 3) and color.max() > 0
    pixels = np.asarray(Image.open(tmp_path / "c.png").convert("RGB")).astype(int)
    expected = tonemap(color, "aces").astype(int)[..., :3]
    assert np.abs(pixels - expected).max() <= 1


def test_half_layers_are_refused_in_temporal_mode(tmp_path, capsys):
    """The half_* AOVs are one frame's copy after half its samples; temporal mode keeps its own across
    frames, so asking for them there is one line naming the AOV and no output."""
    out = tmp_path / "x.exr"
    assert main(["render", "cornell", "--size", "8x8", "--denoise", "--temporal", "--aov", "spp,half_spp",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "AOV 'half_spp'" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()
