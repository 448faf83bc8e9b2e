"""The truth engine (with a fake renderer: no GPU needed), the dataset reader's errors, scene variety
and the training targets."""

import json

import numpy as np
import pytest
from dataset_fakes import fake_render

from wgpu_rt.dataset import DatasetConfig, DatasetError, TruthEngine, load_views, plan_views
from wgpu_rt.dataset.truth import GOLD_AOV_SPP, frame_file
from wgpu_rt.dataset.variety import HELD_OUT_SHAPES, TRAINING_SHAPES, catmull_rom, vary_scene
from wgpu_rt.io import read_exr, write_exr
from wgpu_rt.train.targets import disocclusion_mask, error_heatmap, reproject, runtime_history

CONFIG = DatasetConfig(scenes=("cornell", "sun-room"), views=10, size=16, spp=(1, 4), gold=64,
                       sequence_fraction=0.4)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("data")
    TruthEngine(CONFIG, out, renderer=fake_render).run(progress=False)
    return out


def test_plan_is_deterministic_and_shards_partition_it():
    full = plan_views(CONFIG)
    assert full == plan_views(CONFIG)
    shards = [plan_views(CONFIG, (i, 3)) for i in range(3)]
    assert sorted(v.view_id for s in shards for v in s) == sorted(v.view_id for v in full)
    assert {v.split for v in full} == {"train", "val", "test"}
    assert {v.frames for v in full} == {1, CONFIG.sequence_length}


def test_engine_writes_every_file_and_a_manifest(dataset):
    manifest = json.loads((dataset / "manifest.json").read_text())
    assert len(manifest["views"]) == 20
    for record in manifest["views"]:
        for f in range(record["frames"]):
            for spp in (*CONFIG.spp, "gold"):
                image = read_exr(dataset / "views" / record["view_id"] / frame_file(f, spp))
                assert {"color", "albedo", "normal", "depth", "motion"} <= set(image)
    assert not list(dataset.rglob("*.tmp"))


def test_a_manifest_gives_back_the_config_it_was_rendered_with(dataset):
    recorded = json.loads((dataset / "manifest.json").read_text())["config"]
    assert "guide_albedo" in recorded            # the renderer's convention, recorded beside the settings
    assert DatasetConfig.from_record(recorded) == CONFIG


def test_test_views_hold_only_held_out_shapes(dataset):
    for record in json.loads((dataset / "manifest.json").read_text())["views"]:
        added = {name.rsplit("_", 1)[0] for name in record["objects"]
                 if name.rsplit("_", 1)[0] in TRAINING_SHAPES + HELD_OUT_SHAPES}
        assert added, record
        assert added <= set(HELD_OUT_SHAPES if record["split"] == "test" else TRAINING_SHAPES), record


def test_rerun_skips_finished_views_and_rerenders_identically(dataset, tmp_path):
    calls = []
    counting = lambda *a, **k: calls.append(1) or fake_render(*a, **k)  # noqa: E731
    assert TruthEngine(CONFIG, dataset, renderer=counting).run(progress=False) == []
    assert not calls
    victim = dataset / "views" / "v00003" / frame_file(0, 4)
    before = read_exr(victim)["color"]
    victim.unlink()
    redone = TruthEngine(CONFIG, dataset, renderer=counting).run(progress=False)
    assert [r.view_id for r in redone] == ["v00003"] and len(calls) == 1
    np.testing.assert_array_equal(read_exr(victim)["color"], before)


def test_an_interrupted_run_resumes_without_losing_work(tmp_path):
    config = DatasetConfig(scenes=("cornell",), views=4, size=8, spp=(1,), gold=4,
                           sequence_fraction=0.0)
    budget = iter(range(5))

    def dies_midway(*args, **kwargs):
        if next(budget, None) is None:
            raise KeyboardInterrupt
        return fake_render(*args, **kwargs)

    with pytest.raises(KeyboardInterrupt):
        TruthEngine(config, tmp_path, renderer=dies_midway).run(progress=False)
    finished = sorted(p.parent.name for p in tmp_path.glob("views/*/view.json"))
    assert finished == ["v00000", "v00001"]
    assert not list(tmp_path.rglob("*.tmp"))
    rest = TruthEngine(config, tmp_path, renderer=fake_render).run(progress=False)
    assert [r.view_id for r in rest] == ["v00002", "v00003"]
    assert len(json.loads((tmp_path / "manifest.json").read_text())["views"]) == 4


def test_every_noisy_render_gets_the_aux_pass_and_gold_none(tmp_path):
    """A noisy render at the gold's sample count is still a noisy render: it takes the aux pass (it did
    not when the pass was chosen by spp < gold, and a --gold 1 dataset's 1-spp inputs came out with noisy
    albedo)."""
    calls = []
    recording = lambda *a, **k: calls.append((k["spp"], k["aux_samples"])) or fake_render(*a, **k)  # noqa: E731
    config = DatasetConfig(scenes=("cornell",), views=1, size=8, spp=(1, 4), gold=4, aux_samples=3,
                           sequence_fraction=0.0)
    TruthEngine(config, tmp_path, renderer=recording).run(progress=False)
    assert calls == [(1, 3), (4, 3), (4, 0)]


def test_a_mitsuba_gold_takes_its_colour_from_mitsuba_and_its_g_buffers_from_our_tracer(tmp_path):
    """--gold-renderer mitsuba: the gold file's colour is gold_color's at the gold's spp, seed and frame; its
    G-buffers come from our tracer at GOLD_AOV_SPP (without the aux pass); the noisy renders stay ours. The
    setting is recorded, and a dataset rendered with our golds refuses to resume with Mitsuba's."""
    ours, mitsuba = [], []
    recording = lambda *a, **k: ours.append((k["spp"], k["seed"])) or fake_render(*a, **k)  # noqa: E731

    def gold_color(scene, size, spp, max_depth, seed, frame):
        mitsuba.append((spp, seed, frame))
        return np.full((size[1], size[0], 3), 7.0, np.float32)

    config = DatasetConfig(scenes=("cornell",), views=1, size=8, spp=(1, 4), gold=4096, gold_renderer="mitsuba",
                           sequence_fraction=0.0)
    TruthEngine(config, tmp_path / "m", renderer=recording, gold_color=gold_color).run(progress=False)
    assert [spp for spp, _ in ours] == [1, 4, GOLD_AOV_SPP]
    assert mitsuba == [(4096, ours[-1][1], 0)]
    gold = read_exr(tmp_path / "m" / "views" / "v00000" / frame_file(0, "gold"))
    assert np.all(gold["color"] == 7.0) and {"albedo", "normal", "depth", "motion"} <= set(gold)
    assert json.loads((tmp_path / "m" / "config.json").read_text())["gold_renderer"] == "mitsuba"
    ours_config = DatasetConfig(**{**config.__dict__, "gold_renderer": "ours"})
    TruthEngine(ours_config, tmp_path / "o", renderer=fake_render).run(progress=False)
    with pytest.raises(DatasetError, match="gold_renderer='ours'"):
        TruthEngine(config, tmp_path / "o", renderer=fake_render, gold_color=gold_color).run(progress=False)
    with pytest.raises(DatasetError, match="--gold-renderer must be one of ours, mitsuba"):
        DatasetConfig(scenes=("cornell",), gold_renderer="blender")


def test_mitsuba_golds_without_mitsuba_fail_before_anything_is_written(tmp_path, monkeypatch):
    import wgpu_rt.scene.mitsuba

    def missing(variant=None):
        raise ImportError("No module named 'mitsuba'")

    monkeypatch.setattr(wgpu_rt.scene.mitsuba, "load_mitsuba", missing)
    config = DatasetConfig(scenes=("cornell",), views=1, size=8, spp=(1,), gold=4, gold_renderer="mitsuba")
    with pytest.raises(DatasetError, match="--gold-renderer mitsuba: Mitsuba 3 does not load here"):
        TruthEngine(config, tmp_path / "data", renderer=fake_render)
    assert not (tmp_path / "data").exists()


def test_mitsuba_golds_of_a_scene_with_a_light_through_a_thin_pane_are_refused_before_anything_is_written(tmp_path):
    """Mitsuba's shadow rays stop at thin panes, ours cross them: a scene with a pane and a point, spot or directional
    light has no Mitsuba gold, so --gold-renderer mitsuba refuses it by name; without the light (an area light alone,
    which Mitsuba's paths meet through the pane) it is rendered."""
    scene = {"camera": {"origin": [0, 1, 3], "target": [0, 0, 0]},
             "materials": {"pane": {"kind": "thin_dielectric"}, "floor": {}},
             "meshes": [{"shape": "rectangle", "material": "floor", "transform": {"rotate": {"axis": [1, 0, 0],
                                                                                             "angle": -90}}},
                        {"shape": "rectangle", "material": "pane", "transform": {"translate": [0, 0.5, 1]}}],
             "lights": [{"type": "point", "position": [0, 2, 2], "intensity": 1}]}
    (tmp_path / "window.json").write_text(json.dumps(scene))
    def gold_color(scene, size, spp, max_depth, seed, frame):
        return np.ones((size[1], size[0], 3), np.float32)

    config = DatasetConfig(scenes=(str(tmp_path / "window.json"),), views=1, size=8, spp=(1,), gold=4,
                           gold_renderer="mitsuba", sequence_fraction=0.0)
    with pytest.raises(DatasetError, match=r"window\.json: Mitsuba's shadow rays stop at thin panes"):
        TruthEngine(config, tmp_path / "data", renderer=fake_render, gold_color=gold_color)
    assert not (tmp_path / "data").exists()
    scene["lights"] = []
    scene["materials"]["lamp"] = {"emission": 2}
    scene["meshes"].append({"shape": "rectangle", "material": "lamp", "transform": {"translate": [0, 2, -1]}})
    (tmp_path / "window.json").write_text(json.dumps(scene))
    TruthEngine(config, tmp_path / "data", renderer=fake_render, gold_color=gold_color).run(progress=False)
    assert (tmp_path / "data" / "views" / "v00000" / frame_file(0, "gold")).exists()


def test_noisy_copies_extend_a_finished_dataset_with_new_noise_only(tmp_path):
    """Raising noisy_copies on a finished dataset renders just the copies (1-spp, fresh seeds), leaves
    every earlier file as it was, and the reader hands them out beside the frame's first render."""
    one = DatasetConfig(scenes=("cornell",), views=4, size=8, spp=(1, 4), gold=4, sequence_fraction=0.5)
    TruthEngine(one, tmp_path, renderer=fake_render).run(progress=False)
    before = {p.relative_to(tmp_path): read_exr(p)["color"] for p in tmp_path.glob("views/*/*.exr")}
    calls = []
    counting = lambda *a, **k: calls.append(k["spp"]) or fake_render(*a, **k)  # noqa: E731
    three = DatasetConfig(**{**one.__dict__, "noisy_copies": 3})
    TruthEngine(three, tmp_path, renderer=counting).run(progress=False)
    frames = sum(v.frames for v in plan_views(three))
    assert calls == [1] * 2 * frames
    for path, color in before.items():
        np.testing.assert_array_equal(read_exr(tmp_path / path)["color"], color)
    for view in load_views(tmp_path):
        for frame in view.frames:
            renders = frame.renders_at(1)
            assert len(renders) == 3 and frame.renders_at(4) == [frame.noisy[4]]
            colors = [r["color"] for r in renders]
            assert not np.array_equal(colors[0], colors[1]) and not np.array_equal(colors[1], colors[2])
    assert TruthEngine(three, tmp_path, renderer=counting).run(progress=False) == []


def test_resuming_with_other_settings_is_refused(dataset):
    other = DatasetConfig(**{**CONFIG.__dict__, "gold": 128})
    with pytest.raises(DatasetError, match=r"config\.json.*gold=64"):
        TruthEngine(other, dataset, renderer=fake_render).run(progress=False)


def test_reader_loads_splits(dataset):
    val = load_views(dataset, "val")
    assert val and all(v.split == "val" for v in val)
    assert val[0].spp == [1, 4]
    assert val[0].frames[0].gold["color"].shape == (16, 16, 3)


def _copy(dataset, tmp_path):
    import shutil

    target = tmp_path / "copy"
    shutil.copytree(dataset, target)
    return target


def test_reader_names_a_missing_file(dataset, tmp_path):
    root = _copy(dataset, tmp_path)
    victim = root / "views" / "v00000" / frame_file(0, "gold")
    victim.unlink()
    with pytest.raises(DatasetError, match=f"{victim}: no such file"):
        load_views(root)


def test_reader_names_a_corrupt_file(dataset, tmp_path):
    root = _copy(dataset, tmp_path)
    victim = root / "views" / "v00001" / frame_file(0, 1)
    victim.write_bytes(victim.read_bytes()[:100])
    with pytest.raises(DatasetError, match=f"{victim}: not a readable OpenEXR"):
        load_views(root)


def test_reader_names_a_file_of_the_wrong_size(dataset, tmp_path):
    root = _copy(dataset, tmp_path)
    victim = root / "views" / "v00002" / frame_file(0, 4)
    write_exr(victim, np.zeros((8, 16, 3)), {k: np.zeros((8, 16, c)) for k, c in
                                             (("albedo", 3), ("normal", 3), ("depth", 1), ("motion", 2))})
    with pytest.raises(DatasetError, match=f"{victim}: layer 'color' is 16×8, but this view's images are 16×16"):
        load_views(root)


def test_reader_names_a_missing_layer(dataset, tmp_path):
    root = _copy(dataset, tmp_path)
    victim = root / "views" / "v00002" / frame_file(0, 1)
    write_exr(victim, np.zeros((16, 16, 3)), {"albedo": np.zeros((16, 16, 3))})
    with pytest.raises(DatasetError, match=f"{victim}: missing layer 'normal'"):
        load_views(root)


def test_reader_without_manifest_says_how_to_make_one(tmp_path):
    with pytest.raises(DatasetError, match="no manifest"):
        load_views(tmp_path)


def test_variety_is_seeded_and_leaves_the_input_alone():
    from wgpu_rt.scene import load_scene

    base = load_scene("cornell")
    meshes, camera = len(base.meshes), base.camera.origin.copy()
    a = vary_scene(base, np.random.default_rng(5), frames=3)
    b = vary_scene(base, np.random.default_rng(5), frames=3)
    assert len(base.meshes) == meshes and np.array_equal(base.camera.origin, camera)
    assert [m.name for m in a.meshes] == [m.name for m in b.meshes]
    assert np.array_equal(a.camera_at(2).origin, b.camera_at(2).origin)
    assert a.has_motion and len(a.meshes) > meshes


def test_catmull_rom_passes_through_its_control_points():
    points = np.array([[0.0, 0.0], [1.0, 2.0], [3.0, 1.0], [4.0, 4.0]])
    path = catmull_rom(points, 7)
    np.testing.assert_allclose(path[::2], points, atol=1e-12)


def test_reproject_with_integer_motion_is_a_shift():
    rng = np.random.default_rng(0)
    previous = rng.uniform(size=(6, 7, 3)).astype(np.float32)
    motion = np.zeros((6, 7, 2), np.float32)
    motion[..., 0], motion[..., 1] = 2.0, -1.0
    warped, valid = reproject(previous, motion)
    for y in range(6):
        for x in range(7):
            sx, sy = x + 2, y - 1
            inside = 0 <= sx < 7 and 0 <= sy < 6
            assert valid[y, x] == inside
            if inside:
                np.testing.assert_allclose(warped[y, x], previous[sy, sx], rtol=1e-6)


def test_disocclusion_mask_flags_only_changed_or_offscreen_pixels():
    gold = np.ones((8, 8, 3), np.float32)
    current = gold.copy()
    current[2:4, 2:4] = 5.0
    motion = np.zeros((8, 8, 2), np.float32)
    motion[..., 0] = 1.0
    mask = disocclusion_mask(gold, current, motion)
    expected = np.zeros((8, 8), np.float32)
    expected[2:4, 2:4] = 1
    expected[:, 7] = 1
    np.testing.assert_array_equal(mask, expected)


def test_blurred_disocclusion_mask_ignores_gold_noise_but_keeps_a_real_change():
    rng = np.random.default_rng(4)
    clean = np.full((32, 32, 3), 0.5, np.float32)
    previous, current = (clean * rng.lognormal(0.0, 0.3, clean.shape).astype(np.float32) for _ in range(2))
    current[10:16, 12:18] = 5.0                       # something new in frame t+1
    changed = np.zeros((32, 32), bool)
    changed[10:16, 12:18] = True
    near_change = np.zeros((32, 32), bool)
    near_change[6:20, 8:22] = True                    # the change dilated by 4 px, where the blur spreads it
    motion = np.zeros((32, 32, 2), np.float32)
    raw = disocclusion_mask(previous, current, motion)
    blurred = disocclusion_mask(previous, current, motion, blur_sigma=1.5)
    assert raw[changed].all() and raw[~near_change].mean() > 0.1     # noise alone flags unchanged pixels
    assert blurred[changed].all() and not blurred[~near_change].any()


def test_runtime_history_zeroes_what_the_temporal_tests_reject():
    """The confidence model's history input is the temporal pass's reprojection: a shift where the
    surfaces match, zero (and not valid) off-screen and where the depth test fails."""
    rng = np.random.default_rng(1)
    colour = rng.uniform(0.1, 1.0, (6, 7, 3)).astype(np.float32)
    normal = np.zeros((6, 7, 3), np.float32)
    normal[..., 2] = 1.0
    previous = {"depth": np.full((6, 7, 1), 2.0, np.float32), "normal": normal}
    current = {"depth": np.full((6, 7, 1), 2.0, np.float32), "normal": normal}
    current["depth"][4, 1] = 3.0                       # a surface that was not there: fails the depth test
    motion = np.zeros((6, 7, 2), np.float32)
    motion[..., 0] = 1.0                               # everything came from one pixel to the right
    history, history_depth, valid = runtime_history(colour, previous, current, motion)
    expected_valid = np.ones((6, 7), bool)
    expected_valid[:, 6] = False
    expected_valid[4, 1] = False
    np.testing.assert_array_equal(valid, expected_valid)
    np.testing.assert_allclose(history[:, :6][expected_valid[:, :6]], colour[:, 1:][expected_valid[:, :6]], rtol=1e-6)
    assert not history[~valid].any() and not history_depth[~valid].any()
    np.testing.assert_allclose(history_depth[valid], 2.0)


def test_error_heatmap_is_a_normalized_rank_of_the_log_error():
    gold = np.ones((10, 10, 3), np.float32)
    noisy = gold.copy()
    noisy[0, :5] = 3.0
    noisy[1, :5] = 1.5
    heat = error_heatmap(noisy, gold)
    assert heat.min() == 0.0 and heat.max() == 1.0
    assert heat[0, 0] > heat[1, 0] > heat[5, 5]


def test_the_real_tracer_fills_a_tiny_dataset(gpu, tmp_path):
    pytest.importorskip("wgpu_rt.renderer")
    from wgpu_rt import metrics

    config = DatasetConfig(scenes=("cornell",), views=3, size=16, spp=(1, 4), gold=64,
                           sequence_length=2, sequence_fraction=1.0, max_depth=3)
    TruthEngine(config, tmp_path).run(progress=False)
    views = load_views(tmp_path)
    assert len(views) == 3 and all(len(v.frames) == 2 for v in views)
    for view in views:
        frame = view.frames[0]
        gold = frame.gold["color"]
        assert gold.max() > 0 and np.all(np.isfinite(gold))
    errors = {s: np.mean([metrics.rel_mse(v.frames[0].gold["color"], v.frames[0].noisy[s]["color"]) for v in views])
              for s in (1, 4)}
    assert errors[4] < errors[1]


def test_a_folder_of_meshes_feeds_the_views(tmp_path):
    import trimesh

    from wgpu_rt.dataset.variety import load_mesh_folder
    from wgpu_rt.scene import load_scene

    trimesh.creation.annulus(r_min=0.2, r_max=0.5, height=0.3).export(tmp_path / "ring.obj")
    (tmp_path / "notes.txt").write_text("not a mesh")
    files = load_mesh_folder(tmp_path)
    assert files == [tmp_path / "ring.obj"]
    names = set()
    for seed in range(8):
        varied = vary_scene(load_scene("cornell"), np.random.default_rng(seed), mesh_files=files)
        names |= {m.name for m in varied.meshes}
    ring = [n for n in names if n.startswith("ring_")]
    assert ring


def test_cli_rejects_a_bad_shard_and_names_a_missing_manifest(tmp_path, capsys):
    from wgpu_rt.cli import main

    with pytest.raises(SystemExit):
        main(["dataset", "--out", str(tmp_path), "--shard", "3/2"])
    assert "0 ≤ i < n" in capsys.readouterr().err
    assert main(["dataset", "--out", str(tmp_path / "d"), "--noisy-copies", "0"]) == 2
    assert "--noisy-copies must be at least 1" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()
    assert main(["train", "denoiser", "--data", str(tmp_path), "--out", str(tmp_path / "m")]) == 2
    assert f"{tmp_path / 'manifest.json'}: no manifest" in capsys.readouterr().err


@pytest.mark.parametrize("flags, message", [
    (["--size", "0"], "--size must be at least 1, got 0"),
    (["--gold", "0"], "--gold must be at least 1, got 0"),
    (["--max-depth", "0"], "--max-depth must be at least 1, got 0"),
    (["--views", "0"], "--views must be at least 1, got 0"),
    (["--sequence-length", "0"], "--sequence-length must be at least 2, got 0"),
    (["--sequence-fraction", "nan"], r"--sequence-fraction must be in \[0, 1\], got nan"),
    (["--sequence-fraction", "-3"], r"--sequence-fraction must be in \[0, 1\], got -3"),
    (["--seed", "-1"], "--seed must be at least 0, got -1"),
    (["--worlds", "-2"], "--worlds must be at least 0, got -2"),
    (["--scenes", "cornell", "no-such-scene"], "no-such-scene: neither a built-in scene"),
    (["--scenes", "{broken}.json"], "broken"),
])
def test_cli_refuses_bad_settings_before_creating_anything(tmp_path, capsys, flags, message):
    """Every setting, scene and mesh is checked before the folder or its config.json exists, so the
    corrected rerun is not refused for settings under which nothing was rendered."""
    import re

    from wgpu_rt.cli import main

    flags = [f.replace("{broken}", str(tmp_path / "broken")) for f in flags]
    (tmp_path / "broken.json").write_text('{"camera": ')
    out = tmp_path / "data"
    assert main(["dataset", "--out", str(out), "--size", "8", "--spp", "1", "--gold", "2", "--quiet", *flags]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err) and err.count("\n") == 1, err
    assert not out.exists()


def test_a_bad_mesh_in_the_folder_is_named_before_anything_is_rendered(tmp_path):
    import trimesh

    from wgpu_rt.errors import SceneError

    meshes = tmp_path / "meshes"
    meshes.mkdir()
    trimesh.creation.box().export(meshes / "good.obj")
    (meshes / "bad.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 9\n")
    config = DatasetConfig(scenes=("cornell",), views=2, size=8, spp=(1,), gold=2, mesh_dir=str(meshes))
    calls = []
    with pytest.raises(SceneError, match="bad.ply"):
        TruthEngine(config, tmp_path / "data", renderer=lambda *a, **k: calls.append(1)).run(progress=False)
    assert not calls and not (tmp_path / "data").exists()
    (meshes / "bad.ply").unlink()
    (meshes / "good.obj").rename(meshes / "notes.txt")
    with pytest.raises(DatasetError, match="--meshes holds no mesh files"):
        TruthEngine(DatasetConfig(**{**config.__dict__, "mesh_dir": str(meshes)}), tmp_path / "data")
    with pytest.raises(SceneError, match="not a folder of mesh files"):
        TruthEngine(DatasetConfig(**{**config.__dict__, "mesh_dir": str(tmp_path / "none")}), tmp_path / "data")


def test_an_out_that_cannot_be_a_dataset_folder_is_refused_before_rendering(tmp_path, monkeypatch):
    from pathlib import Path

    from wgpu_rt.errors import OutputError

    config = DatasetConfig(scenes=("cornell",), views=2, size=8, spp=(1,), gold=2)
    calls = []
    counting = lambda *a, **k: calls.append(1) or fake_render(*a, **k)  # noqa: E731
    a_file = tmp_path / "file"
    a_file.write_text("x")
    with pytest.raises(OutputError, match="is a file; name a folder"):
        TruthEngine(config, a_file, renderer=counting).run(progress=False)
    with pytest.raises(OutputError, match="cannot write the dataset there"):
        TruthEngine(config, a_file / "data", renderer=counting).run(progress=False)

    def read_only(self, *args, **kwargs):
        raise PermissionError(13, "Read-only file system", str(self))

    monkeypatch.setattr(Path, "mkdir", read_only)
    with pytest.raises(OutputError, match=r"cannot write the dataset there \(Read-only file system\)"):
        TruthEngine(config, tmp_path / "data", renderer=counting).run(progress=False)
    assert not calls


def test_a_config_under_which_nothing_was_rendered_does_not_bind_the_rerun(tmp_path):
    """A run that died before its first image (no GPU, an interrupt) left config.json: a rerun with
    other settings takes over the folder; once an image exists, other settings are refused."""
    first = DatasetConfig(scenes=("cornell",), views=2, size=8, spp=(1,), gold=2)
    second = DatasetConfig(**{**first.__dict__, "size": 16})

    def no_gpu(*args, **kwargs):
        raise DatasetError("no adapter")

    with pytest.raises(DatasetError, match="no adapter"):
        TruthEngine(first, tmp_path, renderer=no_gpu).run(progress=False)
    assert (tmp_path / "config.json").exists()
    assert len(TruthEngine(second, tmp_path, renderer=fake_render).run(progress=False)) == 2
    with pytest.raises(DatasetError, match="size=16"):
        TruthEngine(first, tmp_path, renderer=fake_render).run(progress=False)


def test_a_dataset_from_before_the_worlds_resumes(dataset):
    """config.json files written before ``worlds``/``family`` existed lack those keys."""
    path = dataset / "config.json"
    held = json.loads(path.read_text())
    for key in ("worlds", "family"):
        held.pop(key)
    path.write_text(json.dumps(held))
    assert TruthEngine(CONFIG, dataset, renderer=fake_render).run(progress=False) == []


def _resume_without(folder, config, key):
    """Resume ``folder`` after taking ``key`` out of its config.json (a dataset from before it existed)."""
    path = folder / "config.json"
    original = path.read_text()
    held = json.loads(original)
    held.pop(key)
    path.write_text(json.dumps(held))
    try:
        return TruthEngine(config, folder, renderer=fake_render).run(progress=False)
    finally:
        path.write_text(original)


def test_a_dataset_from_before_the_guide_albedo_is_not_resumed_with_it(dataset):
    """config.json records the albedo convention the renderer writes (``guide_albedo``, not a setting);
    a dataset rendered while escaping paths had albedo 0 lacks the key and reads as version 1, and adding
    views with today's albedo to it is refused by name rather than mixing the two in one folder."""
    from wgpu_rt.trace.trace_pass import GUIDE_ALBEDO

    assert json.loads((dataset / "config.json").read_text())["guide_albedo"] == GUIDE_ALBEDO
    assert TruthEngine(CONFIG, dataset, renderer=fake_render).run(progress=False) == []
    with pytest.raises(DatasetError, match=f"guide_albedo=1, not {GUIDE_ALBEDO}"):
        _resume_without(dataset, CONFIG, "guide_albedo")


def test_training_worlds_from_an_older_generator_are_not_resumed_with_new_ones(dataset, tmp_path):
    """config.json records the world generator's version (``worlds_version``): a training-worlds dataset
    from before training worlds held lamps in view reads as version 1 and is refused by name; the
    generator's change leaves built-in scenes and the held-out family as they were, so those resume."""
    from wgpu_rt.dataset.worlds import WORLDS_VERSION

    assert json.loads((dataset / "config.json").read_text())["worlds_version"] == WORLDS_VERSION
    assert _resume_without(dataset, CONFIG, "worlds_version") == []
    for family in ("training", "held_out"):
        config = DatasetConfig(scenes=(), worlds=2, family=family, size=8, spp=(1,), gold=4, sequence_fraction=0)
        folder = tmp_path / family
        TruthEngine(config, folder, renderer=fake_render).run(progress=False)
        if family == "training":
            with pytest.raises(DatasetError, match=f"worlds_version=1, not {WORLDS_VERSION}"):
                _resume_without(folder, config, "worlds_version")
        else:
            assert _resume_without(folder, config, "worlds_version") == []


@pytest.mark.parametrize("change, field", [
    ({"view_id": None}, "view_id"), ({"size": "64"}, "size"), ({"frames": 0}, "≥ 1"), ({"spp": []}, "≥ 1"),
    ({"split": "bogus"}, "split"), ({"seconds": "a while"}, "seconds"), ({"noisy_copies": -1}, "≥ 1"),
])
def test_a_malformed_manifest_record_is_named_by_the_reader(tmp_path, change, field):
    """The reader checks every record before using it: one DatasetError naming the manifest, the view
    and the field, not a KeyError or TypeError from deep inside."""
    import json

    from wgpu_rt.dataset.store import DatasetError, read_manifest

    record = {"view_id": "v00000", "scene": "cornell", "split": "train", "size": 16, "frames": 1, "spp": [1],
              "seconds": 1.0}
    (tmp_path / "manifest.json").write_text(json.dumps({"config": {}, "views": [{**record, **change}]}))
    with pytest.raises(DatasetError, match=f"manifest.json: views\\[0\\].*{field}"):
        read_manifest(tmp_path)


def test_an_interrupted_run_lists_the_views_it_finished(tmp_path):
    """Stopped between views (Ctrl-C, or SIGTERM, which wgpu_rt.cli turns into an exit with cleanup), a run
    still writes the manifest of every finished view, so a time-limited render leaves a usable dataset."""
    config = DatasetConfig(scenes=("cornell",), views=6, size=8, spp=(1,), gold=2, sequence_fraction=0.0)
    calls = []

    def render_then_stop(*args, **kwargs):
        calls.append(1)
        if len(calls) > 4:   # two renders a view (noisy, gold): stopped while rendering the third view
            raise SystemExit(143)
        return fake_render(*args, **kwargs)

    with pytest.raises(SystemExit):
        TruthEngine(config, tmp_path, renderer=render_then_stop).run(progress=False)
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert len(manifest["views"]) == 2 and len(load_views(tmp_path)) == 2


def test_a_sigterm_a_library_swallowed_still_stops_the_run_after_that_view(tmp_path):
    """trimesh catches BaseException around its vertex normals, so the exit SIGTERM raises can be swallowed
    mid-view (CI, stop 45): the run then stops once that view is written, its manifest listing it."""
    import signal

    from wgpu_rt import termination

    config = DatasetConfig(scenes=("cornell",), views=6, size=8, spp=(1,), gold=2, sequence_fraction=0.0)
    calls = []

    def render_with_a_swallowed_sigterm(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:   # the second view's first render
            try:
                termination.on_sigterm(signal.SIGTERM, None)
            except BaseException:
                pass
        return fake_render(*args, **kwargs)

    previous = termination.install()
    try:
        with pytest.raises(SystemExit) as stopped:
            TruthEngine(config, tmp_path, renderer=render_with_a_swallowed_sigterm).run(progress=False)
    finally:
        termination.uninstall(previous)
    assert stopped.value.code == 143 and len(calls) == 4
    assert len(json.loads((tmp_path / "manifest.json").read_text())["views"]) == 2


@pytest.mark.gpu
def test_sigterm_stops_the_command_and_its_shards_with_the_manifest_written(tmp_path, gpu):
    """`wgpu-rt dataset` under SIGTERM exits 143 after writing the manifest, and scripts/render_sharded.sh
    (gpu_session.sh's renders, stopped at a part's time limit) passes the signal on to its shards instead
    of leaving them rendering."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "scripts" / "render_sharded.sh"
    args = ["--scenes", "cornell", "--views", "200", "--size", "8", "--spp", "1", "--gold", "2",
            "--sequence-fraction", "0", "--quiet"]
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    for command, out in (([sys.executable, "-m", "wgpu_rt", "dataset", *args, "-o", str(tmp_path / "one")],
                          tmp_path / "one"),
                         (["bash", str(script), "2", *args, "-o", str(tmp_path / "two")], tmp_path / "two")):
        process = subprocess.Popen(command, env=env, start_new_session=True, stdout=subprocess.DEVNULL,
                                   stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 120
        while not list(out.glob("views/*/view.json")) and time.monotonic() < deadline and process.poll() is None:
            time.sleep(0.2)
        process.send_signal(signal.SIGTERM)
        try:
            assert process.wait(timeout=60) == 143, process.stderr.read()
        finally:
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGKILL)
        time.sleep(0.5)
        with pytest.raises(ProcessLookupError):   # no shard left running in the session
            os.killpg(process.pid, 0)
        views = json.loads((out / "manifest.json").read_text())["views"]
        assert 1 <= len(views) < 200 and len(load_views(out)) == len(views)


def test_randomized_materials_keep_a_glasss_tint_and_absorption_and_a_thin_pane_smooth():
    """The dataset's material jitter changes reflectance, roughness and a glass's ior, and keeps the rest: a glass's
    transmittance and absorption (dropped before), a thin pane's zero roughness."""
    from wgpu_rt.dataset.variety import randomize_materials
    from wgpu_rt.scene.model import Camera, Material, Scene

    materials = {"amber": Material("dielectric", transmittance=(0.9, 0.6, 0.3), absorption=(0.5, 1.0, 3.0)),
                 "pane": Material("thin_dielectric", ior=1.5, transmittance=(0.8, 0.9, 1.0))}
    scene = Scene(Camera([0, 0, 3], [0, 0, 0]), [], materials)
    randomize_materials(scene, np.random.default_rng(3))
    amber, pane = scene.materials["amber"], scene.materials["pane"]
    np.testing.assert_allclose(amber.transmittance, [0.9, 0.6, 0.3])
    np.testing.assert_allclose(amber.absorption, [0.5, 1.0, 3.0])
    assert amber.roughness > 0 and pane.kind == "thin_dielectric" and pane.roughness == 0
    assert 1.3 <= pane.ior <= 1.8 and pane.ior != 1.5   # jittered (left alone it would stay 1.5)
    np.testing.assert_allclose(pane.transmittance, [0.8, 0.9, 1.0])
