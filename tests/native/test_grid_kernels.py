"""grid_kernels: the per-ray tracking kernels the integrator calls, through GridMedium.tables.

Statistical checks are seeded z-tests with the estimator's own sample variance (|z| < Z_LIMIT) and a
chi-square test at the 1e-4 level.
"""
import numba
import numpy as np
import pytest
from native_helpers import chi2_critical, rotated_transform

from volpath_native.grid_kernels import (FLAG_BUDGET, TRACKING_BUDGET, grid_free_flight, grid_scattering,
                                         grid_transmittance)
from volpath_native.grid_medium import GridMedium
from volpath_native.sample_pattern import path_key1
from volpath_native.sampling import seed_key

Z_LIMIT = 4.0


# Loops shaped like the integrator's stage kernels (jit.stage_kernel: no NRT), calling the kernels per ray.
@numba.njit(_nrt=False)
def _transmittances(G, origins, dirs, t_max, keys, stream, out):
    for n in range(len(origins)):
        o, d = origins[n], dirs[n]
        out[n, 0], out[n, 1], out[n, 2] = grid_transmittance(G, o[0], o[1], o[2], d[0], d[1], d[2], t_max[n],
                                                             keys[n], stream)


@numba.njit(_nrt=False)
def _free_flights(G, origins, dirs, t_max, keys, stream, t_out, scattered, weight):
    for n in range(len(origins)):
        o, d = origins[n], dirs[n]
        r = grid_free_flight(G, o[0], o[1], o[2], d[0], d[1], d[2], t_max[n], keys[n], stream, 1.0, 1.0, 1.0,
                             0.0, 0.0, 0.0, 0.0, False)
        t_out[n], scattered[n] = r[0], r[1]
        weight[n, 0], weight[n, 1], weight[n, 2] = r[2], r[3], r[4]


def smooth_random_medium(seed=21, n=20):
    """A random smooth, strictly positive density with a random colour grid (non-axis-aligned)."""
    rng = np.random.default_rng(seed)
    x, y, z = np.meshgrid(*(np.linspace(0.0, 1.0, n),) * 3, indexing="ij")
    density = np.full((n, n, n), 0.6)
    for _ in range(4):
        k = rng.normal(scale=4.0, size=3)
        density += 0.25 * np.sin(k[0] * x + k[1] * y + k[2] * z + rng.uniform(0, 2 * np.pi))
    color = 0.5 + 0.4 * np.sin(3.0 * x[..., None] + rng.uniform(0, 2 * np.pi, 3)) * np.cos(2.0 * y)[..., None]
    medium = GridMedium.with_color_grid("smooth", density.astype(np.float32), color.astype(np.float32),
                                        rotated_transform(), color=(0.9, 0.7, 0.5), density_scale=4.0,
                                        absorption_color=0.2, majorant_resolution=5)
    return medium, n


def test_grid_transmittance_averages_to_exp_of_minus_optical_depth():
    medium, n = smooth_random_medium()
    rng = np.random.default_rng(22)
    rays, count = 6, 20_000
    m = medium.source_index_to_world
    ends = rng.uniform(-2.0, n + 1.0, size=(2, rays, 3))  # some ends outside the box
    w0, w1 = (e @ m[:3, :3].T + m[:3, 3] for e in ends)
    length = np.linalg.norm(w1 - w0, axis=1)
    dirs = (w1 - w0) / length[:, None]
    tau = medium.optical_depth(w0, dirs, length, steps=4096)
    assert tau.max() > 1.5 and np.median(tau) > 0.5  # the rays see the medium: the test has teeth
    origins, directions = np.repeat(w0, count, 0), np.repeat(dirs, count, 0)
    keys = rng.integers(0, 2 ** 63, rays * count, dtype=np.int64).astype(np.uint64)
    out = np.empty((rays * count, 3))
    _transmittances(medium.tables, origins, directions, np.repeat(length, count), keys, 7 << 20, out)
    estimates = out.reshape(rays, count, 3)
    mean, stderr = estimates.mean(axis=1), estimates.std(axis=1, ddof=1) / np.sqrt(count)
    z = np.abs(mean - np.exp(-tau)) / np.maximum(stderr, 1e-12)
    assert np.all(z < Z_LIMIT), (mean, np.exp(-tau), z)
    # The numpy-facing method is a loop over the same kernel (stream 0, keys from the generator).
    again = np.empty_like(out)
    _transmittances(medium.tables, origins, directions, np.repeat(length, count), keys, 7 << 20, again)
    np.testing.assert_array_equal(out, again)  # deterministic per (key, stream)
    _transmittances(medium.tables, origins, directions, np.repeat(length, count), keys, 8 << 20, again)
    assert not np.array_equal(out, again)  # another stream, other numbers
    from volpath_native.grid_kernels import FLAG_LOOKUPS, FLAG_MAJORANT, FLAG_RESIDUAL
    np.testing.assert_array_equal(medium.tables.flags[:FLAG_LOOKUPS], 0)  # no violation, no budget stop
    assert medium.tables.flags[FLAG_LOOKUPS + 1] > 0  # the lookups of residual ratio tracking are counted
    assert FLAG_MAJORANT < FLAG_LOOKUPS and FLAG_RESIDUAL < FLAG_LOOKUPS


def test_grid_free_flight_scatter_distances_follow_the_exponential_pdf():
    """Constant grey grid: collisions at rate sigma_t, all real (sigma_n = 0), weight = albedo;
    histogram of distances against p(t) = sigma_t exp(-sigma_t t) plus the escape mass exp(-sigma_t L)."""
    sigma_s, sigma_a, n = 2.0, 0.5, 16
    transform = rotated_transform()
    medium = GridMedium("const", np.ones((n, n, n), np.float32), transform, sigma_s, sigma_a)
    start, end = np.array([2.0, 3.0, 2.5]), np.array([13.0, 12.0, 12.5])  # inside the voxel-centre box
    w0, w1 = (p @ transform[:3, :3].T + transform[:3, 3] for p in (start, end))
    length = float(np.linalg.norm(w1 - w0))
    count = 100_000
    origins, dirs = np.tile(w0, (count, 1)), np.tile((w1 - w0) / length, (count, 1))
    keys = np.random.default_rng(23).integers(0, 2 ** 63, count, dtype=np.int64).astype(np.uint64)
    t, scattered, weight = np.empty(count), np.empty(count, np.bool_), np.empty((count, 3))
    _free_flights(medium.tables, origins, dirs, np.full(count, length), keys, 3 << 20, t, scattered, weight)
    sigma_t = sigma_s + sigma_a
    np.testing.assert_allclose(weight[scattered], sigma_s / sigma_t, rtol=1e-9)
    np.testing.assert_allclose(weight[~scattered], 1.0, rtol=1e-9)
    np.testing.assert_array_equal(t[~scattered], length)
    bins = np.linspace(0.0, length, 21)
    observed = np.append(np.histogram(t[scattered], bins)[0], np.count_nonzero(~scattered))
    cdf = 1.0 - np.exp(-sigma_t * bins)
    expected = count * np.append(np.diff(cdf), np.exp(-sigma_t * length))
    assert expected.min() > 50
    chi2 = np.sum((observed - expected) ** 2 / expected)
    assert chi2 < chi2_critical(len(observed) - 1), (chi2, observed, expected)


def _one_per_stratum(u):
    """Each of the len(u) equal strata of [0, 1) holds exactly one of the numbers u."""
    return np.array_equal(np.sort(np.floor(np.asarray(u) * len(u)).astype(np.int64)), np.arange(len(u)))


def test_first_collision_distances_are_stratified_over_a_pixels_samples():
    """The first tentative collision of a tracking call is the path's Sobol' number (grid_kernels
    QMC_DRAWS), so over a pixel's first 2^k samples the exponential's uniforms 1 - exp(-sigma_t t)
    fall one per stratum of width 2^-k (a (0, 2)-sequence's first coordinate); independent numbers
    (the planted error: what tracking drew before) almost never do."""
    sigma_s, sigma_a, n = 2.0, 0.5, 16
    medium = GridMedium("const", np.ones((n, n, n), np.float32), np.eye(4), sigma_s, sigma_a)
    count = 256
    origins, dirs = np.tile([0.5, 0.5, 0.5], (count, 1)), np.tile(np.array([1.0, 1.0, 1.0]) / np.sqrt(3), (count, 1))
    length = float(np.sqrt(3) * (n - 2))  # optical depth 58: every path collides
    keys = np.array([path_key1(seed_key(7), 1234, s) for s in range(count)], np.uint64)
    t, scattered, weight = np.empty(count), np.empty(count, np.bool_), np.empty((count, 3))
    _free_flights(medium.tables, origins, dirs, np.full(count, length), keys, 5 << 20, t, scattered, weight)
    assert scattered.all()  # sigma_n = 0: the first collision is real
    assert _one_per_stratum(1.0 - np.exp(-(sigma_s + sigma_a) * t))
    assert not _one_per_stratum(np.random.default_rng(5).random(count))


def test_grid_scattering_is_the_sigma_s_of_coefficients():
    medium, n = smooth_random_medium(seed=24, n=8)
    rng = np.random.default_rng(25)
    points = rng.uniform(*medium.world_bounds(), size=(50, 3))
    sigma_s, _, _ = medium.coefficients(points)
    G = medium.tables
    for p, expected in zip(points, sigma_s):
        assert grid_scattering(G, p[0], p[1], p[2]) == pytest.approx(tuple(expected), rel=1e-12, abs=1e-15)


def test_a_ray_beyond_the_step_budget_is_opaque_and_counted():
    """A tracking call whose collisions (taken + expected in the current cell) would exceed
    TRACKING_BUDGET ends as opaque (weight 0), is counted, and the numpy-facing method warns; one
    that fits runs normally (planted contrast: the same empty medium on a shorter segment)."""
    medium = GridMedium("empty", np.zeros((4, 4, 4), np.float32), np.eye(4), 1.0, 0.0, majorant_resolution=1)
    medium.majorant_grid[:] = 2.0 * TRACKING_BUDGET  # ~2 x budget null collisions per unit length
    with pytest.warns(RuntimeWarning, match="treated as opaque"):
        flight = medium.sample_free_flight([[1.0, 1.0, 0.5]], [[0.0, 0.0, 1.0]], 2.0, np.random.default_rng(0))
    np.testing.assert_array_equal(flight.weight, 0.0)
    G = medium.tables
    r = grid_free_flight(G, 1.0, 1.0, 0.5, 0.0, 0.0, 1.0, 2.0, np.uint64(5), 0, 1.0, 1.0, 1.0,
                         0.0, 0.0, 0.0, 0.0, False)
    assert r[2:5] == (0.0, 0.0, 0.0) and G.flags[FLAG_BUDGET] == 1
    # A short segment fits in the budget (~330 null collisions): weight 1 (nothing there), not counted.
    r = grid_free_flight(G, 1.0, 1.0, 0.5, 0.0, 0.0, 1.0, 0.01, np.uint64(5), 0, 1.0, 1.0, 1.0,
                         0.0, 0.0, 0.0, 0.0, False)
    assert r[2:5] == (1.0, 1.0, 1.0) and G.flags[FLAG_BUDGET] == 1
    # NaN or infinite majorants end at once too
    for bad in (np.inf, np.nan):
        medium.majorant_grid[:] = bad
        r = grid_free_flight(G, 1.0, 1.0, 0.5, 0.0, 0.0, 1.0, 0.01, np.uint64(5), 0, 1.0, 1.0, 1.0,
                             0.0, 0.0, 0.0, 0.0, False)
        assert r[2:5] == (0.0, 0.0, 0.0)
    assert G.flags[FLAG_BUDGET] == 3


def test_the_stop_flag_abandons_tracking():
    medium = GridMedium("empty", np.zeros((4, 4, 4), np.float32), np.eye(4), 1.0, 0.0, majorant_resolution=1)
    medium.majorant_grid[:] = 1000.0
    G = medium.tables
    assert grid_free_flight(G, 1.0, 1.0, 0.5, 0.0, 0.0, 1.0, 2.0, np.uint64(5), 0, 1.0, 1.0, 1.0,
                            0.0, 0.0, 0.0, 0.0, False)[2] == 1.0
    G.stop[0] = 1
    assert grid_free_flight(G, 1.0, 1.0, 0.5, 0.0, 0.0, 1.0, 2.0, np.uint64(5), 0, 1.0, 1.0, 1.0,
                            0.0, 0.0, 0.0, 0.0, False)[2] == 0.0
    assert G.flags[FLAG_BUDGET] == 0  # abandoned, not counted as opaque


def test_tables_of_every_medium_have_one_numba_type():
    """Media with and without colour/emission grids give tables of the same numba type, so a kernel
    compiles once and the integrator can hold several grids in one homogeneous tuple."""
    plain = GridMedium("plain", np.ones((3, 4, 5), np.float32), np.eye(4), 1.0, 0.5)
    colored, _ = smooth_random_medium(seed=26, n=6)
    glowing = GridMedium("glow", np.ones((2, 2, 2), np.float32), np.eye(4), 1.0, 0.0, emission=1.0,
                         emission_grid=np.ones((2, 2, 2, 3), np.float32))
    types = {numba.typeof(m.tables) for m in (plain, colored, glowing)}
    assert len(types) == 1
    for array in (a for a in plain.tables if isinstance(a, np.ndarray)):
        assert array.flags.c_contiguous
