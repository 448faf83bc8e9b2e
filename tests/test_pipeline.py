"""The fused frame pipeline: one readback per frame, no uploads of its own, and each mode's output
equal to the numpy references applied to the traced planes. Networks are stand-ins recorded on the
device (an identity denoiser, a fixed heatmap), so the test checks the wiring, not a trained model."""

import time

import numpy as np
import pytest

from wgpu_rt.frame.adaptive import HALF_RADIANCE, AdaptiveSettings
from wgpu_rt.frame.planes import DENOISER_INPUT
from wgpu_rt.frame.temporal import TemporalSettings
from wgpu_rt.frame.tonemap import tonemap
from wgpu_rt.frame.converge import CONVERGE_CAP_SCALE, HALF_SPP, converge
from wgpu_rt.passes import ALBEDO, DEPTH, NORMAL, RADIANCE, SPP
from wgpu_rt.renderer import Renderer, render
from wgpu_rt.scene.builtin import builtin_scene

W, H = 24, 16


def make_pipeline(scene, gpu, denoiser=None, error_predictor=None, **settings):
    """The FramePipeline ``render`` sets up for ``scene`` at W×H, with stand-in networks."""
    networks = {name: net for name, net in (("denoiser", denoiser), ("error_predictor", error_predictor)) if net}
    settings = {"aovs": (), "max_depth": 3, **settings}
    return Renderer(scene, size=(W, H), ctx=gpu, denoise=denoiser is not None, networks=networks,
                    **settings).pipeline


class IdentityDenoiser:
    """Copies the packed log1p colour (channels 0–2) to its output: denoised = sanitised radiance."""

    def __init__(self, gpu):
        self.output = gpu.storage(3 * W * H * 4, label="identity output")

    def record(self, encoder, input_buffer, height, width):
        encoder.copy_buffer_to_buffer(input_buffer, 0, self.output, 0, 3 * width * height * 4)
        return self.output


class FixedHeat:
    def __init__(self, gpu, heat):
        self.output = gpu.upload(heat.astype(np.float32))

    def record(self, encoder, input_buffer, height, width):
        return self.output


class TrafficCounter:
    """Counts host ↔ device traffic at the lowest level wgpu-py offers, so no route escapes it: every
    readback (queue.read_buffer, buffer.map_sync/map_async + read_mapped, GpuContext.read) ends in
    GPUBuffer.read_mapped; every upload is queue.write_buffer/write_texture or GPUBuffer.write_mapped
    (which create_buffer_with_data and mapped_at_creation buffers use)."""

    def __init__(self, monkeypatch, gpu):
        self.reads = self.uploads = 0
        buffer_type, queue_type = type(gpu.storage(16)), type(gpu.device.queue)
        for owner, name, counter in ((buffer_type, "read_mapped", "reads"),
                                     (buffer_type, "_experimental_get_mapped_range", "reads"),
                                     (buffer_type, "write_mapped", "uploads"),
                                     (queue_type, "write_buffer", "uploads"),
                                     (queue_type, "write_texture", "uploads")):
            monkeypatch.setattr(owner, name, self._counted(getattr(owner, name), counter))

    def _counted(self, method, counter):
        def wrapper(*args, **kwargs):
            setattr(self, counter, getattr(self, counter) + 1)
            return method(*args, **kwargs)

        return wrapper


@pytest.fixture(scope="module")
def scene():
    return builtin_scene("cornell")


def frames_and_traffic(monkeypatch, gpu, scene, frames, **settings):
    """Frames rendered by a pipeline built beforehand, and the traffic of the frames alone, after a first
    frame (setup, such as uploading network weights or the scene's geometry once, is not per-frame
    traffic)."""
    pipeline = make_pipeline(scene, gpu, tonemap="aces", **settings)
    pipeline.render(scene, frames[0] - 1)
    counter = TrafficCounter(monkeypatch, gpu)
    out = [pipeline.render(scene, frame) for frame in frames]
    monkeypatch.undo()
    return out, counter


def test_one_readback_and_no_uploads_of_its_own(gpu, scene, monkeypatch):
    """The full pipeline (denoise, adaptive, temporal) moves exactly what a plain trace does, plus nothing:
    one readback per frame and the tracer's own parameters, written only when they change: the plain
    frames each take a new seed (one write each); the full pipeline's temporal mode converges on this
    static view under one seed, so its probe and targeted passes have nothing to write."""
    heat = np.linspace(0, 1, W * H).astype(np.float32)
    _, plain_traffic = frames_and_traffic(monkeypatch, gpu, scene, [1, 2])
    full, full_traffic = frames_and_traffic(
        monkeypatch, gpu, scene, [1, 2], denoiser=IdentityDenoiser(gpu), error_predictor=FixedHeat(gpu, heat),
        adaptive=AdaptiveSettings(budget=2.0), temporal=TemporalSettings())
    assert plain_traffic.reads == full_traffic.reads == 2
    assert plain_traffic.uploads == 2 and full_traffic.uploads == 0
    assert all(f.image.shape == (H, W, 4) and f.image.dtype == np.uint8 for f in full)


class LeakyDenoiser(IdentityDenoiser):
    """An identity denoiser that also moves data between host and device the way a careless stage
    would: ``leak`` names the route."""

    def __init__(self, gpu, leak):
        super().__init__(gpu)
        self.gpu, self.leak = gpu, leak

    def record(self, encoder, input_buffer, height, width):
        import wgpu

        if self.leak == "GpuContext.read":
            self.gpu.read(input_buffer, nbytes=16)
        elif self.leak == "map_sync":
            staging = self.gpu.device.create_buffer(size=16, usage=wgpu.BufferUsage.MAP_READ)
            staging.map_sync(wgpu.MapMode.READ)
            staging.read_mapped()
            staging.unmap()
        elif self.leak == "write_buffer":
            self.gpu.device.queue.write_buffer(self.output, 0, np.zeros(4, np.float32))
        elif self.leak == "GpuContext.upload":
            self.gpu.upload(np.zeros(4, np.float32))
        return super().record(encoder, input_buffer, height, width)


@pytest.mark.parametrize("leak", ["GpuContext.read", "map_sync", "write_buffer", "GpuContext.upload"])
def test_traffic_counter_catches_a_stage_that_leaks(gpu, scene, monkeypatch, leak):
    """The counting test above can fail: one stray transfer per frame inside a stage shows up."""
    _, clean = frames_and_traffic(monkeypatch, gpu, scene, [1, 2], denoiser=IdentityDenoiser(gpu))
    _, leaky = frames_and_traffic(monkeypatch, gpu, scene, [1, 2], denoiser=LeakyDenoiser(gpu, leak))
    reads, uploads = leaky.reads - clean.reads, leaky.uploads - clean.uploads
    assert (reads, uploads) == ((2, 0) if leak in ("GpuContext.read", "map_sync") else (0, 2))


def test_identity_denoiser_gives_tonemapped_radiance(gpu, scene):
    from wgpu_rt.accel.geometry import GeometryBuffers
    from wgpu_rt.frame.pipeline import FramePipeline
    from wgpu_rt.trace.trace_pass import TracePass

    geometry = GeometryBuffers.build(scene, 0)
    pipeline = FramePipeline(gpu, W, H, lambda f, _: TracePass(gpu, scene, geometry, W, H, frame=f, max_depth=3),
                             denoiser=IdentityDenoiser(gpu), operator="reinhard", chroma=False, post_filter=False)
    frame = pipeline.render(scene, 0)
    radiance = pipeline.buffers.read(RADIANCE.name).transpose(1, 2, 0)
    assert radiance.max() > 0
    expected = tonemap(radiance, "reinhard")
    assert np.abs(frame.image.astype(int) - expected.astype(int)).max() <= 1
    if gpu.has_timestamps:
        assert {"trace", "pack", "denoise", "tonemap"} <= set(frame.stage_ms)
        assert all(ms >= 0 for ms in frame.stage_ms.values())


def test_adaptive_budget_reaches_the_spp_plane(gpu, scene):
    from wgpu_rt.accel.geometry import GeometryBuffers
    from wgpu_rt.frame.pipeline import FramePipeline
    from wgpu_rt.trace.trace_pass import TracePass

    geometry = GeometryBuffers.build(scene, 0)
    heat = np.zeros((H, W), np.float32)
    heat[:, : W // 2] = 1.0
    for sampler, error_predictor in (("heat", FixedHeat(gpu, heat)), ("uniform", None), ("variance", None)):
        pipeline = FramePipeline(gpu, W, H, lambda f, _: TracePass(gpu, scene, geometry, W, H, max_depth=2),
                                 adaptive=AdaptiveSettings(sampler=sampler, budget=3.5, pool_sigma=0.0),
                                 error_predictor=error_predictor, denoiser=IdentityDenoiser(gpu))
        pipeline.render(scene, 0)
        spp = pipeline.buffers.read(SPP.name)[0]
        assert int(spp.sum()) == round(3.5 * W * H), sampler
        if sampler == "heat":
            assert spp[:, W // 2:].max() <= 2 and spp[:, : W // 2].min() >= 4
        # the denoiser is told each pixel's count
        np.testing.assert_allclose(pipeline.buffers.read(DENOISER_INPUT.name)[-1], 1 / np.sqrt(spp), rtol=1e-6)


def test_temporal_static_frames_converge(gpu, scene):
    """A static scene accumulates: the temporal output of 4 frames is smoother than one frame."""
    options = dict(size=(W, H), max_depth=3, ctx=gpu, aovs=())
    frames = render(scene, temporal=TemporalSettings(), frames=range(4), **options)
    single = render(scene, frames=3, seed=0, **options).color
    reference = render(scene, seed=100, **options).color
    assert np.all(np.isfinite(frames[-1].color))
    error_accumulated = np.abs(frames[-1].color - reference).mean()
    assert error_accumulated < np.abs(single - reference).mean()


def test_without_a_denoiser_a_static_view_shows_its_sample_mean_whole(gpu, scene):
    """Nothing to hand over without a denoiser: no converge pass, no copy of the mean, and each static
    frame shows exactly the accumulated mean."""
    pipeline = make_pipeline(scene, gpu, temporal=True)
    assert pipeline.temporal.converge is None
    for frame in range(3):
        image = pipeline.render(scene, frame).color
    np.testing.assert_array_equal(image, pipeline.buffers.read(RADIANCE.name).transpose(1, 2, 0))
    assert (pipeline.buffers.read(SPP.name) == 3).all()


def brute_force_planes(gpu, scene, geometry, samples):
    """Mean radiance and spp of one trace of ``samples`` samples per pixel, seeded as frame 0."""
    from wgpu_rt.passes import FrameBuffers
    from wgpu_rt.trace.trace_pass import SampleSchedule, TracePass

    buffers = FrameBuffers(gpu, W, H)
    trace = TracePass(gpu, scene, geometry, W, H, frame=0, max_depth=3, seed=0)
    encoder = gpu.device.create_command_encoder()
    trace.clear(encoder, buffers)
    trace.execute(encoder, buffers, SampleSchedule(samples=samples))
    gpu.device.queue.submit([encoder.finish()])
    return buffers.read(RADIANCE.name).transpose(1, 2, 0), buffers.read(SPP.name)[0]


def test_temporal_static_camera_accumulates_samples_before_denoising(gpu, scene):
    """Under a static camera the tracer keeps its planes and the first frame's seed: frame k denoises the
    mean of k + 1 samples (not the mean of k + 1 denoised 1-spp frames), the same samples a brute-force
    render of k + 1 spp takes (one stratified sequence), so with an identity denoiser its output is that
    render; a cut starts again from one sample."""
    from wgpu_rt.accel.geometry import GeometryBuffers
    from wgpu_rt.frame.pipeline import FramePipeline
    from wgpu_rt.trace.trace_pass import TracePass

    geometry = GeometryBuffers.build(scene, 0)
    seeds = []

    def trace_factory(frame, seed_frame):
        seeds.append(seed_frame)
        return TracePass(gpu, scene, geometry, W, H, frame=frame, max_depth=3, seed=seed_frame)

    pipeline = FramePipeline(gpu, W, H, trace_factory, denoiser=IdentityDenoiser(gpu),
                             temporal=TemporalSettings(), operator=None, post_filter=False)
    frames = [pipeline.render(scene, frame) for frame in range(4)]
    expected, expected_spp = brute_force_planes(gpu, scene, geometry, 4)
    assert (expected_spp == 4).all() and seeds == [0, 0, 0, 0]
    np.testing.assert_array_equal(pipeline.buffers.read(SPP.name)[0], expected_spp)
    np.testing.assert_allclose(frames[-1].color, expected, rtol=1e-4, atol=1e-5)
    assert np.abs(frames[-1].color - frames[0].color).max() > 1e-2   # frames differ
    pipeline.render(scene, 6)                                                          # a cut
    assert (pipeline.buffers.read(SPP.name)[0] == 1).all() and seeds[-1] == 6


class ZeroDenoiser:
    """Outputs log1p colour 0 everywhere: the denoised frame is black."""

    def __init__(self, gpu):
        self.output = gpu.storage(3 * W * H * 4, label="zero output")

    def record(self, encoder, input_buffer, height, width):
        return self.output


def converged_planes(pipeline):
    """The converge reference's inputs from ``pipeline``'s planes: radiance (H, W, 3), spp (H, W), the
    copy of the radiance after part of the samples and that part's spp."""
    read = pipeline.buffers.read
    return (read(RADIANCE.name).transpose(1, 2, 0), read(SPP.name)[0], read(HALF_RADIANCE.name).transpose(1, 2, 0),
            read(HALF_SPP.name)[0])


def test_temporal_static_camera_fades_the_denoiser_as_samples_grow(gpu, scene):
    """Under a static camera the samples accumulate and each frame shows the converge pass's blend of
    their mean and its denoised frame: a black denoiser's frame is black on the first frame (a cut takes
    the denoised frame alone), then frame after frame brings in more of the mean, as the converge
    reference says."""
    pipeline = make_pipeline(scene, gpu, denoiser=ZeroDenoiser(gpu), temporal=True)
    first = pipeline.render(scene, 0).color
    assert first.max() == 0
    shares, copies = [], []
    for frame in range(1, 16):
        image = pipeline.render(scene, frame).color
        radiance, spp, half, half_spp = converged_planes(pipeline)
        assert (spp == frame + 1).all() and radiance.max() > 0
        np.testing.assert_allclose(image, converge(np.zeros_like(radiance), radiance, spp, half, half_spp),
                                   rtol=1e-4, atol=1e-6)
        shares.append(image.sum() / radiance.sum())
        copies.append(int(half_spp[0, 0]))
    # the copy is taken again once the samples since it reach those before it: 1, 2, 4, 8 …
    assert copies == [1, 2, 2, 4, 4, 4, 4, 8, 8, 8, 8, 8, 8, 8, 8]
    # two samples: the mean's share is at most the cap, n² / (n² + CAP_SCALE)
    assert 0 < shares[0] <= 1.001 * 4 / (4 + CONVERGE_CAP_SCALE) and shares[-1] > 0.1


def test_moving_camera_traces_each_frame_afresh(gpu):
    """On ``moving`` (camera and a box move every frame) no samples carry over between frames."""
    moving = builtin_scene("moving")
    pipeline = make_pipeline(moving, gpu, temporal=True)
    for frame in range(3):
        pipeline.render(moving, frame)
        assert (pipeline.buffers.read(SPP.name)[0] == 1).all()


def test_read_back_frames_own_their_arrays(gpu):
    """Planes are copied out of the mapped readback before it is unmapped: a frame's arrays stay as they
    were while the two readback buffers serve later frames, and match the planes on the device
    (channels interleaved, u32 sample counts as float32)."""
    from wgpu_rt.frame.interleave import interleaved

    frames = render("moving", frames=range(4), size=(12, 10), max_depth=2, ctx=gpu, aovs=("albedo", "spp"))
    again = render("moving", frames=[0], size=(12, 10), max_depth=2, ctx=gpu, aovs=("albedo", "spp"))[0]
    np.testing.assert_array_equal(frames[0].color, again.color)
    np.testing.assert_array_equal(frames[0].aovs["albedo"], again.aovs["albedo"])
    assert frames[0].color.flags.owndata and frames[0].color.shape == (10, 12, 3)
    assert not np.array_equal(frames[0].color, frames[3].color)
    planar = np.arange(3 * 10 * 12, dtype=np.uint32)
    expected = planar.reshape(3, 10, 12).transpose(1, 2, 0).astype(np.float32)
    np.testing.assert_array_equal(interleaved(planar, 10, 12), expected)
    assert interleaved(planar, 10, 12).dtype == np.float32


def test_planes_are_interleaved_on_the_device_as_numpy_would(gpu, scene):
    """The HDR colour and three-channel AOVs come back through the device's interleave pass (one
    contiguous copy on the host), equal to the planes on the device interleaved by the numpy reference;
    single-channel and integer planes keep the host's way."""
    from wgpu_rt.frame.interleave import interleaved

    pipeline = make_pipeline(scene, gpu, aovs=("albedo", "normal", "depth", "spp"))
    assert sorted(pipeline.interleave) == sorted([RADIANCE.name, ALBEDO.name, NORMAL.name])
    result = pipeline.render(scene, 0)
    planes = {RADIANCE.name: result.color, **result.aovs}
    for plane in (RADIANCE, ALBEDO, NORMAL, DEPTH, SPP):
        on_device = pipeline.buffers.read(plane.name)
        np.testing.assert_array_equal(planes[plane.name], interleaved(on_device.ravel(), H, W), err_msg=plane.name)
        assert planes[plane.name].dtype == np.float32 and planes[plane.name].flags.owndata
    assert "interleave" in result.stage_ms or not gpu.has_timestamps



def test_next_frame_runs_while_the_caller_holds_a_frame(gpu, scene, monkeypatch):
    """Frames in flight: frame N+1 is recorded before frame N is waited for, submitted as soon as frame
    N's readback is mapped (mapping waits for everything submitted so far, so N+1 submitted earlier
    would finish before N could be copied out, and the device would idle while the host copies), and
    frame N is copied out and handed over after that submit. Each frame equals the same frame rendered
    alone."""
    pipeline = make_pipeline(scene, gpu, tonemap="aces")
    events = []
    for name in ("record", "submit", "wait", "read"):
        def logged(*args, _method=getattr(pipeline, name), _name=name):
            result = _method(*args)
            frame = result.frame if _name in ("record", "read") else args[-1].frame
            events.append(f"{_name} {frame}")
            return result

        monkeypatch.setattr(pipeline, name, logged)
    out = []
    for result in pipeline.frames(scene, range(3)):
        events.append(f"caller {result.frame}")
        out.append(result)
    assert events == ["record 0", "submit 0",
                      "record 1", "wait 0", "submit 1", "read 0", "caller 0",
                      "record 2", "wait 1", "submit 2", "read 1", "caller 1",
                      "wait 2", "read 2", "caller 2"]
    monkeypatch.undo()
    for result in out:
        np.testing.assert_array_equal(result.color, pipeline.render(scene, result.frame).color)

def test_frames_in_flight_do_not_count_the_same_seconds_twice(gpu):
    """Each frame's seconds run from its recording, or from the previous frame's hand-over where it was
    recorded while that one ran, to its readback: over a run they sum to no more than its wall time after
    set-up (counted from each recording, overlapping frames summed to more, about twice a frame's time)."""
    from wgpu_rt.frame.denoise import load_model

    renderer = Renderer("cornell", 1, (96, 64), ctx=gpu, denoise=True, aovs=(),
                        networks={"denoiser": load_model("denoiser", ctx=gpu)})
    started = time.perf_counter()
    results = list(renderer.frames(range(4)))
    wall = time.perf_counter() - started
    assert all(result.seconds > 0 for result in results)
    prepared = results[0].setup_seconds - renderer.setup_seconds   # (the rest was the renderer's, before the run)
    assert sum(result.seconds for result in results) + prepared <= wall


def submits_while_recording(pipeline, scene, frame, monkeypatch) -> int:
    """How many command buffers ``pipeline`` submits while recording ``frame`` (then it is submitted and
    read back as usual)."""
    queue_type, count = type(pipeline.ctx.device.queue), [0]
    submit = queue_type.submit

    def counted(self, buffers):
        count[0] += 1
        return submit(self, buffers)

    with monkeypatch.context() as patch:
        patch.setattr(queue_type, "submit", counted)
        pending = pipeline.record(scene, frame)
    pipeline.finish(pipeline.submit(pending))
    return count[0]


def test_a_frame_is_split_into_submits_only_past_a_submits_worth(gpu, scene, monkeypatch):
    """A frame's samples go into one command buffer until the next batch would take it past
    SAMPLES_PER_SUBMIT pixel samples (here 16 spp): 40 spp are submitted as 16 + 16 while recording and
    the last 8 with the rest of the frame, the same image as one batch; 8 spp handed over from a
    denoiser (a copy of the mean after the first half, between the halves) stay one command buffer, so
    its stage times hold no host gaps. Without a progress bar nothing waits mid-frame; with one, it is
    told of the samples done when it waits (ProgressWaits)."""
    from wgpu_rt.frame import pipeline as frame_pipeline

    whole = make_pipeline(scene, gpu, spp=40).render(scene, 0).color
    monkeypatch.setattr(frame_pipeline, "SAMPLES_PER_SUBMIT", 16 * W * H)
    split = make_pipeline(scene, gpu, spp=40)
    assert submits_while_recording(split, scene, 0, monkeypatch) == 2
    np.testing.assert_array_equal(split.render(scene, 0).color, whole)

    handed_over = make_pipeline(scene, gpu, spp=8, denoiser=IdentityDenoiser(gpu))
    assert handed_over.copies_half
    assert submits_while_recording(handed_over, scene, 0, monkeypatch) == 0

    reads, told = [], []
    monkeypatch.setattr(type(gpu), "read",
                        lambda self, *args, **kwargs: reads.append(1) or np.zeros(1, np.uint32))
    submits_while_recording(split, scene, 1, monkeypatch)
    assert reads == [] and told == []
    split.progress = told.append
    submits_while_recording(split, scene, 2, monkeypatch)
    assert told and told[0] == 16 and sum(told) <= 32 and len(reads) == len(told)


def test_missing_model_is_named(tmp_path, scene, gpu):
    from wgpu_rt.errors import ModelError

    with pytest.raises(ModelError, match="denoiser.onnx"):
        render(scene, size=(W, H), ctx=gpu, denoise=True, models_dir=tmp_path)


def test_render_takes_a_builtin_name_and_a_frame_list(gpu):
    frames = render("cornell", frames=[0], size=(8, 8), max_depth=2, ctx=gpu)
    assert len(frames) == 1 and frames[0].color.shape == (8, 8, 3)


@pytest.mark.parametrize("slow", ["BVH build", "network plan"])
def test_what_the_first_frame_builds_is_set_up_time_not_frame_time(gpu, monkeypatch, slow):
    """A frame's ``seconds`` (what samples/s divide by) leave out what its first frame would build on its
    way, as a peer's timed render leaves out its scene load: a BVH build, or a denoiser plan (kernels,
    activations), that takes a second shows in ``setup_seconds``. A render first, unslowed, compiles the
    passes' shaders, which a slow CPU driver may take seconds over; the second builds its BVH and plan afresh."""
    from wgpu_rt.accel import geometry as geometry_module
    from wgpu_rt.nn.model import WgslModel

    module, name = (geometry_module, "build_bvh") if slow == "BVH build" else (WgslModel, "_build_plan")
    original = getattr(module, name)
    render("cornell", frames=[0], size=(8, 8), max_depth=2, ctx=gpu, denoise=slow == "network plan")

    def slowly(*args):
        time.sleep(1.0)
        return original(*args)

    monkeypatch.setattr(module, name, slowly)
    first = render("cornell", frames=[0], size=(8, 8), max_depth=2, ctx=gpu, denoise=slow == "network plan")[0]
    assert first.setup_seconds >= 1.0 and first.seconds < 1.0, (first.setup_seconds, first.seconds)


def test_unchanged_geometry_is_not_uploaded_again(gpu, scene, monkeypatch):
    """Frames that share geometry reuse the tracer's uploads and allocate nothing: each frame after the
    first writes only its frame parameters (a new seed), whatever the scene's size."""
    pipeline = make_pipeline(scene, gpu)
    pipeline.render(scene, 0)
    counter = TrafficCounter(monkeypatch, gpu)
    for frame in (1, 2, 3):
        pipeline.render(scene, frame)
    monkeypatch.undo()
    assert counter.uploads == 3 and counter.reads == 3


def test_readme_python_example_runs(gpu):
    """The README's Python example: one render() call that denoises and adapts (shipped models)."""
    import wgpu_rt

    result = wgpu_rt.render("cornell", spp=1, size=(32, 24), denoise=True, adaptive=4, tonemap="aces")
    assert result.color.shape == (24, 32, 3) and np.all(np.isfinite(result.color))
    assert result.image.shape == (24, 32, 4) and result.image.dtype == np.uint8
    assert result.aovs["spp"].mean() == pytest.approx(4.0, abs=0.01)
    assert set(result.aovs) == {"albedo", "normal", "depth", "motion", "spp"}
    noisy = wgpu_rt.render("cornell", spp=4, size=(32, 24), aovs=("albedo", "normal", "depth"))
    clean = wgpu_rt.denoise(noisy.color, noisy.aovs["albedo"], noisy.aovs["normal"], noisy.aovs["depth"][..., 0], spp=4)
    assert clean.shape == (24, 32, 3) and np.all(np.isfinite(clean)) and not np.allclose(clean, noisy.color)


def test_the_radiance_aov_is_the_samples_mean_before_the_denoiser(gpu):
    """AOV "radiance": what the tracer's samples averaged to, the denoiser's input; a frame nothing denoises
    gives it as its colour too (each array its own)."""
    from wgpu_rt.frame.denoise import load_model

    options = dict(spp=2, size=(24, 16), seed=4, ctx=gpu)
    plain = render("cornell", aovs=("radiance",), **options)
    np.testing.assert_array_equal(plain.aovs["radiance"], plain.color)
    assert plain.aovs["radiance"] is not plain.color
    denoised = render("cornell", denoise=True, aovs=("radiance", "albedo"),
                      networks={"denoiser": load_model("denoiser", ctx=gpu)}, **options)
    np.testing.assert_allclose(denoised.aovs["radiance"], plain.color, rtol=1e-6)   # (another build of the tracer)
    assert not np.allclose(denoised.color, plain.color, atol=1e-3)


def test_a_frame_of_several_samples_hands_over_from_the_denoiser_to_their_mean(gpu, scene):
    """denoise at n > 1 spp: the converge pass blends the denoised frame with the mean (a black
    denoiser's frame is the mean scaled by the mean's weight: at most n² / (n² + CAP_SCALE)); at 1 spp the
    denoised frame alone."""
    for spp in (1, 4, 32):
        pipeline = make_pipeline(scene, gpu, denoiser=ZeroDenoiser(gpu), spp=spp)
        image = pipeline.render(scene, 0).color
        if spp == 1:
            assert image.max() == 0
            continue
        radiance, counts, half, half_spp = converged_planes(pipeline)
        assert (counts == spp).all() and radiance.max() > 0
        assert (half_spp == spp // 2).all()
        np.testing.assert_allclose(image, converge(np.zeros_like(radiance), radiance, counts, half, half_spp),
                                   rtol=1e-4, atol=1e-6)
        lit = radiance > 0.01
        share = image[lit] / radiance[lit]
        cap = spp ** 2 / (spp ** 2 + CONVERGE_CAP_SCALE)
        assert share.max() <= cap * (1 + 1e-4) and share.mean() > 0.1 * cap


@pytest.mark.parametrize("sampler", ["variance", "heat"])
def test_an_adaptive_frame_measures_its_means_error_against_the_probe(gpu, scene, sampler):
    """An adaptive frame's converge pass reads the probe's mean as the copy (1 spp, 2 for the variance
    sampler's two probe samples): pixels that took extra samples can hand over, the rest keep the
    denoised frame."""
    heat = np.random.default_rng(5).random((H, W)).astype(np.float32) + 0.1
    pipeline = make_pipeline(scene, gpu, denoiser=ZeroDenoiser(gpu), error_predictor=FixedHeat(gpu, heat),
                             adaptive=AdaptiveSettings(sampler=sampler, budget=4.0, pool_sigma=0.0, uniform_share=0.0))
    image = pipeline.render(scene, 0).color
    radiance, counts, half, half_spp = converged_planes(pipeline)
    probe = 2 if sampler == "variance" else 1
    assert (half_spp == probe).all() and (counts > probe).any() and (counts == probe).any()
    np.testing.assert_allclose(image, converge(np.zeros_like(radiance), radiance, counts, half, half_spp),
                               rtol=1e-4, atol=1e-6)
    assert image[counts == probe].max() == 0 and image.max() > 0


def test_wiring_is_checked_from_the_declared_planes(gpu):
    """A stage reading a plane no earlier stage writes (FrameBuffers would give it zeros) is refused
    when the pipeline is built; the pipelines every mode builds pass the check (the tests above)."""
    from wgpu_rt.frame.pipeline import Stage, check_wiring
    from wgpu_rt.frame.planes import DENOISED
    from wgpu_rt.frame.tonemap import TonemapPass
    from wgpu_rt.frame.unpack import UnpackPass
    from wgpu_rt.trace.trace_pass import TracePass

    tonemap = TonemapPass(gpu, W, H, DENOISED)
    with pytest.raises(ValueError, match="TonemapPass reads denoised"):
        check_wiring([tonemap], written=TracePass.outputs)
    check_wiring([UnpackPass(gpu, W, H, gpu.storage(12)), tonemap], written=TracePass.outputs)
    with pytest.raises(ValueError, match="denoiser reads denoiser_input"):
        check_wiring([Stage("denoiser", (DENOISER_INPUT,), ())], written=TracePass.outputs)


@pytest.mark.parametrize("denoised", [False, True])
def test_hdr_false_drops_the_colour_plane_from_the_readback(gpu, scene, monkeypatch, denoised):
    """hdr=False reads back the same display image and AOVs in a buffer smaller by exactly the colour
    plane (12 bytes a pixel), still in one readback a frame, and leaves ``color`` None."""
    def frame_of(hdr):
        pipeline = make_pipeline(scene, gpu, denoiser=IdentityDenoiser(gpu) if denoised else None,
                                 tonemap="aces", aovs=("depth",), hdr=hdr)
        counter = TrafficCounter(monkeypatch, gpu)
        result = pipeline.render(scene, 0)
        monkeypatch.undo()
        assert counter.reads == 1
        return pipeline, result

    with_colour, full = frame_of(True)
    without_colour, display_only = frame_of(False)
    colour_bytes = 12 * W * H
    assert with_colour.color.nbytes(W, H) == colour_bytes
    assert without_colour.layout.nbytes == with_colour.layout.nbytes - colour_bytes
    assert all(buffer.size == without_colour.layout.nbytes for buffer in without_colour._readbacks)
    assert display_only.color is None and full.color.shape == (H, W, 3) and full.color.max() > 0
    np.testing.assert_array_equal(display_only.image, full.image)
    np.testing.assert_array_equal(display_only.aovs["depth"], full.aovs["depth"])
    assert set(display_only.aovs) == {"depth"}


def test_quality_high_denoises_with_an_ensemble_of_four(gpu):
    """render(quality="high") runs the denoiser as an ensemble of 4 passes on the device: the frame equals
    the same frame denoised by a model built with ensemble=4, and differs from the one-pass frame."""
    from wgpu_rt.frame.denoise import load_model

    options = dict(spp=1, size=(W, H), seed=5, denoise=True, ctx=gpu)
    high = render("cornell", quality="high", **options).color
    given = render("cornell", networks={"denoiser": load_model("denoiser", ctx=gpu, quality="high")}, **options)
    assert given.color is not None and np.array_equal(high, given.color) and np.all(np.isfinite(high))
    assert not np.allclose(high, render("cornell", **options).color, atol=1e-3)


@pytest.mark.parametrize("size, min_side, levels", [((21, 13), None, 1), ((37, 29), 8, 2)])
def test_low_band_frame_equals_the_numpy_path(gpu, monkeypatch, size, min_side, levels):
    """A denoised frame with the low band (forced on at an odd size: one coarser level; with the level
    rule's side lowered to 8: two) equals ``denoise()`` with the same model on the frame's own traced
    planes, and differs from the frame without it; the automatic choice takes it from 256 pixels a side."""
    from wgpu_rt.frame import lowband
    from wgpu_rt.frame.denoise import denoise, load_model
    from wgpu_rt.trace.trace_pass import AUX_SAMPLES

    if min_side is not None:
        monkeypatch.setattr(lowband, "LOW_BAND_MIN_SIDE", min_side)
    assert lowband.low_band_levels(*size, True) == levels
    model = load_model("denoiser", ctx=gpu)
    options = dict(spp=1, size=size, seed=3, ctx=gpu)
    planes = render("cornell", aovs=("albedo", "normal", "depth", "spp"), aux_samples=AUX_SAMPLES, **options)
    frames = {setting: render("cornell", denoise=True, aovs=(), low_band=setting, networks={"denoiser": model},
                              **options).color for setting in (False, True)}
    expected = denoise(model, planes.color, *(planes.aovs[name] for name in ("albedo", "normal", "depth")),
                       planes.aovs["spp"], low_band=True)
    np.testing.assert_allclose(frames[True], expected, rtol=1e-4, atol=1e-5)
    assert not np.allclose(frames[True], frames[False], rtol=1e-3, atol=1e-4)
    if min_side is None:
        assert Renderer("cornell", size=(256, 300), denoise=True, ctx=gpu).pipeline.chain.low_band is not None
        assert Renderer("cornell", size=(255, 300), denoise=True, ctx=gpu).pipeline.chain.low_band is None


def test_low_band_left_out_from_16_samples_a_pixel(gpu, monkeypatch):
    """Auto: a frame of 16 spp is built without the coarser levels, one of 15 with them; a static view
    accumulating 4 spp a frame in temporal mode runs them on its first three frames (4, 8, 12 samples)
    and not from the fourth (16) on; forced on, every frame runs them."""
    from wgpu_rt.frame import lowband

    monkeypatch.setattr(lowband, "LOW_BAND_MIN_SIDE", 8)
    options = dict(size=(21, 13), denoise=True, aovs=(), ctx=gpu)
    assert Renderer("cornell", spp=lowband.LOW_BAND_MAX_SPP, **options).pipeline.chain.low_band is None
    assert Renderer("cornell", spp=lowband.LOW_BAND_MAX_SPP - 1, **options).pipeline.chain.low_band is not None
    runs = []
    monkeypatch.setattr(lowband.LowBand, "execute", lambda self, encoder, buffers: runs.append(1))
    for setting, expected in ((None, 3), (True, 5)):
        runs.clear()
        render("cornell", spp=4, temporal=True, frames=range(5), low_band=setting, **options)
        assert len(runs) == expected


def test_static_view_traces_its_aux_albedo_once(gpu, monkeypatch):
    """In temporal mode a static view's aux albedo (the same seed, camera and scene each frame) is traced
    on its first frame and put back on the next ones: every frame reads back the albedo a fresh aux pass
    gives, and after a cut it is traced again."""
    from wgpu_rt.trace.trace_pass import AUX_SAMPLES, TracePass

    calls = []
    traced = TracePass.execute_aux
    monkeypatch.setattr(TracePass, "execute_aux", lambda self, *a, **k: calls.append(1) or traced(self, *a, **k))
    options = dict(size=(21, 13), aovs=("albedo",), aux_samples=AUX_SAMPLES, ctx=gpu, seed=2)
    frames = render("cornell", temporal=True, frames=range(3), **options)
    assert len(calls) == 1
    fresh = render("cornell", **options).aovs["albedo"]   # frame 0 on its own: the aux pass's estimate
    for frame in frames:
        np.testing.assert_array_equal(frame.aovs["albedo"], fresh)
    calls.clear()
    render("cornell", temporal=True, frames=[0, 1, 5, 6], **options)   # 5 is a cut (frames skipped)
    assert len(calls) == 2


def test_denoiser_steps_frame_equals_the_numpy_path(gpu):
    """A denoised frame with its colour balance held to the samples and the à-trous post filter (both
    by default), and with each left out, and with the exposure step on and off (by default as the model
    was trained: the shipped one with it), equals ``denoise()`` with the same settings on the frame's own
    traced planes; each step changes the frame."""
    from wgpu_rt.frame.denoise import denoise, load_model
    from wgpu_rt.frame.denoise_chain import trained_auto_exposure
    from wgpu_rt.trace.trace_pass import AUX_SAMPLES

    model = load_model("denoiser", ctx=gpu)
    options = dict(spp=1, size=(37, 29), seed=4, ctx=gpu)
    planes = render("cornell", aovs=("albedo", "normal", "depth", "spp"), aux_samples=AUX_SAMPLES, **options)
    inputs = (planes.color, *(planes.aovs[name] for name in ("albedo", "normal", "depth", "spp")))
    frames = {}
    for settings in ((True, True, None), (False, True, None), (True, False, None), (True, True, True),
                     (True, True, False)):
        steps = dict(zip(("chroma", "post_filter", "auto_exposure"), settings))
        frames[settings] = render("cornell", denoise=True, aovs=(), networks={"denoiser": model}, **steps,
                                  **options).color
        np.testing.assert_allclose(frames[settings], denoise(model, *inputs, **steps), rtol=1e-4, atol=1e-5)
    trained = trained_auto_exposure(model)
    for settings in ((False, True, None), (True, False, None), (True, True, not trained)):
        assert not np.allclose(frames[True, True, None], frames[settings], rtol=1e-3, atol=1e-4)
    np.testing.assert_array_equal(frames[True, True, None], frames[True, True, trained])


@pytest.mark.parametrize("options, message", [
    (dict(quality="best"), "quality 'best': choose one of balanced, high"),
    (dict(chroma="on"), "chroma must be True or False"),
    (dict(post_filter=1), "post_filter must be True or False"),
    (dict(white_balance="off"), "white_balance must be True or False"),
    (dict(auto_exposure="on"), "auto_exposure must be True, False or None"),
    (dict(low_band="on"), "low_band must be True, False or None"),
    (dict(hdr=False, aovs=()), "read nothing back"),
    (dict(hdr=False, tonemap=None, aovs=""), "read nothing back"),
    (dict(hdr="no", tonemap="aces"), "hdr must be True or False"),
])
def test_bad_readback_choices_are_refused_before_work(options, message):
    """Checked before the scene is loaded: the unknown scene name is never reached."""
    from wgpu_rt.errors import WgpuRtError

    with pytest.raises(WgpuRtError, match=message):
        render("no-such-scene", size=(W, H), **options)




def contrasted_onnx(network, path, said):
    """``network`` (a small heat/confidence CNN) with its last conv's weights ×30, so its output varies
    across the frame, exported with the exposure step's metadata ``said`` ("on", or None: nothing)."""
    import torch

    from wgpu_rt.frame.denoise_chain import INPUT_EXPOSURE
    from wgpu_rt.train.networks import export_onnx

    with torch.no_grad():
        network.body[-2].weight *= 30.0
    return export_onnx(network, path, metadata={INPUT_EXPOSURE: said} if said else None)


def test_error_predictor_reads_its_probe_at_one_key(gpu, scene, tmp_path):
    """An error predictor whose ONNX file says it was trained with the exposure step gets the same sample
    map from the scene at any scale of its light (the probe brought to PROBE_KEY on the device; the scene
    renders exactly scaled; the key's own f32 rounding may move a pixel or two); one whose file says
    nothing reads the probe as it is, and its map moves."""
    torch = pytest.importorskip("torch")
    from wgpu_rt.frame.adaptive import EXTRA_SAMPLES
    from wgpu_rt.frame.denoise import load_model
    from wgpu_rt.train.networks import ErrorPredictor

    probe = render(scene, size=(W, H), max_depth=3, ctx=gpu, aovs=()).color
    adaptive, maps = AdaptiveSettings(budget=3.0, uniform_share=0.0, pool_sigma=0.0), {}
    # (what the file says, auto_exposure=): auto follows the file, True and False override it
    cases = (("on", None), (None, None), (None, True), ("on", False))
    for said, forced in cases:
        torch.manual_seed(0)
        path = contrasted_onnx(ErrorPredictor(), tmp_path / f"{said}.onnx", said)
        model = load_model("error_predictor", "fp32", path=path, ctx=gpu)
        for stops in (0, -7, 9):
            lit = scene.with_light_scaled(2.0 ** stops)
            np.testing.assert_array_equal(render(lit, size=(W, H), max_depth=3, ctx=gpu, aovs=()).color,
                                          np.float32(2.0 ** stops) * probe)
            pipeline = make_pipeline(lit, gpu, error_predictor=model, adaptive=adaptive, auto_exposure=forced)
            pipeline.render(lit, 0)
            maps[said, forced, stops] = pipeline.buffers.read(EXTRA_SAMPLES.name)
    assert maps["on", None, 0].min() < 2 < maps["on", None, 0].max()
    for said, forced in cases:
        at_one_key = said == "on" if forced is None else forced
        for stops in (-7, 9):
            moved = np.mean(maps[said, forced, stops] != maps[said, forced, 0])
            assert moved < 0.01 if at_one_key else moved > 0.1, (said, forced, stops)


def test_confidence_reads_the_frame_at_one_key(gpu, tmp_path):
    """A confidence model whose ONNX file says it was trained with the exposure step keeps the same history
    on a moving scene at any scale of its light (the temporal output scales with it); one whose file says
    nothing reads the frames as they are, and what it keeps moves with the light."""
    torch = pytest.importorskip("torch")
    from wgpu_rt.frame.denoise import load_model
    from wgpu_rt.train.networks import ConfidencePredictor

    moving = builtin_scene("moving")
    outputs = {}
    cases = (("on", None), (None, None), (None, True), ("on", False))   # as for the error predictor
    for said, forced in cases:
        torch.manual_seed(0)
        model = load_model("confidence", "fp32", path=contrasted_onnx(ConfidencePredictor(), tmp_path / f"{said}.onnx",
                                                                      said), ctx=gpu)
        for stops in (0, -7, 9):
            scale = np.float32(2.0 ** stops)
            frames = render(moving.with_light_scaled(scale), size=(W, H), max_depth=3, ctx=gpu, aovs=(),
                            temporal=TemporalSettings(), frames=range(3), networks={"confidence": model},
                            auto_exposure=forced)
            outputs[said, forced, stops] = frames[-1].color / scale
    for said, forced in cases:
        base = outputs[said, forced, 0]
        for stops in (-7, 9):
            if (said == "on" if forced is None else forced):
                np.testing.assert_allclose(outputs[said, forced, stops], base, rtol=1e-4, atol=1e-5 * base.max())
            else:
                assert np.abs(outputs[said, forced, stops] - base).max() > 0.01 * base.max(), (said, forced, stops)
