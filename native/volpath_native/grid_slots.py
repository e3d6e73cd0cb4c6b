"""Calls on the grid medium in a runtime slot of the stage kernels' tuple of GridTables.

The stage kernels take the scene's grid media as one tuple of GRID_SLOTS GridTables
(integrator.py pads it so that every scene with up to that many grids shares one compiled
signature). Indexing that tuple with a runtime slot (`GR[gi]`) makes numba select the whole
33-field struct through a switch and copy it, and a non-inlined call that receives the tuple
receives all four structs field by field: measured on the height fog's shadow rays
(tests/benchmarks-style loop of grids_transmittance, one grid), 509 ns per call against 238 ns for
the same tracking called on GR[0] directly. _on_slot branches on the slot and indexes the tuple with
constants (free: the fields are the caller's own arguments), then calls the grid kernel with that
one struct; it places the medium at the path's shutter time first (medium_motion.place_at_time, a
no-op for static media).
"""
from __future__ import annotations

from .grid_kernels import (grid_attenuation, grid_cell_max_extinction, grid_control_occupancy, grid_emission,
                           grid_free_flight, grid_nee_distance_pdf_given, grid_nee_distance_sample_pdf_given,
                           grid_scattering, grid_transmittance)
from .jit import inline_stage_kernel
from .medium_motion import place_at_time

#: slots of the grid tuple with constant-index calls (integrator.GRID_SLOTS pads the tuple to this)
GRID_SLOTS = 4


@inline_stage_kernel
def _on_slot(GR, gi, time, kernel, args):
    """kernel(grid, *args) on the grid in slot gi, placed at shutter time `time`."""
    if gi == 0:
        place_at_time(GR[0], time)
        return kernel(GR[0], *args)
    if gi == 1:
        place_at_time(GR[1], time)
        return kernel(GR[1], *args)
    if gi == 2:
        place_at_time(GR[2], time)
        return kernel(GR[2], *args)
    if gi == 3:
        place_at_time(GR[3], time)
        return kernel(GR[3], *args)
    # more grids than slots (a tuple compiled longer): the runtime index, slower
    place_at_time(GR[gi], time)
    return kernel(GR[gi], *args)


@inline_stage_kernel
def slot_transmittance(GR, gi, time, o, d, t_max, key, stream):
    """grid_transmittance of the grid in slot gi over [0, t_max] of ray (o, d): rgb."""
    return _on_slot(GR, gi, time, grid_transmittance, (o[0], o[1], o[2], d[0], d[1], d[2], t_max, key, stream))


@inline_stage_kernel
def slot_attenuation(GR, gi, time, o, d, t_max, key, stream, mis):
    """grid_attenuation of the grid in slot gi: (wr, wg, wb, er, eg, eb). mis: (pdf, x, y, z) of
    the surface bounce the ray is (grid_kernels._track), pdf 0 for none."""
    return _on_slot(GR, gi, time, grid_attenuation,
                    (o[0], o[1], o[2], d[0], d[1], d[2], t_max, key, stream, mis[0], mis[1], mis[2], mis[3]))


@inline_stage_kernel
def slot_free_flight(GR, gi, time, o, d, t_max, key, stream, thr, mis, camera):
    """grid_free_flight of the grid in slot gi (thr: the path throughput, rgb; mis: as
    slot_attenuation's; camera: a camera ray): (t, scattered, wr, wg, wb, er, eg, eb)."""
    return _on_slot(GR, gi, time, grid_free_flight,
                    (o[0], o[1], o[2], d[0], d[1], d[2], t_max, key, stream, thr[0], thr[1], thr[2], mis[0], mis[1],
                     mis[2], mis[3], camera))


@inline_stage_kernel
def slot_emission(GR, gi, time, x):
    """grid_emission of the grid in slot gi at world point x: (er, eg, eb, majorant, p_point)."""
    return _on_slot(GR, gi, time, grid_emission, (x[0], x[1], x[2]))


@inline_stage_kernel
def slot_scattering(GR, gi, time, x):
    """sigma_s (rgb) of the grid in slot gi at world point x, and its Henyey-Greenstein g."""
    return _on_slot(GR, gi, time, grid_scattering, (x[0], x[1], x[2])), slot_g(GR, gi)


@inline_stage_kernel
def slot_cell_max_extinction(GR, gi, time, x):
    """grid_cell_max_extinction of the grid in slot gi at world point x."""
    return _on_slot(GR, gi, time, grid_cell_max_extinction, (x[0], x[1], x[2]))


@inline_stage_kernel
def slot_g(GR, gi):
    """Henyey-Greenstein g of the grid in slot gi."""
    if gi == 0:
        return GR[0].g
    if gi == 1:
        return GR[1].g
    if gi == 2:
        return GR[2].g
    if gi == 3:
        return GR[3].g
    return GR[gi].g


@inline_stage_kernel
def slot_nee_distance_pdf_given(GR, gi, time, o, d, t_end, sigma_extra, total, t):
    """grid_nee_distance_pdf_given of the grid in slot gi at distance t."""
    return _on_slot(GR, gi, time, grid_nee_distance_pdf_given,
                    (o[0], o[1], o[2], d[0], d[1], d[2], t_end, sigma_extra, total, t))


@inline_stage_kernel
def slot_control_occupancy(GR, gi, time, o, d, t_end, sigma_extra):
    """grid_control_occupancy of the grid in slot gi: (control depth, occupancy)."""
    return _on_slot(GR, gi, time, grid_control_occupancy, (o[0], o[1], o[2], d[0], d[1], d[2], t_end, sigma_extra))


@inline_stage_kernel
def slot_nee_distance_sample_pdf_given(GR, gi, time, o, d, t_end, sigma_extra, total, u_choice, u_t):
    """grid_nee_distance_sample_pdf_given of the grid in slot gi: (t, pdf)."""
    return _on_slot(GR, gi, time, grid_nee_distance_sample_pdf_given,
                    (o[0], o[1], o[2], d[0], d[1], d[2], t_end, sigma_extra, total, u_choice, u_t))
