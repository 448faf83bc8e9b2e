"""Generated training worlds: deterministic per seed, varied across seeds, two families that never meet,
and wired into the truth engine (fake renderer) and the real tracer (GPU test)."""

import json

import numpy as np
import pytest
from dataset_fakes import fake_render

from wgpu_rt.dataset import DatasetConfig, TruthEngine, plan_views
from wgpu_rt.dataset.worlds import (FAMILY_SHAPES, FAMILY_SIZE, LIGHTINGS, METALS, SETUPS, family_of,
                                    generate_world, mesh_family, world_seed)
from wgpu_rt.scene.model import DirectionalLight, PointLight
from wgpu_rt.scene.transforms import transform_points

SEEDS = range(200)


@pytest.fixture(scope="module")
def worlds():
    return [generate_world(world_seed("training", n)) for n in SEEDS]


def _arrays(scene):
    """Every number in a scene, by where it sits, for exact comparison."""
    out = {"camera": np.concatenate([scene.camera.origin, scene.camera.target, [scene.camera.fov]]),
           "lens": np.array([scene.camera.aperture_radius, scene.camera.focus_distance]),
           "background": scene.background}
    for f, camera in scene.camera_keyframes.items():
        out[f"camera@{f}"] = np.concatenate([camera.origin, camera.target])
        out[f"lens@{f}"] = np.array([camera.aperture_radius, camera.focus_distance])
    for mesh in scene.meshes:
        out[f"{mesh.name}.vertices"], out[f"{mesh.name}.faces"] = mesh.vertices, mesh.faces
        out[f"{mesh.name}.transform"] = mesh.transform
        if mesh.normals is not None:
            out[f"{mesh.name}.normals"] = mesh.normals
        if mesh.colors is not None:
            out[f"{mesh.name}.colors"] = mesh.colors
        for f, matrix in mesh.keyframes.items():
            out[f"{mesh.name}@{f}"] = matrix
    for name, m in scene.materials.items():
        out[f"material {name}"] = np.concatenate([m.reflectance, m.eta, m.k, m.emission, m.transmittance,
                                                  m.absorption, [m.roughness, m.ior]])
    for i, light in enumerate(scene.lights):
        out[f"light {i}"] = np.concatenate([np.ravel(v) for v in vars(light).values()])
    return out


def test_a_seed_fixes_its_world_exactly():
    for seed in (3, world_seed("held_out", 3)):
        a, b = generate_world(seed, frames=3), generate_world(seed, frames=3)
        arrays_a, arrays_b = _arrays(a), _arrays(b)
        assert a.name == b.name and arrays_a.keys() == arrays_b.keys()
        for key in arrays_a:
            np.testing.assert_array_equal(arrays_a[key], arrays_b[key], err_msg=key)
        assert a.frame_count == 3 and a.has_motion


def test_different_seeds_give_different_worlds(worlds):
    fingerprints = {tuple(np.round(w.camera.origin, 5)) + (len(w.meshes),) for w in worlds}
    assert len(fingerprints) == len(worlds)


def _material_classes(scene):
    classes = set()
    metals = {tuple(np.float32(eta)) + tuple(np.float32(k)) for eta, k in METALS.values()}
    for mesh in scene.meshes:
        m = scene.materials[mesh.material]
        if m.is_emissive:
            classes.add("emissive")
        elif m.kind == "diffuse":
            top = float(m.reflectance.max())
            if top < 0.1:
                classes.add("dark diffuse")
            if float(m.reflectance.min()) > 0.6:
                classes.add("bright diffuse")
            if top > 0 and (top - float(m.reflectance.min())) / top > 0.8:
                classes.add("saturated diffuse")
        elif m.kind == "conductor":
            assert tuple(m.eta) + tuple(m.k) in metals, f"{scene.name}: {mesh.name} is no measured metal"
            classes.add("rough conductor" if m.roughness > 0 else "smooth conductor")
        else:
            world = transform_points(mesh.transform, mesh.vertices).astype(np.float64)
            axes = np.linalg.svd(world - world.mean(0), full_matrices=False)[2]
            extent = np.ptp(world @ axes.T, axis=0)          # along the mesh's own principal axes
            if extent.min() < 0.05 * extent.max():
                classes.add("thin glass")
            classes.add("rough glass" if m.roughness > 0 else "smooth glass")
    return classes


def _emitter_areas(scene):
    """World-space area of each emissive mesh."""
    areas = []
    for mesh in scene.meshes:
        if scene.materials[mesh.material].is_emissive:
            t = transform_points(mesh.transform, mesh.vertices)[mesh.faces].astype(np.float64)
            areas.append(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum())
    return areas


def test_two_hundred_worlds_cover_every_material_light_and_setup(worlds):
    materials, lights = set(), set()
    for w in worlds:
        assert 20 <= w.camera.fov <= 90, w.name
        materials |= _material_classes(w)
        lights |= {"point" for light in w.lights if isinstance(light, PointLight)}
        lights |= {"sun" for light in w.lights if isinstance(light, DirectionalLight)}
        if w.background.max() > 0 and np.ptp(w.background) > 0:
            lights.add("coloured sky")
        areas = _emitter_areas(w)
        lights |= {"tiny area" for a in areas if a < 0.005} | {"large area" for a in areas if a > 0.5}
        names = {m.name.rsplit("_", 1)[0] for m in w.meshes}
        lights |= {"looks through glass" for _ in ["pane"] if "pane" in names}
        lights |= {"looks at a mirror" for _ in ["mirror"] if "mirror" in names}
    assert materials == {"dark diffuse", "bright diffuse", "saturated diffuse", "smooth conductor",
                         "rough conductor", "smooth glass", "rough glass", "thin glass", "emissive"}
    assert lights == {"point", "sun", "coloured sky", "tiny area", "large area", "looks through glass",
                      "looks at a mirror"}
    seen = {tuple(w.name.split("/")[1:]) for w in worlds}
    assert seen == {(setup, lighting) for setup in SETUPS for lighting in LIGHTINGS[setup]}


def test_indirect_worlds_show_no_emitting_side_to_the_camera(worlds):
    indirect = [w for w in worlds if w.name.endswith("/indirect")]
    assert indirect
    for w in indirect:
        for mesh in w.meshes:
            if not w.materials[mesh.material].is_emissive:
                continue
            t = transform_points(mesh.transform, mesh.vertices)[mesh.faces].astype(np.float64)
            front = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
            toward_camera = w.camera.origin - t.mean(1)
            assert np.all(np.sum(front * toward_camera, axis=1) < 0), f"{w.name}: {mesh.name} faces the camera"


def _lamps_in_view(scene):
    return [mesh for mesh in scene.meshes if mesh.name.startswith("lamp_in_view_")]


def test_some_training_worlds_hold_small_lamps_the_camera_sees(worlds):
    """Lamps seen directly (BENCHMARKS.md §30's corridor): in about LAMPS_IN_VIEW_SHARE of the training
    worlds, never where all light must arrive indirectly; each emits, lies inside the set and projects
    into the frame, a small part of it."""
    from wgpu_rt.dataset.worlds import LAMPS_IN_VIEW_SHARE

    with_lamps = [w for w in worlds if _lamps_in_view(w)]
    assert abs(len(with_lamps) / len(worlds) - LAMPS_IN_VIEW_SHARE) < 0.1
    assert not any(_lamps_in_view(w) for w in worlds if w.name.endswith("/indirect"))
    black = 0
    for w in with_lamps:
        cam = w.camera
        right, up, forward = cam.basis()
        tan_half = np.tan(np.radians(cam.fov) / 2)
        for lamp in _lamps_in_view(w):
            material = w.materials[lamp.material]
            assert material.is_emissive, (w.name, lamp.name)
            black += float(np.max(material.reflectance)) == 0
            corners = transform_points(lamp.transform, lamp.vertices).astype(np.float64)
            centre, extent = corners.mean(0), np.ptp(corners, axis=0).max()
            assert centre[1] > 0, (w.name, lamp.name)
            depth = (centre - cam.origin) @ forward
            x, y = ((centre - cam.origin) @ right, (centre - cam.origin) @ up)
            assert depth > 0 and abs(x) <= depth * tan_half * 1.01 and abs(y) <= depth * tan_half * 1.01
            assert extent <= 0.1 * 2 * depth * tan_half, (w.name, lamp.name)   # a small part of the frame
    assert black > 0


def _with_and_without(monkeypatch, share: str, seed: int, frames: int = 1):
    """The world of ``seed`` generated with the module's ``share`` set to 1 and to 0 (a choice drawn from a
    random stream of its own, always and never taken)."""
    from wgpu_rt.dataset import worlds as worlds_module

    monkeypatch.setattr(worlds_module, share, 1.0)
    taken = generate_world(seed, frames=frames)
    monkeypatch.setattr(worlds_module, share, 0.0)
    return taken, generate_world(seed, frames=frames)


def _without_worn_metal(monkeypatch) -> None:
    """Worn metal off: it makes plastics of the matte and coated surfaces that the other streams leave (taking a
    coat's ior, a normal map's or a screen's coordinates), so those streams' tests compare worlds without it."""
    from wgpu_rt.dataset import worlds as worlds_module

    monkeypatch.setattr(worlds_module, "METAL_ROUGH_SHARE", 0.0)


def _assert_alike_but(changed, plain, seed: int, allowed=lambda key: False) -> None:
    """``changed`` holds every number of ``plain`` where it sits, equal, but at the keys ``allowed`` says may
    differ (see ``_arrays``)."""
    ours, theirs = _arrays(changed), _arrays(plain)
    assert ours.keys() == theirs.keys()
    for key in theirs:
        if not allowed(key):
            np.testing.assert_array_equal(ours[key], theirs[key], err_msg=f"{seed}: {key}")


def test_lamps_in_view_leave_every_other_choice_and_the_held_out_family_alone(monkeypatch):
    """The lamps draw from a random stream of their own: a training world with them is the world without
    them plus the lamps, and a held-out world never gets any (its gold images stay valid)."""
    for seed in [world_seed("training", n) for n in range(12)] + [world_seed("held_out", n) for n in range(6)]:
        lit, plain = _with_and_without(monkeypatch, "LAMPS_IN_VIEW_SHARE", seed)
        assert bool(_lamps_in_view(lit)) == (family_of(seed) == "training" and not lit.name.endswith("/indirect"))
        lamps = {m.name for m in _lamps_in_view(lit)} | {m.material for m in _lamps_in_view(lit)}
        without = {key: value for key, value in _arrays(lit).items()
                   if not any(key.startswith(f"{name}.") or key == f"material {name}" for name in lamps)}
        expected = _arrays(plain)
        assert lit.name == plain.name and without.keys() == expected.keys()
        for key in expected:
            np.testing.assert_array_equal(without[key], expected[key], err_msg=f"{seed}: {key}")


def test_painting_leaves_every_other_choice_and_the_held_out_family_alone(monkeypatch):
    """Painted surfaces draw from a random stream of their own: a painted training world is the world without
    paint, its painted meshes subdivided (the same bounds) and given vertex colours in [0, 1] (never glass or
    an emitter); a held-out world is never painted (its gold images stay valid). (Coats and worn metal are left
    out: a painted mesh's material is never coated or worn.)"""
    from wgpu_rt.dataset import worlds as worlds_module

    monkeypatch.setattr(worlds_module, "PLASTIC_SHARE", 0.0)
    _without_worn_metal(monkeypatch)
    painted_meshes = 0
    for seed in [world_seed("training", n) for n in range(12)] + [world_seed("held_out", n) for n in range(6)]:
        painted, plain = _with_and_without(monkeypatch, "PAINTED_SHARE", seed)
        colored = [mesh for mesh in painted.meshes if mesh.colors is not None]
        assert not colored or family_of(seed) == "training"
        painted_meshes += len(colored)
        for mesh in colored:
            material = painted.materials[mesh.material]
            assert material.kind != "dielectric" and not material.is_emissive, (seed, mesh.name)
            assert mesh.colors.shape == mesh.vertices.shape and 0 <= mesh.colors.min() and mesh.colors.max() <= 1
            before = next(m for m in plain.meshes if m.name == mesh.name)
            np.testing.assert_allclose([mesh.vertices.min(0), mesh.vertices.max(0)],
                                       [before.vertices.min(0), before.vertices.max(0)], atol=1e-6)
            assert len(mesh.faces) >= len(before.faces)
        names = {mesh.name for mesh in colored}
        kept = {key: value for key, value in _arrays(painted).items()
                if not any(key in (f"{name}.vertices", f"{name}.faces", f"{name}.normals", f"{name}.colors")
                           for name in names)}
        expected = {key: value for key, value in _arrays(plain).items()
                    if not any(key in (f"{name}.vertices", f"{name}.faces", f"{name}.normals") for name in names)}
        assert painted.name == plain.name and kept.keys() == expected.keys()
        for key in expected:
            np.testing.assert_array_equal(kept[key], expected[key], err_msg=f"{seed}: {key}")
    assert painted_meshes >= 12


def test_a_lens_leaves_every_other_choice_and_the_held_out_family_alone(monkeypatch):
    """The lens draws from a random stream of its own: a training world with one is the world without it
    but for its cameras' aperture and focus (every keyframe's alike); a held-out world is never given one."""
    lenses = 0
    for seed in [world_seed("training", n) for n in range(12)] + [world_seed("held_out", n) for n in range(6)]:
        for frames in (1, 3):
            through, plain = _with_and_without(monkeypatch, "LENS_SHARE", seed, frames)
            cameras = [through.camera, *through.camera_keyframes.values()]
            if family_of(seed) == "held_out":
                assert all(camera.aperture_radius == 0 for camera in cameras)
                continue
            lenses += 1
            for camera in cameras:
                distance = np.linalg.norm(camera.target - camera.origin)
                assert 0.003 <= camera.aperture_radius / distance <= 0.03
                assert 0.7 <= camera.focus_distance / distance <= 1.3
            _assert_alike_but(through, plain, seed, lambda key: key.startswith("lens"))
    assert lenses == 24


def test_a_sky_map_leaves_every_other_choice_and_the_held_out_family_alone(monkeypatch):
    """The sky map draws from a random stream of its own: a training world with one is the world without it
    plus the map (finite, positive, brighter on the mean above the horizon than below); a held-out world
    never gets one, nor does a world without a sky."""
    from wgpu_rt.dataset import worlds as worlds_module

    maps = 0
    for seed in [world_seed("training", n) for n in range(16)] + [world_seed("held_out", n) for n in range(8)]:
        mapped, plain = _with_and_without(monkeypatch, "SKY_MAP_SHARE", seed)
        assert plain.environment is None
        if family_of(seed) == "held_out" or not np.any(plain.background > 0):
            assert mapped.environment is None
            continue
        maps += 1
        sky = mapped.environment
        assert sky.shape == (*worlds_module.SKY_MAP_SIZE, 3) and np.all(np.isfinite(sky)) and sky.min() > 0
        assert sky[: len(sky) // 2].mean() > sky[-3:].mean()
        _assert_alike_but(mapped, plain, seed)
    assert maps >= 3


def test_coats_leave_every_other_choice_and_the_held_out_family_alone(monkeypatch):
    """Coated materials draw from a random stream of their own: a training world with them is the world
    without them but for some matte materials turned plastic of the same colour, some of them under a rough coat;
    a held-out world has none."""
    _without_worn_metal(monkeypatch)
    coated = rough = 0
    for seed in [world_seed("training", n) for n in range(12)] + [world_seed("held_out", n) for n in range(6)]:
        with_coats, plain = _with_and_without(monkeypatch, "PLASTIC_SHARE", seed)
        kinds = {name: m.kind for name, m in with_coats.materials.items()}
        if family_of(seed) == "held_out":
            assert "plastic" not in kinds.values()
        for name, material in with_coats.materials.items():
            before = plain.materials[name]
            if material.kind == "plastic":
                coated += 1
                assert before.kind == "diffuse" and not before.is_emissive and 1.3 <= material.ior <= 1.7
                np.testing.assert_array_equal(material.reflectance, before.reflectance)
                rough += material.roughness > 0
                assert material.roughness == 0 or 0.02 <= material.roughness <= 0.6
        _assert_alike_but(with_coats, plain, seed,
                          lambda key: key.startswith("material ") and kinds[key[len("material "):]] == "plastic")
    assert coated >= 12 and 0.25 * coated <= rough <= 0.75 * coated


def test_tinted_glass_leaves_every_other_choice_and_the_held_out_family_alone(monkeypatch):
    """Glass tints draw from a random stream of their own: a training world with them is the world without them
    but for its glass's transmittance; a held-out world's glass stays clear."""
    tinted = 0
    for seed in [world_seed("training", n) for n in range(24)] + [world_seed("held_out", n) for n in range(6)]:
        with_tints, plain = _with_and_without(monkeypatch, "TINTED_GLASS_SHARE", seed)
        for name, material in with_tints.materials.items():
            if np.any(material.transmittance < 1):
                tinted += 1
                assert family_of(seed) == "training" and material.kind == "dielectric"
                assert 0.75 <= material.transmittance.max() <= 1 and material.transmittance.min() >= 0.25 * 0.75
        _assert_alike_but(with_tints, plain, seed,
                          lambda key: key.startswith("material ") and with_tints.materials[key[9:]].kind == "dielectric")
    assert tinted >= 4


def test_absorbing_glass_leaves_every_other_choice_and_the_held_out_family_alone(monkeypatch):
    """Glass absorption draws from a random stream of its own: a training world with it is the world without it but
    for its glass's absorption, which keeps 5–90 % of each channel over 5 cm to 1 m; a held-out world's glass
    absorbs nothing."""
    absorbing = 0
    for seed in [world_seed("training", n) for n in range(24)] + [world_seed("held_out", n) for n in range(6)]:
        with_absorption, plain = _with_and_without(monkeypatch, "ABSORBING_GLASS_SHARE", seed)
        for name, material in with_absorption.materials.items():
            if material.absorbs:
                absorbing += 1
                assert family_of(seed) == "training" and material.kind == "dielectric"
                assert -np.log(0.9) / 1.0 <= material.absorption.min()
                assert material.absorption.max() <= -np.log(0.05) / 0.05
        _assert_alike_but(with_absorption, plain, seed, lambda key: key.startswith("material ")
                          and with_absorption.materials[key[9:]].kind == "dielectric")
    assert absorbing >= 4


def test_screens_leave_every_other_choice_and_the_held_out_family_alone(monkeypatch):
    """Cut-out screens draw from a random stream of their own: a training world with one is the world without it
    plus the screen, which stands in the view between the camera and its target, is cut out by its texture and
    keeps clear of glass and lamps (none where it would not); a held-out world never has one."""
    from wgpu_rt.scene.transforms import transform_points

    _without_worn_metal(monkeypatch)
    screens = 0
    for seed in [world_seed("training", n) for n in range(24)] + [world_seed("held_out", n) for n in range(6)]:
        with_screen, plain = _with_and_without(monkeypatch, "SCREEN_SHARE", seed)
        added = [mesh for mesh in with_screen.meshes if mesh.name == "screen"]
        assert len(added) <= (family_of(seed) == "training")
        if not added:
            continue
        corners = transform_points(added[0].transform, added[0].vertices)
        for other in with_screen.meshes:
            material = with_screen.materials[other.material]
            if material.kind == "dielectric" or material.is_emissive:
                points = transform_points(other.transform, other.vertices)
                assert np.any(points.min(0) > corners.max(0)) or np.any(corners.min(0) > points.max(0)), other.name
        screens += 1
        (screen,) = added
        assert screen.is_cut_out and screen.uvs is not None
        kept = screen.texture[..., 3] >= 128
        assert 0.1 < kept.mean() < 0.95
        camera = with_screen.camera
        right, up, forward = (axis.astype(np.float64) for axis in camera.basis())
        offset = screen.transform[:3, 3].astype(np.float64) - camera.origin
        distance = np.linalg.norm(camera.target.astype(np.float64) - camera.origin)
        assert 0.25 * distance - 1e-4 <= offset @ forward <= 0.6 * distance + 1e-4
        without = {key: value for key, value in _arrays(with_screen).items()
                   if not key.startswith("screen.") and key != "material screen"}
        expected = _arrays(plain)
        assert without.keys() == expected.keys()
        for key in expected:
            np.testing.assert_array_equal(without[key], expected[key], err_msg=f"{seed}: {key}")
    assert screens >= 3


def test_normal_maps_leave_every_other_choice_and_the_held_out_family_alone(monkeypatch):
    """Normal maps draw from a random stream of their own: a training world with them is the world without them
    but for some flat set surfaces given coordinates in their own plane and a seamless map of moderate tilts;
    a held-out world never has one."""
    from wgpu_rt.dataset.worlds import RELIEF_SIZE, SET_RECTANGLES

    _without_worn_metal(monkeypatch)
    mapped_surfaces = 0
    for seed in [world_seed("training", n) for n in range(12)] + [world_seed("held_out", n) for n in range(6)]:
        mapped, plain = _with_and_without(monkeypatch, "NORMAL_MAP_SHARE", seed)
        with_maps = [mesh for mesh in mapped.meshes if mesh.normal_map is not None]
        assert not with_maps or family_of(seed) == "training"
        # (a screen has coordinates for its cut-out texture)
        assert all(mesh.normal_map is None and (mesh.uvs is None or mesh.name == "screen") for mesh in plain.meshes)
        for mesh in with_maps:
            mapped_surfaces += 1
            assert mesh.name in SET_RECTANGLES and not mapped.materials[mesh.material].is_emissive
            assert mesh.normal_map.shape == (RELIEF_SIZE, RELIEF_SIZE, 3) and mesh.uvs.shape == (len(mesh.vertices), 2)
            normals = mesh.normal_map / 255.0 * 2 - 1
            tilts = np.degrees(np.arccos(np.clip(normals[..., 2] / np.linalg.norm(normals, axis=-1), -1, 1)))
            assert 5 <= np.percentile(tilts, 95) <= 50, (seed, mesh.name)
        _assert_alike_but(mapped, plain, seed)
    assert mapped_surfaces >= 6


def test_worn_metal_leaves_every_other_choice_and_the_held_out_family_alone(monkeypatch):
    """Worn metal draws from a random stream of its own: a training world with it is the world without it but for
    some matte or coated surfaces made plastics of their colour under a metal-rough map (fully metal or matte texels,
    the matte ones of one roughness, as Mitsuba's roughplastic has); a held-out world never has one."""
    from wgpu_rt.dataset.worlds import WORN_SIZE

    worn_surfaces = 0
    for seed in [world_seed("training", n) for n in range(12)] + [world_seed("held_out", n) for n in range(6)]:
        worn, plain = _with_and_without(monkeypatch, "METAL_ROUGH_SHARE", seed)
        mapped = [mesh for mesh in worn.meshes if mesh.metal_rough_map is not None]
        assert not mapped or family_of(seed) == "training"
        assert all(mesh.metal_rough_map is None for mesh in plain.meshes)
        before = {mesh.name: plain.materials[mesh.material] for mesh in plain.meshes}
        for mesh in mapped:
            worn_surfaces += 1
            material, was = worn.materials[mesh.material], before[mesh.name]
            assert material.kind == "plastic" and was.kind in ("diffuse", "plastic") and not was.is_emissive
            np.testing.assert_array_equal(material.reflectance, was.reflectance)
            codes = mesh.metal_rough_map
            assert codes.shape == (WORN_SIZE, WORN_SIZE, 3) and mesh.uvs.shape == (len(mesh.vertices), 2)
            metal = codes[..., 2] == 255
            assert set(np.unique(codes[..., 2])) <= {0, 255} and 0.1 < metal.mean() < 0.9, (seed, mesh.name)
            assert len(np.unique(codes[..., 1][~metal])) == 1
        changed = {key: value for key, value in _arrays(worn).items() if not key.endswith("/worn")}
        expected = _arrays(plain)
        assert changed.keys() == expected.keys()
        for key in expected:
            np.testing.assert_array_equal(changed[key], expected[key], err_msg=f"{seed}: {key}")
    assert worn_surfaces >= 6


def test_a_quarter_of_the_training_worlds_look_through_a_lens(worlds):
    from wgpu_rt.dataset.worlds import LENS_SHARE

    assert abs(np.mean([w.camera.aperture_radius > 0 for w in worlds]) - LENS_SHARE) < 0.08


def test_about_half_the_training_worlds_are_painted(worlds):
    from wgpu_rt.dataset.worlds import PAINTED_SHARE

    painted = [w for w in worlds if any(mesh.colors is not None for mesh in w.meshes)]
    assert abs(len(painted) / len(worlds) - PAINTED_SHARE) < 0.1
    varied = [np.ptp(mesh.colors, axis=0).max() > 0.05 for w in painted for mesh in w.meshes if mesh.colors is not None]
    # (two colours drawn alike, or a pattern whose cells fall between vertices, vary less)
    assert np.mean(varied) > 0.9


def test_the_families_share_no_seed_and_no_geometry(tmp_path):
    import trimesh

    assert world_seed("training", 2 ** 40 + 5) < FAMILY_SIZE <= world_seed("held_out", 0)
    assert family_of(world_seed("training", 7)) == "training" and family_of(world_seed("held_out", 7)) == "held_out"
    assert not set(FAMILY_SHAPES["training"]) & set(FAMILY_SHAPES["held_out"])
    names = [f"scan{i:02d}.obj" for i in range(12)]
    for name in names:
        trimesh.creation.box(extents=(1, 2, 3)).export(tmp_path / name)
    split = {name: mesh_family(tmp_path / name) for name in names}
    assert set(split.values()) == {"training", "held_out"}
    drawn = {"training": set(), "held_out": set()}
    for family in drawn:
        for n in range(20):
            for mesh in generate_world(world_seed(family, n), tmp_path).meshes:
                drawn[family].add(mesh.name.rsplit("_", 1)[0])
    for family, labels in drawn.items():
        meshes = {label for label in labels if f"{label}.obj" in split}
        assert meshes and all(split[f"{label}.obj"] == family for label in meshes), family
    shapes = {family: labels & set(FAMILY_SHAPES["training"] + FAMILY_SHAPES["held_out"])
              for family, labels in drawn.items()}
    assert shapes["training"] and shapes["held_out"] and not shapes["training"] & shapes["held_out"]


def test_worlds_become_views_with_family_splits(tmp_path):
    training = DatasetConfig(scenes=("cornell",), views=3, size=8, spp=(1,), gold=2, worlds=20,
                             sequence_fraction=0.2)
    plans = plan_views(training)
    worlds = [p for p in plans if p.world_seed is not None]
    assert len(worlds) == 20 and [p.view_id for p in plans] == [f"v{i:05d}" for i in range(23)]
    assert {p.split for p in worlds} == {"train", "val"}
    assert sum(p.split == "val" for p in worlds) == 2
    assert all(family_of(p.world_seed) == "training" for p in worlds)
    shards = [plan_views(training, (i, 4)) for i in range(4)]
    assert sorted(p.view_id for shard in shards for p in shard) == [p.view_id for p in plans]
    held_out = DatasetConfig(scenes=(), worlds=5, family="held_out", size=8, spp=(1,), gold=2)
    held_plans = plan_views(held_out)
    assert {p.split for p in held_plans} == {"test"} and held_plans[0].frames == held_out.sequence_length
    assert all(family_of(p.world_seed) == "held_out" for p in held_plans)
    reseeded = DatasetConfig(**{**held_out.__dict__, "seed": 1})
    assert not {p.world_seed for p in plan_views(reseeded)} & {p.world_seed for p in held_plans}

    TruthEngine(held_out, tmp_path, renderer=fake_render).run(progress=False)
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert [v["scene"] for v in manifest["views"]] == [p.scene for p in held_plans]
    assert all(v["scene"].startswith("world-") and v["split"] == "test" for v in manifest["views"])
    assert TruthEngine(held_out, tmp_path, renderer=fake_render).run(progress=False) == []


def test_a_generated_world_renders_finite(gpu):
    from wgpu_rt.renderer import render

    scene = generate_world(world_seed("held_out", 11), frames=2)
    result = render(scene, spp=2, size=(16, 16), max_depth=4, frames=1, aovs=("albedo", "normal", "depth", "motion"))
    assert result.color.shape == (16, 16, 3) and np.all(np.isfinite(result.color)) and result.color.max() > 0
    assert all(np.all(np.isfinite(plane)) for plane in result.aovs.values())
