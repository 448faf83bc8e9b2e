"""benchmarks/peers.py: discovery of the benchmarks' peers (torch, OIDN, Mitsuba) never raises when one
is missing, picks CUDA when it is there, and the torch peer runs the very network our engine runs
(checked against onnxruntime on the shipped models)."""

import importlib
import sys
import time
import types
from pathlib import Path

import numpy as np
import pytest

from parity import check_parity
from test_nn_ops import ALL as ENGINE_OP_GRAPHS
from test_nn_ops import make_model, onnxruntime_fn

REPO = Path(__file__).resolve().parents[1]
MODELS = REPO / "models"


@pytest.fixture
def peers(monkeypatch):
    monkeypatch.syspath_prepend(str(REPO / "benchmarks"))
    return importlib.import_module("peers")


def hide_module(monkeypatch, name: str) -> None:
    """Make ``import name`` raise ImportError for the rest of the test."""
    monkeypatch.setitem(sys.modules, name, None)


def test_discovery_without_torch_skips_torch_and_oidn_cuda(peers, monkeypatch):
    hide_module(monkeypatch, "torch")
    devices, lines = peers.torch_devices()
    assert devices == []
    assert len(lines) == 1 and lines[0].startswith("torch: skipped (torch not importable")
    pytest.importorskip("pyoidn")
    devices, lines = peers.oidn_devices()
    assert "cuda" not in devices
    assert any(line.startswith("OIDN CUDA: skipped (torch not importable") for line in lines)


def test_discovery_without_pyoidn_is_one_skip_line(peers, monkeypatch):
    hide_module(monkeypatch, "pyoidn")
    devices, lines = peers.oidn_devices()
    assert devices == [] and len(lines) == 1
    assert lines[0].startswith("OIDN: skipped (pyoidn not importable: ModuleNotFoundError")


def test_discovery_without_mitsuba_is_one_skip_line(peers, monkeypatch):
    hide_module(monkeypatch, "drjit")
    hide_module(monkeypatch, "mitsuba")
    module, lines = peers.mitsuba_peer()
    assert module is None
    assert len(lines) == 1 and lines[0].startswith("Mitsuba: skipped (ModuleNotFoundError") and "drjit" in lines[0]


def test_torch_devices_pick_cuda_when_torch_sees_one(peers, monkeypatch):
    torch = pytest.importorskip("torch")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.backends.cudnn, "is_available", lambda: True)
    devices, lines = peers.torch_devices()
    assert devices == ["cpu", "cuda"] and lines == []
    assert peers.preferred(devices) == "cuda"
    assert peers.torch_precisions("cuda") == ("fp32", "fp16")
    monkeypatch.setattr(torch.backends.cudnn, "is_available", lambda: False)
    devices, lines = peers.torch_devices()
    assert devices == ["cpu"] and lines[0].startswith("torch cuDNN: skipped (") and "no cuDNN" in lines[0]


def test_torch_devices_stay_on_cpu_without_cuda(peers, monkeypatch):
    torch = pytest.importorskip("torch")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    devices, lines = peers.torch_devices()
    assert devices == ["cpu"] and peers.preferred(devices) == "cpu"
    assert lines[0].startswith("torch cuDNN: skipped (") and "sees no CUDA device" in lines[0]
    assert peers.torch_precisions("cpu") == ("fp32",)


def test_oidn_devices_pick_cuda_when_torch_and_oidn_support_it(peers, monkeypatch):
    torch = pytest.importorskip("torch")
    pyoidn = pytest.importorskip("pyoidn")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "current_device", lambda: 0)
    monkeypatch.setattr(torch.cuda, "get_device_name", lambda device=None: "a test GPU")
    asked = []
    monkeypatch.setattr(pyoidn.Device, "is_cuda_available", staticmethod(lambda device_id=0: asked.append(device_id)
                                                                         or True))
    devices, lines = peers.oidn_devices()
    assert "cuda" in devices and peers.preferred(devices) == "cuda"
    assert asked == [0] and not any(line.startswith("OIDN CUDA") for line in lines)
    monkeypatch.setattr(pyoidn.Device, "is_cuda_available", staticmethod(lambda device_id=0: False))
    devices, lines = peers.oidn_devices()
    assert "cuda" not in devices
    assert "OIDN CUDA: skipped (OIDN's CUDA backend does not support a test GPU)" in lines


def test_mitsuba_variant_is_cuda_when_drjit_finds_a_device(peers, monkeypatch):
    """The variant choice follows Dr.Jit's CUDA backend, then LLVM (stand-in modules: no GPU here)."""
    import wgpu_rt.scene.mitsuba as setup
    backends = {"CUDA": True}
    drjit = types.SimpleNamespace(JitBackend=types.SimpleNamespace(CUDA="CUDA"),
                                  has_backend=lambda backend: backends[backend])
    mitsuba = types.SimpleNamespace(variants=lambda: ["scalar_rgb", "llvm_ad_rgb", "cuda_ad_rgb"])
    monkeypatch.setitem(sys.modules, "drjit", drjit)
    monkeypatch.setitem(sys.modules, "mitsuba", mitsuba)
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", "/some/libLLVM.so")
    assert setup.variant_choice() == ("cuda_ad_rgb", [])
    backends["CUDA"] = False
    variant, lines = setup.variant_choice()
    assert variant == "llvm_ad_rgb" and lines == ["Mitsuba cuda_ad_rgb: skipped (Dr.Jit finds no CUDA device)"]
    monkeypatch.setattr(setup, "LLVM19", Path("/nonexistent/libLLVM.so.19.1"))
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH")
    variant, lines = setup.variant_choice()
    assert variant == "scalar_rgb" and len(lines) == 2 and lines[1].startswith("Mitsuba llvm_ad_rgb: skipped (")


@pytest.mark.parametrize("model, blocks", [("denoiser", (1, 2)), ("error_predictor", (12, 20)),
                                            ("confidence", (12, 20))])
def test_torch_network_matches_onnxruntime(peers, model, blocks):
    """At a size of ``blocks`` times the network's size multiple (the shipped U-Net's levels' 2^(levels−1))."""
    pytest.importorskip("torch")
    import onnxruntime as ort

    path = MODELS / f"{model}.onnx"
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    network = peers.TorchNetwork(path)
    size = tuple(network.graph.multiple * b for b in blocks)
    check_parity([(1, network.graph.input_channels, *size)], lambda x: session.run(None, {"input": x})[0], network.numpy, atol=1e-4, low=0.0,
                 high=1.0, name=f"torch {model}")


@pytest.mark.parametrize("name", list(ENGINE_OP_GRAPHS))
def test_torch_network_runs_every_op_the_engine_lowers(peers, tmp_path, name):
    """The one-op (and fused, and concat) graphs of tests/test_nn_ops.py, through the torch peer."""
    pytest.importorskip("torch")
    channels, build = ENGINE_OP_GRAPHS[name]
    nodes, initializers = build()
    path = make_model(tmp_path, name, nodes, channels, initializers)
    check_parity([(1, channels, 12, 18)], onnxruntime_fn(path), peers.TorchNetwork(path).numpy, atol=1e-4, name=name)


def test_torch_network_fp16_stays_near_onnxruntime(peers):
    pytest.importorskip("torch")
    import onnxruntime as ort

    path = MODELS / "denoiser.onnx"
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    network = peers.TorchNetwork(path, precision="fp16")
    channels, multiple = network.graph.input_channels, network.graph.multiple
    assert network.numpy(np.zeros((1, channels, multiple, multiple), np.float32)).dtype == np.float32
    check_parity([(1, channels, multiple, 2 * multiple)], lambda x: session.run(None, {"input": x})[0], network.numpy, atol=2e-2,
                 low=0.0, high=1.0, name="torch fp16 denoiser")


def test_torch_network_refuses_sizes_it_cannot_run(peers):
    pytest.importorskip("torch")
    network = peers.TorchNetwork(MODELS / "denoiser.onnx")
    channels, multiple = network.graph.input_channels, network.graph.multiple
    with pytest.raises(ValueError, match=f"multiples of {multiple}"):
        network.input(np.zeros((1, channels, multiple + 4, multiple), np.float32))
    with pytest.raises(ValueError, match=f"N×{channels}×H×W"):
        network.input(np.zeros((1, 3, 16, 16), np.float32))


def test_oidn_filter_on_the_cpu_matches_pyoidn_denoise(peers):
    """The timed OIDN path (a filter committed once) denoises like pyoidn's one-call API."""
    pytest.importorskip("pyoidn")
    images = peers.oidn_inputs(16, 24, seed=3)
    denoiser = peers.OidnFilter("cpu", "fast", *images)
    try:
        denoiser()
        denoiser.check("execution")
        output = np.array(denoiser.output)
    finally:
        denoiser.release()
    np.testing.assert_allclose(output, peers.oidn_denoise(*images, quality="fast"), rtol=1e-5, atol=1e-6)
    assert np.all(np.isfinite(output)) and output.shape == (16, 24, 3)


def test_best_seconds_on_the_cpu_is_the_fastest_call(peers):
    durations = iter([0.2, 0.05, 0.12])
    wall, cpu = peers.best_seconds(lambda: time.sleep(next(durations)), repeats=3)
    assert 0.05 <= wall < 0.12 and cpu is not None and cpu < wall   # sleeping takes no CPU time


def test_oidn_with_prefiltered_aux_denoises_the_guides_first(peers):
    """The "Accurate" prefilter Blender runs by default: the noisy albedo and normal are denoised first (closer
    to the truth than given), and the colour is denoised with them as clean guides."""
    pyoidn = pytest.importorskip("pyoidn")
    rng = np.random.default_rng(0)
    ys, xs = np.mgrid[0:48, 0:64] / 64.0
    albedo = np.stack([0.2 + 0.6 * (xs > 0.5), 0.5 + 0.3 * ys, np.full_like(xs, 0.4)], -1).astype(np.float32)
    normal = np.dstack([np.zeros_like(xs), 0.6 * np.ones_like(xs), 0.8 * np.ones_like(xs)]).astype(np.float32)
    color = (albedo * rng.exponential(1.0, (48, 64, 1))).astype(np.float32)
    noisy_albedo = np.clip(albedo + rng.normal(0, 0.2, albedo.shape), 0, 1).astype(np.float32)
    noisy_normal = (normal + rng.normal(0, 0.3, normal.shape)).astype(np.float32)
    clean_albedo, clean_normal = peers.oidn_clean_guides(noisy_albedo, noisy_normal, "balanced")
    assert np.abs(clean_albedo - albedo).mean() < 0.5 * np.abs(noisy_albedo - albedo).mean()
    assert np.abs(clean_normal - normal).mean() < 0.5 * np.abs(noisy_normal - normal).mean()
    prefiltered = peers.oidn_prefiltered(color, noisy_albedo, noisy_normal, "balanced")
    np.testing.assert_array_equal(prefiltered, pyoidn.denoise(color, clean_albedo, clean_normal, hdr=True,
                                                              clean_aux=True, quality="balanced"))
    assert not np.allclose(prefiltered, peers.oidn_denoise(color, noisy_albedo, noisy_normal, "balanced"), atol=1e-3)
