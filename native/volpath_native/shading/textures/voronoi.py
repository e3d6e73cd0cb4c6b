"""Voronoi Texture node (Cycles src/kernel/svm/voronoi.h `svm_node_tex_voronoi`), 1D-4D: F1, F2,
Smooth F1, Distance to Edge, N-Sphere Radius; Euclidean / Manhattan / Chebychev / Minkowski; the
fractal octaves (detail, roughness, lacunarity) and normalize of Blender 4.x / 5.0.

One implementation for every dimension: coordinates travel as four float32 (x, y, z, w) of which
the first `dimensions` are used (1D: its coordinate, W, is carried in x), and the cell loops run
over -1..1 (-2..2 for Smooth F1) in the used axes only, in Cycles' order (w outermost, x
innermost) so that ties pick the same cell. 1D hashes the cell's float (hash_float_to_float),
2D-4D the integer cell with PCG (hash_int*_to_float*). Cells and local positions are float32 as
in Cycles; distances and blends run in float64.
"""
from __future__ import annotations

import math

import numpy as np

from ...jit import stage_kernel
from .hash import hash_float_to_float, hash_float_to_float3, hash_int2_to_float2, hash_int3_to_float3, hash_int4_to_float4

#: Cycles svm/types.h NodeVoronoiFeature / NodeVoronoiDistanceMetric
VORONOI_F1, VORONOI_F2, VORONOI_SMOOTH_F1, VORONOI_DISTANCE_TO_EDGE, VORONOI_N_SPHERE_RADIUS = range(5)
VORONOI_FEATURES = {"F1": VORONOI_F1, "F2": VORONOI_F2, "SMOOTH_F1": VORONOI_SMOOTH_F1,
                    "DISTANCE_TO_EDGE": VORONOI_DISTANCE_TO_EDGE, "N_SPHERE_RADIUS": VORONOI_N_SPHERE_RADIUS}
VORONOI_EUCLIDEAN, VORONOI_MANHATTAN, VORONOI_CHEBYCHEV, VORONOI_MINKOWSKI = range(4)
VORONOI_METRICS = {"EUCLIDEAN": VORONOI_EUCLIDEAN, "MANHATTAN": VORONOI_MANHATTAN, "CHEBYCHEV": VORONOI_CHEBYCHEV,
                   "MINKOWSKI": VORONOI_MINKOWSKI}
FLT_MAX = float(np.finfo(np.float32).max)


@stage_kernel
def cell_point(dimensions, cell_x_f, cx, cy, cz, cw, randomness):
    """The feature point of cell (cx, cy, cz, cw) in [0, 1)^n scaled by randomness: 1D hashes the
    float32 cell position cell_x_f (voronoi.h 1D: hash_float_to_float(cellPosition + cellOffset)),
    2D-4D the int cell (hash_int{2,3,4}_to_float{2,3,4})."""
    if dimensions == 1:
        return hash_float_to_float(cell_x_f) * randomness, 0.0, 0.0, 0.0
    if dimensions == 2:
        hx, hy = hash_int2_to_float2(cx, cy)
        return hx * randomness, hy * randomness, 0.0, 0.0
    if dimensions == 3:
        hx, hy, hz = hash_int3_to_float3(cx, cy, cz)
        return hx * randomness, hy * randomness, hz * randomness, 0.0
    hx, hy, hz, hw = hash_int4_to_float4(cx, cy, cz, cw)
    return hx * randomness, hy * randomness, hz * randomness, hw * randomness


@stage_kernel
def cell_color(dimensions, cell_x_f, cx, cy, cz, cw):
    """voronoi.h colours: hash_float_to_float3 (1D), hash_int2_to_float3 = pcg3d(x, y, 0) (2D),
    hash_int3_to_float3 (3D), hash_int4_to_float3 (4D)."""
    if dimensions == 1:
        return hash_float_to_float3(cell_x_f)
    if dimensions == 2:
        return hash_int3_to_float3(cx, cy, 0)
    if dimensions == 3:
        return hash_int3_to_float3(cx, cy, cz)
    r, g, b, _ = hash_int4_to_float4(cx, cy, cz, cw)
    return r, g, b


@stage_kernel
def metric_distance(dimensions, metric, exponent, dx, dy, dz, dw):
    """voronoi.h `voronoi_distance` of a difference vector (1D: |d| whatever the metric)."""
    if dimensions == 1:
        return abs(dx)
    if metric == VORONOI_EUCLIDEAN:
        return math.sqrt(dx * dx + dy * dy + dz * dz + dw * dw)
    if metric == VORONOI_MANHATTAN:
        return abs(dx) + abs(dy) + abs(dz) + abs(dw)
    if metric == VORONOI_CHEBYCHEV:
        return max(max(abs(dx), abs(dy)), max(abs(dz), abs(dw)))
    if metric == VORONOI_MINKOWSKI:
        total = abs(dx) ** exponent + abs(dy) ** exponent
        if dimensions >= 3:
            total += abs(dz) ** exponent
        if dimensions >= 4:
            total += abs(dw) ** exponent
        return total ** (1.0 / exponent)
    return 0.0


@stage_kernel
def metric_bound(dimensions, metric, exponent, dx, dy, dz, dw):
    """voronoi.h `voronoi_distance_bound`: same order as the distance, cheaper (no root)."""
    if dimensions == 1:
        return abs(dx)
    if metric == VORONOI_EUCLIDEAN:
        return dx * dx + dy * dy + dz * dz + dw * dw
    if metric == VORONOI_MINKOWSKI:
        total = abs(dx) ** exponent + abs(dy) ** exponent
        if dimensions >= 3:
            total += abs(dz) ** exponent
        if dimensions >= 4:
            total += abs(dw) ** exponent
        return total
    return metric_distance(dimensions, metric, exponent, dx, dy, dz, dw)


@stage_kernel
def split_cell(x):
    """floor(coord) as float32 and int, and the float32 local position coord - floor."""
    f = np.float32(math.floor(x))
    return f, int(f), float(np.float32(x) - f)


@stage_kernel
def cell_range(dimensions, axis, reach):
    """The offsets -reach..reach on a used axis, 0..0 on an unused one."""
    if axis < dimensions:
        return -reach, reach + 1
    return 0, 1


@stage_kernel
def voronoi_f1_f2(dimensions, feature, metric, exponent, randomness, x, y, z, w):
    """voronoi.h `voronoi_f1` / `voronoi_f2` (feature VORONOI_F1 / VORONOI_F2) at float32 coords:
    (distance, r, g, b, px, py, pz, pw), position in the texture's scaled space."""
    fx, ix, lx = split_cell(x)
    fy, iy, ly = split_cell(y)
    fz, iz, lz = split_cell(z)
    fw, iw, lw = split_cell(w)
    d1 = FLT_MAX
    d2 = FLT_MAX
    o1x = o1y = o1z = o1w = 0
    o2x = o2y = o2z = o2w = 0
    p1x = p1y = p1z = p1w = 0.0
    p2x = p2y = p2z = p2w = 0.0
    u0, u1 = cell_range(dimensions, 3, 1)
    k0, k1 = cell_range(dimensions, 2, 1)
    j0, j1 = cell_range(dimensions, 1, 1)
    i0, i1 = cell_range(dimensions, 0, 1)
    for u in range(u0, u1):
        for k in range(k0, k1):
            for j in range(j0, j1):
                for i in range(i0, i1):
                    hx, hy, hz, hw = cell_point(dimensions, np.float32(fx + np.float32(i)), ix + i, iy + j, iz + k,
                                                iw + u, randomness)
                    px, py, pz, pw = i + hx, j + hy, k + hz, u + hw
                    if feature == VORONOI_F1:
                        # F1 2D-4D compares the bound and measures the winner at the end
                        d = metric_bound(dimensions, metric, exponent, px - lx, py - ly, pz - lz, pw - lw)
                    else:
                        d = metric_distance(dimensions, metric, exponent, px - lx, py - ly, pz - lz, pw - lw)
                    if d < d1:
                        d2, o2x, o2y, o2z, o2w, p2x, p2y, p2z, p2w = d1, o1x, o1y, o1z, o1w, p1x, p1y, p1z, p1w
                        d1, o1x, o1y, o1z, o1w, p1x, p1y, p1z, p1w = d, i, j, k, u, px, py, pz, pw
                    elif d < d2:
                        d2, o2x, o2y, o2z, o2w, p2x, p2y, p2z, p2w = d, i, j, k, u, px, py, pz, pw
    if feature == VORONOI_F1:
        distance = metric_distance(dimensions, metric, exponent, p1x - lx, p1y - ly, p1z - lz, p1w - lw)
        ox, oy, oz, ow, px, py, pz, pw = o1x, o1y, o1z, o1w, p1x, p1y, p1z, p1w
    else:
        distance = d2
        ox, oy, oz, ow, px, py, pz, pw = o2x, o2y, o2z, o2w, p2x, p2y, p2z, p2w
    r, g, b = cell_color(dimensions, np.float32(fx + np.float32(ox)), ix + ox, iy + oy, iz + oz, iw + ow)
    return distance, r, g, b, px + fx, py + fy, pz + fz, pw + fw


@stage_kernel
def smoothstep01(x):
    """util/math_base.h `smoothstep(0, 1, x)`."""
    if x < 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    return (3.0 - 2.0 * x) * (x * x)


@stage_kernel
def voronoi_smooth_f1(dimensions, metric, exponent, randomness, smoothness, x, y, z, w):
    """voronoi.h `voronoi_smooth_f1`: smooth minimum over the 5^n cells -2..2."""
    fx, ix, lx = split_cell(x)
    fy, iy, ly = split_cell(y)
    fz, iz, lz = split_cell(z)
    fw, iw, lw = split_cell(w)
    sd = 0.0
    sr = sg = sb = 0.0
    spx = spy = spz = spw = 0.0
    h = -1.0
    u0, u1 = cell_range(dimensions, 3, 2)
    k0, k1 = cell_range(dimensions, 2, 2)
    j0, j1 = cell_range(dimensions, 1, 2)
    i0, i1 = cell_range(dimensions, 0, 2)
    for u in range(u0, u1):
        for k in range(k0, k1):
            for j in range(j0, j1):
                for i in range(i0, i1):
                    cell_f = np.float32(fx + np.float32(i))
                    hx, hy, hz, hw = cell_point(dimensions, cell_f, ix + i, iy + j, iz + k, iw + u, randomness)
                    px, py, pz, pw = i + hx, j + hy, k + hz, u + hw
                    d = metric_distance(dimensions, metric, exponent, px - lx, py - ly, pz - lz, pw - lw)
                    h = 1.0 if h == -1.0 else smoothstep01(0.5 + 0.5 * (sd - d) / smoothness)
                    correction = smoothness * h * (1.0 - h)
                    sd = sd + h * (d - sd) - correction
                    correction /= 1.0 + 3.0 * smoothness
                    cr, cg, cb = cell_color(dimensions, cell_f, ix + i, iy + j, iz + k, iw + u)
                    sr = sr + h * (cr - sr) - correction
                    sg = sg + h * (cg - sg) - correction
                    sb = sb + h * (cb - sb) - correction
                    spx = spx + h * (px - spx) - correction
                    spy = spy + h * (py - spy) - correction
                    spz = spz + h * (pz - spz) - correction
                    spw = spw + h * (pw - spw) - correction
    # unused axes stay 0 in Cycles' position (voronoi_position of a lower-dimensional coord)
    if dimensions < 2:
        spy = 0.0
    if dimensions < 3:
        spz = 0.0
    if dimensions < 4:
        spw = 0.0
    return sd, sr, sg, sb, fx + spx, fy + spy, fz + spz, fw + spw


@stage_kernel
def voronoi_distance_to_edge(dimensions, randomness, x, y, z, w):
    """voronoi.h `voronoi_distance_to_edge` (1D: half-way to the neighbour points)."""
    fx, ix, lx = split_cell(x)
    if dimensions == 1:
        mid = hash_float_to_float(fx) * randomness
        left = -1.0 + hash_float_to_float(np.float32(fx - np.float32(1.0))) * randomness
        right = 1.0 + hash_float_to_float(np.float32(fx + np.float32(1.0))) * randomness
        return min(abs((mid + left) / 2.0 - lx), abs((mid + right) / 2.0 - lx))
    fy, iy, ly = split_cell(y)
    fz, iz, lz = split_cell(z)
    fw, iw, lw = split_cell(w)
    u0, u1 = cell_range(dimensions, 3, 1)
    k0, k1 = cell_range(dimensions, 2, 1)
    j0, j1 = cell_range(dimensions, 1, 1)
    best = FLT_MAX
    cx = cy = cz = cw = 0.0
    for u in range(u0, u1):
        for k in range(k0, k1):
            for j in range(j0, j1):
                for i in range(-1, 2):
                    hx, hy, hz, hw = cell_point(dimensions, fx, ix + i, iy + j, iz + k, iw + u, randomness)
                    vx, vy, vz, vw = i + hx - lx, j + hy - ly, k + hz - lz, u + hw - lw
                    d = vx * vx + vy * vy + vz * vz + vw * vw
                    if d < best:
                        best = d
                        cx, cy, cz, cw = vx, vy, vz, vw
    best = FLT_MAX
    for u in range(u0, u1):
        for k in range(k0, k1):
            for j in range(j0, j1):
                for i in range(-1, 2):
                    hx, hy, hz, hw = cell_point(dimensions, fx, ix + i, iy + j, iz + k, iw + u, randomness)
                    vx, vy, vz, vw = i + hx - lx, j + hy - ly, k + hz - lz, u + hw - lw
                    ex, ey, ez, ew = vx - cx, vy - cy, vz - cz, vw - cw
                    e2 = ex * ex + ey * ey + ez * ez + ew * ew
                    if e2 > 0.0001:
                        inv = 1.0 / math.sqrt(e2)
                        d = ((cx + vx) * ex + (cy + vy) * ey + (cz + vz) * ez + (cw + vw) * ew) * 0.5 * inv
                        best = min(best, d)
    return best


@stage_kernel
def voronoi_n_sphere_radius(dimensions, randomness, x, y, z, w):
    """voronoi.h `voronoi_n_sphere_radius`: half the distance from the closest point to its own
    closest point among the cells around the closest point's cell."""
    fx, ix, lx = split_cell(x)
    fy, iy, ly = split_cell(y)
    fz, iz, lz = split_cell(z)
    fw, iw, lw = split_cell(w)
    u0, u1 = cell_range(dimensions, 3, 1)
    k0, k1 = cell_range(dimensions, 2, 1)
    j0, j1 = cell_range(dimensions, 1, 1)
    best = FLT_MAX
    ox = oy = oz = ow = 0
    cx = cy = cz = cw = 0.0
    for u in range(u0, u1):
        for k in range(k0, k1):
            for j in range(j0, j1):
                for i in range(-1, 2):
                    hx, hy, hz, hw = cell_point(dimensions, np.float32(fx + np.float32(i)), ix + i, iy + j, iz + k,
                                                iw + u, randomness)
                    px, py, pz, pw = i + hx, j + hy, k + hz, u + hw
                    d = (px - lx) ** 2 + (py - ly) ** 2 + (pz - lz) ** 2 + (pw - lw) ** 2
                    if d < best:
                        best = d
                        ox, oy, oz, ow = i, j, k, u
                        cx, cy, cz, cw = px, py, pz, pw
    best = FLT_MAX
    nx = ny = nz = nw = 0.0
    for u in range(u0, u1):
        for k in range(k0, k1):
            for j in range(j0, j1):
                for i in range(-1, 2):
                    if i == 0 and j == 0 and k == 0 and u == 0:
                        continue
                    a, b, c, e = i + ox, j + oy, k + oz, u + ow
                    hx, hy, hz, hw = cell_point(dimensions, np.float32(fx + np.float32(a)), ix + a, iy + b, iz + c,
                                                iw + e, randomness)
                    px, py, pz, pw = a + hx, b + hy, c + hz, e + hw
                    d = (cx - px) ** 2 + (cy - py) ** 2 + (cz - pz) ** 2 + (cw - pw) ** 2
                    if d < best:
                        best = d
                        nx, ny, nz, nw = px, py, pz, pw
    return math.sqrt((nx - cx) ** 2 + (ny - cy) ** 2 + (nz - cz) ** 2 + (nw - cw) ** 2) / 2.0


@stage_kernel
def fractal_voronoi_x_fx(dimensions, feature, metric, exponent, randomness, smoothness, detail, roughness,
                         lacunarity, normalize, max_distance, scale, x, y, z, w):
    """voronoi.h `fractal_voronoi_x_fx` (F1, F2, Smooth F1 with octaves): (distance, r, g, b, px,
    py, pz, pw), the position divided back by the node's scale."""
    amplitude = 1.0
    max_amplitude = 0.0
    octave_scale = np.float32(1.0)
    distance = 0.0
    r = g = b = 0.0
    px = py = pz = pw = 0.0
    zero_input = detail == 0.0 or roughness == 0.0
    n = int(math.ceil(detail))
    for i in range(n + 1):
        ox, oy, oz, ow = x * octave_scale, y * octave_scale, z * octave_scale, w * octave_scale
        if feature == VORONOI_SMOOTH_F1 and smoothness != 0.0:
            od, o_r, o_g, o_b, opx, opy, opz, opw = voronoi_smooth_f1(dimensions, metric, exponent, randomness,
                                                                    smoothness, ox, oy, oz, ow)
        else:
            f = VORONOI_F2 if feature == VORONOI_F2 else VORONOI_F1
            od, o_r, o_g, o_b, opx, opy, opz, opw = voronoi_f1_f2(dimensions, f, metric, exponent, randomness,
                                                                ox, oy, oz, ow)
        if zero_input:
            max_amplitude = 1.0
            distance, r, g, b, px, py, pz, pw = od, o_r, o_g, o_b, opx, opy, opz, opw
            break
        s = float(octave_scale)
        if i <= detail:
            max_amplitude += amplitude
            distance += od * amplitude
            r += o_r * amplitude
            g += o_g * amplitude
            b += o_b * amplitude
            px += amplitude * (opx / s - px)
            py += amplitude * (opy / s - py)
            pz += amplitude * (opz / s - pz)
            pw += amplitude * (opw / s - pw)
            octave_scale = octave_scale * np.float32(lacunarity)
            amplitude *= roughness
        else:
            remainder = detail - math.floor(detail)
            if remainder != 0.0:
                max_amplitude += remainder * amplitude
                distance += remainder * od * amplitude
                r += remainder * o_r * amplitude
                g += remainder * o_g * amplitude
                b += remainder * o_b * amplitude
                px += remainder * amplitude * (opx / s - px)
                py += remainder * amplitude * (opy / s - py)
                pz += remainder * amplitude * (opz / s - pz)
                pw += remainder * amplitude * (opw / s - pw)
    if normalize:
        distance /= max_amplitude * max_distance
        r /= max_amplitude
        g /= max_amplitude
        b /= max_amplitude
    if scale != 0.0:  # safe_divide
        px, py, pz, pw = px / scale, py / scale, pz / scale, pw / scale
    else:
        px = py = pz = pw = 0.0
    return distance, r, g, b, px, py, pz, pw


@stage_kernel
def fractal_voronoi_distance_to_edge(dimensions, randomness, detail, roughness, lacunarity, normalize, max_distance,
                                     x, y, z, w):
    """voronoi.h `fractal_voronoi_distance_to_edge`."""
    amplitude = 1.0
    max_amplitude = max_distance
    octave_scale = np.float32(1.0)
    distance = 8.0
    zero_input = detail == 0.0 or roughness == 0.0
    n = int(math.ceil(detail))
    for i in range(n + 1):
        od = voronoi_distance_to_edge(dimensions, randomness, x * octave_scale, y * octave_scale, z * octave_scale,
                                      w * octave_scale)
        if zero_input:
            distance = od
            break
        s = float(octave_scale)
        if i <= detail:
            max_amplitude += amplitude * (max_distance / s - max_amplitude)
            distance += amplitude * (min(distance, od / s) - distance)
            octave_scale = octave_scale * np.float32(lacunarity)
            amplitude *= roughness
        else:
            remainder = detail - math.floor(detail)
            if remainder != 0.0:
                lerp_amplitude = max_amplitude + amplitude * (max_distance / s - max_amplitude)
                max_amplitude += remainder * (lerp_amplitude - max_amplitude)
                lerp_distance = distance + amplitude * (min(distance, od / s) - distance)
                distance += remainder * (min(distance, lerp_distance) - distance)
    if normalize:
        distance /= max_amplitude
    return distance


@stage_kernel
def voronoi_texture(dimensions, feature, metric, normalize, vx, vy, vz, vw, scale, detail, roughness, lacunarity,
                    smoothness, exponent, randomness):
    """voronoi.h `svm_node_tex_voronoi`: (distance, r, g, b, px, py, pz, w, radius) for the node's
    Distance, Color, Position, W and Radius outputs (those the feature does not write are 0)."""
    scale32 = np.float32(scale)
    detail_ = min(max(float(np.float32(detail)), 0.0), 15.0)
    roughness_ = min(max(float(np.float32(roughness)), 0.0), 1.0)
    randomness_ = min(max(float(np.float32(randomness)), 0.0), 1.0)
    smoothness_ = min(max(float(np.float32(smoothness)) / 2.0, 0.0), 0.5)
    exponent_ = float(np.float32(exponent))
    zero = np.float32(0.0)
    if dimensions == 1:
        x, y, z, w = np.float32(vw) * scale32, zero, zero, zero
    else:
        x, y, z, w = np.float32(vx) * scale32, np.float32(vy) * scale32, np.float32(vz) * scale32, np.float32(vw) * scale32
        if dimensions == 2:
            z, w = zero, zero
        elif dimensions == 3:
            w = zero
    half = 0.5 + 0.5 * randomness_
    if feature == VORONOI_DISTANCE_TO_EDGE:
        d = fractal_voronoi_distance_to_edge(dimensions, randomness_, detail_, roughness_, lacunarity, normalize, half,
                                             x, y, z, w)
        return d, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if feature == VORONOI_N_SPHERE_RADIUS:
        radius = voronoi_n_sphere_radius(dimensions, randomness_, x, y, z, w)
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, radius
    # max_distance: the metric's length of (half, ..., half), doubled for F2 (1D: half)
    if dimensions == 1:
        max_distance = half
    else:
        max_distance = metric_distance(dimensions, metric, exponent_, half, half, half if dimensions >= 3 else 0.0,
                                       half if dimensions >= 4 else 0.0)
    if feature == VORONOI_F2:
        max_distance *= 2.0
    d, r, g, b, px, py, pz, pw = fractal_voronoi_x_fx(dimensions, feature, metric, exponent_, randomness_, smoothness_,
                                                      detail_, roughness_, lacunarity, normalize, max_distance,
                                                      float(scale32), x, y, z, w)
    if dimensions == 1:  # voronoi_position(float) = (0, 0, 0, coord): W output
        return d, r, g, b, 0.0, 0.0, 0.0, px, 0.0
    return d, r, g, b, px, py, pz, pw, 0.0
