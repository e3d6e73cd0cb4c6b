"""Surface programs end to end in the renderer: a textured plane under a uniform white sky returns
exactly its albedo (a diffuse surface lit by radiance 1 from its whole hemisphere), so each pixel
must equal the texel the UV map puts under it -- the image's orientation, the per-corner UV
interpolation, the binding to Base Color and the sRGB decoding are all checked texel by texel.
The same image with the v axis flipped (a planted error) must fail."""
import numpy as np
import pytest

from volpath_native import Camera, Film, Material, Mesh, RenderSettings, Scene, World, render
from volpath_native.bsdfs.nodes import SurfaceNode
from volpath_native.shading import program as P
from volpath_native.shading.builder import ProgramBuilder
from volpath_native.shading.images import EXT_REPEAT, INTERP_CLOSEST, Image
from volpath_native.surface_programs import SurfaceProgram

N = 4  # image and film resolution


def _texels():
    rng = np.random.default_rng(7)
    return rng.integers(20, 235, size=(N, N, 4), dtype=np.uint8) | np.uint8(1)


def _srgb(c):
    c = c / 255.0
    return np.where(c < 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _textured_plane(texels, flip_v=False, field="color", kind="diffuse"):
    b = ProgramBuilder("textured plane")
    uv = b.alloc(3)
    b.emit("TEXCO", P.TEXCO_UV, uv)
    color, alpha = b.alloc(3), b.alloc()
    b.emit("IMAGE_TEXTURE", 0, 0, 0, INTERP_CLOSEST, EXT_REPEAT, 0, 0, uv, color, alpha)
    program = SurfaceProgram(b.build(), bindings=[(0, field, color if field == "color" else color + 1)])
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    uvs = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    if flip_v:
        uvs[:, 1] = 1 - uvs[:, 1]
    tris = np.array([[0, 1, 2], [0, 2, 3]])
    mesh = Mesh("plane", v, tris, np.zeros(2, int), corner_attributes={"uv:": uvs[tris]})
    camera = np.eye(4)
    camera[2, 3] = 5.0
    material = Material("textured", surface_nodes=[SurfaceNode.for_kind(kind)], surface_program=program)
    return Scene(camera=Camera(camera, projection="orthographic", ortho_scale=2.0),
                 film=Film(N, N, filter="box", filter_width=1.0), meshes=[mesh], materials=[material],
                 world=World(background=np.ones(3)), images=[Image("texels", texels, compress_as_srgb=True)],
                 settings=RenderSettings(samples=64, seed=3, threads=1))


def _expected(texels):
    # film row 0 is the top of the frame: image row N - 1 (Image rows start at the bottom)
    return _srgb(texels[::-1, :, :3].astype(np.float64))


def _matches(image, albedo):
    """The plane's radiance is albedo x a grey path weight whose mean is 1 (light and BSDF
    sampling of the uniform sky, MIS-weighted): per pixel the three channels must share one ratio
    to the albedo exactly, and the ratios must average to 1 within their noise."""
    ratio = image[..., :3] / albedo
    same_hue = np.allclose(ratio, ratio[..., :1], rtol=1e-5)
    scalars = ratio[..., 0].reshape(-1)
    z = abs(scalars.mean() - 1.0) / max(scalars.std(ddof=1) / np.sqrt(scalars.size), 1e-9)
    return same_hue, z


def test_textured_plane_shows_each_texel():
    texels = _texels()
    same_hue, z = _matches(render(_textured_plane(texels)).image, _expected(texels))
    assert same_hue and z < 4.0, z


def test_flipped_uv_is_caught():
    texels = _texels()
    same_hue, _ = _matches(render(_textured_plane(texels, flip_v=True)).image, _expected(texels))
    assert not same_hue


def test_mesh_without_uv_reads_uv_zero():
    texels = _texels()
    scene = _textured_plane(texels)
    scene.meshes[0].corner_attributes = {}
    same_hue, z = _matches(render(scene).image, _srgb(texels[0, 0, :3].astype(np.float64)))
    assert same_hue and z < 4.0, z


def test_vpscene_round_trip(tmp_path):
    from volpath_native import load_scene, save_scene

    scene = _textured_plane(_texels())
    loaded = load_scene(save_scene(scene, tmp_path / "textured.vpscene"))
    np.testing.assert_array_equal(loaded.images[0].pixels, scene.images[0].pixels)
    assert loaded.images[0].compress_as_srgb
    program, original = loaded.materials[0].surface_program, scene.materials[0].surface_program
    np.testing.assert_array_equal(program.program.code, original.program.code)
    assert program.bindings == original.bindings
    np.testing.assert_array_equal(loaded.meshes[0].corner_attributes["uv:"], scene.meshes[0].corner_attributes["uv:"])


def _normal_map(colour, tangent, sign, normal, strength=1.0, backfacing=0.0, space=0, frame=None):
    from volpath_native.shading.images import empty_image_table
    from volpath_native.shading.interpreter import run_program_many

    b = ProgramBuilder("normal map")
    c, t, out = b.const(list(colour)), b.alloc(4), b.alloc(3)
    b.init[t:t + 4] = list(tangent) + [sign]
    b.init[P.R_N:P.R_N + 3] = list(normal)
    b.init[P.R_BACKFACING] = backfacing
    b.emit("NORMAL_MAP", space, b.const(strength), c, t, t + 3, P.R_N, out)
    program = b.build()
    result = np.zeros((1, 3))
    frame = np.stack([np.eye(4)[:3], np.eye(4)[:3]]) if frame is None else frame
    run_program_many(program.code, program.init, program.tables, np.zeros(program.n_registers),
                     np.ascontiguousarray(frame), np.zeros((1, 1, 1, 1), np.float32), np.zeros((3, 4)),
                     np.zeros((1, 3)), result, out, 3, empty_image_table())
    return result[0]


def test_normal_map_tangent_space():
    """svm_node_normal_map by hand: N' = normalize(c.x T + c.y B + c.z N), B = sign N x T."""
    n, t = (0.0, 0.0, 1.0), (1.0, 0.0, 0.0)
    assert _normal_map((0.5, 0.5, 1.0), t, 1.0, n) == pytest.approx([0, 0, 1])  # the flat colour
    c = (0.8, 0.3, 0.9)
    x, y, z = 2 * (np.array(c) - 0.5)
    expected = np.array([x, y, z]) / np.linalg.norm([x, y, z])  # B = z x x = +y
    assert _normal_map(c, t, 1.0, n) == pytest.approx(expected, abs=1e-12)
    flipped = np.array([x, -y, z]) / np.linalg.norm([x, y, z])  # sign -1 flips the bitangent
    assert _normal_map(c, t, -1.0, n) == pytest.approx(flipped, abs=1e-12)
    # strength 0.5: xy halved, z = mix(1, z, 0.5)
    half = np.array([0.5 * x, 0.5 * y, 0.5 + 0.5 * z])
    assert _normal_map(c, t, 1.0, n, strength=0.5) == pytest.approx(half / np.linalg.norm(half), abs=1e-12)
    # back face: computed for the unflipped normal, then flipped
    assert _normal_map(c, t, 1.0, (0.0, 0.0, -1.0), backfacing=1.0) == pytest.approx(-expected, abs=1e-12)
    # no tangent (no UV map): the unperturbed normal
    assert _normal_map(c, (0.0, 0.0, 0.0), 1.0, n) == pytest.approx([0, 0, 1])
    # object space through a rotated object: object_normal_transform of the decoded colour
    rotation = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 deg about z
    world_to_object = np.zeros((3, 4))
    world_to_object[:, :3] = rotation.T
    frame = np.stack([world_to_object, np.eye(4)[:3]])
    obj = _normal_map(c, t, 1.0, n, space=1, frame=frame)
    assert obj == pytest.approx(rotation @ np.array([x, y, z]) / np.linalg.norm([x, y, z]), abs=1e-12)
