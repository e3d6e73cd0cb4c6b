"""Camera rays with Blender's viewplane (BKE_camera_params_compute_viewplane, blenkernel/camera.cc):
the fitted sensor axis spans the field of view, lens shift is in units of the fitted image size,
and clipping is planar (Cycles kernel/camera/camera.h divides the clip distances by the ray's
camera-space z)."""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from .jit import kernel
from .scene import Camera, Film, SceneError

# What camera_ray1 reads: film size and shift in pixels, pixel size (at unit depth, or in metres
# for orthographic), clip range, camera-to-world rotation (3,3) and position (3,).
CameraTables = namedtuple("CameraTables", ["width", "height", "shift_x", "shift_y", "pixel_size",
                                           "perspective", "clip_start", "clip_end", "rotation", "position"])


def crop_window(film: Film) -> tuple[int, int, int, int]:
    """(x0, y0, width, height) of the rendered region in pixels, y0 from the TOP of the frame.

    Blender's border is (xmin, xmax, ymin, ymax) in [0, 1] with y measured from the bottom."""
    if film.crop is None:
        return 0, 0, film.width, film.height
    xmin, xmax, ymin, ymax = (float(c) for c in film.crop)
    if not all(np.isfinite([xmin, xmax, ymin, ymax])):
        raise SceneError(f"crop region {film.crop} is not finite")
    x0, x1 = (int(round(np.clip(x, 0, 1) * film.width)) for x in (xmin, xmax))
    y0_bottom, y1_bottom = (int(round(np.clip(y, 0, 1) * film.height)) for y in (ymin, ymax))
    if x1 <= x0 or y1_bottom <= y0_bottom:
        raise SceneError(f"crop region {film.crop} is empty at {film.width}x{film.height}")
    return x0, film.height - y1_bottom, x1 - x0, y1_bottom - y0_bottom


class CameraModel:
    def __init__(self, camera: Camera, film: Film):
        self.camera = camera
        self.width, self.height = film.width, film.height
        fit = camera.sensor_fit.upper()
        if fit == "AUTO":
            fit = "HORIZONTAL" if self.width >= self.height else "VERTICAL"
        if fit not in ("HORIZONTAL", "VERTICAL"):
            raise SceneError(f"unknown sensor fit '{camera.sensor_fit}'")
        self.viewfac = float(self.width if fit == "HORIZONTAL" else self.height)
        if camera.projection == "perspective":
            if not 0.0 < camera.fov < np.pi:
                raise SceneError(f"camera field of view {camera.fov} rad outside (0, pi)")
            self.pixel_size = 2.0 * np.tan(0.5 * camera.fov) / self.viewfac  # at unit depth
        else:
            if not camera.ortho_scale > 0:
                raise SceneError(f"orthographic scale {camera.ortho_scale} must be positive")
            self.pixel_size = camera.ortho_scale / self.viewfac
        if not 0 <= camera.clip_start < camera.clip_end:
            raise SceneError(f"camera clip range [{camera.clip_start}, {camera.clip_end}] is empty")
        m = camera.camera_to_world
        self.rotation = m[:3, :3]
        self.position = m[:3, 3].copy()
        # Shift moves the viewplane by shift * (fitted image size), in pixels:
        self.shift_px = np.array([camera.shift_x * self.viewfac, camera.shift_y * self.viewfac])

        self.tables = CameraTables(float(self.width), float(self.height), float(self.shift_px[0]),
                                   float(self.shift_px[1]), float(self.pixel_size),
                                   camera.projection == "perspective", float(camera.clip_start),
                                   float(camera.clip_end), np.ascontiguousarray(self.rotation, dtype=np.float64),
                                   np.ascontiguousarray(self.position, dtype=np.float64))

    def near_bounds(self, pad: float) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of a box holding every camera ray's origin and the camera position, for film
        positions up to `pad` pixels outside the frame (the pixel filter's reach): the region the
        rays skip between the camera and the near clip."""
        w, h = float(self.width), float(self.height)
        xs = np.array([-pad, w + pad, -pad, w + pad])
        ys = np.array([-pad, -pad, h + pad, h + pad])
        origins, _, _ = self.generate_rays(xs, ys)
        points = np.vstack([origins, self.position[None, :]])
        return points.min(axis=0), points.max(axis=0)

    def generate_rays(self, film_x: np.ndarray, film_y: np.ndarray):
        """Rays through continuous full-frame film positions (x right, y DOWN from the top-left).

        Returns (origins, unit directions, tmax) in world space; origins already at the near clip."""
        n = len(film_x)
        o, d, tmax = np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
        _camera_rays_many(self.tables, np.ascontiguousarray(film_x, np.float64),
                          np.ascontiguousarray(film_y, np.float64), o, d, tmax)
        return o, d, tmax


@kernel
def camera_ray1(cam, film_x, film_y):
    """(origin, unit direction, tmax) of the ray through one full-frame film position."""
    x = (film_x - 0.5 * cam.width + cam.shift_x) * cam.pixel_size
    y = (0.5 * cam.height - film_y + cam.shift_y) * cam.pixel_size
    if cam.perspective:
        # through (x, y, -1) at unit depth; planar clipping divides by the direction's depth
        length = np.sqrt(x * x + y * y + 1.0)
        lx, ly, lz = x / length, y / length, -1.0 / length
        ox, oy, oz = x * cam.clip_start, y * cam.clip_start, -cam.clip_start
        tmax = (cam.clip_end - cam.clip_start) * length
    else:
        lx, ly, lz = 0.0, 0.0, -1.0
        ox, oy, oz = x, y, -cam.clip_start
        tmax = cam.clip_end - cam.clip_start
    r = cam.rotation
    dx = r[0, 0] * lx + r[0, 1] * ly + r[0, 2] * lz
    dy = r[1, 0] * lx + r[1, 1] * ly + r[1, 2] * lz
    dz = r[2, 0] * lx + r[2, 1] * ly + r[2, 2] * lz
    inv = 1.0 / np.sqrt(dx * dx + dy * dy + dz * dz)  # the rotation may carry the object's scale
    return ((r[0, 0] * ox + r[0, 1] * oy + r[0, 2] * oz + cam.position[0],
             r[1, 0] * ox + r[1, 1] * oy + r[1, 2] * oz + cam.position[1],
             r[2, 0] * ox + r[2, 1] * oy + r[2, 2] * oz + cam.position[2]),
            (dx * inv, dy * inv, dz * inv), tmax)


@kernel
def _camera_rays_many(cam, film_x, film_y, o, d, tmax):
    for i in range(film_x.shape[0]):
        origin, direction, tmax[i] = camera_ray1(cam, film_x[i], film_y[i])
        for c in range(3):
            o[i, c] = origin[c]
            d[i, c] = direction[c]
