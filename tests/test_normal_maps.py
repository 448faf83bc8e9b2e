"""Normal maps: a mesh's tangent-space normals read raw at its texture coordinates and tilting its shading
normal in the frame of the surface's u direction (numpy reference ``scene.model.mapped_normal``; Mitsuba's
agreement, with the mirroring and shadowing that go with it, is in tests/test_mitsuba.py)."""

import json

import numpy as np
import pytest
import trimesh
from gltf_files import edit_glb_json
from PIL import Image
from trimesh.visual.material import PBRMaterial

from wgpu_rt.accel.geometry import GeometryBuffers, InstancedGeometry
from wgpu_rt.errors import SceneError
from wgpu_rt.passes import FrameBuffers
from wgpu_rt.scene import load_scene
from wgpu_rt.scene.model import Camera, Material, Mesh, Scene, mapped_normal, sample_texture
from wgpu_rt.scene.primitives import rectangle
from wgpu_rt.trace import SampleSchedule, TracePass

SIZE = 32


def _normal_map(seed=0, tilt_degrees=35.0, height=4, width=6) -> np.ndarray:
    """Codes of unit normals tilted by ``tilt_degrees`` in random directions, one a texel."""
    phi = np.random.default_rng(seed).uniform(0, 2 * np.pi, (height, width))
    tilt = np.radians(tilt_degrees)
    normal = np.stack([np.sin(tilt) * np.cos(phi), np.sin(tilt) * np.sin(phi), np.full_like(phi, np.cos(tilt))], -1)
    return np.round((normal + 1) / 2 * 255).astype(np.uint8)


def _pixel_centre_uvs() -> np.ndarray:
    centres = (np.arange(SIZE) + 0.5) / SIZE
    u, v = np.meshgrid(centres, 1 - centres)
    return np.stack([u, v], -1).reshape(-1, 2)


def _tile(normal_map, turned: bool = False) -> Mesh:
    """The [-1, 1]² rectangle facing +z (the camera), its u along +x, or along −y where ``turned``."""
    vertices, faces, _ = rectangle()
    uvs = (vertices[:, :2] + 1) / 2
    if turned:
        uvs = np.stack([1 - uvs[:, 1], uvs[:, 0]], -1)
    return Mesh("tile", vertices, faces, "paint", uvs=uvs.astype(np.float32), normal_map=normal_map)


def _scene(*meshes) -> Scene:
    camera = Camera(origin=[0, 0, 1], target=[0, 0, 0], up=[0, 1, 0], fov=90)
    return Scene(camera, list(meshes), {"paint": Material(reflectance=0.8)}, name="normal-mapped tile")


def _planes(gpu, scene, geometry=None, spp=16) -> tuple[np.ndarray, np.ndarray]:
    """The albedo and the unit normal plane, each (SIZE², 3)."""
    trace = TracePass(gpu, scene, geometry or GeometryBuffers.build(scene), SIZE, SIZE, max_depth=2, seed=3)
    buffers = FrameBuffers(gpu, SIZE, SIZE)
    encoder = gpu.device.create_command_encoder()
    trace.clear(encoder, buffers)
    trace.execute(encoder, buffers, SampleSchedule(spp))
    gpu.device.queue.submit([encoder.finish()])
    albedo, normals = (buffers.read(name).transpose(1, 2, 0).reshape(-1, 3) for name in ("albedo", "normal"))
    return albedo, normals / np.linalg.norm(normals, axis=-1, keepdims=True)


def _normals(gpu, scene, geometry=None, spp=16) -> np.ndarray:
    return _planes(gpu, scene, geometry, spp)[1]


def test_the_reference_tilts_in_the_frame_of_u():
    up = np.array([[0.0, 0.0, 1.0]])
    along_u = np.array([[0.0, 1.0, 0.0]])                       # u runs along +y here
    flat = np.array([[128, 128, 255]]) / 255.0
    np.testing.assert_allclose(mapped_normal(up, along_u, flat), up, atol=0.01)
    toward_u = mapped_normal(up, along_u, np.array([[1.0, 0.5, 1.0]]))  # local (1, 0, 1): 45° toward +u
    np.testing.assert_allclose(toward_u, [[0, np.sqrt(0.5), np.sqrt(0.5)]], atol=0.01)
    toward_v = mapped_normal(up, along_u, np.array([[0.5, 1.0, 1.0]]))  # local (0, 1, 1): toward n × s = −x
    np.testing.assert_allclose(toward_v, [[-np.sqrt(0.5), 0, np.sqrt(0.5)]], atol=0.01)


@pytest.mark.parametrize("turned", [False, True])
def test_the_normal_plane_is_the_tilted_normal_where_the_tile_is_seen(gpu, turned):
    """Each texel covers several pixels, so a pixel's mean normal is near its centre's; with the coordinates
    turned a quarter, u runs along −y and the same map tilts the other way."""
    normal_map = _normal_map()
    normals = _normals(gpu, _scene(_tile(normal_map, turned)))
    uvs = _pixel_centre_uvs()
    if turned:
        uvs = np.stack([1 - uvs[:, 1], uvs[:, 0]], -1)
    dp_du = np.tile([0.0, -1.0, 0.0] if turned else [1.0, 0.0, 0.0], (len(uvs), 1))
    up, texels = np.tile([0.0, 0.0, 1.0], (len(uvs), 1)), sample_texture(normal_map, uvs, srgb=False)
    expected = mapped_normal(up, dp_du, texels)
    error = np.linalg.norm(normals - expected, axis=-1)
    assert np.median(error) < 0.02 and np.percentile(error, 90) < 0.06, (np.median(error), error.max())
    other = mapped_normal(up, -dp_du, texels)
    assert np.median(np.linalg.norm(normals - other, axis=-1)) > 5 * np.median(error)   # the frame is seen


def test_two_levels_read_their_maps_as_one(gpu):
    """The tile (a colour texture and a normal map) placed twice, a second placement behind the camera, is a
    two-level scene whose triangles and records are stored once: the same albedo, the same normals."""
    def tile():
        mesh = _tile(_normal_map(seed=2))
        mesh.texture = np.random.default_rng(2).integers(0, 256, (4, 6, 3), dtype=np.uint8)
        return mesh

    single = _planes(gpu, _scene(tile()), spp=4)
    behind = np.eye(4, dtype=np.float32)
    behind[2, 3] = 5
    first = tile()
    scene = _scene(first, first.instance("copy", transform=behind))
    assert scene.has_instances
    for plane, expected in zip(_planes(gpu, scene, InstancedGeometry(scene), spp=4), single):
        np.testing.assert_allclose(plane, expected, atol=1e-4)


def test_a_flat_map_changes_nothing(gpu):
    flat = np.full((2, 2, 3), [128, 128, 255], np.uint8)
    plain = _normals(gpu, _scene(Mesh("tile", *rectangle()[:2], "paint")), spp=4)
    assert np.max(np.linalg.norm(_normals(gpu, _scene(_tile(flat)), spp=4) - plain, axis=-1)) < 0.01


def _scene_file(tmp_path, **entry):
    Image.fromarray(_normal_map()).save(tmp_path / "bumps.png")
    data = {"camera": {"origin": [0, 0, 3], "target": [0, 0, 0]}, "materials": {"paint": {}},
            "meshes": [{"material": "paint", **entry}]}
    (tmp_path / "scene.json").write_text(json.dumps(data))
    return tmp_path / "scene.json"


def test_a_scene_files_normal_map_on_a_shape_and_on_a_mesh_file(tmp_path):
    (mesh,) = load_scene(_scene_file(tmp_path, shape="rectangle", normal_map="bumps.png",
                                     texture_repeat=3)).meshes
    np.testing.assert_array_equal(mesh.normal_map, _normal_map())
    assert mesh.texture is None and mesh.uvs.max() == pytest.approx(3.0)
    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(uv=np.random.default_rng(0).random((len(box.vertices), 2)))
    box.export(tmp_path / "box.glb")
    meshes = load_scene(_scene_file(tmp_path, file="box.glb", normal_map="bumps.png")).meshes
    assert all(m.normal_map is not None and m.uvs is not None for m in meshes)


@pytest.mark.parametrize("entry, message", [
    (dict(shape="sphere", normal_map="bumps.png"), r"normal_map: a sphere has no texture coordinates"),
    (dict(shape="cube", normal_map="missing.png"), r"normal_map: .*missing.png: texture image not found"),
])
def test_bad_normal_map_entries_are_refused_by_field(tmp_path, entry, message):
    with pytest.raises(SceneError, match=message):
        load_scene(_scene_file(tmp_path, **entry))


def test_a_gltf_materials_normal_texture_is_its_meshes_normal_map(tmp_path):
    bumps = _normal_map(seed=4)
    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(uv=np.random.default_rng(1).random((len(box.vertices), 2)),
                                               material=PBRMaterial(normalTexture=Image.fromarray(bumps)))
    box.export(tmp_path / "bumpy.glb")
    (mesh,) = load_scene(_scene_file(tmp_path, file="bumpy.glb")).meshes
    np.testing.assert_array_equal(mesh.normal_map, bumps)
    assert mesh.texture is None and mesh.colors is None


def test_a_gltf_normal_textures_scale_scales_its_tilts(tmp_path):
    """glTF: the normal is normalize((2·texel − 1) · (scale, scale, 1)); a scale of 0 flattens the map."""
    from wgpu_rt.scene.meshio import load_mesh_file

    bumps = _normal_map(seed=5, tilt_degrees=30)
    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(uv=np.random.default_rng(1).random((len(box.vertices), 2)),
                                               material=PBRMaterial(name="bumpy", normalTexture=Image.fromarray(bumps)))
    data = box.export(file_type="glb")
    for scale, tilt in ((0.5, np.degrees(np.arctan(0.5 * np.tan(np.radians(30))))), (0.0, 0.0)):
        def rescale(tree, scale=scale):
            tree["materials"][0]["normalTexture"]["scale"] = scale
        (tmp_path / "scaled.glb").write_bytes(edit_glb_json(data, rescale))
        (mesh,) = load_mesh_file(tmp_path / "scaled.glb", "paint")
        normals = mesh.normal_map / 255.0 * 2 - 1
        tilts = np.degrees(np.arctan2(np.hypot(normals[..., 0], normals[..., 1]), normals[..., 2]))
        np.testing.assert_allclose(tilts, tilt, atol=0.6)


def _obj_with(tmp_path, statements: str):
    (tmp_path / "tri.obj").write_text("mtllib tri.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                      "usemtl m\nf 1/1 2/2 3/3\n")
    (tmp_path / "tri.mtl").write_text("newmtl m\nKd 0.5 0.5 0.5\n" + statements)
    return tmp_path / "tri.obj"


def test_an_obj_materials_normal_map(tmp_path):
    """MTL's ``norm``, or a ``map_Bump`` whose image is a normal map (bluish; a grey height map is not read),
    with its ``-bm`` scale; a missing image names the statement."""
    from wgpu_rt.scene.meshio import load_mesh_file

    Image.fromarray(_normal_map(seed=6, tilt_degrees=30)).save(tmp_path / "normals.png")
    Image.fromarray(np.full((4, 4, 3), 90, np.uint8)).save(tmp_path / "height.png")
    (mesh,) = load_mesh_file(_obj_with(tmp_path, "norm normals.png\n"), "paint")
    np.testing.assert_array_equal(mesh.normal_map, _normal_map(seed=6, tilt_degrees=30))
    (mesh,) = load_mesh_file(_obj_with(tmp_path, "map_Bump -bm 0.5 normals.png\n"), "paint")
    normals = mesh.normal_map / 255.0 * 2 - 1
    tilts = np.degrees(np.arctan2(np.hypot(normals[..., 0], normals[..., 1]), normals[..., 2]))
    np.testing.assert_allclose(tilts, np.degrees(np.arctan(0.5 * np.tan(np.radians(30)))), atol=0.6)
    (mesh,) = load_mesh_file(_obj_with(tmp_path, "map_Bump height.png\n"), "paint")
    assert mesh.normal_map is None
    with pytest.raises(SceneError, match=r"tri.obj.*its material's norm: .*gone.png: texture image not found"):
        load_mesh_file(_obj_with(tmp_path, "norm gone.png\n"), "paint")
