"""Scenes: the data model, loaders (scene files, meshes) and the built-in scenes.

``load_scene(spec, mesh=None)`` is the one entry point: ``spec`` is a built-in name (see
``BUILTIN_SCENES``), a path to a .json/.toml scene file, a mesh file (the built-in ``mesh`` scene around it, in
its own materials; a glTF file with a camera is a scene of its own, ``gltf_scene``), or a ``Scene`` (returned as
is).
"""

from __future__ import annotations

from pathlib import Path

from ..errors import SceneError
from .builtin import BUILTIN_SCENES, builtin_scene
from .file_materials import GLTF_SUFFIXES
from .gltf_scene import gltf_scene
from .loader import SCENE_SUFFIXES, load_scene_file
from .meshio import MESH_SUFFIXES
from .model import Camera, DirectionalLight, Material, Mesh, PointLight, Scene, SpotLight


def load_scene(spec, mesh=None, camera: str | None = None, animation: str | None = None) -> Scene:
    """The Scene that ``spec`` names; ``mesh`` is the mesh file of the built-in 'mesh' scene; ``camera`` picks one
    of a glTF scene's cameras (``gltf_scene``), ``animation`` one of a glTF file's animations (by index or name;
    default: ``gltf_animation.read_animations``')."""
    if not isinstance(spec, (str, Path, Scene)):
        raise SceneError(f"a scene is a built-in name, a scene file path or a Scene, not {type(spec).__name__}")
    if mesh is not None and spec != "mesh":
        # Silently rendering the scene without the mesh would look like the mesh was lost.
        raise SceneError(f"{spec if isinstance(spec, (str, Path)) else 'a Scene object'}: takes no mesh file "
                         f"(mesh=/--mesh {mesh} is only for the built-in 'mesh' scene)")
    is_gltf = isinstance(spec, (str, Path)) and Path(spec).suffix.lower() in GLTF_SUFFIXES
    if camera is not None and not is_gltf:
        raise SceneError(f"{spec if isinstance(spec, (str, Path)) else 'a Scene object'}: a camera choice "
                         f"(camera=/--camera {camera}) is for a glTF file with cameras")
    animates_gltf = is_gltf or (spec == "mesh" and mesh is not None and Path(mesh).suffix.lower() in GLTF_SUFFIXES)
    if animation is not None and not animates_gltf:
        raise SceneError(f"{spec if isinstance(spec, (str, Path)) else 'a Scene object'}: an animation choice "
                         f"(animation=/--animation {animation}) is for a glTF file (a scene file's mesh entry takes "
                         f"an 'animation' key)")
    if isinstance(spec, Scene):
        return spec
    if isinstance(spec, str) and spec in BUILTIN_SCENES:
        return builtin_scene(spec, mesh=mesh, animation=animation)
    if Path(spec).suffix.lower() in MESH_SUFFIXES:
        own = gltf_scene(spec, camera, animation) if is_gltf else None
        if own is None and camera is not None:
            raise SceneError(f"{spec}: has no camera for camera=/--camera {camera} to pick")
        return own or builtin_scene("mesh", mesh=spec, animation=animation)
    if Path(spec).suffix.lower() in SCENE_SUFFIXES or Path(spec).exists():
        return load_scene_file(spec)
    raise SceneError(f"{spec}: neither a built-in scene ({', '.join(sorted(BUILTIN_SCENES))}), "
                     f"a .json/.toml scene file nor a mesh file ({', '.join(MESH_SUFFIXES)})")


__all__ = ["BUILTIN_SCENES", "Camera", "DirectionalLight", "Material", "Mesh", "PointLight", "Scene", "SpotLight",
           "load_scene"]
