"""Opcodes 60-99: the nodes that only mean something at a surface hit -- image textures, normal maps,
object-space normals -- run by the one interpreter (interpreter.run_program dispatches here).
C5 = blender/cycles v5.0.0, src/kernel/svm/.
"""
from __future__ import annotations

import math

from ..jit import stage_kernel
from .images import image_texture
from .program import OP_IMAGE_TEXTURE, OP_NORMAL_MAP, OP_OBJECT_NORMAL, R_BACKFACING

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
    elif op == OP_OBJECT_NORMAL:  # Texture Coordinate > Normal (NODE_TEXCO_NORMAL)
        i = code[a]
        ox, oy, oz = _object_normal(frame, regs[i], regs[i + 1], regs[i + 2])
        o = code[a + 1]
        regs[o], regs[o + 1], regs[o + 2] = ox, oy, oz
