"""Scenes built in Blender and rendered by Cycles to the multilayer EXR a Blender user has (Combined plus the
view layer's Denoising Data passes), for benchmarks/bench_blender.py. Runs inside a Python that imports
``bpy`` (``pip install bpy`` in a virtual environment of its own: Blender's module pins its own Python):

    PYTHON_WITH_BPY benchmarks/blender_scenes.py SCENE SPP SEED OUT.exr [--size N] [--threads N]

SCENE is one of SCENES. Every scene is made of Blender's own primitives and procedural textures, none of
them from wgpu-rt's worlds, so the denoiser meets another renderer's conventions and geometry at once.
"""

from __future__ import annotations

import argparse
import math

import bpy

SCENES = ("glass-monkey", "dark-room", "sun-metals", "textured-studio")


def material(name: str, color=(0.8, 0.8, 0.8), roughness: float = 0.5, metallic: float = 0.0,
             transmission: float = 0.0, emission: float = 0.0, texture: str | None = None):
    """A Principled BSDF material; ``texture``: "checker" or "noise" drives its base colour."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    bsdf = nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Transmission Weight"].default_value = transmission
    if emission:
        bsdf.inputs["Emission Color"].default_value = (*color, 1.0)
        bsdf.inputs["Emission Strength"].default_value = emission
    if texture == "checker":
        node = nodes.new("ShaderNodeTexChecker")
        node.inputs["Scale"].default_value = 8.0
        node.inputs["Color1"].default_value = (*color, 1.0)
        node.inputs["Color2"].default_value = (0.08, 0.08, 0.1, 1.0)
        mat.node_tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
    elif texture == "noise":
        noise = nodes.new("ShaderNodeTexNoise")
        noise.inputs["Scale"].default_value = 6.0
        ramp = nodes.new("ShaderNodeValToRGB")
        ramp.color_ramp.elements[0].color = (0.05, 0.15, 0.05, 1.0)
        ramp.color_ramp.elements[1].color = (*color, 1.0)
        mat.node_tree.links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
        mat.node_tree.links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def add(kind: str, mat, smooth: bool = True, **placement):
    getattr(bpy.ops.mesh, f"primitive_{kind}_add")(**placement)
    obj = bpy.context.object
    if smooth:
        bpy.ops.object.shade_smooth()
    obj.data.materials.append(mat)
    return obj


def light(kind: str, location, energy: float, size: float = 0.5, rotation=(0.0, 0.0, 0.0), color=(1, 1, 1)):
    bpy.ops.object.light_add(type=kind, location=location, rotation=rotation)
    data = bpy.context.object.data
    data.energy, data.color = energy, color
    if kind == "AREA":
        data.size = size
    elif kind in ("POINT", "SPOT"):
        data.shadow_soft_size = size
    elif kind == "SUN":
        data.angle = size
    return bpy.context.object


def sky(color, strength: float):
    world = bpy.data.worlds.new("sky")
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (*color, 1.0)
    background.inputs["Strength"].default_value = strength
    bpy.context.scene.world = world


def camera(location, rotation_degrees, lens: float = 35.0):
    bpy.ops.object.camera_add(location=location, rotation=tuple(math.radians(a) for a in rotation_degrees))
    bpy.context.object.data.lens = lens
    bpy.context.scene.camera = bpy.context.object


def glass_monkey():
    """Open floor under a blue sky, a smooth glass sphere beside a red Suzanne, one tilted area light."""
    sky((0.3, 0.4, 0.6), 0.5)
    add("plane", material("floor", (0.7, 0.6, 0.5)), smooth=False, size=20)
    add("uv_sphere", material("glass", roughness=0.0, transmission=1.0), radius=1, location=(-1.2, 0, 1))
    add("monkey", material("red", (0.8, 0.1, 0.1), roughness=0.4), location=(1.3, 0.5, 1))
    light("AREA", (2, -2, 5), 800, size=1.0, rotation=(math.radians(20), 0, 0))
    camera((0, -7, 3.5), (68, 0, 0))


def dark_room():
    """A closed room lit by one small, bright lamp in a corner facing the ceiling: nearly all light is indirect."""
    walls = material("walls", (0.6, 0.55, 0.5), roughness=0.8)
    add("cube", walls, smooth=False, size=10, location=(0, 0, 2.5)).scale = (1, 1, 0.5)
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.flip_normals()
    bpy.ops.object.mode_set(mode="OBJECT")
    add("torus", material("teal", (0.1, 0.5, 0.5), roughness=0.3), location=(-1.5, 1.0, 0.25))
    add("cylinder", material("purple", (0.5, 0.2, 0.6)), location=(1.5, 1.5, 1.0), radius=0.6, depth=2.0)
    add("ico_sphere", material("white", (0.9, 0.9, 0.85), roughness=0.2), smooth=False, location=(0.2, -0.5, 0.6),
        radius=0.6, subdivisions=1)
    light("POINT", (-4.2, 4.2, 0.4), 300, size=0.05, color=(1.0, 0.85, 0.7))
    camera((3.5, -4.3, 2.5), (72, 0, 35), lens=24)


def sun_metals():
    """A low sun and a pale sky over a checkered ground: rough gold and copper, a mirror-smooth steel sphere."""
    sky((0.5, 0.6, 0.8), 0.8)
    add("plane", material("ground", (0.8, 0.8, 0.75), texture="checker"), smooth=False, size=30)
    add("uv_sphere", material("gold", (1.0, 0.77, 0.34), roughness=0.35, metallic=1.0), radius=0.9, location=(-1.5, 0, 0.9))
    add("monkey", material("copper", (0.95, 0.64, 0.54), roughness=0.2, metallic=1.0), location=(0.6, 1.2, 1.0))
    add("uv_sphere", material("steel", (0.9, 0.9, 0.9), roughness=0.02, metallic=1.0), radius=0.6, location=(1.8, -0.8, 0.6))
    light("SUN", (0, 0, 10), 4.0, size=math.radians(2), rotation=(math.radians(70), 0, math.radians(-40)),
          color=(1.0, 0.9, 0.75))
    camera((0, -8, 2.2), (80, 0, 0), lens=40)


def textured_studio():
    """A studio sweep with a glossy floor, noise-textured objects and an emissive panel in view."""
    sky((0.02, 0.02, 0.03), 1.0)
    add("plane", material("sweep", (0.35, 0.35, 0.4), roughness=0.15), smooth=False, size=20)
    add("cube", material("mossy", (0.6, 0.5, 0.2), texture="noise"), smooth=False, size=1.4, location=(-1.2, 0.3, 0.7))
    add("uv_sphere", material("marble", (0.85, 0.85, 0.9), roughness=0.25, texture="noise"), radius=0.8,
        location=(1.0, -0.2, 0.8))
    panel = add("plane", material("panel", (1.0, 0.95, 0.9), emission=6.0), smooth=False, size=1.5,
                location=(0.0, 3.0, 2.0))
    panel.rotation_euler = (math.radians(80), 0, 0)
    light("AREA", (-3, -2, 4), 400, size=2.0, rotation=(math.radians(40), math.radians(-30), 0))
    camera((0, -6.5, 2.5), (72, 0, 0), lens=38)


def render(scene_name: str, spp: int, seed: int, out: str, size: int, threads: int) -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    {"glass-monkey": glass_monkey, "dark-room": dark_room, "sun-metals": sun_metals,
     "textured-studio": textured_studio}[scene_name]()
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device, cycles.samples, cycles.seed = "CPU", spp, seed
    cycles.use_adaptive_sampling = cycles.use_denoising = False
    cycles.max_bounces = 8
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    if threads:
        scene.render.threads_mode, scene.render.threads = "FIXED", threads
    view_layer = scene.view_layers[0]
    view_layer.cycles.denoising_store_passes = True   # Denoising Albedo, Normal and Depth
    view_layer.use_pass_z = view_layer.use_pass_normal = True   # passes a user may have on as well
    settings = scene.render.image_settings
    settings.media_type = "MULTI_LAYER_IMAGE"
    settings.file_format, settings.color_depth = "OPEN_EXR_MULTILAYER", "32"
    scene.render.filepath = out
    bpy.ops.render.render(write_still=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", choices=SCENES)
    parser.add_argument("spp", type=int)
    parser.add_argument("seed", type=int)
    parser.add_argument("out")
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--threads", type=int, default=0, help="render threads (0: all)")
    args = parser.parse_args()
    render(args.scene, args.spp, args.seed, args.out, args.size, args.threads)


if __name__ == "__main__":
    main()
