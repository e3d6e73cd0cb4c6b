"""Opcodes 60-99: the nodes that only mean something at a surface hit -- image textures, normal maps,
object-space normals -- run by the one interpreter (interpreter.run_program dispatches here).
C5 = blender/cycles v5.0.0, src/kernel/svm/.
"""
from __future__ import annotations

import math

from ..jit import stage_kernel
from .images import image_texture
from .program import (OP_BUMP, OP_DISPLACEMENT, OP_IMAGE_BOX, OP_IMAGE_TEXTURE, OP_NORMAL_MAP, OP_OBJECT_NORMAL,
                      OP_SWAP, OP_TANGENT, OP_VECTOR_DISPLACEMENT, R_BACKFACING, TANGENT_UV)

_PI = math.pi


@stage_kernel
def _map_to_tube(x, y, z):
    """map_to_tube (C5 util/math_float3.h) of a point remapped from [0, 1] to [-1, 1]."""
    length = math.sqrt(x * x + y * y)
    if length > 0.0:
        return (1.0 - math.atan2(x / length, y / length) / _PI) * 0.5, (z + 1.0) * 0.5
    return 0.0, 0.0


@stage_kernel
def _map_to_sphere(x, y, z):
    """map_to_sphere (C5 util/math_float3.h)."""
    sq = x * x + y * y + z * z
    if sq > 0.0:
        u = 0.0 if (x == 0.0 and y == 0.0) else 0.5 - math.atan2(x, y) * (0.5 / _PI)
        c = min(max(z / math.sqrt(sq), -1.0), 1.0)
        return u, 1.0 - math.acos(c) / _PI
    return 0.0, 0.0


@stage_kernel
def _udim_image(tables, tiles, count, u, v):
    """svm_node_tex_image's tile search: (image index, u, v relative to the tile); -1 outside the
    set's tiles (magenta, as Cycles' id -1)."""
    tx, ty = int(u), int(v)  # C's (int) truncation, as Cycles
    if tx >= 0 and ty >= 0 and tx < 10:
        tile = 1001 + 10 * ty + tx
        for k in range(count):
            if int(tables[tiles + 2 * k]) == tile:
                return int(tables[tiles + 2 * k + 1]), u - tx, v - ty
    return -1, u, v


@stage_kernel
def _object_normal(frame, nx, ny, nz):
    """object_inverse_normal_transform (C5 kernel/geom/object.h): safe_normalize((object ->
    world)^T n). frame[0] is world -> object, so (object -> world)^T is its inverse's transpose."""
    m = frame[0]
    a00, a01, a02 = m[0, 0], m[0, 1], m[0, 2]
    a10, a11, a12 = m[1, 0], m[1, 1], m[1, 2]
    a20, a21, a22 = m[2, 0], m[2, 1], m[2, 2]
    det = a00 * (a11 * a22 - a12 * a21) - a01 * (a10 * a22 - a12 * a20) + a02 * (a10 * a21 - a11 * a20)
    # adjugate = det x inverse; (inverse^T n)_r = sum_c inverse[c, r] n_c
    ox = (a11 * a22 - a12 * a21) * nx - (a10 * a22 - a12 * a20) * ny + (a10 * a21 - a11 * a20) * nz
    oy = -(a01 * a22 - a02 * a21) * nx + (a00 * a22 - a02 * a20) * ny - (a00 * a21 - a01 * a20) * nz
    oz = (a01 * a12 - a02 * a11) * nx - (a00 * a12 - a02 * a10) * ny + (a00 * a11 - a01 * a10) * nz
    if det < 0.0:
        ox, oy, oz = -ox, -oy, -oz
    return _safe_normalize(ox, oy, oz)


@stage_kernel
def _object_direction(frame, dx, dy, dz):
    """object_dir_transform (C5 kernel/geom/object.h): (object -> world) d, the inverse of the 3x3
    part of frame[0] (world -> object) applied through its adjugate; 0 for a singular frame."""
    m = frame[0]
    a00, a01, a02 = m[0, 0], m[0, 1], m[0, 2]
    a10, a11, a12 = m[1, 0], m[1, 1], m[1, 2]
    a20, a21, a22 = m[2, 0], m[2, 1], m[2, 2]
    c00, c01, c02 = a11 * a22 - a12 * a21, -(a10 * a22 - a12 * a20), a10 * a21 - a11 * a20
    c10, c11, c12 = -(a01 * a22 - a02 * a21), a00 * a22 - a02 * a20, -(a00 * a21 - a01 * a20)
    c20, c21, c22 = a01 * a12 - a02 * a11, -(a00 * a12 - a02 * a10), a00 * a11 - a01 * a10
    det = a00 * c00 + a01 * c01 + a02 * c02
    if det == 0.0:
        return 0.0, 0.0, 0.0
    return ((c00 * dx + c10 * dy + c20 * dz) / det, (c01 * dx + c11 * dy + c21 * dz) / det,
            (c02 * dx + c12 * dy + c22 * dz) / det)


@stage_kernel
def _world_normal(frame, nx, ny, nz):
    """object_normal_transform: normalize((world -> object)^T n)."""
    m = frame[0]
    return _safe_normalize(m[0, 0] * nx + m[1, 0] * ny + m[2, 0] * nz, m[0, 1] * nx + m[1, 1] * ny + m[2, 1] * nz,
                           m[0, 2] * nx + m[1, 2] * ny + m[2, 2] * nz)


@stage_kernel
def _safe_normalize(x, y, z):
    length = math.sqrt(x * x + y * y + z * z)
    if length > 0.0:
        return x / length, y / length, z / length
    return x, y, z


@stage_kernel
def _normal_map(regs, frame, space, strength, c, t, sign, n):
    """svm_node_normal_map (C5 svm/tex_coord.h). Tangent space works in object space as Cycles
    does (triangle_smooth_normal_unnormalized brings applied-transform normals back to object
    space): the MikkTSpace tangent is object-space, the shading normal is taken back to object
    space, the result goes to the world with object_normal_transform. The tangent-space
    fallbacks (no tangent: the unperturbed normal) are Cycles'."""
    cx, cy, cz = 2.0 * (regs[c] - 0.5), 2.0 * (regs[c + 1] - 0.5), 2.0 * (regs[c + 2] - 0.5)
    back = regs[R_BACKFACING] != 0.0
    s = -1.0 if back else 1.0
    sx, sy, sz = regs[n], regs[n + 1], regs[n + 2]  # sd->N, on the viewer's side
    if space == 0:
        tx, ty, tz = regs[t], regs[t + 1], regs[t + 2]
        if tx == 0.0 and ty == 0.0 and tz == 0.0:
            return sx, sy, sz
        # the normal before its flip toward the viewer, in object space
        nx, ny, nz = _object_normal(frame, sx * s, sy * s, sz * s)
        cx *= strength
        cy *= strength
        k = min(max(strength, 0.0), 1.0)
        cz = (1.0 - k) + k * cz
        sg = regs[sign]
        bx = sg * (ny * tz - nz * ty)
        by = sg * (nz * tx - nx * tz)
        bz = sg * (nx * ty - ny * tx)
        ox, oy, oz = _safe_normalize(cx * tx + cy * bx + cz * nx, cx * ty + cy * by + cz * ny,
                                     cx * tz + cy * bz + cz * nz)
        ox, oy, oz = _world_normal(frame, ox, oy, oz)
        if back:
            ox, oy, oz = -ox, -oy, -oz
    else:
        if space == 3 or space == 4:  # "strange blender convention"
            cy, cz = -cy, -cz
        if space == 1 or space == 3:
            ox, oy, oz = _world_normal(frame, cx, cy, cz)
        else:
            ox, oy, oz = _safe_normalize(cx, cy, cz)
        if back:
            ox, oy, oz = -ox, -oy, -oz
        if strength != 1.0:  # N = safe_normalize(sd->N + (N - sd->N) max(strength, 0))
            k = max(strength, 0.0)
            ox, oy, oz = _safe_normalize(sx + (ox - sx) * k, sy + (oy - sy) * k, sz + (oz - sz) * k)
    if (ox == 0.0 and oy == 0.0 and oz == 0.0) or not (math.isfinite(ox) and math.isfinite(oy)
                                                      and math.isfinite(oz)):
        return sx, sy, sz
    return ox, oy, oz


@stage_kernel
def _tangent(regs, frame, kind, v, n):
    """svm_node_tangent (C5 svm/tex_coord.h): a radial tangent around an axis through the centre
    of the Generated texture space, or the UV map's tangent; object_normal_transform to the
    world, then cross(N, normalize(cross(T, N))). A missing UV tangent stays 0 (Cycles stores
    zero), as does a degenerate one (Cycles' normalize would give NaN there)."""
    x, y, z = regs[v], regs[v + 1], regs[v + 2]
    if kind == TANGENT_UV:
        tx, ty, tz = x, y, z
    elif kind == 0:
        tx, ty, tz = 0.0, -(z - 0.5), y - 0.5
    elif kind == 1:
        tx, ty, tz = -(z - 0.5), 0.0, x - 0.5
    else:
        tx, ty, tz = -(y - 0.5), x - 0.5, 0.0
    if tx == 0.0 and ty == 0.0 and tz == 0.0:
        return 0.0, 0.0, 0.0
    tx, ty, tz = _world_normal(frame, tx, ty, tz)
    nx, ny, nz = regs[n], regs[n + 1], regs[n + 2]
    cx, cy, cz = _safe_normalize(ty * nz - tz * ny, tz * nx - tx * nz, tx * ny - ty * nx)
    return ny * cz - nz * cy, nz * cx - nx * cz, nx * cy - ny * cx


@stage_kernel
def _bump(regs, invert, n, distance, strength, filter_width, hc, hx, hy, ex, ey):
    """svm_node_set_bump (C5 svm/displace.h) with the heights sampled at the hit moved by ex, ey
    (Cycles: by filter_width x dPdx, dPdy). Cycles' filter_width |det(dPdx, dPdy)| N becomes
    |det(ex, ey)| N once both are written in the moved offsets (the common 1 / filter_width
    drops out of the normalisation); a zero filter width samples the centre thrice: no bump."""
    nx, ny, nz = regs[n], regs[n + 1], regs[n + 2]
    if not filter_width > 0.0:
        return nx, ny, nz
    ax, ay, az = regs[ex], regs[ex + 1], regs[ex + 2]
    bx, by, bz = regs[ey], regs[ey + 1], regs[ey + 2]
    # Rx = cross(dPdy, N), Ry = cross(N, dPdx)
    rxx, rxy, rxz = by * nz - bz * ny, bz * nx - bx * nz, bx * ny - by * nx
    ryx, ryy, ryz = ny * az - nz * ay, nz * ax - nx * az, nx * ay - ny * ax
    det = ax * rxx + ay * rxy + az * rxz
    dhx, dhy = regs[hx] - regs[hc], regs[hy] - regs[hc]
    scale = -distance if invert else distance
    s = -scale if det < 0.0 else scale
    ad = abs(det)
    ox, oy, oz = _safe_normalize(ad * nx - s * (dhx * rxx + dhy * ryx), ad * ny - s * (dhx * rxy + dhy * ryy),
                                 ad * nz - s * (dhx * rxz + dhy * ryz))
    if (ox == 0.0 and oy == 0.0 and oz == 0.0) or not (math.isfinite(ox) and math.isfinite(oy)
                                                      and math.isfinite(oz)):
        return nx, ny, nz
    k = max(strength, 0.0)
    return _safe_normalize(k * ox + (1.0 - k) * nx, k * oy + (1.0 - k) * ny, k * oz + (1.0 - k) * nz)


@stage_kernel
def _box_weights(nx, ny, nz, blend):
    """The three planes' weights of svm_node_tex_image_box for the object-space normal."""
    ax, ay, az = abs(nx), abs(ny), abs(nz)
    total = ax + ay + az
    if total > 0.0:
        ax, ay, az = ax / total, ay / total, az / total
    limit = 0.5 * (1.0 + blend)
    wx = wy = wz = 0.0
    if ax > limit * (ax + ay) and ax > limit * (ax + az):
        wx = 1.0
    elif ay > limit * (ax + ay) and ay > limit * (ay + az):
        wy = 1.0
    elif az > limit * (ax + az) and az > limit * (ay + az):
        wz = 1.0
    elif blend > 0.0:
        if az < (1.0 - limit) * (ay + ax):
            wx = min(max((ax / (ax + ay) - 0.5 * (1.0 - blend)) / blend, 0.0), 1.0)
            wy = 1.0 - wx
        elif ax < (1.0 - limit) * (ay + az):
            wy = min(max((ay / (ay + az) - 0.5 * (1.0 - blend)) / blend, 0.0), 1.0)
            wz = 1.0 - wy
        elif ay < (1.0 - limit) * (ax + az):
            wx = min(max((ax / (ax + az) - 0.5 * (1.0 - blend)) / blend, 0.0), 1.0)
            wz = 1.0 - wx
        else:
            wx = ((2.0 - limit) * ax + (limit - 1.0)) / (2.0 * limit - 1.0)
            wy = ((2.0 - limit) * ay + (limit - 1.0)) / (2.0 * limit - 1.0)
            wz = ((2.0 - limit) * az + (limit - 1.0)) / (2.0 * limit - 1.0)
    else:  # "desperate mode": one side
        wx = 1.0
    return wx, wy, wz


@stage_kernel
def _image_box(regs, images, frame, index, interpolation, extension, unassociate, blend, v, n):
    """svm_node_tex_image_box (C5 svm/image.h): planes mapped so that no texture is flipped."""
    sx, sy, sz = _object_normal(frame, regs[n], regs[n + 1], regs[n + 2])
    wx, wy, wz = _box_weights(sx, sy, sz, blend)
    x, y, z = regs[v], regs[v + 1], regs[v + 2]
    r = g = b = alpha = 0.0
    for axis in range(3):
        w = wx if axis == 0 else (wy if axis == 1 else wz)
        if not w > 0.0:
            continue
        if axis == 0:
            u, t = (1.0 - y if sx < 0.0 else y), z
        elif axis == 1:
            u, t = (1.0 - x if sy > 0.0 else x), z
        else:
            u, t = (1.0 - y if sz > 0.0 else y), x
        cr, cg, cb, ca = image_texture(images, index, u, t, interpolation, extension, unassociate)
        r += w * cr
        g += w * cg
        b += w * cb
        alpha += w * ca
    return r, g, b, alpha


@stage_kernel
def run_surface_op(op, code, a, regs, tables, images, frame):
    """Execute surface opcode `op` whose operands start at code[a]."""
    if op == OP_IMAGE_TEXTURE:
        v = code[a + 7]
        x, y, z = regs[v], regs[v + 1], regs[v + 2]
        projection = code[a + 5]
        if projection == 2:
            x, y = _map_to_sphere((x - 0.5) * 2.0, (y - 0.5) * 2.0, (z - 0.5) * 2.0)
        elif projection == 3:
            x, y = _map_to_tube((x - 0.5) * 2.0, (y - 0.5) * 2.0, (z - 0.5) * 2.0)
        index = code[a]
        if code[a + 2] > 0:
            index, x, y = _udim_image(tables, code[a + 1], code[a + 2], x, y)
        r, g, b, alpha = image_texture(images, index, x, y, code[a + 3], code[a + 4], code[a + 6] != 0)
        o = code[a + 8]
        regs[o], regs[o + 1], regs[o + 2] = r, g, b
        regs[code[a + 9]] = alpha
    elif op == OP_NORMAL_MAP:
        ox, oy, oz = _normal_map(regs, frame, code[a], regs[code[a + 1]], code[a + 2], code[a + 3], code[a + 4],
                                 code[a + 5])
        o = code[a + 6]
        regs[o], regs[o + 1], regs[o + 2] = ox, oy, oz
    elif op == OP_TANGENT:
        tx, ty, tz = _tangent(regs, frame, code[a], code[a + 1], code[a + 2])
        o = code[a + 3]
        regs[o], regs[o + 1], regs[o + 2] = tx, ty, tz
    elif op == OP_BUMP:
        ox, oy, oz = _bump(regs, code[a] != 0, code[a + 1], regs[code[a + 2]], regs[code[a + 3]], regs[code[a + 4]],
                           code[a + 5], code[a + 6], code[a + 7], code[a + 8], code[a + 9])
        o = code[a + 10]
        regs[o], regs[o + 1], regs[o + 2] = ox, oy, oz
    elif op == OP_IMAGE_BOX:
        r, g, b, alpha = _image_box(regs, images, frame, code[a], code[a + 1], code[a + 2], code[a + 3] != 0,
                                    regs[code[a + 4]], code[a + 5], code[a + 6])
        o = code[a + 7]
        regs[o], regs[o + 1], regs[o + 2] = r, g, b
        regs[code[a + 8]] = alpha
    elif op == OP_DISPLACEMENT:  # svm_node_displacement
        amount = (regs[code[a + 1]] - regs[code[a + 2]]) * regs[code[a + 3]]
        n = code[a + 4]
        nx, ny, nz = regs[n], regs[n + 1], regs[n + 2]
        if code[a] == 0:  # object space: inverse normal transform, scale, back to world
            nx, ny, nz = _object_normal(frame, nx, ny, nz)
            nx, ny, nz = _object_direction(frame, nx * amount, ny * amount, nz * amount)
        else:
            nx, ny, nz = nx * amount, ny * amount, nz * amount
        o = code[a + 5]
        regs[o], regs[o + 1], regs[o + 2] = nx, ny, nz
    elif op == OP_VECTOR_DISPLACEMENT:  # svm_node_vector_displacement (object / world space)
        v, mid, scale = code[a + 1], regs[code[a + 2]], regs[code[a + 3]]
        dx, dy, dz = (regs[v] - mid) * scale, (regs[v + 1] - mid) * scale, (regs[v + 2] - mid) * scale
        if code[a] == 0:
            dx, dy, dz = _object_direction(frame, dx, dy, dz)
        o = code[a + 4]
        regs[o], regs[o + 1], regs[o + 2] = dx, dy, dz
    elif op == OP_SWAP:
        x, y = code[a + 1], code[a + 2]
        for c in range(code[a]):
            regs[x + c], regs[y + c] = regs[y + c], regs[x + c]
    elif op == OP_OBJECT_NORMAL:  # Texture Coordinate > Normal (NODE_TEXCO_NORMAL)
        i = code[a]
        ox, oy, oz = _object_normal(frame, regs[i], regs[i + 1], regs[i + 2])
        o = code[a + 1]
        regs[o], regs[o + 1], regs[o + 2] = ox, oy, oz
