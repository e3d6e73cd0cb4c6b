"""Instanced meshes and object / deformation motion in the scene model: the Mesh fields, their
.vpscene round trip and schema checks, and the world-space expansion used as reference."""
from __future__ import annotations

import numpy as np
import pytest

from volpath_native import Camera, Film, Material, Mesh, Scene, SceneError, load_scene, save_scene

from native_helpers import box_mesh, camera_at


def rotation_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def placed(linear, offset):
    return np.concatenate([np.asarray(linear, float), np.asarray(offset, float)[:, None]], axis=1)


def instanced_box(k=3, motion_steps=0, deforming=False):
    box = box_mesh("proto", [-0.5, -0.5, -0.5], [0.5, 0.5, 0.5])
    box.corner_normals = np.tile(np.float32([0, 0, 1]), (12, 3, 1))
    box.instances = np.stack([placed(rotation_z(0.3 * i) * (1 + 0.5 * i), [2.0 * i, 0, 0]) for i in range(k)])
    if motion_steps:
        box.motion = np.stack([[placed(rotation_z(0.3 * i + 0.1 * s), [2.0 * i, 0.1 * s, 0])
                                for s in range(motion_steps)] for i in range(k)])
    if deforming:
        box.vertex_motion = np.stack([box.vertices * (1 + 0.1 * s) for s in range(3)])
        box.corner_normal_motion = np.stack([box.corner_normals] * 3)
    box.__post_init__()
    return box


def scene_of(meshes):
    return Scene(camera=Camera(camera_at([0, 0, 6])), film=Film(4, 4), meshes=meshes,
                 materials=[Material("grey")])


def test_instanced_fields_round_trip(tmp_path):
    mesh = instanced_box(3, motion_steps=3, deforming=True)
    scene = scene_of([mesh, box_mesh("plain", [-1, -1, -3], [1, 1, -2])])
    assert scene.validate() == []
    loaded = load_scene(save_scene(scene, tmp_path / "s.vpscene"))
    a, b = loaded.meshes
    for name in ("instances", "motion", "vertex_motion", "corner_normal_motion"):
        np.testing.assert_array_equal(getattr(a, name), getattr(mesh, name))
        assert getattr(b, name) is None
    assert (a.instance_count, a.motion_steps, a.vertex_motion_steps) == (3, 3, 3)


@pytest.mark.parametrize("field,value,message", [
    ("motion", np.zeros((2, 3, 3, 4)), "motion must have shape"),
    ("motion", np.zeros((3, 1, 3, 4)), "motion must have shape"),
    ("vertex_motion", np.zeros((2, 5, 3)), "vertex_motion must have shape"),
    ("instances", np.full((3, 3, 4), np.nan), "instances are not finite"),
])
def test_bad_placement_is_refused(field, value, message):
    mesh = instanced_box(3, motion_steps=2)
    setattr(mesh, field, value)
    with pytest.raises(SceneError, match=message):
        scene_of([mesh]).validate()


def test_motion_without_instances_is_refused():
    mesh = box_mesh("m", [0, 0, 0], [1, 1, 1])
    mesh.motion = np.zeros((1, 2, 3, 4))
    with pytest.raises(SceneError, match="motion needs instances"):
        scene_of([mesh]).validate()


def test_schema_names_a_bad_placement_array(tmp_path):
    from test_scene_files import read_archive, write_archive
    path = save_scene(scene_of([instanced_box(3, motion_steps=2)]), tmp_path / "s.vpscene")
    header, arrays = read_archive(path)
    arrays["mesh0.motion"] = arrays["mesh0.motion"][:, :1]
    with pytest.raises(SceneError, match=r"meshes\[0\]\.motion"):
        load_scene(write_archive(tmp_path / "bad.vpscene", header, arrays))
    header["meshes"][0]["instances"] = False
    arrays["mesh0.motion"] = np.zeros((3, 2, 3, 4))
    with pytest.raises(SceneError, match="motion needs instances"):
        load_scene(write_archive(tmp_path / "bad2.vpscene", header, arrays))


def test_world_copies_place_vertices_normals_and_frames():
    mesh = instanced_box(2)
    mesh.instances[1] = placed(np.diag([1.0, 1.0, -2.0]), [0, 3, 0])  # mirrored: winding flips
    copies = mesh.world_copies()
    assert len(copies) == 2
    for copy, transform in zip(copies, mesh.instances):
        linear, offset = transform[:, :3], transform[:, 3]
        # the geometric normal stays outward: each face's normal points away from the box centre
        p = copy.vertices[copy.triangles].astype(float)
        normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        assert np.all(np.einsum("ij,ij->i", normal, p.mean(axis=1) - offset) > 0)
        # world -> object of the copy maps its vertices back to the prototype's
        frame = copy.object_frame[0]
        back = copy.vertices.astype(float) @ frame[:, :3].T + frame[:, 3]
        assert np.allclose(np.sort(back, axis=0), np.sort(mesh.vertices.astype(float), axis=0), atol=1e-5)
        expected = mesh.corner_normals[0, 0] @ np.linalg.inv(linear)
        assert np.allclose(copy.corner_normals[0, 0], expected / np.linalg.norm(expected), atol=1e-6)
