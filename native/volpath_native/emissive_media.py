"""Emissive grid and shader-program media sampled as lights from surface vertices (a fire lighting
the floor under it).

Cycles finds volume emission only along the rays that happen to cross it: a shader's emission
estimate for light sampling reads its Surface output alone (C5 scene/shader.cpp
Shader::estimate_emission), so a floor lit by a fire gathers that light from the few bounce rays
that cross the fire, and they carry most of the image's error (README session 19: ~80 % of the
procedural fire row's). Here every surface vertex also draws a point x in the emitting media, a
majorant cell with probability proportional to its mean emission (GridMedium.emission_weight: the
voxels', or a program's at the majorant build's points) x its volume and a uniform point in it
(volume density p_point(x) = mean / total, per m^3), and sends a shadow ray to it: the
estimate f |cos| T E(x) / (p_point(x) r^2) (the transmittance T by the shadow ray's tracking, as a
lamp's). The bounce ray of the same vertex keeps collecting emission at its tentative collisions
(grid_kernels: w E / majorant at each), a Poisson process of rate `majorant` along its direction:
per unit volume it places points with density p_bsdf(w) x majorant / r^2. The two are combined by
the power heuristic on those two densities (Veach 1997 sect. 9.2; any partition of unity that
depends on x and the vertex alone keeps both unbiased, so the transmittance's absence from the
bounce's density costs efficiency only): `bounce_share` on both sides, computed from the same
vertex point (the MIS origin, light_tree's MIS_P) so their weights sum to one exactly.

Sampled media: static grid or program media whose boundary mesh is a box aligned with the medium's
index axes (a Volume object's box, a cube: a program medium's box is its object's, a little
padded), points drawn in that box only -- a point outside a shaped mesh is no part of the medium
(the volume stack confines it), so media that move or a shaped mesh's are left to the bounce rays
(their collisions then weigh 1: p_point = 0 there). Cells whose sampled mean missed some glow
likewise leave it to the bounces: unbiased whatever the weights.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from .jit import inline_stage_kernel

#: relative tolerance of "the boundary mesh fills the medium's box" (volumes compared)
BOX_TOLERANCE = 1e-4
#: the share of surface vertices that take an emission sample (the point density both MIS sides
#: use is this share x p_point). Each sample's shadow ray tracks the transmittance through the
#: medium (program lookups); fewer samples leave more of the glow to the MIS-weighted bounces.
#: Measured on the procedural fire (48x48, 3 s, paired by seed, 4 seeds per run; README session 26),
#: error x time against 1.0: 0.5 -> 0.947, 0.25 -> 0.945; against 0.5: 0.35 -> 0.945, 0.7 -> 0.985
EMISSION_SHARE = 0.35

# count: sampled media (0: none); slot (K,): their grid slot; cell_start (K + 1,): each one's first
# cell in the concatenated arrays; cell_keep (N,), cell_alias (N,): the cells' pick probabilities
# as a Walker alias table (alias_table; C order per medium); cell_density (N,): p_point in that
# cell (per world m^3); cell_shape (K, 3);
# index_to_cell (K, 3): index space -> cell space scale; index_to_world (K, 3, 4); clip (K, 2, 3):
# the boundary mesh's box in index space (lowest, highest corner), where points are drawn; share:
# EMISSION_SHARE (cell_density and the grid tables' densities include it); world_to_index (K, 3, 4);
# direct: the scene's only volumes are these media and no surface lets shadows through, so a
# sample's transmittance is their tracking across their boxes and its shadow ray asks about
# opaque geometry only (path_kernels._sampled_media_transmittance, drop_blocked)
EmissiveMedia = namedtuple("EmissiveMedia", ["count", "slot", "cell_start", "cell_keep", "cell_alias", "cell_density",
                                             "cell_shape",
                                             "index_to_cell", "index_to_world", "clip", "share", "world_to_index",
                                             "direct"])


def no_emissive_media() -> EmissiveMedia:
    """A table without sampled media: surface vertices take no emission sample."""
    return EmissiveMedia(0, np.zeros(1, np.int64), np.zeros(2, np.int64), np.ones(1), np.zeros(1, np.int64), np.zeros(1),
                         np.ones((1, 3), np.int64), np.ones((1, 3)), np.zeros((1, 3, 4)), np.zeros((1, 2, 3)), 0.0,
                         np.zeros((1, 3, 4)), False)


def alias_table(weights):
    """(keep, alias) of a Walker alias table for the non-negative weights (Vose 1991): cell
    n = floor(u N) is kept when the rest of u N is below keep[n], else alias[n] is taken -- each cell
    with probability weight / sum, in O(1) where a binary search over 24^3 cells took ~14
    unpredictable branches (README session 24)."""
    n = len(weights)
    scaled = np.asarray(weights, np.float64) * (n / float(np.sum(weights)))
    keep, alias = np.ones(n), np.arange(n, dtype=np.int64)
    small = [i for i in range(n) if scaled[i] < 1.0]
    large = [i for i in range(n) if scaled[i] >= 1.0]
    while small and large:
        s, l = small.pop(), large.pop()
        keep[s], alias[s] = scaled[s], l
        scaled[l] -= 1.0 - scaled[s]
        (small if scaled[l] < 1.0 else large).append(l)
    # what is left has scaled weight 1 up to rounding: kept (keep 1)
    return keep, alias


def mesh_box(grid, corners):
    """The boundary mesh's box in the grid's index space, (lowest, highest) corner clipped to the
    grid's box, when the closed mesh with triangle corners (n, 3, 3) (world) fills that box (equal
    volumes: the box bounds the mesh, so the mesh is the box up to a set of no volume); else None."""
    if len(corners) == 0:
        return None
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    mesh = abs(float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) / 6.0)
    index = corners.reshape(-1, 3) @ grid.world_to_index[:3, :3].T + grid.world_to_index[:3, 3]
    lo, hi = index.min(axis=0), index.max(axis=0)
    box = abs(float(np.linalg.det(grid.index_to_world[:3, :3]))) * float(np.prod(hi - lo))
    if not (box > 0.0 and abs(mesh - box) <= BOX_TOLERANCE * box):
        return None
    lo, hi = np.maximum(lo, 0.0), np.minimum(hi, grid.shape - 1.0)
    return (lo, hi) if np.all(hi > lo) else None


def _overlap(grid, lo, hi):
    """(R0, R1, R2) volume (index units) of each majorant cell inside the box [lo, hi]."""
    lengths = []
    for axis in range(3):
        edges = np.arange(grid.majorant_shape[axis] + 1) * grid.cell_size[axis]
        lengths.append(np.clip(np.minimum(edges[1:], hi[axis]) - np.maximum(edges[:-1], lo[axis]), 0.0, None))
    return lengths[0][:, None, None] * lengths[1][None, :, None] * lengths[2][None, None, :]


def emissive_media(media, accel, see_through_surfaces=True):
    """(EmissiveMedia, {slot: (R0, R1, R2) p_point per majorant cell}) for the grid media of a
    MediaTable (slots in media.grid_volumes' order) that may emit (GridMedium.emission_weight > 0
    somewhere), are static and whose boundary mesh fills their box. see_through_surfaces: whether
    any surface may let shadow rays through (transparency): no direct shadows then."""
    chosen = []
    for slot, (volume, grid) in enumerate(media.grid_volumes):
        mean = getattr(grid, "emission_weight", None)
        if mean is None or not np.any(mean > 0.0):
            continue
        if grid.motion is not None or media.boundaries_move:
            continue
        box = mesh_box(grid, accel.triangle_corners(np.flatnonzero(media.tri_volume == volume)))
        if box is None:  # a shaped mesh
            continue
        inside = _overlap(grid, *box) * abs(float(np.linalg.det(grid.index_to_world[:3, :3])))  # m^3 per cell
        mean = np.where(np.isfinite(mean) & (mean > 0.0) & (inside > 0.0), mean, 0.0)
        weights = mean * inside
        if not (np.isfinite(weights.sum()) and weights.sum() > 0.0):
            continue
        chosen.append((slot, grid, weights, mean, box))
    if not chosen:
        return no_emissive_media(), {}
    total = sum(float(weights.sum()) for _, _, weights, _, _ in chosen)
    keep, alias = alias_table(np.concatenate([weights.ravel() for _, _, weights, _, _ in chosen]))
    share = float(EMISSION_SHARE)
    densities = {slot: share * mean / total for slot, _, _, mean, _ in chosen}  # per m^3 where points fall
    table = EmissiveMedia(
        count=len(chosen),
        slot=np.array([slot for slot, *_ in chosen], np.int64),
        cell_start=np.cumsum([0] + [w.size for _, _, w, _, _ in chosen]).astype(np.int64),
        cell_keep=keep, cell_alias=alias,
        cell_density=np.ascontiguousarray(np.concatenate([densities[slot].ravel() for slot, *_ in chosen])),
        cell_shape=np.array([w.shape for _, _, w, _, _ in chosen], np.int64),
        index_to_cell=np.array([1.0 / grid.cell_size for _, grid, _, _, _ in chosen], np.float64),
        index_to_world=np.ascontiguousarray([grid.index_to_world[:3] for _, grid, _, _, _ in chosen], np.float64),
        clip=np.ascontiguousarray([np.stack(box) for *_, box in chosen], np.float64), share=share,
        world_to_index=np.ascontiguousarray([grid.world_to_index[:3] for _, grid, _, _, _ in chosen], np.float64),
        direct=bool(len(chosen) == media.n_volumes and not see_through_surfaces and accel.masked))
    return table, densities


@inline_stage_kernel
def _in_cell(cell, scale, lo, hi, u):
    """Index coordinate u of the way across cell `cell` (index -> cell scale) within [lo, hi]."""
    a, b = max(cell / scale, lo), min((cell + 1) / scale, hi)
    return a + u * (b - a)


@inline_stage_kernel
def sample_emissive_point(E, u_cell, u1, u2, u3):
    """A point in the sampled media: (grid slot, (x, y, z) world, share x p_point there per m^3);
    pdf 0 when this vertex takes none (u_cell >= share)."""
    if not u_cell < E.share:
        return -1, (0.0, 0.0, 0.0), 0.0
    scaled = u_cell / E.share * E.cell_keep.shape[0]
    n = min(int(scaled), E.cell_keep.shape[0] - 1)
    if not scaled - n < E.cell_keep[n]:
        n = E.cell_alias[n]
    k = 0
    while k + 1 < E.count and n >= E.cell_start[k + 1]:
        k += 1
    local = n - E.cell_start[k]
    ny, nz = E.cell_shape[k, 1], E.cell_shape[k, 2]
    i, j, l = local // (ny * nz), (local // nz) % ny, local % nz
    px = _in_cell(i, E.index_to_cell[k, 0], E.clip[k, 0, 0], E.clip[k, 1, 0], u1)
    py = _in_cell(j, E.index_to_cell[k, 1], E.clip[k, 0, 1], E.clip[k, 1, 1], u2)
    pz = _in_cell(l, E.index_to_cell[k, 2], E.clip[k, 0, 2], E.clip[k, 1, 2], u3)
    M = E.index_to_world[k]
    x = (M[0, 0] * px + M[0, 1] * py + M[0, 2] * pz + M[0, 3],
         M[1, 0] * px + M[1, 1] * py + M[1, 2] * pz + M[1, 3],
         M[2, 0] * px + M[2, 1] * py + M[2, 2] * pz + M[2, 3])
    return E.slot[k], x, E.cell_density[n]


@inline_stage_kernel
def bounce_share(bsdf_pdf, rate, distance2, point_pdf):
    """The bounce's MIS weight (power heuristic) for emission at a point at squared distance
    distance2 from the vertex, in a cell of majorant `rate` and point density point_pdf, found
    along a direction of solid-angle pdf bsdf_pdf; the point sample's weight is 1 minus it."""
    if not point_pdf > 0.0:
        return 1.0
    if not (bsdf_pdf > 0.0 and distance2 > 0.0):
        return 0.0
    a = bsdf_pdf * rate / distance2
    if not np.isfinite(a):
        return 1.0
    return a * a / (a * a + point_pdf * point_pdf)
