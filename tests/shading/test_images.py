"""Image lookups against hand-computed texels: every interpolation and extension at borders and
seams, Cycles' frac quirk at negative integers, sRGB bytes interpolated encoded then linearised,
alpha un-association, 1-channel images, UDIM tiles and the missing-image magenta
(Cycles 5.0 src/kernel/device/cpu/image.h, src/kernel/svm/image.h)."""
import math

import numpy as np
import pytest

from volpath_native.shading import program as P
from volpath_native.shading.builder import ProgramBuilder
from volpath_native.shading.images import (EXT_CLIP, EXT_EXTEND, EXT_MIRROR, EXT_REPEAT, INTERP_CLOSEST,
                                           INTERP_CUBIC, INTERP_LINEAR, Image, image_lookup, image_table,
                                           image_texture)
from volpath_native.shading.interpreter import run_program_many

W, H = 4, 2


def _grid():
    """4 x 2 RGBA float image: texel (x, y) holds (x + 10 y, 100 + x + 10 y, 200 + ..., 0.5)."""
    pixels = np.zeros((H, W, 4), np.float32)
    for y in range(H):
        for x in range(W):
            pixels[y, x] = (x + 10 * y, 100 + x + 10 * y, 200 + x + 10 * y, 0.5)
    return pixels


@pytest.fixture(scope="module")
def table():
    byte = np.zeros((1, 2, 4), np.uint8)
    byte[0, 0] = (0, 0, 0, 255)
    byte[0, 1] = (255, 255, 255, 255)
    grey = np.array([[[0.25], [0.75]]], np.float32)  # 1 channel, 2 x 1
    return image_table([Image("grid", _grid()), Image("srgb", byte, compress_as_srgb=True),
                        Image("grey", grey), Image("raw", byte)])


def t(x, y):  # red channel of the grid texel
    return x + 10.0 * y


def red(table, u, v, interpolation, extension):
    return image_lookup(table, 0, u, v, interpolation, extension)[0]


# (u, v) points at texel centres, edges and outside, and the red value expected by hand
CLOSEST = [
    ((0.3, 0.6), EXT_REPEAT, t(1, 1)),
    ((0.0, 0.0), EXT_REPEAT, t(0, 0)),
    ((0.999, 0.999), EXT_REPEAT, t(3, 1)),
    ((1.1, -0.2), EXT_REPEAT, t(0, 1)),        # x 4.4 -> 4 -> 0; y -0.4 -> -1 -> 1
    ((-0.25, 0.25), EXT_REPEAT, t(2, 0)),      # x = -1.0 exactly: Cycles' frac gives -2 -> 2
    ((-0.25, 0.25), EXT_EXTEND, t(0, 0)),
    ((1.5, 2.0), EXT_EXTEND, t(3, 1)),
    ((1.1, 0.25), EXT_CLIP, 0.0),
    ((0.9, 0.25), EXT_CLIP, t(3, 0)),
    ((1.1, 0.25), EXT_MIRROR, t(3, 0)),        # x 4 -> mirror(4) = 3
    ((-0.1, 0.25), EXT_MIRROR, t(0, 0)),       # x -1 -> mirror(-1) = 0
    ((1.6, 0.25), EXT_MIRROR, t(1, 0)),        # x 6 -> 2 * 4 - 6 - 1 = 1
]


@pytest.mark.parametrize("uv,extension,expected", CLOSEST)
def test_closest(table, uv, extension, expected):
    assert red(table, *uv, INTERP_CLOSEST, extension) == pytest.approx(expected, abs=1e-12)


LINEAR = [
    # texel centre (x + 0.5) / W: exactly that texel, any extension
    ((1.5 / W, 0.5 / H), EXT_REPEAT, t(1, 0)),
    ((1.5 / W, 0.5 / H), EXT_CLIP, t(1, 0)),
    # halfway between texels 1 and 2 of row 1
    ((2.0 / W, 1.5 / H), EXT_REPEAT, 0.5 * (t(1, 1) + t(2, 1))),
    # the seam u = 0: between the last and first column (repeat) / clamped (extend) / half zero (clip)
    ((0.0, 0.5 / H), EXT_REPEAT, 0.5 * (t(3, 0) + t(0, 0))),
    ((0.0, 0.5 / H), EXT_EXTEND, t(0, 0)),
    ((0.0, 0.5 / H), EXT_CLIP, 0.5 * t(0, 0)),
    ((0.0, 0.5 / H), EXT_MIRROR, t(0, 0)),
    # the corner (0, 0): four texels
    ((0.0, 0.0), EXT_REPEAT, 0.25 * (t(3, 1) + t(0, 1) + t(3, 0) + t(0, 0))),
    ((0.0, 0.0), EXT_CLIP, 0.25 * t(0, 0)),
    # a quarter past texel 0 along x in row 0: 0.75 t0 + 0.25 t1
    ((0.75 / W, 0.5 / H), EXT_EXTEND, 0.75 * t(0, 0) + 0.25 * t(1, 0)),
    # far outside: clip is 0 beyond one texel, extend the border
    ((1.3, 0.5 / H), EXT_CLIP, 0.0),
    ((1.3, 0.5 / H), EXT_EXTEND, t(3, 0)),
    ((1.0 + 1.5 / W, 0.5 / H), EXT_REPEAT, t(1, 0)),
    # mirror past the right border: x 4.5 -> between mirror(4) = 3 and mirror(5) = 2 at 0.0 ... (4.0, 5.0)
    ((4.75 / W, 0.5 / H), EXT_MIRROR, 0.75 * t(3, 0) + 0.25 * t(2, 0)),
]


@pytest.mark.parametrize("uv,extension,expected", LINEAR)
def test_linear(table, uv, extension, expected):
    assert red(table, *uv, INTERP_LINEAR, extension) == pytest.approx(expected, abs=1e-9)


def _bspline(s):
    return np.array([(1 - s) ** 3 / 6, (3 * s ** 3 - 6 * s ** 2 + 4) / 6, (-3 * s ** 3 + 3 * s ** 2 + 3 * s + 1) / 6,
                     s ** 3 / 6])


def test_cubic_at_texel_centre_is_the_bspline_blur(table):
    # at a centre the B-spline weights are (1/6, 2/3, 1/6, 0) on texels -1, 0, +1, +2
    u, v = 1.5 / W, 0.5 / H
    row = lambda y: (t(0, y) + 4 * t(1, y) + t(2, y)) / 6  # noqa: E731
    expected = (row(1) + 4 * row(0) + row(1)) / 6  # rows -1 -> 1 (repeat) and +1 -> 1
    assert red(table, u, v, INTERP_CUBIC, EXT_REPEAT) == pytest.approx(expected, abs=1e-9)
    # clip: the rows/columns outside read 0
    expected_clip = (4 * row(0) + row(1)) / 6
    assert red(table, u, v, INTERP_CUBIC, EXT_CLIP) == pytest.approx(expected_clip, abs=1e-9)
    # weights sum to one
    for s in (0.0, 0.3, 0.99):
        assert _bspline(s).sum() == pytest.approx(1.0)


def test_cubic_between_texels_extend(table):
    u, v = 1.8 / W, 0.5 / H  # x = 1.3 -> ix 1, tx 0.3; y at row 0 centre (rows clamp)
    wx = _bspline(0.3)
    wy = _bspline(0.0)
    rows = [0, 0, 1, 1]  # iy - 1 .. iy + 2 clamped to [0, 1]
    cols = [0, 1, 2, 3]
    expected = sum(wy[j] * sum(wx[i] * t(cols[i], rows[j]) for i in range(4)) for j in range(4))
    assert red(table, u, v, INTERP_CUBIC, EXT_EXTEND) == pytest.approx(expected, abs=1e-9)


def test_all_channels_and_grey(table):
    r, g, b, a = image_lookup(table, 0, 1.5 / W, 1.5 / H, INTERP_LINEAR, EXT_REPEAT)
    assert (r, g, b, a) == pytest.approx((11.0, 111.0, 211.0, 0.5))
    # 1 channel: (v, v, v, 1), linear between 0.25 and 0.75
    assert image_lookup(table, 2, 0.5, 0.5, INTERP_LINEAR, EXT_EXTEND) == pytest.approx((0.5, 0.5, 0.5, 1.0))


def test_srgb_bytes_interpolated_encoded_then_linearised(table):
    # halfway between byte 0 and byte 255: encoded 0.5, linearised after interpolation
    r, g, b, a = image_texture(table, 1, 0.5, 0.5, INTERP_LINEAR, EXT_EXTEND, False)
    srgb_half = ((0.5 + 0.055) / 1.055) ** 2.4
    assert r == pytest.approx(srgb_half, abs=1e-9) and a == 1.0
    assert abs(r - 0.5) > 0.2  # linearising first would give 0.5
    # the same bytes as Non-Color: raw
    assert image_texture(table, 3, 0.5, 0.5, INTERP_LINEAR, EXT_EXTEND, False)[0] == pytest.approx(0.5)
    # byte values are k / 255
    assert image_texture(table, 3, 0.75, 0.5, INTERP_CLOSEST, EXT_EXTEND, False)[0] == 1.0
    assert image_texture(table, 1, 0.1, 0.5, INTERP_CLOSEST, EXT_EXTEND, False)[0] == 0.0


def test_alpha_unassociated_only_when_asked(table):
    r, _, _, a = image_texture(table, 0, 1.5 / W, 0.5 / H, INTERP_CLOSEST, EXT_REPEAT, False)
    assert (r, a) == (1.0, 0.5)  # premultiplied as stored
    r, _, _, a = image_texture(table, 0, 1.5 / W, 0.5 / H, INTERP_CLOSEST, EXT_REPEAT, True)
    assert (r, a) == (2.0, 0.5)


def test_missing_image_is_magenta(table):
    assert image_texture(table, -1, 0.5, 0.5, INTERP_LINEAR, EXT_REPEAT, False) == (1.0, 0.0, 1.0, 1.0)
    assert image_lookup(table, 17, 0.5, 0.5, INTERP_LINEAR, EXT_REPEAT) == (1.0, 0.0, 1.0, 1.0)


def test_non_finite_and_huge_coordinates_are_finite(table):
    for u in (math.nan, math.inf, -math.inf, 1e30, -1e30):
        for interpolation in (INTERP_LINEAR, INTERP_CLOSEST, INTERP_CUBIC):
            for extension in (EXT_REPEAT, EXT_EXTEND, EXT_CLIP, EXT_MIRROR):
                assert all(math.isfinite(c) for c in image_lookup(table, 0, u, 0.3, interpolation, extension))


def _image_program(image, tiles=(), unassociate=0, projection=0):
    b = ProgramBuilder("image")
    vector = b.alloc(3)
    b.emit("COPY", 3, P.R_P, vector)
    offset = b.table([v for pair in tiles for v in pair]) if tiles else 0
    color, alpha = b.alloc(3), b.alloc()
    b.emit("IMAGE_TEXTURE", image, offset, len(tiles), INTERP_CLOSEST, EXT_REPEAT, projection, unassociate,
           vector, color, alpha)
    return b.build(), color, alpha


def _run(program, first, count, points, table):
    out = np.zeros((len(points), count))
    run_program_many(program.code, program.init, program.tables, np.zeros(program.n_registers),
                     np.zeros((2, 3, 4)), np.zeros((1, 1, 1, 1), np.float32), np.zeros((3, 4)),
                     np.ascontiguousarray(points, dtype=np.float64), out, first, count, table)
    return out


def test_opcode_through_the_interpreter_and_udim(table):
    program, color, alpha = _image_program(0, unassociate=1)
    out = _run(program, color, 4, [[1.5 / W, 0.5 / H, 0.0]], table)
    assert out[0] == pytest.approx([2.0, 202.0, 402.0, 0.5])  # (1, 101, 201) / 0.5, then alpha
    # UDIM: tile 1001 -> grey image (2), tile 1002 -> raw bytes (3); tile 1011 absent -> magenta
    program, color, _ = _image_program(-1, tiles=[(1001, 2), (1002, 3)])
    out = _run(program, color, 3, [[0.2, 0.5, 0], [1.8, 0.5, 0], [0.5, 1.5, 0]], table)
    assert out[0] == pytest.approx([0.25] * 3)
    assert out[1] == pytest.approx([1.0] * 3)
    assert out[2] == pytest.approx([1.0, 0.0, 1.0])
