"""Headless `blender -b smoke.blend -E VOLPATH -a` in a real Blender (Debian's 3.4 in CI) over the
baked Quick Smoke domain: every frame is written; inside the cache range (28-30) each frame shows
its own grids, read from Blender's fluid runtime (3.4 has no openvdb module) and said so in the
log; outside it (27, 31) the domain renders nothing (as Cycles) and the two frames are the same
image (no smoke, same seed). Shares the installed Blender (and its compiled kernels) with
tests/addon/test_extension.py."""
import numpy as np
import pytest

from blender_process import BLENDER, run_blender
import fluid_runtime

FRAMES = range(27, 32)
# Run before -a: the meshes VolPath exports outside and inside the cache range (the domain's box
# must never be one of them), through the installed legacy add-on `volpath`.
_MESHES = ("import bpy; from volpath.export import export_scene; s = bpy.context.scene; s.volpath.samples = 16\n"
           "for f in (27, 29):\n"
           "    s.frame_set(f); native, _ = export_scene(bpy.context.evaluated_depsgraph_get())\n"
           "    print('MESHES', f, sorted(m.name for m in native.meshes))")


def read_exr(path):
    from volpath_native import imageio

    return imageio.read_exr(path)[..., :3]


def test_animation_renders_every_frame_of_the_baked_range(installed_blender, tmp_path):
    _, env = installed_blender
    folder = fluid_runtime.copy_data(tmp_path / "data")
    out = run_blender([BLENDER, "-b", folder / "smoke.blend", "-E", "VOLPATH",
                       "--python-expr", _MESHES,
                       "-o", tmp_path / "render_####", "-F", "OPEN_EXR", "-s", FRAMES[0], "-e", FRAMES[-1], "-a"],
                      env, timeout=900)
    images = {}
    for frame in FRAMES:
        path = tmp_path / f"render_{frame:04d}.exr"
        assert path.exists(), f"frame {frame} was not written\n{out[-3000:]}"
        images[frame] = read_exr(path)
        assert np.all(np.isfinite(images[frame]))
    for frame in (28, 29, 30):
        assert (f"fluid domain 'Smoke Domain' (frame {frame}): grids ['density'] from the fluid runtime"
                in out), out[-3000:]
    # No smoke outside the cache range: frames 27 and 31 are the same picture of floor and sky.
    np.testing.assert_array_equal(images[27], images[31])
    empty = images[27]
    for frame in (28, 29, 30):
        change = np.abs(images[frame] - empty).mean(axis=-1)
        assert (change > 0.05).mean() > 0.05, f"frame {frame}: no plume in view"
    # Each frame is its own simulation step (the plume grows), not a repeat.
    assert np.abs(images[30] - images[28]).mean() > 1e-3
    assert "outside the cache range 28-30" in out
    assert "MESHES 27 ['Floor']" in out and "MESHES 29 ['Floor', 'Smoke Domain bounds']" in out, out[-3000:]
