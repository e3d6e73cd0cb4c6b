"""Materials and the world: each supported node against coefficients computed by hand from
Cycles' formulas (intern/cycles/kernel/svm/closure.h)."""
import math

import bpy
import numpy as np
import pytest

from addon_scenes import add_mesh, export, node_material, shader


def _albedo(material):
    """The diffuse albedo the material's nodes add up to (weight x colour of its diffuse nodes)."""
    total = np.zeros(3)
    for node in material.bsdf_nodes():
        if node.kind == "diffuse":
            total += node.weight * node.color
    return total


def _only(material, kind):
    nodes = material.bsdf_nodes()
    assert [n.kind for n in nodes] == [kind], [n.kind for n in nodes]
    return nodes[0]


def _material(sc, mat):
    add_mesh(sc, "Box", material=mat)
    scene, warnings = export(sc)
    assert len(scene.meshes) == 1
    return scene, scene.materials[int(scene.meshes[0].material_ids[0])], warnings


def test_diffuse_bsdf(scene):
    mat = node_material("Red", surface=shader("ShaderNodeBsdfDiffuse", Color=(0.7, 0.2, 0.1, 1.0)))
    _, material, warnings = _material(scene, mat)
    assert material.surface == "shaded"
    np.testing.assert_allclose(_albedo(material), [0.7, 0.2, 0.1], rtol=1e-6)
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
    node = _only(material, "principled")
    np.testing.assert_allclose(node.color, [0.3, 0.6, 0.9], rtol=1e-6)
    np.testing.assert_allclose(material.emission, [4.0, 2.0, 1.0], rtol=1e-6)
    # Blender's defaults reach the kernel unchanged (it builds Cycles' layers from them)
    assert (node.roughness, node.ior, node.metallic, node.transmission, node.alpha) == pytest.approx(
        (0.5, 1.5, 0.0, 0.0, 1.0))
    assert node.specular_ior_level == pytest.approx(0.5) and node.distribution == "multi_ggx"
    assert warnings == []


def test_principled_bsdf_layers_are_exported(scene):
    values = {"Metallic": 0.3, "Roughness": 0.2, "IOR": 1.33, "Alpha": 0.7, "Transmission Weight": 0.4,
              "Coat Weight": 0.6, "Coat Roughness": 0.1, "Coat IOR": 1.6, "Sheen Weight": 0.5,
              "Sheen Roughness": 0.3, "Specular IOR Level": 0.25}
    colours = {"Specular Tint": (0.9, 0.8, 0.7), "Coat Tint": (0.5, 0.6, 0.7), "Sheen Tint": (0.2, 0.3, 0.4)}
    inputs = {k.replace(" ", "_"): v for k, v in values.items()}
    inputs.update({k.replace(" ", "_"): (*v, 1.0) for k, v in colours.items()})
    _, material, warnings = _material(scene, node_material("Layers", surface=shader("ShaderNodeBsdfPrincipled",
                                                                                    **inputs)))
    node = _only(material, "principled")
    fields = {"Metallic": "metallic", "Roughness": "roughness", "IOR": "ior", "Alpha": "alpha",
              "Transmission Weight": "transmission", "Coat Weight": "coat_weight", "Coat Roughness": "coat_roughness",
              "Coat IOR": "coat_ior", "Sheen Weight": "sheen_weight", "Sheen Roughness": "sheen_roughness",
              "Specular IOR Level": "specular_ior_level"}
    for socket, field in fields.items():
        assert getattr(node, field) == pytest.approx(values[socket]), field
    np.testing.assert_allclose(node.specular_tint, colours["Specular Tint"], rtol=1e-6)
    np.testing.assert_allclose(node.coat_tint, colours["Coat Tint"], rtol=1e-6)
    np.testing.assert_allclose(node.sheen_tint, colours["Sheen Tint"], rtol=1e-6)
    assert warnings == []


@pytest.mark.parametrize("node_type, inputs, kind, expected", [
    ("ShaderNodeBsdfGlass", dict(Color=(0.9, 0.8, 0.7, 1.0), Roughness=0.1, IOR=1.45), "glass",
     dict(roughness=0.1, ior=1.45, distribution="multi_ggx")),
    ("ShaderNodeBsdfRefraction", dict(Roughness=0.2, IOR=1.33), "refraction",
     dict(roughness=0.2, ior=1.33, distribution="beckmann")),
    ("ShaderNodeBsdfGlossy", dict(Color=(0.5, 0.5, 0.5, 1.0), Roughness=0.3), "glossy",
     dict(roughness=0.3, distribution="multi_ggx")),
    ("ShaderNodeBsdfMetallic", dict(Roughness=0.4), "metallic", dict(roughness=0.4, fresnel="f82")),
    ("ShaderNodeBsdfTranslucent", dict(Color=(0.2, 0.9, 0.2, 1.0)), "translucent", {}),
    ("ShaderNodeBsdfTransparent", dict(Color=(0.5, 0.9, 0.2, 1.0)), "transparent", {}),
    ("ShaderNodeBsdfSheen", dict(Roughness=0.6), "sheen", dict(roughness=0.6)),
])
def test_glass_glossy_metallic_and_friends(scene, node_type, inputs, kind, expected):
    _, material, warnings = _material(scene, node_material("M", surface=shader(node_type, **inputs)))
    node = _only(material, kind)
    for field, value in expected.items():
        assert getattr(node, field) == pytest.approx(value), (kind, field)
    if "Color" in inputs:
        np.testing.assert_allclose(node.color, inputs["Color"][:3], rtol=1e-6)
    assert warnings == [], warnings


def test_physical_conductor_exports_ior_and_extinction(scene):
    def metal(tree):
        node = tree.nodes.new("ShaderNodeBsdfMetallic")
        node.fresnel_type = "PHYSICAL_CONDUCTOR"
        node.inputs["IOR"].default_value = (0.2, 0.9, 1.1)
        node.inputs["Extinction"].default_value = (3.9, 2.4, 2.2)
        return node.outputs[0]

    _, material, _ = _material(scene, node_material("Copper", surface=metal))
    node = _only(material, "metallic")
    assert node.fresnel == "physical"
    np.testing.assert_allclose(node.conductor_n, [0.2, 0.9, 1.1], rtol=1e-6)
    np.testing.assert_allclose(node.conductor_k, [3.9, 2.4, 2.2], rtol=1e-6)


def test_glass_with_a_volume_keeps_surface_and_medium(scene):
    glass = shader("ShaderNodeBsdfGlass", IOR=1.33)
    volume = shader("ShaderNodeVolumeAbsorption", Color=(0.9, 0.4, 0.1, 1.0), Density=2.0)
    scene_, material, _ = _material(scene, node_material("Liquid", surface=glass, volume=volume))
    assert material.surface == "shaded" and material.medium == 0
    assert _only(material, "glass").ior == pytest.approx(1.33)
    np.testing.assert_allclose(scene_.media[0].sigma_a, 2.0 * np.array([0.1, 0.6, 0.9]), rtol=1e-6)


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
    np.testing.assert_allclose(_albedo(material), 0.75 * np.array([0.8, 0.8, 0.4]), rtol=1e-6)
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
    assert material.surface == "shaded" and material.medium == 0  # surface AND medium inside
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
    assert material.surface == "shaded" and material.medium == -1
    assert material.bsdf_nodes() == []


def test_no_material_is_cycles_default_principled(scene):
    _, material, warnings = _material(scene, None)
    node = _only(material, "principled")
    np.testing.assert_allclose(node.color, 0.8)
    assert node.roughness == pytest.approx(0.5) and node.ior == pytest.approx(1.5)
    assert warnings == []


def test_unsupported_node_warns_and_falls_back(scene):
    toon = shader("ShaderNodeBsdfToon")
    _, material, warnings = _material(scene, node_material("Cartoon", surface=toon))
    np.testing.assert_allclose(_albedo(material), 0.8)  # documented fallback
    assert any("'Cartoon'" in w and "Toon" in w for w in warnings), warnings


def test_holdout_warns_and_renders_black(scene):
    _, material, warnings = _material(scene, node_material("Hole", surface=shader("ShaderNodeHoldout")))
    assert material.bsdf_nodes() == []
    assert any("'Hole'" in w and "Holdout" in w for w in warnings), warnings


def test_linked_texture_is_compiled_into_a_surface_program(scene):
    def textured(tree):
        diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = (0.1, 0.2, 0.3, 1.0)
        noise = tree.nodes.new("ShaderNodeTexNoise")
        tree.links.new(noise.outputs["Color"], diffuse.inputs["Color"])
        return diffuse.outputs[0]

    _, material, warnings = _material(scene, node_material("Tex", surface=textured))
    # the socket's own value stays in the node (the program overwrites it per hit)
    np.testing.assert_allclose(_albedo(material), [0.1, 0.2, 0.3], rtol=1e-6)
    assert [(i, field) for i, field, _ in material.surface_program.bindings] == [(0, "color")]
    assert warnings == []


def test_rgb_node_feeding_an_input_is_a_constant(scene):
    def rgb_fed(tree):
        diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
        rgb = tree.nodes.new("ShaderNodeRGB")
        rgb.outputs[0].default_value = (0.25, 0.5, 0.75, 1.0)
        tree.links.new(rgb.outputs[0], diffuse.inputs["Color"])
        return diffuse.outputs[0]

    _, material, warnings = _material(scene, node_material("Const", surface=rgb_fed))
    np.testing.assert_allclose(_albedo(material), [0.25, 0.5, 0.75], rtol=1e-6)
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
    np.testing.assert_allclose(_albedo(scene_.materials[scene_.meshes[0].material_ids[0]]), [0, 0, 1])


def test_reroutes_and_muted_links(scene):
    def rerouted(tree):
        diffuse = shader("ShaderNodeBsdfDiffuse", Color=(0.2, 0.4, 0.6, 1.0))(tree)
        reroute = tree.nodes.new("NodeReroute")
        tree.links.new(diffuse, reroute.inputs[0])
        return reroute.outputs[0]

    _, material, _ = _material(scene, node_material("Rerouted", surface=rerouted))
    np.testing.assert_allclose(_albedo(material), [0.2, 0.4, 0.6], rtol=1e-6)
    link = bpy.data.materials["Rerouted"].node_tree.links[0]
    link.is_muted = True  # a muted link is no link: black surface
    scene_, _ = export(scene)
    assert scene_.materials[scene_.meshes[0].material_ids[0]].bsdf_nodes() == []
