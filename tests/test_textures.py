"""Colour textures: a mesh's image sampled at each hit's interpolated coordinates (bilinear, repeat, v = 1 at
the image's top), multiplying its material's reflectance, for the tracer's albedo, the aux pass's and the
colour alike; read from a mesh file's material; the same on one level and two; malformed ones refused by
name. Mitsuba's agreement is in tests/test_mitsuba.py."""

import numpy as np
import pytest
import trimesh
from PIL import Image

from wgpu_rt.accel.geometry import GeometryBuffers
from wgpu_rt.errors import SceneError
from wgpu_rt.passes import FrameBuffers
from wgpu_rt.scene.meshio import load_mesh_file
from wgpu_rt.scene.model import Camera, Material, Mesh, Scene, linear_from_srgb8, sample_texture
from wgpu_rt.scene.primitives import rectangle
from wgpu_rt.trace import SampleSchedule, TracePass

SIZE = 32
REFLECTANCE = 0.8


def _texture(height=4, width=6, seed=0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (height, width, 3), dtype=np.uint8)


def _tile(texture, uvs=None, name="tile") -> Mesh:
    """The [-1, 1]² rectangle facing +z, its coordinates (0, 0) at the bottom left and (1, 1) at the top right
    unless ``uvs`` says otherwise."""
    vertices, faces, _ = rectangle()
    if uvs is None:
        uvs = (vertices[:, :2] + 1) / 2
    return Mesh(name, vertices, faces, "paint", texture=texture, uvs=np.asarray(uvs, np.float32))


def _scene(*meshes) -> Scene:
    """The camera 1 unit in front of the tile with a 90° view: the tile fills the square image exactly."""
    camera = Camera(origin=[0, 0, 1], target=[0, 0, 0], up=[0, 1, 0], fov=90)
    return Scene(camera, list(meshes), {"paint": Material(reflectance=REFLECTANCE)}, name="textured tile")


def _albedo(gpu, scene, spp=16, aux_samples=0, geometry=None):
    trace = TracePass(gpu, scene, geometry or GeometryBuffers.build(scene), SIZE, SIZE, max_depth=2, seed=3)
    buffers = FrameBuffers(gpu, SIZE, SIZE)
    encoder = gpu.device.create_command_encoder()
    trace.clear(encoder, buffers)
    trace.execute(encoder, buffers, SampleSchedule(spp))
    if aux_samples:
        trace.execute_aux(encoder, buffers, aux_samples)
    gpu.device.queue.submit([encoder.finish()])
    return buffers.read("albedo").transpose(1, 2, 0)


def _pixel_centre_uvs(size=SIZE) -> np.ndarray:
    """(size², 2) the tile's coordinates at each pixel's centre, rows from the image's top."""
    centres = (np.arange(size) + 0.5) / size
    u, v = np.meshgrid(centres, 1 - centres)
    return np.stack([u, v], -1).reshape(-1, 2)


def test_numpy_reference_hits_texel_centres_and_wraps():
    texture = _texture()
    height, width = texture.shape[:2]
    rows, columns = np.meshgrid(np.arange(height), np.arange(width), indexing="ij")
    centres = np.stack([(columns + 0.5) / width, 1 - (rows + 0.5) / height], -1).reshape(-1, 2)
    np.testing.assert_allclose(sample_texture(texture, centres), linear_from_srgb8(texture).reshape(-1, 3), atol=1e-6)
    np.testing.assert_allclose(sample_texture(texture, centres + [3, -2]), sample_texture(texture, centres), atol=1e-5)
    between = sample_texture(texture, [[1 / width, 1 - 0.5 / height]])[0]      # halfway between texels 0 and 1
    np.testing.assert_allclose(between, linear_from_srgb8(texture[0, :2]).mean(0), atol=1e-6)


@pytest.mark.parametrize("aux_samples", [0, 4])
def test_albedo_is_the_texture_where_the_tile_is_seen(gpu, aux_samples):
    """Each texel covers 8×5.3 pixels, so the bilinear texture is near linear across a pixel and the pixel's
    mean is its centre's sample; the image's top row (row 0) shows at the top of the tile."""
    texture = _texture()
    albedo = _albedo(gpu, _scene(_tile(texture)), aux_samples=aux_samples)
    expected = REFLECTANCE * sample_texture(texture, _pixel_centre_uvs()).reshape(SIZE, SIZE, 3)
    error = np.abs(albedo - expected)
    assert np.median(error) < 0.01 and np.percentile(error, 95) < 0.04, (np.median(error), error.max())
    flipped = REFLECTANCE * sample_texture(texture[::-1], _pixel_centre_uvs()).reshape(SIZE, SIZE, 3)
    assert np.median(np.abs(albedo - flipped)) > 5 * np.median(error)     # the orientation is seen


def test_coordinates_outside_the_unit_square_repeat(gpu):
    texture = _texture(seed=1)
    vertices = rectangle()[0]
    tiled = _albedo(gpu, _scene(_tile(texture, uvs=(vertices[:, :2] + 1) * 1.5 - 1)))   # [-1, 2]²: 3×3 copies
    expected = REFLECTANCE * sample_texture(texture, _pixel_centre_uvs() * 3 - 1).reshape(SIZE, SIZE, 3)
    assert np.median(np.abs(tiled - expected)) < 0.02


def test_an_untextured_mesh_beside_a_textured_one_keeps_its_reflectance(gpu):
    texture = np.full((2, 2, 3), 255, np.uint8)
    texture[..., 1:] = 0                                               # pure red
    plain = Mesh("plain", *rectangle()[:2], "paint", transform=np.diag([0.5, 1, 1, 1]).astype(np.float32))
    plain.transform[0, 3] = 0.5
    left = _tile(texture)
    left.transform = np.diag([0.5, 1, 1, 1]).astype(np.float32)
    left.transform[0, 3] = -0.5
    albedo = _albedo(gpu, _scene(left, plain), spp=4)
    red = np.broadcast_to(np.float32([REFLECTANCE, 0, 0]), (SIZE, SIZE // 2 - 1, 3))
    np.testing.assert_allclose(albedo[:, :SIZE // 2 - 1], red, atol=1e-5)
    np.testing.assert_allclose(albedo[:, SIZE // 2 + 1:], REFLECTANCE, atol=1e-5)


def test_a_mesh_files_texture_is_read_as_trimesh_reads_it(tmp_path):
    """A glTF's base colour texture: the image and per-vertex coordinates, which ``sample_texture`` reads at
    the vertices as trimesh's own ``to_color`` does (same orientation; on a smooth image, since trimesh takes
    the nearest texel of a slightly other grid), and one array for the geometries that share it."""
    box = trimesh.creation.box()
    uvs = np.random.default_rng(3).uniform(0, 1, (len(box.vertices), 2))
    rows, columns = np.meshgrid(np.linspace(0, 1, 48), np.linspace(0, 1, 64), indexing="ij")
    pixels = (255 * np.stack([rows, columns, 0.5 + 0 * rows], -1)).astype(np.uint8)   # red down, green across
    box.visual = trimesh.visual.TextureVisuals(uv=uvs, image=Image.fromarray(pixels))
    other = box.copy()
    other.apply_translation([3, 0, 0])
    path = tmp_path / "boxes.glb"
    trimesh.Scene([box, other]).export(path)
    meshes = load_mesh_file(path, "paint")
    assert len(meshes) == 2 and meshes[0].texture is meshes[1].texture
    assert meshes[0].colors is None
    np.testing.assert_array_equal(meshes[0].texture, pixels)
    loaded = trimesh.load(path, force="scene", process=False)
    geometry = next(iter(loaded.geometry.values()))
    theirs = linear_from_srgb8(np.asarray(geometry.visual.to_color().vertex_colors)[:, :3])
    ours = sample_texture(meshes[0].texture, meshes[0].uvs)
    assert np.abs(ours - theirs).max() < 0.04
    assert np.abs(sample_texture(meshes[0].texture[::-1], meshes[0].uvs) - theirs).max() > 0.3
    assert load_mesh_file(path, "paint", vertex_colors=False)[0].texture is None


def test_an_obj_files_material_image_is_its_texture(tmp_path):
    box = trimesh.creation.box()
    pixels = _texture(4, 4, seed=5)
    box.visual = trimesh.visual.TextureVisuals(uv=np.random.default_rng(6).uniform(0, 1, (len(box.vertices), 2)),
                                               image=Image.fromarray(pixels))
    box.export(tmp_path / "box.obj")            # box.obj, material.mtl (map_Kd) and its image beside
    (mesh,) = load_mesh_file(tmp_path / "box.obj", "paint")
    np.testing.assert_array_equal(mesh.texture, pixels)
    assert mesh.uvs.shape == (len(mesh.vertices), 2) and mesh.colors is None


def test_an_image_trimesh_cannot_decode_leaves_the_mesh_plain(tmp_path):
    """Never half-textured: no image, no coordinates either (the material's reflectance alone)."""
    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(uv=np.zeros((len(box.vertices), 2)), image=Image.fromarray(_texture()))
    box.export(tmp_path / "box.obj")
    (tmp_path / "material_0.png").write_bytes(b"not a png")
    (mesh,) = load_mesh_file(tmp_path / "box.obj", "paint")
    assert mesh.texture is None and mesh.uvs is None and mesh.colors is None


@pytest.mark.parametrize("change, message", [
    (dict(uvs=None), "needs its coordinates"),
    (dict(texture=None), "needs its coordinates"),
    (dict(uvs=np.zeros((3, 2), np.float32)), "uvs must be finite"),
    (dict(uvs=np.full((4, 2), np.nan, np.float32)), "uvs must be finite"),
    (dict(texture=np.zeros((4, 4), np.uint8)), r"\(H, W, 3\) or \(H, W, 4\) uint8"),
    (dict(texture=np.zeros((4, 4, 3), np.float32)), r"\(H, W, 3\) or \(H, W, 4\) uint8"),
    (dict(texture=np.zeros((4, 4, 5), np.uint8)), r"\(H, W, 3\) or \(H, W, 4\) uint8"),
    (dict(colors=np.ones((4, 3), np.float32)), "both vertex colours and a texture"),
])
def test_malformed_textures_are_refused_by_name(change, message):
    tile = _tile(_texture())
    for key, value in change.items():
        setattr(tile, key, value)
    with pytest.raises(SceneError, match=f"mesh 'tile'.*{message}"):
        GeometryBuffers.build(_scene(tile))


# -- scene files: a mesh entry's `texture` and `texture_repeat` ------------------------------------------------
def _scene_file(tmp_path, **entry):
    from wgpu_rt.scene.loader import parse_scene

    data = {"camera": {"origin": [0, 0, 1], "target": [0, 0, 0], "fov": 90},
            "materials": {"paint": {"kind": "diffuse", "reflectance": REFLECTANCE},
                          "lamp": {"kind": "diffuse", "emission": 1.0}},
            "meshes": [{"shape": "rectangle", "material": "paint", **entry},
                       {"shape": "rectangle", "material": "lamp", "transform": {"translate": [0, 0, 5]}}]}
    return parse_scene(data, "scene.json", tmp_path)


def test_a_scene_files_texture_on_a_rectangle_shows_upright(gpu, tmp_path):
    """The image file's top row at the rectangle's top seen from its front, repeated as told."""
    pixels = _texture(seed=7)
    Image.fromarray(pixels).save(tmp_path / "paint.png")
    scene = _scene_file(tmp_path, texture="paint.png")
    np.testing.assert_array_equal(scene.meshes[0].texture, pixels)
    albedo = _albedo(gpu, scene)
    expected = REFLECTANCE * sample_texture(pixels, _pixel_centre_uvs()).reshape(SIZE, SIZE, 3)
    assert np.median(np.abs(albedo - expected)) < 0.01
    repeated = _scene_file(tmp_path, texture="paint.png", texture_repeat=[2, 3])
    np.testing.assert_allclose(repeated.meshes[0].uvs, scene.meshes[0].uvs * [2, 3])


def test_every_cube_face_shows_the_whole_image_upright():
    from wgpu_rt.scene.primitives import primitive, primitive_uvs

    vertices = primitive("cube")[0].reshape(6, 4, 3)
    uvs = primitive_uvs("cube").reshape(6, 4, 2)
    for face, coordinates in zip(vertices, uvs):
        normal = face.mean(0)
        assert sorted(map(tuple, coordinates)) == [(0, 0), (0, 1), (1, 0), (1, 1)]
        if abs(normal[1]) < 0.5:      # a side face: v rises with y, u to the right seen from outside
            np.testing.assert_allclose(coordinates[:, 1], (face[:, 1] + 1) / 2)
            right = np.cross([0, 1, 0], normal)
            np.testing.assert_allclose(coordinates[:, 0], (face @ right + 1) / 2)


@pytest.mark.parametrize("entry, message", [
    (dict(texture="missing.png"), r"meshes\[0\]\.texture: .*missing\.png: texture image not found"),
    (dict(texture="bad.png"), r"meshes\[0\]\.texture: .*bad\.png: cannot read texture image"),
    (dict(texture=3), r"meshes\[0\]\.texture: expected a string"),
    (dict(shape="sphere", texture="paint.png"), r"meshes\[0\]\.texture: a sphere has no texture coordinates"),
    (dict(texture="paint.png", texture_repeat=0), r"meshes\[0\]\.texture_repeat: expected counts in"),
    (dict(texture="paint.png", texture_repeat=[1, 2, 3]), r"meshes\[0\]\.texture_repeat: expected a number or a list"),
    (dict(texture_repeat=2), r"meshes\[0\]\.texture_repeat: the mesh has no texture to repeat"),
])
def test_bad_texture_entries_are_refused_by_field(tmp_path, entry, message):
    Image.fromarray(_texture()).save(tmp_path / "paint.png")
    (tmp_path / "bad.png").write_bytes(b"not a png")
    with pytest.raises(SceneError, match=message):
        _scene_file(tmp_path, **entry)


def test_a_texture_on_a_mesh_file_reads_the_files_coordinates(tmp_path):
    """A file with coordinates but no image of its own takes the entry's image at them; one without
    coordinates is refused, naming the file."""
    from wgpu_rt.scene.loader import parse_scene

    box = trimesh.creation.box()
    uvs = np.random.default_rng(8).uniform(0, 1, (len(box.vertices), 2))
    box.visual = trimesh.visual.TextureVisuals(uv=uvs)
    box.export(tmp_path / "uv-box.obj")
    trimesh.creation.box().export(tmp_path / "plain-box.obj")
    pixels = _texture(seed=9)
    Image.fromarray(pixels).save(tmp_path / "paint.png")
    data = {"camera": {"origin": [0, 0, 5], "target": [0, 0, 0]}, "materials": {"paint": {"kind": "diffuse"}},
            "meshes": [{"file": "uv-box.obj", "material": "paint", "texture": "paint.png"}]}
    (mesh,) = parse_scene(data, "scene.json", tmp_path).meshes
    np.testing.assert_array_equal(mesh.texture, pixels)
    assert mesh.uvs.shape == (len(mesh.vertices), 2)
    data["meshes"][0]["file"] = "plain-box.obj"
    with pytest.raises(SceneError, match=r"meshes\[0\]\.file: .*plain-box\.obj.*has no texture coordinates"):
        parse_scene(data, "scene.json", tmp_path)


def _transformed_box(tmp_path, base_transform, normal_transform=None):
    """A .glb box whose vertices' coordinates are the unit square's corners (in turn), with a base colour
    texture (and a normal texture) under the KHR_texture_transforms given."""
    from gltf_files import edit_glb_json
    from trimesh.visual.material import PBRMaterial

    box = trimesh.creation.box()
    corners = np.float32([[0, 1], [1, 1], [0, 0], [1, 0]])        # ours: v up; glTF's (0, 0), (1, 0), (0, 1), (1, 1)
    flat = np.full((4, 4, 3), [128, 128, 255], np.uint8)
    material = PBRMaterial(name="tiled", baseColorTexture=Image.fromarray(_texture(4, 4, seed=2)),
                           normalTexture=Image.fromarray(flat))
    box.visual = trimesh.visual.TextureVisuals(uv=corners[np.arange(len(box.vertices)) % 4], material=material)

    def add(tree):
        entry = tree["materials"][0]
        for info, transform in ((entry["pbrMetallicRoughness"]["baseColorTexture"], base_transform),
                                (entry["normalTexture"], normal_transform)):
            if transform is not None:
                info["extensions"] = {"KHR_texture_transform": transform}
    (tmp_path / "tiled.glb").write_bytes(edit_glb_json(box.export(file_type="glb"), add))
    return tmp_path / "tiled.glb"


def test_a_gltf_texture_transform_moves_the_coordinates(tmp_path):
    """KHR_texture_transform, by its specification's example: offset (0, 1), a quarter turn and scale ½ read the
    image's lower-left quadrant turned clockwise, glTF's (0, 0), (1, 0), (0, 1), (1, 1) going to (0, 1),
    (0, ½), (½, 1), (½, ½); in the tracer's coordinates (v up) each v is 1 − v. The same transform on the
    normal texture is welcome; a file without one keeps its coordinates."""
    example = {"offset": [0, 1], "rotation": np.pi / 2, "scale": [0.5, 0.5]}
    (mesh,) = load_mesh_file(_transformed_box(tmp_path, example, example), "paint")
    expected = np.float32([[0, 0], [0, 0.5], [0.5, 0], [0.5, 0.5]])
    np.testing.assert_allclose(mesh.uvs, expected[np.arange(len(mesh.uvs)) % 4], atol=1e-6)
    (plain,) = load_mesh_file(_transformed_box(tmp_path, None), "paint")
    np.testing.assert_allclose(plain.uvs, np.float32([[0, 1], [1, 1], [0, 0], [1, 0]])[np.arange(len(mesh.uvs)) % 4])


@pytest.mark.parametrize("base, normal, message", [
    ({"scale": [2, 2]}, {"scale": [3, 3]}, "material 'tiled': its textures have different KHR_texture_transforms"),
    ({"rotation": "left"}, None, r"material 'tiled': baseColorTexture's KHR_texture_transform: rotation must be"),
    ({"offset": [0, float("inf")]}, None, "KHR_texture_transform: offset must be in"),
    ([1, 2], None, "baseColorTexture's KHR_texture_transform: expected an object"),
])
def test_bad_texture_transforms_are_refused_by_file_and_material(tmp_path, base, normal, message):
    path = _transformed_box(tmp_path, base, normal)
    with pytest.raises(SceneError, match=message):
        load_mesh_file(path, "paint")
