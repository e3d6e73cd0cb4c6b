"""Camera rays with Blender's viewplane (BKE_camera_params_compute_viewplane, blenkernel/camera.cc):
the fitted sensor axis spans the field of view, lens shift is in units of the fitted image size,
and clipping is planar (Cycles kernel/camera/camera.h divides the clip distances by the ray's
camera-space z)."""
from __future__ import annotations

import numpy as np

from .scene import Camera, Film, SceneError
from .vec import norm


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

    def generate_rays(self, film_x: np.ndarray, film_y: np.ndarray):
        """Rays through continuous full-frame film positions (x right, y DOWN from the top-left).

        Returns (origins, unit directions, tmax) in world space; origins already at the near clip."""
        x = (film_x - 0.5 * self.width + self.shift_px[0]) * self.pixel_size
        y = (0.5 * self.height - film_y + self.shift_px[1]) * self.pixel_size
        n = len(film_x)
        cam = self.camera
        if cam.projection == "perspective":
            local = np.stack([x, y, -np.ones(n)], axis=1)
            length = norm(local)
            local_dir = local / length[:, None]
            z = 1.0 / length  # |camera-space z| of the unit direction
            origins_local = local_dir * (cam.clip_start / z)[:, None]
            tmax = (cam.clip_end - cam.clip_start) / z
        else:
            origins_local = np.stack([x, y, -np.full(n, cam.clip_start)], axis=1)
            local_dir = np.tile([0.0, 0.0, -1.0], (n, 1))
            tmax = np.full(n, cam.clip_end - cam.clip_start)
        directions = self._rotate(local_dir)
        directions /= norm(directions)[:, None]
        origins = self._rotate(origins_local) + self.position
        return origins, directions, tmax

    def _rotate(self, v: np.ndarray) -> np.ndarray:
        """v @ rotation.T column by column: a (N,3) @ (3,3) product goes to BLAS, whose thread
        pool then spins on the other cores while the render threads need them."""
        r = self.rotation
        return v[:, 0:1] * r[:, 0] + v[:, 1:2] * r[:, 1] + v[:, 2:3] * r[:, 2]
