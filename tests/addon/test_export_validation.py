"""Invalid Blender input is named -- datablock and field -- with the fallback taken
(addon/export/validate.py), and the render goes on with that fallback."""
from __future__ import annotations

import math
import warnings

import bpy
import numpy as np
import pytest

import importlib

from addon import export_volume_grids as evg
from addon.engine import VolpathRenderEngine
from addon_scenes import CUBE_FACES, CUBE_VERTICES, add_light, add_mesh, export, node_material, shader

native_render = importlib.import_module("volpath_native.render")
NAN, INF = float("nan"), float("inf")
FLT_MAX = float(np.finfo(np.float32).max)


def export_quietly(sc):
    """export() with Python warnings turned into errors: nothing may leak past the exporter."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return export(sc)


def lit_box(sc, name="Box", material=None, **kw):
    add_light(sc, "Lamp", "POINT", 500.0, location=(0, -2, 2))
    return add_mesh(sc, name, material=material, **kw)


def test_nan_in_principled_volume_colour_names_material_node_and_input(scene):
    fog = node_material("Fog", volume=shader("ShaderNodeVolumePrincipled", Color=(NAN, 0.5, 0.5, 1.0), Density=2.0))
    lit_box(scene, "FogBox", fog)
    native, messages = export_quietly(scene)
    message = next(m for m in messages if "NaN" in m)
    assert "material 'Fog'" in message and "'Principled Volume'" in message and "input 'Color'" in message
    assert "NaN as 0" in message
    medium = native.media[0]  # the fallback: the NaN channel scatters nothing (Color 0 there)
    assert medium.sigma_s[0] == 0.0 and medium.sigma_s[1] == pytest.approx(1.0)


def test_inf_density_is_named_as_the_largest_float(scene):
    fog = node_material("Fog", volume=shader("ShaderNodeVolumePrincipled", Density=INF))
    lit_box(scene, "FogBox", fog)
    native, messages = export_quietly(scene)
    assert any("input 'Density' is the largest float" in m and "'Fog'" in m for m in messages), messages
    assert np.all(np.isfinite(native.media[0].sigma_s))


def test_nan_rotation_names_the_object_and_skips_it_without_numpy_warnings(scene):
    lit_box(scene, "Good")
    bad = add_mesh(scene, "Tilted", location=(2, 0, 0))
    bad.rotation_euler = (NAN, 0.0, 0.0)
    native, messages = export_quietly(scene)
    assert any("object 'Tilted'" in m and "rotation_euler" in m and "not rendered" in m for m in messages), messages
    assert [m.name for m in native.meshes] == ["Good"]


def test_nan_from_a_parent_names_the_child(scene):
    parent = bpy.data.objects.new("Rig", None)
    scene.collection.objects.link(parent)
    parent.scale = (NAN, 1.0, 1.0)
    child = lit_box(scene, "Child")
    child.parent = parent
    native, messages = export_quietly(scene)
    assert any("object 'Child'" in m and "parent" in m for m in messages), messages
    assert not native.meshes


def test_negative_world_strength_renders_black_with_a_warning(scene):
    world = bpy.data.worlds.new("Night")
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = -2.0
    scene.world = world
    lit_box(scene)
    native, messages = export_quietly(scene)
    assert any("world 'Night'" in m and "negative" in m and "black" in m for m in messages), messages
    assert np.all(native.world.background == 0.0)


def test_zero_size_area_light_is_named_and_skipped(scene):
    lit_box(scene)
    add_light(scene, "Slit", "AREA", 100.0, size=0.0)
    native, messages = export_quietly(scene)
    assert any("light 'Slit': area light has zero size" in m for m in messages), messages
    assert [light.name for light in native.lights] == ["Lamp"]


def test_negative_and_overflowing_lights_are_named(scene):
    lit_box(scene)
    add_light(scene, "Dark", "POINT", -100.0, location=(0, -2, 1))
    add_light(scene, "Blinding", "SPOT", FLT_MAX, location=(0, -2, 1))
    bpy.data.lights["Blinding"].exposure = 10.0  # x 2^10: beyond float32
    native, messages = export_quietly(scene)
    assert any("light 'Dark'" in m and "negative" in m for m in messages), messages
    assert any("light 'Blinding'" in m and "not rendered" in m for m in messages), messages
    names = [light.name for light in native.lights]
    assert "Blinding" not in names and "Dark" in names
    assert np.all(native.lights[names.index("Dark")].power == 0.0)


def test_open_mesh_bounding_a_volume_is_named_and_its_volume_dropped(scene):
    fog = node_material("Fog", volume=shader("ShaderNodeVolumePrincipled"))
    lit_box(scene, "OpenBox", fog, vertices=CUBE_VERTICES, faces=CUBE_FACES[:-1])
    add_mesh(scene, "ClosedBox", material=fog, location=(3, 0, 0))
    native, messages = export_quietly(scene)
    assert any("object 'OpenBox'" in m and "material 'Fog'" in m and "not closed" in m for m in messages), messages
    assert not any("ClosedBox" in m for m in messages)
    by_name = {m.name: m for m in native.meshes}
    assert native.materials[by_name["OpenBox"].material_ids[0]].medium == -1
    assert native.materials[by_name["ClosedBox"].material_ids[0]].medium >= 0


def test_extruded_text_closes_its_volume_once_seams_are_welded(scene):
    fog = node_material("Fog", volume=shader("ShaderNodeVolumePrincipled"))
    curve = bpy.data.curves.new("Label", "FONT")
    curve.body, curve.extrude = "O", 0.2
    curve.materials.append(fog)
    text = bpy.data.objects.new("Label", curve)
    scene.collection.objects.link(text)
    lit_box(scene)
    _, messages = export_quietly(scene)
    assert not any("not closed" in m for m in messages), messages
    curve.extrude = 0.0  # a flat text cannot hold a volume: named
    _, messages = export_quietly(scene)
    assert any("object 'Label'" in m and "not closed" in m for m in messages), messages


def test_nan_camera_is_an_error_naming_the_camera(scene):
    lit_box(scene)
    scene.camera.location = (0.0, NAN, 0.0)
    import volpath_native as vp
    with pytest.raises(vp.SceneError, match="camera 'Camera': its transform"):
        export_quietly(scene)


def test_a_failing_export_still_reports_every_other_problem(scene, capfd, monkeypatch):
    """A scene with many defects: the one that stops the render is the error, and the others
    (an unsupported Toon BSDF, an open volume mesh, a NaN rotation) are reported by name too."""
    import volpath_native as vp

    def refuse(self):
        raise vp.SceneError("light 'Slit': area light has zero size")
    monkeypatch.setattr(vp.Scene, "validate", refuse)  # an error found after everything was read
    add_mesh(scene, "Toon", material=node_material("ToonPaint", surface=shader("ShaderNodeBsdfToon")))
    fog = node_material("Fog", volume=shader("ShaderNodeVolumePrincipled"))
    add_mesh(scene, "OpenFog", material=fog, vertices=CUBE_VERTICES, faces=CUBE_FACES[:-1], location=(3, 0, 0))
    add_mesh(scene, "Tilted", location=(-3, 0, 0)).rotation_euler = (0.0, NAN, 0.0)
    try:
        bpy.ops.render.render()
    except RuntimeError:  # Blender raises the engine's error_set message
        pass
    out = capfd.readouterr()
    text = out.out + out.err
    for name in ("ToonPaint", "OpenFog", "Tilted", "light 'Slit': area light has zero size"):
        assert name in text, (name, text)


def test_huge_base_colour_and_emission_render_finite_like_cycles(scene, tmp_path):
    """Base Color 1e30 beside Emission Strength 1e30: Cycles' image stays finite (measured with
    Blender 5.0.1), and so does VolPath's, with the emitter at ~1e30."""
    hot = node_material("Hot", surface=shader("ShaderNodeBsdfPrincipled", Base_Color=(1e30, 1e30, 1e30, 1.0),
                                              Emission_Color=(1.0, 1.0, 1.0, 1.0), Emission_Strength=1e30))
    lit_box(scene, "HotBox", hot, scale=(0.6, 0.6, 0.6))
    add_mesh(scene, "Floor", location=(0, 0, -1.5), scale=(4, 4, 0.1))
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "hot.exr")
    bpy.ops.render.render(write_still=True)
    from addon_scenes import read_exr
    image = read_exr(tmp_path / "hot.exr")
    assert np.all(np.isfinite(image))
    assert image[12, 12, :3].min() > 1e29  # the emitter itself, seen directly


def test_nan_in_a_volume_objects_material_names_object_and_input(scene, tmp_path):
    try:
        openvdb = evg.import_openvdb()
    except evg.OpenVDBUnavailable:
        pytest.skip("no openvdb in this Blender")
    grid = openvdb.FloatGrid()
    grid.name = "density"
    grid.copyFromArray(np.ones((4, 4, 4), np.float32))
    grid.transform = openvdb.createLinearTransform(voxelSize=0.25)
    path = tmp_path / "cube.vdb"
    openvdb.write(str(path), grids=[grid])
    volume = bpy.data.volumes.new("Smoke")
    volume.filepath = str(path)
    material = node_material("SmokeMat", volume=shader("ShaderNodeVolumePrincipled", Color=(0.5, NAN, 0.5, 1.0)))
    volume.materials.append(material)
    smoke = bpy.data.objects.new("Smoke", volume)
    scene.collection.objects.link(smoke)
    twin = bpy.data.objects.new("SmokeTwin", bpy.data.volumes.new("Twin"))
    twin.data.filepath = str(path)
    twin.location = (2.0, 0.0, 0.0)
    twin.rotation_euler = (0.0, 0.0, NAN)
    scene.collection.objects.link(twin)
    lit_box(scene)
    native, messages = export_quietly(scene)
    assert any("volume 'Smoke'" in m and "material 'SmokeMat'" in m and "input 'Color' is NaN" in m
               for m in messages), messages
    assert any("object 'SmokeTwin'" in m and "rotation_euler" in m for m in messages), messages
    assert all(medium.is_homogeneous for medium in native.media)  # both Volume objects skipped
