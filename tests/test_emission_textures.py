"""Emission textures: a mesh's ``emission_texture`` (sRGB, sampled as a colour texture is) tints its material's
emission per texel, where a path meets the light (trace/trace.wgsl) and where next-event estimation samples a point
on it (trace/emitters.wgsl); read from glTF emissive textures, OBJ ``map_Ke`` and a scene file's
``emission_texture``. Mitsuba's agreement (its area emitter with a bitmap radiance) is in tests/test_mitsuba.py."""

import json

import numpy as np
import pytest
import trimesh
from PIL import Image
from test_cutouts import _head_on, _square
from trimesh.visual.material import PBRMaterial

from wgpu_rt.errors import SceneError
from wgpu_rt.renderer import render
from wgpu_rt.scene import Camera, Material, Scene, load_scene
from wgpu_rt.scene.meshio import load_mesh_file
from wgpu_rt.scene.model import linear_from_srgb8, sample_texture
from wgpu_rt.scene.transforms import rotate, scale, translate

PATTERN = np.array([[[255, 40, 40], [255, 255, 255]], [[20, 20, 20], [40, 80, 255]]], np.uint8)


def lamp_scene(texture, emission=6.0) -> Scene:
    """A floor lit by a tilted rectangular lamp the camera also sees, its emission tinted by ``texture``."""
    floor = _square("floor", "white", translate([0, -1, 0]) @ rotate([1, 0, 0], -90) @ scale(3))
    lamp = _square("lamp", "lamp", translate([0, 0.6, -0.5]) @ rotate([1, 0, 0], 60) @ scale(0.7),
                   emission_texture=texture)
    materials = {"white": Material("diffuse", reflectance=0.7),
                 "lamp": Material("diffuse", reflectance=0.2, emission=emission)}
    return Scene(Camera([0, 0.5, 3], [0, -0.3, 0], fov=55), [floor, lamp], materials, name="lamp")


def test_a_uniform_emission_texture_is_its_colour_times_the_emission(gpu):
    """One colour over the whole image lights the scene exactly as the emission times that colour (linear)."""
    grey = np.full((2, 2, 3), 180, np.uint8)
    options = dict(spp=16, size=(32, 32), max_depth=4, aovs=())
    textured = render(lamp_scene(grey), **options).color
    plain = render(lamp_scene(None, emission=6.0 * linear_from_srgb8(grey[0, 0])), **options).color
    np.testing.assert_allclose(textured, plain, rtol=1e-5, atol=1e-6)


def test_the_lamp_shows_its_texture_where_the_reference_samples_it(gpu):
    """Seen head-on with only emission counted (max depth 1), each pixel inside one of the four colours' quarters
    (away from the bilinear blends, where the texture is flat) is the emission times ``sample_texture`` there."""
    size = 64
    blocks = np.repeat(np.repeat(PATTERN, 4, axis=0), 4, axis=1)     # 8×8: each colour a 4×4 block
    lamp = _square("lamp", "lamp", np.eye(4), emission_texture=blocks)
    scene = Scene(_head_on(), [lamp], {"lamp": Material("diffuse", emission=3.0)})
    image = render(scene, spp=4, size=(size, size), max_depth=1, aovs=()).color
    centres = (np.arange(size) + 0.5) / size
    uvs = np.stack(np.meshgrid(centres, 1 - centres), -1).reshape(-1, 2)
    expected = 3.0 * sample_texture(blocks, uvs).reshape(size, size, 3)
    flat = np.zeros((size, size), bool)                  # a block's texel centres and a pixel's margin away
    for rows in (slice(6, 26), slice(38, 58)):
        for columns in (slice(6, 26), slice(38, 58)):
            flat[rows, columns] = True
    np.testing.assert_allclose(image[flat], expected[flat], rtol=1e-4)
    assert len({tuple(np.round(image[r, c], 3)) for r, c in ((16, 16), (16, 48), (48, 16), (48, 48))}) == 4


def test_emission_textures_are_read_from_files(tmp_path):
    """glTF: the material's emissive texture, its emission the factor times the strength (no longer times the
    texture's mean); OBJ: ``map_Ke``; a scene file's ``emission_texture`` (a sphere has no coordinates)."""
    box = trimesh.creation.box()
    material = PBRMaterial(name="screen", emissiveFactor=[1.0, 1.0, 1.0], emissiveTexture=Image.fromarray(PATTERN))
    box.visual = trimesh.visual.TextureVisuals(uv=np.random.default_rng(2).random((8, 2)), material=material)
    box.export(tmp_path / "screen.glb")
    data = {"camera": {"origin": [0, 0, 3], "target": [0, 0, 0]}, "materials": {"white": {}},
            "meshes": [{"file": "screen.glb"}]}
    (tmp_path / "scene.json").write_text(json.dumps(data))
    scene = load_scene(tmp_path / "scene.json")
    screen = next(mesh for mesh in scene.meshes if mesh.name.startswith("screen"))
    np.testing.assert_array_equal(screen.emission_texture, PATTERN)
    np.testing.assert_allclose(scene.materials["screen/screen"].emission, [1, 1, 1])

    Image.fromarray(PATTERN).save(tmp_path / "glow.png")
    (tmp_path / "lamp.obj").write_text("mtllib lamp.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                       "usemtl m\nf 1/1 2/2 3/3\n")
    (tmp_path / "lamp.mtl").write_text("newmtl m\nKd 0.5 0.5 0.5\nKe 4 4 4\nmap_Ke glow.png\n")
    np.testing.assert_array_equal(load_mesh_file(tmp_path / "lamp.obj", "x")[0].emission_texture, PATTERN)

    data["meshes"] = [{"shape": "rectangle", "material": "white", "emission_texture": "glow.png"}]
    (tmp_path / "scene.json").write_text(json.dumps(data))
    np.testing.assert_array_equal(load_scene(tmp_path / "scene.json").meshes[0].emission_texture, PATTERN)
    data["meshes"][0]["shape"] = "sphere"
    (tmp_path / "scene.json").write_text(json.dumps(data))
    with pytest.raises(SceneError, match=r"meshes\[0\]\.emission_texture: a sphere has no texture coordinates"):
        load_scene(tmp_path / "scene.json")


def test_an_emission_textures_mean_from_code_counts_is_its_decoded_mean():
    """The emitter table weighs a textured triangle's pick by its image's mean linear colour, taken from each
    channel's counts of its 256 codes: the mean of every texel decoded."""
    from wgpu_rt.trace.scene_data import srgb8_mean

    image = np.random.default_rng(4).integers(0, 256, (37, 53, 3)).astype(np.uint8)
    decoded = linear_from_srgb8(image).astype(np.float64).reshape(-1, 3).mean(0)
    np.testing.assert_allclose(srgb8_mean(image), decoded, rtol=1e-6)
