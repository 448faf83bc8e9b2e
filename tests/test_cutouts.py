"""Cut-out surfaces: an (H, W, 4) texture's alpha cuts its mesh away where a bilinear sample of it is below one
half (wgsl/trace/cutouts.wgsl, tested by the walks for closest-hit and shadow rays alike; numpy reference
``sample_alpha``), or with ``alpha_mode`` "blend" is there with probability alpha; loaded from glTF MASK and BLEND
materials, OBJ ``map_d`` and a scene file's ``alpha_mode``/``alpha_cutoff``. Mitsuba's agreement
(its ``mask`` under ``volpath``) is in tests/test_mitsuba.py."""

import json

import numpy as np
import pytest
import trimesh
from PIL import Image
from trimesh.visual.material import PBRMaterial

from wgpu_rt import renderer as renderer_module
from wgpu_rt.errors import SceneError
from wgpu_rt.renderer import render
from wgpu_rt.scene import Camera, Material, Mesh, PointLight, Scene, load_scene
from wgpu_rt.scene.meshio import load_mesh_file
from wgpu_rt.scene.model import CUTOUT_ALPHA, sample_alpha
from wgpu_rt.scene.primitives import primitive
from wgpu_rt.scene.transforms import rotate, scale, translate

CHECKER = 4     # texels a side


def _square(name: str, material: str, transform, texture=None, emission_texture=None) -> Mesh:
    """The rectangle primitive ([-1, 1]² at z = 0) placed by ``transform``, its coordinates (x + 1) / 2 where it
    has an image."""
    vertices, faces, normals = primitive("rectangle")
    imaged = texture is not None or emission_texture is not None
    return Mesh(name, vertices, faces, material, normals=normals, transform=np.asarray(transform, np.float32),
                texture=texture, uvs=((vertices[:, :2] + 1) / 2).astype(np.float32) if imaged else None,
                emission_texture=emission_texture)


def _head_on() -> Camera:
    """A camera from z = 2 whose view (fov along x) the untransformed ``_square`` fills exactly."""
    return Camera([0, 0, 2], [0, 0, 0], fov=float(2 * np.degrees(np.arctan(0.5))), fov_axis="x")


def _checker(alpha: bool = True) -> np.ndarray:
    """A white CHECKER² texture whose alpha keeps the texels with an even row + column."""
    kept = (np.add.outer(np.arange(CHECKER), np.arange(CHECKER)) % 2) == 0
    image = np.full((CHECKER, CHECKER, 4 if alpha else 3), 255, np.uint8)
    if alpha:
        image[..., 3] = np.where(kept, 255, 0)
    return image


def _scene(name: str, panels: list[Mesh]) -> Scene:
    """``panels`` (white) over a red floor, lit by a point light in front, so the holes show the floor and
    let light through onto it."""
    floor = _square("floor", "red", translate([0, 0, -1]) @ scale(3))
    materials = {"red": Material("diffuse", reflectance=[0.8, 0.2, 0.2]), "white": Material("diffuse", reflectance=0.8)}
    return Scene(Camera([0.3, 0.4, 3], [0, 0, 0], fov=50), [floor, *panels], materials,
                 lights=[PointLight(np.float32([0.5, 0.8, 2.5]), np.float32([8, 8, 8]))], name=name)


def _kept_squares(placement) -> list[Mesh]:
    """The checker's kept texels as squares of geometry, placed as the cut-out panel is by ``placement``."""
    squares = []
    for row in range(CHECKER):
        for column in range(CHECKER):
            if (row + column) % 2 == 0:
                centre = [(column + 0.5) / CHECKER * 2 - 1, 1 - (row + 0.5) / CHECKER * 2, 0]   # row 0 at the top
                squares.append(_square(f"kept{row}-{column}", "white",
                                       placement @ translate(centre) @ scale(1 / CHECKER)))
    return squares


def test_a_cut_out_checkerboard_is_the_squares_it_keeps(gpu):
    """Bilinear alpha of a 0/1 checker crosses one half exactly on the texel edges, so a panel cut out by it is
    the kept squares as geometry: seen and casting its shadow alike, sample for sample; uncut, it is not."""
    options = dict(spp=8, size=(48, 48), max_depth=3, aovs=())
    cut = render(_scene("cut", [_square("panel", "white", np.eye(4), _checker())]), **options).color
    squares = render(_scene("squares", _kept_squares(np.eye(4))), **options).color
    whole = render(_scene("whole", [_square("panel", "white", np.eye(4), _checker(alpha=False))]), **options).color
    assert np.all(np.isfinite(cut))
    assert np.abs(cut - squares).mean() < 1e-4 * squares.mean()
    assert np.abs(whole - squares).mean() > 0.1 * squares.mean()


def test_instances_of_a_cut_out_panel_are_cut_alike(gpu, monkeypatch):
    """Placed twice (a two-level scene: each placement walks the one stored shape), both placements are cut."""
    monkeypatch.setattr(renderer_module, "FLATTEN_PLACED_TRIANGLES", 0)
    left, right = translate([-0.6, 0, 0]) @ scale(0.5), translate([0.6, 0.1, 0.2]) @ scale(0.5)
    panel = _square("panel", "white", left, _checker())
    options = dict(spp=8, size=(48, 48), max_depth=3, aovs=())
    cut = render(_scene("placed", [panel, panel.instance("again", transform=right)]), **options).color
    squares = render(_scene("squares", _kept_squares(left) + _kept_squares(right)), **options).color
    assert np.abs(cut - squares).mean() < 1e-3 * squares.mean()


def test_the_albedo_shows_the_surface_where_the_reference_keeps_it(gpu):
    """A panel that fills the view head-on, its alpha a ramp across and down: every pixel whose four corners
    ``sample_alpha`` keeps shows the panel's albedo, every pixel whose corners it all cuts the black behind."""
    size = 64
    ramp = np.full((3, 5, 4), 255, np.uint8)
    ramp[..., 3] = np.round(np.add.outer(np.linspace(0, 120, 3), np.linspace(0, 135, 5))).astype(np.uint8)
    panel = _square("panel", "white", np.eye(4), ramp)
    scene = Scene(_head_on(), [panel], {"white": Material("diffuse", reflectance=0.8)},
                  lights=[PointLight(np.float32([0, 0, 2]), np.float32([1, 1, 1]))])
    albedo = render(scene, spp=4, size=(size, size), max_depth=2, aovs=("albedo",)).aovs["albedo"][..., 0]
    edges = np.linspace(0, 1, size + 1)
    corners = sample_alpha(ramp, np.stack(np.meshgrid(edges, 1 - edges), -1).reshape(-1, 2)).reshape(size + 1,
                                                                                                   size + 1)
    kept = corners >= CUTOUT_ALPHA
    whole = kept[:-1, :-1] & kept[1:, :-1] & kept[:-1, 1:] & kept[1:, 1:]
    gone = ~(kept[:-1, :-1] | kept[1:, :-1] | kept[:-1, 1:] | kept[1:, 1:])
    assert whole.sum() > 200 and gone.sum() > 200
    np.testing.assert_allclose(albedo[whole], 0.8, atol=1e-4)
    np.testing.assert_allclose(albedo[gone], 0.0, atol=1e-6)


def test_a_blended_surface_is_there_as_often_as_its_alpha(gpu):
    """alpha_mode "blend": a point is there with probability alpha (a hash of the point decides), so a panel of
    alpha 0.3 that fills the view head-on over black shows 0.3 of its albedo on the mean, in every quarter."""
    texture = np.full((2, 2, 4), 255, np.uint8)
    texture[..., 3] = round(0.3 * 255)
    panel = _square("panel", "white", np.eye(4), texture)
    panel.alpha_mode = "blend"
    scene = Scene(_head_on(), [panel], {"white": Material("diffuse", reflectance=0.8)},
                  lights=[PointLight(np.float32([0, 0, 2]), np.float32([1, 1, 1]))])
    albedo = render(scene, spp=16, size=(64, 64), max_depth=2, aovs=("albedo",)).aovs["albedo"][..., 0]
    quarters = albedo.reshape(2, 32, 2, 32).mean((1, 3))
    np.testing.assert_allclose(quarters, 0.8 * texture[0, 0, 3] / 255, rtol=0.03)


FACING_FLOOR = rotate([1, 0, 0], 180)


def lamp_scene(panels: list[Mesh]) -> Scene:
    """Emissive ``panels`` (material "white": emission 2, placed by FACING_FLOOR to face it) over a red floor, seen
    from behind them: the floor shows their light, through their holes where they have any."""
    materials = {"red": Material("diffuse", reflectance=[0.8, 0.2, 0.2]),
                 "white": Material("diffuse", reflectance=0.5, emission=2.0)}
    floor = _square("floor", "red", translate([0, 0, -1]) @ scale(3))
    return Scene(Camera([0.3, 0.4, 3], [0, 0, 0], fov=50), [floor, *panels], materials, name="lamp")


def test_a_cut_out_emitter_lights_as_its_kept_part_alone(gpu):
    """An emissive checker panel facing the floor, its holes cut out, against its kept texels as emissive squares:
    a light sample that lands in a hole gives nothing (trace/emitters.wgsl) and paths pass through the holes, so the
    floor is lit alike (the panel's two triangles are sampled over their whole area, the squares over theirs: alike
    on the mean, 4×4 blocks within 4 %, the whole image within 1.5 %); the panel uncut gives more light."""
    def lit(panels):
        return render(lamp_scene(panels), spp=256, size=(32, 32), max_depth=3, aovs=()).color

    cut = lit([_square("panel", "white", FACING_FLOOR, _checker())])
    squares = lit(_kept_squares(FACING_FLOOR))
    whole = lit([_square("panel", "white", FACING_FLOOR, _checker(alpha=False))])
    assert np.all(np.isfinite(cut))
    blocks = [image.reshape(4, 8, 4, 8, 3).mean((1, 3)) for image in (cut, squares)]
    np.testing.assert_allclose(blocks[0], blocks[1], rtol=0.04, atol=0.01 * squares.mean())
    assert abs(cut.mean() / squares.mean() - 1) < 0.015
    assert abs(whole.mean() / squares.mean() - 1) > 0.2


def _leaf_glb(tmp_path, mode: str, cutoff=None, factor_alpha: float = 1.0):
    """A .glb box with a base colour texture whose alpha ramps 0 … 255 in sixteen steps."""
    rgba = np.zeros((4, 4, 4), np.uint8)
    rgba[..., :3] = 200
    rgba[..., 3] = np.arange(16).reshape(4, 4) * 17
    material = PBRMaterial(name="leaf", baseColorTexture=Image.fromarray(rgba, "RGBA"), alphaMode=mode,
                           alphaCutoff=cutoff, baseColorFactor=[1.0, 1.0, 1.0, factor_alpha])
    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(uv=np.random.default_rng(1).random((8, 2)), material=material)
    box.export(tmp_path / "leaf.glb")
    return tmp_path / "leaf.glb", rgba[..., 3].astype(np.float64)


@pytest.mark.parametrize("cutoff, factor_alpha", [(None, 1.0), (0.3, 1.0), (0.5, 0.6)])
def test_a_gltf_mask_materials_alpha_cuts_at_its_cutoff(tmp_path, cutoff, factor_alpha):
    """glTF MASK: kept where the texture's alpha times the base colour factor's reaches alphaCutoff (default ½),
    shifted so that the cutoff falls at the tracer's one half; BLEND: that alpha as it is, blended; OPAQUE keeps
    the whole surface."""
    path, alpha = _leaf_glb(tmp_path, "MASK", cutoff, factor_alpha)
    (mesh,) = load_mesh_file(path, "paint")
    assert mesh.is_cut_out
    expected_kept = alpha / 255 * factor_alpha >= (0.5 if cutoff is None else cutoff) - 1e-3
    np.testing.assert_array_equal(mesh.texture[..., 3] >= 255 * CUTOUT_ALPHA, expected_kept)
    assert mesh.alpha_mode == "mask"
    path, _ = _leaf_glb(tmp_path, "OPAQUE")
    assert load_mesh_file(path, "paint")[0].texture.shape[2] == 3
    path, alpha = _leaf_glb(tmp_path, "BLEND", factor_alpha=factor_alpha)
    (blended,) = load_mesh_file(path, "paint")
    assert blended.alpha_mode == "blend"
    np.testing.assert_allclose(blended.texture[..., 3], alpha * factor_alpha, atol=1.0)


def test_a_scene_files_alpha_cutoff(tmp_path):
    """A mesh entry's ``alpha_cutoff`` reads its texture's alpha; without a texture, or out of [0, 1], it is
    refused by field."""
    rgba = np.full((2, 2, 4), 255, np.uint8)
    rgba[0, 0, 3] = 40
    Image.fromarray(rgba, "RGBA").save(tmp_path / "leaf.png")
    entry = {"shape": "rectangle", "material": "white", "texture": "leaf.png", "alpha_cutoff": 0.3}
    data = {"camera": {"origin": [0, 0, 3], "target": [0, 0, 0]}, "materials": {"white": {}}, "meshes": [entry]}

    def load():
        (tmp_path / "scene.json").write_text(json.dumps(data))
        return load_scene(tmp_path / "scene.json")

    texture = load().meshes[0].texture
    assert texture.shape == (2, 2, 4) and texture[0, 0, 3] < 128 and np.all(texture.reshape(-1, 4)[1:, 3] >= 128)
    entry["alpha_cutoff"] = 0.1                                         # 40 / 255 is above: nothing cut
    assert load().meshes[0].texture.shape == (2, 2, 3)
    entry["alpha_cutoff"] = 1.5
    with pytest.raises(SceneError, match=r"meshes\[0\]\.alpha_cutoff: expected a number in \[0, 1\]"):
        load()
    del entry["alpha_cutoff"]
    entry["alpha_mode"] = "blend"                                       # the alpha as it is
    blended = load().meshes[0]
    assert blended.alpha_mode == "blend" and blended.texture[0, 0, 3] == 40
    entry["alpha_cutoff"] = 0.5
    with pytest.raises(SceneError, match=r"meshes\[0\]\.alpha_cutoff: a cutoff is for alpha_mode \"mask\""):
        load()
    entry["alpha_mode"] = "mask"
    del entry["texture"]
    entry["alpha_cutoff"] = 0.5
    with pytest.raises(SceneError, match=r"meshes\[0\]\.alpha_mode: a cutout needs a 'texture'"):
        load()


def _obj_with_mask(tmp_path, statements: str, mask: np.ndarray):
    (tmp_path / "leaf.obj").write_text("mtllib leaf.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                       "usemtl m\nf 1/1 2/2 3/3\n")
    (tmp_path / "leaf.mtl").write_text("newmtl m\nKd 0.5 0.5 0.5\n" + statements)
    Image.fromarray(mask).save(tmp_path / "mask.png")
    return tmp_path / "leaf.obj"


def test_an_obj_materials_map_d_cuts_it_out(tmp_path):
    """An OBJ material's ``map_d`` (its grey level, or an alpha channel where it has one) cuts the surface away
    below one half, read at the colour image's size (white where the material has none); a missing file is
    refused by name."""
    grey = np.zeros((8, 8), np.uint8)
    grey[:, 4:] = 255                                            # the right half kept
    Image.fromarray(np.full((4, 4, 3), 200, np.uint8)).save(tmp_path / "colour.png")
    (mesh,) = load_mesh_file(_obj_with_mask(tmp_path, "map_Kd colour.png\nmap_d -imfchan m mask.png\n", grey), "x")
    assert mesh.texture.shape == (4, 4, 4)
    np.testing.assert_array_equal(mesh.texture[..., :3], 200)
    np.testing.assert_array_equal(mesh.texture[..., 3] >= 128, np.tile([False, False, True, True], (4, 1)))
    (bare,) = load_mesh_file(_obj_with_mask(tmp_path, "map_d mask.png\n", grey), "x")
    assert bare.texture.shape == (8, 8, 4) and np.all(bare.texture[..., :3] == 255)
    rgba = np.zeros((2, 2, 4), np.uint8)
    rgba[..., 3] = [[0, 255], [255, 255]]                         # alpha, where the image has one, not grey
    (alpha,) = load_mesh_file(_obj_with_mask(tmp_path, "map_d mask.png\n", rgba), "x")
    np.testing.assert_array_equal(alpha.texture[..., 3] >= 128, [[False, True], [True, True]])
    (tmp_path / "mask.png").unlink()
    with pytest.raises(SceneError, match=r"leaf\.obj.*its material's map_d: .*mask\.png: texture image not found"):
        load_mesh_file(tmp_path / "leaf.obj", "x")


@pytest.mark.parametrize("mode, factor_alpha, kept", [("BLEND", 0.3, None), ("MASK", 0.3, False), ("MASK", 0.8, True)])
def test_a_gltf_materials_own_alpha_cuts_it_without_a_texture(tmp_path, mode, factor_alpha, kept):
    """A MASK or BLEND material with no base colour texture: its base colour factor's alpha, as a white 1×1
    texture read anywhere (BLEND: there with that probability; MASK: cut away everywhere below the cutoff, the
    whole surface kept above it, no texture then)."""
    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(material=PBRMaterial(
        name="pane", baseColorFactor=[0.8, 0.9, 1.0, factor_alpha], alphaMode=mode))
    box.export(tmp_path / "pane.glb")
    (mesh,) = load_mesh_file(tmp_path / "pane.glb", "x")
    if kept:
        assert mesh.texture is None
        return
    assert mesh.texture.shape == (1, 1, 4) and np.all(mesh.texture[..., :3] == 255)
    assert mesh.alpha_mode == mode.lower() and mesh.uvs.shape == (len(mesh.vertices), 2)
    if mode == "BLEND":
        assert mesh.texture[0, 0, 3] == round(factor_alpha * 255)
    else:
        assert mesh.texture[0, 0, 3] < 255 * CUTOUT_ALPHA
