"""grid_slots: a call on the grid in a runtime slot of the grid tuple equals the grid kernel called on
that grid directly, bit for bit, for every slot -- the constant-index branches (0..GRID_SLOTS - 1)
and the runtime-index fallback of a tuple longer than GRID_SLOTS."""
import numba
import numpy as np
from test_grid_kernels import smooth_random_medium

from volpath_native.grid_kernels import (grid_attenuation, grid_control_occupancy, grid_free_flight,
                                         grid_nee_distance_pdf_given, grid_nee_distance_sample_pdf_given,
                                         grid_scattering, grid_transmittance)
from volpath_native.grid_slots import (GRID_SLOTS, slot_attenuation, slot_control_occupancy, slot_free_flight, slot_g,
                                       slot_nee_distance_pdf_given, slot_nee_distance_sample_pdf_given, slot_scattering,
                                       slot_transmittance)

N_VALUES = 16


@numba.njit(_nrt=False)
def _through_slots(GR, gi, o, d, t_max, key, out):
    t = slot_transmittance(GR, gi, 0.0, o, d, t_max, key, np.uint64(7))
    a = slot_attenuation(GR, gi, 0.0, o, d, t_max, key, np.uint64(7), (0.0, 0.0, 0.0, 0.0))
    f = slot_free_flight(GR, gi, 0.0, o, d, t_max, key, np.uint64(7), (1.0, 0.5, 0.25), (0.0, 0.0, 0.0, 0.0), False)
    x = (o[0] + 0.3 * t_max * d[0], o[1] + 0.3 * t_max * d[1], o[2] + 0.3 * t_max * d[2])
    s, g = slot_scattering(GR, gi, 0.0, x)
    depth, occupancy = slot_control_occupancy(GR, gi, 0.0, o, d, t_max, 0.1)
    g_t, g_pdf = slot_nee_distance_sample_pdf_given(GR, gi, 0.0, o, d, t_max, 0.1, depth, 0.7, 0.4)
    pdf_given = slot_nee_distance_pdf_given(GR, gi, 0.0, o, d, t_max, 0.1, depth, 0.5 * t_max)
    values = (t[0], t[1], t[2], a[0], a[3], f[0], f[2], f[3], s[0], s[2], g, slot_g(GR, gi), occupancy,
              g_t, g_pdf, pdf_given)
    for i in range(len(values)):
        out[i] = values[i]


@numba.njit(_nrt=False)
def _direct(G, o, d, t_max, key, out):
    t = grid_transmittance(G, o[0], o[1], o[2], d[0], d[1], d[2], t_max, key, np.uint64(7))
    a = grid_attenuation(G, o[0], o[1], o[2], d[0], d[1], d[2], t_max, key, np.uint64(7), 0.0, 0.0, 0.0, 0.0)
    f = grid_free_flight(G, o[0], o[1], o[2], d[0], d[1], d[2], t_max, key, np.uint64(7), 1.0, 0.5, 0.25,
                         0.0, 0.0, 0.0, 0.0, False)
    x = (o[0] + 0.3 * t_max * d[0], o[1] + 0.3 * t_max * d[1], o[2] + 0.3 * t_max * d[2])
    s = grid_scattering(G, x[0], x[1], x[2])
    depth, occupancy = grid_control_occupancy(G, o[0], o[1], o[2], d[0], d[1], d[2], t_max, 0.1)
    g_t, g_pdf = grid_nee_distance_sample_pdf_given(G, o[0], o[1], o[2], d[0], d[1], d[2], t_max, 0.1, depth, 0.7, 0.4)
    pdf_given = grid_nee_distance_pdf_given(G, o[0], o[1], o[2], d[0], d[1], d[2], t_max, 0.1, depth, 0.5 * t_max)
    values = (t[0], t[1], t[2], a[0], a[3], f[0], f[2], f[3], s[0], s[2], G.g, G.g, occupancy,
              g_t, g_pdf, pdf_given)
    for i in range(len(values)):
        out[i] = values[i]


def test_every_slot_calls_its_own_grid():
    count = GRID_SLOTS + 1  # one past the constant-index branches
    media = [smooth_random_medium(seed=30 + seed)[0] for seed in range(count)]
    for seed, medium in enumerate(media):
        medium.g = 0.1 * seed
    GR = tuple(medium.tables for medium in media)
    m = media[0].source_index_to_world
    o = tuple(m[:3, 3] - 2.0 * m[:3, 0])
    d = tuple(m[:3, 0] / np.linalg.norm(m[:3, 0]))
    t_max = 30.0 * float(np.linalg.norm(m[:3, 0]))
    for gi in range(count):
        via_slot, direct = np.zeros(N_VALUES), np.zeros(N_VALUES)
        _through_slots(GR, gi, o, d, t_max, np.uint64(1234 + gi), via_slot)
        _direct(GR[gi], o, d, t_max, np.uint64(1234 + gi), direct)
        np.testing.assert_array_equal(via_slot, direct, err_msg=f"slot {gi}")
        assert direct[10] == 0.1 * gi  # each slot read its own grid, not slot 0's
    # the grids differ, so a slot reading the wrong grid would not match
    first = np.zeros(N_VALUES)
    _direct(GR[0], o, d, t_max, np.uint64(1234 + 1), first)
    second = np.zeros(N_VALUES)
    _through_slots(GR, 1, o, d, t_max, np.uint64(1234 + 1), second)
    assert not np.array_equal(first[:10], second[:10])
    assert first[12] != second[12]  # the occupancy too (the control walks read their slot's cells)
