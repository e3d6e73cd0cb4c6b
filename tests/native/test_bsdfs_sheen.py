"""The sheen lobe and its table (bsdfs/sheen.py, sheen_fit.py): the committed table is what our
reference -- a random walk in a fiber-like SGGX layer -- and fit produce, the fitted LTC lobe
follows the reference's reflected distribution, and the closure follows Cycles' rules."""
import numpy as np
import pytest

from volpath_native.bsdfs import SurfaceNode as S
from volpath_native.bsdfs import sheen_fit as sf
from volpath_native.bsdfs.batch import Hit
from volpath_native.bsdfs.tables import bsdf_tables

from bsdf_helpers import albedo

SIN_WEIGHT = np.sin((np.arange(sf.RES) + 0.5) / sf.RES * np.pi / 2)[:, None]


def _reference(mi, ai, walks=1 << 18, seed=4242):
    g = sf.grid()
    hist = np.zeros((sf.RES, sf.RES))
    R = sf._tabulate(g[mi], g[ai], walks, seed, hist)
    hist[0, :] = hist[0, :].mean()
    return R, hist


@pytest.mark.parametrize("mi,ai", [(16, 16), (8, 24), (31, 31), (4, 28), (28, 6)])
def test_table_reflectance_matches_the_reference_walk(mi, ai):
    R_table = bsdf_tables().sheen_ltc[2, ai, mi]
    R, _ = _reference(mi, ai)
    se = np.sqrt(R * (1 - R) / (1 << 18))
    assert abs(R_table - R) < 5 * se + 5e-4, (R_table, R)


@pytest.mark.parametrize("mi,ai", [(16, 16), (8, 24), (31, 31), (4, 28)])
def test_fitted_lobe_follows_the_reference(mi, ai):
    """Solid-angle weighted relative L1 distance between the LTC lobe and a fresh reference
    histogram; ~0.09 of it is the histogram's own noise at this sample count."""
    a, b, R = bsdf_tables().sheen_ltc[:, ai, mi]
    _, hist = _reference(mi, ai, walks=1 << 19)
    ltc = sf.ltc_value(a, b, R, sf._bin_directions())
    distance = (np.abs(ltc - hist) * SIN_WEIGHT).sum() / (hist * SIN_WEIGHT).sum()
    assert distance < 0.16, distance
    # the test can fail: a lobe with a 30 % wrong a is measurably further away
    wrong = sf.ltc_value(a * 1.3, b, R, sf._bin_directions())
    assert (np.abs(wrong - hist) * SIN_WEIGHT).sum() / (hist * SIN_WEIGHT).sum() > distance + 0.05


def test_sheen_node_albedo_is_the_layer_reflectance():
    """Cycles scales the sheen closure by the table's R; the LTC lobe is normalised, so the albedo
    is R times the part of the lobe above the horizon (~1)."""
    mi, ai = 20, 12
    g = sf.grid()
    mu, rough = g[mi], g[ai]
    a, se = albedo(Hit(S.for_kind("sheen", roughness=rough, color=(1.0, 1.0, 1.0)), (np.sqrt(1 - mu * mu), 0, mu)))
    R = bsdf_tables().sheen_ltc[2, ai, mi]
    assert 0.97 * R - 5 * se[0] < a[0] < R + 5 * se[0] + 1e-6


def test_sheen_closure_is_dropped_where_the_fit_is_invalid():
    """Cycles skips a sheen closure whose table albedo (or a) is below 1e-5: smooth fibres seen
    from near the normal reflect nothing back."""
    T = bsdf_tables().sheen_ltc
    ai, mi = np.argwhere(T[2] < 1e-6)[-1]
    mu = sf.grid()[mi] if mi > 0 else 0.0
    rough = ai / 31
    hit = Hit(S.for_kind("sheen", roughness=max(rough, 1e-3)), (np.sqrt(1 - mu * mu), 0, mu))
    assert hit.count == 0
    assert Hit(S.for_kind("sheen", roughness=0.5), (0.6, 0.0, 0.8)).count == 1
