"""Lights, camera and film against hand-computed values (Cycles: intern/cycles/blender/light.cpp,
scene/light.cpp; Blender's viewplane for the camera)."""
import math

import bpy
import numpy as np
import pytest

import volpath_native as vp
from addon_scenes import add_light, export


def _only_light(sc):
    scene, _ = export(sc)
    assert len(scene.lights) == 1
    return scene.lights[0]


def test_point_light_power_colour_exposure(scene):
    obj = add_light(scene, "Bulb", "POINT", 100.0, location=(1, 2, 3), color=(1.0, 0.5, 0.25),
                    shadow_soft_size=0.2)
    expected = np.array([100.0, 50.0, 25.0])
    if hasattr(obj.data, "exposure"):
        obj.data.exposure = 1.0
        expected *= 2.0
    light = _only_light(scene)
    assert isinstance(light, vp.PointLight) and not isinstance(light, vp.SpotLight)
    np.testing.assert_allclose(light.power, expected, rtol=1e-6)
    np.testing.assert_allclose(light.position, [1, 2, 3], atol=1e-6)
    assert light.radius == pytest.approx(0.2)


@pytest.mark.skipif("normalize" not in bpy.types.Light.bl_rna.properties, reason="Light.normalize is Blender 4.1+")
def test_unnormalized_point_light_scales_by_area(scene):
    add_light(scene, "Raw", "POINT", 10.0, shadow_soft_size=0.5, normalize=False)
    # Cycles: invarea = 1 instead of 1/area, area = 4 pi r^2.
    np.testing.assert_allclose(_only_light(scene).power, 10.0 * 4 * math.pi * 0.25, rtol=1e-6)


@pytest.mark.skipif("temperature" not in bpy.types.Light.bl_rna.properties, reason="light temperature is Blender 4.5+")
def test_light_temperature_colour(scene):
    obj = add_light(scene, "Warm", "POINT", 10.0, use_temperature=True, temperature=3000.0)
    expected = 10.0 * np.array(obj.data.temperature_color[:3])
    assert expected[0] > expected[2]  # warm
    np.testing.assert_allclose(_only_light(scene).power, expected, rtol=1e-6)


def test_spot_light(scene):
    add_light(scene, "Spot", "SPOT", 500.0, rotation=(math.pi / 2, 0, 0), spot_size=math.radians(30),
              spot_blend=0.4, shadow_soft_size=0.0)
    light = _only_light(scene)
    assert isinstance(light, vp.SpotLight)
    np.testing.assert_allclose(light.direction, [0, 1, 0], atol=1e-6)  # local -Z rotated to +Y
    assert light.spot_size == pytest.approx(math.radians(30))
    assert light.spot_blend == pytest.approx(0.4)
    np.testing.assert_allclose(light.power, 500.0, rtol=1e-6)


def test_area_rectangle_with_object_scale(scene):
    obj = add_light(scene, "Panel", "AREA", 40.0, location=(0, 0, 2), shape="RECTANGLE", size=2.0, size_y=0.5)
    obj.scale = (1.5, 2.0, 1.0)
    light = _only_light(scene)
    np.testing.assert_allclose(light.axis_u, [3.0, 0, 0], atol=1e-6)
    np.testing.assert_allclose(np.abs(light.axis_v), [0, 1.0, 0], atol=1e-6)
    np.testing.assert_allclose(light.direction, [0, 0, -1], atol=1e-6)  # shines down
    assert light.area == pytest.approx(3.0)
    assert light.shape == "rectangle"
    np.testing.assert_allclose(light.power, 40.0, rtol=1e-6)


def test_area_disk_and_mirrored_transform_keeps_direction(scene):
    obj = add_light(scene, "Disk", "AREA", 5.0, shape="DISK", size=1.0)
    obj.scale = (-1.0, 1.0, 1.0)  # mirrored: the lamp still shines down its local -Z
    light = _only_light(scene)
    assert light.shape == "disk"
    assert light.area == pytest.approx(math.pi / 4)
    # Without care -(u x v) would point up here, since u is mirrored.
    np.testing.assert_allclose(light.direction, [0, 0, -1], atol=1e-6)


def test_sun_light(scene):
    add_light(scene, "Sun", "SUN", 3.0, rotation=(0, 0, 0), angle=math.radians(10))
    light = _only_light(scene)
    assert isinstance(light, vp.SunLight)
    np.testing.assert_allclose(light.irradiance, 3.0, rtol=1e-6)
    np.testing.assert_allclose(light.direction, [0, 0, -1], atol=1e-6)
    assert light.angle == pytest.approx(math.radians(10))


def test_instanced_light_counts_twice(scene):
    obj = add_light(scene, "Bulb", "POINT", 1.0)
    copy = obj.copy()
    copy.location = (2, 0, 0)
    scene.collection.objects.link(copy)
    exported, _ = export(scene)
    assert sorted(l.position[0] for l in exported.lights) == pytest.approx([0.0, 2.0])


# ----------------------------------------------------------------------------------------------
# Camera and film
# ----------------------------------------------------------------------------------------------
def test_perspective_camera(scene):
    cam = scene.camera
    cam.data.lens = 35.0
    cam.data.sensor_width = 36.0
    cam.data.shift_x, cam.data.shift_y = 0.1, -0.05
    cam.data.clip_start, cam.data.clip_end = 0.5, 50.0
    cam.scale = (2.0, 2.0, 2.0)  # ignored by camera rays
    exported, _ = export(scene)
    camera = exported.camera
    assert camera.projection == "perspective"
    assert camera.fov == pytest.approx(2 * math.atan(18.0 / 35.0))
    assert (camera.shift_x, camera.shift_y) == pytest.approx((0.1, -0.05))
    assert (camera.clip_start, camera.clip_end) == pytest.approx((0.5, 50.0))
    np.testing.assert_allclose(camera.camera_to_world[:3, 2], [0, -1, 0], atol=1e-6)  # looks +Y
    np.testing.assert_allclose(camera.camera_to_world[:3, 3], [0, -6, 0], atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(camera.camera_to_world[:3, :3], axis=0), 1.0, atol=1e-6)


def test_vertical_sensor_fit_uses_sensor_height(scene):
    cam = scene.camera.data
    cam.sensor_fit = "VERTICAL"
    cam.sensor_height = 24.0
    cam.lens = 50.0
    camera = export(scene)[0].camera
    assert camera.sensor_fit == "VERTICAL"
    assert camera.fov == pytest.approx(2 * math.atan(12.0 / 50.0))


def test_orthographic_camera(scene):
    scene.camera.data.type = "ORTHO"
    scene.camera.data.ortho_scale = 4.5
    camera = export(scene)[0].camera
    assert camera.projection == "orthographic" and camera.ortho_scale == pytest.approx(4.5)


def test_resolution_percentage_border_and_filter(scene):
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 37, 23, 50  # -> 18 x 11
    r.use_border = True
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.1, 0.77, 0.25, 0.9
    scene.cycles.pixel_filter_type = "GAUSSIAN"
    scene.cycles.filter_width = 2.0
    film = export(scene)[0].film
    assert (film.width, film.height) == (18, 11)
    # Blender truncates border edges to pixels: x 1..13, y 2..9 (from the bottom).
    assert film.crop == pytest.approx((1 / 18, 13 / 18, 2 / 11, 9 / 11))
    assert (film.filter, film.filter_width) == ("gaussian", 2.0)


def test_no_camera_is_a_clear_error(scene):
    scene.camera = None
    with pytest.raises(vp.SceneError, match="no active camera"):
        export(scene)


def test_light_hidden_from_camera(scene):
    obj = add_light(scene, "Hidden", "AREA", 10.0)
    obj.visible_camera = False
    assert _only_light(scene).visible_camera is False


def test_light_node_tree_scales_strength(scene):
    obj = add_light(scene, "Lamp", "POINT", 10.0)
    obj.data.use_nodes = True
    emission = next(n for n in obj.data.node_tree.nodes if n.type == "EMISSION")
    emission.inputs["Color"].default_value = (1.0, 0.5, 0.0, 1.0)
    emission.inputs["Strength"].default_value = 3.0
    np.testing.assert_allclose(_only_light(scene).power, [30.0, 15.0, 0.0], rtol=1e-6)


def test_unsupported_light_nodes_fall_back_to_plain_light(scene):
    obj = add_light(scene, "Lamp", "POINT", 10.0)
    obj.data.use_nodes = True
    tree = obj.data.node_tree
    emission = next(n for n in tree.nodes if n.type == "EMISSION")
    texture = tree.nodes.new("ShaderNodeTexNoise")
    tree.links.new(texture.outputs["Color"], emission.inputs["Color"])
    light = _only_light(scene)
    np.testing.assert_allclose(light.power, 10.0, rtol=1e-6)
    assert any("'Lamp'" in w and "not fully supported" in w for w in export(scene)[1])


def test_plain_lights_export_without_warnings(scene):
    for kind in ("POINT", "SPOT", "AREA", "SUN"):
        obj = add_light(scene, kind.title(), kind, 10.0)
        obj.visible_camera = True
    assert export(scene)[1] == []
