"""Benchmark: a big mesh's load time and memory, VolPath against Cycles (not collected by pytest).

Suzanne with a Subdivision Surface modifier (level 5: ~1M triangles, 6: ~4M), smooth shaded, a
point light, 64x64 at 1 sample. Each engine renders the same scene in its own process (F12 via
bpy.ops.render.render): wall time of the render call (which includes evaluating the modifier,
exporting and building the BVH), peak resident memory above what the process held before the
render, and for VolPath the export (depsgraph -> arrays) and scene build (Accelerator: tables and
Embree BVH) separately. Kernels are loaded before the clock starts.

    python tests/benchmarks/bench_scene_load.py [--level 5] [--samples 1] [--repeats 5]

--repeats N runs both engines N times, alternating (the machine's load drifts), and reports the
medians, each run's times and the median of the paired VolPath / Cycles ratios.

With --instances N the mesh is one collection (Suzanne at --level; level 3 has 63k triangles)
instanced N times on a grid by empties, inside a box of fog (issue 13: memory and time should grow
with unique geometry, not with the instance count):

    python tests/benchmarks/bench_scene_load.py --instances 400 --level 3 --samples 4
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def _rss_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def child(engine: str, level: int, samples: int, instances: int = 0) -> dict:
    sys.path.insert(0, str(ROOT))
    import bpy

    import addon
    addon.register()
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = engine
    sc.render.resolution_x = sc.render.resolution_y = 64
    sc.render.resolution_percentage = 100
    if engine == "VOLPATH":
        sc.volpath.samples = samples
        import volpath_native
        volpath_native.warm_up()  # kernels ready before the clock starts
    else:
        sc.cycles.samples = samples
        sc.cycles.device = "CPU"
        sc.cycles.use_denoising = False
    bpy.ops.mesh.primitive_monkey_add()
    obj = bpy.context.active_object
    modifier = obj.modifiers.new("Subdivision", "SUBSURF")
    modifier.levels = modifier.render_levels = level
    bpy.ops.object.shade_smooth()
    if instances:
        _instance_grid(bpy, sc, obj, instances)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (0.0, -4.0, 0.0)
    cam.rotation_euler = (1.5708, 0.0, 0.0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    lamp.location = (0.0, -3.0, 2.0)
    sc.collection.objects.link(lamp)
    phases = {}
    if engine == "VOLPATH":  # time the two load phases inside the render
        from addon import export as export_package
        from volpath_native import integrator

        def timed(name, function):
            def wrapper(*args, **kwargs):
                start = time.perf_counter()
                try:
                    return function(*args, **kwargs)
                finally:
                    phases[name] = phases.get(name, 0.0) + time.perf_counter() - start
            return wrapper
        export_package.export_scene = timed("export", export_package.export_scene)  # engine imports it per render
        integrator.Integrator.__init__ = timed("build", integrator.Integrator.__init__)
    before = _rss_bytes()
    start = time.perf_counter()
    bpy.ops.render.render()
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    depsgraph = bpy.context.evaluated_depsgraph_get()
    triangles = sum(len(i.object.data.loop_triangles) for i in depsgraph.object_instances
                    if i.object.type == "MESH" and i.show_self and i.object.name != "Fog")
    return dict(engine=engine, seconds=seconds, peak_above_start=max(peak - before, 0), triangles=triangles, **phases)


def _instance_grid(bpy, sc, obj, count: int) -> None:
    """obj moved into a hidden collection, instanced `count` times on a square grid by empties,
    the whole grid inside a fog box seen by the camera."""
    import math
    source = bpy.data.collections.new("Suzannes")
    sc.collection.children.link(source)
    for collection in list(obj.users_collection):
        collection.objects.unlink(obj)
    source.objects.link(obj)
    sc.view_layers[0].layer_collection.children["Suzannes"].exclude = True
    side = math.ceil(math.sqrt(count))
    spacing = 2.4 / side
    for k in range(count):
        empty = bpy.data.objects.new(f"Instance{k}", None)
        empty.instance_type = "COLLECTION"
        empty.instance_collection = source
        empty.location = ((k % side - (side - 1) / 2) * spacing, 0.0, (k // side - (side - 1) / 2) * spacing)
        empty.scale = (0.4 * spacing,) * 3
        sc.collection.objects.link(empty)
    bpy.ops.mesh.primitive_cube_add(size=3.0)
    fog = bpy.context.active_object
    fog.name = "Fog"
    material = bpy.data.materials.new("Fog")
    material.use_nodes = True
    nodes = material.node_tree.nodes
    for node in list(nodes):
        if node.type == "BSDF_PRINCIPLED":
            nodes.remove(node)
    volume = nodes.new("ShaderNodeVolumePrincipled")
    volume.inputs["Density"].default_value = 0.1
    output = next(node for node in nodes if node.type == "OUTPUT_MATERIAL")
    material.node_tree.links.new(volume.outputs[0], output.inputs["Volume"])
    fog.data.materials.append(material)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--level", type=int, default=5)
    parser.add_argument("--samples", type=int, default=1)
    parser.add_argument("--instances", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=1, help="paired runs of both engines (medians reported)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print("RESULT " + json.dumps(child(args.child, args.level, args.samples, args.instances)), flush=True)
        os._exit(0)  # skip Blender's teardown
    samples = {"CYCLES": [], "VOLPATH": []}
    loads = []
    for _ in range(args.repeats):  # paired: both engines in each round, the load noted per round
        loads.append(os.getloadavg()[0])
        for engine in ("CYCLES", "VOLPATH"):
            row = run_child(engine, args)
            if row is None:
                return 1
            samples[engine].append(row)
    rows = {engine: _medians(runs) for engine, runs in samples.items()}
    cycles, volpath = rows["CYCLES"], rows["VOLPATH"]
    n = volpath["triangles"]
    what = f"{args.instances} instances of " if args.instances else ""
    print(f"{what}Suzanne, Subdivision level {args.level}: {n / 1e6:.2f}M triangles, 64x64, {args.samples} spp; "
          f"medians of {args.repeats} paired runs, load {min(loads):.1f}-{max(loads):.1f}")
    if args.repeats > 1:
        print("  each run, Cycles / VolPath seconds: " + ", ".join(
            f"{c['seconds']:.2f}/{v['seconds']:.2f}" for c, v in zip(samples["CYCLES"], samples["VOLPATH"])))
    print(f"  Cycles : render {cycles['seconds']:.2f} s, peak +{cycles['peak_above_start'] / 1e6:.0f} MB "
          f"({cycles['peak_above_start'] / n:.0f} bytes/triangle)")
    print(f"  VolPath: render {volpath['seconds']:.2f} s (export {volpath.get('export', 0):.2f} s, "
          f"scene build {volpath.get('build', 0):.2f} s), peak +{volpath['peak_above_start'] / 1e6:.0f} MB "
          f"({volpath['peak_above_start'] / n:.0f} bytes/triangle)")
    ratios = [v["seconds"] / c["seconds"] for c, v in zip(samples["CYCLES"], samples["VOLPATH"])]
    print(f"  VolPath / Cycles: time {float(np.median(ratios)):.2f}x (median of the paired ratios), "
          f"memory {volpath['peak_above_start'] / max(cycles['peak_above_start'], 1):.2f}x")
    return 0


def run_child(engine: str, args) -> dict | None:
    proc = subprocess.run([sys.executable, __file__, "--child", engine, "--level", str(args.level),
                           "--samples", str(args.samples),
                           "--instances", str(args.instances)], capture_output=True, text=True)
    line = [l for l in proc.stdout.splitlines() if l.startswith("RESULT ")]
    if proc.returncode != 0 or not line:
        print(f"{engine} failed:\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
        return None
    return json.loads(line[0][len("RESULT "):])


def _medians(runs: list) -> dict:
    out = dict(runs[0])
    for key, value in runs[0].items():
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            out[key] = float(np.median([run[key] for run in runs]))
    return out


if __name__ == "__main__":
    sys.exit(main())
