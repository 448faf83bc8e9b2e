"""glTF skins and morph targets (wgpu_rt/scene/gltf_skins.py): a skinned strip bends where its second joint turns
(linear blend skinning against its closed form, normals by the inverse transpose), morph targets mix by animated
weights; the tracer builds each frame's shape, and a hit's motion follows its triangle's corners."""

from pathlib import Path

import numpy as np
import pytest
import trimesh
from gltf_files import with_accessors

from wgpu_rt.accel.geometry import GeometryBuffers, InstancedGeometry
from wgpu_rt.errors import SceneError
from wgpu_rt.scene import load_scene
from wgpu_rt.scene.gltf_animation import FRAME_RATE
from wgpu_rt.scene.model import Mesh, Scene

ROOT_EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "meshes"
CAMERA = {"type": "perspective", "perspective": {"yfov": 0.6, "znear": 0.1}}
# a strip along x from 0 to 2, 0.2 wide in y: vertices (x, ±0.1, 0) at x = 0, 1, 2
STRIP = np.array([[x, y, 0.0] for x in (0.0, 1.0, 2.0) for y in (-0.1, 0.1)])
STRIP_FACES = np.array([[0, 2, 1], [1, 2, 3], [2, 4, 3], [3, 4, 5]])
QUARTER_ABOUT_X = [np.sin(np.pi / 4), 0.0, 0.0, np.cos(np.pi / 4)]


def _strip_file(tmp_path, edit_more=None, arrays=(), name="skinned.glb"):
    """The strip skinned to two joints (node "root" at the origin, node "elbow" its child at x = 1): x = 0 on the
    root, x = 1 half on each, x = 2 on the elbow, which turns a quarter about +x over 1 s; the strip's own node is
    moved 5 along z, which glTF ignores for a skinned mesh. ``edit_more(tree, first)`` edits further, ``first`` the
    index of ``arrays``' first accessor (appended after the skin's own)."""
    scene = trimesh.Scene()
    strip = trimesh.Trimesh(STRIP, STRIP_FACES, vertex_normals=np.tile([0.0, 0.0, 1.0], (6, 1)), process=False)
    scene.add_geometry(strip, node_name="strip", transform=trimesh.transformations.translation_matrix([0, 0, 5]))
    joints = np.array([[0, 0, 0, 0]] * 2 + [[0, 1, 0, 0]] * 2 + [[1, 0, 0, 0]] * 2, np.uint16)     # joint numbers
    shares = np.array([[1, 0, 0, 0], [1, 0, 0, 0], [0.5, 0.5, 0, 0], [0.5, 0.5, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0]])
    inverse_binds = np.stack([np.eye(4), trimesh.transformations.translation_matrix([-1, 0, 0])])
    inverse_binds = inverse_binds.transpose(0, 2, 1).reshape(2, 16)          # column-major

    def edit(tree, first):
        strip_node = next(i for i, node in enumerate(tree["nodes"]) if node.get("name") == "strip")
        tree["nodes"][strip_node]["skin"] = 0
        attributes = tree["meshes"][tree["nodes"][strip_node]["mesh"]]["primitives"][0]["attributes"]
        attributes["JOINTS_0"], attributes["WEIGHTS_0"] = first, first + 1
        root = len(tree["nodes"])
        tree["nodes"] += [{"name": "root", "children": [root + 1]}, {"name": "elbow", "translation": [1, 0, 0]},
                          {"camera": 0, "translation": [1, 0.5, 6]}]
        tree["scenes"][0]["nodes"] += [root, root + 2]
        tree["cameras"] = [CAMERA]
        tree["skins"] = [{"joints": [root, root + 1], "inverseBindMatrices": first + 2}]
        tree["animations"] = [{"samplers": [{"input": first + 3, "output": first + 4}],
                               "channels": [{"sampler": 0, "target": {"node": root + 1, "path": "rotation"}}]}]
        if edit_more is not None:
            edit_more(tree, first + 5)

    data = scene.export(file_type="glb")
    arrays = [joints, shares, inverse_binds, [0.0, 1.0], [[0, 0, 0, 1], QUARTER_ABOUT_X], *arrays]
    (tmp_path / name).write_bytes(with_accessors(data, arrays, edit))
    return tmp_path / name


def test_a_skinned_strip_bends_as_linear_blend_skinning_has_it(tmp_path):
    """At 1 s the elbow has turned a quarter about +x: (2, y, 0) on it alone goes to (2, 0, y), (1, y, 0) half on
    each to (1, y/2, y/2), the root's vertices stay; the strip's own node offset is ignored; the normal of a vertex on
    the elbow turns with it to −y. Halfway in time (slerp) the elbow's vertices are at 45°."""
    scene = load_scene(_strip_file(tmp_path))
    (strip,) = scene.meshes
    assert scene.frame_count == int(FRAME_RATE) + 1 and strip.deforms and scene.deforms and scene.has_motion
    np.testing.assert_allclose(strip.transform_at(24), np.eye(4))
    np.testing.assert_allclose(strip.vertices, STRIP, atol=1e-6)            # frame 0: the bind pose
    y = STRIP[:, 1]
    expected = np.array([[0, y[0], 0], [0, y[1], 0], [1, y[2] / 2, y[2] / 2], [1, y[3] / 2, y[3] / 2],
                         [2, 0, y[4]], [2, 0, y[5]]])
    np.testing.assert_allclose(strip.vertices_at(24), expected, atol=1e-6)
    np.testing.assert_allclose(strip.normals_at(24)[4:], [[0, -1, 0]] * 2, atol=1e-6)
    np.testing.assert_allclose(strip.normals_at(24)[:2], [[0, 0, 1]] * 2, atol=1e-6)
    half = np.radians(45.0)
    np.testing.assert_allclose(strip.vertices_at(12)[5], [2, 0.1 * np.cos(half), 0.1 * np.sin(half)], atol=1e-6)


def test_morph_targets_mix_by_their_animated_weights(tmp_path):
    """Two targets on the strip (no skin): the first lifts the far end by 1 in z, the second moves every vertex
    0.5 along y; the mesh's weights are (0, 0.4) and a weights channel takes the first from 0 to 1 over 1 s (the
    second keeps 0.4 as the channel gives it). Its node's own offset still places it."""
    lift = np.zeros((6, 3))
    lift[4:, 2] = 1.0
    slide = np.tile([0.0, 0.5, 0.0], (6, 1))

    def edit(tree, first):
        strip_node = next(i for i, node in enumerate(tree["nodes"]) if node.get("name") == "strip")
        del tree["nodes"][strip_node]["skin"], tree["skins"]
        mesh = tree["meshes"][tree["nodes"][strip_node]["mesh"]]
        mesh["primitives"][0]["targets"] = [{"POSITION": first}, {"POSITION": first + 1}]
        mesh["weights"] = [0.0, 0.4]
        tree["animations"] = [{"samplers": [{"input": first + 2, "output": first + 3}],
                               "channels": [{"sampler": 0, "target": {"node": strip_node, "path": "weights"}}]}]

    scene = load_scene(_strip_file(tmp_path, edit, [lift, slide, [0.0, 1.0], [0.0, 0.4, 1.0, 0.4]]))
    (strip,) = scene.meshes
    np.testing.assert_allclose(strip.transform_at(12)[:3, 3], [0, 0, 5])
    for frame in (0, 12, 24):
        expected = STRIP + frame / FRAME_RATE * lift + 0.4 * slide
        np.testing.assert_allclose(strip.vertices_at(frame), expected, atol=1e-6)


def test_the_tracer_builds_each_frames_shape(tmp_path):
    """The single-level geometry of frame 24 holds the bent strip, and where its triangles were at frame 23 for
    the motion vectors; a bending scene is never built in two levels (its bottom level would be frozen)."""
    scene = load_scene(_strip_file(tmp_path))
    (strip,) = scene.meshes
    geometry = GeometryBuffers.build(scene, 24)
    np.testing.assert_allclose(geometry.triangles, strip.vertices_at(24)[strip.faces][geometry.bvh.order], atol=1e-6)
    np.testing.assert_allclose(geometry.previous_triangles, strip.vertices_at(23)[strip.faces][geometry.bvh.order],
                               atol=1e-6)
    assert GeometryBuffers.build(load_scene(ROOT_EXAMPLES / "turntable.glb"), 3).previous_triangles is None
    assert not InstancedGeometry.suits(scene)


def test_a_hit_on_a_bending_mesh_was_where_its_triangle_was(gpu, tmp_path):
    """On the GPU, a hit point's previous position is the blend of its triangle's corners at the frame before by its
    barycentrics (accel/motion_vertices.wgsl): for rays at the strip's elbow half at frame 12, as the numpy blend
    has it, and not where its node's (still) transform would put it."""
    from wgpu_rt.accel.ray_query import RayQuery, query_rays

    scene = load_scene(_strip_file(tmp_path))
    (strip,) = scene.meshes
    geometry = GeometryBuffers.build(scene, 12)
    corners = strip.vertices_at(12)[STRIP_FACES[2:]].astype(np.float64)   # the far half's two triangles
    rng = np.random.default_rng(4)
    shares = rng.dirichlet([2, 2, 2], 40)
    which = np.arange(40) % 2
    targets = np.einsum("nk,nkj->nj", shares, corners[which])
    facing = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])[which]
    origins = targets + facing / np.linalg.norm(facing, axis=1, keepdims=True)
    hits, surfaces = RayQuery(gpu, geometry).intersect(query_rays(origins, targets - origins))
    hit = hits["prim"] != 0xFFFFFFFF
    assert hit.sum() > 20
    prim, u, v = hits["prim"][hit], hits["u"][hit], hits["v"][hit]
    weights = np.stack([1 - u - v, u, v], 1)
    expected = np.einsum("nk,nkj->nj", weights, geometry.previous_triangles[prim].astype(np.float64))
    now = np.einsum("nk,nkj->nj", weights, geometry.triangles[prim].astype(np.float64))
    np.testing.assert_allclose(surfaces["previous_position"][hit], expected, atol=1e-5)
    assert np.abs(expected - now).max() > 100 * 1e-5    # (the strip bent between the frames: 0.004 at most)


def test_mitsubas_scene_of_a_frame_has_that_frames_shape(mi, tmp_path):
    from wgpu_rt.scene.mitsuba import to_mitsuba

    scene = load_scene(_strip_file(tmp_path))
    index = 0       # (the file's one mesh)
    converted = mi.load_dict(to_mitsuba(scene, 8, 8, spp=1, max_depth=2, frame=24))
    shape = next(s for s in converted.shapes() if s.id().startswith(f"mesh{index:04d}"))
    positions = np.array(shape.vertex_positions_buffer()).reshape(-1, 3)
    np.testing.assert_allclose(np.unique(np.round(positions, 5), axis=0),
                               np.unique(np.round(scene.meshes[index].vertices_at(24), 5), axis=0), atol=1e-5)


def _weights_from_the_extra_array(tree, first):
    """Point the strip's WEIGHTS_0 at the first array the test adds."""
    tree["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"] = first


@pytest.mark.parametrize("change, arrays, message", [
    (lambda tree, first: tree["skins"][0].update(joints=[0, 99]), [], r"node 0: skin 0's joints must be a list of"),
    (lambda tree, first: tree["accessors"][first - 5].update(count=5), [],
     r"node 0: JOINTS_n and WEIGHTS_n must be VEC4s, one a vertex"),
    (lambda tree, first: tree["skins"][0].update(inverseBindMatrices=first - 4), [],
     r"node 0: skin 0's inverseBindMatrices must be 2 finite MAT4s"),
    (_weights_from_the_extra_array, [np.zeros((6, 4))], r"node 0: a vertex has no weight on any joint"),
    (_weights_from_the_extra_array, [np.full((6, 4), -0.5)], r"node 0: WEIGHTS_n must be finite and not negative"),
])
def test_bad_skins_fail_naming_the_node(tmp_path, change, arrays, message):
    with pytest.raises(SceneError, match=message):
        load_scene(_strip_file(tmp_path, change, arrays))


def test_a_bent_frame_renders_as_the_still_mesh_of_its_shape(gpu, tmp_path):
    """Frames 0 and 24 rendered in one run (the geometry built anew for the second) against still scenes of each
    frame's shape: sample for sample the same."""
    from wgpu_rt.renderer import render

    scene = load_scene(_strip_file(tmp_path))
    results = render(scene, spp=2, size=(24, 16), max_depth=2, aovs=(), frames=[0, 24], seed=3)
    (strip,) = scene.meshes
    for frame, result in zip((0, 24), results):
        shape = Mesh("still", strip.vertices_at(frame), strip.faces, strip.material, strip.normals_at(frame))
        still = Scene(scene.camera, [shape], scene.materials, scene.lights, scene.background, name="still")
        expected = render(still, spp=2, size=(24, 16), max_depth=2, aovs=(), frames=frame, seed=3).color
        np.testing.assert_array_equal(result.color, expected)
    assert np.abs(results[0].color - results[1].color).max() > 0.1        # (the elbow's half has turned)


def test_the_swaying_example_bends_its_reeds_and_squashes_its_blob():
    """examples/meshes/swaying.glb (make_swaying.py): 49 frames; each reed's root ring stays while its tip sways;
    the blob is squashed fully at 0.5 s (weight sin²(πt)), 0.65 as tall and 1.25 as wide, resting on the floor."""
    scene = load_scene(ROOT_EXAMPLES / "swaying.glb")
    assert scene.frame_count == 49 and not scene.camera_keyframes
    reeds = [mesh for mesh in scene.meshes if "reed" in mesh.name]
    assert len(reeds) == 3 and all(reed.deforms for reed in reeds)
    for reed in reeds:
        rest, swayed = reed.vertices_at(0), reed.vertices_at(30)
        np.testing.assert_allclose(swayed[:16], rest[:16], atol=1e-5)          # the root ring
        assert np.linalg.norm(swayed[-1] - rest[-1]) > 0.05                     # the tip
    (blob,) = [mesh for mesh in scene.meshes if "blob" in mesh.name]
    rest, squashed = (blob.transform_at(f)[:3, :3] @ blob.vertices_at(f).T + blob.transform_at(f)[:3, 3:]
                      for f in (0, 12))
    np.testing.assert_allclose(np.ptp(squashed, axis=1) / np.ptp(rest, axis=1), [1.25, 0.65, 1.25], rtol=1e-3)
    np.testing.assert_allclose([rest[1].min(), squashed[1].min()], 0.0, atol=1e-3)


def test_bent_shapes_beyond_the_memory_held_are_refused(tmp_path, monkeypatch):
    """Every frame's shape is held: a file whose bent meshes would pass MOST_BENT_BYTES over its frames stops with
    one line saying how much (here the strip's 6 vertices × 25 frames × 24 bytes, 3600 bytes, against 1000)."""
    import importlib

    monkeypatch.setattr(importlib.import_module("wgpu_rt.scene.gltf_scene"), "MOST_BENT_BYTES", 1000)
    with pytest.raises(SceneError, match=r"skinned.glb: its skinned or morphed meshes would take 0.0 GiB over its 25 "):
        load_scene(_strip_file(tmp_path))


def test_a_skin_that_throws_vertices_beyond_float32s_range_is_refused_by_frame(tmp_path):
    """The elbow also slides to x = 2e9 over the second: the bent strip leaves the tracer's range at some frame, which
    the file as a scene and a scene file's entry of it both name (the rest pose is within it)."""
    def slide(tree, first):
        elbow = next(i for i, node in enumerate(tree["nodes"]) if node.get("name") == "elbow")
        tree["animations"][0]["samplers"].append({"input": first - 2, "output": first})
        tree["animations"][0]["channels"].append({"sampler": 1, "target": {"node": elbow, "path": "translation"}})

    path = _strip_file(tmp_path, slide, [[[1, 0, 0], [2e9, 0, 0]]])
    with pytest.raises(SceneError, match=r"skinned.glb: mesh 'skinned' at frame \d+: its placement puts vertices"):
        load_scene(path)
    scene_file = tmp_path / "stage.toml"
    scene_file.write_text('[camera]\norigin = [0, 0, 5]\ntarget = [0, 0, 0]\n\n[materials.white]\nreflectance = 0.8\n\n'
                          '[[meshes]]\nfile = "skinned.glb"\nmaterial = "white"\n')
    with pytest.raises(SceneError, match=r"stage.toml: meshes\[0\].file: mesh 'skinned' at frame \d+: its placement"):
        load_scene(scene_file)
