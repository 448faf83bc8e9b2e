"""The BVH layout chosen per adapter by measurement (wgpu_rt.trace.bvh_choice, WGPU_RT_BVH=auto): the
faster layout wins and is remembered per scene size, small scenes are not measured (the adapter's kind
picks), the renderer follows the cache, and the real timer measures real traces."""

import json
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

from wgpu_rt.accel import geometry as geometry_module
from wgpu_rt.accel.bvh import wide_nodes as bvh_wide_nodes
from wgpu_rt.accel.geometry import (LANES_TRAVERSAL, SUBGROUP_TRAVERSAL, GeometryBuffers, bvh_variants,
                                    traversal_module)
from wgpu_rt.measured_choices import CACHE_DIR_ENV, MeasuredChoices
from wgpu_rt.scene import load_scene
from wgpu_rt.trace.bvh_choice import AUTO_MIN_TRIANGLES, choose_layout, layout_key, unmeasured_layout

pytestmark = pytest.mark.gpu


@pytest.fixture(scope="module")
def sphere_room(tmp_path_factory):
    """The mesh scene with an icosphere of 5120 triangles: big enough to be measured."""
    path = tmp_path_factory.mktemp("mesh") / "sphere.obj"
    trimesh.creation.icosphere(subdivisions=4).export(path)
    scene = load_scene("mesh", mesh=path)
    assert sum(len(mesh.faces) for mesh in scene.meshes) >= AUTO_MIN_TRIANGLES
    return scene


def fake_timer(seconds: dict, traced: list):
    """Runs each candidate's probe once (it must really trace) and reports ``seconds`` of its variant
    (10 s for a variant not named: the row loads beside a per-invocation traversal)."""
    def timer(candidate):
        variant, run = candidate
        assert run() > 0
        traced.append(variant)
        return seconds.get(variant, 10.0)
    return timer


def test_the_faster_layout_is_chosen_and_remembered(gpu, sphere_room, tmp_path):
    cache = tmp_path / "autotune.json"
    traced = []
    choices = MeasuredChoices(gpu, cache, timer=fake_timer({"threaded": 2.0, "wide": 1.0}, traced))
    built = GeometryBuffers.build(sphere_room)
    assert choose_layout(gpu, sphere_room, built, max_depth=3, choices=choices).layout == "wide"
    assert sorted(traced) == sorted(bvh_variants(traversal_module(gpu)))
    key = layout_key(choices, traversal_module(gpu), built.triangle_count)
    entry = json.loads(cache.read_text())["entries"][key]
    assert entry["variant"] == "wide" and entry["seconds"]["threaded"] == 2.0 and entry["seconds"]["wide"] == 1.0

    def must_not_measure(candidate):
        raise AssertionError("a remembered choice was measured again")
    again = MeasuredChoices(gpu, cache, timer=must_not_measure)
    assert choose_layout(gpu, sphere_room, built, max_depth=3, choices=again).layout == "wide"

    other = MeasuredChoices(gpu, tmp_path / "other.json", timer=fake_timer({"threaded": 1.0, "wide": 3.0}, []))
    assert choose_layout(gpu, sphere_room, built, max_depth=3, choices=other).layout == "threaded"


def test_small_scenes_take_the_adapters_layout_unmeasured(gpu, tmp_path):
    scene = load_scene("cornell")
    choices = MeasuredChoices(gpu, tmp_path / "autotune.json", timer=fake_timer({"threaded": 2.0, "wide": 1.0}, []))
    chosen = choose_layout(gpu, scene, GeometryBuffers.build(scene), choices=choices)
    assert chosen.variant == unmeasured_layout(gpu, traversal_module(gpu))
    assert choices.measured == 0 and not (tmp_path / "autotune.json").exists()


@pytest.mark.parametrize("adapter_type, traversal, layout", [
    ("CPU", SUBGROUP_TRAVERSAL, "threaded"), ("CPU", LANES_TRAVERSAL, "threaded"),
    ("DiscreteGPU", LANES_TRAVERSAL, "wide+rows"), ("IntegratedGPU", LANES_TRAVERSAL, "wide+rows"),
    ("DiscreteGPU", SUBGROUP_TRAVERSAL, "wide")])
def test_small_scenes_walk_the_wide_tree_on_gpus(adapter_type, traversal, layout):
    """Lavapipe keeps the stackless threaded walk; a GPU takes the 4-wide tree (1.6× on an H200), fetched
    as rows where its traversal takes them."""
    ctx = SimpleNamespace(adapter=SimpleNamespace(info={"adapter_type": adapter_type}))
    assert unmeasured_layout(ctx, traversal) == layout


def test_the_wall_timer_measures_both_walks(gpu, sphere_room, tmp_path):
    choices = MeasuredChoices(gpu, tmp_path / "autotune.json", timer=None)
    from wgpu_rt.trace.bvh_choice import wall_timer

    choices.timer = lambda candidate: wall_timer(candidate[1])
    chosen = choose_layout(gpu, sphere_room, GeometryBuffers.build(sphere_room), max_depth=3, choices=choices)
    (entry,) = json.loads((tmp_path / "autotune.json").read_text())["entries"].values()
    assert all(seconds > 0 for seconds in entry["seconds"].values())
    assert sorted(entry["seconds"]) == sorted(bvh_variants(traversal_module(gpu)))
    assert chosen.variant == entry["variant"] == min(entry["seconds"], key=entry["seconds"].get)


def test_the_renderer_follows_the_remembered_choice(gpu, sphere_room, tmp_path, monkeypatch):
    """With WGPU_RT_BVH unset (auto) the renderer traces the layout the cache names: the wide walk here,
    whatever this adapter would measure, and the same image as the threaded walk."""
    from wgpu_rt.renderer import render

    monkeypatch.setenv(CACHE_DIR_ENV, str(tmp_path))
    choices = MeasuredChoices(gpu, timer=fake_timer({"threaded": 2.0, "wide": 1.0}, []))
    choose_layout(gpu, sphere_room, GeometryBuffers.build(sphere_room), choices=choices)
    laid_out = []
    monkeypatch.setattr(geometry_module, "wide_nodes", lambda bvh: laid_out.append(bvh) or bvh_wide_nodes(bvh))
    options = dict(size=(16, 16), spp=2, max_depth=4, aovs=(), ctx=gpu)
    monkeypatch.delenv(geometry_module.BVH_LAYOUT_ENV, raising=False)
    auto = render(sphere_room, **options).color
    assert laid_out
    monkeypatch.setenv(geometry_module.BVH_LAYOUT_ENV, "threaded")
    np.testing.assert_array_equal(auto, render(sphere_room, **options).color)


def test_a_remembered_small_leaf_choice_costs_one_bvh_build(gpu, sphere_room, tmp_path, monkeypatch):
    """Where the cache names a variant built with small leaves, the renderer builds that tree alone (not
    the default one first and then the other); before any measurement, or for a scene too small to be
    measured, it builds the default tree."""
    from wgpu_rt.accel.bvh import SMALL_LEAF_TRAVERSAL_COST, build_bvh
    from wgpu_rt.renderer import render
    from wgpu_rt.trace.bvh_choice import remembers_small_leaves

    monkeypatch.setenv(CACHE_DIR_ENV, str(tmp_path))
    assert not remembers_small_leaves(gpu, sphere_room)
    small = "wide+small-leaves"
    choices = MeasuredChoices(gpu, timer=fake_timer({"threaded": 2.0, "wide": 1.5, small: 1.0}, []))
    assert choose_layout(gpu, sphere_room, GeometryBuffers.build(sphere_room), choices=choices).variant == small
    assert remembers_small_leaves(gpu, sphere_room) and not remembers_small_leaves(gpu, load_scene("cornell"))
    costs = []
    monkeypatch.setattr(geometry_module, "build_bvh",
                        lambda triangles, *cost: costs.append(cost) or build_bvh(triangles, *cost))
    monkeypatch.delenv(geometry_module.BVH_LAYOUT_ENV, raising=False)
    render(sphere_room, size=(16, 16), spp=1, max_depth=2, aovs=(), ctx=gpu)
    assert costs == [(SMALL_LEAF_TRAVERSAL_COST,)]
