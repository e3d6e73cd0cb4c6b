"""Solid-angle sampling of rectangles (spherical_rectangle.py, Cycles' area_light_rect_sample):
the pdf is 1 / the solid angle in closed form (Van Oosterom & Strackee), the samples lie on the
rectangle and fall into its parts in proportion to their solid angles (chi-square), and the
irradiance estimate cos / pdf is Lambert's closed form (z-test). Planted errors -- a warped
second uniform, samples drawn by area -- must be rejected by the same tests."""
import numpy as np
import pytest

from volpath_native.spherical_rectangle import rectangle_sample, rectangle_solid_angle_pdf

from native_helpers import Z_LIMIT, chi2_critical

# (shading point, centre, edge u, edge v): overhead, off to the side and grazing, long and thin,
# tilted, small and far
CASES = [
    ([0.0, 0.0, 0.0], [0.2, -0.1, 1.5], [1.2, 0.0, 0.0], [0.0, 0.8, 0.0]),
    ([0.0, 0.0, 0.0], [2.5, 0.3, 0.4], [1.0, 0.0, 0.0], [0.0, 0.6, 0.0]),
    ([0.3, 0.1, 0.2], [0.0, 1.0, 1.0], [3.0, 0.0, 0.0], [0.0, 0.1, -0.1]),
    ([0.0, 0.0, 0.0], [-0.5, 0.4, 2.0], [0.6, 0.6, 0.0], [-0.3, 0.3, 0.5]),
    ([0.0, 0.0, 0.0], [10.0, -4.0, 6.0], [0.05, 0.0, 0.0], [0.0, 0.03, 0.0]),
]


def _corners(c, u, v):
    c, u, v = (np.asarray(a, float) for a in (c, u, v))
    return [c - u / 2 - v / 2, c + u / 2 - v / 2, c + u / 2 + v / 2, c - u / 2 + v / 2]


def _triangle_solid_angle(p, a, b, c):
    """Van Oosterom & Strackee 1983."""
    a, b, c = a - p, b - p, c - p
    la, lb, lc = np.linalg.norm(a), np.linalg.norm(b), np.linalg.norm(c)
    numerator = abs(a @ np.cross(b, c))
    denominator = la * lb * lc + (a @ b) * lc + (a @ c) * lb + (b @ c) * la
    return 2.0 * np.arctan2(numerator, denominator)


def _solid_angle(p, c, u, v):
    q = _corners(c, u, v)
    p = np.asarray(p, float)
    return _triangle_solid_angle(p, q[0], q[1], q[2]) + _triangle_solid_angle(p, q[0], q[2], q[3])


def _polygon_irradiance(p, n, corners):
    """Lambert's formula, unit radiance."""
    w = [(q - p) / np.linalg.norm(q - p) for q in corners]
    total = 0.0
    for a, b in zip(w, w[1:] + w[:1]):
        g = np.cross(a, b)
        total += np.arccos(np.clip(a @ b, -1, 1)) * (g / np.linalg.norm(g)) @ n
    return 0.5 * abs(total)


def _samples(case, n, seed, warp=lambda r: r):
    p, c, u, v = (np.asarray(a, float) for a in case)
    rng = np.random.default_rng(seed)
    r1, r2 = rng.random(n), warp(rng.random(n))
    out = np.array([rectangle_sample(*p, *c, *u, *v, a, b) for a, b in zip(r1, r2)])
    return out[:, :3], out[:, 3]


def _by_area(case, n, seed):
    """Planted error: points uniform by area, claimed uniform in solid angle."""
    p, c, u, v = (np.asarray(a, float) for a in case)
    rng = np.random.default_rng(seed)
    y = c + np.outer(rng.random(n) - 0.5, u) + np.outer(rng.random(n) - 0.5, v)
    return y, np.full(n, 1.0 / _solid_angle(p, c, u, v))


@pytest.mark.parametrize("case", CASES)
def test_pdf_is_one_over_the_solid_angle(case):
    expected = _solid_angle(*case)
    assert 1.0 / rectangle_solid_angle_pdf(*np.concatenate(case)) == pytest.approx(expected, rel=1e-9)
    _, pdf = _samples(case, 16, 1)
    np.testing.assert_allclose(1.0 / pdf, expected, rtol=1e-9)
    # from behind (mirrored through the plane) the same solid angle; in the plane none
    p, c, u, v = (np.asarray(a, float) for a in case)
    normal = np.cross(u, v) / np.linalg.norm(np.cross(u, v))
    mirrored = p - 2.0 * ((p - c) @ normal) * normal
    assert 1.0 / rectangle_solid_angle_pdf(*mirrored, *c, *u, *v) == pytest.approx(expected, rel=1e-9)
    assert rectangle_solid_angle_pdf(*(c + 3.0 * u), *c, *u, *v) == 0.0


def _cell_counts(case, y, cells=3):
    """Counts of points y in a cells x cells grid over the rectangle, and the grid cells."""
    p, c, u, v = (np.asarray(a, float) for a in case)
    a = (y - c) @ u / (u @ u) + 0.5
    b = (y - c) @ v / (v @ v) + 0.5
    assert np.all((a > -1e-9) & (a < 1 + 1e-9) & (b > -1e-9) & (b < 1 + 1e-9))
    counts, _, _ = np.histogram2d(a, b, bins=cells, range=[[0, 1], [0, 1]])
    expected = np.array([[_solid_angle(p, c + ((i + 0.5) / cells - 0.5) * u + ((j + 0.5) / cells - 0.5) * v,
                                       u / cells, v / cells) for j in range(cells)] for i in range(cells)])
    return counts, expected / _solid_angle(p, c, u, v) * len(y)


def _chi2(counts, expected):
    return float(((counts - expected) ** 2 / expected).sum()), counts.size - 1


@pytest.mark.parametrize("case", CASES)
def test_samples_fall_in_proportion_to_solid_angle(case):
    n = 30000
    y, _ = _samples(case, n, 2)
    # on the rectangle's plane
    p, c, u, v = (np.asarray(a, float) for a in case)
    normal = np.cross(u, v)
    assert np.abs((y - c) @ normal).max() < 1e-9 * np.linalg.norm(normal) * (1 + np.abs(c).max())
    stat, dof = _chi2(*_cell_counts(case, y))
    assert stat < chi2_critical(dof), stat
    # planted: a warped second uniform is rejected; so are area samples, where area and solid
    # angle differ by more than the test resolves (not the small far rectangle)
    warped, _ = _samples(case, n, 2, warp=lambda r: r ** 1.15)
    assert _chi2(*_cell_counts(case, warped))[0] > chi2_critical(dof)
    if case is not CASES[-1]:
        assert _chi2(*_cell_counts(case, _by_area(case, n, 2)[0]))[0] > chi2_critical(dof)


@pytest.mark.parametrize("case", CASES[:4])
def test_irradiance_estimate_is_lamberts(case):
    p, c, u, v = (np.asarray(a, float) for a in case)
    n = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])
    expected = _polygon_irradiance(p, n, _corners(c, u, v))

    def z(y, pdf):
        w = (y - p) / np.linalg.norm(y - p, axis=1, keepdims=True)
        values = np.maximum(w @ n, 0.0) / pdf
        return (values.mean() - expected) / (values.std(ddof=1) / np.sqrt(len(values)))

    count = 20000
    assert abs(z(*_samples(case, count, 3))) < Z_LIMIT
    y, pdf = _samples(case, count, 3)
    assert abs(z(y, pdf * 1.03)) > Z_LIMIT  # planted: a pdf 3 % off
