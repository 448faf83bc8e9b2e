"""Autotuning (wgpu_rt.nn.autotune): the fastest tiling (and weight fetch) per layer shape wins and is
cached per adapter, the cache is reused unless it was made among fewer candidates, a corrupt cache is
rebuilt, and it stays off unless asked for."""

import json

import numpy as np
import pytest
from onnx import helper

from parity import check_parity
from test_nn_ops import FP16_ATOL, FP32_ATOL, conv, every_dispatch, make_model, onnxruntime_fn

SIZE = (19, 23)


@pytest.fixture
def two_layers(tmp_path):
    """A 3×3 conv (9 → 48 channels, ReLU; six distinct kernels: none, loop, register, staged,
    staged-weights, staged-narrow) and a 1×1 conv (48 → 5; two: none, loop)."""
    first, first_inits = conv("conv3x3", "x", "t", 9, 48, 3)
    relu = helper.make_node("Relu", ["t"], ["r"], name="relu")
    second, second_inits = conv("conv1x1", "r", "y", 48, 5, 1, pads=[0, 0, 0, 0], seed=2)
    return make_model(tmp_path, "two_layers", [*first, relu, *second], 9, [*first_inits, *second_inits])


DIRECT = "+direct-weights"


def fake_timer(calls, direct_seconds=10.0):
    """Staged fastest among the 3×3 kernels, one pixel per invocation ("none", most workgroups) fastest
    among the 1×1 ones: neither is lavapipe's default, so a choice that ignored the timer shows. Weights
    read directly (on an adapter with subgroups) add ``direct_seconds`` (negative: they win)."""
    seconds_of_3x3 = {"conv3x3_staged.wgsl+tile16": 1.0, "conv3x3.wgsl+tile16": 2.0, "conv.wgsl": 3.0,
                      "conv3x3_staged.wgsl+tile16+staged-weights": 4.0, "conv3x3_staged.wgsl+tile8": 5.0}

    def seconds(dispatches):
        dispatch = dispatches[0]
        calls.append(dispatch.kernel)
        kernel = dispatch.kernel.removesuffix(DIRECT)
        extra = direct_seconds if dispatch.kernel.endswith(DIRECT) else 0.0
        if kernel == "gemm.wgsl":
            return 1.0 / np.prod(dispatch.workgroups) + extra
        return seconds_of_3x3[kernel] + extra
    return seconds


def candidate_kernels(gpu):
    """What the autotuner times for the two layers: five 3×3 kernels (the staged one also with 8-channel
    tiles) and two 1×1 ones, each also with weights read directly where the adapter has subgroups (else
    direct reads are all there is), and the staged 3×3 kernel with its weights staged in workgroup memory."""
    kernels = ["conv.wgsl", "conv.wgsl", "conv3x3.wgsl+tile16", "conv3x3_staged.wgsl+tile16",
               "conv3x3_staged.wgsl+tile8", "gemm.wgsl", "gemm.wgsl"]
    fetched = kernels + [kernel + DIRECT for kernel in kernels] if gpu.has_subgroups else kernels
    return sorted(fetched + ["conv3x3_staged.wgsl+tile16+staged-weights"])


def chosen(model):
    """(kernel, workgroups along x) of each weighted layer's dispatch at 19×23."""
    return [(d.kernel, d.workgroups[0]) for d in every_dispatch(model, *SIZE) if d.flops]


# the staged 3×3 kernel, reading the input image itself; the 1×1 one with one pixel per invocation
# (437 pixels in 7 workgroups of 64), writing the output image
FAKE_CHOICE = [("pack+conv3x3_staged.wgsl+tile16", 1), ("gemm.wgsl+unpack", 7)]


@pytest.mark.gpu
def test_fastest_kernel_is_chosen_cached_and_reused(gpu, two_layers, tmp_path):
    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn.autotune import Autotuner
    from wgpu_rt.nn.profile import profile

    cache = tmp_path / "cache" / "autotune.json"
    calls = []
    model = WgslModel(two_layers, ctx=gpu, autotune=Autotuner(gpu, cache, timer=fake_timer(calls)))
    assert chosen(model) == FAKE_CHOICE
    assert sorted(calls) == candidate_kernels(gpu)
    check_parity([(1, 9, *SIZE)], onnxruntime_fn(two_layers), model, atol=FP32_ATOL)
    assert profile(model, *SIZE, repeat=1).conv_tiling == "autotuned"
    entries = json.loads(cache.read_text())["entries"]
    assert sorted(entry["variant"] for entry in entries.values()) == ["none", "staged"]
    assert all(gpu.adapter.info["device"] in key and " fp32 " in key for key in entries)
    assert list(cache.parent.iterdir()) == [cache]  # written atomically: no temporary file left

    def no_timer(dispatches):
        raise AssertionError("a cached choice was measured again")
    again = WgslModel(two_layers, ctx=gpu, autotune=Autotuner(gpu, cache, timer=no_timer))
    assert chosen(again) == FAKE_CHOICE
    assert again.autotuner.measured == 0


@pytest.mark.gpu
def test_weights_read_directly_win_where_faster(gpu, two_layers, tmp_path):
    """With subgroups, reading weights directly is a candidate of its own: chosen where it times faster,
    named in the cache, the same numbers as onnxruntime. A choice cached before that candidate existed
    (its timings lack it) is measured again, not reused."""
    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn.autotune import Autotuner

    if not gpu.has_subgroups:
        pytest.skip(f"{gpu.label} has no subgroups: weights are always read directly")
    cache = tmp_path / "autotune.json"
    model = WgslModel(two_layers, ctx=gpu, autotune=Autotuner(gpu, cache, timer=fake_timer([], -0.5)))
    assert chosen(model) == [(kernel + DIRECT, groups) for kernel, groups in FAKE_CHOICE]
    check_parity([(1, 9, *SIZE)], onnxruntime_fn(two_layers), model, atol=FP32_ATOL)
    data = json.loads(cache.read_text())
    assert sorted(entry["variant"] for entry in data["entries"].values()) == ["none" + DIRECT, "staged" + DIRECT]

    for entry in data["entries"].values():   # as cached before direct reads were candidates
        entry["seconds"] = {v: t for v, t in entry["seconds"].items() if not v.endswith(DIRECT)}
        entry["variant"] = min(entry["seconds"], key=entry["seconds"].get)
    cache.write_text(json.dumps(data))
    calls = []
    again = WgslModel(two_layers, ctx=gpu, autotune=Autotuner(gpu, cache, timer=fake_timer(calls, -0.5)))
    assert chosen(again) == chosen(model) and sorted(calls) == candidate_kernels(gpu)


@pytest.mark.gpu
@pytest.mark.parametrize("fastest", ["+f16-math", "+f16-acc"])
def test_f16_multiply_adds_are_a_candidate_of_fp16_models(gpu, two_layers, tmp_path, monkeypatch, fastest):
    """An fp16 model's 3×3 kernels are also timed multiplying in f16, and summing their tile in f16 too:
    chosen where faster, named in the cache, within the fp16 bound of onnxruntime (fp32 models never time
    them: see candidate_kernels). A half math that fails the device check is never a candidate."""
    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn import model as nn_model
    from wgpu_rt.nn.autotune import Autotuner

    if not gpu.has_f16:
        pytest.skip(f"{gpu.label} has no shader-f16")
    calls = []

    def seconds(dispatches):
        calls.append(dispatches[0].kernel)
        return 0.5 if fastest in dispatches[0].kernel else 0.7 if "+f16" in dispatches[0].kernel else 1.0

    cache = tmp_path / "autotune.json"
    model = WgslModel(two_layers, "fp16", ctx=gpu, autotune=Autotuner(gpu, cache, timer=seconds))
    first = [d.kernel for d in every_dispatch(model, *SIZE) if d.flops][0]
    # register, staged and staged-narrow, weights read directly, for each half math
    assert sum("+f16-math" in kernel for kernel in calls) == sum("+f16-acc" in kernel for kernel in calls) == 3
    assert first.startswith("pack+conv3x3") and first.endswith(fastest)
    variants = [entry["variant"] for entry in json.loads(cache.read_text())["entries"].values()]
    assert sum(fastest in variant for variant in variants) == 1
    check_parity([(1, 9, *SIZE)], onnxruntime_fn(two_layers), model, atol=FP16_ATOL)

    monkeypatch.setattr(nn_model, "half_math_agrees", lambda ctx, math="f16": math != "f16-acc")
    calls.clear()
    WgslModel(two_layers, "fp16", ctx=gpu, autotune=Autotuner(gpu, tmp_path / "other.json", timer=seconds)).plan(*SIZE)
    assert sum("+f16-math" in kernel for kernel in calls) == 3 and not any("+f16-acc" in k for k in calls)


@pytest.mark.gpu
def test_a_candidate_the_device_refuses_is_left_out_and_remembered(gpu, two_layers, tmp_path):
    """A candidate whose shader the driver rejects (here the fake timer raises the validation error
    wgpu would) is not chosen, is kept in the cache as failed with the first line of why, and is not
    tried again; if every candidate fails, the default stands."""
    import wgpu

    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn.autotune import Autotuner

    def refusing(dispatches):
        if dispatches[0].kernel.startswith("conv3x3_staged"):
            raise wgpu.GPUValidationError("Shader validation error: no\nmore detail")
        return fake_timer([])(dispatches)

    cache = tmp_path / "autotune.json"
    model = WgslModel(two_layers, ctx=gpu, autotune=Autotuner(gpu, cache, timer=refusing))
    assert chosen(model)[0] == ("pack+conv3x3.wgsl+tile16", 1)   # the next fastest, not the staged one
    entries = json.loads(cache.read_text())["entries"].values()
    failed = [entry["failed"] for entry in entries if "failed" in entry]
    assert len(failed) == 1 and set(failed[0].values()) == {"Shader validation error: no"}
    assert all(variant.startswith("staged") for variant in failed[0])

    def no_timer(dispatches):
        raise AssertionError("a cached choice was measured again")
    again = WgslModel(two_layers, ctx=gpu, autotune=Autotuner(gpu, cache, timer=no_timer))
    assert chosen(again) == chosen(model)

    def refuse_all(dispatches):
        raise wgpu.GPUValidationError("no")
    fallback = WgslModel(two_layers, ctx=gpu, autotune=Autotuner(gpu, tmp_path / "other.json", timer=refuse_all))
    assert chosen(fallback) == chosen(WgslModel(two_layers, ctx=gpu))


@pytest.mark.gpu
@pytest.mark.parametrize("content", [b"{not json", b"\x00\xff", b"[1, 2]", b'{"version": 1, "entries": []}',
                                     b'{"version": 1, "entries": {"k": "staged"}}'],
                         ids=["truncated", "binary", "list", "entries_list", "entry_not_a_dict"])
def test_corrupt_cache_is_ignored_and_rebuilt(gpu, two_layers, tmp_path, content):
    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn.autotune import Autotuner

    cache = tmp_path / "autotune.json"
    cache.write_bytes(content)
    calls = []
    model = WgslModel(two_layers, ctx=gpu, autotune=Autotuner(gpu, cache, timer=fake_timer(calls)))
    assert chosen(model) == FAKE_CHOICE and sorted(calls) == candidate_kernels(gpu)
    assert len(json.loads(cache.read_text())["entries"]) == 2


@pytest.mark.gpu
def test_without_timestamps_or_a_writable_cache_it_still_runs(gpu, two_layers, tmp_path):
    from wgpu_rt.gpu import GpuContext
    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn.autotune import Autotuner

    untimed = GpuContext(gpu.adapter, gpu.device, gpu.features - {"timestamp-query"})
    cache = tmp_path / "autotune.json"
    model = WgslModel(two_layers, ctx=untimed, autotune=Autotuner(untimed, cache))
    assert chosen(model) == chosen(WgslModel(two_layers, ctx=gpu))  # the default tiling
    assert not cache.exists()

    blocked = tmp_path / "a file"
    blocked.write_text("")
    model = WgslModel(two_layers, ctx=gpu, autotune=Autotuner(gpu, blocked / "autotune.json",
                                                               timer=fake_timer([])))
    with pytest.warns(UserWarning, match="autotune cache not saved"):
        check_parity([(1, 9, *SIZE)], onnxruntime_fn(two_layers), model, atol=FP32_ATOL)


@pytest.mark.gpu
def test_timestamp_timer_measures_real_dispatches(gpu, two_layers, tmp_path):
    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn.autotune import Autotuner

    if not gpu.has_timestamps:
        pytest.skip(f"{gpu.label} has no timestamp queries")
    model = WgslModel(two_layers, ctx=gpu, autotune=Autotuner(gpu, tmp_path / "autotune.json"))
    check_parity([(1, 9, *SIZE)], onnxruntime_fn(two_layers), model, atol=FP32_ATOL)
    entries = json.loads((tmp_path / "autotune.json").read_text())["entries"].values()
    assert all(min(entry["seconds"].values()) > 0 for entry in entries) and len(entries) == 2


@pytest.mark.gpu
def test_off_unless_asked(gpu, two_layers, tmp_path, monkeypatch):
    from wgpu_rt.errors import ModelError
    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn.autotune import ENV, cache_path

    from wgpu_rt.measured_choices import CACHE_DIR_ENV

    monkeypatch.delenv(CACHE_DIR_ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert cache_path() == tmp_path / "wgpu-rt" / "autotune.json"
    monkeypatch.setenv(CACHE_DIR_ENV, str(tmp_path / "own"))
    assert cache_path() == tmp_path / "own" / "autotune.json"
    monkeypatch.delenv(ENV, raising=False)
    assert WgslModel(two_layers, ctx=gpu).autotuner is None
    assert WgslModel(two_layers, ctx=gpu, autotune=True).autotuner.path == cache_path()
    assert WgslModel(two_layers, ctx=gpu, autotune=True, conv_tiling="loop").autotuner is None
    monkeypatch.setenv(ENV, "1")
    assert WgslModel(two_layers, ctx=gpu).autotuner is not None
    monkeypatch.setenv(ENV, "0")
    assert WgslModel(two_layers, ctx=gpu, autotune=True).autotuner is None
    monkeypatch.setenv(ENV, "yes")
    with pytest.raises(ModelError, match=r"\$WGPU_RT_AUTOTUNE='yes'"):
        WgslModel(two_layers, ctx=gpu)


@pytest.mark.gpu
@pytest.mark.parametrize("per_group_faster", [True, False], ids=["group_dispatches", "one_dispatch"])
def test_dispatch_per_layer_or_per_group_is_measured_too(gpu, tmp_path, per_group_faster):
    """128 → 48 channels: 221 KiB of weights, more than one uniform binding, in 36 KiB pair windows that
    each fit one: every kernel runs either as one dispatch reading storage or as one dispatch per group of
    uniform windows, and the measurement picks, whatever the adapter's default."""
    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn.autotune import Autotuner

    nodes, inits = conv("conv", "x", "y", 128, 48, 3)
    path = make_model(tmp_path, "wide", nodes, 128, inits)
    calls = []

    def seconds(dispatches):
        calls.append(dispatches[0].kernel)
        per_group = len(dispatches) > 1
        register = dispatches[0].kernel.startswith("conv3x3.")
        direct = 10.0 if dispatches[0].kernel.endswith(DIRECT) else 0.0
        return (1.0 if per_group == per_group_faster else 2.0) * (1.0 if register else 3.0) + direct

    cache = tmp_path / "autotune.json"
    model = WgslModel(path, ctx=gpu, autotune=Autotuner(gpu, cache, timer=seconds))
    dispatches = [d for d in every_dispatch(model, *SIZE) if d.flops]
    # none, loop, register, staged, staged-narrow × both ways (× fetches), staged-weights × both ways
    assert len(calls) == 10 * (1 + gpu.has_subgroups) + 2
    expected = [1, 1, 1] if per_group_faster else [3]
    assert [(d.kernel, d.workgroups[2]) for d in dispatches] == [("conv3x3.wgsl+tile16+unpack", z)
                                                                 for z in expected]
    variant = "register+uniform-windows" if per_group_faster else "register"
    assert [entry["variant"] for entry in json.loads(cache.read_text())["entries"].values()] == [variant]
    check_parity([(1, 128, *SIZE)], onnxruntime_fn(path), model, atol=FP32_ATOL)


@pytest.mark.gpu
def test_a_conv_pooling_in_its_epilogue_is_timed_with_the_pool(gpu, tmp_path):
    """A conv whose epilogue max-pools its output is measured doing so (each candidate writes a scratch
    pooled tensor too) and cached under a key of its own."""
    from test_nn_ops import FOLDS, canvas_onnxruntime_fn

    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn.autotune import Autotuner

    channels, build = FOLDS["pool_skip16"]
    nodes, inits = build()
    path = make_model(tmp_path, "pool_skip", nodes, channels, inits)
    calls = []

    def seconds(dispatches):
        calls.append(dispatches[0].kernel)
        direct = 10.0 if dispatches[0].kernel.endswith(DIRECT) else 0.0
        staged = dispatches[0].kernel.startswith("conv3x3_staged")
        return (1.0 if staged and "+tile16" in dispatches[0].kernel else 1.5 if staged else 2.0) + direct

    cache = tmp_path / "autotune.json"
    model = WgslModel(path, ctx=gpu, autotune=Autotuner(gpu, cache, timer=seconds))
    check_parity([(1, channels, 37, 53)], canvas_onnxruntime_fn(path, model), model, atol=FP32_ATOL)
    pooled = sorted(kernel for kernel in calls if kernel.endswith("+maxpool"))  # the pooled conv's candidates
    assert pooled == ["conv.wgsl+maxpool", "conv.wgsl+maxpool", "conv3x3.wgsl+tile16+maxpool",
                      "conv3x3_staged.wgsl+tile16+maxpool", "conv3x3_staged.wgsl+tile8+maxpool"]
    keys = json.loads(cache.read_text())["entries"]
    assert sum(" conv+maxpool 16x5x3x3 " in key for key in keys) == 1
    assert every_dispatch(model, 37, 53)[0].kernel == "pack+conv3x3_staged.wgsl+tile16+maxpool"
