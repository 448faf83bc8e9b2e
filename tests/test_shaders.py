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
