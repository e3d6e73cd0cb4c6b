"""The scene camera and the render film (resolution, border, pixel filter)."""
from __future__ import annotations

import math

import numpy as np

import volpath_native as vp

# scene.cycles.pixel_filter_type -> VolPath's filter names.
_FILTERS = {"BLACKMAN_HARRIS": "blackman-harris", "BOX": "box", "GAUSSIAN": "gaussian"}


def _without_scale(matrix: np.ndarray) -> np.ndarray:
    """Camera rays ignore object scale in Blender: normalise the rotation columns."""
    out = np.array(matrix, dtype=np.float64)
    norms = np.linalg.norm(out[:3, :3], axis=0)
    if np.any(norms < 1e-12):
        raise vp.SceneError("the camera object has zero scale")
    out[:3, :3] /= norms
    return out


def export_camera(camera_object, reporter) -> vp.Camera:
    if camera_object is None:
        raise vp.SceneError("the scene has no active camera: set one in Scene Properties > Camera")
    if camera_object.type != "CAMERA":
        raise vp.SceneError(f"the scene camera '{camera_object.name}' is not a camera object")
    cam = camera_object.data
    name = camera_object.name
    if cam.type == "PANO":
        raise vp.SceneError(f"camera '{name}': panoramic cameras are not supported by VolPath")
    if cam.dof.use_dof:
        reporter.warn(f"camera '{name}': depth of field is not supported; rendered as a pinhole camera")
    # Blender's viewplane (BKE_camera_params_compute_viewplane): AUTO and HORIZONTAL fit
    # sensor_width, VERTICAL fits sensor_height; fov = 2 atan(sensor / (2 lens)).
    sensor = cam.sensor_height if cam.sensor_fit == "VERTICAL" else cam.sensor_width
    return vp.Camera(
        camera_to_world=_without_scale(np.array(camera_object.matrix_world)),
        projection="orthographic" if cam.type == "ORTHO" else "perspective",
        fov=2.0 * math.atan(0.5 * sensor / cam.lens),
        ortho_scale=float(cam.ortho_scale),
        sensor_fit=cam.sensor_fit,
        shift_x=float(cam.shift_x),
        shift_y=float(cam.shift_y),
        clip_start=float(cam.clip_start),
        clip_end=float(cam.clip_end),
    )


def export_film(scene, reporter) -> vp.Film:
    render = scene.render
    # Blender's render size: resolution x percentage / 100 in integer arithmetic.
    width = render.resolution_x * render.resolution_percentage // 100
    height = render.resolution_y * render.resolution_percentage // 100
    if render.pixel_aspect_x != render.pixel_aspect_y:
        reporter.warn("non-square pixel aspect is not supported; rendered with square pixels")
    if render.film_transparent:
        reporter.warn("Film > Transparent is not supported; the background is rendered opaque")
    if render.use_motion_blur:
        reporter.warn("motion blur is not supported; rendered at the frame's shutter centre")
    crop = None
    if render.use_border:
        # Blender truncates the border to whole pixels (render/intern/pipeline.cc:
        # disprect.xmin = border.xmin * winx, an int); hand the renderer those exact pixel edges.
        x0, x1 = (int(render.border_min_x * width), int(render.border_max_x * width))
        y0, y1 = (int(render.border_min_y * height), int(render.border_max_y * height))
        if x1 <= x0 or y1 <= y0:
            raise vp.SceneError(f"the render region (border) is empty at {width}x{height} pixels")
        if (x0, x1, y0, y1) != (0, width, 0, height):
            crop = (x0 / width, x1 / width, y0 / height, y1 / height)
    # Cycles' pixel filter settings (scene.cycles exists when the Cycles add-on is enabled);
    # otherwise Cycles' defaults, Blackman-Harris 1.5 px.
    cycles = getattr(scene, "cycles", None)
    filter_type = getattr(cycles, "pixel_filter_type", "BLACKMAN_HARRIS")
    filter_width = float(getattr(cycles, "filter_width", 1.5))
    return vp.Film(width=width, height=height, crop=crop, filter=_FILTERS.get(filter_type, "blackman-harris"),
                   filter_width=filter_width)
