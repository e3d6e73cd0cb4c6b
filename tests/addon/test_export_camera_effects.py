"""Depth of field, panoramic cameras and motion blur exported as Cycles syncs them
(intern/cycles/blender/camera.cpp, blender/sync.cpp sync_motion), with Cycles' values and a
warning naming the camera for the numbers Cycles corrects."""
import math

import bpy
import numpy as np
import pytest

import volpath_native as vp
from addon.export.motion import CYCLES_MOVING_VOLUME_NOTE
from addon_scenes import add_mesh, export


def _camera(sc):
    return export(sc)[0].camera


def test_depth_of_field_from_f_stop(scene):
    data = scene.camera.data
    data.lens = 50.0
    data.dof.use_dof = True
    data.dof.aperture_fstop = 2.8
    data.dof.focus_distance = 4.0
    data.dof.aperture_blades = 6
    data.dof.aperture_rotation = 0.3
    data.dof.aperture_ratio = 2.0
    camera, warnings = export(scene)
    camera = camera.camera
    assert camera.aperture_size == pytest.approx(0.05 / (2 * 2.8))  # lens / (2 F-stop), metres
    assert camera.focus_distance == pytest.approx(4.0)
    assert (camera.aperture_blades, camera.aperture_ratio) == (6, pytest.approx(2.0))
    assert camera.aperture_rotation == pytest.approx(0.3)
    assert not [w for w in warnings if "camera" in w]


def test_depth_of_field_off_is_a_pinhole(scene):
    scene.camera.data.dof.use_dof = False
    assert _camera(scene).aperture_size == 0.0


def test_orthographic_aperture_is_one_over_two_f_stops(scene):
    data = scene.camera.data
    data.type = "ORTHO"
    data.dof.use_dof = True
    data.dof.aperture_fstop = 4.0
    assert _camera(scene).aperture_size == pytest.approx(1.0 / 8.0)


def test_focus_object_distance_along_the_view_axis(scene):
    scene.camera.data.dof.use_dof = True
    target = add_mesh(scene, "Target", location=(1.5, 2.0, -0.7))  # camera at (0, -6, 0) looks along +Y
    scene.camera.data.dof.focus_object = target
    assert _camera(scene).focus_distance == pytest.approx(8.0)


def test_zero_f_stop_and_focus_take_cycles_values_with_a_warning(scene):
    data = scene.camera.data
    data.dof.use_dof = True
    data.dof.aperture_fstop = 0.0
    data.dof.focus_distance = 0.0
    exported, warnings = export(scene)
    assert exported.camera.aperture_size == pytest.approx(data.lens * 1e-3 / 2e-5)
    assert exported.camera.focus_distance == pytest.approx(1e-5)
    assert any("'Camera'" in w and "F-stop" in w for w in warnings)
    assert any("'Camera'" in w and "focus distance" in w for w in warnings)


def test_focus_object_that_is_the_camera(scene):
    scene.camera.data.dof.use_dof = True
    scene.camera.data.dof.focus_object = scene.camera
    exported, warnings = export(scene)
    assert exported.camera.focus_distance == pytest.approx(1e-5)
    assert any("camera 'Camera'" in w and "focus object 'Camera'" in w for w in warnings)


@pytest.mark.parametrize("blender_type, native_type", [
    ("EQUIRECTANGULAR", "equirectangular"), ("FISHEYE_EQUIDISTANT", "fisheye_equidistant"),
    ("FISHEYE_EQUISOLID", "fisheye_equisolid"), ("MIRRORBALL", "mirrorball"),
    ("CENTRAL_CYLINDRICAL", "central_cylindrical")])
def test_panoramic_types(scene, blender_type, native_type):
    data = scene.camera.data
    data.type = "PANO"
    data.panorama_type = blender_type
    data.latitude_min, data.latitude_max = -1.0, 1.2
    data.longitude_min, data.longitude_max = -2.0, 2.5
    data.fisheye_fov, data.fisheye_lens = 2.5, 8.0
    if hasattr(data, "central_cylindrical_radius"):
        data.central_cylindrical_range_v_min, data.central_cylindrical_range_v_max = -2.0, 3.0
        data.central_cylindrical_radius = 2.0
    camera = _camera(scene)
    assert camera.projection == "panoramic" and camera.panorama_type == native_type
    assert (camera.latitude_min, camera.latitude_max) == pytest.approx((-1.0, 1.2))
    assert (camera.longitude_min, camera.longitude_max) == pytest.approx((-2.0, 2.5))
    assert (camera.fisheye_fov, camera.fisheye_lens) == pytest.approx((2.5, 8.0))
    if hasattr(data, "central_cylindrical_radius"):
        assert (camera.cylinder_v_min, camera.cylinder_v_max) == pytest.approx((-1.0, 1.5))  # over the radius


def test_unsupported_panorama_is_a_clear_error(scene):
    scene.camera.data.type = "PANO"
    scene.camera.data.panorama_type = "FISHEYE_LENS_POLYNOMIAL"
    with pytest.raises(vp.SceneError, match="camera 'Camera'.*FISHEYE_LENS_POLYNOMIAL"):
        export(scene)


def _animate_camera(scene, start=(0.0, -6.0, 0.0), end=(2.0, -6.0, 0.0)):
    cam = scene.camera
    scene.frame_set(1)
    cam.location = start
    cam.keyframe_insert("location", frame=1)
    cam.location = end
    cam.keyframe_insert("location", frame=3)
    _make_linear(cam)
    scene.frame_set(2)


def _make_linear(obj):
    action = obj.animation_data.action
    curves = action.fcurves if hasattr(action, "fcurves") else [c for layer in action.layers for strip in layer.strips
                                                                for bag in strip.channelbags for c in bag.fcurves]
    for curve in curves:
        for point in curve.keyframe_points:
            point.interpolation = "LINEAR"


@pytest.mark.parametrize("position, centre", [("CENTER", 2.0), ("START", 2.25), ("END", 1.75)])
def test_camera_motion_steps_over_the_shutter(scene, position, centre):
    _animate_camera(scene)
    scene.render.use_motion_blur = True
    scene.render.motion_blur_shutter = 0.5
    scene.render.motion_blur_position = position
    camera, warnings = export(scene)
    camera = camera.camera
    # 3 steps (Cycles' default 1 motion step: 2 << 0 + 1) at centre - 0.25, centre, centre + 0.25 frames;
    # the camera moves 1 unit along x per frame from x = 0 at frame 1.
    xs = [m[0, 3] for m in camera.motion_transforms]
    np.testing.assert_allclose(xs, [centre - 1.25, centre - 1.0, centre - 0.75], atol=1e-5)
    assert camera.camera_to_world[0, 3] == pytest.approx(centre - 1.0, abs=1e-5)
    assert (scene.frame_current, scene.frame_subframe) == (2, 0.0)  # the frame comes back
    assert not any("move during the shutter" in w for w in warnings)


def test_moving_object_with_a_varying_volume_moves_its_medium(scene):
    """A mesh whose volume shader varies in space moves with its medium: the mesh gets its motion
    steps and its program medium the same transforms (Cycles shades it at the ray's time)."""
    from addon_scenes import node_material
    from test_export_procedural_volumes import height_fog

    scene.render.use_motion_blur = True
    scene.render.motion_blur_shutter = 0.5
    box = add_mesh(scene, "Mover", material=node_material("Fog", volume=height_fog))
    _animate(box, "location", (0.0, 0.0, 0.0), (0.0, 0.0, 4.0))  # 2 units per frame
    exported, warnings = export(scene)
    (mesh,) = exported.meshes
    assert mesh.motion_steps == 3
    medium = exported.media[exported.materials[mesh.material_ids[0]].medium]
    assert not medium.is_homogeneous and medium.motion is not None
    np.testing.assert_allclose(medium.motion[:, 2, 3], [1.5, 2.0, 2.5], atol=1e-5)
    np.testing.assert_allclose(medium.motion_object_to_world[2, 3], 2.0, atol=1e-5)
    assert not any("shutter centre" in w or "move during the shutter" in w for w in warnings), warnings
    # the known difference is told (Cycles' blur of a moving volume is biased), naming the datablock
    assert any(w.startswith("material 'Fog' on 'Mover'") and CYCLES_MOVING_VOLUME_NOTE in w for w in warnings), warnings
    # planted: a still object's medium gets no motion
    scene.render.use_motion_blur = False
    exported, still_warnings = export(scene)
    assert all(getattr(m, "motion", None) is None for m in exported.media)
    assert not any(CYCLES_MOVING_VOLUME_NOTE in w for w in still_warnings), still_warnings


def test_zero_shutter_warns_and_does_not_move(scene):
    _animate_camera(scene)
    scene.render.use_motion_blur = True
    scene.render.motion_blur_shutter = 0.0
    camera, warnings = export(scene)
    xs = [m[0, 3] for m in camera.camera.motion_transforms]
    np.testing.assert_allclose(xs, 1.0, atol=1e-6)
    assert any("camera 'Camera'" in w and "shutter of 0" in w for w in warnings)


def test_shutter_curve_and_rolling_shutter(scene):
    render = scene.render
    render.use_motion_blur = True
    points = render.motion_blur_shutter_curve.curves[0].points
    points[0].location = (0.0, 0.0)
    points[-1].location = (1.0, 1.0)
    render.motion_blur_shutter_curve.update()
    if not hasattr(scene, "cycles"):
        pytest.skip("Cycles is not registered")
    scene.cycles.rolling_shutter_type = "TOP"
    scene.cycles.rolling_shutter_duration = 0.3
    camera = _camera(scene)
    assert len(camera.shutter_curve) == 256
    assert camera.shutter_curve[0] == pytest.approx(0.0, abs=1e-6)
    assert camera.shutter_curve[-1] == pytest.approx(1.0, abs=1e-6)
    assert camera.rolling_shutter and camera.rolling_shutter_duration == pytest.approx(0.3)


def test_motion_blur_off_has_no_motion(scene):
    _animate_camera(scene)
    scene.render.use_motion_blur = False
    camera = _camera(scene)
    assert camera.motion_transforms == [] and camera.shutter_curve == []


def _animate(obj, attribute, start, end, frames=(1, 3)):
    scene = bpy.context.scene
    scene.frame_set(frames[0])
    setattr(obj, attribute, start)
    obj.keyframe_insert(attribute, frame=frames[0])
    setattr(obj, attribute, end)
    obj.keyframe_insert(attribute, frame=frames[1])
    _make_linear(obj.id_data)  # a modifier's keys live on its object
    scene.frame_set(2)


def test_moving_object_gets_its_transforms_over_the_shutter(scene):
    """Cycles' object motion (blender/object.cpp sync_object in motion passes): matrix_world at the
    object's 3 motion steps over the shutter, the frame's transform as its instance."""
    scene.render.use_motion_blur = True
    scene.render.motion_blur_shutter = 0.5
    _animate(add_mesh(scene, "Mover"), "location", (0.0, 0.0, 0.0), (0.0, 0.0, 4.0))  # 2 units per frame
    exported, warnings = export(scene)
    (mesh,) = exported.meshes
    assert mesh.instance_count == 1 and mesh.motion_steps == 3
    np.testing.assert_allclose(mesh.motion[0, :, 2, 3], [1.5, 2.0, 2.5], atol=1e-5)
    np.testing.assert_allclose(mesh.instances[0][2, 3], 2.0, atol=1e-5)
    np.testing.assert_allclose(mesh.vertices.mean(axis=0), 0.0, atol=1e-6)  # object space
    assert not any("move during the shutter" in w for w in warnings), warnings


def test_motion_steps_and_switches_per_object(scene):
    scene.render.use_motion_blur = True
    fast = add_mesh(scene, "Fast")
    fast.cycles.motion_steps = 2  # (2 << 1) + 1 = 5 transforms
    _animate(fast, "location", (0.0, 0.0, 0.0), (4.0, 0.0, 0.0))
    still = add_mesh(scene, "Still", location=(0, 5, 0))
    still.cycles.use_motion_blur = False
    _animate(still, "location", (0.0, 5.0, 0.0), (4.0, 5.0, 0.0))
    meshes = {m.name: m for m in export(scene)[0].meshes}
    assert meshes["Fast"].motion_steps == 5
    np.testing.assert_allclose(meshes["Fast"].motion[0, :, 0, 3], [1.5, 1.75, 2.0, 2.25, 2.5], atol=1e-5)
    assert meshes["Still"].motion is None and meshes["Still"].instances is None  # at the shutter centre
    scene.render.use_motion_blur = False
    assert all(m.motion is None for m in export(scene)[0].meshes)


def test_deforming_mesh_gets_its_vertex_positions_over_the_shutter(scene):
    """A mesh deformed by an animated modifier (Cycles blender/mesh.cpp sync_mesh_motion)."""
    scene.render.use_motion_blur = True
    obj = add_mesh(scene, "Wobble")
    warp = obj.modifiers.new("Scale", "DISPLACE")
    warp.direction = "Z"
    # without a texture every vertex moves (1 - midlevel 0.5) x strength along z: strength grows 1 a
    # frame, the default shutter is 0.5 frames -> +-0.25 frames -> +-0.125
    _animate(warp, "strength", 0.0, 2.0)
    (mesh,) = export(scene)[0].meshes
    assert mesh.vertex_motion_steps == 3 and mesh.motion is None
    shift = mesh.vertex_motion[:, :, 2] - mesh.vertices[None, :, 2]
    np.testing.assert_allclose(shift, [[-0.125] * 8, [0.0] * 8, [0.125] * 8], atol=1e-5)


def test_deforming_varying_volume_keeps_its_deformation_inside_its_medium_box(scene):
    """A mesh with a varying volume deformed during the shutter: its boundary deforms (vertex
    steps) and its medium's box holds every step's vertices (Cycles evaluates the shader wherever
    the deformed boundary goes; its density follows the object's transform only)."""
    from addon_scenes import node_material
    from test_export_procedural_volumes import height_fog

    scene.render.use_motion_blur = True
    obj = add_mesh(scene, "Wobble", material=node_material("Fog", volume=height_fog))
    warp = obj.modifiers.new("Scale", "DISPLACE")
    warp.direction = "Z"
    _animate(warp, "strength", 0.0, 2.0)  # +-0.125 along z over the shutter (see above)
    exported, warnings = export(scene)
    (mesh,) = exported.meshes
    assert mesh.vertex_motion_steps == 3
    medium = exported.media[exported.materials[mesh.material_ids[0]].medium]
    lo, hi = medium.object_bounds
    assert lo[2] <= mesh.vertex_motion[..., 2].min() + 1e-6 and hi[2] >= mesh.vertex_motion[..., 2].max() - 1e-6
    assert hi[2] - lo[2] > np.ptp(mesh.vertices[:, 2]) + 0.2  # planted: the frame's box alone is too small
    assert not any("shutter centre" in w for w in warnings), warnings


def test_moving_light_stays_at_the_shutter_centre_as_in_cycles(scene):
    from addon_scenes import add_light

    scene.render.use_motion_blur = True
    _animate(add_light(scene, "Lamp", "POINT", 100.0), "location", (0.0, 0.0, 0.0), (4.0, 0.0, 0.0))
    exported, warnings = export(scene)
    assert exported.lights[0].position[0] == pytest.approx(2.0)
    assert any("'Lamp'" in w and "as Cycles does" in w for w in warnings), warnings


def test_a_moving_and_a_still_copy_share_one_mesh(scene):
    scene.render.use_motion_blur = True
    mover = add_mesh(scene, "Mover")
    still = mover.copy()  # a linked duplicate: the same mesh
    still.location = (0.0, 5.0, 0.0)
    scene.collection.objects.link(still)
    _animate(mover, "location", (0.0, 0.0, 0.0), (4.0, 0.0, 0.0))
    (mesh,) = export(scene)[0].meshes
    assert mesh.instance_count == 2 and mesh.motion.shape == (2, 3, 3, 4)
    moving = int(np.argmax(np.ptp(mesh.motion[:, :, 0, 3], axis=1)))
    np.testing.assert_allclose(mesh.motion[moving, :, 0, 3], [1.5, 2.0, 2.5], atol=1e-5)
    np.testing.assert_allclose(mesh.motion[1 - moving, :, 1, 3], [5.0] * 3, atol=1e-6)  # repeated: it stands still
