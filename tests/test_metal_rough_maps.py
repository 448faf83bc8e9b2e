"""Metal-rough maps (glTF's metallic-roughness texture read per texel, ``Mesh.metal_rough_map``): each point of the
plastic it is on is glTF's metal with probability the map's metalness, else the plastic, of the map's roughness there
(wgsl/trace/metal_rough_maps.wgsl). Here: a map of three bands renders each band as the uniform material it stands
for, the loaders' reading of a glTF texture, an OBJ's map_Pr / map_Pm and a scene file's entry, and the errors;
Mitsuba's agreement is in tests/test_mitsuba.py."""

import numpy as np
import pytest
import trimesh
from PIL import Image
from test_normal_maps import _obj_with
from trimesh.visual.material import PBRMaterial

from wgpu_rt.errors import SceneError
from wgpu_rt.renderer import render
from wgpu_rt.scene import Camera, Material, Mesh, PointLight, Scene, load_scene
from wgpu_rt.scene.meshio import load_mesh_file
from wgpu_rt.scene.primitives import primitive
from wgpu_rt.trace.coat import COAT_LEVELS, coat_levels, coat_transmittance, coat_words, coat_words_between

SIZE = 48
BASE = [0.7, 0.4, 0.2]
# (roughness, metalness) codes of the map's three bands, left to right: a rough plastic between two coat levels,
# a fairly smooth metal, and half metal at that roughness.
BANDS = [(153, 0), (77, 255), (77, 128)]


def _band_map(width_per_band: int = 8) -> np.ndarray:
    image = np.zeros((2, 3 * width_per_band, 3), np.uint8)
    for i, (roughness, metalness) in enumerate(BANDS):
        image[:, i * width_per_band:(i + 1) * width_per_band, 1:] = roughness, metalness
    return image


def _scene(material: Material, metal_rough_map=None) -> Scene:
    """A square ([-1, 1]² facing the camera, u along x) seen head-on, lit by a point light and a grey sky."""
    vertices, faces, normals = primitive("rectangle")
    uvs = None if metal_rough_map is None else ((vertices[:, :2] + 1) / 2).astype(np.float32)
    square = Mesh("square", vertices, faces, "surface", normals=normals, uvs=uvs, metal_rough_map=metal_rough_map)
    camera = Camera([0, 0, 2], [0, 0, 0], fov=float(2 * np.degrees(np.arctan(0.5))), fov_axis="x")
    return Scene(camera, [square], {"surface": material}, lights=[PointLight(np.float32([0.3, 0.5, 1.2]),
                                                                            np.float32([3, 3, 3]))],
                 background=np.full(3, 0.3, np.float32), name="banded square")


def _band_means(image: np.ndarray) -> np.ndarray:
    """(3, 3): the mean colour of each band's inner columns (away from where bilinear filtering blends bands)."""
    third = SIZE // 3
    return np.stack([image[:, i * third + 3:(i + 1) * third - 3].reshape(-1, 3).mean(0) for i in range(3)])


def _plastic(roughness_code: int) -> Material:
    return Material("plastic", reflectance=BASE, ior=1.5, roughness=(roughness_code / 255) ** 2)


def _metal(roughness_code: int) -> Material:
    return Material("conductor", reflectance=BASE, eta=0.0, k=1.0, roughness=(roughness_code / 255) ** 2)


def _image(scene: Scene) -> np.ndarray:
    return render(scene, spp=128, size=(SIZE, SIZE), seed=5, max_depth=3).color


def test_each_band_of_a_map_renders_as_the_material_it_stands_for(gpu):
    """Against the square in one material: the plastic band as a plastic of its roughness (its coat table between
    two levels), the metal band as glTF's metal of its roughness, the half-metal band as the mean of that metal and
    plastic weighted by its metalness."""
    banded = _band_means(_image(_scene(_plastic(0), _band_map())))
    plastic_rough = _band_means(_image(_scene(_plastic(BANDS[0][0]))))[0]
    metal = _band_means(_image(_scene(_metal(BANDS[1][0]))))
    plastic = _band_means(_image(_scene(_plastic(BANDS[1][0]))))
    weight = BANDS[2][1] / 255
    expected = np.stack([plastic_rough, metal[1], weight * metal[2] + (1 - weight) * plastic[2]])
    np.testing.assert_allclose(banded, expected, rtol=0.01)
    # the bands differ by far more than that bound
    assert np.min(np.abs(np.diff(expected, axis=0)) / expected[1:]) > 0.1


def test_between_levels_a_coat_table_is_close_to_its_own():
    """The tables a varying coat reads, mixed between levels, stay within 1 % (cos-weighted) of the table its
    roughness has, and at a level are that level's."""
    levels = coat_levels(1.5)
    cosines = np.linspace(0, 1, 201)
    for roughness in (0.2, 0.45, 0.6, 0.93):
        exact = coat_transmittance(coat_words(roughness ** 2, 1.5), cosines)
        mixed = coat_transmittance(coat_words_between(levels, roughness), cosines)
        assert np.sum(np.abs(mixed - exact) * cosines) / np.sum(exact * cosines) < 0.01, roughness
    at_level = coat_words_between(levels, 3 / (COAT_LEVELS - 1))
    np.testing.assert_array_equal(at_level.view(np.uint32), levels[3].view(np.uint32))


def _textured_box(tmp_path, material: PBRMaterial, name: str = "box.glb"):
    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(uv=np.random.default_rng(1).random((len(box.vertices), 2)),
                                               material=material)
    box.export(tmp_path / name)
    return tmp_path / name


def _loaded(path) -> tuple[Mesh, Material]:
    """The one mesh of the file at ``path`` in its own material."""
    materials: dict = {}
    (mesh,) = load_mesh_file(path, None, materials=materials)
    return mesh, materials[mesh.material]


def test_a_gltf_materials_metallic_roughness_texture_is_its_meshes_map(tmp_path):
    """The texture's green and blue times the material's roughness and metallic factors; the material the plastic of
    its base colour, whatever its metallic factor (the map makes its metal)."""
    codes = np.zeros((4, 4, 3), np.uint8)
    codes[..., 0], codes[..., 1], codes[..., 2] = 99, np.arange(16).reshape(4, 4) * 16, 200
    shiny = PBRMaterial(name="shiny", baseColorFactor=[0.5, 0.6, 0.7, 1.0], metallicFactor=0.5, roughnessFactor=0.8,
                        metallicRoughnessTexture=Image.fromarray(codes))
    mesh, material = _loaded(_textured_box(tmp_path, shiny))
    assert material.kind == "plastic" and material.ior == pytest.approx(1.5)
    np.testing.assert_allclose(material.reflectance, [0.5, 0.6, 0.7], atol=1 / 255)
    np.testing.assert_array_equal(mesh.metal_rough_map[..., 0], 0)
    np.testing.assert_array_equal(mesh.metal_rough_map[..., 1], np.round(codes[..., 1] * 0.8))
    np.testing.assert_array_equal(mesh.metal_rough_map[..., 2], 100)


def test_on_glass_the_texture_counts_by_its_mean(tmp_path):
    from gltf_files import edit_glb_json

    codes = np.zeros((2, 2, 3), np.uint8)
    codes[..., 1] = [[0, 102], [102, 0]]              # roughness 0.2 on the mean
    frosted = PBRMaterial(name="frosted", roughnessFactor=1.0, metallicRoughnessTexture=Image.fromarray(codes))
    path = _textured_box(tmp_path, frosted)

    def transmissive(tree):
        tree["materials"][0]["extensions"] = {"KHR_materials_transmission": {"transmissionFactor": 1.0}}
    path.write_bytes(edit_glb_json(path.read_bytes(), transmissive))
    mesh, material = _loaded(path)
    assert material.kind == "dielectric" and mesh.metal_rough_map is None
    assert material.roughness == pytest.approx(0.2 ** 2, rel=0.02)


COPPER = dict(eta=[0.27, 0.68, 1.32], k=[3.61, 2.63, 2.29])


def test_on_a_conductor_a_map_roughens_it_per_point(gpu):
    """A copper square under a map of two roughnesses (its metalness left out: the copper is metal everywhere), each
    half against the square in copper of that roughness, within 1 %."""
    codes = np.zeros((2, 16, 3), np.uint8)
    codes[:, :8, 1], codes[:, 8:, 1] = 77, 179
    banded = _image(_scene(Material("conductor", **COPPER, roughness=0.5), codes))
    half = SIZE // 2
    for columns, code in ((slice(3, half - 3), 77), (slice(half + 3, SIZE - 3), 179)):
        alone = _image(_scene(Material("conductor", **COPPER, roughness=(code / 255) ** 2)))
        np.testing.assert_allclose(banded[:, columns].mean((0, 1)), alone[:, columns].mean((0, 1)), rtol=0.01)
    assert abs(banded[:, 3:half - 3].mean() / banded[:, half + 3:-3].mean() - 1) > 0.1


def test_a_map_on_anything_but_plastic_or_a_conductor_is_refused_by_mesh(gpu):
    scene = _scene(Material("diffuse"), _band_map())
    with pytest.raises(SceneError, match=r"mesh 'square': a metal-rough map needs a plastic .* or a conductor"):
        render(scene, spp=1, size=(8, 8))


def _scene_file(tmp_path, material: str, **entry):
    Image.fromarray(_band_map()).save(tmp_path / "bands.png")
    keys = "".join(f'{key} = "{value}"\n' for key, value in entry.items())
    (tmp_path / "scene.toml").write_text(
        '[camera]\norigin = [0, 0, 2]\ntarget = [0, 0, 0]\n\n'
        f'[materials.paint]\nkind = "{material}"\nreflectance = [0.7, 0.4, 0.2]\n\n'
        f'[[meshes]]\nmaterial = "paint"\n{keys}')
    return tmp_path / "scene.toml"


def test_a_scene_files_metal_rough_map_on_a_shape(tmp_path):
    scene = load_scene(_scene_file(tmp_path, "plastic", shape="rectangle", metal_rough_map="bands.png"))
    (mesh,) = scene.meshes
    np.testing.assert_array_equal(mesh.metal_rough_map, _band_map())
    assert mesh.uvs is not None


@pytest.mark.parametrize("material, entry, message", [
    ("diffuse", dict(shape="rectangle", metal_rough_map="bands.png"), r"metal_rough_map: .*give the entry a plastic"),
    ("plastic", dict(shape="sphere", metal_rough_map="bands.png"), r"metal_rough_map: a sphere has no texture coord"),
])
def test_bad_metal_rough_map_entries_are_refused_by_field(tmp_path, material, entry, message):
    with pytest.raises(SceneError, match=message):
        load_scene(_scene_file(tmp_path, material, **entry))


def test_the_kernel_and_the_packing_agree_on_their_constants():
    """The coat levels' count and the empty map index are written in the WGSL as well as in Python."""
    import re

    from wgpu_rt.accel.geometry import NO_MAP
    from wgpu_rt.shaders import read_wgsl

    kernel, images = read_wgsl("trace/metal_rough_maps.wgsl"), read_wgsl("trace/texture_images.wgsl")
    assert int(re.search(r"const COAT_LEVELS: u32 = (\d+)u;", kernel).group(1)) == COAT_LEVELS
    assert int(re.search(r"const NO_MAP: u32 = (0x[0-9a-f]+)u;", images).group(1), 16) == NO_MAP


def test_an_obj_materials_roughness_and_metalness_images_are_its_meshes_map(tmp_path):
    """The MTL PBR extension's ``map_Pr`` and ``map_Pm`` (grey, read raw): the roughness in green, the metalness in
    blue, a missing one's scalar in its place (``Pm`` here), the metalness image resized to the roughness image's."""
    roughness = np.arange(12, dtype=np.uint8).reshape(3, 4) * 20
    Image.fromarray(roughness).save(tmp_path / "rough.png")
    Image.fromarray(np.full((6, 8), 255, np.uint8)).save(tmp_path / "metal.png")
    mesh, material = _loaded(_obj_with(tmp_path, "map_Pr rough.png\nmap_Pm metal.png\n"))
    assert material.kind == "plastic"
    np.testing.assert_allclose(material.reflectance, 0.5)
    np.testing.assert_array_equal(mesh.metal_rough_map[..., 1], roughness)
    np.testing.assert_array_equal(mesh.metal_rough_map[..., 2], 255)
    mesh, _ = _loaded(_obj_with(tmp_path, "map_Pr rough.png\nPm 0.4\n"))
    np.testing.assert_array_equal(mesh.metal_rough_map[..., 2], round(0.4 * 255))
    (tmp_path / "rough.png").unlink()
    with pytest.raises(SceneError, match=r"its material's map_Pr: .*rough.png: texture image not found"):
        _loaded(_obj_with(tmp_path, "map_Pr rough.png\n"))
