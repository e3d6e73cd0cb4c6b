"""Camera rays as Cycles makes them (kernel/camera/camera.h camera_sample and the
camera_sample_perspective / _orthographic / _panorama it dispatches to).

- Viewplane: Blender's (BKE_camera_params_compute_viewplane, blenkernel/camera.cc): the fitted
  sensor axis spans the field of view, lens shift is in units of the fitted image size; clipping
  is planar for perspective rays (Cycles divides the clip distances by the pinhole ray's
  camera-space z), spherical for panoramic ones (camera_sample_to_ray).
- Depth of field: a lens sample on the aperture (a disk, or a regular polygon of `blades`
  corners; kernel/camera/camera.h camera_sample_aperture, x divided by the aperture ratio), the
  ray aimed at the pinhole ray's point on the plane of focus (perspective, orthographic) or at
  the focus distance along it (panoramic).
- Panoramic: projection.py maps the image to directions (Cycles' projection.h); the image's
  (u, v) are the raster position over the full frame plus the lens shift (blender/camera.cpp
  blender_camera_viewplane: the panoramic viewplane is [0, 1]^2 offset by the shift).
- Motion blur: camera_motion.py (shutter time per ray, interpolated transform).
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from . import camera_motion, projection
from .camera_motion import interpolate_motion1, shutter_time1
from .jit import inline_stage_kernel, kernel, stage_kernel
from .sampling import concentric_disk1
from .scene import Camera, Film, SceneError

PERSPECTIVE, ORTHOGRAPHIC, PANORAMIC = 0, 1, 2
_KINDS = {"perspective": PERSPECTIVE, "orthographic": ORTHOGRAPHIC, "panoramic": PANORAMIC}

# What camera_ray1 reads.
CameraTables = namedtuple("CameraTables", [
    "kind",                     # PERSPECTIVE, ORTHOGRAPHIC or PANORAMIC
    "width", "height",          # full frame in pixels
    "shift_x", "shift_y",       # lens shift in pixels (perspective, orthographic) or in image units (panoramic)
    "pixel_size",               # at unit depth (perspective) or in metres (orthographic)
    "clip_start", "clip_end",
    "rotation", "position",     # camera-to-world (3, 3) and (3,): from camera space (Blender's object space,
                                # or Cycles' panoramic camera space, projection.py) to the world
    "aperture_size",            # lens radius in metres (0: pinhole)
    "focus_distance",
    "blades", "blades_rotation",  # aperture polygon (blades 0: a disk)
    "inv_aperture_ratio",
    "panorama", "equirectangular_range", "cylindrical_range", "fisheye_fov", "fisheye_lens",
    "sensor_width", "sensor_height",  # in mm, fitted to the frame (fisheye equisolid)
    "motion_rotations", "motion_positions",  # (S, 4) quaternions, (S, 3); S = 0: no camera motion
    "shutter", "rolling_shutter", "rolling_shutter_duration",  # inverted shutter curve; rolling shutter
])


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
        if fit not in ("AUTO", "HORIZONTAL", "VERTICAL"):
            raise SceneError(f"unknown sensor fit '{camera.sensor_fit}'")
        if camera.projection not in _KINDS:
            raise SceneError(f"unknown camera projection '{camera.projection}'")
        self.kind = _KINDS[camera.projection]
        fitted = fit if fit != "AUTO" else ("HORIZONTAL" if self.width >= self.height else "VERTICAL")
        self.viewfac = float(self.width if fitted == "HORIZONTAL" else self.height)
        self.pixel_size = 0.0
        if self.kind == PERSPECTIVE:
            if not 0.0 < camera.fov < np.pi:
                raise SceneError(f"camera field of view {camera.fov} rad outside (0, pi)")
            self.pixel_size = 2.0 * np.tan(0.5 * camera.fov) / self.viewfac  # at unit depth
        elif self.kind == ORTHOGRAPHIC:
            if not camera.ortho_scale > 0:
                raise SceneError(f"orthographic scale {camera.ortho_scale} must be positive")
            self.pixel_size = camera.ortho_scale / self.viewfac
        if not 0 <= camera.clip_start < camera.clip_end:
            raise SceneError(f"camera clip range [{camera.clip_start}, {camera.clip_end}] is empty")
        if self.kind == PANORAMIC:
            # the image's (u, v) = raster position / frame size + shift (blender_camera_viewplane)
            shift = (float(camera.shift_x), float(camera.shift_y))
            panorama = projection.PANORAMA_TYPES.index(camera.panorama_type)
            to_object = projection.MIRRORBALL_TO_OBJECT if panorama == projection.MIRRORBALL else projection.PANORAMA_TO_OBJECT
        else:
            # Shift moves the viewplane by shift * (fitted image size), in pixels:
            shift = (camera.shift_x * self.viewfac, camera.shift_y * self.viewfac)
            panorama = 0
            to_object = np.eye(3)
        m = camera.camera_to_world
        self.rotation = m[:3, :3] @ to_object
        self.position = m[:3, 3].copy()
        motion = [np.asarray(t, np.float64).reshape(4, 4) for t in camera.motion_transforms]
        if motion and not all(np.array_equal(t, motion[0]) for t in motion):
            quats, positions = camera_motion.decompose_motion([t[:3, :3] @ to_object for t in motion],
                                                              [t[:3, 3] for t in motion])
        else:  # Cycles: no motion unless a step differs (scene/camera.cpp Camera::update)
            quats, positions = np.zeros((0, 4)), np.zeros((0, 3))
        self.has_motion = len(quats) > 0
        sensor_width, sensor_height = _panorama_sensor(camera, self.width, self.height)
        self.tables = CameraTables(
            kind=self.kind, width=float(self.width), height=float(self.height),
            shift_x=float(shift[0]), shift_y=float(shift[1]), pixel_size=float(self.pixel_size),
            clip_start=float(camera.clip_start), clip_end=float(camera.clip_end),
            rotation=np.ascontiguousarray(self.rotation, dtype=np.float64),
            position=np.ascontiguousarray(self.position, dtype=np.float64),
            aperture_size=float(max(camera.aperture_size, 0.0)),
            # scene/camera.cpp Camera::update: focaldistance >= 1e-5, fewer than 3 blades: a disk
            focus_distance=float(max(camera.focus_distance, 1e-5)),
            blades=float(camera.aperture_blades if camera.aperture_blades >= 3 else 0),
            blades_rotation=float(camera.aperture_rotation),
            inv_aperture_ratio=float(1.0 / camera.aperture_ratio),
            panorama=int(panorama),
            equirectangular_range=projection.equirectangular_range(
                camera.latitude_min, camera.latitude_max, camera.longitude_min, camera.longitude_max),
            cylindrical_range=projection.central_cylindrical_range(
                camera.cylinder_u_min, camera.cylinder_u_max, camera.cylinder_v_min, camera.cylinder_v_max),
            fisheye_fov=float(camera.fisheye_fov), fisheye_lens=float(camera.fisheye_lens),
            sensor_width=float(sensor_width), sensor_height=float(sensor_height),
            motion_rotations=quats, motion_positions=positions,
            shutter=camera_motion.shutter_table(camera.shutter_curve),
            rolling_shutter=bool(camera.rolling_shutter),
            rolling_shutter_duration=float(camera.rolling_shutter_duration))

    @property
    def has_lens(self) -> bool:
        return self.tables.aperture_size > 0.0

    def near_bounds(self, pad: float) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of a box holding every camera ray's origin and the camera position, for film
        positions up to `pad` pixels outside the frame (the pixel filter's reach), every lens
        sample and every shutter time: the region the rays skip between the camera and the near
        clip (Cycles scene/camera.cpp viewplane_bounds_get grows its box likewise by the aperture)."""
        t = self.tables
        aperture = t.aperture_size * max(t.inv_aperture_ratio, 1.0)
        pinhole = t._replace(aperture_size=0.0)
        times = np.linspace(0.0, 1.0, 65) if self.has_motion else np.array([0.5])
        w, h = float(self.width), float(self.height)
        xs = np.array([-pad, w + pad, -pad, w + pad, 0.5 * w])
        ys = np.array([-pad, -pad, h + pad, h + pad, 0.5 * h])
        points = []
        for time in times:
            rotation, position = self._pose(time)
            if self.kind == PANORAMIC:  # origins within aperture + clip_start of the camera
                reach = np.full((1, 1), aperture + t.clip_start)
                origins = position[None, :]
            else:
                origins, directions, _ = _rays(pinhole, xs, ys, np.full(len(xs), 0.5), np.full(len(xs), 0.5),
                                               np.full(len(xs), time))
                if self.kind == PERSPECTIVE:
                    # a lens point L moves the origin by L plus near * length * (normalize(F - L) -
                    # normalize(F)), F the focus point at distance focus * length: at most 2 |L| / |F|
                    length = 1.0 / np.maximum(-(directions @ rotation)[:, 2], 1e-9)
                    near = t.clip_start * length
                    tilt = np.minimum(2.0, 2.0 * aperture / (t.focus_distance * length))
                    reach = (aperture + near * tilt)[:, None]
                else:  # the origin moves by L (1 + near / focus)
                    reach = np.full((len(xs), 1), aperture * (1.0 + t.clip_start / t.focus_distance))
                if aperture == 0.0:
                    reach = np.zeros_like(reach)
            points += [origins - reach, origins + reach, position[None, :]]
        points = np.vstack(points)
        return points.min(axis=0), points.max(axis=0)

    def _pose(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        """(rotation, position) of the camera at a shutter time."""
        if not self.has_motion:
            return self.rotation, self.position
        rotation, position = interpolate_motion1(self.tables.motion_rotations, self.tables.motion_positions, float(time))
        return np.array(rotation).reshape(3, 3), np.array(position)

    def generate_rays(self, film_x: np.ndarray, film_y: np.ndarray, lens_u=None, lens_v=None, time=None):
        """Rays through continuous full-frame film positions (x right, y DOWN from the top-left),
        for lens samples (lens_u, lens_v) in [0, 1)^2 (default: the pinhole, no lens) at shutter times
        in [0, 1] (default 0.5).

        Returns (origins, unit directions, tmax) in world space; origins already at the near
        clip. A position a panoramic camera does not see gets direction (0, 0, 0) and tmax 0."""
        n = len(film_x)

        def column(values, default):
            return np.ascontiguousarray(np.full(n, default) if values is None else values, np.float64)
        tables = self.tables if lens_u is not None else self.tables._replace(aperture_size=0.0)
        return _rays(tables, column(film_x, 0.0), column(film_y, 0.0), column(lens_u, 0.5),
                     column(lens_v, 0.5), column(time, 0.5))


def _rays(tables, film_x, film_y, lens_u, lens_v, time):
    n = len(film_x)
    o, d, tmax = np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
    _camera_rays_many(tables, *(np.ascontiguousarray(a, np.float64) for a in (film_x, film_y, lens_u, lens_v, time)),
                      o, d, tmax)
    return o, d, tmax


def _panorama_sensor(camera: Camera, width: int, height: int) -> tuple[float, float]:
    """Sensor size in mm fitted to the frame, as Cycles sets it for fisheye equisolid cameras
    (blender/camera.cpp blender_camera_sync: AUTO fits the wider side, strictly, with the sensor
    width; the other side scales with the frame's aspect)."""
    fit = camera.sensor_fit.upper()
    if fit == "AUTO":
        horizontal, size = width > height, camera.sensor_width
    elif fit == "HORIZONTAL":
        horizontal, size = True, camera.sensor_width
    else:
        horizontal, size = False, camera.sensor_height
    if horizontal:
        return size, size * height / width
    return size * width / height, size


@stage_kernel
def aperture_sample1(cam, lens_u, lens_v):
    """Point on the lens in units of the aperture radius (camera.h camera_sample_aperture:
    a uniform disk, or a regular polygon of `blades` corners (mapping.h regular_polygon_sample);
    x divided by the aperture ratio, for anamorphic bokeh)."""
    if cam.blades == 0.0:
        x, y = concentric_disk1(lens_u, lens_v)
    else:
        corners = cam.blades
        corner = np.floor(lens_u * corners)
        u = lens_u * corners - corner
        u = np.sqrt(u)  # uniform point in the triangle (centre, two neighbouring corners)
        v = lens_v * u
        u = 1.0 - u
        angle = np.pi / corners
        px, py = (u + v) * np.cos(angle), (u - v) * np.sin(angle)
        rotation = cam.blades_rotation + corner * 2.0 * angle
        cr, sr = np.cos(rotation), np.sin(rotation)
        x, y = cr * px - sr * py, sr * px + cr * py
    return x * cam.inv_aperture_ratio, y


@stage_kernel
def ray_time1(cam, row, u):
    """Shutter time in [0, 1] of a camera ray of pixel row `row` (counted from the top) for a
    uniform u (camera.h camera_sample: the inverted shutter curve, then the rolling shutter, whose
    rows are read from the top (time 0) to the bottom (time 1) of the frame)."""
    time = shutter_time1(cam.shutter, u)
    if cam.rolling_shutter:
        row_time = 1.0 - (cam.height - 1.0 - row) / cam.height  # Cycles' raster y counts from the bottom
        duration = cam.rolling_shutter_duration
        if duration != 0.0:
            time = (time - 0.5) * duration + (row_time - 0.5) * (1.0 - duration) + 0.5
        else:
            time = row_time
    return time


# Inlined and without reference counting (as every helper it calls): compiled with it, its reads of
# the camera's arrays cost atomic increments and decrements, and the call ~110 of the ~240 ns a
# path of the coloured absorber took in all (session 32, tests/benchmarks/profile_row.py).
@inline_stage_kernel
def camera_ray1(cam, film_x, film_y, lens_u, lens_v, time):
    """(origin, unit direction, tmax, seen) of the camera ray through one full-frame film position,
    with a lens sample in [0, 1)^2 and a shutter time in [0, 1]. seen is False where a panoramic
    camera has no ray (outside a fisheye's circle): the sample adds nothing."""
    lx, ly = 0.0, 0.0  # lens point, camera space
    if cam.aperture_size > 0.0:
        lx, ly = aperture_sample1(cam, lens_u, lens_v)
        lx *= cam.aperture_size
        ly *= cam.aperture_size
    seen = True
    if cam.kind == PANORAMIC:
        u = film_x / cam.width + cam.shift_x
        v = (cam.height - film_y) / cam.height + cam.shift_y
        dx, dy, dz = projection.panorama_to_direction(
            cam.panorama, u, v, cam.equirectangular_range, cam.cylindrical_range, cam.fisheye_fov,
            cam.fisheye_lens, cam.sensor_width, cam.sensor_height)
        length = np.sqrt(dx * dx + dy * dy + dz * dz)
        if length == 0.0:
            seen = False
            dx, dy, dz, length = 1.0, 0.0, 0.0, 1.0
        dx, dy, dz = dx / length, dy / length, dz / length
        ox, oy, oz = 0.0, 0.0, 0.0
        if cam.aperture_size > 0.0:
            # camera_sample_panorama: the lens spans the plane normal to the ray, the ray meets the
            # pinhole ray at the focus distance; U = normalize(x - D.x D), V = D x U
            ux, uy, uz = 1.0 - dx * dx, -dx * dy, -dx * dz
            norm = np.sqrt(ux * ux + uy * uy + uz * uz)
            if norm < 1e-12:  # the ray along x: Cycles' normalize would give NaN; any normal plane will do
                ux, uy, uz, norm = 0.0, 1.0, 0.0, 1.0
            ux, uy, uz = ux / norm, uy / norm, uz / norm
            vx, vy, vz = dy * uz - dz * uy, dz * ux - dx * uz, dx * uy - dy * ux
            ox, oy, oz = ux * lx + vx * ly, uy * lx + vy * ly, uz * lx + vz * ly
            fx, fy, fz = dx * cam.focus_distance - ox, dy * cam.focus_distance - oy, dz * cam.focus_distance - oz
            inv = 1.0 / np.sqrt(fx * fx + fy * fy + fz * fz)
            dx, dy, dz = fx * inv, fy * inv, fz * inv
        near = cam.clip_start  # camera_sample_to_ray: clipping along the ray
        tmax = cam.clip_end - cam.clip_start
    else:
        x = (film_x - 0.5 * cam.width + cam.shift_x) * cam.pixel_size
        y = (0.5 * cam.height - film_y + cam.shift_y) * cam.pixel_size
        if cam.kind == PERSPECTIVE:
            # pinhole ray through (x, y, -1) at unit depth; planar clipping divides by its depth
            length = np.sqrt(x * x + y * y + 1.0)
            dx, dy, dz = x / length, y / length, -1.0 / length
            ox, oy, oz = 0.0, 0.0, 0.0
            if cam.aperture_size > 0.0:  # aim from the lens point at the pinhole ray's focus-plane point
                fx = x * cam.focus_distance - lx
                fy = y * cam.focus_distance - ly
                fz = -cam.focus_distance
                inv = 1.0 / np.sqrt(fx * fx + fy * fy + fz * fz)
                dx, dy, dz = fx * inv, fy * inv, fz * inv
                ox, oy = lx, ly
            near = cam.clip_start * length
            tmax = (cam.clip_end - cam.clip_start) * length
        else:
            dx, dy, dz = 0.0, 0.0, -1.0
            ox, oy, oz = x, y, 0.0
            if cam.aperture_size > 0.0:  # camera_sample_orthographic: focus straight ahead of the lens centre
                fx, fy, fz = -lx, -ly, -cam.focus_distance
                inv = 1.0 / np.sqrt(fx * fx + fy * fy + fz * fz)
                dx, dy, dz = fx * inv, fy * inv, fz * inv
                ox, oy = x + lx, y + ly
            near = cam.clip_start / -dz  # the origin moves onto the near clip plane
            tmax = cam.clip_end - cam.clip_start
    ox, oy, oz = ox + near * dx, oy + near * dy, oz + near * dz
    if cam.motion_rotations.shape[0] > 0:
        r, p = interpolate_motion1(cam.motion_rotations, cam.motion_positions, time)
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = r
        p0, p1, p2 = p
    else:
        r = cam.rotation
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = (r[0, 0], r[0, 1], r[0, 2], r[1, 0], r[1, 1], r[1, 2],
                                                       r[2, 0], r[2, 1], r[2, 2])
        p0, p1, p2 = cam.position[0], cam.position[1], cam.position[2]
    wx = r00 * dx + r01 * dy + r02 * dz
    wy = r10 * dx + r11 * dy + r12 * dz
    wz = r20 * dx + r21 * dy + r22 * dz
    inv = 1.0 / np.sqrt(wx * wx + wy * wy + wz * wz)
    return ((r00 * ox + r01 * oy + r02 * oz + p0, r10 * ox + r11 * oy + r12 * oz + p1,
             r20 * ox + r21 * oy + r22 * oz + p2),
            (wx * inv, wy * inv, wz * inv), tmax if seen else 0.0, seen)


@kernel
def _camera_rays_many(cam, film_x, film_y, lens_u, lens_v, time, o, d, tmax):
    for i in range(film_x.shape[0]):
        origin, direction, tmax[i], seen = camera_ray1(cam, film_x[i], film_y[i], lens_u[i], lens_v[i], time[i])
        for c in range(3):
            o[i, c] = origin[c]
            d[i, c] = direction[c] if seen else 0.0
