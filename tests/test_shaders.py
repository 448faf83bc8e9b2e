"""Every WGSL module compiles (naga validation through create_shader_module), and so does every
specialization of the path-tracing kernel the renderer can request (override constants are applied at
pipeline creation), so a shader error fails the suite with the compiler's message."""

import re

import pytest

from wgpu_rt import shaders


# Modules with {{PLACEHOLDER}}s (array or workgroup sizes) compile with each placeholder set to 1.
PLACEHOLDERS = {key: 1 for name in shaders.list_wgsl()
                for key in re.findall(r"\{\{(\w+)\}\}", shaders.read_wgsl(name))}


@pytest.mark.parametrize("name", shaders.list_wgsl())
def test_module_compiles(gpu, name):
    gpu.device.create_shader_module(code=shaders.compose(name, substitutions=PLACEHOLDERS), label=name)


def test_every_trace_specialization_builds(gpu):
    from wgpu_rt.trace.features import SceneFeatures
    from wgpu_rt.trace.trace_pass import trace_pipeline

    for features in SceneFeatures.all_combinations():
        assert trace_pipeline(gpu, features, geometry_bindings=4) is not None, features


@pytest.mark.parametrize("walk", ["threaded", "wide"])
@pytest.mark.parametrize("swaps", ["cutouts", "emission textures", "rough coats", "absorbing glass", "panes",
                                   "metal-rough maps", "all"])
def test_every_swapped_in_module_builds_with_each_walk(gpu, walk, swaps):
    """Scenes with cut-out surfaces swap trace/cutouts.wgsl into the walks' triangle test, scenes whose lights have
    emission textures trace/emission_textures.wgsl into the light sampling, scenes with a rough coat
    trace/coats_rough.wgsl into the plastic, scenes with absorbing glass trace/interior_absorbing.wgsl into the path's
    throughput, scenes with thin panes trace/shadow_panes.wgsl into the walks' shadow test, scenes with metal-rough
    maps trace/metal_rough_maps.wgsl into the hit's material: the kernel builds so with both walks, every feature on
    and every feature off."""
    from wgpu_rt.accel.geometry import BVH_LAYOUTS, NO_CUTOUTS, THREADED_WALK
    from wgpu_rt.trace.features import SceneFeatures
    from wgpu_rt.trace.trace_pass import (ABSORBING_INTERIORS, CLEAR_INTERIORS, CUTOUTS, EMISSION_TEXTURES,
                                          METAL_ROUGH_MAPS, NO_METAL_ROUGH_MAPS, NO_PANES, PLAIN_EMISSION, ROUGH_COATS,
                                          SHADOW_PANES, SMOOTH_COATS, trace_pipeline)

    modules = {THREADED_WALK: BVH_LAYOUTS[walk]}
    if swaps in ("cutouts", "all"):
        modules[NO_CUTOUTS] = CUTOUTS
    if swaps in ("emission textures", "all"):
        modules[PLAIN_EMISSION] = EMISSION_TEXTURES
    if swaps in ("rough coats", "all"):
        modules[SMOOTH_COATS] = ROUGH_COATS
    if swaps in ("absorbing glass", "all"):
        modules[CLEAR_INTERIORS] = ABSORBING_INTERIORS
    if swaps in ("panes", "all"):
        modules[NO_PANES] = SHADOW_PANES
    if swaps in ("metal-rough maps", "all"):
        modules[NO_METAL_ROUGH_MAPS] = METAL_ROUGH_MAPS
    for features in (SceneFeatures.everything(), SceneFeatures.all_combinations()[0]):
        assert trace_pipeline(gpu, features, geometry_bindings=4, geometry_modules=modules) is not None
