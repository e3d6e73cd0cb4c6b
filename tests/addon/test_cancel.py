"""Esc at random moments of an F12 render (export, first samples, mid-render, the last round):
Blender gets control back within a second, no render thread is left running, and the Render
Result holds a consistent partial image (whole rounds only) with its sample count."""
import os
import threading
import time

import bpy
import numpy as np
import pytest

import importlib

from addon.engine import VolpathRenderEngine
from addon_scenes import add_light, add_mesh, node_material, shader

native_render = importlib.import_module("volpath_native.render")
CANCELS = int(os.environ.get("VOLPATH_RANDOM_CANCELS", "10"))


def busy_scene(sc, objects=40):
    """Fog, a wall and many small boxes (an export of some length), 2000 spp (tens of seconds)."""
    wall = node_material("Wall", surface=shader("ShaderNodeBsdfDiffuse", Color=(0.8, 0.8, 0.8, 1.0)))
    fog = node_material("Fog", volume=shader("ShaderNodeVolumePrincipled", Density=0.4))
    add_mesh(sc, "Back", material=wall, location=(0, 4, 0), scale=(4, 0.1, 4))
    add_mesh(sc, "Fog", material=fog, scale=(2.0, 2.0, 2.0))
    for k in range(objects):
        add_mesh(sc, f"Pebble{k}", material=wall, location=(-1.5 + 0.1 * k, 1.0, -1.0), scale=(0.04, 0.04, 0.04))
    add_light(sc, "Bulb", "POINT", 800.0, location=(0, 0, 2.5), shadow_soft_size=0.0)
    sc.render.resolution_x = sc.render.resolution_y = 32
    sc.volpath.samples = 2000
    sc.volpath.batch_size = 1024


def test_random_cancels_return_within_a_second(scene, monkeypatch):
    import volpath_native
    volpath_native.warm_up()  # the compile moment has its own test below
    busy_scene(scene)
    results = []
    real = native_render.render

    def spy(native_scene, **kwargs):
        result = real(native_scene, **kwargs)
        results.append(result)
        return result

    monkeypatch.setattr(native_render, "render", spy)
    rng = np.random.default_rng(13)
    baseline = threading.active_count()
    worst = 0.0
    moments = []
    for k in range(CANCELS):
        delay = float(rng.choice([0.0, rng.uniform(0.0, 0.3), rng.uniform(0.3, 1.5)]))
        state = {}

        def esc_pressed(self, delay=delay, state=state):
            now = time.perf_counter()
            state.setdefault("first", now)  # the engine's first poll: the start of its work
            if now - state["first"] >= delay:
                state.setdefault("pressed", now)
                return True
            return False

        monkeypatch.setattr(VolpathRenderEngine, "cancel_requested", esc_pressed)
        before = len(results)
        bpy.ops.render.render()
        late = time.perf_counter() - state["pressed"]
        worst = max(worst, late)
        assert late < 1.0, (k, delay, late)
        assert threading.active_count() == baseline, threading.enumerate()
        if len(results) > before:  # cancelled while rendering (else: while exporting)
            result = results[-1]
            moments.append("render")
            assert result.cancelled and result.samples < 2000
            alpha = result.image[..., 3]
            assert np.all(alpha == (1.0 if result.samples else 0.0)) and np.all(np.isfinite(result.image))
        else:
            moments.append("export")
    print(f"{CANCELS} random Esc presses ({moments.count('export')} while exporting): slowest return "
          f"{worst:.3f} s after the press")
    assert "export" in moments and "render" in moments  # both moments were exercised


def test_esc_while_compiling_the_kernels_returns_within_a_second(scene, monkeypatch, tmp_path):
    """The first render after an install compiles for ~100 s in a child process: Esc kills it."""
    from addon import engine
    from volpath_native import kernel_compile

    busy_scene(scene, objects=1)
    monkeypatch.setattr(engine, "_kernels_ready", False)
    monkeypatch.setattr(kernel_compile, "kernels_cached", lambda *args: False)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))  # the child compiles from scratch, there
    state = {}

    def esc_pressed(self):
        now = time.perf_counter()
        state.setdefault("first", now)
        if now - state["first"] >= 1.0:
            state.setdefault("pressed", now)
            return True
        return False

    monkeypatch.setattr(VolpathRenderEngine, "cancel_requested", esc_pressed)
    baseline = threading.active_count()
    bpy.ops.render.render()
    assert time.perf_counter() - state["pressed"] < 1.0
    assert threading.active_count() == baseline
    assert not engine._kernels_ready  # the next F12 compiles again


def test_compile_on_enable_shows_its_state_an_f12_waits_and_disable_stops_it(scene, monkeypatch, tmp_path):
    """When no cache can serve the kernels, enabling the add-on compiles them in a background
    child (addon/kernel_status.py): the render panel's status line says so, an F12 meanwhile waits
    for it and Esc ends that wait (the compile goes on), and stopping the job kills the child."""
    from addon import engine, kernel_status
    from volpath_native import kernel_compile

    busy_scene(scene, objects=1)
    monkeypatch.setattr(engine, "_kernels_ready", False)
    monkeypatch.setattr(kernel_compile, "kernels_cached", lambda *args: False)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))  # the child compiles from scratch, there
    assert kernel_status.start()
    try:
        deadline = time.monotonic() + 30.0
        while kernel_status.phase() != kernel_status.COMPILING and time.monotonic() < deadline:
            time.sleep(0.05)
        text, icon = kernel_status.status_line()
        assert text.startswith("Compiling render kernels in the background"), text
        state = {}

        def esc_pressed(self):
            now = time.perf_counter()
            state.setdefault("first", now)
            if now - state["first"] >= 1.0:
                state.setdefault("pressed", now)
                return True
            return False

        monkeypatch.setattr(VolpathRenderEngine, "cancel_requested", esc_pressed)
        bpy.ops.render.render()
        assert time.perf_counter() - state["pressed"] < 1.0
        assert kernel_status.busy() and kernel_status.phase() == kernel_status.COMPILING  # still compiling
    finally:
        kernel_status.stop()
    assert not kernel_status.busy() and kernel_status.phase() == kernel_status.STOPPED
    assert not any(tmp_path.rglob("path_kernels.shade-*.nbi"))  # killed before it finished


def test_compile_on_enable_finds_cached_kernels_at_once():
    import volpath_native
    from addon import kernel_status

    volpath_native.warm_up()
    assert kernel_status.start()
    kernel_status.wait(lambda: False)
    assert kernel_status.phase() == kernel_status.READY
    assert kernel_status.status_line() == ("Render kernels ready", "CHECKMARK")
