"""Volume materials driven by nodes: compiled to shader programs, one ProgramMedium per object."""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from volpath_native.program_medium import ProgramMedium  # noqa: E402

from addon_scenes import add_mesh, export, node_material  # noqa: E402


def height_fog(tree, bottom=2.0, top=0.0, coordinate="Object"):
    """Principled Volume, Density = Map Range(coordinate Z, -1..1 -> bottom..top)."""
    nodes, links = tree.nodes, tree.links
    volume = nodes.new("ShaderNodeVolumePrincipled")
    volume.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    coords = nodes.new("ShaderNodeTexCoord")
    separate = nodes.new("ShaderNodeSeparateXYZ")
    map_range = nodes.new("ShaderNodeMapRange")
    for name, value in (("From Min", -1.0 if coordinate == "Object" else 0.0),
                        ("From Max", 1.0), ("To Min", bottom), ("To Max", top)):
        map_range.inputs[name].default_value = value
    links.new(coords.outputs[coordinate], separate.inputs["Vector"])
    links.new(separate.outputs["Z"], map_range.inputs["Value"])
    links.new(map_range.outputs["Result"], volume.inputs["Density"])
    return volume.outputs[0]


def test_a_node_driven_density_becomes_a_program_medium_per_object(scene):
    fog = node_material("Fog", volume=height_fog)
    a = add_mesh(scene, "FogA", material=fog, location=(-1.5, 0, 0))
    b = add_mesh(scene, "FogB", material=fog, location=(1.5, 0, 0.5), scale=(0.5, 0.5, 2.0))
    vp_scene, warnings = export(scene)
    media = [m for m in vp_scene.media if isinstance(m, ProgramMedium)]
    assert len(media) == 2, [type(m).__name__ for m in vp_scene.media]
    assert not [w for w in warnings if "Fog" in w], warnings
    for obj, medium in zip((a, b), sorted(media, key=lambda m: m.name)):
        matrix = np.array(obj.matrix_world)
        # Density at object-space z = -0.5 is 1.5 (Map Range -1..1 -> 2..0), x 0.8 colour for sigma_s
        point = matrix @ np.array([0.2, -0.3, -0.5, 1.0])
        sigma_s, sigma_t, _ = medium.coefficients(point[None, :3])
        assert np.allclose(sigma_t[0], 1.5, rtol=1e-9), (obj.name, sigma_t)
        assert np.allclose(sigma_s[0], 0.8 * 1.5, rtol=1e-6)
    # each object's triangles point at their own medium through a copied material
    for mesh in vp_scene.meshes:
        ids = set(mesh.material_ids.tolist())
        assert len(ids) == 1
        assert isinstance(vp_scene.media[vp_scene.materials[ids.pop()].medium], ProgramMedium)


def test_generated_coordinates_use_the_mesh_texture_space(scene):
    """Generated = (P_obj - L) / 2S + 0.5 (auto texture space = bounds): a cube from -1..1 maps to
    0..1, so Map Range 0..1 -> 2..0 of Generated Z gives 1 at the centre."""
    fog = node_material("GenFog", volume=lambda tree: height_fog(tree, coordinate="Generated"))
    add_mesh(scene, "Fog", material=fog, location=(0.3, 0.2, 0.1), scale=(2.0, 1.0, 0.5))
    vp_scene, _ = export(scene)
    medium = next(m for m in vp_scene.media if isinstance(m, ProgramMedium))
    _, sigma_t, _ = medium.coefficients(np.array([[0.3, 0.2, 0.1], [0.3, 0.2, 0.1 + 0.25]]))
    assert np.allclose(sigma_t[:, 0], [1.0, 0.5], rtol=1e-9)


def test_a_constant_node_tree_stays_homogeneous(scene):
    fog = node_material("Plain", volume=lambda tree: tree.nodes.new("ShaderNodeVolumePrincipled").outputs[0])
    add_mesh(scene, "Fog", material=fog)
    vp_scene, _ = export(scene)
    assert len(vp_scene.media) == 1 and vp_scene.media[0].is_homogeneous


def test_an_unsupported_node_is_named(scene):
    def tree_with_script(tree):
        out = height_fog(tree)
        script = tree.nodes.new("ShaderNodeLightPath")
        volume = next(n for n in tree.nodes if n.type == "PRINCIPLED_VOLUME")
        tree.links.new(script.outputs["Ray Length"], volume.inputs["Anisotropy"])
        return out

    add_mesh(scene, "Fog", material=node_material("Odd", volume=tree_with_script))
    _, warnings = export(scene)
    assert any("Odd" in w and "Light Path" in w for w in warnings), warnings


def test_a_varying_world_volume_fills_a_box_around_the_scene(scene):
    """World Volume = height fog from Geometry Position: a ProgramMedium in a null box around the
    scene (Cycles bounds it at 10 km), named in a warning."""
    world = bpy.data.worlds.new("Foggy")
    scene.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    tree = world.node_tree
    output = next(n for n in tree.nodes if n.type == "OUTPUT_WORLD")
    volume = tree.nodes.new("ShaderNodeVolumePrincipled")
    geometry, separate = tree.nodes.new("ShaderNodeNewGeometry"), tree.nodes.new("ShaderNodeSeparateXYZ")
    map_range = tree.nodes.new("ShaderNodeMapRange")
    map_range.inputs["From Min"].default_value, map_range.inputs["From Max"].default_value = 0.0, 2.0
    map_range.inputs["To Min"].default_value, map_range.inputs["To Max"].default_value = 1.0, 0.0
    tree.links.new(geometry.outputs["Position"], separate.inputs["Vector"])
    tree.links.new(separate.outputs["Z"], map_range.inputs["Value"])
    tree.links.new(map_range.outputs["Result"], volume.inputs["Density"])
    tree.links.new(volume.outputs[0], output.inputs["Volume"])
    add_mesh(scene, "Block")
    vp_scene, warnings = export(scene)
    assert vp_scene.world.medium == -1
    (medium,) = [m for m in vp_scene.media if isinstance(m, ProgramMedium)]
    _, sigma_t, _ = medium.coefficients(np.array([[0.3, 0.2, 0.5], [0.0, 0.0, 3.0]]))
    assert np.allclose(sigma_t[:, 0], [0.75, 0.0])
    box = vp_scene.meshes[-1]
    assert vp_scene.materials[box.material_ids[0]].surface == "null"
    lo, hi = box.vertices.min(axis=0), box.vertices.max(axis=0)
    assert np.all(lo < [-1, -6, -1]) and np.all(hi > [1, 1, 1])  # camera at (0, -6, 0) inside
    assert any("Foggy" in w and "box around the scene" in w for w in warnings), warnings
