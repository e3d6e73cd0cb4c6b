"""ProgramMedium: shader-program media tracked by the grid trackers, against quadrature of the same
program, with the sampled majorant deliberately violated, and rendered against a homogeneous medium."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from volpath_native import Camera, Film, Material, Medium, PointLight, RenderSettings, Scene, render
from volpath_native import program_medium
from volpath_native.program_medium import DEFAULT_MAJORANT_RESOLUTION, EMISSIVE_MAJORANT_RESOLUTION, ProgramMedium
from volpath_native.shading import program as P
from volpath_native.shading.builder import ProgramBuilder
from volpath_native.shading.interpreter import closure_coefficients, run_program_many
from volpath_native.shading.images import empty_image_table

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "native"))
from native_helpers import Z_LIMIT, box_mesh  # noqa: E402

ALBEDO = 0.7


def wavy_program(scale: float = 1.0, constant: bool = False, second_axis: str = "z", emission: float = 0.0):
    """sigma_t(P) = scale (2 + 1.5 sin(3 x) cos(2 z)) in object space (0.5 if constant), albedo 0.7
    (second_axis "y": cos(2 y) instead), Emission Strength `emission`."""
    b = ProgramBuilder("wavy")
    pos = b.alloc(3)
    b.emit("TEXCO", P.TEXCO_OBJECT, pos)
    x, y, z = b.alloc(), b.alloc(), b.alloc()
    b.emit("SEPARATE3", 0, pos, x, y, z)
    sx, cz, prod, dens = b.alloc(), b.alloc(), b.alloc(), b.alloc()
    b.emit("MATH", P.MATH["MULTIPLY"], x, b.const(3.0), b.const(0.0), sx)
    b.emit("MATH", P.MATH["SINE"], sx, sx, sx, sx)
    b.emit("MATH", P.MATH["MULTIPLY"], y if second_axis == "y" else z, b.const(2.0), b.const(0.0), cz)
    b.emit("MATH", P.MATH["COSINE"], cz, cz, cz, cz)
    b.emit("MATH", P.MATH["MULTIPLY"], sx, cz, cz, prod)
    if constant:
        b.emit("MATH", P.MATH["MULTIPLY_ADD"], prod, b.const(0.0), b.const(0.5), dens)
    else:
        b.emit("MATH", P.MATH["MULTIPLY_ADD"], prod, b.const(1.5 * scale), b.const(2.0 * scale), dens)
    b.emit("PRINCIPLED_VOLUME", 0, b.const(1.0), b.const([ALBEDO] * 3), dens, b.const(0.0), b.const([0.0] * 3),
           b.const(emission), b.const([1.0] * 3), b.const(0.0), b.const([1.0] * 3), b.const(1000.0))
    return b.build()


def object_matrix():
    m = np.eye(4)
    m[:3, :3] = np.diag([1.0, 0.8, 1.2])
    m[:3, 3] = [0.2, -0.1, 0.3]
    return m


def quadrature_depth(medium: ProgramMedium, origins, dirs, t_max, steps=2000):
    """Midpoint-rule optical depth of the program itself (max channel), inside the medium's box:
    over the ray's exact interval in the box (a rule across the box's faces would be off by
    O(step x sigma_t), more than the residual tracker's standard error)."""
    p = medium.program
    regs = np.zeros(p.n_registers)
    depth = np.zeros(len(origins))
    m = medium.world_to_index[:3]
    for n, (o, d) in enumerate(zip(origins, dirs)):
        po, pd = m[:, :3] @ o + m[:, 3], m[:, :3] @ d  # the index-space ray: box [0, shape - 1]
        with np.errstate(divide="ignore"):
            a, b = (0.0 - po) / pd, (medium.shape - 1 - po) / pd
        t0, t1 = max(np.minimum(a, b).max(), 0.0), min(np.maximum(a, b).min(), t_max)
        if not t1 > t0:
            continue
        t = t0 + (np.arange(steps) + 0.5) / steps * (t1 - t0)
        points = np.ascontiguousarray(o + d * t[:, None])
        out = np.zeros((steps, 22))
        run_program_many(p.code, p.init, p.tables, regs, medium.frame, medium.attributes,
                         np.ascontiguousarray(medium.world_to_index[:3]), points, out, P.R_SIGMA_A, 22,
                         empty_image_table())
        inside = np.all((points @ medium.world_to_index[:3, :3].T + medium.world_to_index[:3, 3] >= 0)
                        & (points @ medium.world_to_index[:3, :3].T + medium.world_to_index[:3, 3]
                           <= medium.shape - 1), axis=1)
        sigma_t = out[:, 0] + out[:, 6]  # sigma_a + lobe 0 sigma_s (red)
        depth[n] = np.sum(sigma_t * inside) * (t1 - t0) / steps
    return depth


RAYS = [((-3.0, 0.1, 0.4), (1.0, 0.05, -0.1)), ((0.3, -3.0, 0.2), (0.1, 1.0, 0.15)), ((0.5, 0.2, -3.0), (-0.1, 0.05, 1.0))]


@pytest.fixture(scope="module")
def medium():
    return ProgramMedium("wavy", wavy_program(), object_matrix(), ([-1, -1, -1], [1, 1, 1]))


def _rays():
    origins = np.array([o for o, _ in RAYS], dtype=np.float64)
    dirs = np.array([d for _, d in RAYS], dtype=np.float64)
    return origins, dirs / np.linalg.norm(dirs, axis=1, keepdims=True)


def _transmittance_z(medium, origins, dirs, reference, n=20000, seed=3):
    rng = np.random.default_rng(seed)
    zs = []
    for o, d, ref in zip(origins, dirs, reference):
        estimates = medium.transmittance(np.repeat(o[None], n, 0), np.repeat(d[None], n, 0), 8.0, rng)[:, 0]
        zs.append((estimates.mean() - ref) / (estimates.std() / np.sqrt(n) + 1e-12))
    return np.array(zs)


def test_program_coefficients_match_the_program(medium):
    points = np.random.default_rng(0).uniform(-1.0, 1.5, (500, 3))
    sigma_s, sigma_t, emission = medium.coefficients(points)
    local = (points - object_matrix()[:3, 3]) @ np.linalg.inv(object_matrix()[:3, :3]).T
    expected = 2.0 + 1.5 * np.sin(3 * local[:, 0]) * np.cos(2 * local[:, 2])
    inside = np.all(np.abs(local) <= 1.0, axis=1)
    assert np.allclose(sigma_t[inside, 0], expected[inside], rtol=1e-12)
    assert np.allclose(sigma_s[inside, 1], ALBEDO * expected[inside], rtol=1e-12)
    assert np.all(sigma_t[np.all(np.abs(local) > 1.001, axis=1)] == 0.0)
    assert np.all(emission == 0.0)


def test_majorant_bounds_the_program(medium):
    """The sampled, dilated majorant holds everywhere in the box for this smooth program."""
    rng = np.random.default_rng(1)
    index = rng.uniform(0, medium.shape - 1, (20000, 3))
    world = index @ medium.index_to_world[:3, :3].T + medium.index_to_world[:3, 3]
    _, sigma_t, _ = medium.coefficients(world)
    cells = np.minimum(index.astype(int), medium.majorant_shape - 1)
    bound = medium.majorant_grid[cells[:, 0], cells[:, 1], cells[:, 2]]
    assert np.all(sigma_t.max(axis=1) <= bound)


def test_majorant_cells_merge_along_an_axis_the_density_does_not_vary_on(medium):
    """The wavy density is constant along y: one majorant cell spans y (the tests above and below
    run on that merged grid); a density varying along y keeps its cells."""
    n = DEFAULT_MAJORANT_RESOLUTION
    assert tuple(medium.majorant_shape) == (n, 1, n)
    varying = ProgramMedium("wavy y", wavy_program(second_axis="y"), object_matrix(), ([-1, -1, -1], [1, 1, 1]))
    assert tuple(varying.majorant_shape) == (n, n, 1)


def test_an_emitting_medium_gets_the_coarser_majorant_grid():
    """Without a resolution given, a medium whose program emits gets EMISSIVE_MAJORANT_RESOLUTION
    cells per axis (its collisions estimate the glow), one without emission the finer default; a
    resolution given is kept."""
    box = ([-1, -1, -1], [1, 1, 1])
    glowing = ProgramMedium("glow", wavy_program(emission=2.0), object_matrix(), box)
    assert glowing.majorant_resolution == EMISSIVE_MAJORANT_RESOLUTION
    assert tuple(glowing.majorant_shape) == (EMISSIVE_MAJORANT_RESOLUTION, 1, EMISSIVE_MAJORANT_RESOLUTION)
    assert glowing.coefficients(np.array([[0.2, -0.1, 0.3]]))[2].max() > 0.0
    dark = ProgramMedium("dark", wavy_program(), object_matrix(), box)
    assert dark.majorant_resolution == DEFAULT_MAJORANT_RESOLUTION != EMISSIVE_MAJORANT_RESOLUTION
    given = ProgramMedium("given", wavy_program(emission=2.0), object_matrix(), box, majorant_resolution=10)
    assert given.majorant_resolution == 10 and given.majorant_shape[0] == 10


def test_the_majorant_build_in_slabs_equals_one_walk(monkeypatch):
    """The majorant grid sampled in slabs on several threads holds the same bounds, bit for bit, as
    one thread walking every cell (each slab starts at its own place in the random sequence); a
    slab starting at the sequence's beginning (planted) gives other bounds."""
    box = ([-1, -1, -1], [1, 1, 1])
    program = wavy_program(second_axis="y")  # no merged axis: every sampled cell is compared
    monkeypatch.setattr(program_medium.os, "cpu_count", lambda: 1)
    one = ProgramMedium("one", program, object_matrix(), box, majorant_resolution=12)
    monkeypatch.setattr(program_medium.os, "cpu_count", lambda: 5)
    slabs = ProgramMedium("slabs", program, object_matrix(), box, majorant_resolution=12)
    assert np.array_equal(one.majorant_grid, slabs.majorant_grid)
    assert np.array_equal(one.control_rgb, slabs.control_rgb)
    assert np.array_equal(one.residual_rate, slabs.residual_rate)
    monkeypatch.setattr(program_medium, "_slab_first_draw", lambda *args: 0)  # planted: each slab restarts
    planted = ProgramMedium("planted", program, object_matrix(), box, majorant_resolution=12)
    assert not np.array_equal(one.majorant_grid, planted.majorant_grid)


def test_transmittance_matches_quadrature_and_a_planted_error_fails(medium):
    origins, dirs = _rays()
    depth = quadrature_depth(medium, origins, dirs, 8.0)
    assert np.all(depth > 0.5)
    z = _transmittance_z(medium, origins, dirs, np.exp(-depth))
    assert np.all(np.abs(z) < Z_LIMIT), z
    planted = _transmittance_z(medium, origins, dirs, np.exp(-1.08 * depth))  # density 8 % off
    assert np.max(np.abs(planted)) > Z_LIMIT, planted


def test_free_flight_is_unbiased(medium):
    """E[weight, scattered] = albedo (1 - T) and E[weight, not scattered] = T for a grey albedo."""
    origins, dirs = _rays()
    depth = quadrature_depth(medium, origins, dirs, 8.0)
    rng = np.random.default_rng(5)
    n = 20000
    for o, d, tau in zip(origins, dirs, depth):
        ff = medium.sample_free_flight(np.repeat(o[None], n, 0), np.repeat(d[None], n, 0), 8.0, rng)
        w = ff.weight[:, 0]
        for estimate, expected in ((w * ff.scattered, ALBEDO * (1 - np.exp(-tau))), (w * ~ff.scattered, np.exp(-tau))):
            z = (estimate.mean() - expected) / (estimate.std() / np.sqrt(n))
            assert abs(z) < Z_LIMIT, (z, expected)


def test_the_camera_free_flight_collides_more_often_and_stays_unbiased():
    """Camera rays (grid_kernels.CAMERA_COLLISION_BOOST) collide more often in a thin medium that
    does not glow, with the same expectations as the plain free flight: E[weight, scattered] =
    albedo (1 - T), E[weight, not scattered] = T; planted: the boosted choice with the plain
    weights (albedo at a collision, 1 when passing) fails. A glowing medium's camera rays are left
    as they were."""
    box = ([-1, -1, -1], [1, 1, 1])
    thin = ProgramMedium("thin", wavy_program(scale=0.1), object_matrix(), box)
    origins, dirs = _rays()
    depth = quadrature_depth(thin, origins, dirs, 8.0)
    n = 20000
    for o, d, tau in zip(origins, dirs, depth):
        rays = np.repeat(o[None], n, 0), np.repeat(d[None], n, 0)
        plain = thin.sample_free_flight(*rays, 8.0, np.random.default_rng(5))
        camera = thin.sample_free_flight(*rays, 8.0, np.random.default_rng(5), camera=True)
        rate_plain, rate_camera = plain.scattered.mean(), camera.scattered.mean()
        assert rate_camera > rate_plain + 4.0 * np.sqrt(rate_plain * (1 - rate_plain) / n), (rate_plain, rate_camera)
        w = camera.weight[:, 0]
        expectations = (ALBEDO * (1 - np.exp(-tau)), np.exp(-tau))
        for estimate, expected in zip((w * camera.scattered, w * ~camera.scattered), expectations):
            z = (estimate.mean() - expected) / (estimate.std() / np.sqrt(n))
            assert abs(z) < Z_LIMIT, (z, expected)
        planted = (ALBEDO * camera.scattered, 1.0 * ~camera.scattered)
        z = [(e.mean() - x) / (e.std() / np.sqrt(n)) for e, x in zip(planted, expectations)]
        assert min(abs(np.array(z))) > Z_LIMIT, z
    glowing = ProgramMedium("glow", wavy_program(scale=0.1, emission=2.0), object_matrix(), box)
    rays = np.repeat(origins[:1], 2000, 0), np.repeat(dirs[:1], 2000, 0)
    plain = glowing.sample_free_flight(*rays, 8.0, np.random.default_rng(5))
    camera = glowing.sample_free_flight(*rays, 8.0, np.random.default_rng(5), camera=True)
    assert np.array_equal(plain.weight, camera.weight) and np.array_equal(plain.scattered, camera.scattered)


def test_a_too_low_majorant_stays_unbiased_and_is_counted():
    """Halve the sampled majorant and the residual rate: sigma_t exceeds the one and leaves control
    +- rate in much of the box; the signed weights of weighted delta / (residual) ratio tracking keep
    the estimators unbiased, and the kernels count the events."""
    from volpath_native.grid_kernels import FLAG_MAJORANT, FLAG_RESIDUAL, track_many
    low = ProgramMedium("low", wavy_program(), object_matrix(), ([-1, -1, -1], [1, 1, 1]))
    low.majorant_grid *= 0.5  # in place: the kernels read these arrays
    low.residual_rate *= 0.25
    origins, dirs = _rays()
    depth = quadrature_depth(low, origins, dirs, 8.0)
    for residual in (True, False):
        rng = np.random.default_rng(3)
        n = 40000
        for o, d, tau in zip(origins, dirs, depth):
            estimates = low.transmittance(np.repeat(o[None], n, 0), np.repeat(d[None], n, 0), 8.0, rng,
                                          residual=residual)[:, 0]
            z = (estimates.mean() - np.exp(-tau)) / (estimates.std() / np.sqrt(n) + 1e-12)
            assert abs(z) < Z_LIMIT, (residual, z)
    n = 2000
    keys = np.arange(n, dtype=np.uint64) * np.uint64(7919)
    t_out, scattered = np.empty(n), np.empty(n, bool)
    weight, emission = np.empty((n, 3)), np.empty((n, 3))
    for mode, flag in ((0, FLAG_MAJORANT), (1, FLAG_RESIDUAL)):
        tables = low._call_tables()
        track_many(tables, np.repeat(origins[:1], n, 0), np.repeat(dirs[:1], n, 0), np.zeros(n), np.full(n, 8.0),
                   keys, 0, mode, np.ones((n, 3)), t_out, scattered, weight, emission)
        assert tables.flags[flag] > 0  # the violations were seen


def lit_box_scene(medium):
    """A 2 m box of `medium` over a floor, lit by a point lamp, 12x12 at 256 spp."""
    camera = np.eye(4)
    camera[:3, 3] = [0.0, 0.0, 4.0]
    floor = box_mesh("floor", [-3, -3, -2.5], [3, 3, -2.0], 0)
    fog = box_mesh("fog", [-1, -1, -1], [1, 1, 1], 1)
    return Scene(camera=Camera(camera, fov=0.9), film=Film(12, 12), meshes=[floor, fog],
                 materials=[Material("floor"), Material("fog", surface="null", medium=0)], media=[medium],
                 lights=[PointLight("lamp", [0.5, 0.8, 1.6], power=300.0)],
                 settings=RenderSettings(samples=256, volume_bounces=4, seed=7, threads=1))


def test_render_of_a_constant_program_equals_the_homogeneous_medium():
    """The whole path: a 'varying' program whose density is the constant 0.5 renders like the
    homogeneous Medium of the same coefficients (per-pixel z-test between the two renders)."""
    program = wavy_program(constant=True)
    assert program.varying
    varying = render(lit_box_scene(ProgramMedium("const", program, np.eye(4), ([-1, -1, -1], [1, 1, 1]))))
    homogeneous = render(lit_box_scene(Medium("const", sigma_s=0.5 * ALBEDO, sigma_a=0.5 * (1 - ALBEDO))))
    a, b = varying.image[..., :3], homogeneous.image[..., :3]
    se = np.sqrt(varying.variance + homogeneous.variance) + 1e-9
    z = (a - b) / se
    assert np.all(np.abs(z) < 4.5), np.abs(z).max()
    assert a.mean() > 0.01


def test_next_events_in_cells_that_looked_empty_are_rouletted_without_bias():
    """A grid next-event vertex where every majorant cell looked empty (largest sampled extinction
    0) survives Russian roulette with EMPTY_CELL_SURVIVAL and is weighted by its inverse
    (path_kernels._empty_cell_survival). With every cell's sampled maximum set to 0 (in place: the
    kernels read the array), all next-event vertices of a wavy medium go through the roulette: the
    render must equal the untouched medium's (per-pixel z-test). Without the inverse weight the
    next events would lose 7/8 of their light, far outside the test's tolerance."""
    from volpath_native.path_kernels import EMPTY_CELL_SURVIVAL
    assert 0.0 < EMPTY_CELL_SURVIVAL < 1.0

    reference = render(lit_box_scene(ProgramMedium("wavy", wavy_program(), np.eye(4), ([-1, -1, -1], [1, 1, 1]))))
    emptied = ProgramMedium("wavy", wavy_program(), np.eye(4), ([-1, -1, -1], [1, 1, 1]))
    emptied.extinction_extrema[..., 1] = 0.0
    rouletted = render(lit_box_scene(emptied))
    a, b = rouletted.image[..., :3], reference.image[..., :3]
    z = (a - b) / (np.sqrt(rouletted.variance + reference.variance) + 1e-9)
    assert np.all(np.abs(z) < 4.5), np.abs(z).max()
    assert a.mean() > 0.01
    # the roulette did run: fewer next events survive, so the rouletted image is noisier
    assert rouletted.variance.mean() > 1.05 * reference.variance.mean()
