"""Next-event estimation picks an emitter group by the irradiance it is estimated to give at the shading
point (wgpu_rt/trace/scene_data.py, wgsl/trace/emitters.wgsl): the groups a scene gets, the numpy
reference of the probabilities, and on the device the same image with less noise than picks by power."""

from pathlib import Path

import numpy as np
import pytest

from wgpu_rt.accel.geometry import GeometryBuffers, scene_material_names
from wgpu_rt.renderer import render
from wgpu_rt.scene.loader import parse_scene
from wgpu_rt.trace import scene_data
from wgpu_rt.trace.scene_data import (
    DEFENSIVE_SHARE, GROUP_CONSTANT, GROUP_FLAT, GROUP_POINT, GROUP_SOLID, build_emitter_table, emissive_triangles,
    emitter_group_count, group_probabilities,
)
from wgpu_rt.trace.features import SceneFeatures

# A floor lit from its two ends: a panel facing down at x = -1.5, a glowing ball at x = +1.5, a point
# light, a sun and a sky.
_FIVE_LIGHTS = {
    "camera": {"origin": [0, 2.5, 4], "target": [0, 0, 0], "fov": 50},
    "materials": {"floor": {"reflectance": 0.6},
                  "panel": {"reflectance": 0.8, "emission": [30, 28, 25]},
                  "glow": {"reflectance": 0.8, "emission": [2, 6, 3]}},
    "meshes": [{"shape": "rectangle", "material": "floor",
                "transform": {"rotate": {"axis": [1, 0, 0], "angle": -90}, "scale": 3}},
               {"shape": "rectangle", "material": "panel",
                "transform": {"rotate": {"axis": [1, 0, 0], "angle": 90}, "scale": 0.15,
                              "translate": [-1.5, 1.0, 0]}},
               {"shape": "sphere", "material": "glow", "transform": {"scale": 0.2, "translate": [1.5, 0.3, 0]}}],
    "lights": [{"type": "point", "position": [0, 1.2, -1.5], "intensity": [1, 1, 1]},
               {"type": "directional", "direction": [-0.3, -1, -0.2], "irradiance": [0.3, 0.3, 0.3]}],
    "background": [0.02, 0.03, 0.05],
}


def _table(description, max_groups=None, monkeypatch=None):
    scene = parse_scene(description, "five lights", Path.cwd())
    if max_groups is not None:
        monkeypatch.setattr(scene_data, "MAX_EMITTER_GROUPS", max_groups)
    geometry = GeometryBuffers.build(scene)
    materials = [scene.materials[n] for n in scene_material_names(scene)]
    emissive = emissive_triangles(geometry.material_ids, materials)
    radius = 0.5 * float(np.ptp(geometry.triangles.reshape(-1, 3), axis=0).max())
    table = build_emitter_table(scene, emissive, geometry.triangles[emissive], geometry.material_ids, materials,
                                radius, geometry.object_ids)
    return scene, geometry, table


def test_each_light_and_each_emitting_mesh_is_a_group():
    scene, geometry, table = _table(_FIVE_LIGHTS)
    kinds = sorted(int(k) for k in table.groups["kind"])
    assert kinds == sorted([GROUP_FLAT, GROUP_SOLID, GROUP_POINT, GROUP_CONSTANT, GROUP_CONSTANT])
    flat = table.groups[table.groups["kind"] == GROUP_FLAT][0]
    np.testing.assert_allclose(flat["normal"], [0, -1, 0], atol=1e-6)     # the panel faces the floor
    np.testing.assert_allclose(flat["center"], [-1.5, 1.0, 0], atol=1e-6)
    solid = table.groups[table.groups["kind"] == GROUP_SOLID][0]
    np.testing.assert_allclose(solid["center"], [1.5, 0.3, 0], atol=1e-2)
    assert solid["radius"] == pytest.approx(0.2, rel=1e-3)
    _check_layout(table)
    assert table.background_share == 1.0 and table.groups[table.background_group]["kind"] == GROUP_CONSTANT
    # each triangle points at its record (the floor's at none), each record at its group
    _check_entries(table, geometry)
    groups = _group_of(table)
    for mesh, kind in ((0, -1), (1, GROUP_FLAT), (2, GROUP_SOLID)):
        of_mesh = groups[geometry.object_ids == mesh]
        assert len(set(of_mesh)) == 1 and (of_mesh[0] == -1 if kind == -1 else table.groups[of_mesh[0]]["kind"] == kind)


def test_two_lamps_of_one_material_are_two_groups():
    """Groups follow meshes, not materials: a second panel of the panel's material far away is its own group."""
    scene = {**_FIVE_LIGHTS, "meshes": _FIVE_LIGHTS["meshes"] + [
        {"shape": "rectangle", "material": "panel",
         "transform": {"rotate": {"axis": [1, 0, 0], "angle": 90}, "scale": 0.15, "translate": [0, 1.0, -2]}}]}
    _, geometry, table = _table(scene)
    assert sorted(int(k) for k in table.groups["kind"]).count(GROUP_FLAT) == 2
    groups = _group_of(table)
    assert groups[geometry.object_ids == 1][0] != groups[geometry.object_ids == 3][0]
    _check_entries(table, geometry)


def test_probabilities_follow_the_irradiance_and_never_starve_a_light():
    _, _, table = _table(_FIVE_LIGHTS)
    groups = table.groups
    kind = groups["kind"]
    near_panel, near_ball = group_probabilities(groups, [-1.5, 0, 0]), group_probabilities(groups, [1.5, 0, 0.3])
    for p in (near_panel, near_ball):
        assert p.sum() == pytest.approx(1.0, abs=1e-9)
        assert np.all(p >= DEFENSIVE_SHARE * groups["pmf"] - 1e-12)
    assert near_panel[kind == GROUP_FLAT][0] > 0.5 > near_ball[kind == GROUP_FLAT][0]
    assert near_ball[kind == GROUP_SOLID][0] > near_panel[kind == GROUP_SOLID][0]
    # above the panel's plane (behind it) the panel gets only its defensive share
    behind = group_probabilities(groups, [-1.5, 1.5, 0])
    assert behind[kind == GROUP_FLAT][0] == pytest.approx(DEFENSIVE_SHARE * groups["pmf"][kind == GROUP_FLAT][0])


def test_more_groups_than_the_kernel_holds_are_clustered_in_space(monkeypatch):
    """With room for 4 groups, the sun and the sky keep theirs and the panel (x = -1.5), the point light
    (x = 0) and the ball (x = 1.5) are cut at the median along x; with room for 2, the sun and the sky
    leave none, and one group of everything is picked by power."""
    scene, geometry, grouped = _table(_FIVE_LIGHTS)
    assert emitter_group_count(scene) == len(grouped.groups) == 5 and SceneFeatures.of(scene).has_emitter_groups
    _, _, clustered = _table(_FIVE_LIGHTS, max_groups=4, monkeypatch=monkeypatch)
    assert emitter_group_count(scene) == len(clustered.groups) == 4
    kinds = sorted(int(k) for k in clustered.groups["kind"])
    assert kinds == sorted([GROUP_FLAT, GROUP_SOLID, GROUP_CONSTANT, GROUP_CONSTANT])
    pair = clustered.groups[clustered.groups["kind"] == GROUP_SOLID][0]
    assert pair["count"] == grouped.groups[grouped.groups["kind"] == GROUP_SOLID][0]["count"] + 1
    assert -0.1 < pair["center"][0] < 1.5 and pair["radius"] >= 1.5
    solid = int(np.flatnonzero(clustered.groups["kind"] == GROUP_SOLID)[0])
    assert set(_group_of(clustered)[geometry.object_ids == 2]) == {solid}      # the ball's triangles
    _check_layout(clustered)
    _check_entries(clustered, geometry)      # the records were reordered: the entries follow them
    np.testing.assert_allclose(np.sort(clustered.power_pmf()), np.sort(grouped.power_pmf()), rtol=1e-5)

    _, _, merged = _table(_FIVE_LIGHTS, max_groups=2, monkeypatch=monkeypatch)
    assert emitter_group_count(scene) == 1 and not SceneFeatures.of(scene).has_emitter_groups
    assert len(merged.groups) == 1 and merged.groups[0]["count"] == merged.count
    assert set(_group_of(merged)[merged.triangle_entry > 0]) == {0}
    np.testing.assert_allclose(merged.power_pmf(), grouped.power_pmf(), rtol=1e-5)
    assert group_probabilities(merged.groups, [0, 0, 0]) == pytest.approx([1.0])


def _group_of(table) -> np.ndarray:
    """(T,) per scene triangle, the index of its record's group, -1 if it does not emit."""
    entry = table.triangle_entry.astype(np.int64) - 1
    return np.where(entry >= 0, table.records["group"][np.maximum(entry, 0)].astype(np.int64), -1)


def _check_entries(table, geometry):
    """Each emissive triangle's entry is the record of that triangle, every triangle record has one."""
    entries = table.triangle_entry
    emitting = np.flatnonzero(entries)
    assert len(emitting) == np.count_nonzero(table.records["kind"][:table.count] == 0)
    records = table.records[entries[emitting] - 1]
    assert np.all(records["kind"] == 0)
    np.testing.assert_allclose(records["position"], geometry.triangles[emitting, 0], atol=1e-6)


def _check_layout(table):
    """Every group's records contiguous and covering the table once, shares summing to 1, aliases inside."""
    covered = []
    for group in table.groups:
        span = np.arange(group["first"], group["first"] + group["count"])
        covered.extend(span)
        assert table.records["share"][span].sum() == pytest.approx(1.0, abs=1e-5)
        assert np.all(np.isin(table.records["alias_index"][span], span))
    assert sorted(covered) == list(range(table.count))
    assert table.groups["pmf"].sum() == pytest.approx(1.0, abs=1e-6)


def test_local_picks_render_the_same_image_with_less_noise(gpu, monkeypatch):
    """Unbiased (the same mean as picks by power, within noise) and less noisy: against a 1024-spp render,
    the 16-spp image's error falls by at least a quarter."""
    grouped, by_power = _error_against_picks_by_power(parse_scene(_FIVE_LIGHTS, "five lights", Path.cwd()),
                                                      monkeypatch)
    assert grouped < 0.75 * by_power, (grouped, by_power)


def _error_against_picks_by_power(scene, monkeypatch) -> tuple[float, float]:
    """The relative squared error of a 16-spp render against a 1024-spp one, with the emitter groups and
    with picks by power alone (one group), after checking that the two 1024-spp means agree within 1%."""
    size = (32, 32)
    reference = render(scene, spp=1024, size=size, aovs=(), seed=5).color
    grouped = render(scene, spp=16, size=size, aovs=(), seed=1).color
    monkeypatch.setattr(scene_data, "MAX_EMITTER_GROUPS", 1)
    by_power = render(scene, spp=16, size=size, aovs=(), seed=1).color
    by_power_reference = render(scene, spp=1024, size=size, aovs=(), seed=5).color
    monkeypatch.undo()
    ratio = reference.reshape(-1, 3).mean(0) / by_power_reference.reshape(-1, 3).mean(0)
    assert np.all(np.abs(ratio - 1) < 0.01), ratio
    return tuple(float(np.mean((image - reference) ** 2) / np.mean(reference ** 2)) for image in (grouped, by_power))


def test_a_kernel_without_emitter_groups_refuses_a_scene_with_several(gpu):
    """A kernel specialized without the group picks would draw every light from the first group alone."""
    from dataclasses import replace

    from wgpu_rt.trace import TracePass

    scene = parse_scene(_FIVE_LIGHTS, "five lights", Path.cwd())
    features = replace(SceneFeatures.of(scene), has_emitter_groups=False)
    with pytest.raises(ValueError, match="5 emitter groups"):
        TracePass(gpu, scene, GeometryBuffers.build(scene), 8, 8, features=features)


def test_many_lights_clustered_render_the_same_image_with_less_noise(gpu, monkeypatch):
    """Twenty point lights along a corridor, more than the kernel's 16 groups: clustered in space, the
    16-spp image's error against a 1024-spp render falls five times and more against picks by power
    alone, and the mean stays."""
    corridor = {
        "camera": {"origin": [0, 1.5, 3], "target": [0, 0, -4], "fov": 60},
        "materials": {"floor": {"reflectance": 0.6}},
        "meshes": [{"shape": "rectangle", "material": "floor",
                    "transform": {"rotate": {"axis": [1, 0, 0], "angle": -90}, "scale": [2, 12, 1],
                                  "translate": [0, 0, -6]}}],
        "lights": [{"type": "point", "position": [0.8 * (-1) ** i, 0.4, 2 - 0.8 * i], "intensity": [0.3, 0.3, 0.3]}
                   for i in range(20)],
    }
    scene = parse_scene(corridor, "corridor", Path.cwd())
    assert emitter_group_count(scene) == 16 and SceneFeatures.of(scene).has_emitter_groups
    clustered, by_power = _error_against_picks_by_power(scene, monkeypatch)
    assert clustered < 0.2 * by_power, (clustered, by_power)


def test_the_kernel_and_the_packing_agree_on_their_constants():
    """The defensive share and the group capacity are written in the WGSL as well as in scene_data."""
    import re

    from wgpu_rt.shaders import read_wgsl

    emitters, bindings = read_wgsl("trace/emitters.wgsl"), read_wgsl("trace/trace_bindings.wgsl")
    assert float(re.search(r"const DEFENSIVE_SHARE: f32 = ([0-9.]+);", emitters).group(1)) == DEFENSIVE_SHARE
    assert f"array<f32, {scene_data.MAX_EMITTER_GROUPS}>" in emitters
    assert f"emitter_groups: array<EmitterGroup, {scene_data.MAX_EMITTER_GROUPS}>" in bindings
