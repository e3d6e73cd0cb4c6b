"""Benchmark: the first render after a fresh install against the second (not collected by pytest).

`make install-blender` into a new temporary Blender user config (HOME, BLENDER_USER_CONFIG,
BLENDER_USER_SCRIPTS), then `blender -b fog.blend -E VOLPATH -f 1` twice; prints the wall times
of the install and of both renders (Blender's start-up included) and their ratio. The first render
loads the kernels shipped in the wheel (volpath_native/jit.py); --cold adds a third render with
VOLPATH_KERNEL_CPU=host, which cannot use them and compiles every kernel (what every first render
cost before kernels were shipped).

    python tests/benchmarks/bench_first_render.py [--blender /usr/bin/blender] [--cold]
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

_SCENE = textwrap.dedent('''
    import math, sys, bpy
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    sc = bpy.context.scene
    sc.render.engine = "VOLPATH"
    sc.render.resolution_x = sc.render.resolution_y = 64
    sc.render.resolution_percentage = 100
    sc.volpath.samples = 4
    sc.world = None
    bpy.ops.mesh.primitive_cube_add(location=(0, 0, 0))
    fog = bpy.context.active_object
    mat = bpy.data.materials.new("Fog")
    mat.use_nodes = True
    mat.node_tree.nodes.clear()
    out = mat.node_tree.nodes.new("ShaderNodeOutputMaterial")
    vol = mat.node_tree.nodes.new("ShaderNodeVolumePrincipled")
    mat.node_tree.links.new(vol.outputs[0], out.inputs["Volume"])
    fog.data.materials.append(mat)
    bpy.ops.mesh.primitive_plane_add(size=8, location=(0, 0, -1.2))
    light = bpy.data.lights.new("Bulb", "POINT")
    light.energy = 800.0
    lamp = bpy.data.objects.new("Bulb", light)
    lamp.location = (0, 0, 2.5)
    sc.collection.objects.link(lamp)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (0, -6, 0)
    cam.rotation_euler = (math.pi / 2, 0, 0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    bpy.ops.wm.save_as_mainfile(filepath=sys.argv[sys.argv.index("--") + 1])
''')


def _timed(cmd, env) -> float:
    start = time.perf_counter()
    proc = subprocess.run([str(c) for c in cmd], env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"failed: {cmd}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return seconds


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blender", default=os.environ.get("BLENDER") or shutil.which("blender") or "/usr/bin/blender")
    parser.add_argument("--cold", action="store_true", help="also time a render that compiles every kernel")
    args = parser.parse_args(argv)
    if not Path(args.blender).exists():
        print(f"no Blender at {args.blender}: skipped")
        return 0
    with tempfile.TemporaryDirectory(prefix="volpath_first_render_") as tmp:
        home = Path(tmp)
        env = dict(os.environ, HOME=str(home), BLENDER_USER_CONFIG=str(home / "config"),
                   BLENDER_USER_SCRIPTS=str(home / "scripts"))
        env.pop("PYTHONPATH", None)
        install = _timed(["make", "-s", "-C", ROOT, "install-blender", f"BLENDER={args.blender}"], env)
        for variable in ("NUMBA_CACHE_DIR", "NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES"):  # Blender as installed
            env.pop(variable, None)
        (home / "scene.py").write_text(_SCENE)
        _timed([args.blender, "-b", "--python-exit-code", "1", "--python", home / "scene.py", "--",
                home / "fog.blend"], env)
        render = [args.blender, "-b", home / "fog.blend", "-E", "VOLPATH", "-o", home / "out_", "-f", "1"]
        first = _timed(render, env)
        if not (home / "out_0001.png").exists():
            raise SystemExit("the first render wrote no frame")
        second = _timed(render, env)
        print(f"fresh install into {args.blender}: install {install:.1f} s, first render {first:.1f} s, "
              f"second {second:.1f} s, first/second {first / second:.2f} (target <= 2)")
        if args.cold:
            cold_env = dict(env, VOLPATH_KERNEL_CPU="host")
            cold = _timed(render, cold_env)
            print(f"without the shipped kernels (compiling for this CPU): first render {cold:.1f} s, "
                  f"{cold / second:.1f}x the second")
    return 0


if __name__ == "__main__":
    sys.exit(main())
