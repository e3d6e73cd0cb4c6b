"""Surface-program opcodes of issues 10 and 11 against hand computations: the Bump node
(svm_node_set_bump) on given heights and offsets, the whole bump path at a hit (the kernel moves
the inputs, the program swaps them in) against its small-footprint limit, the Tangent node
(svm_node_tangent), Box projection weights (svm_node_tex_image_box), and a program emission equal
to a constant emitter rendering the same image as that emitter."""
import numpy as np
import pytest

from volpath_native import Camera, Film, Material, Mesh, RenderSettings, Scene, World, render
from volpath_native.accel import Accelerator
from volpath_native.bsdfs.nodes import SurfaceNode
from volpath_native.shading import program as P
from volpath_native.shading.builder import ProgramBuilder
from volpath_native.shading.images import empty_image_table
from volpath_native.shading.interpreter import run_program_many
from volpath_native.shading.surface_ops import _box_weights
from volpath_native.surface_programs import (SurfaceProgram, new_surface_scratch, program_shading_normal,
                                             shade_surface_program, surface_program_tables)

IDENTITY_FRAME = np.stack([np.eye(4)[:3], np.eye(4)[:3]])


def _run(b, out, width=3, frame=IDENTITY_FRAME, point=(0.0, 0.0, 0.0)):
    program = b.build()
    result = np.zeros((1, width))
    run_program_many(program.code, program.init, program.tables, np.zeros(program.n_registers),
                     np.ascontiguousarray(frame), np.zeros((1, 1, 1, 1), np.float32), np.zeros((3, 4)),
                     np.array([point], float), result, out, width, empty_image_table())
    return result[0]


def _bump(n, ex, ey, hc, hx, hy, distance=1.0, strength=1.0, filter_width=0.1, invert=0):
    b = ProgramBuilder("bump")
    b.init[P.R_N:P.R_N + 3] = list(n)
    offsets = b.alloc(6)
    b.init[offsets:offsets + 6] = list(ex) + list(ey)
    out = b.alloc(3)
    b.emit("BUMP", invert, P.R_N, b.const(distance), b.const(strength), b.const(filter_width), b.const(hc),
           b.const(hx), b.const(hy), offsets, offsets + 3, out)
    return _run(b, out)


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def test_bump_on_a_plane():
    """Heights rising g per unit along x: N' = normalize(N - Distance g x) (svm_node_set_bump with
    dPdx = ex, dPdy = ey: Rx = ey x N, det = delta^2); invert, strength and a zero filter width."""
    d, g = 1e-3, 0.7
    n, ex, ey = (0.0, 0.0, 1.0), (d, 0.0, 0.0), (0.0, d, 0.0)
    expected = _unit([-0.3 * g, 0.0, 1.0])
    assert _bump(n, ex, ey, 0.0, g * d, 0.0, distance=0.3) == pytest.approx(expected, abs=1e-12)
    assert _bump(n, ex, ey, 0.0, g * d, 0.0, distance=0.3, invert=1) == pytest.approx(
        _unit([0.3 * g, 0.0, 1.0]), abs=1e-12)
    half = _unit(0.5 * expected + 0.5 * np.array(n))
    assert _bump(n, ex, ey, 0.0, g * d, 0.0, distance=0.3, strength=0.5) == pytest.approx(half, abs=1e-12)
    assert _bump(n, ex, ey, 0.0, g * d, 0.0, distance=0.3, filter_width=0.0) == pytest.approx(n)
    # the offsets' handedness does not matter (sign(det))
    assert _bump(n, ey, ex, 0.0, 0.0, g * d, distance=0.3) == pytest.approx(expected, abs=1e-12)


# A tilted triangle shaded at one point with a shading normal different from its geometric one
TILTED_TRIANGLE = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.5], [0.0, 1.5, 0.3]])


def _shade_tilted_triangle(mesh, name, program):
    """shade_surface_program at barycentrics (0.3, 0.25) of `mesh` (TILTED_TRIANGLE) with a
    diffuse material driven by `program`: (normal, tangent, Ng, Ns, tables, scratch)."""
    from volpath_native.bsdfs.nodes import surface_node_table

    material = Material(name, surface_nodes=[SurfaceNode.for_kind("diffuse")], surface_program=program)
    tables = surface_program_tables([material], Accelerator([mesh]))
    scratch = new_surface_scratch([material], tables)
    nodes = surface_node_table([material.surface_nodes])
    corners = TILTED_TRIANGLE
    ng = _unit(np.cross(corners[1] - corners[0], corners[2] - corners[0]))
    ns = _unit(ng + np.array([0.2, 0.1, -0.05]))
    hu, hv = 0.3, 0.25
    p = corners[0] * (1 - hu - hv) + corners[1] * hu + corners[2] * hv
    normal, tangent = shade_surface_program(tables, scratch, nodes, 0, 0, 0, hu, hv, p[0], p[1], p[2], tuple(ns),
                                            tuple(ng), tuple(ng), False)
    return normal, tangent, ng, ns, tables, scratch


def _bump_plane_program(kind):
    """Height = a . P (kind 'position') or 0.8 u of the active UV map (kind 'uv'), through the
    copies the exporter makes (SWAP the moved inputs in, the same nodes, SWAP back)."""
    b = ProgramBuilder("bumped plane")
    offsets = b.alloc(6)
    a = b.const([0.3, -0.5, 0.2])

    def height():
        out, value = b.alloc(3), b.alloc()
        vector = b.alloc(3)
        b.emit("TEXCO", P.TEXCO_POSITION if kind == "position" else P.TEXCO_UV, vector)
        b.emit("VECTOR_MATH", P.VECTOR_MATH["DOT_PRODUCT"], vector,
               a if kind == "position" else b.const([0.8, 0.0, 0.0]), a, b.const(1.0), out, value)
        return value

    source, name = (P.R_P, "P") if kind == "position" else (P.R_UV, "uv:")
    dx, dy = b.alloc(3), b.alloc(3)
    hc = height()
    b.emit("SWAP", 3, source, dx)
    hx = height()
    b.emit("SWAP", 3, source, dx)
    b.emit("SWAP", 3, source, dy)
    hy = height()
    b.emit("SWAP", 3, source, dy)
    out = b.alloc(3)
    b.emit("BUMP", 0, P.R_N, b.const(0.25), b.const(1.0), b.const(0.1), hc, hx, hy, offsets, offsets + 3, out)
    return SurfaceProgram(b.build(), normal=out, bump_offsets=offsets, shifts=[(name, 3, dx, dy)])


@pytest.mark.parametrize("kind", ["position", "uv"])
def test_bump_at_a_hit_is_the_small_footprint_limit(kind):
    """A tilted triangle with a shading normal different from its geometric one: the program's
    normal is normalize(N - Distance (g - (g.N)/(Ng.N) Ng)), g the height's gradient in the
    triangle's plane -- the limit of Cycles' svm_node_set_bump as its footprint shrinks."""
    corners = TILTED_TRIANGLE
    uvs = np.array([[0.1, 0.2], [0.9, 0.3], [0.2, 0.8]])
    mesh = Mesh("tri", corners, np.array([[0, 1, 2]]), np.zeros(1, int), corner_attributes={"uv:": uvs[None]})
    normal, tangent, ng, ns, _, _ = _shade_tilted_triangle(mesh, "bumped", _bump_plane_program(kind))
    if kind == "position":
        gradient = np.array([0.3, -0.5, 0.2])
    else:  # u as a function on the plane: solve dP = e1 du + e2 dv
        e = np.stack([corners[1] - corners[0], corners[2] - corners[0]])
        du = np.array([uvs[1, 0] - uvs[0, 0], uvs[2, 0] - uvs[0, 0]])
        gradient = 0.8 * np.linalg.lstsq(e, du, rcond=None)[0]
    g = gradient - gradient.dot(ng) * ng
    expected = _unit(ns - 0.25 * (g - g.dot(ns) / ng.dot(ns) * ng))
    assert np.array(normal) == pytest.approx(expected, abs=2e-5)
    assert tangent == (0.0, 0.0, 0.0)
    # the planted error: a bump read with the heights' sign flipped points the other way
    wrong = _unit(ns + 0.25 * (g - g.dot(ns) / ng.dot(ns) * ng))
    assert not np.allclose(normal, wrong, atol=1e-3)


def _tangent(kind, vector, normal, frame=IDENTITY_FRAME):
    b = ProgramBuilder("tangent")
    b.init[P.R_N:P.R_N + 3] = list(normal)
    v, out = b.const(list(vector)), b.alloc(3)
    b.emit("TANGENT", kind, v, P.R_N, out)
    return _run(b, out, frame=frame)


def test_tangent_node():
    """svm_node_tangent: radial around Z of Generated (0.8, 0.5, z) is (-0, 0.3, 0) -> +y, made
    orthogonal to N; around X and Y likewise; a UV tangent is used as given; an object rotation
    turns it (object_normal_transform)."""
    n = _unit([0.3, 0.0, 1.0])
    t = _tangent(P.TANGENT_RADIAL_Z, (0.8, 0.5, 0.2), n)
    assert t == pytest.approx([0.0, 1.0, 0.0], abs=1e-12)
    t = _tangent(P.TANGENT_RADIAL_Z, (0.5, 0.9, 0.2), n)  # (-0.4, 0, 0) made orthogonal to N
    expected = _unit(np.cross(n, np.cross([-1.0, 0.0, 0.0], n)))
    assert t == pytest.approx(expected, abs=1e-12)
    assert _tangent(P.TANGENT_RADIAL_X, (0.1, 0.5, 0.9), (1.0, 0.0, 0.0)) == pytest.approx([0, -1, 0], abs=1e-12)
    assert _tangent(P.TANGENT_RADIAL_Y, (0.9, 0.2, 0.5), (0.0, 1.0, 0.0)) == pytest.approx([0, 0, 1], abs=1e-12)
    assert _tangent(P.TANGENT_UV, (0.0, 2.0, 0.0), (0.0, 0.0, 1.0)) == pytest.approx([0, 1, 0], abs=1e-12)
    assert _tangent(P.TANGENT_UV, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)) == pytest.approx([0, 0, 0])
    rotation = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 deg about z
    world_to_object = np.zeros((3, 4))
    world_to_object[:, :3] = rotation.T
    frame = np.stack([world_to_object, np.eye(4)[:3]])
    assert _tangent(P.TANGENT_UV, (1.0, 0.0, 0.0), (0.0, 0.0, 1.0), frame) == pytest.approx([0, 1, 0], abs=1e-12)


def test_box_projection_weights():
    """svm_node_tex_image_box's zones: one plane near an axis, two blended across an edge, three
    near a corner; weights sum to 1; no blend picks the dominant axis."""
    assert _box_weights(0.9, 0.1, 0.1, 0.3) == (1.0, 0.0, 0.0)
    assert _box_weights(0.1, -0.9, 0.2, 0.3) == (0.0, 1.0, 0.0)
    wx, wy, wz = _box_weights(0.6, 0.55, 0.05, 0.3)
    nx, ny = 0.6 / 1.2, 0.55 / 1.2
    assert wx == pytest.approx(min(max((nx / (nx + ny) - 0.35) / 0.3, 0.0), 1.0)) and wz == 0.0
    assert wx + wy == pytest.approx(1.0)
    w = _box_weights(0.5, 0.5, 0.5, 0.5)
    assert w == pytest.approx((1 / 3, 1 / 3, 1 / 3))
    assert _box_weights(0.6, 0.55, 0.05, 0.0) == (1.0, 0.0, 0.0)


def _emitter_scene(program_emission):
    """A diffuse floor lit only by an emissive quad: constant emission, or the same radiance from
    a program (unit light strength times the program's value at each point)."""
    floor = np.array([[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]], float)
    lamp = np.array([[-0.5, -0.5, 1.5], [-0.5, 0.5, 1.5], [0.5, 0.5, 1.5], [0.5, -0.5, 1.5]], float)
    quads = np.array([[0, 1, 2], [0, 2, 3]])
    radiance = np.array([3.0, 2.0, 1.0])
    emitter = Material("lamp", base_color=np.zeros(3), emission=radiance)
    if program_emission is not None:
        b = ProgramBuilder("emission")
        value = b.const(list(program_emission))
        emitter = Material("lamp", base_color=np.zeros(3), emission=radiance,
                           surface_program=SurfaceProgram(b.build(), emission=value))
    camera = np.eye(4)
    camera[2, 3] = 4.0
    return Scene(camera=Camera(camera, fov=np.radians(60.0)), film=Film(6, 6, filter="box", filter_width=1.0),
                 meshes=[Mesh("floor", floor, quads, np.zeros(2, int)), Mesh("lamp", lamp, quads, np.ones(2, int))],
                 materials=[Material("floor", surface_nodes=[SurfaceNode.for_kind("diffuse")]), emitter],
                 world=World(background=np.zeros(3)), settings=RenderSettings(samples=16, seed=5, threads=1))


def test_program_emission_matches_a_constant_emitter():
    """Same radiance, same light-selection weight: the same random decisions give the same image
    (camera hits, BSDF hits with MIS and light samples all multiply the program's radiance in);
    a program emitting twice as much (the planted error) does not."""
    constant = render(_emitter_scene(None)).image
    programmed = render(_emitter_scene([3.0, 2.0, 1.0])).image
    assert constant.max() > 0
    np.testing.assert_allclose(programmed, constant, rtol=1e-9, atol=1e-12)
    doubled = render(_emitter_scene([6.0, 4.0, 2.0])).image
    assert not np.allclose(doubled, constant, rtol=1e-3)


def test_new_program_outputs_survive_a_vpscene_round_trip(tmp_path):
    from volpath_native import load_scene, save_scene

    scene = _emitter_scene([3.0, 2.0, 1.0])
    program = scene.materials[1].surface_program
    scene.materials[0].surface_program = _bump_plane_program("uv")
    scene.materials[0].surface_program.shading_normal = P.R_N
    scene.meshes[0].corner_attributes["uv:"] = np.zeros((2, 3, 2))
    loaded = load_scene(save_scene(scene, tmp_path / "bumped.vpscene"))
    assert loaded.materials[1].surface_program.emission == program.emission
    bumped, original = loaded.materials[0].surface_program, scene.materials[0].surface_program
    assert (bumped.normal, bumped.tangent, bumped.bump_offsets) == (original.normal, -1, original.bump_offsets)
    assert bumped.shifts == original.shifts
    assert bumped.shading_normal == P.R_N


def _displaced_plane_program(space):
    """The Material Output's Displacement as the exporter compiles it for "Bump Only"
    (scene/shader_graph.cpp bump_from_displacement): a Displacement node (Height = a . P,
    Midlevel 0.2, Scale 0.5) at the hit and at the two moved points, each dotted with the shading
    normal, into a Bump of Distance 1."""
    b = ProgramBuilder("displaced plane")
    offsets = b.alloc(6)
    a = b.const([0.3, -0.5, 0.2])

    def height():
        position, unused, value = b.alloc(3), b.alloc(3), b.alloc()
        b.emit("TEXCO", P.TEXCO_POSITION, position)
        b.emit("VECTOR_MATH", P.VECTOR_MATH["DOT_PRODUCT"], position, a, a, b.const(1.0), unused, value)
        vector, h = b.alloc(3), b.alloc()
        b.emit("DISPLACEMENT", P.DISPLACEMENT_SPACES[space], value, b.const(0.2), b.const(0.5), P.R_N, vector)
        b.emit("VECTOR_MATH", P.VECTOR_MATH["DOT_PRODUCT"], vector, P.R_N, P.R_N, b.const(1.0), unused, h)
        return h

    dx, dy = b.alloc(3), b.alloc(3)
    hc = height()
    b.emit("SWAP", 3, P.R_P, dx)
    hx = height()
    b.emit("SWAP", 3, P.R_P, dx)
    b.emit("SWAP", 3, P.R_P, dy)
    hy = height()
    b.emit("SWAP", 3, P.R_P, dy)
    out = b.alloc(3)
    one = b.const(1.0)
    b.emit("BUMP", 0, P.R_N, one, one, b.const(0.1), hc, hx, hy, offsets, offsets + 3, out)
    b.emit("COPY", 3, out, P.R_N)  # SetNormalNode: the shading normal itself
    return SurfaceProgram(b.build(), normal=out, bump_offsets=offsets, shifts=[("P", 3, dx, dy)],
                          shading_normal=P.R_N)


def _rotation_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("space, object_scale", [("OBJECT", 2.5), ("WORLD", 2.5), ("OBJECT", 1.0)])
def test_displacement_as_bump_on_a_tilted_plane(space, object_scale):
    """Displacement (h - midlevel) x scale along N with h = a . P: in Object space the object's
    scale s multiplies the displacement (svm_node_displacement: inverse normal transform, scale,
    object_dir_transform), so the height's world gradient is s x 0.5 a (World: 0.5 a), and the
    normal is the Bump node's small-footprint limit with Distance 1 -- normalize(N - (g - (g.N) /
    (Ng.N) Ng)), g that gradient in the plane of the tilted triangle."""
    corners = TILTED_TRIANGLE
    rotation, translation = _rotation_z(0.6), np.array([0.4, -0.2, 0.1])
    object_to_world = np.hstack([object_scale * rotation, translation[:, None]])
    world_to_object = np.hstack([rotation.T / object_scale, (-rotation.T @ translation / object_scale)[:, None]])
    assert world_to_object[:, :3] @ object_to_world[:, :3] == pytest.approx(np.eye(3))
    mesh = Mesh("tri", corners, np.array([[0, 1, 2]]), np.zeros(1, int),
                object_frame=np.stack([world_to_object, np.eye(4)[:3]]))
    normal, _, ng, ns, tables, scratch = _shade_tilted_triangle(mesh, "displaced", _displaced_plane_program(space))

    def expected(factor):
        gradient = factor * 0.5 * np.array([0.3, -0.5, 0.2])
        g = gradient - gradient.dot(ng) * ng
        return _unit(ns - (g - g.dot(ns) / ng.dot(ns) * ng))

    factor = object_scale if space == "OBJECT" else 1.0
    assert np.array(normal) == pytest.approx(expected(factor), abs=2e-5)
    assert np.array(program_shading_normal(tables, scratch, 0, tuple(ns))) == pytest.approx(np.array(normal), abs=1e-12)
    # planted errors: the object's scale ignored (or applied in World space), the height's sign flipped
    if object_scale != 1.0:
        assert not np.allclose(normal, expected(object_scale if space == "WORLD" else 1.0), atol=1e-3)
    assert not np.allclose(normal, expected(-factor), atol=1e-3)


def test_displacement_nodes_at_a_point():
    """svm_node_displacement and svm_node_vector_displacement on given inputs: World space as given,
    Object space through a rotated frame scaled by 3 (the normal's direction kept, its length x3;
    a vector's object-space components rotated and scaled)."""
    rotation = _rotation_z(0.9)
    frame = np.stack([np.hstack([rotation.T / 3.0, np.zeros((3, 1))]), np.eye(4)[:3]])
    n = _unit([0.2, -0.4, 0.9])
    for space, factor in (("WORLD", 1.0), ("OBJECT", 3.0)):
        b = ProgramBuilder("displacement")
        b.init[P.R_N:P.R_N + 3] = list(n)
        out = b.alloc(3)
        b.emit("DISPLACEMENT", P.DISPLACEMENT_SPACES[space], b.const(0.9), b.const(0.5), b.const(2.0), P.R_N, out)
        assert _run(b, out, frame=frame) == pytest.approx(factor * 0.8 * n, abs=1e-12)
        b = ProgramBuilder("vector displacement")
        out = b.alloc(3)
        b.emit("VECTOR_DISPLACEMENT", P.DISPLACEMENT_SPACES[space], b.const([0.7, 0.1, 0.5]), b.const(0.5),
               b.const(2.0), out)
        vector = 2.0 * (np.array([0.7, 0.1, 0.5]) - 0.5)
        want = vector if space == "WORLD" else 3.0 * rotation @ vector
        assert _run(b, out, frame=frame) == pytest.approx(want, abs=1e-12)
