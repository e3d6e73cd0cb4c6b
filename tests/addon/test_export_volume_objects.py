"""Volume objects (OpenVDB grids) through export_scene: a grid medium inside an invisible, closed
bounds mesh. (The grid reading itself is tested in tests/addon_volume.)"""
import numpy as np
import pytest

import bpy
from addon.export.motion import CYCLES_MOVING_VOLUME_NOTE
from addon_scenes import export, node_material, shader


@pytest.fixture
def vdb_file(tmp_path):
    from addon import export_volume_grids

    try:
        openvdb = export_volume_grids.import_openvdb()
    except export_volume_grids.OpenVDBUnavailable as error:
        pytest.skip(str(error))
    density = np.zeros((10, 10, 10), dtype=np.float32)
    density[2:8, 2:8, 2:8] = 3.0
    grid = openvdb.FloatGrid()
    grid.name = "density"
    grid.copyFromArray(density)
    grid.transform = openvdb.createLinearTransform(voxelSize=0.2)
    path = tmp_path / "smoke.vdb"
    openvdb.write(str(path), grids=[grid])
    return path


def test_volume_object_becomes_bounded_grid_medium(scene, vdb_file):
    volume = bpy.data.volumes.new("Smoke")
    volume.filepath = str(vdb_file)
    obj = bpy.data.objects.new("Smoke", volume)
    obj.data.materials.append(node_material("SmokeMat", volume=shader("ShaderNodeVolumePrincipled", Density=2.0)))
    scene.collection.objects.link(obj)
    exported, warnings = export(scene)
    grids = [m for m in exported.media if not m.is_homogeneous]
    assert len(grids) == 1, warnings
    bounds = [m for m in exported.meshes if exported.materials[m.material_ids[0]].medium >= 0]
    assert len(bounds) == 1
    material = exported.materials[bounds[0].material_ids[0]]
    assert material.surface == "null" and exported.media[material.medium] is grids[0]
    assert bounds[0].open_edge_count() == 0


def test_volume_object_renders(scene, vdb_file, tmp_path):
    from addon_scenes import add_light, read_exr

    volume = bpy.data.volumes.new("Smoke")
    volume.filepath = str(vdb_file)
    obj = bpy.data.objects.new("Smoke", volume)
    obj.location = (-1, -1, -1)
    scene.collection.objects.link(obj)
    add_light(scene, "Bulb", "POINT", 500.0, location=(0, 0, 3), shadow_soft_size=0.0)
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "smoke.exr")
    bpy.ops.render.render(write_still=True)
    image = read_exr(tmp_path / "smoke.exr")
    assert np.all(np.isfinite(image))
    centre, corner = image[8:16, 8:16, :3].mean(), image[:4, :4, :3].mean()
    assert centre > 10 * max(corner, 1e-6)  # lit smoke in the middle, black vacuum around


def test_moving_volume_object_exports_its_motion_steps(scene, vdb_file):
    """A Volume object moving over the shutter: its grid medium and its bounds mesh get the object's
    transforms at its motion steps (Cycles shades a moving volume at the ray's time); the one
    message is the note on Cycles' biased blur of it."""
    from test_export_camera_effects import _animate

    volume = bpy.data.volumes.new("Smoke")
    volume.filepath = str(vdb_file)
    obj = bpy.data.objects.new("Smoke", volume)
    obj.data.materials.append(node_material("SmokeMat", volume=shader("ShaderNodeVolumePrincipled", Density=2.0)))
    scene.collection.objects.link(obj)
    scene.render.use_motion_blur = True
    scene.render.motion_blur_shutter = 0.5
    _animate(obj, "location", (0.0, 0.0, 0.0), (4.0, 0.0, 0.0))  # 2 units per frame
    exported, warnings = export(scene)
    (grid,) = [m for m in exported.media if not m.is_homogeneous]
    assert grid.motion is not None and len(grid.motion) == 3
    np.testing.assert_allclose(grid.motion[:, 0, 3], [1.5, 2.0, 2.5], atol=1e-5)
    (bounds,) = [m for m in exported.meshes if exported.materials[m.material_ids[0]].medium >= 0]
    assert bounds.motion_steps == 3 and bounds.open_edge_count() == 0
    np.testing.assert_allclose(bounds.motion[0, :, 0, 3], [1.5, 2.0, 2.5], atol=1e-5)
    assert not any("move during the shutter" in w or "shutter centre" in w for w in warnings), warnings
    # the known difference is told (Cycles' blur of a moving volume is biased), naming the datablock
    assert any(w.startswith("volume 'Smoke'") and CYCLES_MOVING_VOLUME_NOTE in w for w in warnings), warnings
    # planted: motion blur off -> the medium stands still
    scene.render.use_motion_blur = False
    exported, still_warnings = export(scene)
    assert all(getattr(m, "motion", None) is None for m in exported.media)
    assert not any(CYCLES_MOVING_VOLUME_NOTE in w for w in still_warnings), still_warnings
