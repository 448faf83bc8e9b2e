"""Scenes: the data model, loaders (scene files, meshes) and the built-in scenes."""

from .model import Camera, DirectionalLight, Material, Mesh, PointLight, Scene

__all__ = ["Camera", "DirectionalLight", "Material", "Mesh", "PointLight", "Scene"]
