"""Instancing: a shape placed N times (Mesh.instance, the scene files' `instances`) against the same scene
written out with N copied meshes. Prints, for both: the triangles and bytes of bind group 0 (what the GPU
holds of the geometry), the geometry build time (BVH, CPU), the time to set a trace pass up (the
geometry's build and upload plus the tracer's emitter tables, kernels already compiled) and the
median trace time of a frame, wall-clock and CPU (the process's, all driver threads: steadier on a
shared machine), the two scenes alternating; then the instanced/expanded ratios of the run.

    python3 benchmarks/bench_instances.py --count 1000 --subdivisions 3 --size 64x64 --spp 4
    python3 benchmarks/bench_instances.py --scene examples/forest.toml --size 96x64 --spp 4
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import resource
import shlex
import sys
import time

import numpy as np
import trimesh

from wgpu_rt.accel.geometry import GeometryBuffers, InstancedGeometry
from wgpu_rt.gpu import get_context
from wgpu_rt.passes import FrameBuffers
from wgpu_rt.scene import Camera, DirectionalLight, Material, Mesh, Scene, load_scene
from wgpu_rt.scene.primitives import primitive
from wgpu_rt.scene.transforms import compose, rotate, scale, translate
from wgpu_rt.trace import SampleSchedule, TracePass

SUN = np.array([-0.3, -1, -0.2], np.float32)


def grid_scene(count: int, subdivisions: int) -> Scene:
    """A floor and an icosphere placed ``count`` times on a square grid, in two materials."""
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
    vertices = np.asarray(sphere.vertices, np.float32)
    ball = Mesh("ball", vertices, np.asarray(sphere.faces, np.uint32), "grey", normals=vertices.copy())
    side = int(np.ceil(np.sqrt(count)))
    balls = [ball.instance(f"ball[{i}]", "red" if i % 3 == 0 else None,
                           compose(translate([i % side - side / 2, 0.4, i // side - side / 2]),
                                   rotate([0, 1, 0], 7 * i), scale(0.4))) for i in range(count)]
    floor = Mesh("floor", *primitive("rectangle")[:2], "grey",
                 transform=compose(rotate([1, 0, 0], -90), scale(side)))
    return Scene(Camera([0, 0.4 * side, 0.9 * side], [0, 0, 0]), [floor, *balls],
                 {"grey": Material(), "red": Material(reflectance=(0.8, 0.1, 0.1))},
                 lights=[DirectionalLight(SUN / np.linalg.norm(SUN), np.array([2, 2, 2], np.float32))],
                 background=np.array([0.2, 0.25, 0.3], np.float32), name="sphere grid")


def copied(scene: Scene) -> Scene:
    """``scene`` with every mesh holding arrays of its own (no instances)."""
    return dataclasses.replace(scene, meshes=[
        Mesh(m.name, m.vertices.copy(), m.faces.copy(), m.material, None if m.normals is None else m.normals.copy(),
             m.transform.copy(), dict(m.keyframes)) for m in scene.meshes])


def set_up(ctx, scene: Scene, build, size: tuple[int, int]) -> dict:
    """Geometry build and trace pass set-up of ``scene`` with ``build`` (timed)."""
    started = time.perf_counter()
    geometry = build(scene)
    built = time.perf_counter() - started
    trace = TracePass(ctx, scene, geometry, *size, max_depth=4)
    arrays = geometry.packed_arrays(geometry.orderings(ctx))
    return {"stored": geometry.triangle_count, "placed": len(geometry.material_ids),
            "bytes": sum(a.nbytes for a in arrays), "build": built, "setup": time.perf_counter() - started,
            "trace_pass": trace, "buffers": FrameBuffers(ctx, *size), "times": [], "cpu": []}


def trace_frame(ctx, run: dict, spp: int) -> None:
    """One frame of ``spp`` samples, timed from submission until its planes can be read."""
    encoder = ctx.device.create_command_encoder()
    run["trace_pass"].clear(encoder, run["buffers"])
    run["trace_pass"].execute(encoder, run["buffers"], SampleSchedule(samples=spp))
    started, cpu = time.perf_counter(), resource.getrusage(resource.RUSAGE_SELF)
    ctx.device.queue.submit([encoder.finish()])
    run["mean"] = float(run["buffers"].read("radiance").mean())
    used = resource.getrusage(resource.RUSAGE_SELF)
    run["times"].append(time.perf_counter() - started)
    run["cpu"].append(used.ru_utime + used.ru_stime - cpu.ru_utime - cpu.ru_stime)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=1000, help="placements of the shape")
    parser.add_argument("--subdivisions", type=int, default=3, help="icosphere subdivisions (20·4^s triangles)")
    parser.add_argument("--scene", help="a scene file with instances to use instead of the grid of spheres")
    parser.add_argument("--size", default="64x64")
    parser.add_argument("--spp", type=int, default=4)
    parser.add_argument("--frames", type=int, default=5, help="timed frames of each (after a warm-up)")
    args = parser.parse_args()
    size = tuple(int(x) for x in args.size.split("x"))
    ctx = get_context()
    print("command: " + shlex.join(["python3", os.path.relpath(sys.argv[0])] + sys.argv[1:]))
    print(f"adapter: {ctx.label}")
    small = grid_scene(4, 1)      # compiles both kernels before anything is timed
    for build, scene in ((InstancedGeometry, small), (GeometryBuffers.build, copied(small))):
        trace_frame(ctx, set_up(ctx, scene, build, (8, 8)), 1)
    scene = load_scene(args.scene) if args.scene else grid_scene(args.count, args.subdivisions)
    results = {"instanced": set_up(ctx, scene, InstancedGeometry, size),
               "expanded": set_up(ctx, copied(scene), GeometryBuffers.build, size)}
    for _ in range(args.frames + 1):     # alternating, so both see the same machine load
        for run in results.values():
            trace_frame(ctx, run, args.spp)
    for run in results.values():
        run["trace"] = float(np.median(run["times"][1:]))     # the first frame is a warm-up
        run["trace_cpu"] = float(np.median(run["cpu"][1:]))
    shapes = [f"{len(group)} placements of a {len(scene.meshes[group[0]].faces)}-triangle shape"
              for group in scene.shapes() if len(group) > 1]
    print(f"{scene.name}: {', '.join(shapes)}; {size[0]}x{size[1]}, {args.spp} spp per frame, max depth 4")
    print(f"{'':10s} {'triangles stored':>17s} {'placed':>9s} {'group 0 MiB':>12s} {'BVH build s':>12s} "
          f"{'set-up s':>9s} {'trace ms':>9s} {'CPU ms':>7s} {'mean radiance':>14s}")
    for name, r in results.items():
        print(f"{name:10s} {r['stored']:17d} {r['placed']:9d} {r['bytes'] / 2 ** 20:12.1f} {r['build']:12.2f} "
              f"{r['setup']:9.2f} {1000 * r['trace']:9.1f} {1000 * r['trace_cpu']:7.0f} {r['mean']:14.5f}")
    a, b = results["instanced"], results["expanded"]
    print(f"instanced / expanded: bytes {a['bytes'] / b['bytes']:.4f}, build {a['build'] / b['build']:.3f}, "
          f"set-up {a['setup'] / b['setup']:.3f}, trace {a['trace'] / b['trace']:.2f} (CPU time "
          f"{a['trace_cpu'] / b['trace_cpu']:.2f})")


if __name__ == "__main__":
    main()
