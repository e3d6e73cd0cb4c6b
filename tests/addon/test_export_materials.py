"""Materials and the world: each supported node against coefficients computed by hand from
Cycles' formulas (intern/cycles/kernel/svm/closure.h)."""
import math

import bpy
import numpy as np
import pytest

from addon_scenes import add_mesh, export, node_material, shader


def _material(sc, mat):
    add_mesh(sc, "Box", material=mat)
    scene, warnings = export(sc)
    assert len(scene.meshes) == 1
    return scene, scene.materials[int(scene.meshes[0].material_ids[0])], warnings


def test_diffuse_bsdf(scene):
    mat = node_material("Red", surface=shader("ShaderNodeBsdfDiffuse", Color=(0.7, 0.2, 0.1, 1.0)))
    _, material, warnings = _material(scene, mat)
    assert material.surface == "diffuse"
    np.testing.assert_allclose(material.base_color, [0.7, 0.2, 0.1], rtol=1e-6)
    np.testing.assert_allclose(material.emission, 0.0)
    assert warnings == []


def test_principled_bsdf_base_and_emission(scene):
    def principled(tree):
        node = tree.nodes.new("ShaderNodeBsdfPrincipled")
        node.inputs["Base Color"].default_value = (0.3, 0.6, 0.9, 1.0)
        emission = node.inputs.get("Emission Color") or node.inputs["Emission"]
        emission.default_value = (1.0, 0.5, 0.25, 1.0)
        node.inputs["Emission Strength"].default_value = 4.0
        return node.outputs[0]

    _, material, warnings = _material(scene, node_material("P", surface=principled))
    np.testing.assert_allclose(material.base_color, [0.3, 0.6, 0.9], rtol=1e-6)
    np.testing.assert_allclose(material.emission, [4.0, 2.0, 1.0], rtol=1e-6)
    # The default dielectric specular layer is not rendered: the user is told.
    assert any("'P'" in w and "specular" in w for w in warnings)


def test_emission_and_mix_shader(scene):
    def mixed(tree):
        mix = tree.nodes.new("ShaderNodeMixShader")
        mix.inputs[0].default_value = 0.25
        diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = (0.8, 0.8, 0.4, 1.0)
        emission = tree.nodes.new("ShaderNodeEmission")
        emission.inputs["Color"].default_value = (1.0, 0.0, 0.5, 1.0)
        emission.inputs["Strength"].default_value = 10.0
        tree.links.new(diffuse.outputs[0], mix.inputs[1])
        tree.links.new(emission.outputs[0], mix.inputs[2])
        return mix.outputs[0]

    _, material, _ = _material(scene, node_material("Mix", surface=mixed))
    np.testing.assert_allclose(material.base_color, 0.75 * np.array([0.8, 0.8, 0.4]), rtol=1e-6)
    np.testing.assert_allclose(material.emission, 0.25 * np.array([10.0, 0.0, 5.0]), rtol=1e-6)


def test_principled_volume_coefficients(scene):
    color, density, absorption = np.array([0.6, 0.5, 0.2]), 2.0, np.array([0.25, 0.04, 0.0])
    volume = shader("ShaderNodeVolumePrincipled", Color=(*color, 1.0), Density=density,
                    Absorption_Color=(*absorption, 1.0), Anisotropy=0.3, Emission_Strength=3.0,
                    Emission_Color=(1.0, 0.5, 0.0, 1.0))
    scene_, material, warnings = _material(scene, node_material("Fog", volume=volume))
    assert material.surface == "null" and material.medium == 0
    medium = scene_.media[0]
    # sigma_s = rho C; sigma_a = rho (1 - C)(1 - sqrt(A)); emission not scaled by density.
    np.testing.assert_allclose(medium.sigma_s, [1.2, 1.0, 0.4], rtol=1e-6)
    np.testing.assert_allclose(medium.sigma_a, 2.0 * (1 - color) * (1 - np.sqrt(absorption)), rtol=1e-6)
    np.testing.assert_allclose(medium.sigma_a, [0.4, 0.8, 1.6], rtol=1e-6)
    np.testing.assert_allclose(medium.emission, [3.0, 1.5, 0.0], rtol=1e-6)
    assert medium.g == pytest.approx(0.3)
    assert warnings == []


def test_scatter_plus_absorption(scene):
    def added(tree):
        add = tree.nodes.new("ShaderNodeAddShader")
        scatter = shader("ShaderNodeVolumeScatter", Color=(0.9, 0.5, 0.1, 1.0), Density=0.5,
                         Anisotropy=-0.5)(tree)
        absorb = shader("ShaderNodeVolumeAbsorption", Color=(0.2, 0.4, 1.0, 1.0), Density=3.0)(tree)
        tree.links.new(scatter, add.inputs[0])
        tree.links.new(absorb, add.inputs[1])
        return add.outputs[0]

    surface = shader("ShaderNodeBsdfDiffuse", Color=(0.5, 0.5, 0.5, 1.0))
    scene_, material, _ = _material(scene, node_material("Murk", surface=surface, volume=added))
    assert material.surface == "diffuse" and material.medium == 0  # surface AND medium inside
    medium = scene_.media[0]
    np.testing.assert_allclose(medium.sigma_s, [0.45, 0.25, 0.05], rtol=1e-6)
    np.testing.assert_allclose(medium.sigma_a, [2.4, 1.8, 0.0], atol=1e-6)
    assert medium.g == pytest.approx(-0.5)


def test_anisotropy_clamped_like_cycles(scene):
    volume = shader("ShaderNodeVolumeScatter", Density=1.0, Anisotropy=1.0)
    scene_, _, _ = _material(scene, node_material("Forward", volume=volume))
    assert scene_.media[0].g == pytest.approx(0.999)


def test_scatter_closures_with_different_anisotropy_become_phase_lobes(scene):
    def mixed(tree):
        mix = tree.nodes.new("ShaderNodeMixShader")
        mix.inputs[0].default_value = 0.25
        forward = shader("ShaderNodeVolumeScatter", Color=(1.0, 1.0, 1.0, 1.0), Density=2.0, Anisotropy=0.8)(tree)
        backward = shader("ShaderNodeVolumeScatter", Color=(1.0, 0.5, 0.0, 1.0), Density=4.0, Anisotropy=-0.6)(tree)
        tree.links.new(forward, mix.inputs[1])
        tree.links.new(backward, mix.inputs[2])
        return mix.outputs[0]

    scene_, _, warnings = _material(scene, node_material("TwoLobes", volume=mixed))
    medium = scene_.media[0]
    lobes = {g: sigma_s for sigma_s, g in medium.lobes()}
    assert sorted(lobes) == pytest.approx([-0.6, 0.8])
    # Mix Shader weights each closure (Cycles svm_node_mix_closure): 0.75 x 2 x white, 0.25 x 4 x colour.
    np.testing.assert_allclose(lobes[max(lobes)], [1.5, 1.5, 1.5], rtol=1e-6)
    np.testing.assert_allclose(lobes[min(lobes)], [1.0, 0.5, 0.0], rtol=1e-6)
    np.testing.assert_allclose(medium.sigma_s, [2.5, 2.0, 1.5], rtol=1e-6)
    assert not any("anisotrop" in w for w in warnings), warnings


def test_nothing_connected_is_black(scene):
    _, material, _ = _material(scene, node_material("Empty"))
    assert material.surface == "diffuse" and material.medium == -1
    np.testing.assert_allclose(material.base_color, 0.0)


def test_no_material_is_grey_diffuse(scene):
    _, material, warnings = _material(scene, None)
    np.testing.assert_allclose(material.base_color, 0.8)
    assert any("without a material" in w for w in warnings)


def test_unsupported_node_warns_and_falls_back(scene):
    glossy = shader("ShaderNodeBsdfGlossy")
    _, material, warnings = _material(scene, node_material("Shiny", surface=glossy))
    np.testing.assert_allclose(material.base_color, 0.8)  # documented fallback
    assert any("'Shiny'" in w and "Glossy" in w for w in warnings), warnings


def test_linked_texture_warns_and_uses_socket_value(scene):
    def textured(tree):
        diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = (0.1, 0.2, 0.3, 1.0)
        noise = tree.nodes.new("ShaderNodeTexNoise")
        tree.links.new(noise.outputs["Color"], diffuse.inputs["Color"])
        return diffuse.outputs[0]

    _, material, warnings = _material(scene, node_material("Tex", surface=textured))
    np.testing.assert_allclose(material.base_color, [0.1, 0.2, 0.3], rtol=1e-6)
    assert any("'Tex'" in w and "Noise Texture" in w and "Color" in w for w in warnings), warnings


def test_rgb_node_feeding_an_input_is_a_constant(scene):
    def rgb_fed(tree):
        diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
        rgb = tree.nodes.new("ShaderNodeRGB")
        rgb.outputs[0].default_value = (0.25, 0.5, 0.75, 1.0)
        tree.links.new(rgb.outputs[0], diffuse.inputs["Color"])
        return diffuse.outputs[0]

    _, material, warnings = _material(scene, node_material("Const", surface=rgb_fed))
    np.testing.assert_allclose(material.base_color, [0.25, 0.5, 0.75], rtol=1e-6)
    assert warnings == []


def _world(sc, strength=2.0, color=(0.2, 0.4, 0.6), volume=None):
    world = bpy.data.worlds.new("Sky")
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    tree = world.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputWorld")
    background = tree.nodes.new("ShaderNodeBackground")
    background.inputs["Color"].default_value = (*color, 1.0)
    background.inputs["Strength"].default_value = strength
    tree.links.new(background.outputs[0], out.inputs["Surface"])
    if volume is not None:
        tree.links.new(volume(tree), out.inputs["Volume"])
    sc.world = world
    return world


def test_world_background_and_volume(scene):
    _world(scene, volume=shader("ShaderNodeVolumeScatter", Color=(0.5, 0.5, 0.5, 1.0), Density=0.01))
    scene_, warnings = export(scene)
    np.testing.assert_allclose(scene_.world.background, [0.4, 0.8, 1.2], rtol=1e-6)
    assert scene_.world.medium == 0
    np.testing.assert_allclose(scene_.media[0].sigma_s, 0.005, rtol=1e-6)
    np.testing.assert_allclose(scene_.media[0].sigma_a, 0.0)


def test_open_mesh_bounding_a_medium_is_named_and_rendered_without_it(scene):
    fog = node_material("Fog", volume=shader("ShaderNodeVolumePrincipled"))
    from addon_scenes import CUBE_FACES, CUBE_VERTICES

    add_mesh(scene, "OpenBox", vertices=CUBE_VERTICES, faces=CUBE_FACES[:-1], material=fog)
    native, warnings = export(scene)
    assert any("object 'OpenBox'" in w and "not closed" in w for w in warnings), warnings
    assert native.materials[native.meshes[0].material_ids[0]].medium == -1


def test_transparent_surface_around_a_volume_is_a_null_boundary(scene):
    transparent = shader("ShaderNodeBsdfTransparent", Color=(1.0, 1.0, 1.0, 1.0))
    volume = shader("ShaderNodeVolumeAbsorption", Color=(0.5, 0.5, 0.5, 1.0), Density=1.0)
    scene_, material, warnings = _material(scene, node_material("Glassless", surface=transparent, volume=volume))
    assert material.surface == "null" and material.medium == 0
    np.testing.assert_allclose(scene_.media[0].sigma_a, 0.5, rtol=1e-6)
    assert warnings == []


def test_world_hidden_from_camera_warns(scene):
    world = _world(scene)
    world.cycles_visibility.camera = False
    assert any("world 'Sky'" in w and "camera" in w for w in export(scene)[1])


def test_view_layer_material_override(scene):
    red = node_material("Red", surface=shader("ShaderNodeBsdfDiffuse", Color=(1.0, 0.0, 0.0, 1.0)))
    blue = node_material("Blue", surface=shader("ShaderNodeBsdfDiffuse", Color=(0.0, 0.0, 1.0, 1.0)))
    add_mesh(scene, "Box", material=red)
    bpy.context.view_layer.material_override = blue
    scene_, _ = export(scene)
    np.testing.assert_allclose(scene_.materials[scene_.meshes[0].material_ids[0]].base_color, [0, 0, 1])


def test_reroutes_and_muted_links(scene):
    def rerouted(tree):
        diffuse = shader("ShaderNodeBsdfDiffuse", Color=(0.2, 0.4, 0.6, 1.0))(tree)
        reroute = tree.nodes.new("NodeReroute")
        tree.links.new(diffuse, reroute.inputs[0])
        return reroute.outputs[0]

    _, material, _ = _material(scene, node_material("Rerouted", surface=rerouted))
    np.testing.assert_allclose(material.base_color, [0.2, 0.4, 0.6], rtol=1e-6)
    link = bpy.data.materials["Rerouted"].node_tree.links[0]
    link.is_muted = True  # a muted link is no link: black surface
    scene_, _ = export(scene)
    np.testing.assert_allclose(scene_.materials[scene_.meshes[0].material_ids[0]].base_color, 0.0)
