"""Packaging: the manifest and the built zip pass Blender's own validator, and a real Blender
executable (Debian's 3.4 in CI, or $BLENDER) installs VolPath and renders a frame headless.

The executable test works in a temporary user config (HOME, BLENDER_USER_CONFIG,
BLENDER_USER_SCRIPTS), never in the real user's preferences."""
import importlib.util
import os
import shutil
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import bpy
import numpy as np
import pytest

from addon_scenes import read_exr

ROOT = Path(__file__).resolve().parents[2]


def _load_build_script():
    """addon/build_extension.py is a bpy-free script, loaded by path (not as addon.*)."""
    spec = importlib.util.spec_from_file_location("volpath_build_extension", ROOT / "addon" / "build_extension.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


build_extension = _load_build_script()


@pytest.fixture(scope="module")
def extension_zip():
    try:
        return build_extension.build()
    except build_extension.BuildError as error:
        if "pip download" in str(error) and "embreex" in str(error):
            pytest.skip(f"cannot download the embreex wheel here: {str(error)[:300]}")
        raise


def test_manifest_and_zip_pass_blenders_validator(extension_zip):
    cli = build_extension.blender_ext_cli()
    for target in (build_extension.STAGE_DIR, extension_zip):
        proc = subprocess.run([sys.executable, str(cli), "validate", str(target)],
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stdout + proc.stderr
    names = zipfile.ZipFile(extension_zip).namelist()
    assert "blender_manifest.toml" in names and "__init__.py" in names and "engine.py" in names
    assert not any(n.endswith("build_extension.py") or "__pycache__" in n for n in names)
    manifest = build_extension.read_manifest()
    for wheel in manifest["wheels"]:
        assert wheel.removeprefix("./") in names
    assert not any("numpy" in n or "OpenImageIO" in n.lower() for n in manifest["wheels"])


def test_validator_rejects_a_broken_manifest(tmp_path):
    """The validator really checks: a manifest without its id must fail."""
    text = (ROOT / "blender_manifest.toml").read_text().replace('id = "volpath"\n', "")
    (tmp_path / "blender_manifest.toml").write_text(text)
    proc = subprocess.run([sys.executable, str(build_extension.blender_ext_cli()), "validate", str(tmp_path)],
                          capture_output=True, text=True)
    assert proc.returncode != 0


# ----------------------------------------------------------------------------------------------
# A real Blender executable
# ----------------------------------------------------------------------------------------------
from blender_process import BLENDER, run_blender as _run  # noqa: E402,F401  (tests/blender_process.py)

_SCENE_SCRIPT = textwrap.dedent('''
    import math, sys, bpy
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    sc = bpy.context.scene
    sc.render.engine = "VOLPATH"
    sc.render.resolution_x = sc.render.resolution_y = 32
    sc.render.resolution_percentage = 100
    sc.volpath.samples = 8
    sc.volpath.seed = 3
    sc.world = None

    def material(name, surface=None, volume=None):
        mat = bpy.data.materials.new(name)
        mat.use_nodes = True
        tree = mat.node_tree
        tree.nodes.clear()
        out = tree.nodes.new("ShaderNodeOutputMaterial")
        if surface:
            node = tree.nodes.new(surface[0])
            for key, value in surface[1].items():
                node.inputs[key].default_value = value
            tree.links.new(node.outputs[0], out.inputs["Surface"])
        if volume:
            node = tree.nodes.new(volume[0])
            for key, value in volume[1].items():
                node.inputs[key].default_value = value
            tree.links.new(node.outputs[0], out.inputs["Volume"])
        return mat

    def box(name, mat, location, scale):
        bpy.ops.mesh.primitive_cube_add(location=location)
        obj = bpy.context.active_object
        obj.name = name
        obj.scale = scale
        obj.data.materials.append(mat)

    box("Back", material("Wall", surface=("ShaderNodeBsdfDiffuse", {"Color": (0.8, 0.6, 0.4, 1)})),
        (0, 4, 0), (4, 0.1, 4))
    box("Fog", material("Fog", volume=("ShaderNodeVolumePrincipled", {"Density": 0.6})), (0, 0, 0),
        (1.5, 1.5, 1.5))
    light = bpy.data.lights.new("Bulb", "POINT")
    light.energy = 800.0
    light.shadow_soft_size = 0.0
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


def test_installed_in_blender_renders_headless(installed_blender, tmp_path):
    home, env = installed_blender  # a fresh install: the first render loads the shipped kernels
    assert not (Path.home() / ".config" / "blender" / "volpath-test-marker").exists()

    scene_file = tmp_path / "fog.blend"
    (tmp_path / "make_scene.py").write_text(_SCENE_SCRIPT)
    _run([BLENDER, "-b", "--python-exit-code", "1", "--python", tmp_path / "make_scene.py", "--", scene_file], env)
    out = _run([BLENDER, "-b", scene_file, "-E", "VOLPATH", "-o", tmp_path / "out_", "-F", "OPEN_EXR", "-f", "1"], env)
    frame = tmp_path / "out_0001.exr"
    assert frame.exists(), out[-3000:]
    # numba's cache goes to the add-on's per-user folder (datafiles/volpath/numba for the legacy
    # add-on, extensions/.user/<repo>/volpath/numba for an extension), not next to its sources.
    assert list(home.rglob("volpath/numba/**/*.nbi")), "no compiled kernels cached under " + str(home)
    image = read_exr(frame)
    assert image.shape == (32, 32, 4)
    assert np.all(np.isfinite(image)) and image[..., :3].mean() > 1e-3

    # Plausible = the same frame as VolPath renders it from Blender 5 (bpy module) for the same
    # .blend: same exporter, same renderer, same seed. A per-image mean z-test on the difference.
    bpy.ops.wm.open_mainfile(filepath=str(scene_file))
    sc = bpy.context.scene
    sc.render.engine = "VOLPATH"
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.filepath = str(tmp_path / "bpy5.exr")
    bpy.ops.render.render(write_still=True)
    reference = read_exr(tmp_path / "bpy5.exr")
    diff = (image[..., :3] - reference[..., :3]).reshape(-1)
    standard_error = max(diff.std(ddof=1) / np.sqrt(diff.size), 1e-6 * reference[..., :3].mean())
    assert abs(diff.mean()) < 4.0 * standard_error, (diff.mean(), standard_error)
    assert abs(image[..., :3].mean() / reference[..., :3].mean() - 1.0) < 0.05


_KERNELS_SCRIPT = textwrap.dedent('''
    import gc, time, bpy
    started = time.perf_counter()
    bpy.ops.render.render()
    seconds = time.perf_counter() - started
    import numba
    from numba.core.registry import CPUDispatcher
    from volpath_native import jit
    ours = [d for d in gc.get_objects() if isinstance(d, CPUDispatcher) and d.py_func.__module__.startswith("volpath_native")]
    compiled = sorted(f"{d.py_func.__module__}.{d.py_func.__qualname__}" for d in ours if sum(d.stats.cache_misses.values()))
    loaded = sum(sum(d.stats.cache_hits.values()) for d in ours)
    print("VOLPATH_KERNELS loaded=%d compiled=%s cpu=%s seconds=%.1f" % (loaded, ",".join(compiled) or "-", numba.config.CPU_NAME, seconds))
    print("VOLPATH_CACHE " + jit.KERNEL_CACHE_DIR)
    print("VOLPATH_SHIPPED " + str(jit.PREBUILT_DIR / jit.CACHE_KEY), flush=True)
    import os
    os._exit(0)  # Debian's 3.4 crashes in addon_utils.disable_all at exit once the renderer was imported by a script (also before this change)
''')


def test_installed_blender_loads_the_shipped_kernels(installed_blender, tmp_path):
    """After `make install-blender` (a legacy add-on in Debian's 3.4), a render compiles no kernel:
    all of them load from the cache shipped in the volpath_native wheel, which the add-on copied
    into its per-user folder. Independent of which kernels exist: any kernel a render needs that
    the build's warm-up missed shows up here by name."""
    home, env = installed_blender
    scene_file = tmp_path / "fog.blend"
    (tmp_path / "make_scene.py").write_text(_SCENE_SCRIPT)
    _run([BLENDER, "-b", "--python-exit-code", "1", "--python", tmp_path / "make_scene.py", "--", scene_file], env)
    (tmp_path / "count.py").write_text(_KERNELS_SCRIPT)
    out = _run([BLENDER, "-b", scene_file, "--python-exit-code", "1", "--python", tmp_path / "count.py"], env)
    found = dict(item.split("=", 1) for item in out.split("VOLPATH_KERNELS ")[1].split("\n")[0].split())
    assert found["cpu"] == "generic", found
    assert found["compiled"] == "-", ("kernels compiled at render time (extend integrator.warm_up(thorough=True)): "
                                      + found["compiled"])
    assert int(found["loaded"]) > 0, found
    cache = Path(out.split("VOLPATH_CACHE ")[1].split("\n")[0].strip())
    shipped = Path(out.split("VOLPATH_SHIPPED ")[1].split("\n")[0].strip())
    assert str(cache).startswith(str(home)) and "volpath/numba" in str(cache), cache
    indexes = sorted(p.relative_to(shipped) for p in shipped.rglob("*.nbi"))
    assert indexes, "no kernels shipped in " + str(shipped)
    for index in indexes:  # seeded, and not rewritten by a compile since
        assert (cache / index).read_bytes() == (shipped / index).read_bytes(), index


_EXTENSION_SCRIPT = textwrap.dedent('''
    import importlib.machinery, os, pathlib, sys, sysconfig
    zip_path, out_path = sys.argv[1], sys.argv[2]

    # The packages the extension bundles must come from its wheels, as in a real Blender whose
    # Python has none of them: never from this venv (bpy, numpy and the rest still do).
    BUNDLED = {"numba", "llvmlite", "embreex", "volpath_native"}
    VENV_SITE = os.path.realpath(sysconfig.get_paths()["purelib"])

    class WithoutVenvCopies:
        @staticmethod
        def find_spec(name, path=None, target=None):
            if path is not None or name not in BUNDLED:
                return None
            elsewhere = [p for p in sys.path if os.path.realpath(p) != VENV_SITE]
            spec = importlib.machinery.PathFinder.find_spec(name, elsewhere)
            if spec is None:
                raise ModuleNotFoundError(f"{name} is not in the extension's wheels", name=name)
            return spec

    sys.meta_path.insert(0, WithoutVenvCopies)
    import bpy, numpy as np

    def compiled_kernels():
        """volpath_native kernels numba compiled in this process (rather than loaded)."""
        import gc
        from numba.core.registry import CPUDispatcher
        return sorted(f"{d.py_func.__module__}.{d.py_func.__qualname__}" for d in gc.get_objects()
                      if isinstance(d, CPUDispatcher) and d.py_func.__module__.startswith("volpath_native")
                      and sum(d.stats.cache_misses.values()))
    result = bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                                      enable_on_install=True)
    assert result == {"FINISHED"}, result
    assert "bl_ext.user_default.volpath" in bpy.context.preferences.addons
    cache = pathlib.Path(os.environ["NUMBA_CACHE_DIR"])  # set by the add-on before the renderer loads
    assert "/extensions/.user/user_default/volpath/" in str(cache), cache
    import embreex, llvmlite, numba, volpath_native
    for module in (volpath_native, embreex, numba, llvmlite):
        assert "/extensions/" in module.__file__, module.__file__
    sc = bpy.context.scene
    sc.render.engine = "VOLPATH"
    sc.render.resolution_x = sc.render.resolution_y = 16
    sc.volpath.samples = 2
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.filepath = out_path
    bpy.ops.render.render(write_still=True)
    from volpath_native import jit
    from volpath_native.sampling import uniform1
    # the signature the kernels call it with (tracking draws: uint64 key and dimension): shipped
    assert 0.0 <= uniform1(np.uint64(7), np.uint64(1)) < 1.0  # run by the bundled numba, cached per user
    assert list(cache.rglob("*.nbi")), "numba wrote no cache index into " + str(cache)
    # the first render of a fresh install compiled nothing: the kernels shipped in the wheel
    # seeded the per-user cache and loaded from it
    assert jit.KERNELS_SEEDED > 0, "no shipped kernels seeded " + jit.KERNEL_CACHE_DIR
    assert not compiled_kernels(), "compiled at the first render: " + ", ".join(compiled_kernels())
''')


def test_extension_installs_and_renders_in_blender_5(extension_zip, tmp_path):
    """The zip installed the way Blender 4.2+ does (Extensions > Install from Disk) into a
    temporary user config of the bpy module: wheels land in Blender's extension site-packages,
    the add-on enables as bl_ext.user_default.volpath, and F12 renders the default scene.
    numba, llvmlite and embreex must come from the extension's wheels, numba's cache from the
    add-on's per-user folder."""
    home = tmp_path / "home"
    env = dict(os.environ, HOME=str(home), BLENDER_USER_CONFIG=str(home / "config"),
               BLENDER_USER_SCRIPTS=str(home / "scripts"), BLENDER_USER_EXTENSIONS=str(home / "extensions"))
    env.pop("NUMBA_CACHE_DIR", None)
    script = tmp_path / "install.py"
    script.write_text(_EXTENSION_SCRIPT)
    out = tmp_path / "default.exr"
    proc = subprocess.run([sys.executable, "-I", str(script), str(extension_zip), str(out)], env=env,
                          capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    image = read_exr(out)
    assert image.shape == (16, 16, 4) and np.all(np.isfinite(image)) and image[..., :3].mean() > 0
