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


# ---------------------------------------------------------------------------------------------
# Rendering: an instanced scene against the same scene flattened into world-space meshes
# ---------------------------------------------------------------------------------------------
from volpath_native import PointLight, RenderSettings, World, render  # noqa: E402

from native_helpers import Z_LIMIT, block_z_scores, icosphere, tiny_box_film  # noqa: E402


def smooth_sphere(name, material=0):
    sphere = icosphere(name, radius=0.7, subdivisions=2, material=material)
    normals = sphere.vertices[sphere.triangles].astype(np.float64)
    sphere.corner_normals = (normals / np.linalg.norm(normals, axis=2, keepdims=True)).astype(np.float32)
    sphere.vertices = sphere.vertices * np.float32([1.0, 0.8, 1.2])  # the normals are not the radial ones
    sphere.__post_init__()
    return sphere


def sphere_instances():
    """Four placements: translation, rotation + non-uniform scale, a mirror, a shear."""
    shear = np.array([[1.0, 0.4, 0], [0, 1, 0], [0, 0, 1]])
    return np.stack([placed(np.eye(3), [-1.6, 1.2, 0]),
                     placed(rotation_z(0.8) @ np.diag([1.3, 0.6, 1.0]), [1.5, 1.1, 0.2]),
                     placed(np.diag([-1.0, 1.0, 1.0]), [-1.4, -1.3, 0]),
                     placed(shear, [1.4, -1.2, -0.3])])


def instanced_scene(instances, seed=1, flatten=False, spp=96):
    sphere = smooth_sphere("sphere")
    sphere.instances = instances
    meshes = sphere.world_copies() if flatten else [sphere]
    floor = box_mesh("floor", [-4, -4, -3], [4, 4, -2], material=1)
    return Scene(camera=Camera(camera_at([0, 0, 8])), film=tiny_box_film(24),
                 meshes=meshes + [floor],
                 materials=[Material("grey", base_color=0.7), Material("floor", base_color=0.4)],
                 lights=[PointLight("lamp", [2, 3, 6], power=2000.0)], world=World(background=0.3),
                 settings=RenderSettings(samples=spp, seed=seed, threads=1, max_bounces=3))


def test_instanced_render_matches_the_flattened_scene():
    instances = sphere_instances()
    scene = instanced_scene(instances, seed=1)
    assert scene.validate() == []
    instanced = render(scene)
    flattened = render(instanced_scene(instances, seed=2, flatten=True))
    z = block_z_scores(instanced, flattened, block=2)
    assert np.all(np.isfinite(instanced.image))
    assert np.abs(z).max() < Z_LIMIT, np.abs(z).max()
    # a planted wrong instance transform (the sheared one moved by 0.3) is caught
    wrong = instances.copy()
    wrong[3, :, 3] += [0.3, 0.0, 0.0]
    moved = render(instanced_scene(wrong, seed=2, flatten=True))
    assert np.abs(block_z_scores(instanced, moved, block=2)).max() > Z_LIMIT


def test_instanced_emitter_is_flattened_for_light_sampling():
    from volpath_native.accel import Accelerator
    sphere = smooth_sphere("lamp")
    sphere.instances = sphere_instances()[:2]
    materials = [Material("glow", emission=5.0)]
    accel = Accelerator([sphere], materials)
    assert accel.instance_count == 0 and accel.triangle_count == 2 * len(sphere.triangles)
    accel = Accelerator([sphere], [Material("grey")])
    assert accel.instance_count == 2 and accel.triangle_count == len(sphere.triangles)


def test_instance_frames_and_normals_match_the_world_copies():
    from volpath_native.accel import Accelerator
    sphere = smooth_sphere("s")
    sphere.instances = sphere_instances()
    accel = Accelerator([sphere], [Material("grey")])
    frames = accel.mesh_frames()[accel.instance_frame_base:]
    copies = sphere.world_copies()
    assert len(frames) == len(copies) == accel.instance_count == 4
    for k, copy in enumerate(copies):
        np.testing.assert_allclose(frames[k], copy.object_frame, atol=1e-12)
        # the outward geometric normal of triangle 0 through the instance = the copy's own
        expected = np.cross(*(copy.vertices[copy.triangles[0]][1:] - copy.vertices[copy.triangles[0]][0]))
        got = accel.geometric_normals(np.int32([0]), np.int32([k]))[0]
        np.testing.assert_allclose(got, expected / np.linalg.norm(expected), atol=1e-5)


def test_four_by_four_matrices_are_taken_and_bad_shapes_named():
    mesh = box_mesh("b", [0, 0, 0], [1, 1, 1])
    full = np.tile(np.eye(4), (2, 1, 1))
    full[1, :3, 3] = [2, 0, 0]
    placed_mesh = Mesh("b", mesh.vertices, mesh.triangles, mesh.material_ids, instances=full,
                       motion=np.stack([full, full], axis=1))
    assert placed_mesh.instances.shape == (2, 3, 4) and placed_mesh.motion.shape == (2, 2, 3, 4)
    np.testing.assert_array_equal(placed_mesh.instances[1, :, 3], [2, 0, 0])
    with pytest.raises(SceneError, match="instances: expected 3 dimensions"):
        Mesh("b", mesh.vertices, mesh.triangles, mesh.material_ids, instances=np.zeros((2, 3, 3)))
