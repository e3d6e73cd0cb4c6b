"""The engine end to end through Blender: F12 (bpy.ops.render.render) with VolPath, cancellation,
warnings and errors reported by the engine."""
import time

import bpy
import numpy as np
import pytest

import importlib

native_render = importlib.import_module("volpath_native.render")  # the package re-exports render()
from addon.engine import VolpathRenderEngine
from addon_scenes import add_light, add_mesh, node_material, read_exr, shader


def _fog_scene(sc):
    """A grey box in front of a fog cube lit by a point light: small but every feature is used."""
    wall = node_material("Wall", surface=shader("ShaderNodeBsdfDiffuse", Color=(0.8, 0.8, 0.8, 1.0)))
    fog = node_material("Fog", volume=shader("ShaderNodeVolumePrincipled", Density=0.5))
    add_mesh(sc, "Back", material=wall, location=(0, 4, 0), scale=(4, 0.1, 4))
    add_mesh(sc, "Fog", material=fog, scale=(1.5, 1.5, 1.5))
    add_light(sc, "Bulb", "POINT", 800.0, location=(0, 0, 2.5), shadow_soft_size=0.0)


def _render_to_exr(sc, tmp_path):
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.filepath = str(tmp_path / "frame.exr")
    bpy.ops.render.render(write_still=True)
    return read_exr(tmp_path / "frame.exr")


def test_f12_render_is_finite_and_lit(scene, tmp_path):
    _fog_scene(scene)
    image = _render_to_exr(scene, tmp_path)
    assert image.shape == (24, 24, 4)
    assert np.all(np.isfinite(image))
    rgb = image[..., :3]
    assert rgb.mean() > 1e-3
    # Row 0 of the file is the TOP of the frame: the light is above, so the fog's top half is
    # brighter than its bottom half (a flipped image would fail this).
    centre = rgb[:, 8:16].mean(axis=(1, 2))
    assert centre[4:12].mean() > centre[12:20].mean()


def test_render_region_fills_blender_result(scene, tmp_path):
    _fog_scene(scene)
    r = scene.render
    r.resolution_x, r.resolution_y = 37, 23
    r.use_border, r.use_crop_to_border = True, True
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.1, 0.77, 0.25, 0.9
    image = _render_to_exr(scene, tmp_path)
    assert image.shape[:2] == (15, 25)  # Blender's truncated border: x 3..28, y 5..20
    assert np.all(np.isfinite(image)) and np.all(image[..., 3] > 0)


@pytest.fixture
def captured(monkeypatch):
    """Records what the engine's call of volpath_native.render.render returned."""
    results = []
    real = native_render.render

    def spy(scene, **kwargs):
        result = real(scene, **kwargs)
        results.append(result)
        return result

    monkeypatch.setattr(native_render, "render", spy)
    return results


def test_cancel_stops_within_a_second(scene, captured, monkeypatch):
    _fog_scene(scene)
    scene.render.resolution_x = scene.render.resolution_y = 32
    scene.volpath.samples = 2000  # tens of seconds: bounded even if cancelling were broken
    cancel_at = []

    def esc_pressed(self):
        # Blender's test_break() is never true in background mode: Esc "pressed" 0.3 s in.
        if not cancel_at:
            cancel_at.append(time.perf_counter() + 0.3)
        return time.perf_counter() > cancel_at[0]

    monkeypatch.setattr(VolpathRenderEngine, "cancel_requested", esc_pressed)
    bpy.ops.render.render()
    returned = time.perf_counter()
    assert captured and captured[0].cancelled
    assert 0 <= captured[0].samples < 2000
    assert returned - cancel_at[0] < 1.0


def test_unsupported_node_is_reported_as_warning(scene, captured, capfd):
    _fog_scene(scene)
    add_mesh(scene, "Shiny", material=node_material("Shiny", surface=shader("ShaderNodeBsdfToon")),
             location=(2.5, 0, 0), scale=(0.3, 0.3, 0.3))
    bpy.ops.render.render()
    out = capfd.readouterr()
    assert "Warning" in out.out + out.err and "'Shiny'" in out.out + out.err
    assert captured and np.all(np.isfinite(captured[0].image))


def test_open_mesh_bounding_a_medium_is_named_and_rendered_without_its_volume(scene, captured, capfd):
    from addon_scenes import CUBE_FACES, CUBE_VERTICES

    fog = node_material("Fog", volume=shader("ShaderNodeVolumePrincipled"))
    add_mesh(scene, "OpenBox", vertices=CUBE_VERTICES, faces=CUBE_FACES[:-1], material=fog)
    add_light(scene, "Bulb", "POINT", 800.0, location=(0, 0, 2.5), shadow_soft_size=0.0)
    bpy.ops.render.render()
    out = capfd.readouterr()
    assert "OpenBox" in out.out + out.err and "not closed" in out.out + out.err
    assert captured and np.all(np.isfinite(captured[0].image))


def test_time_limit_ends_an_f12_render_with_whole_samples(scene, captured):
    """Render > Time Limit: an F12 render of 10^6 samples stops on the clock (not cancelled), with
    a finite image of whole passes."""
    import volpath_native
    volpath_native.warm_up()  # the clock is the render's, not the first compile's
    _fog_scene(scene)
    scene.volpath.samples = 1 << 20
    scene.volpath.time_limit = 0.5
    started = time.perf_counter()
    try:
        bpy.ops.render.render()
    finally:
        scene.volpath.time_limit = 0.0
    assert time.perf_counter() - started < 30.0  # (10^6 samples would take hours)
    result = captured[0]
    assert not result.cancelled and 1 < result.samples < 1 << 20
    assert np.all(np.isfinite(result.image)) and np.all(result.image[..., 3] == 1.0)
