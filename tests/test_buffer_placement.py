"""Uniform-buffer placement of the tracer's tables (wgpu_rt.trace.trace_pass.BufferPlacement): the
kernels composed with wgsl/trace/shading_tables_uniform.wgsl and wgsl/accel/geometry_words_uniform.wgsl read the
same records as the storage-buffer kernel (validated against Mitsuba 3 in test_mitsuba.py), so every
placement must give the storage placement's image bit for bit; scenes beyond a uniform capacity keep
storage buffers."""

import itertools

import pytest

from wgpu_rt.accel.bvh import ORDERINGS
from wgpu_rt.passes import FrameBuffers
from wgpu_rt.scene import load_scene
from wgpu_rt.accel.geometry import UNIFORM_GEOMETRY_BYTES, GeometryBuffers
from wgpu_rt.trace.trace_pass import BufferPlacement, SampleSchedule, TracePass

SIZE = (24, 24)
PLANES = ("radiance", "albedo", "normal", "depth", "motion", "spp")


def _planes(gpu, scene, geometry, placement):
    trace = TracePass(gpu, scene, geometry, *SIZE, frame=1, placement=placement)
    buffers = FrameBuffers(gpu, *SIZE)
    encoder = gpu.device.create_command_encoder()
    trace.clear(encoder, buffers)
    trace.execute(encoder, buffers, SampleSchedule(samples=3))
    gpu.device.queue.submit([encoder.finish()])
    return {name: buffers.read(name) for name in PLANES}


@pytest.mark.parametrize("scene_name", ["cornell", "moving", "sun-room"])
def test_every_placement_gives_the_storage_image(gpu, scene_name):
    scene = load_scene(scene_name)
    geometry = GeometryBuffers.build(scene)
    assert geometry.fits_uniform
    reference = _planes(gpu, scene, geometry, BufferPlacement())
    assert reference["radiance"].mean() > 0.01
    for tables, in_uniform_geometry in itertools.product((False, True), repeat=2):
        planes = _planes(gpu, scene, geometry, BufferPlacement(tables, in_uniform_geometry))
        for name in PLANES:
            assert planes[name].tobytes() == reference[name].tobytes(), (scene_name, tables, in_uniform_geometry, name)


def test_large_geometry_stays_in_storage_buffers(gpu):
    scene = load_scene("cornell-glossy")
    geometry = GeometryBuffers.build(scene)
    assert geometry.packed_arrays()[1].nbytes > UNIFORM_GEOMETRY_BYTES
    assert not geometry.fits_uniform
    trace = TracePass(gpu, scene, geometry, *SIZE)
    assert trace.placement == BufferPlacement(tables=True, geometry=False)
    with pytest.raises(ValueError, match="capacity"):
        TracePass(gpu, scene, geometry, *SIZE, placement=BufferPlacement(geometry=True))
    nodes = geometry.packed_arrays()[0]   # bvh_node_count() (geometry_words*.wgsl) reads the root's skip
    assert nodes[0]["skip"] * ORDERINGS == len(nodes)
