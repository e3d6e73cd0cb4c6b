"""Per-shading-point light selection: Cycles' light tree (scene/light_tree.cpp builds it,
kernel/light/tree.h samples it; Conty Estevez & Kulla 2018, "Importance Sampling of Many Lights
with Adaptive Tree Splitting", without splitting).

Every light row of lights.LightSet (lamps, each emissive triangle, suns, the world) is an emitter
with a bounding box, an orientation cone (axis, theta_o, theta_e) and an energy. The local
emitters form a binary tree built by the surface-area-orientation heuristic; the distant ones
(suns, world) sit in one leaf; the root's two children are the local tree and that leaf, so the
world and suns are weighed against the local lights per point as in Cycles. A shading point picks
a child by its importance (a bound on what the node can send to the point), down to a leaf, then
one emitter of the leaf. Surfaces use their position and normal, volume segments the whole ray
segment (Cycles' in_volume_segment variant). tree_pdf gives the probability of any row from the
same point: every MIS weight (lamp hit, emissive triangle, escaped ray) uses it.

Difference from Cycles, knowingly: emissive triangles go straight into the one tree with the
lamps (VolPath's emitters are world-space triangles); Cycles builds a subtree per mesh and puts
each mesh in the top tree as one emitter (for instancing). Both are unbiased; the pdfs differ.

With `enabled` False (RenderSettings.light_tree off, as Cycles' use_light_tree off) the static
selection by power (LightTables.select_prob) is used instead, through the same functions.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from .jit import kernel, stage_kernel
from .light_kernels import (AREA_ELLIPSE, AREA_RECT, DISK, POINT, SPHERE, SUN, TRIANGLE, WORLD,
                            cdf_row, distant_emission_unselected)
from .mis import mis_weight

LightTreeTables = namedtuple("LightTreeTables", [
    "enabled",       # bool: per-point selection; False: static selection by power
    "count",         # int: light rows
    "node_f",        # (M, N_NF) float64 per node: bounds, cone and its cosines (N_* columns)
    "node_i",        # (M, N_NI) int64 per node: children, leaf range, parent, distant flag
    "leaf_rows",     # (E,) int64 light rows in leaf order
    "leaf_of_row",   # (n,) int64 leaf of each light row, -1: not in the tree (no energy)
    "e_f",           # (n, E_NF) float64 per light row: what its importance needs (E_* columns)
    "e_kind",        # (n,) int64 light kind (light_kernels)
    "select_prob",   # (n,) the static selection by power (LightTables.select_prob)
    "select_cdf",    # (n,)
])
# The selection runs at every next event and every MIS weight: its tables are a few packed arrays,
# so that each call between its kernels passes a handful of array descriptors (numba passes a
# tuple of arrays field by field: the light tables' ~45 arrays cost more than the importance's
# arithmetic), and the cosines of the cone angles are computed once here, not per evaluation.
# node_f columns: bounds, cone axis and angles, energy, cos/sin of theta_o, cos(theta_o + theta_e),
# cos(theta_e - theta_o), the box centre, half its diagonal and its squared half-diagonal.
N_MIN, N_MAX, N_AXIS, N_THETA_O, N_THETA_E, N_ENERGY = 0, 3, 6, 9, 10, 11
N_COS_O, N_SIN_O, N_COS_OE, N_COS_EO, N_CENTER, N_HALF, N_R2 = 12, 13, 14, 15, 16, 19, 20
N_NF = 21
# node_i columns: left / right child (-1 for leaves), first slot in leaf_rows, emitters of a leaf
# (-1 for inner nodes, Cycles' num_emitters), parent (-1 for the root), the distant leaf flag.
N_LEFT, N_RIGHT, N_FIRST, N_COUNT, N_PARENT, N_DISTANT = range(6)
N_NI = 6
# e_f columns: position (sun: its axis), cone axis, theta_o as the importance uses it (0 for
# point-like lamps that are no spots, whose disk faces the point), theta_e, energy, the cosines as
# for nodes and cos(theta_e), radius, spot smoothstep factor, area edge vectors, triangle corners.
E_POS, E_AXIS, E_THETA_O, E_THETA_E, E_ENERGY = 0, 3, 6, 7, 8
E_COS_O, E_SIN_O, E_COS_OE, E_COS_EO, E_COS_E, E_RADIUS, E_SPOT, E_AXIS_U, E_AXIS_V, E_CORNERS = \
    9, 10, 11, 12, 13, 14, 15, 16, 19, 22
E_NF = 31

# Surface shading points without / with transmitting closures; volume segments.
MODE_SURFACE, MODE_SURFACE_TRANSMIT, MODE_VOLUME = 0, 1, 2

_PI = np.pi
_EMPTY = -1e30           # theta_o of an empty cone (Cycles OrientationBounds::empty)
_NUM_BUCKETS = 12        # LightTreeBucket::num_buckets
_MAX_LIGHTS_IN_LEAF = 8  # scene/light.cpp: LightTree light_tree(scene, dscene, progress, 8)
_FLT_MAX = 3.4028234663852886e38


# ---------------------------------------------------------------------------------------------
# Emitter measures (scene/light_tree.cpp, LightTreeEmitter constructor)
# ---------------------------------------------------------------------------------------------
def emitter_measures(lights):
    """Per light row: centroid, bbox min/max, cone axis, theta_o, theta_e, energy, distant flag."""
    n = lights.count
    centroid = np.array(lights.position, dtype=np.float64).reshape(n, 3).copy()
    bmin, bmax = centroid.copy(), centroid.copy()
    axis = np.tile([0.0, 0.0, 1.0], (n, 1))
    theta_o = np.zeros(n)
    theta_e = np.full(n, 0.5 * _PI)
    energy = np.asarray(lights.tree_energy, dtype=np.float64).copy()
    distant = np.zeros(n, bool)
    for row in range(n):
        kind = lights.kind[row]
        if kind in (POINT, SPHERE, DISK):
            r = lights.radius[row]
            bmin[row] -= r
            bmax[row] += r
            if lights.spot_smooth[row] > 0.0:   # spot: cone of its beam
                axis[row] = lights.normal[row]
                theta_e[row] = min(np.arccos(np.clip(lights.cos_half[row], -1, 1)), 0.5 * _PI)
            else:
                theta_o[row] = _PI
        elif kind in (AREA_RECT, AREA_ELLIPSE):  # one-sided, Lambertian (spread 180 degrees)
            axis[row] = lights.normal[row]
            for su in (-0.5, 0.5):
                for sv in (-0.5, 0.5):
                    c = lights.position[row] + su * lights.axis_u[row] + sv * lights.axis_v[row]
                    bmin[row] = np.minimum(bmin[row], c)
                    bmax[row] = np.maximum(bmax[row], c)
        elif kind == TRIANGLE:
            c = lights.corners[lights.triangle[row]]
            bmin[row], bmax[row] = c.min(axis=0), c.max(axis=0)
            if lights.two_sided[row]:  # any vector in the plane, theta_o = pi / 2
                edge = c[0] - c[1]
                axis[row] = edge / max(np.linalg.norm(edge), 1e-300)
                theta_o[row] = 0.5 * _PI
            else:
                axis[row] = lights.normal[row]
        elif kind == SUN:
            axis[row] = -lights.normal[row]  # travel direction (Cycles klight->co)
            centroid[row] = axis[row]
            theta_e[row] = np.arccos(np.clip(lights.cos_half[row], -1, 1))
            distant[row] = True
        elif kind == WORLD:
            axis[row] = (0.0, 0.0, 1.0)  # arbitrary (LightTreeEmitter: background)
            theta_o[row] = _PI
            theta_e[row] = 0.0
            distant[row] = True
    return centroid, bmin, bmax, axis, theta_o, theta_e, energy, distant


def build_light_tree(lights, enabled: bool = True) -> LightTreeTables:
    n = lights.count
    centroid, bmin, bmax, axis, theta_o, theta_e, energy, distant = emitter_measures(lights)
    usable = energy > 0.0
    local = np.nonzero(usable & ~distant)[0].astype(np.int64)
    far = np.nonzero(usable & distant)[0].astype(np.int64)
    cap = 2 * len(local) + 4
    node_min, node_max, node_axis = np.zeros((cap, 3)), np.zeros((cap, 3)), np.zeros((cap, 3))
    node_to, node_te, node_energy = np.full(cap, _EMPTY), np.full(cap, _EMPTY), np.zeros(cap)
    node_left, node_right = np.full(cap, -1, np.int64), np.full(cap, -1, np.int64)
    node_first, node_count = np.zeros(cap, np.int64), np.full(cap, -1, np.int64)
    node_parent = np.full(cap, -1, np.int64)
    order = local.copy()
    m = _build(order, centroid, bmin, bmax, axis, theta_o, theta_e, energy, node_min, node_max, node_axis,
               node_to, node_te, node_energy, node_left, node_right, node_first, node_count, node_parent)
    # root: [0]; local tree from [1]; the distant leaf last (light_tree.cpp LightTree::build)
    d = m
    node_first[d], node_count[d], node_parent[d] = len(local), len(far), 0
    node_left[0], node_right[0] = 1, d
    _leaf_measure(far, bmin, bmax, axis, theta_o, theta_e, energy, node_min, node_max, node_axis, node_to,
                  node_te, node_energy, d)
    m += 1
    node_distant = np.zeros(m, bool)
    node_distant[d] = True
    leaf_rows = np.concatenate([order, far]).astype(np.int64)
    leaf_of_row = np.full(n, -1, np.int64)
    for node in range(m):
        if node_count[node] > 0:
            leaf_of_row[leaf_rows[node_first[node]:node_first[node] + node_count[node]]] = node
    node_f = np.zeros((m, N_NF))
    node_f[:, N_MIN:N_MIN + 3], node_f[:, N_MAX:N_MAX + 3] = node_min[:m], node_max[:m]
    node_f[:, N_AXIS:N_AXIS + 3] = node_axis[:m]
    node_f[:, N_THETA_O], node_f[:, N_THETA_E], node_f[:, N_ENERGY] = node_to[:m], node_te[:m], node_energy[:m]
    _cone_cosines(node_f, N_THETA_O, N_THETA_E, N_COS_O)
    with np.errstate(invalid="ignore"):  # an empty leaf's (inf, -inf) box: never evaluated (no emitters)
        centre = 0.5 * (node_min[:m] + node_max[:m])
        node_f[:, N_CENTER:N_CENTER + 3] = centre
        node_f[:, N_R2] = ((node_max[:m] - centre) ** 2).sum(axis=1)
        node_f[:, N_HALF] = 0.5 * np.sqrt(node_f[:, N_R2])
    node_i = np.stack([node_left[:m], node_right[:m], node_first[:m], node_count[:m], node_parent[:m],
                       node_distant.astype(np.int64)], axis=1)
    return LightTreeTables(
        enabled=bool(enabled), count=int(n), node_f=np.ascontiguousarray(node_f),
        node_i=np.ascontiguousarray(node_i, dtype=np.int64), leaf_rows=np.ascontiguousarray(leaf_rows),
        leaf_of_row=leaf_of_row, e_f=_emitter_table(lights, axis, theta_o, theta_e, energy),
        e_kind=np.ascontiguousarray(lights.kind, dtype=np.int64).reshape(n),
        select_prob=np.ascontiguousarray(lights.select_prob, dtype=np.float64).reshape(n),
        select_cdf=np.ascontiguousarray(lights.select_cdf, dtype=np.float64).reshape(n))


def _cone_cosines(table, theta_o_col, theta_e_col, first):
    """cos theta_o, sin theta_o, cos(theta_o + theta_e), cos(theta_e - theta_o) into the four
    columns from `first` (what tree.h light_tree_importance takes the cosine of per evaluation)."""
    to, te = table[:, theta_o_col], table[:, theta_e_col]
    table[:, first], table[:, first + 1] = np.cos(to), np.sin(to)
    table[:, first + 2], table[:, first + 3] = np.cos(to + te), np.cos(te - to)


def _emitter_table(lights, axis, theta_o, theta_e, energy):
    """e_f: per light row what emitter_importance reads (see the E_* columns)."""
    n = lights.count
    e = np.zeros((n, E_NF))
    kind = np.asarray(lights.kind).reshape(n)
    position = np.asarray(lights.position, dtype=np.float64).reshape(n, 3)
    e[:, E_POS:E_POS + 3] = position
    e[kind == SUN, E_POS:E_POS + 3] = axis[kind == SUN]
    e[kind == WORLD, E_POS:E_POS + 3] = (0.0, 0.0, 1.0)
    e[:, E_AXIS:E_AXIS + 3] = axis
    spot_smooth = np.asarray(lights.spot_smooth, dtype=np.float64).reshape(n)
    point_like = np.isin(kind, (POINT, SPHERE, DISK)) & ~(spot_smooth > 0.0)
    e[:, E_THETA_O] = np.where(point_like, 0.0, theta_o)
    e[:, E_THETA_E], e[:, E_ENERGY] = theta_e, energy
    _cone_cosines(e, E_THETA_O, E_THETA_E, E_COS_O)
    e[:, E_COS_E] = np.cos(theta_e)
    e[:, E_RADIUS] = np.asarray(lights.radius, dtype=np.float64).reshape(n)
    e[:, E_SPOT] = spot_smooth
    e[:, E_AXIS_U:E_AXIS_U + 3] = np.asarray(lights.axis_u, dtype=np.float64).reshape(n, 3)
    e[:, E_AXIS_V:E_AXIS_V + 3] = np.asarray(lights.axis_v, dtype=np.float64).reshape(n, 3)
    triangle = np.asarray(lights.triangle).reshape(n)
    rows = np.nonzero(kind == TRIANGLE)[0]
    if len(rows):
        corners = np.asarray(lights.corners, dtype=np.float64).reshape(-1, 3, 3)
        e[rows, E_CORNERS:E_CORNERS + 9] = corners[triangle[rows]].reshape(len(rows), 9)
    return np.ascontiguousarray(e)


# ---------------------------------------------------------------------------------------------
# Construction (compiled: tens of thousands of emissive triangles)
# ---------------------------------------------------------------------------------------------
@kernel
def _cone_merge(ax, ay, az, ao, ae, bx, by, bz, bo, be):
    """Smallest cone holding both (light_tree.cpp merge(OrientationBounds))."""
    if ao == _EMPTY:
        return bx, by, bz, bo, be
    if bo == _EMPTY:
        return ax, ay, az, ao, ae
    if bo > ao:
        ax, ay, az, ao, ae, bx, by, bz, bo, be = bx, by, bz, bo, be, ax, ay, az, ao, ae
    cos_ab = ax * bx + ay * by + az * bz
    theta_d = np.arccos(min(max(cos_ab, -1.0), 1.0))
    te = max(ae, be)
    if ao + 5e-4 >= min(_PI, theta_d + bo):
        return ax, ay, az, ao, te
    to = (theta_d + ao + bo) * 0.5
    if to >= _PI:
        return ax, ay, az, _PI, te
    if cos_ab < -0.9995:
        # any vector orthogonal to a (make_orthonormals)
        if abs(ax) < 0.9:
            ox, oy, oz = 0.0, az, -ay
        else:
            ox, oy, oz = -az, 0.0, ax
        ln = np.sqrt(ox * ox + oy * oy + oz * oz)
        return ox / ln, oy / ln, oz / ln, to, te
    tr = to - ao
    ox, oy, oz = bx - ax * cos_ab, by - ay * cos_ab, bz - az * cos_ab
    ln = np.sqrt(ox * ox + oy * oy + oz * oz)
    if ln > 0.0:
        ox, oy, oz = ox / ln, oy / ln, oz / ln
    c, s = np.cos(tr), np.sin(tr)
    return ax * c + ox * s, ay * c + oy * s, az * c + oz * s, to, te


@kernel
def _cone_measure(to, te):
    """OrientationBounds::calculate_measure."""
    if to == _EMPTY:
        return 0.0
    tw = min(_PI, to + te)
    co, so = np.cos(to), np.sin(to)
    return 2.0 * _PI * (1.0 - co) + 0.5 * _PI * (2.0 * tw * so - np.cos(to - 2.0 * tw) - 2.0 * to * so + co)


@kernel
def _measure_cost(mn, mx, to, te, energy):
    """LightTreeMeasure::calculate (SAOH, Eq. 2 of the paper)."""
    if energy == 0.0:
        return 0.0
    dx, dy, dz = mx[0] - mn[0], mx[1] - mn[1], mx[2] - mn[2]
    area = 2.0 * (dx * dy + dy * dz + dz * dx)
    if area == 0.0:
        area = np.sqrt(dx * dx + dy * dy + dz * dz)
    return energy * area * _cone_measure(to, te)


@kernel
def _accumulate(rows, bmin, bmax, axis, theta_o, theta_e, energy, mn, mx, ax3, cone):
    """Measure of a set of emitters: bbox into mn/mx, cone into ax3/cone[0:2]; returns energy."""
    e = 0.0
    for i in range(rows.shape[0]):
        r = rows[i]
        if energy[r] == 0.0:
            continue
        for k in range(3):
            mn[k] = min(mn[k], bmin[r, k])
            mx[k] = max(mx[k], bmax[r, k])
        a0, a1, a2, cone[0], cone[1] = _cone_merge(ax3[0], ax3[1], ax3[2], cone[0], cone[1], axis[r, 0], axis[r, 1],
                                                   axis[r, 2], theta_o[r], theta_e[r])
        ax3[0], ax3[1], ax3[2] = a0, a1, a2
        e += energy[r]
    return e


@kernel
def _leaf_measure(rows, bmin, bmax, axis, theta_o, theta_e, energy, node_min, node_max, node_axis, node_to,
                  node_te, node_energy, node):
    mn, mx = np.full(3, np.inf), np.full(3, -np.inf)
    ax3, cone = np.zeros(3), np.array([_EMPTY, _EMPTY])
    node_energy[node] = _accumulate(rows, bmin, bmax, axis, theta_o, theta_e, energy, mn, mx, ax3, cone)
    node_min[node], node_max[node], node_axis[node] = mn, mx, ax3
    node_to[node], node_te[node] = cone[0], cone[1]


@kernel
def _build(order, centroid, bmin, bmax, axis, theta_o, theta_e, energy, node_min, node_max, node_axis, node_to,
           node_te, node_energy, node_left, node_right, node_first, node_count, node_parent):
    """Root 0 (inner), local tree from node 1 over order[...] (reordered in place), by
    LightTree::recursive_build / should_split: 12 buckets per axis, SAOH cost with the axis'
    regularisation, a leaf when no split is cheaper and it holds at most 8 emitters. Returns the
    number of nodes used."""
    nb = _NUM_BUCKETS
    # explicit stack of (node, start, end)
    stack = np.zeros((order.shape[0] * 2 + 8, 3), np.int64)
    top = 0
    stack[0, 0], stack[0, 1], stack[0, 2] = 1, 0, order.shape[0]
    top = 1
    count = 2
    node_parent[1] = 0
    b_min, b_max = np.zeros((nb, 3)), np.zeros((nb, 3))
    b_axis, b_cone = np.zeros((nb, 3)), np.zeros((nb, 2))
    b_energy, b_count = np.zeros(nb), np.zeros(nb, np.int64)
    l_min, l_max, l_axis, l_cone = np.zeros((nb, 3)), np.zeros((nb, 3)), np.zeros((nb, 3)), np.zeros((nb, 2))
    l_energy, l_count = np.zeros(nb), np.zeros(nb, np.int64)
    r_min, r_max, r_axis, r_cone = np.zeros((nb, 3)), np.zeros((nb, 3)), np.zeros((nb, 3)), np.zeros((nb, 2))
    r_energy = np.zeros(nb)
    while top > 0:
        top -= 1
        node, start, end = stack[top, 0], stack[top, 1], stack[top, 2]
        rows = order[start:end]
        num = end - start
        # node measure
        mn, mx = np.full(3, np.inf), np.full(3, -np.inf)
        ax3, cone = np.zeros(3), np.array([_EMPTY, _EMPTY])
        e = _accumulate(rows, bmin, bmax, axis, theta_o, theta_e, energy, mn, mx, ax3, cone)
        node_min[node], node_max[node], node_axis[node] = mn, mx, ax3
        node_to[node], node_te[node], node_energy[node] = cone[0], cone[1], e
        split = False
        split_dim = -1
        middle = (start + end) // 2
        if num >= 2:
            cmin, cmax = np.full(3, np.inf), np.full(3, -np.inf)
            for i in range(num):
                for k in range(3):
                    cmin[k] = min(cmin[k], centroid[rows[i], k])
                    cmax[k] = max(cmax[k], centroid[rows[i], k])
            ext = cmax - cmin
            max_extent = max(max(ext[0], ext[1]), max(ext[2], 0.0))
            total_cost = 0.0
            min_cost = _FLT_MAX
            for dim in range(3):
                if ext[dim] == 0.0 and dim != 0:
                    continue
                b_min[:], b_max[:] = np.inf, -np.inf
                b_axis[:], b_cone[:] = 0.0, _EMPTY
                b_energy[:], b_count[:] = 0.0, 0
                inv_extent = _FLT_MAX if ext[dim] == 0.0 else 1.0 / ext[dim]
                for i in range(num):
                    r = rows[i]
                    b = 0
                    if ext[dim] != 0.0:
                        b = min(max(int(nb * (centroid[r, dim] - cmin[dim]) * inv_extent), 0), nb - 1)
                    b_count[b] += 1
                    if energy[r] == 0.0:
                        continue
                    for k in range(3):
                        b_min[b, k] = min(b_min[b, k], bmin[r, k])
                        b_max[b, k] = max(b_max[b, k], bmax[r, k])
                    a0, a1, a2, b_cone[b, 0], b_cone[b, 1] = _cone_merge(
                        b_axis[b, 0], b_axis[b, 1], b_axis[b, 2], b_cone[b, 0], b_cone[b, 1],
                        axis[r, 0], axis[r, 1], axis[r, 2], theta_o[r], theta_e[r])
                    b_axis[b, 0], b_axis[b, 1], b_axis[b, 2] = a0, a1, a2
                    b_energy[b] += energy[r]
                # cumulative left (buckets 0..i) and right (buckets i+1..) measures
                for i in range(nb - 1):
                    if i == 0:
                        l_min[0], l_max[0], l_axis[0], l_cone[0] = b_min[0], b_max[0], b_axis[0], b_cone[0]
                        l_energy[0], l_count[0] = b_energy[0], b_count[0]
                    else:
                        _merge_bucket(l_min, l_max, l_axis, l_cone, l_energy, i - 1, b_min, b_max, b_axis, b_cone,
                                      b_energy, i, l_min, l_max, l_axis, l_cone, l_energy, i)
                        l_count[i] = l_count[i - 1] + b_count[i]
                if dim == 0:
                    if ext[0] == 0.0 and ext[1] == 0.0 and ext[2] == 0.0:
                        break
                    if ext[0] == 0.0:
                        continue  # (Cycles leaves total_cost at 0 here)
                    total_cost = _measure_cost(mn, mx, cone[0], cone[1], e)
                    if total_cost == 0.0:
                        break
                r_min[nb - 2], r_max[nb - 2], r_axis[nb - 2] = b_min[nb - 1], b_max[nb - 1], b_axis[nb - 1]
                r_cone[nb - 2], r_energy[nb - 2] = b_cone[nb - 1], b_energy[nb - 1]
                for i in range(nb - 3, -1, -1):
                    _merge_bucket(r_min, r_max, r_axis, r_cone, r_energy, i + 1, b_min, b_max, b_axis, b_cone,
                                  b_energy, i + 1, r_min, r_max, r_axis, r_cone, r_energy, i)
                regularization = max_extent * inv_extent
                for i in range(nb - 1):
                    lc = _measure_cost(l_min[i], l_max[i], l_cone[i, 0], l_cone[i, 1], l_energy[i])
                    rc = _measure_cost(r_min[i], r_max[i], r_cone[i, 0], r_cone[i, 1], r_energy[i])
                    cost = regularization * (lc + rc)
                    if cost < total_cost and cost < min_cost:
                        min_cost = cost
                        split_dim = dim
                        middle = start + l_count[i]
            split = min_cost < total_cost or num > _MAX_LIGHTS_IN_LEAF
        if not split:
            node_first[node], node_count[node] = start, num
            continue
        if split_dim != -1:  # partition by centroid (nth_element); a sort keeps it deterministic
            keys = np.empty(num)
            for i in range(num):
                keys[i] = centroid[rows[i], split_dim]
            perm = np.argsort(keys, kind="mergesort")
            sorted_rows = rows[perm].copy()
            order[start:end] = sorted_rows
        if middle <= start or middle >= end:
            middle = (start + end) // 2
        left, right = count, count + 1
        count += 2
        node_left[node], node_right[node], node_count[node] = left, right, -1
        node_parent[left], node_parent[right] = node, node
        stack[top, 0], stack[top, 1], stack[top, 2] = right, middle, end
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = left, start, middle
        top += 2
    node_count[0] = -1
    return count


@kernel
def _merge_bucket(a_min, a_max, a_axis, a_cone, a_energy, i, b_min, b_max, b_axis, b_cone, b_energy, j,
                  o_min, o_max, o_axis, o_cone, o_energy, k):
    """o[k] = a[i] + b[j] (LightTreeMeasure::add)."""
    if b_energy[j] == 0.0:
        mn0, mn1, mn2 = a_min[i, 0], a_min[i, 1], a_min[i, 2]
        mx0, mx1, mx2 = a_max[i, 0], a_max[i, 1], a_max[i, 2]
        x, y, z, to, te, e = a_axis[i, 0], a_axis[i, 1], a_axis[i, 2], a_cone[i, 0], a_cone[i, 1], a_energy[i]
    else:
        mn0, mn1, mn2 = min(a_min[i, 0], b_min[j, 0]), min(a_min[i, 1], b_min[j, 1]), min(a_min[i, 2], b_min[j, 2])
        mx0, mx1, mx2 = max(a_max[i, 0], b_max[j, 0]), max(a_max[i, 1], b_max[j, 1]), max(a_max[i, 2], b_max[j, 2])
        x, y, z, to, te = _cone_merge(a_axis[i, 0], a_axis[i, 1], a_axis[i, 2], a_cone[i, 0], a_cone[i, 1],
                                      b_axis[j, 0], b_axis[j, 1], b_axis[j, 2], b_cone[j, 0], b_cone[j, 1])
        e = a_energy[i] + b_energy[j]
    o_min[k, 0], o_min[k, 1], o_min[k, 2] = mn0, mn1, mn2
    o_max[k, 0], o_max[k, 1], o_max[k, 2] = mx0, mx1, mx2
    o_axis[k, 0], o_axis[k, 1], o_axis[k, 2] = x, y, z
    o_cone[k, 0], o_cone[k, 1], o_energy[k] = to, te, e


# ---------------------------------------------------------------------------------------------
# Importance (kernel/light/tree.h)
# ---------------------------------------------------------------------------------------------
@stage_kernel
def _sin_from_cos(c):
    return np.sqrt(max(1.0 - c * c, 0.0))


@stage_kernel
def _normalize_len(x, y, z):
    d = np.sqrt(x * x + y * y + z * z)
    if d > 0.0:
        return x / d, y / d, z / d, d
    return 0.0, 0.0, 0.0, 0.0


@stage_kernel
def _importance(volume, has_transmission, nx, ny, nz, cx, cy, cz, cos_theta_u, ax, ay, az, theta_o, theta_e,
                cos_theta_o, sin_theta_o, cos_theta_oe, cos_theta_eo, max_distance, min_distance, energy, theta_d):
    """(max, min) importance of a cluster or emitter seen along the unit direction c (point to
    centroid) within cos_theta_u (tree.h light_tree_importance; N the normal, or the segment's
    direction in volumes, where the incidence term is omitted). cos_theta_oe, cos_theta_eo:
    cos(theta_o + theta_e), cos(theta_e - theta_o), precomputed with cos / sin theta_o."""
    sin_theta_u = _sin_from_cos(cos_theta_u)
    cos_min_incidence = 1.0
    cos_max_incidence = 1.0
    if not volume:
        cos_theta_i = cx * nx + cy * ny + cz * nz
        if has_transmission:
            cos_theta_i = abs(cos_theta_i)
        sin_theta_i = _sin_from_cos(cos_theta_i)
        cos_min_incidence = 1.0 if cos_theta_i >= cos_theta_u else cos_theta_i * cos_theta_u + sin_theta_i * sin_theta_u
        if not has_transmission and cos_min_incidence < 0.0:
            return 0.0, 0.0
        cos_max_incidence = max(cos_theta_i * cos_theta_u - sin_theta_i * sin_theta_u, 0.0)
    if ax == -cx and ay == -cy and az == -cz:
        cos_theta, sin_theta = 1.0, 0.0
    else:
        cos_theta = -(ax * cx + ay * cy + az * cz)
        sin_theta = _sin_from_cos(cos_theta)
    cos_theta_minus_theta_u = cos_theta * cos_theta_u + sin_theta * sin_theta_u
    if cos_theta >= cos_theta_u or cos_theta_minus_theta_u >= cos_theta_o:
        cos_min_outgoing = 1.0
    elif theta_o + theta_e > _PI or cos_theta_minus_theta_u > cos_theta_oe:
        s = _sin_from_cos(cos_theta_minus_theta_u)
        cos_min_outgoing = cos_theta_minus_theta_u * cos_theta_o + s * sin_theta_o
    else:
        return 0.0, 0.0  # the cluster cannot face the point
    if volume:
        return abs(cos_min_incidence * energy * cos_min_outgoing * theta_d / min_distance), 0.0
    max_importance = abs(cos_min_incidence * energy * cos_min_outgoing / (min_distance * min_distance))
    cos_theta_plus_theta_u = cos_theta * cos_theta_u - sin_theta * sin_theta_u
    if theta_e - theta_o < 0.0 or cos_theta < 0.0 or cos_theta_u < 0.0 or cos_theta_plus_theta_u < cos_theta_eo:
        return max_importance, 0.0
    s = _sin_from_cos(cos_theta_plus_theta_u)
    cos_max_outgoing = cos_theta_plus_theta_u * cos_theta_o - s * sin_theta_o
    return max_importance, abs(cos_max_incidence * energy * cos_max_outgoing / (max_distance * max_distance))


@stage_kernel
def _compute_v(cx, cy, cz, px, py, pz, dx, dy, dz, ax, ay, az, t):
    """The direction from the centroid to the point of the segment that forms the smallest angle
    with the cone axis (tree.h compute_v, Fig. 8 of the paper)."""
    tt = min(t, 1e12)
    v0x, v0y, v0z, _ = _normalize_len(px - cx, py - cy, pz - cz)
    v1x, v1y, v1z, _ = _normalize_len(px - cx + dx * tt, py - cy + dy * tt, pz - cz + dz * tt)
    # make_orthonormals_tangent(o0 = v0, v1): b = normalize(cross(o0, v1)), o1 = cross(b, o0)
    bx, by, bz, _ = _normalize_len(v0y * v1z - v0z * v1y, v0z * v1x - v0x * v1z, v0x * v1y - v0y * v1x)
    o1x, o1y, o1z = by * v0z - bz * v0y, bz * v0x - bx * v0z, bx * v0y - by * v0x
    d0 = v0x * ax + v0y * ay + v0z * az
    d1 = o1x * ax + o1y * ay + o1z * az
    s = d0 * d0 + d1 * d1
    if s <= 0.0:
        return v0x, v0y, v0z
    inv_len = 1.0 / np.sqrt(s)
    cos_phi0 = d0 * inv_len
    if d1 < 0.0 or v0x * v1x + v0y * v1y + v0z * v1z > cos_phi0:
        if d0 > v1x * ax + v1y * ay + v1z * az:
            return v0x, v0y, v0z
        return v1x, v1y, v1z
    return (cos_phi0 * v0x + d1 * inv_len * o1x, cos_phi0 * v0y + d1 * inv_len * o1y,
            cos_phi0 * v0z + d1 * inv_len * o1z)


@stage_kernel
def _segment_theta_d(cx, cy, cz, px, py, pz, dx, dy, dz, t):
    """Closest parameter of the segment to c, its distance and the angle the segment subtends
    from c (theta_b - theta_a of Eq. 4; tree.h)."""
    closest_t = (cx - px) * dx + (cy - py) * dy + (cz - pz) * dz
    ex, ey, ez = cx - px - dx * closest_t, cy - py - dy * closest_t, cz - pz - dz * closest_t
    dist = np.sqrt(ex * ex + ey * ey + ez * ez)
    if t == np.inf:
        theta_d = np.arctan2(closest_t, dist) + 0.5 * _PI
    else:
        ratio = (t - closest_t) / dist if dist != 0.0 else 0.0
        theta_d = np.arctan2(t, dist - closest_t * ratio)
    return closest_t, dist, theta_d


@stage_kernel
def _subtended_cos(r2, cx, cy, cz, px, py, pz):
    """Cosine of the half-angle of the bounding sphere (centre c, squared radius r2) seen from p
    (-1 inside it)."""
    d2 = (px - cx) ** 2 + (py - cy) ** 2 + (pz - cz) ** 2
    if d2 <= r2:
        return -1.0
    return np.sqrt(max(1.0 - r2 / d2, 0.0))


@stage_kernel
def node_importance(LT, node, px, py, pz, nx, ny, nz, t, mode):
    """(max, min) importance of an inner node or a leaf of several emitters
    (tree.h light_tree_node_importance)."""
    volume = mode == MODE_VOLUME
    has_transmission = mode != MODE_SURFACE
    f = LT.node_f[node]
    ax, ay, az = f[N_AXIS], f[N_AXIS + 1], f[N_AXIS + 2]
    if LT.node_i[node, N_DISTANT]:
        cx, cy, cz = -ax, -ay, -az
        cos_theta_u = f[N_COS_OE]
        distance = 1.0
        theta_d = 1.0 if t == np.inf else t
    else:
        ccx, ccy, ccz = f[N_CENTER], f[N_CENTER + 1], f[N_CENTER + 2]
        if volume:
            closest_t, distance, theta_d = _segment_theta_d(ccx, ccy, ccz, px, py, pz, nx, ny, nz, t)
            tc = min(max(closest_t, 0.0), t)
            vx, vy, vz = _compute_v(ccx, ccy, ccz, px, py, pz, nx, ny, nz, ax, ay, az, t)
            cx, cy, cz = -vx, -vy, -vz
            cos_theta_u = _subtended_cos(f[N_R2], ccx, ccy, ccz, px + nx * tc, py + ny * tc, pz + nz * tc)
        else:
            visible = has_transmission or (nx * (ccx - px) + ny * (ccy - py) + nz * (ccz - pz)
                                           + abs(nx) * abs(f[N_MAX] - ccx) + abs(ny) * abs(f[N_MAX + 1] - ccy)
                                           + abs(nz) * abs(f[N_MAX + 2] - ccz) > 0.0)
            if not visible:
                return 0.0, 0.0
            cx, cy, cz, distance = _normalize_len(ccx - px, ccy - py, ccz - pz)
            cos_theta_u = _subtended_cos(f[N_R2], ccx, ccy, ccz, px, py, pz)
            theta_d = 1.0
        distance = max(f[N_HALF], distance)
    return _importance(volume, has_transmission, nx, ny, nz, cx, cy, cz, cos_theta_u, ax, ay, az, f[N_THETA_O],
                       f[N_THETA_E], f[N_COS_O], f[N_SIN_O], f[N_COS_OE], f[N_COS_EO], distance, distance,
                       f[N_ENERGY], theta_d)


@stage_kernel
def _smoothstep(x):
    x = min(max(x, 0.0), 1.0)
    return x * x * (3.0 - 2.0 * x)


@stage_kernel
def emitter_importance(LT, row, px, py, pz, nx, ny, nz, t, mode):
    """(max, min) importance of one light row (tree.h light_tree_emitter_importance with the
    per-type *_light_tree_parameters of point.h, spot.h, area.h, triangle.h, sun.h, background.h)."""
    volume = mode == MODE_VOLUME
    has_transmission = mode != MODE_SURFACE
    kind = LT.e_kind[row]
    e = LT.e_f[row]
    theta_o = e[E_THETA_O]
    ax, ay, az = e[E_AXIS], e[E_AXIS + 1], e[E_AXIS + 2]
    energy = e[E_ENERGY]
    gx, gy, gz = e[E_POS], e[E_POS + 1], e[E_POS + 2]  # the sun's axis, (0, 0, 1) for the world
    is_spot = e[E_SPOT] > 0.0
    if (kind == POINT or kind == SPHERE or kind == DISK) and not is_spot:
        # a point light's disk faces the shading point (theta_o is 0 in e_f)
        ax, ay, az, _ = _normalize_len(px - gx, py - gy, pz - gz)
    theta_d = 1.0
    qx, qy, qz = px, py, pz  # P_c: the closest point of the segment in volumes
    if volume:
        closest_t, _, theta_d = _segment_theta_d(gx, gy, gz, px, py, pz, nx, ny, nz, t)
        tc = min(max(closest_t, 0.0), t)
        qx, qy, qz = px + nx * tc, py + ny * tc, pz + nz * tc
    visible = True
    max_d = min_d = 1.0
    cos_theta_u = 1.0
    cx, cy, cz = 0.0, 0.0, 1.0
    if kind == TRIANGLE:
        cx, cy, cz, min_d = _normalize_len(gx - qx, gy - qy, gz - qz)
        max_d = min_d
        cos_theta_u = 1e30
        above = False
        for i in range(3):
            k = E_CORNERS + 3 * i
            kx, ky, kz, dk = _normalize_len(e[k] - qx, e[k + 1] - qy, e[k + 2] - qz)
            cos_theta_u = min(cos_theta_u, cx * kx + cy * ky + cz * kz)
            above = above or (kx * nx + ky * ny + kz * nz > 0.0)
            if not volume:
                max_d = max(max_d, dk)
        front = theta_o != 0.0 or (ax * cx + ay * cy + az * cz) < 0.0
        visible = front and above
    elif kind == AREA_RECT or kind == AREA_ELLIPSE:
        cx, cy, cz, min_d = _normalize_len(gx - qx, gy - qy, gz - qz)
        max_d = min_d
        cos_theta_u = 1e30
        ux, uy, uz = e[E_AXIS_U], e[E_AXIS_U + 1], e[E_AXIS_U + 2]
        vx, vy, vz = e[E_AXIS_V], e[E_AXIS_V + 1], e[E_AXIS_V + 2]
        for i in range(4):
            su = (i & 1) - 0.5
            sv = 0.5 * ((i & 2) - 1)
            kx, ky, kz, dk = _normalize_len(ux * su + vx * sv + gx - qx, uy * su + vy * sv + gy - qy,
                                            uz * su + vz * sv + gz - qz)
            cos_theta_u = min(cos_theta_u, cx * kx + cy * ky + cz * kz)
            if not volume:
                max_d = max(max_d, dk)
        front = (ax * cx + ay * cy + az * cz) < 0.0
        above = (nx * (gx - qx) + ny * (gy - qy) + nz * (gz - qz) + 0.5 * abs(nx * ux + ny * uy + nz * uz)
                 + 0.5 * abs(nx * vx + ny * vy + nz * vz)) > 0.0
        visible = front and above
    elif kind == SUN:
        if volume:
            theta_d = 1.0 if t == np.inf else t
        cos_theta_u = e[E_COS_E]
        max_d, min_d = 1.0 / cos_theta_u, 1.0
        cx, cy, cz = -gx, -gy, -gz
    elif kind == WORLD:
        if volume:
            theta_d = 1.0 if t == np.inf else t
        cos_theta_u = -1.0
        cx, cy, cz = -gx, -gy, -gz
    else:  # point, sphere, soft disk; spots among them
        cx, cy, cz, min_d = _normalize_len(gx - qx, gy - qy, gz - qz)
        max_d = min_d
        r = e[E_RADIUS]
        if kind == SPHERE:
            if min_d > r:
                cos_theta_u = np.sqrt(max(1.0 - (r / min_d) ** 2, 0.0))
                if not volume:
                    max_d = min_d / cos_theta_u
            else:
                cos_theta_u = -1.0
                if not volume:
                    max_d = min_d = r / np.sqrt(2.0)
        else:
            hyp = np.sqrt(r * r + min_d * min_d)
            cos_theta_u = min_d / hyp if hyp > 0.0 else 1.0
            if not volume:
                max_d = hyp
        if volume and not is_spot:
            cos_theta_u = 1.0
        if is_spot and not volume:
            # spot.h spot_light_tree_parameters: the blend's smoothstep at the smallest angle
            # between the axis and the lamp's disk, cos(max(0, acos(a) - acos(b))) by the angle
            # difference identity (a: cosine to the axis, b: cos_theta_u)
            ca = min(max(-(ax * cx + ay * cy + az * cz), -1.0), 1.0)
            cb = min(max(cos_theta_u, -1.0), 1.0)
            cos_smallest = 1.0 if ca >= cb else ca * cb + _sin_from_cos(ca) * _sin_from_cos(cb)
            energy *= _smoothstep((cos_smallest - e[E_COS_E]) * e[E_SPOT])
    if not (visible or has_transmission):
        return 0.0, 0.0
    if volume:
        if kind == SUN:
            cx, cy, cz = -ax, -ay, -az
        else:
            vx, vy, vz = _compute_v(gx, gy, gz, px, py, pz, nx, ny, nz, ax, ay, az, t)
            cx, cy, cz = -vx, -vy, -vz
    return _importance(volume, has_transmission, nx, ny, nz, cx, cy, cz, cos_theta_u, ax, ay, az, theta_o,
                       e[E_THETA_E], e[E_COS_O], e[E_SIN_O], e[E_COS_OE], e[E_COS_EO], max_d, min_d, energy, theta_d)


@stage_kernel
def _child_importance(LT, node, px, py, pz, nx, ny, nz, t, mode):
    """tree.h light_tree_child_importance: a leaf of one emitter is weighed as that emitter."""
    c = LT.node_i[node, N_COUNT]
    if c == 1:
        return emitter_importance(LT, LT.leaf_rows[LT.node_i[node, N_FIRST]], px, py, pz, nx, ny, nz, t, mode)
    if c == 0:
        return 0.0, 0.0
    return node_importance(LT, node, px, py, pz, nx, ny, nz, t, mode)


@stage_kernel
def _left_probability(LT, node, px, py, pz, nx, ny, nz, t, mode):
    """Probability of the left child (tree.h get_left_probability); -1 when both are worthless.
    A child it gives probability > 0 has importance > 0; a child of zero importance gets exactly
    0 (and its sibling exactly 1)."""
    max_l, min_l = _child_importance(LT, LT.node_i[node, N_LEFT], px, py, pz, nx, ny, nz, t, mode)
    max_r, min_r = _child_importance(LT, LT.node_i[node, N_RIGHT], px, py, pz, nx, ny, nz, t, mode)
    total_max = max_l + max_r
    if total_max == 0.0:
        return -1.0
    total_min = min_l + min_r
    p_max = max_l / total_max
    if total_min > 0.0:
        p_min = min_l / total_min
    else:
        p_min = 0.5 * ((1.0 if max_l > 0.0 else 0.0) + (1.0 if max_r == 0.0 else 0.0))
    return 0.5 * (p_max + p_min)


@stage_kernel
def _leaf_totals(LT, node, px, py, pz, nx, ny, nz, t, mode):
    total_max = total_min = 0.0
    n_important = 0
    first = LT.node_i[node, N_FIRST]
    for i in range(LT.node_i[node, N_COUNT]):
        mx, mn = emitter_importance(LT, LT.leaf_rows[first + i], px, py, pz, nx, ny, nz, t, mode)
        total_max += mx
        total_min += mn
        if mx > 0.0:
            n_important += 1
    return total_max, total_min, n_important


@stage_kernel
def _leaf_probability(mx, mn, total_max, total_min, n_important):
    """Probability of an emitter in its leaf: the mean of picking by the upper and by the lower
    importance bound, uniform among emitters with importance when no lower bound is positive
    (tree.h light_tree_cluster_select_emitter, light_tree_pdf)."""
    if not mx > 0.0:
        return 0.0
    return 0.5 * (mx / total_max + (mn / total_min if total_min > 0.0 else 1.0 / n_important))


@stage_kernel
def _select_static(LT, u):
    """The light chosen by power (light_kernels.select_light on the tree's packed tables)."""
    return cdf_row(LT.select_cdf, LT.count, u)


# ---------------------------------------------------------------------------------------------
# Selection and its pdf
# ---------------------------------------------------------------------------------------------
@stage_kernel
def tree_select(LT, u, px, py, pz, nx, ny, nz, t, mode):
    """A light row for the shading point (p, n; mode MODE_*) or, in volumes, the segment p + s d,
    s in [0, t] (n = d): (row, probability); (-1, 0) when no light can reach it. Static selection
    by power when the tree is off. LT: LightTables.tree."""
    if LT.count == 0:
        return np.int64(-1), 0.0
    if not LT.enabled:
        row = _select_static(LT, u)
        return row, LT.select_prob[row]
    node = 0
    pdf = 1.0
    while LT.node_i[node, N_COUNT] < 0:
        pl = _left_probability(LT, node, px, py, pz, nx, ny, nz, t, mode)
        if pl < 0.0:
            return np.int64(-1), 0.0
        if u < pl:
            u = u / pl
            node = LT.node_i[node, N_LEFT]
            pdf *= pl
        else:
            u = min((u - pl) / (1.0 - pl), 1.0) if pl < 1.0 else 0.0
            node = LT.node_i[node, N_RIGHT]
            pdf *= 1.0 - pl
    first = LT.node_i[node, N_FIRST]
    if LT.node_i[node, N_COUNT] == 1:
        # reached with probability > 0, hence importance > 0 (_left_probability): picked surely
        return LT.leaf_rows[first], pdf
    total_max, total_min, n_important = _leaf_totals(LT, node, px, py, pz, nx, ny, nz, t, mode)
    if n_important == 0:
        return np.int64(-1), 0.0
    acc = 0.0
    chosen = np.int64(-1)
    chosen_p = 0.0
    for i in range(LT.node_i[node, N_COUNT]):
        row = LT.leaf_rows[first + i]
        mx, mn = emitter_importance(LT, row, px, py, pz, nx, ny, nz, t, mode)
        p = _leaf_probability(mx, mn, total_max, total_min, n_important)
        if p > 0.0:
            chosen, chosen_p = row, p
            acc += p
            if u < acc:
                break
    return chosen, pdf * chosen_p


@stage_kernel
def tree_pdf(LT, row, px, py, pz, nx, ny, nz, t, mode):
    """Probability that tree_select picks `row` from the same shading point or segment (the light
    selection part of every MIS weight; tree.h light_tree_pdf). LT: LightTables.tree."""
    if row < 0:
        return 0.0
    if not LT.enabled:
        return LT.select_prob[row]
    leaf = LT.leaf_of_row[row]
    if leaf < 0:
        return 0.0
    if LT.node_i[leaf, N_COUNT] == 1:
        pdf = 1.0  # the parent gives a leaf of one emitter without importance probability 0
    else:
        total_max, total_min, n_important = _leaf_totals(LT, leaf, px, py, pz, nx, ny, nz, t, mode)
        mx, mn = emitter_importance(LT, row, px, py, pz, nx, ny, nz, t, mode)
        pdf = _leaf_probability(mx, mn, total_max, total_min, n_important)
    node = leaf
    while pdf > 0.0 and LT.node_i[node, N_PARENT] >= 0:
        parent = LT.node_i[node, N_PARENT]
        pl = _left_probability(LT, parent, px, py, pz, nx, ny, nz, t, mode)
        if pl < 0.0:
            return 0.0
        pdf *= pl if LT.node_i[parent, N_LEFT] == node else 1.0 - pl
        node = parent
    return pdf


@stage_kernel
def tree_select_many(LT, u, p, n, t, mode, rows, pdf):
    """tree_select for arrays (tests, LightSet)."""
    for i in range(u.shape[0]):
        rows[i], pdf[i] = tree_select(LT, u[i], p[i, 0], p[i, 1], p[i, 2], n[i, 0], n[i, 1], n[i, 2], t[i], mode)


@stage_kernel
def tree_pdf_many(LT, rows, p, n, t, mode, pdf):
    for i in range(rows.shape[0]):
        pdf[i] = tree_pdf(LT, rows[i], p[i, 0], p[i, 1], p[i, 2], n[i, 0], n[i, 1], n[i, 2], t[i], mode)


@stage_kernel
def escaped_emission_mis_at(T, dx, dy, dz, prev_pdf, camera_ray, px, py, pz, nx, ny, nz, t, mode):
    """MIS-weighted radiance of every distant emitter (world, sun cones) seen along unit d by a
    ray sampled with pdf prev_pdf (0: camera ray or delta scattering, full weight) from the vertex
    whose light selection was made at (p, n, t, mode). Emitters hidden from the camera give
    nothing to camera rays (light_kernels.escaped_emission_mis with per-point selection)."""
    r, g, b = 0.0, 0.0, 0.0
    for i in range(-1, T.sun_rows.shape[0]):
        row = T.world_row if i < 0 else T.sun_rows[i]
        if row < 0 or (i >= 0 and camera_ray and not T.camera_visible[row]):
            continue
        er, eg, eb, pdf = distant_emission_unselected(T, row, dx, dy, dz)
        if i >= 0 and not pdf > 0.0:
            continue  # outside the sun's cone
        w = 1.0
        if prev_pdf > 0.0:
            w = mis_weight(prev_pdf, pdf * tree_pdf(T.tree, row, px, py, pz, nx, ny, nz, t, mode))
        r, g, b = r + er * w, g + eg * w, b + eb * w
    return r, g, b
