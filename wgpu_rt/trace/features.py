"""Which parts of the path-tracing kernel a scene needs.

The kernel (wgsl/trace/trace.wgsl) has one override constant per optional feature (wgsl/trace/features.wgsl).
``SceneFeatures.of(scene)`` reads them off a scene; ``constants()`` turns them into pipeline override
constants, so each distinct feature set compiles (once, cached by GpuContext) to a kernel without the
code it cannot reach.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import numpy as np

from ..scene.model import Scene
from .scene_data import emitter_group_count


@dataclass(frozen=True)
class SceneFeatures:
    has_dielectric: bool = True      # any glass (thin too), or a plastic's coat
    has_conductor: bool = True
    has_area_lights: bool = True
    has_analytic_lights: bool = True  # point or directional lights, or a non-black background
    has_emitter_groups: bool = True   # lights in more than one emitter group (scene_data.emitter_group_count)
    has_motion: bool = True
    has_vertex_normals: bool = True   # any mesh with its own vertex normals (smooth shading)
    has_surface_colors: bool = True   # any mesh with vertex colours or a texture
    has_normal_maps: bool = True      # any mesh with a normal map
    write_aovs: bool = True

    @classmethod
    def of(cls, scene: Scene, write_aovs: bool = True) -> "SceneFeatures":
        used = {mesh.material for mesh in scene.meshes}
        kinds = {scene.materials[name].kind for name in used}
        if any(mesh.metal_rough_map is not None and scene.materials[mesh.material].kind == "plastic"
               for mesh in scene.meshes):
            kinds.add("conductor")      # each point of a plastic under a metal-rough map may be glTF's metal instead
        return cls(
            has_dielectric=bool({"dielectric", "thin_dielectric", "plastic"} & kinds),
            has_conductor="conductor" in kinds,
            has_area_lights=any(scene.materials[name].is_emissive for name in used),
            has_analytic_lights=bool(scene.lights) or bool(np.any(np.asarray(scene.background) > 0)),
            has_emitter_groups=emitter_group_count(scene) > 1,
            has_motion=scene.has_motion,
            has_vertex_normals=any(mesh.normals is not None for mesh in scene.meshes),
            has_surface_colors=any(mesh.colors is not None or mesh.texture is not None for mesh in scene.meshes),
            has_normal_maps=any(mesh.normal_map is not None for mesh in scene.meshes),
            write_aovs=write_aovs,
        )

    @classmethod
    def everything(cls) -> "SceneFeatures":
        """The unspecialized kernel (every switch on)."""
        return cls()

    @classmethod
    def all_combinations(cls) -> list["SceneFeatures"]:
        """Every feature set the renderer can request (the shader tests compile each)."""
        names = [f.name for f in fields(cls)]
        return [cls(**{n: bool(bits >> i & 1) for i, n in enumerate(names)}) for bits in range(2 ** len(names))]

    def constants(self) -> dict[str, bool]:
        """Pipeline override constants, named as in wgsl/trace/features.wgsl."""
        return {name.upper(): value for name, value in asdict(self).items()}
