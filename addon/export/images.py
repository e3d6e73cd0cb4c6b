"""Blender images -> volpath_native Image (shading/images.py), one copy each however many nodes
and materials read them, stored as Cycles 5.0 stores them (C5 = blender/cycles v5.0.0):

- Image files are read with OpenImageIO, as Cycles' OIIOImageLoader (scene/image_oiio.cpp):
  8-bit files keep their bytes, 16-bit files read as value / 65535, half and float files as floats;
  files whose alpha is unassociated get it associated at load (byte: c * a / 255).
- Packed, generated, movie and sequence images come from Blender's own buffers (Image.pixels), as
  Cycles' BlenderImageLoader reads them: byte buffers (bytes, premultiplied c * a / 255) or float
  buffers (already scene-linear and premultiplied on Blender's side).
- Colour spaces (ImageMetaData::detect_colorspace, ColorSpaceManager): 'sRGB' stays encoded and
  is linearised after interpolation; data spaces (Non-Color) and the scene-linear space are raw;
  any other space is converted to scene-linear at load by OpenColorIO with Blender's own
  configuration (datafiles/colormanagement/config.ocio), through OpenImageIO's colorconvert.
- Alpha modes: None ignores the alpha (1), Channel Packed and data spaces keep RGB unassociated.
- UDIM (tiled) images: one Image per tile, the node reads them through a tile table.
- A missing or unreadable image reads magenta (1, 0, 1), as Cycles, with a warning naming it.
Memory: the total bytes kept are counted (`nbytes`) and reported by the render.
"""
from __future__ import annotations

import os

import numpy as np

from volpath_native.shading.images import Image

_SCENE_LINEAR = ("Linear Rec.709", "scene_linear", "Linear")


class ImageRegistry:
    """Scene.images being built: index_of(image) loads an image once."""

    def __init__(self, reporter):
        self.reporter = reporter
        self.images: list = []
        self._index: dict = {}

    @property
    def nbytes(self) -> int:
        return sum(image.nbytes for image in self.images)

    def tiles_of(self, image, owner: str, frame: int | None = None) -> list:
        """[(UDIM tile number, image index)] of a tiled image; [] when not tiled."""
        if image is None or getattr(image, "source", "FILE") != "TILED":
            return []
        tiles = []
        for tile in image.tiles:
            key = (image.name_full, int(tile.number))
            if key not in self._index:
                path = _abspath(image).replace("<UDIM>", str(tile.number))
                self._index[key] = self._add(_read_file(path, image, self.reporter, f"{owner}: image "
                                                        f"'{image.name}' tile {tile.number}"), image.name_full)
            tiles.append((int(tile.number), self._index[key]))
        return tiles

    def index_of(self, image, owner: str, frame: int | None = None) -> int:
        """Index of a Blender image in Scene.images (-1: missing, magenta)."""
        if image is None:
            self.reporter.warn(f"{owner}: Image Texture without an image; rendered magenta as Cycles")
            return -1
        key = (image.name_full, frame)
        if key not in self._index:
            self._index[key] = self._add(self._load(image, owner, frame), image.name_full)
        return self._index[key]

    def _add(self, loaded, name) -> int:
        if loaded is None:
            return -1
        self.images.append(loaded)
        return len(self.images) - 1

    def _load(self, image, owner, frame):
        label = f"{owner}: image '{image.name}'"
        source = getattr(image, "source", "FILE")
        if source == "FILE" and image.packed_file is None:
            path = _abspath(image)
            if not os.path.isfile(path):
                self.reporter.warn(f"{label}: file '{path}' not found; rendered magenta as Cycles")
                return None
            loaded = _read_file(path, image, self.reporter, label)
            if loaded is not None:
                return loaded
        if source == "SEQUENCE" and image.packed_file is None and frame is not None:
            path = _sequence_path(image, frame)
            if path is not None and os.path.isfile(path):
                loaded = _read_file(path, image, self.reporter, label)
                if loaded is not None:
                    return loaded
        if source in ("MOVIE", "SEQUENCE") and frame is not None:
            self.reporter.warn(f"{label}: {source.lower()} frames are read as Blender holds them (frame {frame} "
                               "may not be the one loaded)")
        return _read_blender(image, self.reporter, label)


def _abspath(image) -> str:
    import bpy

    return bpy.path.abspath(image.filepath_raw or image.filepath, library=image.library)


def _sequence_path(image, frame: int):
    """The file of frame `frame` of an image sequence (the digits before the extension)."""
    import re

    path = _abspath(image)
    head, tail = os.path.split(path)
    match = re.search(r"(\d+)(\.[^.]*)?$", tail)
    if match is None:
        return None
    digits = match.group(1)
    number = str(frame).zfill(len(digits))
    return os.path.join(head, tail[:match.start(1)] + number + (match.group(2) or ""))


def _colorspace(image) -> tuple:
    """(name, is_data) of the image's colour space."""
    settings = image.colorspace_settings
    return settings.name, bool(getattr(settings, "is_data", settings.name in ("Non-Color", "Raw")))


def _ocio_config() -> str | None:
    import bpy

    folder = bpy.utils.system_resource("DATAFILES", path="colormanagement")
    path = os.path.join(folder, "config.ocio") if folder else ""
    return path if os.path.isfile(path) else None


def _finish(name: str, pixels: np.ndarray, image, reporter, label: str, associated: bool) -> Image | None:
    """Colour space, alpha mode and association of pixels (H, W, C) with row 0 at the bottom."""
    space, is_data = _colorspace(image)
    alpha_mode = getattr(image, "alpha_mode", "STRAIGHT")
    ignore_alpha = alpha_mode == "NONE"
    # image_associate_alpha: not for data, ignored or channel-packed alpha
    associate = not (is_data or ignore_alpha or alpha_mode == "CHANNEL_PACKED")
    channels = pixels.shape[2]
    if channels == 2:  # grey + alpha -> RGBA
        pixels = np.concatenate([pixels[:, :, :1]] * 3 + [pixels[:, :, 1:2]], axis=2)
    elif channels == 3:
        one = np.full(pixels.shape[:2] + (1,), 255 if pixels.dtype == np.uint8 else 1.0, pixels.dtype)
        pixels = np.concatenate([pixels, one], axis=2)
    elif channels > 4:
        pixels = pixels[:, :, :4]
    if pixels.shape[2] == 4:
        if ignore_alpha:
            pixels[:, :, 3] = 255 if pixels.dtype == np.uint8 else 1.0
        elif associate and not associated:
            for rows in _row_chunks(pixels):  # chunks: temporaries stay small for huge images
                if pixels.dtype == np.uint8:  # util_image_multiply_native: (c * a) / 255 in integers
                    a = pixels[rows, :, 3:4].astype(np.uint16)
                    pixels[rows, :, :3] = (pixels[rows, :, :3].astype(np.uint16) * a // 255).astype(np.uint8)
                else:
                    pixels[rows, :, :3] *= pixels[rows, :, 3:4]
    if pixels.dtype != np.uint8:
        bad = ~np.all(np.isfinite(pixels), axis=2)
        if bad.any():  # Cycles zeroes non-finite texels (file_load_image)
            reporter.warn(f"{label}: {int(bad.sum())} texels are not finite; read as 0 as Cycles")
            pixels[bad] = 0.0
    srgb = False
    if is_data or space in _SCENE_LINEAR:
        pass
    elif space == "sRGB":
        srgb = True
    else:
        pixels = _to_scene_linear(pixels, space, reporter, label)
    return Image(name, pixels, compress_as_srgb=srgb)


def _row_chunks(pixels, rows: int = 256):
    for start in range(0, pixels.shape[0], rows):
        yield slice(start, min(start + rows, pixels.shape[0]))


def _flip_rows(pixels: np.ndarray) -> np.ndarray:
    """Bottom row first, in place (no second copy of a large image)."""
    h = pixels.shape[0]
    for i in range(h // 2):
        top = pixels[i].copy()
        pixels[i] = pixels[h - 1 - i]
        pixels[h - 1 - i] = top
    return pixels


def _to_scene_linear(pixels: np.ndarray, space: str, reporter, label: str) -> np.ndarray:
    """Convert from `space` to scene-linear with Blender's OCIO configuration (Cycles' OCIO
    to_scene_linear at load); alpha untouched."""
    values = pixels.astype(np.float32) / (255.0 if pixels.dtype == np.uint8 else 1.0)
    config = _ocio_config()
    try:
        import OpenImageIO as oiio
    except ImportError:
        oiio = None
    if config is None or oiio is None:
        reporter.warn(f"{label}: colour space '{space}' needs OpenColorIO, which is not available; read raw")
        return values
    rgb = np.ascontiguousarray(values[:, :, :3]) if values.shape[2] == 4 else np.repeat(values, 3, axis=2)
    buf = oiio.ImageBuf(rgb)
    if not oiio.ImageBufAlgo.colorconvert(buf, buf, space, "scene_linear", colorconfig=config):
        reporter.warn(f"{label}: colour space '{space}' could not be converted ({oiio.geterror()}); read raw")
        return values
    converted = np.asarray(buf.get_pixels(oiio.FLOAT), np.float32).reshape(rgb.shape)
    if values.shape[2] == 4:
        values[:, :, :3] = converted
        return values
    return np.ascontiguousarray(converted[:, :, :1])


def _read_file(path: str, image, reporter, label: str) -> Image | None:
    """OIIOImageLoader: the file's own sample type, rows flipped so row 0 is the bottom."""
    try:
        import OpenImageIO as oiio
    except ImportError:
        return None
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)  # associated below, as Cycles does
    source = oiio.ImageInput.open(path, config)
    if source is None:
        reporter.warn(f"{label}: '{path}' could not be read ({oiio.geterror()}); rendered magenta as Cycles")
        return None
    try:
        spec = source.spec()
        base = spec.format.basetype
        if base == oiio.UINT8:
            fmt, dtype = oiio.UINT8, np.uint8
        elif base == oiio.UINT16:
            fmt, dtype = oiio.UINT16, np.uint16
        else:
            fmt, dtype = oiio.FLOAT, np.float32
        pixels = source.read_image(0, 0, 0, spec.nchannels, fmt)
        unassociated = bool(spec.get_int_attribute("oiio:UnassociatedAlpha", 0))
        if source.format_name() in ("targa", "dds", "psd") and spec.alpha_channel != -1:
            unassociated = True  # Cycles' per-format workarounds (image_oiio.cpp)
    finally:
        source.close()
    if pixels is None:
        reporter.warn(f"{label}: '{path}' could not be read ({oiio.geterror()}); rendered magenta as Cycles")
        return None
    pixels = _flip_rows(np.asarray(pixels, dtype=dtype).reshape(spec.height, spec.width, spec.nchannels))
    if dtype == np.uint16:
        pixels = pixels.astype(np.float32) * np.float32(1.0 / 65535.0)
    return _finish(image.name_full, pixels, image, reporter, label, associated=not unassociated)


def _read_blender(image, reporter, label: str) -> Image | None:
    """BlenderImageLoader: Blender's byte (encoded, straight) or float (linear, premultiplied) buffer."""
    try:
        width, height = int(image.size[0]), int(image.size[1])
        has_data = width > 0 and height > 0
    except (AttributeError, RuntimeError):
        has_data = False
    if not has_data:
        reporter.warn(f"{label}: no pixels could be loaded; rendered magenta as Cycles")
        return None
    channels = int(image.channels) or 4
    flat = np.empty(width * height * channels, np.float32)
    image.pixels.foreach_get(flat)
    pixels = flat.reshape(height, width, channels)
    if not image.is_float:
        pixels = np.clip(np.rint(pixels * 255.0), 0, 255).astype(np.uint8)
        return _finish(image.name_full, pixels, image, reporter, label, associated=False)
    # float buffers are scene-linear and premultiplied already ("converted on the Blender side")
    if channels not in (1, 4):
        pad = np.zeros((height, width, 4), np.float32)
        pad[:, :, :channels] = pixels[:, :, :min(channels, 4)]
        pad[:, :, 3] = pixels[:, :, 3] if channels >= 4 else 1.0
        pixels = pad
    return Image(image.name_full, np.ascontiguousarray(pixels), compress_as_srgb=False)
