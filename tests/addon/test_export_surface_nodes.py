"""Surface node setups of issues 10 and 11 as exported: anisotropy gets a tangent (Cycles' radial
default or a Tangent node) and its rotation, textured emission becomes the program's emission with
Cycles' estimate as the light's weight, a Bump node compiles its height three times between the
input swaps, Box projection becomes IMAGE_BOX; what stays unsupported is warned naming the
material and node."""
import bpy
import numpy as np

from addon_scenes import add_mesh, export, node_material
from volpath_native.shading import program as P

QUAD = [(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)]


def _opcodes(program, name):
    code, pc, found = program.code, 0, []
    by_code = {s.code: s for s in P.OPS.values()}
    while pc < len(code):
        spec = by_code[int(code[pc])]
        if spec.code == P.OPS[name].code:
            found.append([int(v) for v in code[pc + 1:pc + 1 + len(spec.operands)]])
        pc += 1 + len(spec.operands)
    return found


def _export(scene, material):
    add_mesh(scene, "Quad", vertices=QUAD, faces=[(0, 1, 2, 3)], material=material)
    vp_scene, warnings = export(scene)
    return next(m for m in vp_scene.materials if m.name == material.name), warnings


def test_anisotropic_principled_gets_the_radial_tangent_and_rotation(scene):
    def tree_fn(tree):
        bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
        bsdf.inputs["Anisotropic"].default_value = 0.8
        bsdf.inputs["Anisotropic Rotation"].default_value = 0.2
        return bsdf.outputs[0]
    material, warnings = _export(scene, node_material("Brushed", surface=tree_fn))
    node = material.surface_nodes[0]
    assert node.anisotropic == np.float32(0.8) and node.anisotropic_rotation == np.float32(0.2)
    program = material.surface_program
    assert program is not None and program.tangent >= 0
    assert _opcodes(program.program, "TANGENT")[0][0] == P.TANGENT_RADIAL_Z
    assert not any("Brushed" in w for w in warnings), warnings


def test_glossy_tangent_node_and_varying_rotation(scene):
    def tree_fn(tree):
        bsdf = tree.nodes.new("ShaderNodeBsdfGlossy")
        bsdf.inputs["Anisotropy"].default_value = 0.5
        tangent = tree.nodes.new("ShaderNodeTangent")
        tangent.direction_type = "UV_MAP"
        tangent.uv_map = "UVMap"
        tree.links.new(tangent.outputs["Tangent"], bsdf.inputs["Tangent"])
        noise = tree.nodes.new("ShaderNodeTexNoise")
        tree.links.new(noise.outputs["Fac"], bsdf.inputs["Rotation"])
        return bsdf.outputs[0]
    material = node_material("Brushed glossy", surface=tree_fn)
    obj = add_mesh(scene, "Quad", vertices=QUAD, faces=[(0, 1, 2, 3)], material=material)
    obj.data.uv_layers.new(name="UVMap")
    vp_scene, warnings = export(scene)
    program = vp_scene.materials[0].surface_program
    assert _opcodes(program.program, "TANGENT")[0][0] == P.TANGENT_UV
    assert ("tangent:UVMap", 4) in [(n, w) for n, w, _ in program.inputs]
    assert any(field == "anisotropic_rotation" for _, field, _ in program.bindings)
    assert not any("Brushed glossy" in w for w in warnings), warnings


def test_isotropic_material_needs_no_program(scene):
    material, _ = _export(scene, node_material("Plain", surface=lambda tree: tree.nodes.new(
        "ShaderNodeBsdfPrincipled").outputs[0]))
    assert material.surface_program is None


def test_textured_emission_is_the_programs_with_cycles_estimate(scene):
    def tree_fn(tree):
        emit = tree.nodes.new("ShaderNodeEmission")
        emit.inputs["Strength"].default_value = 5.0
        noise = tree.nodes.new("ShaderNodeTexNoise")
        tree.links.new(noise.outputs["Color"], emit.inputs["Color"])
        return emit.outputs[0]
    material, warnings = _export(scene, node_material("Glowing", surface=tree_fn))
    assert material.surface_program.emission >= 0
    # Shader::estimate_emission: a linked colour counts 1, times the constant strength
    np.testing.assert_allclose(material.emission, [5.0, 5.0, 5.0])
    assert not any("Glowing" in w for w in warnings), warnings


def test_emission_under_a_varying_mix_factor(scene):
    def tree_fn(tree):
        emit = tree.nodes.new("ShaderNodeEmission")
        emit.inputs["Strength"].default_value = 2.0
        diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
        mix = tree.nodes.new("ShaderNodeMixShader")
        noise = tree.nodes.new("ShaderNodeTexNoise")
        tree.links.new(noise.outputs["Fac"], mix.inputs[0])
        tree.links.new(diffuse.outputs[0], mix.inputs[1])
        tree.links.new(emit.outputs[0], mix.inputs[2])
        return mix.outputs[0]
    material, warnings = _export(scene, node_material("Half glowing", surface=tree_fn))
    assert material.surface_program.emission >= 0
    np.testing.assert_allclose(material.emission, [2.0, 2.0, 2.0])  # unweighted, as Cycles' estimate
    assert not any("Half glowing" in w for w in warnings), warnings


def test_bump_compiles_the_height_three_times(scene):
    def tree_fn(tree):
        bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
        bump = tree.nodes.new("ShaderNodeBump")
        bump.invert = True
        wave = tree.nodes.new("ShaderNodeTexWave")
        tree.links.new(wave.outputs["Fac"], bump.inputs["Height"])
        normal_map = tree.nodes.new("ShaderNodeNormalMap")
        tree.links.new(normal_map.outputs["Normal"], bump.inputs["Normal"])
        tree.links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
        return bsdf.outputs[0]
    material, warnings = _export(scene, node_material("Bumpy", surface=tree_fn))
    program = material.surface_program
    assert program.normal >= 0 and program.bump_offsets >= 0
    names = [name for name, *_ in program.shifts]  # the position and the inputs known so far
    assert names[0] == "P" and "uv:" not in names
    assert len(_opcodes(program.program, "TEX_WAVE")) == 3
    bumps = _opcodes(program.program, "BUMP")
    assert len(bumps) == 1 and bumps[0][0] == 1
    assert len(_opcodes(program.program, "SWAP")) == 4 * len(program.shifts)  # in and out, x and y


def test_box_projection(scene):
    image = bpy.data.images.new("box texels", 4, 4)

    def tree_fn(tree):
        bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
        tex = tree.nodes.new("ShaderNodeTexImage")
        tex.image = image
        tex.projection = "BOX"
        tex.projection_blend = 0.25
        coords = tree.nodes.new("ShaderNodeTexCoord")
        tree.links.new(coords.outputs["Object"], tex.inputs["Vector"])
        tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
        return bsdf.outputs[0]
    material, warnings = _export(scene, node_material("Boxed", surface=tree_fn))
    program = material.surface_program
    (box,) = _opcodes(program.program, "IMAGE_BOX")
    assert program.program.init[box[4]] == np.float32(0.25)
    assert not any("Boxed" in w for w in warnings), warnings


def test_unsupported_setups_are_warned_by_material_and_node(scene):
    """What stays a fallback names its material and node: two BSDFs with different tangents, a
    linked Filter Width."""
    def tree_fn(tree):
        first = tree.nodes.new("ShaderNodeBsdfGlossy")
        first.inputs["Anisotropy"].default_value = 0.5
        second = tree.nodes.new("ShaderNodeBsdfGlossy")
        second.inputs["Anisotropy"].default_value = 0.5
        tangent = tree.nodes.new("ShaderNodeTangent")
        tree.links.new(tangent.outputs[0], second.inputs["Tangent"])
        bump = tree.nodes.new("ShaderNodeBump")
        noise = tree.nodes.new("ShaderNodeTexNoise")
        tree.links.new(noise.outputs["Fac"], bump.inputs["Height"])
        tree.links.new(noise.outputs["Fac"], bump.inputs["Filter Width"])
        tree.links.new(bump.outputs[0], first.inputs["Normal"])
        add = tree.nodes.new("ShaderNodeAddShader")
        tree.links.new(first.outputs[0], add.inputs[0])
        tree.links.new(second.outputs[0], add.inputs[1])
        return add.outputs[0]
    _, warnings = _export(scene, node_material("Odd", surface=tree_fn))
    mine = [w for w in warnings if "material 'Odd'" in w]
    assert any("Tangent" in w and "differs" in w for w in mine), warnings
    assert any("Filter Width" in w and "Bump" in w for w in mine), warnings


def _displaced(tree, space="OBJECT", node_type="ShaderNodeDisplacement"):
    output = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
    displacement = tree.nodes.new(node_type)
    displacement.space = space
    displacement.inputs["Scale"].default_value = 0.25
    noise = tree.nodes.new("ShaderNodeTexNoise")
    tree.links.new(noise.outputs["Fac" if node_type == "ShaderNodeDisplacement" else "Color"],
                   displacement.inputs["Height" if node_type == "ShaderNodeDisplacement" else "Vector"])
    tree.links.new(displacement.outputs[0], output.inputs["Displacement"])
    return tree.nodes.new("ShaderNodeBsdfDiffuse").outputs[0]


def test_displacement_output_is_a_bump_only(scene):
    """Cycles' default "Bump Only" (shader_graph.cpp bump_from_displacement): the Displacement node
    three times (centre, two moved copies between SWAPs), each dotted with N, one Bump of Distance 1
    on the shading normal, written back to N and taken as the material's normal; no warning."""
    material, warnings = _export(scene, node_material("Displaced", surface=lambda tree: _displaced(tree)))
    program = material.surface_program
    assert program is not None and program.normal >= 0 and program.bump_offsets >= 0
    displacements = _opcodes(program.program, "DISPLACEMENT")
    assert len(displacements) == 3 and all(d[0] == P.DISPLACEMENT_SPACES["OBJECT"] for d in displacements)
    (bump,) = _opcodes(program.program, "BUMP")
    init = program.program.init
    assert bump[0] == 0 and bump[1] == P.R_N and init[bump[2]] == 1.0 and init[bump[3]] == 1.0
    assert bump[-1] == program.normal and program.shading_normal == P.R_N  # sd->N itself (no bump shadowing)
    assert [program.normal, P.R_N] in [c[1:] for c in _opcodes(program.program, "COPY") if c[0] == 3]
    assert init[displacements[0][2]] == np.float32(0.5) and init[displacements[0][3]] == 0.25  # Midlevel, Scale
    assert not any("Displaced" in w for w in warnings), warnings


def test_displacement_methods_that_move_vertices_are_warned(scene):
    """"Displacement Only" / "Displacement and Bump" move the vertices in Cycles: rendered as the
    bump, warned naming the material; World space and Vector Displacement (Object) compile, its
    Tangent space (the default) is warned."""
    for method in ("DISPLACEMENT", "BOTH"):
        mat = node_material(f"Moved {method}", surface=lambda tree: _displaced(tree, "WORLD"))
        mat.displacement_method = method
        material, warnings = _export(scene, mat)
        assert _opcodes(material.surface_program.program, "DISPLACEMENT")[0][0] == P.DISPLACEMENT_SPACES["WORLD"]
        assert any(f"material 'Moved {method}'" in w and "Bump Only" in w for w in warnings), warnings
    material, warnings = _export(scene, node_material("Vector object", surface=lambda tree: _displaced(
        tree, "OBJECT", "ShaderNodeVectorDisplacement")))
    assert len(_opcodes(material.surface_program.program, "VECTOR_DISPLACEMENT")) == 3
    assert not any("Vector object" in w for w in warnings), warnings
    _, warnings = _export(scene, node_material("Vector tangent", surface=lambda tree: _displaced(
        tree, "TANGENT", "ShaderNodeVectorDisplacement")))
    assert any("material 'Vector tangent'" in w and "TANGENT" in w for w in warnings), warnings
