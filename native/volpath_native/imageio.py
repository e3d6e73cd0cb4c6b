"""Image files through OpenImageIO, imported lazily so the add-on loads without it."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def _oiio():
    try:
        import OpenImageIO
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise RuntimeError("OpenImageIO is needed to read and write image files "
                           "(pip install OpenImageIO, or run inside Blender)") from exc
    return OpenImageIO


def _write(path, pixels: np.ndarray, fmt) -> None:
    oiio = _oiio()
    h, w, c = pixels.shape
    spec = oiio.ImageSpec(w, h, c, fmt)
    if c == 4:
        spec.channelnames = ("R", "G", "B", "A")
    elif c == 3:
        spec.channelnames = ("R", "G", "B")
    out = oiio.ImageOutput.create(str(path))
    if out is None:
        raise RuntimeError(f"cannot write {path}: {oiio.geterror()}")
    try:
        if not out.open(str(path), spec) or not out.write_image(pixels):
            raise RuntimeError(f"cannot write {path}: {out.geterror()}")
    finally:
        out.close()


def write_exr(path, image: np.ndarray) -> Path:
    """Scene-linear float image (H,W,C), row 0 = top, as a 32-bit float OpenEXR file."""
    image = np.ascontiguousarray(image, dtype=np.float32)
    if image.ndim == 2:
        image = image[:, :, None]
    _write(path, image, _oiio().FLOAT)
    return Path(path)


def read_exr(path) -> np.ndarray:
    """Any image OpenImageIO reads, as (H,W,C) float32 with row 0 = top."""
    oiio = _oiio()
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise RuntimeError(f"cannot read {path}: {oiio.geterror()}")
    try:
        pixels = inp.read_image(0, 0, 0, inp.spec().nchannels, oiio.FLOAT)
    finally:
        inp.close()
    if pixels is None:
        raise RuntimeError(f"cannot read {path}")
    return np.asarray(pixels, dtype=np.float32).reshape(inp.spec().height, inp.spec().width, -1)


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB transfer function."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def write_png(path, image: np.ndarray, exposure: float = 0.0) -> Path:
    """8-bit sRGB preview (the 'Standard' view transform) of a scene-linear image."""
    image = np.asarray(image, dtype=np.float64)
    rgb = np.nan_to_num(image[:, :, :3]) * (2.0 ** exposure)
    out = srgb_encode(rgb)
    if image.shape[2] == 4:
        out = np.concatenate([out, np.clip(image[:, :, 3:4], 0, 1)], axis=2)
    _write(path, np.ascontiguousarray(np.round(out * 255.0).astype(np.uint8)), _oiio().UINT8)
    return Path(path)
