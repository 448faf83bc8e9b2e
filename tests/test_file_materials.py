"""A mesh file's own materials (wgpu_rt/scene/file_materials.py): glTF's metallic-roughness with its
transmission, ior and emissive-strength extensions, and OBJ's MTL, each onto the tracer's kinds."""

import json

import numpy as np
import pytest
import trimesh
from gltf_files import edit_glb_json
from trimesh.visual.material import PBRMaterial

from wgpu_rt.errors import SceneError
from wgpu_rt.scene import load_scene
from wgpu_rt.scene.file_materials import pbr_material


@pytest.mark.parametrize("description, kind", [
    (dict(metallic=0.0, roughness=0.8, specular=False), "diffuse"),
    (dict(metallic=0.0, roughness=0.0), "plastic"),
    (dict(metallic=0.0, roughness=0.8), "plastic"),
    (dict(metallic=1.0, roughness=0.8), "conductor"),
    (dict(metallic=1.0, roughness=0.1, transmission=1.0), "dielectric"),
])
def test_each_description_becomes_the_kind_that_carries_its_look(description, kind):
    material = pbr_material((0.2, 0.4, 0.6), **description)
    assert material.kind == kind
    if kind != "dielectric":
        np.testing.assert_allclose(material.reflectance, [0.2, 0.4, 0.6], rtol=1e-6)
    if kind != "diffuse":
        assert material.roughness == pytest.approx(description["roughness"] ** 2)   # glTF's alpha = r²
    if kind == "conductor":     # Fresnel 1: the base colour is what it reflects head-on
        assert material.eta.tolist() == [0, 0, 0] and material.k.tolist() == [1, 1, 1]


def _glb(tmp_path, materials: list, name="thing.glb", edit=None):
    """A .glb of one box per entry of ``materials`` (trimesh PBRMaterials, None for none), its JSON passed
    through ``edit`` (a function of the materials list) before it is written."""
    scene = trimesh.Scene()
    for i, material in enumerate(materials):
        box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
        box.apply_translation((i, 0, 0))
        if material is not None:
            box.visual = trimesh.visual.TextureVisuals(material=material)
        scene.add_geometry(box, node_name=f"part{i}")
    data = scene.export(file_type="glb")
    if edit is not None:
        data = edit_glb_json(data, lambda tree: edit(tree["materials"]))
    (tmp_path / name).write_bytes(data)
    return tmp_path / name


def _scene_file(tmp_path, *entries, materials=None):
    scene = {"camera": {"origin": [0, 1, 5], "target": [0, 0, 0]},
             "materials": materials or {"white": {"reflectance": 0.8}},
             "meshes": [{"shape": "rectangle", "material": "white"}, *entries]}
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    return tmp_path / "scene.json"


def _extend(materials):
    materials[0]["extensions"] = {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                                  "KHR_materials_ior": {"ior": 1.33}}
    materials[1]["emissiveFactor"] = [1.0, 0.5, 0.25]
    materials[1]["extensions"] = {"KHR_materials_emissive_strength": {"emissiveStrength": 8.0}}


def test_a_gltf_files_materials_name_kind_and_values(tmp_path):
    gold = PBRMaterial(name="gold", baseColorFactor=[1.0, 0.8, 0.3, 1.0], metallicFactor=1.0, roughnessFactor=0.3)
    water = PBRMaterial(name="water", baseColorFactor=[0.6, 0.9, 1.0, 1.0], metallicFactor=0.0, roughnessFactor=0.1)
    lamp = PBRMaterial(name="lamp", baseColorFactor=[0.9, 0.9, 0.9, 1.0], metallicFactor=0.0, roughnessFactor=0.9)
    unnamed = PBRMaterial(baseColorFactor=[0.2, 0.4, 0.6, 1.0], metallicFactor=0.0, roughnessFactor=0.0)
    path = _glb(tmp_path, [water, lamp, gold, unnamed], edit=_extend)
    scene = load_scene(_scene_file(tmp_path, {"file": path.name}))
    names = {mesh.name: mesh.material for mesh in scene.meshes[1:]}
    assert [names[f"thing/part{i}"] for i in range(4)][:3] == ["thing/water", "thing/lamp", "thing/gold"]
    assert names["thing/part3"].startswith("thing/material")     # unnamed: by its index in the file
    water, lamp, gold, unnamed = (scene.materials[names[f"thing/part{i}"]] for i in range(4))
    assert (water.kind, water.ior, water.roughness) == ("dielectric", pytest.approx(1.33), pytest.approx(0.01))
    np.testing.assert_allclose(water.transmittance, [0.6, 0.9, 1.0], atol=1 / 255)   # the base colour tints it
    assert (lamp.kind, lamp.roughness) == ("plastic", pytest.approx(0.81))   # a rough coat
    np.testing.assert_allclose(lamp.emission, [8.0, 4.0, 2.0])
    assert gold.kind == "conductor" and gold.roughness == pytest.approx(0.09)
    np.testing.assert_allclose(gold.reflectance, [1.0, 0.8, 0.3], atol=1 / 255)
    assert (unnamed.kind, unnamed.ior, unnamed.roughness) == ("plastic", pytest.approx(1.5), 0.0)   # smooth
    np.testing.assert_allclose(unnamed.reflectance, [0.2, 0.4, 0.6], atol=1 / 255)


def _lacquer(materials):
    for material in materials:
        material["extensions"] = {"KHR_materials_clearcoat": {"clearcoatFactor": 1.0, "clearcoatRoughnessFactor": 0.2}}
    materials[2]["extensions"]["KHR_materials_clearcoat"]["clearcoatFactor"] = 0.3


def test_a_clear_coat_on_a_non_metal_is_its_plastics_coat(tmp_path):
    """KHR_materials_clearcoat of factor ≥ 0.5 over a rough non-metal: the plastic's coat takes the clear coat's
    roughness (alpha 0.2² where the base's was 0.9²); a metal under it and a faint coat (0.3) keep their own."""
    wood = PBRMaterial(name="wood", baseColorFactor=[0.5, 0.3, 0.1, 1.0], metallicFactor=0.0, roughnessFactor=0.9)
    paint = PBRMaterial(name="paint", baseColorFactor=[0.8, 0.1, 0.1, 1.0], metallicFactor=1.0, roughnessFactor=0.5)
    dull = PBRMaterial(name="dull", baseColorFactor=[0.5, 0.5, 0.5, 1.0], metallicFactor=0.0, roughnessFactor=0.9)
    path = _glb(tmp_path, [wood, paint, dull], edit=_lacquer)
    scene = load_scene(_scene_file(tmp_path, {"file": path.name}))
    wood, paint, dull = (scene.materials[f"thing/{name}"] for name in ("wood", "paint", "dull"))
    assert (wood.kind, wood.roughness) == ("plastic", pytest.approx(0.04))
    assert (paint.kind, paint.roughness) == ("conductor", pytest.approx(0.25))
    assert (dull.kind, dull.roughness) == ("plastic", pytest.approx(0.81))


def _volumes(materials):
    for material, volume in zip(materials, [{"thicknessFactor": 0.2, "attenuationColor": [0.5, 1.0, 0.25],
                                             "attenuationDistance": 2.0},
                                            {"thicknessFactor": 0.0, "attenuationColor": [0.5, 1.0, 0.25],
                                             "attenuationDistance": 2.0},
                                            {"thicknessFactor": 0.2, "attenuationColor": [0.5, 1.0, 0.25]}]):
        material["extensions"] = {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                                  "KHR_materials_volume": volume}


def test_a_gltf_glass_volume_absorbs_as_its_attenuation_colour_and_distance_say(tmp_path):
    """KHR_materials_volume: light crossing attenuationDistance keeps attenuationColor (absorption −ln(colour) /
    distance per unit); a thickness of 0 is a thin wall and a distance left out infinite: neither absorbs."""
    glasses = [PBRMaterial(name=name, metallicFactor=0.0) for name in ("thick", "thin", "endless")]
    path = _glb(tmp_path, glasses, edit=_volumes)
    materials = load_scene(_scene_file(tmp_path, {"file": path.name})).materials
    np.testing.assert_allclose(materials["thing/thick"].absorption, np.log([2.0, 1.0, 4.0]) / 2.0, rtol=1e-6)
    assert not materials["thing/thin"].absorbs and not materials["thing/endless"].absorbs
    assert {materials[f"thing/{name}"].kind for name in ("thick", "thin", "endless")} == {"dielectric"}


@pytest.mark.parametrize("transform, factor", [({"scale": 0.01}, 0.01), ({"scale": [2.0, 4.0, 1.0]}, 2.0),
                                               ({"rotate": {"axis": [0, 1, 0], "angle": 30}}, 1.0)])
def test_a_scaled_entry_rescales_its_files_absorption(tmp_path, transform, factor):
    """glTF gives attenuationDistance in the file's world: an entry that scales the file (a model in centimetres
    brought to metres) divides its glass's absorption by that scale (the cube root of the transform's determinant), so
    the glass keeps its colour; a turn changes nothing."""
    glasses = [PBRMaterial(name=name, metallicFactor=0.0) for name in ("thick", "thin", "endless")]
    path = _glb(tmp_path, glasses, edit=_volumes)
    materials = load_scene(_scene_file(tmp_path, {"file": path.name, "transform": transform})).materials
    np.testing.assert_allclose(materials["thing/thick"].absorption, np.log([2.0, 1.0, 4.0]) / 2.0 / factor, rtol=1e-5)
    assert not materials["thing/thin"].absorbs


def test_smooth_glass_on_an_open_surface_is_a_thin_pane_and_on_a_closed_one_a_solid(tmp_path):
    """A glTF glass on a single rectangle (open edges: a window) becomes a thin_dielectric of its ior and tint; the
    same material on a closed box (whose texture seams split its vertices) stays a dielectric."""
    glass = PBRMaterial(name="glass", baseColorFactor=[0.8, 0.9, 1.0, 1.0], metallicFactor=0.0, roughnessFactor=0.0)
    scene = trimesh.Scene()
    pane = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]], process=False)
    box = trimesh.creation.box()
    box = trimesh.Trimesh(box.vertices[box.faces].reshape(-1, 3), np.arange(36).reshape(12, 3), process=False)
    for name, mesh in (("pane", pane), ("box", box)):
        mesh.visual = trimesh.visual.TextureVisuals(uv=np.zeros((len(mesh.vertices), 2)), material=glass)
        scene.add_geometry(mesh, node_name=name)

    def transmissive(materials):
        materials[0]["extensions"] = {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                                      "KHR_materials_ior": {"ior": 1.4}}

    (tmp_path / "glass.glb").write_bytes(edit_glb_json(scene.export(file_type="glb"), lambda tree:
                                                       transmissive(tree["materials"])))
    loaded = load_scene(_scene_file(tmp_path, {"file": "glass.glb"}))
    kinds = {mesh.name: loaded.materials[mesh.material] for mesh in loaded.meshes[1:]}
    assert kinds["glass/box"].kind == "dielectric" and kinds["glass/pane"].kind == "thin_dielectric"
    assert kinds["glass/pane"].ior == pytest.approx(1.4)
    np.testing.assert_allclose(kinds["glass/pane"].transmittance, [0.8, 0.9, 1.0], atol=1 / 255)


def test_an_entrys_material_overrides_the_files_and_instances_keep_their_parts_own(tmp_path):
    path = _glb(tmp_path, [PBRMaterial(name="a", metallicFactor=1.0), PBRMaterial(name="b", metallicFactor=0.0)])
    scene = load_scene(_scene_file(tmp_path, {"file": path.name, "material": "white"}))
    assert {mesh.material for mesh in scene.meshes} == {"white"} and set(scene.materials) == {"white"}
    scene = load_scene(_scene_file(tmp_path, {"file": path.name, "instances": [{}, {"material": "white"}]}))
    assert sorted(mesh.material for mesh in scene.meshes[1:]) == ["thing/a", "thing/b", "white", "white"]


def test_an_obj_files_mtl_statements(tmp_path):
    (tmp_path / "parts.obj").write_text("mtllib parts.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
                                        "usemtl clay\nf 1 2 3\nusemtl glass\nf 2 4 3\nusemtl steel\nf 1 2 4\n"
                                        "usemtl lamp\nf 1 3 4\n")
    (tmp_path / "parts.mtl").write_text("newmtl clay\nKd 0.8 0.1 0.1\nKs 0.5 0.5 0.5\nNs 250\nillum 2\n"
                                        "newmtl glass\nNi 1.45\nillum 4\nPr 0.2\nTf 0.5 0.9 0.6\n"
                                        "newmtl steel\nKd 0.6 0.6 0.6\nPm 1\nPr 0.5\n"
                                        "newmtl lamp\nKd 0.9 0.9 0.9\nKe 5 5 4\n")
    scene = load_scene(_scene_file(tmp_path, {"file": "parts.obj"}))
    materials = {name.split("/")[1]: scene.materials[name] for name in scene.materials if "/" in name}
    assert materials["clay"].kind == "plastic"   # Ns 250 is Blender's roughness 0.5: alpha 0.25
    assert materials["clay"].roughness == pytest.approx(0.25)
    np.testing.assert_allclose(materials["clay"].reflectance, [0.8, 0.1, 0.1])
    assert materials["lamp"].kind == "diffuse"   # no Ks, no Pr: no specular layer
    assert (materials["glass"].kind, materials["glass"].ior) == ("dielectric", pytest.approx(1.45))
    assert materials["glass"].roughness == pytest.approx(0.04)
    np.testing.assert_allclose(materials["glass"].transmittance, [0.5, 0.9, 0.6])   # Tf, not the default Kd
    assert materials["steel"].kind == "conductor" and materials["steel"].roughness == pytest.approx(0.25)
    np.testing.assert_allclose(materials["lamp"].emission, [5, 5, 4])


def test_the_mesh_scene_takes_the_files_materials_and_clay_where_it_has_none(tmp_path):
    path = _glb(tmp_path, [PBRMaterial(name="gold", metallicFactor=1.0, roughnessFactor=0.2), None])
    scene = load_scene("mesh", mesh=path)
    assert {mesh.name: mesh.material for mesh in scene.meshes if mesh.name.startswith("thing")} == {
        "thing/part0": "thing/gold", "thing/part1": "clay"}


def _bad_metal(materials):
    materials[0]["pbrMetallicRoughness"]["metallicFactor"] = 2


def _bad_ior(materials):
    materials[0]["extensions"] = {"KHR_materials_ior": {"ior": 0.5}}


def _bad_volume(materials):
    materials[0]["extensions"] = {"KHR_materials_volume": {"thicknessFactor": 1.0, "attenuationDistance": 0}}


def _bad_coat(materials):
    materials[0]["extensions"] = {"KHR_materials_clearcoat": {"clearcoatFactor": 2}}


@pytest.mark.parametrize("edit, message", [
    (_bad_metal, r"material 'gold': metallicFactor must be in \[0, 1\], got 2"),
    (_bad_coat, r"material 'gold': clearcoatFactor must be in \[0, 1\], got 2"),
    (_bad_ior, r"material 'gold': ior must be in \[1, inf\], got 0.5"),
    (_bad_volume, r"material 'gold': attenuationDistance must be above 0, got 0"),
])
def test_a_gltf_materials_bad_values_are_refused_by_file_and_material(tmp_path, edit, message):
    path = _glb(tmp_path, [PBRMaterial(name="gold", metallicFactor=1.0)], edit=edit)
    with pytest.raises(SceneError, match=r"scene.json: meshes\[1\].file: .*thing.glb: " + message):
        load_scene(_scene_file(tmp_path, {"file": path.name}))


def test_a_file_without_materials_needs_the_entrys(tmp_path):
    trimesh.creation.box().export(tmp_path / "box.ply")
    with pytest.raises(SceneError, match=r"meshes\[1\].file: .*box.ply.*has no material of its own; give the mesh "
                                         r"entry a 'material'"):
        load_scene(_scene_file(tmp_path, {"file": "box.ply"}))


def test_a_files_material_may_not_take_another_materials_name(tmp_path):
    path = _glb(tmp_path, [PBRMaterial(name="gold", metallicFactor=1.0)])
    with pytest.raises(SceneError, match=r"'thing/gold' has the name of another material"):
        load_scene(_scene_file(tmp_path, {"file": path.name}, materials={"white": {}, "thing/gold": {}}))


def test_an_obj_materials_bad_value_is_refused_by_name(tmp_path):
    (tmp_path / "tri.obj").write_text("mtllib tri.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl odd\nf 1 2 3\n")
    (tmp_path / "tri.mtl").write_text("newmtl odd\nKd 0.5 0.5 0.5\nNi 0.5\nillum 4\n")
    with pytest.raises(SceneError, match=r"tri.obj: material 'odd': ni must be in \[1, inf\]"):
        load_scene(_scene_file(tmp_path, {"file": "tri.obj"}))


def test_the_mesh_room_rescales_a_files_absorption_as_it_fits_the_file(tmp_path):
    """``load_scene('mesh', mesh=...)`` scales a file to fit its room: its glass's absorption follows that scale."""
    glasses = [PBRMaterial(name=name, metallicFactor=0.0) for name in ("thick", "thin", "endless")]
    path = _glb(tmp_path, glasses, edit=_volumes)
    scene = load_scene("mesh", mesh=path)
    thick = next(mesh for mesh in scene.meshes if mesh.material.endswith("/thick"))
    fit = abs(np.linalg.det(thick.transform[:3, :3].astype(np.float64))) ** (1 / 3)
    assert abs(fit - 1) > 0.1
    np.testing.assert_allclose(scene.materials[thick.material].absorption, np.log([2.0, 1.0, 4.0]) / 2.0 / fit,
                               rtol=1e-5)


@pytest.mark.parametrize("extension", ["KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_texture_basisu"])
def test_a_gltf_file_that_requires_an_unread_encoding_is_refused_by_name(tmp_path, extension):
    """A file that lists in extensionsRequired an encoding not decoded here (trimesh would read its meshes as zeros)
    stops with one line naming it; listed only as used (the file carries a fallback), it loads."""
    path = _glb(tmp_path, [PBRMaterial(name="grey")])
    data = edit_glb_json(path.read_bytes(), lambda t: (t.update(extensionsUsed=[extension],
                                                                 extensionsRequired=[extension])))
    path.write_bytes(data)
    with pytest.raises(SceneError, match=rf"thing.glb: it needs the glTF extension {extension} \("):
        load_scene(_scene_file(tmp_path, {"file": path.name}))
    path.write_bytes(edit_glb_json(data, lambda t: t.pop("extensionsRequired")))
    assert load_scene(_scene_file(tmp_path, {"file": path.name})).meshes


def _second_set_glb(tmp_path, normal_set: int | None = None):
    """A box whose base colour texture is read at TEXCOORD_1 (each vertex at (0.1 + 0.01 i, 0.2) in glTF's
    coordinates, v down), TEXCOORD_0 being trimesh's own; with ``normal_set`` a normal texture too, at that set."""
    from gltf_files import with_accessors
    from PIL import Image

    box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    image = Image.fromarray(np.arange(48, dtype=np.uint8).reshape(4, 4, 3))
    material = PBRMaterial(name="painted", baseColorTexture=image, normalTexture=image if normal_set is not None
                           else None)
    box.visual = trimesh.visual.TextureVisuals(uv=np.zeros((len(box.vertices), 2)), material=material)
    scene = trimesh.Scene()
    scene.add_geometry(box, node_name="part0")
    second = np.column_stack([0.1 + 0.01 * np.arange(len(box.vertices)), np.full(len(box.vertices), 0.2)])

    def edit(tree, first):
        tree["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_1"] = first
        tree["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"] = 1
        if normal_set is not None:
            tree["materials"][0]["normalTexture"]["texCoord"] = normal_set

    data = with_accessors(scene.export(file_type="glb"), [second], edit)
    (tmp_path / "thing.glb").write_bytes(data)
    return tmp_path / "thing.glb", second


def test_textures_read_at_a_second_coordinate_set(tmp_path):
    """A material whose textures are read at TEXCOORD_1 takes those coordinates (v flipped as trimesh flips
    TEXCOORD_0's); textures at two sets are refused naming the material."""
    path, second = _second_set_glb(tmp_path)
    (mesh,) = load_scene(_scene_file(tmp_path, {"file": path.name})).meshes[1:]
    np.testing.assert_allclose(mesh.uvs, np.column_stack([second[:, 0], 1 - second[:, 1]]), atol=1e-6)
    path, _ = _second_set_glb(tmp_path, normal_set=1)
    (mesh,) = load_scene(_scene_file(tmp_path, {"file": path.name})).meshes[1:]
    assert mesh.normal_map is not None and np.allclose(mesh.uvs[:, 0], second[:, 0])
    path, _ = _second_set_glb(tmp_path, normal_set=0)
    with pytest.raises(SceneError, match=r"material 'painted': its textures are read at texture coordinate sets "
                                         r"baseColorTexture 1, normalTexture 0; the tracer reads one set"):
        load_scene(_scene_file(tmp_path, {"file": path.name}))
