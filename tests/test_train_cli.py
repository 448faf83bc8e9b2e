"""`wgpu-rt train`'s checks (issue 15): every bad flag, a malformed dataset manifest and an unusable
--out end with exit status 2 and one line naming the culprit, before any work or any file is written."""

import json
import shutil

import pytest
import torch
from test_train import tiny_dataset  # noqa: F401  (the module-scoped fake dataset fixture)

from wgpu_rt.cli import main


def train_cli(capsys, data, out, *flags, task="denoiser"):
    """``wgpu-rt train`` with a tiny recipe plus ``flags`` (later flags win); (status, stderr lines)."""
    status = main(["train", task, "--data", str(data), "--out", str(out), "--epochs", "1", "--batch", "2",
                   "--crop", "12", "16", "--widths", "4", "8", "--quiet", *flags])
    return status, capsys.readouterr().err.splitlines()


@pytest.mark.parametrize(("flags", "named"), [
    (["--batch", "0"], "--batch"),
    (["--crop", "0", "0"], "--crop"),
    (["--crop", "-8", "16"], "--crop"),
    (["--crop", "16", "8"], "--crop"),
    (["--crop", "10", "16"], "--crop MIN must be at least 12 for the denoiser"),   # SSIM window, multiple 2
    (["--widths", "0"], "--widths"),
    (["--widths", "4", "-8"], "--widths"),
    (["--epochs", "0"], "--epochs"),
    (["--curriculum", "0"], "--curriculum"),
    (["--curriculum", "4", "-1"], "--curriculum"),
    (["--lr", "0"], "--lr"),
    (["--lr", "-0.001"], "--lr"),
    (["--lr", "nan"], "--lr"),
    (["--lr", "inf"], "--lr"),
    (["--validate-every", "0"], "--validate-every"),
    (["--max-views", "0"], "--max-views"),
    (["--init-from", "/nonexistent/denoiser.pt"], "--init-from /nonexistent/denoiser.pt: no such checkpoint"),
])
def test_a_bad_flag_is_one_line_naming_it_and_nothing_is_written(flags, named, tiny_dataset, tmp_path,  # noqa: F811
                                                                  capsys):
    out = tmp_path / "models"
    status, err = train_cli(capsys, tiny_dataset, out, *flags)
    assert status == 2 and len(err) == 1 and named in err[0], err
    assert not out.exists()


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has CUDA")
def test_device_cuda_without_cuda_is_refused(tiny_dataset, tmp_path, capsys):  # noqa: F811
    status, err = train_cli(capsys, tiny_dataset, tmp_path / "models", "--device", "cuda")
    assert status == 2 and len(err) == 1 and "--device cuda" in err[0], err
    assert not (tmp_path / "models").exists()


def test_out_that_is_a_file_or_inside_one_is_refused_before_training(tiny_dataset, tmp_path, capsys):  # noqa: F811
    existing = tmp_path / "models"
    existing.write_text("not a folder")
    for flag in ("--out", "--checkpoints"):
        for folder in (existing, existing / "sub"):
            status, err = train_cli(capsys, tiny_dataset, tmp_path / "fine", flag, str(folder))
            assert status == 2 and len(err) == 1 and f"{flag} {folder}/" in err[0], err
            assert f"{existing} is a file, not a folder" in err[0]
    assert existing.read_text() == "not a folder" and sorted(tmp_path.iterdir()) == [existing]


def test_an_unwritable_out_is_refused_before_training(tiny_dataset, tmp_path, capsys, monkeypatch):  # noqa: F811
    import tempfile

    # root writes anywhere a mode allows: stand in for a read-only mount by the probe file failing there.
    real_probe = tempfile.TemporaryFile

    def read_only_probe(*args, dir=None, **kwargs):
        if dir == tmp_path:
            raise PermissionError(30, "Read-only file system")
        return real_probe(*args, dir=dir, **kwargs)

    monkeypatch.setattr(tempfile, "TemporaryFile", read_only_probe)
    status, err = train_cli(capsys, tiny_dataset, tmp_path / "models")
    assert status == 2 and len(err) == 1 and f"--out {tmp_path / 'models'}/" in err[0], err
    assert f"cannot write in {tmp_path} (Read-only file system)" in err[0]
    assert list(tmp_path.iterdir()) == []


def corrupt_manifest(tiny, folder, change) -> None:
    """A copy of the dataset ``tiny`` in ``folder`` whose manifest ``change`` (a function or text) altered."""
    shutil.copytree(tiny, folder)
    manifest = folder / "manifest.json"
    if callable(change):
        data = json.loads(manifest.read_text())
        change(data)
        manifest.write_text(json.dumps(data))
    else:
        manifest.write_text(change)


def set_first_view(key, value):
    return lambda data: data["views"][0].__setitem__(key, value)


@pytest.mark.parametrize("change", [
    '{"config": {"size": 24}, "views": [{"view_id": "v0',                 # truncated JSON
    lambda data: data.__setitem__("views", [1, 2]),
    lambda data: data.__setitem__("config", ["not", "a", "table"]),
    lambda data: data["views"][0].pop("split"),
    set_first_view("view_id", 7),
    set_first_view("frames", "two"),
    set_first_view("size", [24]),
    set_first_view("spp", 4),
    set_first_view("seconds", "slow"),
], ids=["truncated", "views-not-records", "config-not-a-table", "no-split", "numeric-id", "frames-text",
        "size-list", "spp-number", "seconds-text"])
def test_a_malformed_manifest_is_one_line_naming_it(change, tiny_dataset, tmp_path, capsys):  # noqa: F811
    data = tmp_path / "data"
    corrupt_manifest(tiny_dataset, data, change)
    status, err = train_cli(capsys, data, tmp_path / "models")
    assert status == 2 and len(err) == 1 and f"{data / 'manifest.json'}: " in err[0], err
    assert not (tmp_path / "models").exists()


def test_a_fine_tune_keeps_the_models_architecture_and_takes_smaller_steps(tiny_dataset, tmp_path,  # noqa: F811
                                                                         monkeypatch):
    """`--init-from MODEL` without --widths and --bottom-merge takes the model's (the shipped denoiser's
    16 32 64 128 128 with the deepest level added), and without --lr a tenth of a fresh run's; flags still win."""
    from wgpu_rt.commands import train as command
    from wgpu_rt.models import DENOISER, ERROR_PREDICTOR
    from wgpu_rt.train import trainer

    shipped_model = str(DENOISER.path())
    configs = []
    monkeypatch.setattr("wgpu_rt.train.train", lambda config, progress: configs.append(config))
    base = ["train", "denoiser", "--data", str(tiny_dataset), "--out", str(tmp_path), "--quiet"]
    assert main([*base, "--init-from", shipped_model]) == 0
    assert main([*base, "--init-from", shipped_model, "--widths", "32", "32", "64", "128", "128",
                 "--lr", "3e-4"]) == 0
    assert main(base) == 0
    shipped, wider, fresh = configs
    assert (shipped.widths, shipped.bottom_merge, shipped.lr) == ((16, 32, 64, 128, 128), "add", command.FINE_TUNE_LR)
    assert (wider.widths, wider.bottom_merge, wider.lr) == ((32, 32, 64, 128, 128), "add", 3e-4)
    assert (fresh.widths, fresh.bottom_merge, fresh.lr) == ((32, 64, 128), "concat", command.FRESH_LR)
    assert trainer.base_architecture(ERROR_PREDICTOR.path()) == {} == trainer.base_architecture(tmp_path)
