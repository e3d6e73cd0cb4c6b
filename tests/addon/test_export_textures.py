"""Image textures and attributes on surfaces, as exported: pixels stored as Cycles stores them (file
bytes through OpenImageIO, associated alpha c * a / 255, sRGB kept encoded, Non-Color raw), other
colour spaces converted by Blender's own colour management, missing images and UV maps warned,
UV maps / colour attributes / tangents per corner, one copy per image."""
import os

import bpy
import numpy as np
import OpenImageIO as oiio
import pytest

from addon_scenes import add_mesh, export, node_material
from volpath_native.shading import program as P

QUAD = [(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)]


def _write_png(path, pixels):
    """pixels (H, W, 4) uint8 with row 0 at the top, as files store them."""
    out = oiio.ImageOutput.create(str(path))
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], oiio.UINT8)
    spec.attribute("oiio:UnassociatedAlpha", 1)  # store these bytes as they are (PNG is unassociated)
    assert out.open(str(path), spec)
    assert out.write_image(pixels)
    out.close()


def _image_material(name, image, socket="Base Color", alpha=False):
    def tree_fn(tree):
        bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
        tex = tree.nodes.new("ShaderNodeTexImage")
        tex.image = image
        tree.links.new(tex.outputs["Color"], bsdf.inputs[socket])
        if alpha:
            tree.links.new(tex.outputs["Alpha"], bsdf.inputs["Alpha"])
        return bsdf.outputs[0]
    return node_material(name, surface=tree_fn)


def _quad_with_uv(sc, material, name="Quad", uv=True):
    obj = add_mesh(sc, name, vertices=QUAD, faces=[(0, 1, 2, 3)], material=material)
    if uv:
        layer = obj.data.uv_layers.new(name="UVMap")
        for i, (u, v) in enumerate([(0, 0), (1, 0), (1, 1), (0, 1)]):
            layer.data[i].uv = (u, v)
    return obj


def _opcode_operands(program, name):
    spec = P.OPS[name]
    code, pc, found = program.code, 0, []
    by_code = {s.code: s for s in P.OPS.values()}
    while pc < len(code):
        op = by_code[int(code[pc])]
        if op.code == spec.code:
            found.append([int(v) for v in code[pc + 1:pc + 1 + len(op.operands)]])
        pc += 1 + len(op.operands)
    return found


@pytest.fixture
def rgba_file(tmp_path):
    rng = np.random.default_rng(3)
    pixels = rng.integers(0, 256, size=(4, 8, 4), dtype=np.uint8)
    path = tmp_path / "texels.png"
    _write_png(path, pixels)
    return path, pixels


def test_srgb_png_keeps_bytes_premultiplied_and_flipped(scene, rgba_file):
    path, pixels = rgba_file
    image = bpy.data.images.load(str(path))
    image.colorspace_settings.name = "sRGB"
    _quad_with_uv(scene, _image_material("Tex", image))
    vp_scene, warnings = export(scene)
    assert len(vp_scene.images) == 1
    stored = vp_scene.images[0]
    assert stored.is_byte and stored.compress_as_srgb
    flipped = pixels[::-1].astype(np.uint16)
    expected = flipped.copy()
    expected[..., :3] = flipped[..., :3] * flipped[..., 3:4] // 255  # Cycles' byte association
    np.testing.assert_array_equal(stored.pixels, expected.astype(np.uint8))
    material = vp_scene.materials[int(vp_scene.meshes[0].material_ids[0])]
    assert [f for _, f, _ in material.surface_program.bindings] == ["color"]
    assert "uv:" in vp_scene.meshes[0].corner_attributes
    assert not any("Tex" in w for w in warnings), warnings


def test_non_color_png_is_raw_and_not_premultiplied(scene, rgba_file):
    path, pixels = rgba_file
    image = bpy.data.images.load(str(path))
    image.colorspace_settings.name = "Non-Color"
    _quad_with_uv(scene, _image_material("Rough", image, socket="Roughness"))
    vp_scene, _ = export(scene)
    stored = vp_scene.images[0]
    assert not stored.compress_as_srgb
    np.testing.assert_array_equal(stored.pixels, pixels[::-1])


def test_one_copy_per_image(scene, rgba_file):
    path, _ = rgba_file
    image = bpy.data.images.load(str(path))
    _quad_with_uv(scene, _image_material("A", image), "A")
    _quad_with_uv(scene, _image_material("B", image), "B")
    vp_scene, _ = export(scene)
    assert len(vp_scene.images) == 1
    for material in vp_scene.materials:
        for operands in _opcode_operands(material.surface_program.program, "IMAGE_TEXTURE"):
            assert operands[0] == 0


def test_missing_file_is_magenta_with_a_warning(scene, tmp_path):
    image = bpy.data.images.load(str(tmp_path / "gone.png"), check_existing=False) \
        if os.path.exists(tmp_path / "gone.png") else bpy.data.images.new("gone", 4, 4)
    image.source = "FILE"
    image.filepath = str(tmp_path / "gone.png")
    _quad_with_uv(scene, _image_material("Lost", image))
    vp_scene, warnings = export(scene)
    material = vp_scene.materials[int(vp_scene.meshes[0].material_ids[0])]
    assert _opcode_operands(material.surface_program.program, "IMAGE_TEXTURE")[0][0] == -1  # magenta
    assert any("'gone'" in w and "magenta" in w for w in warnings), warnings


def test_mesh_without_uv_map_warns(scene, rgba_file):
    path, _ = rgba_file
    _quad_with_uv(scene, _image_material("Tex", bpy.data.images.load(str(path))), uv=False)
    vp_scene, warnings = export(scene)
    assert "uv:" not in vp_scene.meshes[0].corner_attributes
    assert any("'Quad'" in w and "UV" in w for w in warnings), warnings


def test_other_colour_space_converted_by_blenders_ocio_config(scene, rgba_file):
    """A byte image in ACEScg is converted to scene-linear (Linear Rec.709) at load by OpenColorIO
    with Blender's configuration, as Cycles' ColorSpaceManager::to_scene_linear: the result is the
    AP1 -> Rec.709 matrix (ACES TB-2014-004) applied to byte / 255, not an sRGB curve."""
    path, pixels = rgba_file
    opaque = pixels.copy()
    opaque[..., 3] = 255
    _write_png(path, opaque)
    image = bpy.data.images.load(str(path))
    image.colorspace_settings.name = "ACEScg"
    _quad_with_uv(scene, _image_material("Aces", image))
    vp_scene, warnings = export(scene)
    stored = vp_scene.images[0]
    assert not stored.is_byte and not stored.compress_as_srgb
    ap1_to_rec709 = np.array([[1.70505, -0.62179, -0.08326], [-0.13026, 1.14080, -0.01055],
                              [-0.02400, -0.12897, 1.15297]])
    expected = (opaque[::-1, :, :3] / 255.0) @ ap1_to_rec709.T
    np.testing.assert_allclose(stored.pixels[..., :3], expected, atol=2e-3)
    np.testing.assert_array_equal(stored.pixels[..., 3], 1.0)
    # the planted alternative (an sRGB decode) is far from it
    assert np.abs(stored.pixels[..., :3] - ((opaque[::-1, :, :3] / 255.0 + 0.055) / 1.055) ** 2.4).max() > 0.05


def test_colour_attribute_and_uv_map_node(scene):
    def tree_fn(tree):
        bsdf = tree.nodes.new("ShaderNodeBsdfDiffuse")
        attr = tree.nodes.new("ShaderNodeVertexColor")
        attr.layer_name = "Paint"
        tree.links.new(attr.outputs["Color"], bsdf.inputs["Color"])
        uv = tree.nodes.new("ShaderNodeUVMap")
        uv.uv_map = "Second"
        sep = tree.nodes.new("ShaderNodeSeparateXYZ")
        tree.links.new(uv.outputs["UV"], sep.inputs[0])
        tree.links.new(sep.outputs["X"], bsdf.inputs["Roughness"])
        return bsdf.outputs[0]

    obj = _quad_with_uv(scene, node_material("Painted", surface=tree_fn))
    mesh = obj.data
    second = mesh.uv_layers.new(name="Second")
    for i in range(4):
        second.data[i].uv = (0.1 * i, 0.5)
    paint = mesh.color_attributes.new("Paint", "FLOAT_COLOR", "POINT")
    colours = np.array([[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1], [1, 1, 1, 0.5]], np.float32)
    paint.data.foreach_set("color", colours.reshape(-1))
    vp_scene, warnings = export(scene)
    corners = vp_scene.meshes[0].corner_attributes
    assert corners["color:Paint"].shape[2] == 4 and corners["uv:Second"].shape[2] == 2
    # every corner's colour is one of its vertex's colours, and its UV the Second map's
    tris = vp_scene.meshes[0].triangles
    for t in range(len(tris)):
        for k in range(3):
            vertex = int(np.argmin(np.linalg.norm(np.array(QUAD) - vp_scene.meshes[0].vertices[tris[t, k]], axis=1)))
            np.testing.assert_allclose(corners["color:Paint"][t, k], colours[vertex], atol=1e-6)
            np.testing.assert_allclose(corners["uv:Second"][t, k], (0.1 * vertex, 0.5), atol=1e-6)
    assert warnings == [] or not any("Painted" in w for w in warnings), warnings
