"""Image textures: the pixels of every image a scene's shader programs read, in one table, and the
lookup Cycles 5.0 does on them (C5 = blender/cycles v5.0.0).

Storage follows Cycles' image manager (src/scene/image.cpp, src/kernel/device/cpu/image.h):
- 8-bit images keep their bytes (IMAGE_DATA_TYPE_BYTE4 / BYTE). An 'sRGB' byte image stays
  sRGB-encoded: it is interpolated encoded and linearised afterwards (ImageMetaData::
  detect_colorspace sets compress_as_srgb; svm/image.h svm_image_texture applies
  color_srgb_to_linear_v4 to the interpolated value).
- Float images (and 16-bit / half files, whose values Cycles reads as value / 65535 or halfs) are
  float32 here, already scene-linear or raw (the exporter converts other colour spaces).
- 1 channel images return (v, v, v, 1); every other image is RGBA (kernel_tex_image_interp).
- RGBA is premultiplied at load by the loader (BlenderImageLoader / OIIOImageLoader: c * a / 255
  for bytes), not here: `pixels` arrive as Cycles stores them.

One copy of each image whatever the number of nodes and materials reading it: opcodes address
images by their index in Scene.images. Row 0 of `pixels` is the bottom of the image (OIIO's and
Blender's Image.pixels order, as Cycles loads it).
"""
from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from ..jit import inline_stage_kernel, stage_kernel

# Cycles' TEX_IMAGE_MISSING_R/G/B/A (kernel/svm/types.h): a missing image reads magenta
MISSING_RGBA = (1.0, 0.0, 1.0, 1.0)

INTERPOLATIONS = {"Linear": 0, "Closest": 1, "Cubic": 2, "Smart": 2}  # Smart is Cubic on the CPU
EXTENSIONS = {"REPEAT": 0, "EXTEND": 1, "CLIP": 2, "MIRROR": 3}
INTERP_LINEAR, INTERP_CLOSEST, INTERP_CUBIC = 0, 1, 2
EXT_REPEAT, EXT_EXTEND, EXT_CLIP, EXT_MIRROR = 0, 1, 2, 3

# ImageTable.info columns
I_OFFSET, I_WIDTH, I_HEIGHT, I_CHANNELS, I_IS_BYTE, I_SRGB = range(6)
N_INFO = 6

#: bytes (uint8), floats (float32): every image's texels, flat; info (n, N_INFO) int64 per image
ImageTable = namedtuple("ImageTable", ["bytes", "floats", "info"])


@dataclass
class Image:
    """One image as the renderer stores it.

    pixels: (height, width, channels) uint8 (8-bit images, bytes as Cycles keeps them) or float32;
        channels 1 or 4; row 0 is the bottom row.
    compress_as_srgb: the values are sRGB-encoded and are linearised after interpolation (8-bit
        images whose colour space is 'sRGB'; Cycles' compress_as_srgb).
    """

    name: str
    pixels: np.ndarray
    compress_as_srgb: bool = False

    def __post_init__(self):
        pixels = np.asarray(self.pixels)
        if pixels.ndim == 2:
            pixels = pixels[:, :, None]
        if pixels.ndim != 3 or pixels.shape[2] not in (1, 4) or pixels.shape[0] < 1 or pixels.shape[1] < 1:
            raise ValueError(f"image '{self.name}': pixels must be (height, width, 1 or 4), got {pixels.shape}")
        if pixels.dtype != np.uint8:
            pixels = pixels.astype(np.float32, copy=False)
        self.pixels = np.ascontiguousarray(pixels)
        self.compress_as_srgb = bool(self.compress_as_srgb)

    @property
    def is_byte(self) -> bool:
        return self.pixels.dtype == np.uint8

    @property
    def nbytes(self) -> int:
        return int(self.pixels.nbytes)


def image_table(images: list) -> ImageTable:
    """Pack images into one ImageTable (a lone image's pixels are used in place, not copied)."""
    info = np.zeros((max(len(images), 1), N_INFO), np.int64)
    byte_parts, float_parts = [], []
    byte_size = float_size = 0
    for k, image in enumerate(images):
        h, w, c = image.pixels.shape
        info[k, I_WIDTH], info[k, I_HEIGHT], info[k, I_CHANNELS] = w, h, c
        info[k, I_IS_BYTE] = int(image.is_byte)
        info[k, I_SRGB] = int(image.compress_as_srgb)
        flat = image.pixels.reshape(-1)
        if image.is_byte:
            info[k, I_OFFSET] = byte_size
            byte_parts.append(flat)
            byte_size += flat.size
        else:
            info[k, I_OFFSET] = float_size
            float_parts.append(flat)
            float_size += flat.size
    return ImageTable(_pool(byte_parts, np.uint8), _pool(float_parts, np.float32), info)


def _pool(parts, dtype):
    if not parts:
        return np.zeros(1, dtype)
    if len(parts) == 1:  # in place (a read-only array would be a different type for numba: copied)
        return parts[0] if parts[0].flags.writeable else parts[0].copy()
    return np.concatenate(parts)


def empty_image_table() -> ImageTable:
    return image_table([])


def table_nbytes(table: ImageTable) -> int:
    return int(table.bytes.nbytes + table.floats.nbytes + table.info.nbytes)


# ---------------------------------------------------------------------------------------------
# Lookups (C5 src/kernel/device/cpu/image.h TextureInterpolator)
# ---------------------------------------------------------------------------------------------
@inline_stage_kernel
def _frac(x):
    """Cycles' frac(x, &ix): ix = float_to_int(x) - (x < 0), so an exact negative integer gives
    ix = x - 1 and a fraction of 1."""
    i = int(x) - (1 if x < 0.0 else 0)
    return x - i, i


@inline_stage_kernel
def _wrap_periodic(x, width):
    x = x % width  # Python's modulo is already non-negative for width > 0
    return x


@inline_stage_kernel
def _wrap_clamp(x, width):
    return min(max(x, 0), width - 1)


@inline_stage_kernel
def _wrap_mirror(x, width):
    m = abs(x + (1 if x < 0 else 0)) % (2 * width)
    return 2 * width - m - 1 if m >= width else m


@inline_stage_kernel
def _wrap(x, width, extension):
    if extension == EXT_REPEAT:
        return _wrap_periodic(x, width)
    if extension == EXT_MIRROR:
        return _wrap_mirror(x, width)
    if extension == EXT_EXTEND:
        return _wrap_clamp(x, width)
    return x  # clip: checked by the reader


@inline_stage_kernel
def _texel(IT, index, x, y):
    """RGBA of texel (x, y) (a 1-channel image repeats its value; alpha 1); 0 outside the image
    (read_clip)."""
    info = IT.info
    w, h = info[index, I_WIDTH], info[index, I_HEIGHT]
    if x < 0 or x >= w or y < 0 or y >= h:
        return 0.0, 0.0, 0.0, 0.0
    c = info[index, I_CHANNELS]
    at = info[index, I_OFFSET] + (y * w + x) * c
    scale = 1.0 / 255.0 if info[index, I_IS_BYTE] else 1.0
    if c == 1:
        v = (IT.bytes[at] if info[index, I_IS_BYTE] else IT.floats[at]) * scale
        return v, v, v, 1.0
    if info[index, I_IS_BYTE]:
        return (IT.bytes[at] * scale, IT.bytes[at + 1] * scale, IT.bytes[at + 2] * scale,
                IT.bytes[at + 3] * scale)
    return float(IT.floats[at]), float(IT.floats[at + 1]), float(IT.floats[at + 2]), float(IT.floats[at + 3])


@inline_stage_kernel
def _add_weighted(total, weight, texel):
    return (total[0] + weight * texel[0], total[1] + weight * texel[1], total[2] + weight * texel[2],
            total[3] + weight * texel[3])


@stage_kernel
def _interp_rgba(IT, index, x, y, interpolation, extension):
    """All four channels at once: the weights and wrapped indices are computed once per lookup
    (one compiled signature instead of one per channel)."""
    info = IT.info
    w, h = info[index, I_WIDTH], info[index, I_HEIGHT]
    zero = (0.0, 0.0, 0.0, 0.0)
    if interpolation == INTERP_CLOSEST:
        _, ix = _frac(x * w)
        _, iy = _frac(y * h)
        if extension == EXT_CLIP:
            if ix < 0 or ix >= w or iy < 0 or iy >= h:
                return zero
        return _texel(IT, index, _wrap(ix, w, extension), _wrap(iy, h, extension))
    # a -0.5 offset centres the samples around the point
    tx, ix = _frac(x * w - 0.5)
    ty, iy = _frac(y * h - 0.5)
    if interpolation == INTERP_LINEAR:
        if extension == EXT_CLIP:
            if ix < -1 or ix >= w or iy < -1 or iy >= h:
                return zero
            nix, niy = ix + 1, iy + 1
        else:
            nix, niy = _wrap(ix + 1, w, extension), _wrap(iy + 1, h, extension)
            ix, iy = _wrap(ix, w, extension), _wrap(iy, h, extension)
        total = _add_weighted(zero, (1.0 - ty) * (1.0 - tx), _texel(IT, index, ix, iy))
        total = _add_weighted(total, (1.0 - ty) * tx, _texel(IT, index, nix, iy))
        total = _add_weighted(total, ty * (1.0 - tx), _texel(IT, index, ix, niy))
        return _add_weighted(total, ty * tx, _texel(IT, index, nix, niy))
    # cubic B-spline over 4 x 4 texels (interp_cubic; every extension reads through read_clip)
    if extension == EXT_CLIP and (ix < -2 or ix > w or iy < -2 or iy > h):
        return zero
    total = zero
    for j in range(4):
        yy = iy - 1 + j
        if extension != EXT_CLIP:
            yy = _wrap(yy, h, extension)
        wy = _bspline(j, ty)
        for i in range(4):
            xx = ix - 1 + i
            if extension != EXT_CLIP:
                xx = _wrap(xx, w, extension)
            total = _add_weighted(total, wy * _bspline(i, tx), _texel(IT, index, xx, yy))
    return total


@inline_stage_kernel
def _bspline(k, t):
    """SET_CUBIC_SPLINE_WEIGHTS: the uniform cubic B-spline weight of tap k (0..3) at t."""
    if k == 0:
        return (((-1.0 / 6.0) * t + 0.5) * t - 0.5) * t + (1.0 / 6.0)
    if k == 1:
        return ((0.5 * t - 1.0) * t) * t + (2.0 / 3.0)
    if k == 2:
        return ((-0.5 * t + 0.5) * t + 0.5) * t + (1.0 / 6.0)
    return (1.0 / 6.0) * t * t * t


@inline_stage_kernel
def srgb_to_linear(c):
    """color_srgb_to_linear (C5 src/util/color.h)."""
    if c < 0.04045:
        return 0.0 if c < 0.0 else c * (1.0 / 12.92)
    return math.pow((c + 0.055) * (1.0 / 1.055), 2.4)


@stage_kernel
def image_lookup(IT, index, x, y, interpolation, extension):
    """RGBA of image `index` at texture coordinate (x, y) (kernel_tex_image_interp), before the
    node's alpha and colour-space handling; index < 0: the missing-image magenta."""
    if index < 0 or index >= IT.info.shape[0] or IT.info[index, I_WIDTH] == 0:
        return MISSING_RGBA[0], MISSING_RGBA[1], MISSING_RGBA[2], MISSING_RGBA[3]
    if not (math.isfinite(x) and math.isfinite(y)):
        x = 0.0 if not math.isfinite(x) else x
        y = 0.0 if not math.isfinite(y) else y
    # keep the integer texel index in range of int64 for absurd coordinates
    x = min(max(x, -1e15), 1e15)
    y = min(max(y, -1e15), 1e15)
    r, g, b, a = _interp_rgba(IT, index, x, y, interpolation, extension)
    return r, g, b, (1.0 if IT.info[index, I_CHANNELS] == 1 else a)


@stage_kernel
def image_texture(IT, index, x, y, interpolation, extension, unassociate):
    """svm_image_texture (C5 svm/image.h): the lookup, un-premultiplied when the node's Alpha
    output is used (and alpha is neither 0 nor 1), then linearised if the image is stored sRGB."""
    r, g, b, a = image_lookup(IT, index, x, y, interpolation, extension)
    if unassociate and a != 1.0 and a != 0.0:
        r, g, b = r / a, g / a, b / a
    if index >= 0 and index < IT.info.shape[0] and IT.info[index, I_SRGB]:
        r, g, b = srgb_to_linear(r), srgb_to_linear(g), srgb_to_linear(b)
    return r, g, b, a
