"""The pixel filter's importance sampling: offsets follow the filter profile as Cycles' table does
(film.py; tests/compare/test_agreement_pixel_filter.py checks the table against Cycles' renders)."""
import numpy as np
import pytest

from volpath_native import Film
from volpath_native.film import PixelFilter

# the table's last interval (u above 1022/1023) sweeps from the filter's edge back to the pixel's
# corner: Cycles never writes its last entry
REGULAR = 1022 / 1023


def _largest_cdf_gap(f, offsets):
    """Largest distance between the offsets' empirical CDF and the exact profile's CDF."""
    offsets = np.sort(offsets)
    empirical = (np.arange(len(offsets)) + 0.5) / len(offsets)
    return np.max(np.abs(empirical - np.interp(offsets, f._xs, f._cdf)))


@pytest.mark.parametrize("kind,width", [("blackman-harris", 1.5), ("gaussian", 1.5), ("box", 1.0), ("blackman-harris", 3.0)])
def test_filter_offsets_follow_the_profile(kind, width):
    f = PixelFilter(Film(8, 8, filter=kind, filter_width=width))
    u = (np.arange(200_000) + 0.5) / 200_000
    x = f.sample(u)
    assert np.all(np.abs(x) <= f.support + 1e-6)
    # the table's left-Riemann CDF and its extrapolated inverse (Cycles' util_cdf_invert) stay
    # within 1e-3 of the exact profile
    assert _largest_cdf_gap(f, x[u < REGULAR]) < 1e-3
    # planted: the same offsets against a profile half as wide (the width Blender shows, undoubled)
    narrow = PixelFilter(Film(8, 8, filter=kind, filter_width=0.5 * width))
    if kind != "box":
        assert _largest_cdf_gap(narrow, np.clip(x[u < REGULAR], -narrow.support, narrow.support)) > 0.05


def test_blackman_harris_matches_cycles_width():
    """Cycles doubles the Blackman-Harris width: 1.5 px gives support +-1.5 px, and its table a
    standard deviation of 0.4165 px (the exact profile's is 0.4155; scene/film.cpp
    filter_func_blackman_harris with width * 2, util_cdf_inverted)."""
    f = PixelFilter(Film(8, 8, filter="blackman-harris", filter_width=1.5))
    x = f.sample((np.arange(200_000) + 0.5) / 200_000)  # stratified: the std to 3 digits
    assert f.support == pytest.approx(1.5)
    assert x.std() == pytest.approx(0.4165, abs=0.0003)
