"""Registration: engine, settings, panels, Blender's shared panels and their clean removal."""
import bpy
import pytest

import addon
from addon import ui

SHARED = ("DATA_PT_lens", "DATA_PT_spot", "RENDER_PT_format", "EEVEE_MATERIAL_PT_surface",
          "EEVEE_MATERIAL_PT_volume", "EEVEE_WORLD_PT_surface", "EEVEE_WORLD_PT_volume")


def _panel(name):
    return getattr(bpy.types, name)


@pytest.mark.parametrize("name", SHARED)
def test_blender_panels_accept_volpath(name):
    assert "VOLPATH" in _panel(name).COMPAT_ENGINES


def test_eevee_only_panels_stay_eevee_only():
    for name in ("EEVEE_MATERIAL_PT_settings", "DATA_PT_EEVEE_light_shadow"):
        panel = getattr(bpy.types, name, None)
        if panel is not None:
            assert "VOLPATH" not in panel.COMPAT_ENGINES


def test_settings_defaults_match_cycles():
    settings = bpy.context.scene.volpath
    assert (settings.max_bounces, settings.diffuse_bounces, settings.glossy_bounces,
            settings.transmission_bounces, settings.volume_bounces, settings.transparent_bounces) == (12, 4, 4, 12, 0, 8)
    assert settings.bl_rna.properties["time_limit"].default == 0.0  # Cycles' Time Limit default: none


def test_unregister_removes_everything_and_register_restores_it():
    addon.unregister()
    try:
        assert not hasattr(bpy.types.Scene, "volpath")
        assert all("VOLPATH" not in _panel(name).COMPAT_ENGINES for name in SHARED)
        assert "VOLPATH" not in {getattr(e, "bl_idname", None) for e in bpy.types.RenderEngine.__subclasses__()
                                 if e.is_registered}
        assert not ui.operator_available("volpath.render")
    finally:
        addon.register()
    assert ui.operator_available("volpath.render")
    assert all("VOLPATH" in _panel(name).COMPAT_ENGINES for name in SHARED)


def test_optional_operator_detection():
    assert ui.operator_available("volpath.render")
    assert not ui.operator_available("volpath.no_such_operator")


def test_render_button_renders_with_volpath(scene, monkeypatch):
    import importlib

    native_render = importlib.import_module("volpath_native.render")
    calls = []
    real = native_render.render
    monkeypatch.setattr(native_render, "render", lambda s, **kw: calls.append(s) or real(s, **kw))
    scene.render.engine = "CYCLES"
    assert bpy.ops.volpath.render() == {"FINISHED"}
    assert scene.render.engine == "VOLPATH"  # the button switches to VolPath first
    assert len(calls) == 1 and calls[0].settings.samples == scene.volpath.samples


def test_export_vpscene_round_trip(scene, tmp_path):
    import numpy as np
    import volpath_native as vp
    from addon_scenes import add_light, add_mesh, export, node_material, shader

    fog = node_material("Fog", volume=shader("ShaderNodeVolumePrincipled", Density=0.7))
    add_mesh(scene, "Fog", material=fog)
    add_light(scene, "Bulb", "POINT", 100.0, location=(0, 0, 3))
    path = tmp_path / "scene.vpscene"
    assert bpy.ops.volpath.export_scene(filepath=str(path)) == {"FINISHED"}
    loaded, expected = vp.load_scene(path), export(scene)[0]
    np.testing.assert_allclose(loaded.media[0].sigma_s, expected.media[0].sigma_s)
    np.testing.assert_allclose(loaded.meshes[0].vertices, expected.meshes[0].vertices)
    assert loaded.settings.samples == scene.volpath.samples


def test_export_vpscene_reports_errors(scene, tmp_path):
    scene.camera = None
    with pytest.raises(RuntimeError, match="no active camera"):
        bpy.ops.volpath.export_scene(filepath=str(tmp_path / "x.vpscene"))
