"""The pixel filter's importance sampling: offsets must follow the filter profile."""
import numpy as np
import pytest
from native_helpers import chi2_critical

from volpath_native import Film
from volpath_native.film import PixelFilter


@pytest.mark.parametrize("kind,width", [("blackman-harris", 1.5), ("gaussian", 1.5), ("box", 1.0)])
def test_filter_offsets_follow_the_profile(kind, width):
    f = PixelFilter(Film(8, 8, filter=kind, filter_width=width))
    n = 400_000
    x = f.sample(np.random.default_rng(3).random(n))
    assert np.all(np.abs(x) <= f.support + 1e-12)
    edges = np.linspace(-f.support, f.support, 41)
    observed, _ = np.histogram(x, edges)
    expected = n * np.diff(np.interp(edges, f._xs, f._cdf))  # the tabulated profile's mass per bin
    keep = expected > 20
    chi2 = np.sum((observed[keep] - expected[keep]) ** 2 / expected[keep])
    assert chi2 < chi2_critical(int(keep.sum()) - 1), chi2


def test_blackman_harris_matches_cycles_width():
    """Cycles doubles the Blackman-Harris width: 1.5 px gives support +-1.5 px and a standard
    deviation of 0.4155 px (scene/film.cpp filter_func_blackman_harris with width * 2)."""
    f = PixelFilter(Film(8, 8, filter="blackman-harris", filter_width=1.5))
    x = f.sample((np.arange(200_000) + 0.5) / 200_000)  # stratified: the std to 3 digits
    assert f.support == pytest.approx(1.5)
    assert x.std() == pytest.approx(0.41552, abs=0.0005)
