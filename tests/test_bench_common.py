"""benchmarks/common.py: scoring against golds of few samples (twin_corrected_psnr); equivalent spp on a
brute-force curve; scene files named by path, skipped when a mesh they name is absent (the user scenes in
benchmarks/scenes)."""

import importlib
from pathlib import Path

import numpy as np
import pytest

import wgpu_rt.scene.mitsuba
from wgpu_rt import metrics

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def common(monkeypatch):
    monkeypatch.syspath_prepend(str(REPO / "benchmarks"))
    return importlib.import_module("common")


def test_equivalent_spp_reads_the_brute_force_curve_in_log_log(common):
    """On a Monte Carlo curve (error ∝ 1/spp) an error between two measured counts maps back to its exact
    count; brute force's own error at a measured count is that count; outside the curve it says so."""
    spp = [1, 4, 16, 64]
    error = [0.8 / n for n in spp]
    assert common.equivalent_spp(spp, error, 0.8 / 10) == "10.0"
    assert common.equivalent_spp(spp, error, 0.8) == "1.0" and common.equivalent_spp(spp, error, 0.2) == "4.0"
    assert common.equivalent_spp(spp, error, 0.9) == "< 1" and common.equivalent_spp(spp, error, 0.001) == "> 64"
    # a noisy curve that crosses the target twice: the first crossing counts
    first = common.equivalent_spp([1, 4], [1.0, 0.1], 0.15)
    assert common.equivalent_spp([1, 4, 16, 64], [1.0, 0.1, 0.2, 0.05], 0.15) == first


def test_twin_golds_recover_the_score_against_the_truth(common):
    """Two golds with independent noise as strong as the image's own error: against one of them the
    score is 3 dB low and two images' gap is narrowed; the twin-corrected scores match those against the
    truth within a tenth of a dB."""
    rng = np.random.default_rng(3)
    truth = rng.uniform(0.05, 2.0, (256, 256, 3))

    def noisy(sigma):
        return np.maximum(truth * (1 + sigma * rng.standard_normal(truth.shape)), 0.0)

    gold, twin = noisy(0.05), noisy(0.05)
    good, poor = noisy(0.03), noisy(0.06)
    for image in (good, poor):
        exact = metrics.psnr(truth, image)
        assert abs(common.twin_corrected_psnr(gold, twin, image) - exact) < 0.1
        assert metrics.psnr(gold, image) < exact - 1.0
    gap = metrics.psnr(truth, good) - metrics.psnr(truth, poor)
    assert metrics.psnr(gold, good) - metrics.psnr(gold, poor) < gap - 1.0
    assert common.twin_corrected_psnr(gold, twin, 0.5 * (gold + twin)) == float("inf")


SCENE_FILES = sorted((REPO / "benchmarks" / "scenes").glob("*.toml"))
# issue 12's three scenes as a user builds them: a mesh with a rough copper ball and a glass cube, a
# closed room lit indirectly, rough gold and frosted glass under a low sun and a sky
USER_SCENES = [REPO / "benchmarks" / "scenes" / f"{name}.toml"
               for name in ("bunny-copper-glass", "gold-bunny-sky", "teapot-closed-room")]


def test_the_user_scenes_exist():
    """The three user scenes, the corridor of twenty lamps (light picks, BENCHMARKS.md §30) and the paved plaza
    through a thin lens (§47)."""
    assert all(path in SCENE_FILES for path in USER_SCENES)
    assert [p.stem for p in SCENE_FILES if p not in USER_SCENES] == ["corridor-lamps", "plaza-lens"]


def test_the_lens_scene_loads_with_its_texture_and_aperture(common):
    [scene] = common.load_scenes([str(REPO / "benchmarks" / "scenes" / "plaza-lens.toml")])
    assert scene.camera.aperture_radius > 0 and any(m.texture is not None for m in scene.meshes)


def test_the_corridor_scene_loads_with_its_twenty_lamps(common):
    [scene] = common.load_scenes([str(REPO / "benchmarks" / "scenes" / "corridor-lamps.toml")])
    assert sum(scene.materials[m.material].is_emissive for m in scene.meshes) == 20


@pytest.mark.parametrize("path", USER_SCENES, ids=lambda p: p.stem)
def test_user_scenes_load_with_their_scanned_meshes(common, path):
    if common.missing_mesh_files(path):
        pytest.skip(f"{common.missing_mesh_files(path)[0]} not found (../shared/meshes is not shipped)")
    [scene] = common.load_scenes([str(path)])
    assert scene.name == path.stem
    assert max(len(m.faces) for m in scene.meshes) > 5000, "the scanned mesh is in the scene"


def test_a_scene_file_whose_mesh_is_absent_is_skipped_by_name(common, tmp_path, capsys):
    scene = tmp_path / "lost.toml"
    scene.write_text('[camera]\norigin = [0, 0, 3]\n[materials.white]\nreflectance = 0.8\n'
                     '[[meshes]]\nfile = "nowhere/bunny.obj"\nmaterial = "white"\n')
    assert common.missing_mesh_files(scene) == [tmp_path / "nowhere" / "bunny.obj"]
    assert common.load_scenes([str(scene)]) == []
    assert f"skipping {scene}: {tmp_path / 'nowhere' / 'bunny.obj'} not found" in capsys.readouterr().out
    broken = tmp_path / "broken.toml"
    broken.write_text("[camera\n")
    assert common.missing_mesh_files(broken) == []
    from wgpu_rt.errors import SceneError

    with pytest.raises(SceneError, match="broken.toml: cannot parse"):
        common.load_scenes([str(broken)])


def test_a_mitsuba_gold_is_the_sample_weighted_mean_of_its_passes(common, monkeypatch, tmp_path):
    """1100 samples in passes of at most PASS_SPP (512): 367 + 367 + 366, seeds 12345, 12346,
    12347, weighed by their counts; cached under a key of its own."""
    calls = []

    def fake_render(mi, scene, size, spp, max_depth, seed, frame):
        calls.append((spp, seed))
        return np.full((size[1], size[0], 3), float(seed - common.GOLD_SEED), np.float32), 0.0

    monkeypatch.setattr(common, "mitsuba", lambda: (None, "fake"))
    monkeypatch.setattr(wgpu_rt.scene.mitsuba, "timed_render", fake_render)

    class Args:
        gold_renderer, gold_spp, max_depth, gold_cache = "mitsuba", 1100, 8, str(tmp_path)

    class Scene:
        name, lights = "box", []

    gold = common.gold_render(Scene(), (4, 2), Args())
    assert calls == [(367, 12345), (367, 12346), (366, 12347)]
    np.testing.assert_allclose(gold, (367 * 0 + 367 * 1 + 366 * 2) / 1100, rtol=1e-6)
    assert (tmp_path / "box_4x2_1100spp_depth8_mitsuba.npy").exists()
    assert common.gold_render(Scene(), (4, 2), Args()).shape == (2, 4, 3) and len(calls) == 3, "read back"


def test_no_mitsuba_gold_for_a_light_through_a_thin_pane(common, monkeypatch, capsys):
    """Mitsuba's shadow rays stop at thin panes: a scene with one and a point light gets no Mitsuba gold (exit 2, one
    line naming it), before Mitsuba is asked for anything."""
    from pathlib import Path

    from wgpu_rt.scene.loader import parse_scene

    monkeypatch.setattr(common, "mitsuba", lambda: (None, "fake"))
    scene = parse_scene({"camera": {"origin": [0, 0, 3], "target": [0, 0, 0]},
                         "materials": {"pane": {"kind": "thin_dielectric"}},
                         "meshes": [{"shape": "rectangle", "material": "pane"}],
                         "lights": [{"type": "point", "position": [0, 0, -2], "intensity": 1}]}, "window", Path("."))
    with pytest.raises(SystemExit) as stop:
        common.mitsuba_gold(scene, (4, 2), 16, 4, 1)
    assert stop.value.code == 2
    assert "window: Mitsuba's shadow rays stop at thin panes" in capsys.readouterr().err


def test_a_mitsuba_gold_frame_is_mitsubas_radiance_at_that_frame_with_our_motion(common, monkeypatch, tmp_path):
    """Frame 2 of an animated scene: Mitsuba renders that frame (seeds 12345 + 2000 + pass), our tracer only
    the motion vectors (MITSUBA_MOTION_SPP samples, frame 2); cached apart from our own gold of the frame."""
    import wgpu_rt.renderer

    mitsuba_calls, our_calls = [], []

    def fake_mitsuba(mi, scene, size, spp, max_depth, seed, frame):
        mitsuba_calls.append((spp, seed, frame))
        return np.full((size[1], size[0], 3), 0.5, np.float32), 0.0

    def fake_ours(scene, spp, size, max_depth, seed, frames, aovs):
        our_calls.append((spp, frames, aovs))
        motion = np.full((size[1], size[0], 2), 0.25, np.float32)
        return type("Result", (), {"color": np.zeros((size[1], size[0], 3), np.float32), "aovs": {"motion": motion}})

    monkeypatch.setattr(common, "mitsuba", lambda: (None, "fake"))
    monkeypatch.setattr(wgpu_rt.scene.mitsuba, "timed_render", fake_mitsuba)
    monkeypatch.setattr(wgpu_rt.renderer, "render", fake_ours)

    class Args:
        gold_renderer, gold_spp, max_depth, gold_cache = "mitsuba", 600, 8, str(tmp_path)

    class Scene:
        name, lights = "box", []

    color, motion = common.gold_frame(Scene(), (4, 2), Args(), 2)
    assert mitsuba_calls == [(300, 14345, 2), (300, 14346, 2)]
    assert our_calls == [(common.MITSUBA_MOTION_SPP, 2, ("motion",))]
    np.testing.assert_allclose(color, 0.5)
    np.testing.assert_allclose(motion, 0.25)
    assert (tmp_path / "box_4x2_600spp_depth8_frame2_mitsuba.npy").exists()
    assert (tmp_path / "box_4x2_600spp_depth8_frame2_mitsuba_motion.npy").exists()


def test_a_world_named_in_a_benchmark_moves_over_the_frames_asked(common):
    [still] = common.load_scenes(["world-2147483700"])
    [moving] = common.load_scenes(["world-2147483700"], world_frames=4)
    assert still.frame_count == 1 and moving.frame_count == 4
    assert not np.allclose(moving.camera_at(0).origin, moving.camera_at(3).origin)


def test_a_range_of_worlds_names_each_seed_in_it(common):
    assert common.world_range("world-2147483648..2147483650") == [f"world-{s}" for s in (2147483648, 2147483649,
                                                                                          2147483650)]
    assert common.world_range("cornell") == ["cornell"] and common.world_range("world-7") == ["world-7"]
    assert [scene.name for scene in common.load_scenes(["cornell", "world-2147483700..2147483701"])] == [
        "cornell", "world-2147483700", "world-2147483701"]
    with pytest.raises(SystemExit, match="below its first"):
        common.world_range("world-9..8")


def test_the_converge_pass_cost_is_timed_on_the_device(gpu, monkeypatch):
    """bench_converge.py --pass-cost (the GPU session's converge_cost part): the shipped pass alone, a positive
    device time where the adapter has timestamps."""
    if not gpu.has_timestamps:
        pytest.skip("this adapter has no timestamp queries")
    monkeypatch.syspath_prepend(str(REPO / "benchmarks"))
    bench_converge = importlib.import_module("bench_converge")
    assert 0 < bench_converge.pass_cost((24, 20), repeats=2) < 60_000
