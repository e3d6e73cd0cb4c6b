"""The path sampler's stratified random numbers (sample_pattern): Owen-scrambled Sobol' pairs.

What must hold: every pair of dimensions (2k, 2k + 1) of one pixel is a (0,2)-sequence over the
pixel's samples (every aligned block of 2^m samples puts exactly one point in each elementary
interval of area 2^-m); different pairs, different pixels and the same sample index across pixels
are independent and uniform (the estimate stays unbiased); renders do not depend on thread count
or batch size. Each property is checked on sample_pattern.sample1 and, as the planted error it
must catch, on a numpy copy of the algorithm with one ingredient removed (no scramble, no
pair-specific shuffle, no pixel seed, independent numbers). The copy with nothing removed must
reproduce sample1 bit for bit, so the planted variants differ from the real one only there.
"""
import numba
import numpy as np
import pytest
from native_helpers import camera_at, chi2_critical

import volpath_native as vp
from volpath_native.sample_pattern import SAMPLE_INDEX_BITS, SOBOL_BYTE_TABLES, path_key1, sample1, sample2
from volpath_native.sampling import seed_key, uniform1

M32 = np.uint64(0xFFFFFFFF)
SEED = seed_key(11)


@numba.njit
def _draw(keys, dimensions, independent):
    """sample1 (or uniform1 if independent) for every (key, dimension) of the two flat arrays."""
    out = np.empty(keys.shape[0])
    for i in range(keys.shape[0]):
        out[i] = uniform1(keys[i], dimensions[i]) if independent else sample1(keys[i], dimensions[i])
    return out


@numba.njit
def _keys(pixels, samples):
    out = np.empty(pixels.shape[0], np.uint64)
    for i in range(pixels.shape[0]):
        out[i] = path_key1(SEED, pixels[i], samples[i])
    return out


def _mix64(x):
    with np.errstate(over="ignore"):
        z = x + np.uint64(0x9E3779B97F4A7C15)
        z ^= z >> np.uint64(30)
        z *= np.uint64(0xBF58476D1CE4E5B9)
        z ^= z >> np.uint64(27)
        z *= np.uint64(0x94D049BB133111EB)
        return z ^ (z >> np.uint64(31))


def _reverse32(x):
    x = x & M32
    out = np.zeros_like(x)
    for bit in range(32):
        out |= ((x >> np.uint64(bit)) & np.uint64(1)) << np.uint64(31 - bit)
    return out


def _owen(n, seed):
    with np.errstate(over="ignore"):
        n = n ^ ((n * np.uint64(0x3D20ADEA)) & M32)
        n = (n + seed) & M32
        n = (n * ((seed >> np.uint64(16)) | np.uint64(1))) & M32
        n ^= (n * np.uint64(0x05526C56)) & M32
        return n ^ ((n * np.uint64(0x53A22864)) & M32)


def _numpy_sample(keys, dimensions, scramble=True, shuffle_per_pair=True, pixel_seed=True):
    """sample1 in numpy, with the planted errors as switches: scramble=False drops both Owen
    scrambles (the plain Sobol' pair, the same in every pixel); shuffle_per_pair=False seeds every
    pair alike (all pairs the same points); pixel_seed=False seeds every pixel alike."""
    keys = np.asarray(keys, np.uint64)
    d = np.asarray(dimensions, np.uint64)
    coordinate = (d & np.uint64(1)).astype(np.int64)
    pixel = keys >> np.uint64(SAMPLE_INDEX_BITS) if pixel_seed else np.zeros_like(keys)
    pair = d >> np.uint64(1) if shuffle_per_pair else np.zeros_like(d)
    with np.errstate(over="ignore"):
        seeds = _mix64(pixel ^ (pair * np.uint64(0x94D049BB133111EB)))
    index = _reverse32(keys & np.uint64((1 << SAMPLE_INDEX_BITS) - 1))
    if scramble:
        index = _owen(index, seeds & M32)
    x = np.zeros_like(keys)
    for b in range(3):
        x ^= SOBOL_BYTE_TABLES[coordinate, b, ((index >> np.uint64(24 - 8 * b)) & np.uint64(255)).astype(np.int64)]
    if scramble:
        x = _owen(x, (seeds >> np.uint64(32)) ^ np.array([0x2F6A1C3B, 0xE0AAAF76], np.uint64)[coordinate])
    return _reverse32(x).astype(np.float64) / 2.0 ** 32


def _independent(keys, dimensions):
    return _draw(np.asarray(keys, np.uint64), np.asarray(dimensions, np.int64), True)


SAMPLERS = {
    "sobol": lambda k, d: _draw(np.asarray(k, np.uint64), np.asarray(d, np.int64), False),
    "unscrambled": lambda k, d: _numpy_sample(k, d, scramble=False),
    "one shuffle for all pairs": lambda k, d: _numpy_sample(k, d, shuffle_per_pair=False),
    "one seed for all pixels": lambda k, d: _numpy_sample(k, d, pixel_seed=False),
    "independent": _independent,
}


def _grid(pixels, samples):
    """Flat (pixel, sample) arrays of every pixel x sample, and their keys."""
    p, s = np.meshgrid(np.asarray(pixels, np.int64), np.asarray(samples, np.int64), indexing="ij")
    return _keys(p.ravel(), s.ravel()), p.shape


def test_numpy_copy_is_sample1():
    keys, _ = _grid([0, 1, 77, 4095], np.r_[0:300, (1 << 24) - 3:(1 << 24) + 3])
    for dimension in (0, 1, 2, 3, 26, 27, 1 << 39, (1 << 39) + 1, (1 << 39) + 2):
        dims = np.full(keys.shape, dimension)
        np.testing.assert_array_equal(SAMPLERS["sobol"](keys, dims), _numpy_sample(keys, dims))


@numba.njit
def _draw_pairs(keys, dimensions):
    out = np.empty((keys.shape[0], 2))
    for i in range(keys.shape[0]):
        out[i, 0], out[i, 1] = sample2(keys[i], dimensions[i])
    return out


def test_pair_draw_is_both_coordinates_of_sample1():
    """sample2 (one shuffle for a pair's two numbers) equals sample1 at the pair's even and odd
    dimension, bit for bit."""
    keys, _ = _grid([0, 1, 77, 4095], np.r_[0:300, (1 << 24) - 3:(1 << 24) + 3])
    for dimension in (0, 2, 26, 1 << 39):
        dims = np.full(keys.shape, dimension)
        pairs = _draw_pairs(keys, dims)
        np.testing.assert_array_equal(pairs[:, 0], _draw(keys, dims, False))
        np.testing.assert_array_equal(pairs[:, 1], _draw(keys, dims + 1, False))


def test_key_holds_the_sample_index_under_a_pixel_hash():
    keys, _ = _grid([5, 6], [0, 1, 2, (1 << 24) - 1, 1 << 24])
    low = keys & np.uint64((1 << 24) - 1)
    np.testing.assert_array_equal(low, np.tile(np.array([0, 1, 2, (1 << 24) - 1, 0], np.uint64), 2))
    high = keys >> np.uint64(24)
    assert len(set(high[[0, 1, 2, 3]])) == 1 and high[4] != high[0]  # next block of 2^24: another hash
    assert high[0] != high[5]  # another pixel


def _nets(sampler, pixels, m, first_sample, pair):
    """Per pixel: do samples first_sample .. first_sample + 2^m - 1 of dimensions (2 pair, 2 pair
    + 1) put exactly one point in each elementary interval 2^-a x 2^-(m-a), for every a?"""
    keys, shape = _grid(pixels, np.arange(first_sample, first_sample + (1 << m)))
    x = sampler(keys, np.full(keys.shape, 2 * pair)).reshape(shape)
    y = sampler(keys, np.full(keys.shape, 2 * pair + 1)).reshape(shape)
    result = []
    for xs, ys in zip(x, y):
        result.append(all(len(set(np.floor(xs * 2 ** a).astype(np.int64) * 2 ** (m - a)
                                   + np.floor(ys * 2 ** (m - a)).astype(np.int64))) == 1 << m
                          for a in range(m + 1)))
    return np.array(result)


@pytest.mark.parametrize("m, first_sample", [(1, 0), (4, 0), (7, 0), (10, 0), (6, 64), (5, 1 << 20)])
@pytest.mark.parametrize("pair", [0, 1, 13, 1 << 38])
def test_each_pixels_pair_is_a_0_2_net(m, first_sample, pair):
    assert _nets(SAMPLERS["sobol"], range(0, 40, 3), m, first_sample, pair).all()


def test_net_check_rejects_independent_numbers():
    assert not _nets(SAMPLERS["independent"], range(0, 40, 3), 6, 0, 1).any()


def _chi2_uniform_2d(x, y, cells=16):
    counts = np.histogram2d(x, y, bins=cells, range=[[0, 1], [0, 1]])[0].ravel()
    expected = len(x) / cells ** 2
    return np.sum((counts - expected) ** 2 / expected), cells ** 2 - 1


PAIRS_OF_DIMENSIONS = {
    "other pair": (1, 2),                 # odd coordinate of one pair, even of the next
    "same offset, next bounce": (14, 38),  # BSDF u of iteration i and i + 1 (24 apart)
    "first of two pairs": (4, 6),
}


@pytest.mark.parametrize("dims, sampler", [(dims, "sobol") for dims in PAIRS_OF_DIMENSIONS] + [
    # planted: every pair shuffled and scrambled alike repeats a coordinate in every pair (the
    # odd coordinate of one pair and the even of the next then form a stratified pair: not caught)
    ("same offset, next bounce", "one shuffle for all pairs"), ("first of two pairs", "one shuffle for all pairs")])
def test_dimensions_of_different_pairs_are_independent(dims, sampler):
    """Within a pixel, two dimensions of different pairs are jointly uniform (not the same
    sequence twice); 64 pixels x 64 samples, a 16 x 16 chi-square."""
    d0, d1 = PAIRS_OF_DIMENSIONS[dims]
    keys, _ = _grid(range(64), range(64))
    x = SAMPLERS[sampler](keys, np.full(keys.shape, d0))
    y = SAMPLERS[sampler](keys, np.full(keys.shape, d1))
    chi2, dof = _chi2_uniform_2d(x, y)
    correlation = np.corrcoef(x, y)[0, 1]
    if sampler == "sobol":
        assert chi2 < chi2_critical(dof), chi2
        assert abs(correlation) < 4.0 / np.sqrt(len(x)), correlation
    else:  # planted: every pair shuffled alike
        assert chi2 > chi2_critical(dof, z=6.0) or abs(correlation) > 4.0 / np.sqrt(len(x)), (chi2, correlation)


@pytest.mark.parametrize("sampler", ["sobol", "one seed for all pixels", "unscrambled"])
def test_neighbouring_pixels_are_independent(sampler):
    """The same sample index and dimension in neighbouring pixels (x and x + 1, y and y + 64):
    jointly uniform, uncorrelated. 4096 pixel pairs x 4 samples."""
    left, _ = _grid(np.arange(0, 8192, 2), range(4))
    right, _ = _grid(np.arange(1, 8192, 2), range(4))
    below, _ = _grid(np.arange(0, 8192, 2) + 64, range(4))
    for other in (right, below):
        for dimension in (0, 15):
            x = SAMPLERS[sampler](left, np.full(left.shape, dimension))
            y = SAMPLERS[sampler](other, np.full(other.shape, dimension))
            chi2, dof = _chi2_uniform_2d(x, y)
            correlation = np.corrcoef(x, y)[0, 1] if np.std(x) * np.std(y) > 0 else 1.0
            if sampler == "sobol":
                assert chi2 < chi2_critical(dof) and abs(correlation) < 4.0 / np.sqrt(len(x)), (chi2, correlation)
            else:
                assert chi2 > chi2_critical(dof, z=6.0), chi2


@pytest.mark.parametrize("sampler", ["sobol", "unscrambled"])
@pytest.mark.parametrize("sample", [0, 1, 5])
def test_one_sample_index_over_pixels_is_uniform(sampler, sample):
    """Unbiasedness: over pixels, sample s of a dimension is uniform (a 64-bin chi-square over
    8192 pixels) -- so is every sample's estimate, not only their mean."""
    keys, _ = _grid(range(8192), [sample])
    for dimension in (0, 1, 9):
        x = SAMPLERS[sampler](keys, np.full(keys.shape, dimension))
        counts = np.histogram(x, bins=64, range=(0, 1))[0]
        chi2 = np.sum((counts - len(x) / 64) ** 2 / (len(x) / 64))
        if sampler == "sobol":
            assert chi2 < chi2_critical(63), chi2
        else:
            assert chi2 > chi2_critical(63, z=6.0), chi2


def test_values_are_in_the_unit_interval():
    keys, _ = _grid(range(256), range(256))
    for dimension in (0, 1, 2, 101):
        x = SAMPLERS["sobol"](keys, np.full(keys.shape, dimension))
        assert x.min() >= 0.0 and x.max() < 1.0


def _dof_scene(threads, batch_size):
    area = vp.AreaLight("panel", position=[0.0, 1.4, -2.0], axis_u=[0.8, 0, 0], axis_v=[0, 0, 0.8], power=60.0)
    floor = vp.Mesh("floor", np.array([[-3, -1, -6], [3, -1, -6], [3, -1, 1], [-3, -1, 1]], float),
                    np.array([[0, 1, 2], [0, 2, 3]]), np.zeros(2, int))
    return vp.Scene(camera=vp.Camera(camera_at([0, 0, 1]), aperture_size=0.05, focus_distance=3.0),
                    film=vp.Film(20, 12), meshes=[floor], materials=[vp.Material("floor")],
                    media=[vp.Medium("haze", 0.05, 0.01)], world=vp.World(medium=0),
                    lights=[area, vp.PointLight("bulb", [0.5, 1.0, -1.5], power=50.0, radius=0.1)],
                    settings=vp.RenderSettings(samples=9, seed=2, threads=threads, batch_size=batch_size,
                                               max_bounces=3))


def test_renders_do_not_depend_on_threads_or_batches():
    """Lens, area light, medium and bounces all draw from the pattern; the image is a function of
    (seed, pixel, sample) alone."""
    a = vp.render(_dof_scene(threads=1, batch_size=4096)).image
    b = vp.render(_dof_scene(threads=2, batch_size=333)).image
    np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-7)
    assert a[..., 0].max() > 0
