"""Data-parallel training: two CPU processes on the gloo backend, as torchrun launches them, train one
tiny model: each rank on its own share of every epoch, the replicas identical after the run, and only
rank 0 writing the checkpoint, the ONNX and its card."""

import json
import os
import socket
import subprocess
import sys

import numpy as np
import torch
from test_train import tiny_dataset  # noqa: F401  (the module-scoped fake dataset fixture)

from wgpu_rt.models import DENOISER
from wgpu_rt.train import TrainConfig, train
from wgpu_rt.train.context import end_data_parallel_process
from wgpu_rt.train.trainer import Trainer

WORLD_SIZE = 2


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def train_as_rank(rank: int, port: int, config: dict, folder: str) -> None:
    """One torchrun-like process: the launcher's environment, then ``train``; it leaves the items it
    trained on, its final weights and its summary in ``folder`` for the test to compare."""
    os.environ.update(WORLD_SIZE=str(WORLD_SIZE), RANK=str(rank), LOCAL_RANK=str(rank),
                      MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port))
    torch.set_num_threads(1)   # two processes on a 2-core machine
    seen = []
    step, run = Trainer.train_step, Trainer.run

    def recorded_step(self, items, spp):
        seen.append([self.epoch, [list(item) for item in items]])
        return step(self, items, spp)

    def run_then_keep_weights(self):
        metrics = run(self)
        torch.save(self.model.state_dict(), os.path.join(folder, f"weights{rank}.pt"))
        return metrics

    Trainer.train_step, Trainer.run = recorded_step, run_then_keep_weights
    summary = train(TrainConfig(**config), progress=False)
    with open(os.path.join(folder, f"rank{rank}.json"), "w") as out:
        json.dump({"seen": seen, "summary": summary}, out)
    end_data_parallel_process(0)   # as `wgpu-rt train` ends under torchrun


def test_two_gloo_processes_train_one_model(tiny_dataset, tmp_path):  # noqa: F811
    import onnxruntime

    out = tmp_path / "models"
    config = dict(task="denoiser", data=str(tiny_dataset), out=str(out), epochs=2, batch=2, crop_min=12,
                  crop_max=16, widths=(4, 8), device="cpu")
    torch.multiprocessing.spawn(train_as_rank, args=(free_port(), config, str(tmp_path)), nprocs=WORLD_SIZE)

    ranks = [json.loads((tmp_path / f"rank{rank}.json").read_text()) for rank in range(WORLD_SIZE)]
    assert ranks[1]["summary"] is None and ranks[0]["summary"]["onnx"] == str(out / "denoiser.onnx")
    assert sorted(p.name for p in out.iterdir()) == ["checkpoints", "denoiser.md", "denoiser.onnx"]
    assert "2 data-parallel processes" in (out / "denoiser.md").read_text()

    trainer_items = Trainer(TrainConfig(**config), progress=False).train_set.items
    for epoch in range(2):
        shares = [{tuple(item) for e, batch in rank["seen"] if e == epoch for item in batch} for rank in ranks]
        assert not shares[0] & shares[1] and len(shares[0] | shares[1]) == len(trainer_items)
    steps = [len(rank["seen"]) for rank in ranks]
    assert steps[0] == steps[1] == 2 * -(-len(trainer_items) // (WORLD_SIZE * 2))   # half an epoch each

    weights = [torch.load(tmp_path / f"weights{rank}.pt") for rank in range(WORLD_SIZE)]
    for name, weight in weights[0].items():
        assert torch.equal(weights[1][name], weight), name
    saved = torch.load(out / "checkpoints" / "denoiser.pt", weights_only=False)
    assert all(torch.equal(saved["model"][name], weight) for name, weight in weights[1].items())
    assert len(saved["rank_rngs"]) == WORLD_SIZE and saved["rank_rngs"][0] != saved["rank_rngs"][1]

    from wgpu_rt.train.networks import UNet

    replica = UNet(widths=(4, 8)).eval()
    replica.load_state_dict(weights[1])
    x = np.random.default_rng(0).uniform(size=(1, DENOISER.input_channels, 16, 16)).astype(np.float32)
    session = onnxruntime.InferenceSession(str(out / "denoiser.onnx"), providers=["CPUExecutionProvider"])
    with torch.no_grad():
        np.testing.assert_allclose(session.run(None, {"input": x})[0], replica(torch.from_numpy(x)).numpy(),
                                   atol=1e-5)


def test_torchrun_launches_the_cli_with_one_report(tiny_dataset, tmp_path):  # noqa: F811
    out = tmp_path / "models"
    result = subprocess.run(
        [sys.executable, "-m", "torch.distributed.run", "--standalone", f"--nproc_per_node={WORLD_SIZE}",
         "-m", "wgpu_rt", "train", "error-predictor", "--data", str(tiny_dataset), "--out", str(out),
         "--epochs", "1", "--batch", "2", "--crop", "8", "16", "--device", "cpu", "--quiet"],
        capture_output=True, text=True, timeout=120, env={**os.environ, "OMP_NUM_THREADS": "1"})
    assert result.returncode == 0, result.stderr[-2000:]
    reports = [line for line in result.stdout.splitlines() if line.startswith("wrote ")]
    assert len(reports) == 1 and str(out / "error_predictor.onnx") in reports[0], result.stdout
    assert sorted(p.name for p in out.iterdir()) == ["checkpoints", "error_predictor.md", "error_predictor.onnx"]
