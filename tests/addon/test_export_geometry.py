"""Geometry: modifiers, instancing, transforms, normals and per-face materials, all from the
evaluated depsgraph."""
import time

import bpy
import numpy as np
import pytest

from addon_scenes import CUBE_FACES, CUBE_VERTICES, add_mesh, export, node_material, shader


def test_world_transform_and_winding(scene):
    add_mesh(scene, "Box", location=(1, 2, 3), scale=(2, 1, 0.5))
    mesh = export(scene)[0].meshes[0]
    assert mesh.triangles.shape == (12, 3)
    np.testing.assert_allclose(mesh.vertices.min(axis=0), [-1, 1, 2.5], atol=1e-6)
    np.testing.assert_allclose(mesh.vertices.max(axis=0), [3, 3, 3.5], atol=1e-6)
    assert mesh.open_edge_count() == 0
    assert _outward_fraction(mesh) == 1.0
    assert mesh.corner_normals is None  # flat


def _outward_fraction(mesh):
    v = mesh.vertices[mesh.triangles].astype(np.float64)
    normal = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    outward = v.mean(axis=1) - mesh.vertices.mean(axis=0)
    return float(np.mean(np.einsum("ij,ij->i", normal, outward) > 0))


def test_mirrored_object_keeps_outward_normals(scene):
    add_mesh(scene, "Mirrored", scale=(-1, 1, 1))
    assert _outward_fraction(export(scene)[0].meshes[0]) == 1.0


def test_smooth_shading_exports_unit_corner_normals(scene):
    add_mesh(scene, "Smooth", smooth=True, scale=(3, 1, 1))
    mesh = export(scene)[0].meshes[0]
    assert mesh.corner_normals.shape == (12, 3, 3)
    np.testing.assert_allclose(np.linalg.norm(mesh.corner_normals, axis=2), 1.0, atol=1e-5)
    # A smooth cube's corner normal points along the vertex direction (before the scale).
    corner = mesh.corner_normals[0, 0]
    vertex = mesh.vertices[mesh.triangles[0, 0]] / np.array([3.0, 1.0, 1.0]) / np.array([3.0, 1.0, 1.0])
    np.testing.assert_allclose(corner, vertex / np.linalg.norm(vertex), atol=1e-5)


def test_modifiers_are_applied(scene):
    obj = add_mesh(scene, "Sub")
    obj.modifiers.new("Subdivision", "SUBSURF").levels = 2
    array = obj.modifiers.new("Array", "ARRAY")
    array.count = 3
    mesh = export(scene)[0].meshes[0]
    assert len(mesh.triangles) == 3 * 6 * 16 * 2  # 3 copies x 6 faces x 4^2 quads x 2


def test_per_face_material_slots(scene):
    red = node_material("Red", surface=shader("ShaderNodeBsdfDiffuse", Color=(1, 0, 0, 1)))
    blue = node_material("Blue", surface=shader("ShaderNodeBsdfDiffuse", Color=(0, 0, 1, 1)))
    obj = add_mesh(scene, "Two", material=red)
    obj.data.materials.append(blue)
    obj.data.polygons[1].material_index = 1
    exported, _ = export(scene)
    ids = exported.meshes[0].material_ids
    names = [exported.materials[i].name for i in ids]
    assert names.count("Blue") == 2 and names.count("Red") == 10  # one quad = two triangles


def test_linked_duplicates_and_collection_instances(scene):
    original = add_mesh(scene, "Box")
    duplicate = original.copy()  # shares the mesh
    duplicate.location = (5, 0, 0)
    scene.collection.objects.link(duplicate)
    collection = bpy.data.collections.new("Props")
    prop = bpy.data.objects.new("Prop", original.data)
    collection.objects.link(prop)  # not in the scene itself: only through the instancer
    instancer = bpy.data.objects.new("Instancer", None)
    instancer.instance_type = "COLLECTION"
    instancer.instance_collection = collection
    instancer.location = (0, 0, 10)
    scene.collection.objects.link(instancer)
    meshes = export(scene)[0].meshes
    # one copy of the shared mesh in object space, placed three times (memory grows with unique geometry)
    assert len(meshes) == 1 and meshes[0].instance_count == 3 and len(meshes[0].triangles) == 12
    np.testing.assert_allclose(sorted(tuple(t[:, 3]) for t in meshes[0].instances), [(0, 0, 0), (0, 0, 10), (5, 0, 0)])
    centres = sorted(tuple(np.round(m.vertices.mean(axis=0), 5)) for m in _in_world(meshes))
    assert centres == [(0, 0, 0), (0, 0, 10), (5, 0, 0)]


def _in_world(meshes):
    return [copy for mesh in meshes for copy in mesh.world_copies()]


def test_a_mesh_used_once_is_placed_in_the_world(scene):
    add_mesh(scene, "Box", location=(1, 2, 3))
    mesh = export(scene)[0].meshes[0]
    assert mesh.instances is None and mesh.motion is None
    np.testing.assert_allclose(mesh.vertices.mean(axis=0), (1, 2, 3), atol=1e-6)


def test_mirrored_instances_keep_outward_normals(scene):
    original = add_mesh(scene, "Box")
    mirrored = original.copy()
    mirrored.scale = (-1, 1, 1)
    mirrored.location = (4, 0, 0)
    scene.collection.objects.link(mirrored)
    (mesh,) = export(scene)[0].meshes
    assert mesh.instance_count == 2 and np.linalg.det(mesh.instances[1][:, :3]) < 0
    assert [_outward_fraction(copy) for copy in mesh.world_copies()] == [1.0, 1.0]


def test_vertex_instancing(scene):
    points = add_mesh(scene, "Points", vertices=[(0, 0, 0), (4, 0, 0), (0, 4, 0)], faces=[])
    child = add_mesh(scene, "Child", scale=(0.5, 0.5, 0.5))
    child.parent = points
    points.instance_type = "VERTS"
    meshes = export(scene)[0].meshes
    # one copy of the child's mesh for its 3 vertex instances and the original (this viewport depsgraph shows it)
    assert [m.instance_count for m in meshes if "Child" in m.name] == [4]
    instances = [m for m in _in_world(meshes) if "Child" in m.name]
    centres = sorted(tuple(np.round(m.vertices.mean(axis=0), 5)) for m in instances)
    assert centres == [(0, 0, 0), (0, 0, 0), (0, 4, 0), (4, 0, 0)]
    assert all(len(m.triangles) == 12 for m in instances)
    np.testing.assert_allclose(np.ptp(instances[0].vertices, axis=0), 1.0, atol=1e-6)  # child scale
    # (Only render-mode depsgraphs hide the original child; this one is the viewport's.)


def test_a_million_triangles_export_in_seconds(scene):
    obj = add_mesh(scene, "Dense")
    obj.modifiers.new("Subdivision", "SUBSURF").levels = 6  # 6 x 4^6 = 24576 quads
    array = obj.modifiers.new("Array", "ARRAY")
    array.count = 21  # -> 1.03M triangles
    obj.data.polygons.foreach_set("use_smooth", [True] * 6)
    depsgraph = bpy.context.evaluated_depsgraph_get()  # evaluate the modifiers outside the timing
    from addon.export import export_scene

    started = time.perf_counter()
    exported, _ = export_scene(depsgraph)
    seconds = time.perf_counter() - started
    n = len(exported.meshes[0].triangles)
    print(f"exported {n} smooth triangles in {seconds:.2f} s")
    assert n == 21 * 6 * 4 ** 6 * 2
    assert seconds < 10.0


def test_unsupported_ray_visibility_warns(scene):
    obj = add_mesh(scene, "Ghost")
    obj.visible_shadow = False
    _, warnings = export(scene)
    assert any("'Ghost'" in w and "Shadow" in w for w in warnings), warnings


@pytest.mark.skipif(bpy.app.version < (4, 0, 0), reason="node group interface API is Blender 4.0+")
def test_geometry_nodes_instances(scene):
    group = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
    group.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = group.nodes, group.links
    line = nodes.new("GeometryNodeMeshLine")
    line.inputs["Count"].default_value = 3
    line.inputs["Offset"].default_value = (2.0, 0.0, 0.0)
    cube = nodes.new("GeometryNodeMeshCube")
    cube.inputs["Size"].default_value = (0.5, 0.5, 0.5)
    on_points = nodes.new("GeometryNodeInstanceOnPoints")
    output = nodes.new("NodeGroupOutput")
    links.new(line.outputs["Mesh"], on_points.inputs["Points"])
    links.new(cube.outputs["Mesh"], on_points.inputs["Instance"])
    links.new(on_points.outputs["Instances"], output.inputs["Geometry"])
    holder = add_mesh(scene, "Holder", vertices=[(0, 0, 0)], faces=[])
    holder.modifiers.new("Scatter", "NODES").node_group = group
    meshes = export(scene)[0].meshes
    assert len(meshes) == 1 and meshes[0].instance_count == 3
    meshes = _in_world(meshes)
    assert len(meshes) == 3 and all(len(m.triangles) == 12 for m in meshes)
    centres = sorted(round(float(m.vertices.mean(axis=0)[0]), 5) for m in meshes)
    assert centres == [0.0, 2.0, 4.0]
    assert all(np.ptp(m.vertices, axis=0) == pytest.approx(0.5) for m in meshes)


def test_mixed_flat_and_smooth_faces_use_vertex_normals_as_cycles(scene):
    """Cycles 5.0 syncs a mesh mixing flat and smooth faces (no sharp edges, no custom normals)
    in Blender's point normal domain (blender/mesh.cpp normals_domain(true)): smooth faces get the
    vertex normals, averaged over the flat faces too; Blender's own corner normals would split them."""
    obj = add_mesh(scene, "Box", smooth=True)
    obj.data.polygons[0].use_smooth = False  # one flat face
    scene_, _ = export(scene)
    mesh = scene_.meshes[0]
    vertex_normals = {tuple(np.round(v.co, 6)): np.array(v.normal) for v in obj.data.vertices}
    flat_face_normal = np.array(obj.data.polygons[0].normal)
    checked_smooth = checked_flat = 0
    for t, tri in enumerate(mesh.triangles):
        corners = mesh.vertices[tri]
        normals = mesh.corner_normals[t]
        expected = [vertex_normals[tuple(np.round(c, 6))] for c in corners]
        if np.allclose(normals, flat_face_normal, atol=1e-5):
            checked_flat += 1
            continue
        np.testing.assert_allclose(normals, expected, atol=1e-5)
        checked_smooth += 1
    assert checked_flat == 2 and checked_smooth == 10


@pytest.mark.parametrize("shading", ["smooth", "flat", "mixed", "sharp_edge"])
def test_block_reads_match_blenders_loop_triangles(scene, shading):
    """triangulate() reads attributes in block copies; it must give what Blender's per-item
    loop-triangle collection says: vertices, material slots, and (smooth) its corner normals."""
    from addon.export import geometry

    red = node_material("Red", surface=shader("ShaderNodeBsdfDiffuse", Color=(1, 0, 0, 1)))
    blue = node_material("Blue", surface=shader("ShaderNodeBsdfDiffuse", Color=(0, 0, 1, 1)))
    obj = add_mesh(scene, "Sub", material=red, smooth=shading != "flat")
    obj.data.materials.append(blue)
    obj.data.polygons[2].material_index = 1
    obj.modifiers.new("Subdivision", "SUBSURF").levels = 2
    if shading == "mixed":
        obj.data.polygons[0].use_smooth = False
    if shading == "sharp_edge":
        obj.data.edges[0].use_edge_sharp = True
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    local = geometry.triangulate(evaluated)
    mesh = evaluated.to_mesh()
    mesh.calc_loop_triangles()
    n = len(mesh.loop_triangles)
    expected_tris = np.empty(n * 3, np.int32)
    mesh.loop_triangles.foreach_get("vertices", expected_tris)
    expected_slots = np.empty(n, np.int32)
    mesh.loop_triangles.foreach_get("material_index", expected_slots)
    expected_co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", expected_co)
    np.testing.assert_array_equal(local.triangles.reshape(-1), expected_tris)
    np.testing.assert_array_equal(local.material_slots, expected_slots)
    assert set(np.unique(expected_slots)) == {0, 1}
    np.testing.assert_array_equal(local.vertices.reshape(-1), expected_co)
    if shading == "flat":
        assert local.corner_normals is None
    elif shading in ("smooth", "sharp_edge"):  # Blender's own corner normals (point domain: vertex normals)
        loops = np.empty(n * 3, np.int32)
        mesh.loop_triangles.foreach_get("loops", loops)
        corner = np.array([mesh.corner_normals[i].vector for i in loops], np.float32).reshape(n, 3, 3)
        np.testing.assert_allclose(local.corner_normals, corner, atol=1e-6)
    evaluated.to_mesh_clear()


def test_triangle_corners_copied_from_blenders_array_match_foreach_get(scene):
    """compat.triangle_corners copies the loop triangles from Blender's array (as_pointer); the
    same corners as the per-item foreach_get, on the evaluated data the exporter reads in place."""
    from addon import compat

    obj = add_mesh(scene, "Sub")
    obj.modifiers.new("Subdivision", "SUBSURF").levels = 3
    obj.modifiers.new("Triangulate", "TRIANGULATE").quad_method = "SHORTEST_DIAGONAL"
    mesh = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    mesh.calc_loop_triangles()
    n = len(mesh.loop_triangles)
    expected = np.empty(3 * n, np.int32)
    mesh.loop_triangles.foreach_get("loops", expected)
    corners = compat.triangle_corners(mesh, n)
    np.testing.assert_array_equal(corners, expected)


def test_a_scene_larger_than_memory_stops_naming_its_objects(scene, monkeypatch):
    """The export stops with a SceneError naming the largest objects before allocating what the
    triangles would need; the same scene exports with the memory it needs."""
    import volpath_native as vp
    from addon.export import validate

    big = add_mesh(scene, "Big")
    big.modifiers.new("Subdivision", "SUBSURF").levels = 4  # 3072 triangles
    add_mesh(scene, "Small", location=(3, 0, 0))  # 12 triangles
    need = (3072 + 12) * validate.BYTES_PER_TRIANGLE
    monkeypatch.setattr(validate, "available_memory", lambda: int(need / 0.9) + 1)
    assert len(export(scene)[0].meshes) == 2  # just enough
    monkeypatch.setattr(validate, "available_memory", lambda: int(need / 0.9) - 4 * validate.BYTES_PER_TRIANGLE)
    with pytest.raises(vp.SceneError) as error:
        export(scene)
    assert "'Big' (3,072 triangles)" in str(error.value) and "too large for the memory" in str(error.value)
