"""Moving heterogeneous volumes (issue 20): a grid medium and a shader-program medium whose object
moves, turns and stretches over the shutter are shaded at each path's time, as Cycles shades a
moving volume (the object's motion transform at sd->time: kernel/geom/object.h
object_fetch_transform_motion_test): the density at world P and time t is the static density at
M(t)^-1 P (volpath_native/medium_motion.py).

Closed form: an absorbing volume over a white sky, seen from above by an orthographic camera at
pixel centres. Each pixel's expectation is the shutter average of exp(-optical depth) along its
vertical ray through the volume placed at the decomposed-interpolated transform of each time
(test_object_motion.decomposed_at, Cycles' transform_motion_array_interpolate) -- computed from
the static medium's own density lookups (grid) or the program's formula (program medium). The
motion is not symmetric about the centre, so planted errors fail: the volume left at the shutter
centre (what VolPath did before), and the motion inverted about the centre (M_c M(t)^-1 M_c: the
transform applied where its inverse belongs).
"""
from __future__ import annotations

import numpy as np
import pytest

from volpath_native import Camera, Film, Material, RenderSettings, Scene, World, load_scene, render, save_scene
from volpath_native.grid_medium import GridMedium
from volpath_native.program_medium import ProgramMedium
from volpath_native.shading import program as P
from volpath_native.shading.builder import ProgramBuilder

from native_helpers import Z_LIMIT, box_mesh, camera_at
from test_object_motion import decomposed_at

SIZE, WIDTH, SIGMA = 8, 2.4, 2.0
TIMES = (np.arange(512) + 0.5) / 512


def _placed(angle, x, y, stretch=1.0):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, 0]]) @ np.diag([stretch, 1.0, 1.0, 1.0])


STEPS = np.stack([_placed(-0.2, -0.35, 0.0), _placed(0.1, 0.0, 0.0), _placed(0.8, 0.3, 0.15, 1.3)])
CENTRE = np.vstack([STEPS[1], [0, 0, 0, 1]])


def _four(m):
    return np.vstack([m[:3], [0, 0, 0, 1]])


def _pixels():
    centres = ((np.arange(SIZE) + 0.5) / SIZE - 0.5) * WIDTH
    x, y = np.meshgrid(centres, -centres)  # row 0 is the top of the image (+y)
    return np.stack([x.ravel(), y.ravel()], axis=1)


def _expected(sigma_at_object_points, placement, times=TIMES, n_z=600, z_range=1.0):
    """Shutter average of exp(-integral of sigma) along the pixels' vertical rays;
    sigma_at_object_points((N, 3) object-space points, (N, 3) world points) -> (N,);
    placement(time) -> 3x4 object -> world."""
    pixels = _pixels()
    z = (np.arange(n_z) + 0.5) / n_z * 2 * z_range - z_range
    points = np.concatenate([np.repeat(pixels, n_z, axis=0), np.tile(z, len(pixels))[:, None]], axis=1)
    total = np.zeros(len(pixels))
    for time in times:
        to_object = np.linalg.inv(_four(placement(time)))
        local = points @ to_object[:3, :3].T + to_object[:3, 3]
        depth = sigma_at_object_points(local, points).reshape(len(pixels), n_z).sum(axis=1) * (2 * z_range / n_z)
        total += np.exp(-depth)
    return (total / len(times)).reshape(SIZE, SIZE)


SAMPLES = 256


def _render(medium, boundary, samples=SAMPLES):
    camera = Camera(camera_at([0, 0, 5]), projection="orthographic", ortho_scale=WIDTH)
    scene = Scene(camera=camera, film=Film(SIZE, SIZE, filter="box", filter_width=1e-6), meshes=[boundary],
                  materials=[Material("volume", surface="null", medium=0)], media=[medium],
                  world=World(background=1.0), settings=RenderSettings(samples=samples, seed=19, threads=1))
    result = render(scene)
    assert not any("motion" in w or "majorant" in w for w in result.warnings), result.warnings
    return result.image[..., 0], np.sqrt(np.maximum(result.variance[..., 0], 1e-10))


def _z(image, expected, spread, samples=SAMPLES):
    """z-scores of the image against an expectation. A pixel the moving box crosses for a sliver of
    the shutter may have no sample inside it (variance 0): its samples are 1 or a transmittance T,
    so their standard error is at most sqrt((1 - expected) / samples), the floor used there."""
    return (image - expected) / np.maximum(spread, np.sqrt(np.abs(1.0 - expected) / samples))


def _check(image, spread, sigma_at_object_points):
    moving = lambda t: decomposed_at(STEPS, t)
    expected = _expected(sigma_at_object_points, moving)
    assert 0.02 < expected.min() and expected.max() > 0.99  # the volume covers some pixels, not all
    z = _z(image, expected, spread)
    assert np.abs(z).max() < Z_LIMIT, (np.abs(z).max(), image, expected)
    # planted: left at the shutter centre; the motion inverted about the centre
    still = _expected(sigma_at_object_points, lambda t: STEPS[1], times=[0.5])
    inverted = _expected(sigma_at_object_points,
                         lambda t: (CENTRE @ np.linalg.inv(_four(moving(t))) @ CENTRE)[:3])
    for wrong in (still, inverted):
        assert np.abs(_z(image, wrong, spread)).max() > 2 * Z_LIMIT


def _gradient_grid():
    """A 16^3 density grid linear along both object x and y over the object box [-0.5, 0.5]^3,
    absorbing only, placed at the shutter centre's transform."""
    i, j, _ = np.meshgrid(*(np.arange(16),) * 3, indexing="ij")
    density = (0.3 + 1.2 * i / 15 + 0.4 * j / 15).astype(np.float32)
    index_to_object = np.diag([1 / 15, 1 / 15, 1 / 15, 1.0])
    index_to_object[:3, 3] = -0.5
    return GridMedium("cloud", density, CENTRE @ index_to_object, [0, 0, 0], [SIGMA] * 3)


def test_moving_grid_medium_is_the_shutter_average_of_static_ones(tmp_path):
    medium = _gradient_grid()
    static = _gradient_grid()  # the same medium standing still: its lookups are the reference
    medium.set_motion(STEPS, CENTRE)
    assert medium.tables.motion_steps == 3 and static.tables.motion_steps == 1  # static: the fast path

    def sigma(local, world):
        world_at_centre = local @ CENTRE[:3, :3].T + CENTRE[:3, 3]
        return SIGMA * static.density_at(world_at_centre)

    boundary = medium.boundary_mesh(0)
    assert boundary.motion_steps == 3
    image, spread = _render(medium, boundary)
    _check(image, spread, sigma)
    # the motion survives a scene file
    camera = Camera(camera_at([0, 0, 5]))
    path = save_scene(Scene(camera=camera, film=Film(4, 4), meshes=[boundary],
                            materials=[Material("volume", surface="null", medium=0)], media=[medium]),
                      tmp_path / "moving.vpscene")
    loaded = load_scene(path).media[0]
    np.testing.assert_allclose(loaded.motion, medium.motion)
    np.testing.assert_allclose(loaded.motion_object_to_world, CENTRE)


def _ramp_program(coordinates=P.TEXCO_OBJECT):
    """sigma_a = 0.3 + 1.5 (x + 0.5) + 0.5 y^2 at object coordinates (Texture Coordinate Object;
    or another texture coordinate), no scattering (a black Principled Volume)."""
    b = ProgramBuilder("ramp")
    pos = b.alloc(3)
    b.emit("TEXCO", coordinates, pos)
    x, y, z = b.alloc(), b.alloc(), b.alloc()
    b.emit("SEPARATE3", 0, pos, x, y, z)
    lin, yy, dens = b.alloc(), b.alloc(), b.alloc()
    b.emit("MATH", P.MATH["MULTIPLY_ADD"], x, b.const(1.5), b.const(1.05), lin)
    b.emit("MATH", P.MATH["MULTIPLY"], y, y, y, yy)
    b.emit("MATH", P.MATH["MULTIPLY_ADD"], yy, b.const(0.5), lin, dens)
    b.emit("PRINCIPLED_VOLUME", 0, b.const(1.0), b.const([0.0] * 3), dens, b.const(0.0), b.const([0.0] * 3),
           b.const(0.0), b.const([1.0] * 3), b.const(0.0), b.const([1.0] * 3), b.const(1000.0))
    return b.build()


def test_moving_program_medium_is_the_shutter_average_of_static_ones():
    medium = ProgramMedium("ramp", _ramp_program(), CENTRE, ([-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]))
    medium.set_motion(STEPS)
    boundary = box_mesh("ramp box", [-0.5, -0.5, -0.5], [0.5, 0.5, 0.5], material=0)
    boundary.instances, boundary.motion = STEPS[1][None], STEPS[None]

    def sigma(local, world):
        inside = np.all(np.abs(local) <= 0.5, axis=1)
        return np.where(inside, 0.3 + 1.5 * (local[:, 0] + 0.5) + 0.5 * local[:, 1] ** 2, 0.0)

    image, spread = _render(medium, boundary)
    _check(image, spread, sigma)


def test_bad_motion_is_refused():
    medium = _gradient_grid()
    with pytest.raises(Exception, match="motion"):
        medium.set_motion(STEPS[:1], CENTRE)
    singular = STEPS.copy()
    singular[2, :3, :3] = 0.0
    with pytest.raises(Exception, match="singular"):
        medium.set_motion(singular, CENTRE)


@pytest.mark.parametrize("mirror", [1.0, -1.0])
def test_moving_bounds_face_outwards(mirror):
    """The moving box of a grid medium, placed at the frame, has outward faces also when its
    object is mirrored (instances flip a mirroring transform's winding themselves). Planted: the
    static box's winding rule (by the index -> world determinant) flips a mirrored moving box."""
    flip = np.diag([mirror, 1.0, 1.0, 1.0])
    medium = _gradient_grid()
    medium = GridMedium("cloud", medium.density[1:-2, 1:-2, 1:-2], CENTRE @ flip @ np.linalg.inv(CENTRE)
                        @ medium.source_index_to_world, [0, 0, 0], [SIGMA] * 3)
    medium.set_motion(np.stack([_four(m) @ flip for m in STEPS]), CENTRE @ flip)
    (placed,) = medium.boundary_mesh(0).world_copies()
    corners = placed.vertices[placed.triangles].astype(np.float64)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    outwards = np.einsum("ij,ij->i", normals, corners.mean(axis=1) - placed.vertices.mean(axis=0))
    assert np.all(outwards > 0)


def test_a_world_position_shader_stays_in_the_world_inside_a_moving_box():
    """Texture Coordinate Position is the world point (Cycles' sd->P), not the moving object's: the
    density field stands still while the box that holds it moves. Planted: a field that moves with
    the box (the object-coordinate expectation) fails."""
    medium = ProgramMedium("ramp", _ramp_program(P.TEXCO_POSITION), CENTRE, ([-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]))
    medium.set_motion(STEPS)
    boundary = box_mesh("ramp box", [-0.5, -0.5, -0.5], [0.5, 0.5, 0.5], material=0)
    boundary.instances, boundary.motion = STEPS[1][None], STEPS[None]

    def field(p):
        return np.maximum(0.3 + 1.5 * (p[:, 0] + 0.5) + 0.5 * p[:, 1] ** 2, 0.0)

    inside = lambda local: np.all(np.abs(local) <= 0.5, axis=1)
    samples = 8 * SAMPLES  # the carried field differs by a few hundredths: 256 samples cannot tell
    image, spread = _render(medium, boundary, samples)
    moving = lambda t: decomposed_at(STEPS, t)
    expected = _expected(lambda local, world: np.where(inside(local), field(world), 0.0), moving)
    assert np.abs(_z(image, expected, spread, samples)).max() < Z_LIMIT
    carried = _expected(lambda local, world: np.where(inside(local), field(local), 0.0), moving)
    assert np.abs(_z(image, carried, spread, samples)).max() > 2 * Z_LIMIT
