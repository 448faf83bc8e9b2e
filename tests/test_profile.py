"""``wgpu-rt profile`` and ``wgpu_rt.nn.profile``: every dispatch timed, FLOPs that add up, JSON rows, and
one-line errors for bad input."""

import json

import pytest
import torch

from wgpu_rt.cli import main
from wgpu_rt.commands.profile import model_path
from wgpu_rt.gpu import GpuContext
from wgpu_rt.models import network_named
from wgpu_rt.train.networks import UNet, export_onnx

SIZE = 32


@pytest.fixture(scope="module")
def tiny_unet(tmp_path_factory):
    # 10 output channels: a head of 3 output blocks, the last one part-filled, so the per-dispatch
    # FLOPs only add up to the layer's if each dispatch counts the channels it really writes
    torch.manual_seed(0)
    return export_onnx(UNet(out_channels=10, widths=(4, 8)), tmp_path_factory.mktemp("profile") / "unet.onnx",
                       SIZE, SIZE)


@pytest.mark.gpu
@pytest.mark.parametrize("per_group", [False, True], ids=["dispatch_per_layer", "dispatch_per_group"])
def test_every_dispatch_timed_and_flops_add_up(gpu, tiny_unet, monkeypatch, per_group):
    """A weighted layer is one dispatch with its output-block groups in workgroup_id.z, or (uniform
    windows preferred and the layer's weights beyond one uniform binding: forced here by a 128-byte
    limit: the head's three 64-byte windows exceed it together, not one by one) one dispatch per group."""
    from wgpu_rt.nn import WgslModel, kernels
    from wgpu_rt.nn import model as nn_model
    from wgpu_rt.nn.profile import profile

    if per_group:
        monkeypatch.setattr(kernels, "UNIFORM_WINDOW_LIMIT", 128)
    monkeypatch.setattr(nn_model, "default_uniform_windows", lambda ctx: per_group)
    model = WgslModel(tiny_unet, ctx=gpu)
    result = profile(model, SIZE, SIZE, repeat=2)
    plan = model.plan(SIZE, SIZE)
    # the first conv reads the input image itself and the head writes the output image: no pack, no unpack
    exits = sum(row.kernel.endswith("+unpack") for row in result.rows)
    entry, exit = result.rows[:1], result.rows[-exits:]
    assert [row.label for row in entry] == ["/down.0/down.0.0/Conv"] and entry[0].kernel == "pack+conv.wgsl"
    assert [row.label for row in result.rows[1:-len(exit)]] == [d.label for d in plan.dispatches]
    assert [row.workgroups for row in result.rows[1:-len(exit)]] == [d.workgroups for d in plan.dispatches]
    assert all(row.kernel == "gemm.wgsl+unpack" for row in exit)
    assert all(row.seconds >= 0 for row in result.rows) and result.end_to_end_seconds > 0
    assert sum(row.flops for row in result.rows) == plan.flops == result.network_flops
    head = [row for row in result.rows if row.label.startswith("/head/")]
    if per_group:
        assert [row.output for row in head] == [(4, SIZE, SIZE), (4, SIZE, SIZE), (2, SIZE, SIZE)]
        assert [row.workgroups[2] for row in head] == [1, 1, 1]
    else:
        assert [(row.output, row.workgroups[2]) for row in head] == [((10, SIZE, SIZE), 3)]
    assert head == exit


@pytest.mark.gpu
def test_cli_table_and_json(gpu, tiny_unet, tmp_path, capsys):
    out = tmp_path / "rows" / "profile.json"
    assert main(["profile", str(tiny_unet), "--size", f"{SIZE}x{SIZE}", "--repeat", "1", "--sort", "time",
                 "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["dispatch_count"] == len(data["rows"]) > 0
    assert data["dispatch_flops"] == data["network_flops"] == sum(row["flops"] for row in data["rows"])
    assert data["size"] == [SIZE, SIZE] and data["bands"] == 1
    for row in data["rows"]:
        assert row["seconds"] >= 0 and row["workgroup_count"] >= 1
        assert row["label"] in printed
    assert f"dispatches: {len(data['rows'])}" in printed
    times = [float(line.split()[-3]) for line in printed.splitlines()[1:len(data["rows"]) + 1]]
    assert times == sorted(times, reverse=True)  # --sort time: slowest first
    assert list(out.parent.iterdir()) == [out]  # no temporary file left beside it


@pytest.mark.gpu
def test_conv_tiling_picks_the_kernels_timed(gpu, tiny_unet, tmp_path, capsys):
    workgroups = {}
    for tiling in ("none", "loop"):
        out = tmp_path / f"{tiling}.json"
        assert main(["profile", str(tiny_unet), "--size", "32x32", "--repeat", "1", "--conv-tiling", tiling,
                     "--json", str(out)]) == 0
        data = json.loads(out.read_text())
        assert data["conv_tiling"] == tiling and f"{tiling} conv tiling" in capsys.readouterr().out
        workgroups[tiling] = [row["workgroup_count"] for row in data["rows"] if row["kernel"] == "conv.wgsl"]
    # one output pixel per invocation needs more workgroups than 4-pixel tiles on every conv
    assert workgroups["loop"] and all(none > loop for none, loop in zip(workgroups["none"], workgroups["loop"]))
    assert main(["profile", str(tiny_unet), "--size", "32x32", "--conv-tiling", "bogus"]) == 2
    assert "conv_tiling 'bogus': choose one of" in capsys.readouterr().err


@pytest.mark.gpu
def test_weight_fetch_is_profiled_as_asked(gpu, tiny_unet, tmp_path, capsys):
    """``--weight-fetch direct`` times the kernels that read weights per invocation (labelled so where the
    adapter has subgroups, whose shared loads are the default) and says so."""
    out = tmp_path / "direct.json"
    assert main(["profile", str(tiny_unet), "--size", "32x32", "--repeat", "1", "--weight-fetch", "direct",
                 "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["weight_fetch"] == "direct" and "direct weight fetch" in capsys.readouterr().out
    weighted = [row["kernel"] for row in data["rows"] if row["flops"]]
    assert weighted and all(kernel.endswith("+direct-weights") == gpu.has_subgroups for kernel in weighted)


@pytest.mark.gpu
def test_f16_math_is_profiled_as_asked(gpu, tiny_unet, tmp_path, capsys):
    """``--precision fp16 --math f16`` times the 3×3 kernels that multiply in half precision (the shipped
    denoiser's: 16k channels); f16 math without f16 activations is refused."""
    if not gpu.has_f16:
        pytest.skip(f"{gpu.label} has no shader-f16")
    out = tmp_path / "half.json"
    assert main(["profile", "denoiser", "--size", "32x32", "--repeat", "1", "--precision", "fp16",
                 "--math", "f16", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["math"] == "f16" and "f16 math" in capsys.readouterr().out
    assert any(row["kernel"].endswith("+f16-math") for row in data["rows"])
    assert main(["profile", str(tiny_unet), "--size", "32x32", "--precision", "fp32", "--math", "f16"]) == 2
    assert "math f16 needs precision fp16" in capsys.readouterr().err


def test_shipped_network_names_resolve():
    assert model_path("error-predictor") == network_named("error_predictor").path()
    assert str(model_path("no/such/model.onnx")) == "no/such/model.onnx"


@pytest.mark.parametrize("args, message", [
    (["--size", "32by32"], "expected WIDTHxHEIGHT"),
    (["--size", "0x32"], "1..16384"),
    (["--repeat", "0"], "--repeat 0: must be at least 1"),
])
def test_bad_arguments(tiny_unet, capsys, args, message):
    assert main(["profile", str(tiny_unet), *args]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


@pytest.mark.gpu
def test_bad_model_files(gpu, tmp_path, capsys):
    assert main(["profile", str(tmp_path / "missing.onnx"), "--size", "8x8"]) == 2
    assert "missing.onnx: ONNX model file not found" in capsys.readouterr().err
    corrupt = tmp_path / "corrupt.onnx"
    corrupt.write_bytes(b"\x08\x07 not a protobuf \xff\xfe" * 10)
    assert main(["profile", str(corrupt), "--size", "8x8"]) == 2
    assert "corrupt.onnx: not a valid ONNX model" in capsys.readouterr().err


def test_json_under_a_file_is_refused_before_profiling(tiny_unet, tmp_path, capsys):
    (tmp_path / "taken").write_text("")
    assert main(["profile", str(tiny_unet), "--size", "8x8", "--json", str(tmp_path / "taken" / "p.json")]) == 2
    assert "is a file, not a folder" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken"]


@pytest.mark.gpu
def test_adapter_without_timestamps(gpu, tiny_unet, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(GpuContext, "has_timestamps", property(lambda self: False))
    out = tmp_path / "p.json"
    assert main(["profile", str(tiny_unet), "--size", "8x8", "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert "needs the timestamp-query feature" in err and err.count("\n") == 1
    assert not out.exists()


@pytest.mark.gpu
def test_frames_in_bands_list_each_bands_dispatches(gpu, tmp_path):
    from wgpu_rt.commands.profile import summary
    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn.profile import profile

    torch.manual_seed(0)  # its 1.2 MiB full-resolution concat is over the limits, the images are not
    path = export_onnx(UNet(widths=(8, 16)), tmp_path / "unet.onnx", SIZE, SIZE)
    small = GpuContext(gpu.adapter, gpu.device, gpu.features)  # buffer and binding limits that force bands
    small.__dict__["limits"] = {**gpu.limits, "max-storage-buffer-binding-size": 10**6, "max-buffer-size": 10**6}
    model = WgslModel(path, ctx=small)
    plan = model.plan(403, 45)
    result = profile(model, 403, 45, repeat=1)
    exits = sum(row.kernel.endswith("+unpack") for row in result.rows) // result.bands
    per_band = 1 + len(plan.dispatches) + exits  # the first conv, the rest, the head
    assert len(plan.bands) == result.bands > 1 and len(result.rows) == result.bands * per_band
    assert [row.band for row in result.rows] == [i // per_band for i in range(len(result.rows))]
    assert sum(row.flops for row in result.rows) > result.network_flops == plan.flops  # context rows
    assert f"in {result.bands} bands of {plan.canvas[1]}x{plan.canvas[0]}" in summary(result)[0]
