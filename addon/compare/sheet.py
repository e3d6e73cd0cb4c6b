"""Contact sheets: scene-linear renders and false-colour maps side by side in one labelled PNG.

Image work (colour conversion, resampling, pasting, text) is OpenImageIO's; this module only lays
the panels out. No bpy.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from . import metrics

LINEAR_SPACE = "Linear Rec.709 (sRGB)"
DISPLAY_SPACE = "sRGB Encoded Rec.709 (sRGB)"
MIN_PANEL_WIDTH = 256
MARGIN = 8
LABEL_HEIGHT = 22
FONT_SIZE = 15
BAR_HEIGHT = 12


def _oiio():
    try:
        import OpenImageIO as oiio
    except ImportError as error:  # Blender 3.x's Python has no OpenImageIO
        raise RuntimeError("OpenImageIO is needed to write contact sheets") from error
    return oiio


@dataclass
class Panel:
    """One tile: display-referred RGB (H, W, 3) in [0, 1], a title above and a caption below."""

    title: str
    display_rgb: np.ndarray
    caption: str = ""
    colour_bar_scale: Optional[float] = None  # draw a -s..+s colour bar under the tile


def linear_to_display(image: np.ndarray, exposure: float) -> np.ndarray:
    """Scene-linear RGB -> sRGB-encoded display RGB in [0, 1] (clipped) with OpenImageIO."""
    oiio = _oiio()
    scaled = np.clip(metrics.rgb(image) * (2.0 ** exposure), 0.0, 1.0).astype(np.float32)
    buf = oiio.ImageBuf(np.ascontiguousarray(scaled))
    out = oiio.ImageBufAlgo.colorconvert(buf, LINEAR_SPACE, DISPLAY_SPACE)
    if out.has_error:
        raise RuntimeError(f"colour conversion failed: {out.geterror()}")
    return np.clip(out.get_pixels(oiio.FLOAT), 0.0, 1.0)


def render_panel(title: str, image: np.ndarray, exposure: float, caption: str = "") -> Panel:
    return Panel(title, linear_to_display(image, exposure), caption)


def difference_panel(title: str, relative_difference: np.ndarray, scale: Optional[float] = None,
                     caption: str = "") -> Panel:
    scale = metrics.difference_scale(relative_difference) if scale is None else scale
    return Panel(title, metrics.false_colour(relative_difference, scale),
                 caption or "blue: first darker, red: first brighter", colour_bar_scale=scale)


def _upscale_factor(width: int) -> int:
    return max(1, -(-MIN_PANEL_WIDTH // max(width, 1)))


def write_contact_sheet(path, rows: Sequence[Sequence[Panel]], title: str = "") -> Path:
    """Write panels (a list of rows) as one PNG; small renders are enlarged by an integer factor
    with nearest-neighbour sampling so pixels stay visible."""
    oiio = _oiio()
    rows = [list(row) for row in rows if row]
    if not rows:
        raise ValueError("no panels to write")
    factor = max(_upscale_factor(p.display_rgb.shape[1]) for row in rows for p in row)
    tile_w = max(p.display_rgb.shape[1] for row in rows for p in row) * factor
    tile_h = max(p.display_rgb.shape[0] for row in rows for p in row) * factor
    cell_h = LABEL_HEIGHT + tile_h + BAR_HEIGHT + 2 * LABEL_HEIGHT
    columns = max(len(row) for row in rows)
    title_h = LABEL_HEIGHT + MARGIN if title else 0
    width = MARGIN + columns * (tile_w + MARGIN)
    height = title_h + MARGIN + len(rows) * (cell_h + MARGIN)
    canvas = oiio.ImageBuf(oiio.ImageSpec(width, height, 3, oiio.FLOAT))
    oiio.ImageBufAlgo.fill(canvas, [0.12, 0.12, 0.12])
    if title:
        oiio.ImageBufAlgo.render_text(canvas, MARGIN, MARGIN + FONT_SIZE, title, FONT_SIZE + 2, "",
                                      [1.0, 1.0, 1.0])
    for r, row in enumerate(rows):
        y0 = title_h + MARGIN + r * (cell_h + MARGIN)
        for c, panel in enumerate(row):
            x0 = MARGIN + c * (tile_w + MARGIN)
            _draw_panel(oiio, canvas, panel, x0, y0, factor)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # The canvas already holds sRGB-encoded values: quantise without another conversion.
    if not canvas.write(str(path), oiio.UINT8):
        raise RuntimeError(f"cannot write {path}: {canvas.geterror()}")
    return path


def _draw_panel(oiio, canvas, panel: Panel, x0: int, y0: int, factor: int) -> None:
    white = [1.0, 1.0, 1.0]
    oiio.ImageBufAlgo.render_text(canvas, x0, y0 + FONT_SIZE, panel.title, FONT_SIZE, "", white)
    pixels = np.ascontiguousarray(np.clip(panel.display_rgb, 0.0, 1.0).astype(np.float32))
    tile = oiio.ImageBuf(pixels)
    h, w = pixels.shape[:2]
    big = oiio.ImageBuf(oiio.ImageSpec(w * factor, h * factor, 3, oiio.FLOAT))
    oiio.ImageBufAlgo.resample(big, tile, interpolate=False)
    top = y0 + LABEL_HEIGHT
    oiio.ImageBufAlgo.paste(canvas, x0, top, 0, 0, big)
    below = top + h * factor + 4
    if panel.colour_bar_scale is not None:
        bar = oiio.ImageBuf(np.ascontiguousarray(metrics.colour_bar(w * factor, BAR_HEIGHT).astype(np.float32)))
        oiio.ImageBufAlgo.paste(canvas, x0, below, 0, 0, bar)
        s = panel.colour_bar_scale
        label_y = below + BAR_HEIGHT + FONT_SIZE
        oiio.ImageBufAlgo.render_text(canvas, x0, label_y, f"-{s:g}", FONT_SIZE - 2, "", white)
        oiio.ImageBufAlgo.render_text(canvas, x0 + w * factor // 2 - 4, label_y, "0", FONT_SIZE - 2, "", white)
        oiio.ImageBufAlgo.render_text(canvas, x0 + w * factor - 36, label_y, f"+{s:g}", FONT_SIZE - 2, "", white)
        below = label_y + 4
    if panel.caption:
        oiio.ImageBufAlgo.render_text(canvas, x0, below + FONT_SIZE, panel.caption, FONT_SIZE - 3, "", white)
