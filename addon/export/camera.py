"""The scene camera and the render film (resolution, border, pixel filter)."""
from __future__ import annotations

import math

import numpy as np

import volpath_native as vp

from .. import compat

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


# Blender's panorama types VolPath renders (Cycles' projection.h); the others stop the render.
_PANORAMA_TYPES = {"EQUIRECTANGULAR": "equirectangular", "FISHEYE_EQUIDISTANT": "fisheye_equidistant",
                   "FISHEYE_EQUISOLID": "fisheye_equisolid", "MIRRORBALL": "mirrorball",
                   "CENTRAL_CYLINDRICAL": "central_cylindrical"}


def export_camera(camera_object, reporter, motion_transforms=()) -> vp.Camera:
    """The scene camera as Cycles syncs it (intern/cycles/blender/camera.cpp
    blender_camera_from_object / blender_camera_sync). motion_transforms: camera_to_world at the
    camera's motion steps (motion.camera_motion), empty without motion blur."""
    if camera_object is None:
        raise vp.SceneError("the scene has no active camera: set one in Scene Properties > Camera")
    if camera_object.type != "CAMERA":
        raise vp.SceneError(f"the scene camera '{camera_object.name}' is not a camera object")
    cam = camera_object.data
    name = camera_object.name
    projection = {"ORTHO": "orthographic", "PANO": "panoramic"}.get(cam.type, "perspective")
    if cam.type not in ("PERSP", "ORTHO", "PANO"):
        reporter.warn(f"camera '{name}': {cam.type.lower()} cameras are not supported; rendered as perspective")
    panorama_type = "fisheye_equisolid"
    def pano(key):
        return compat.camera_panorama(cam, key)
    if cam.type == "PANO":
        if pano("panorama_type") not in _PANORAMA_TYPES:
            raise vp.SceneError(f"camera '{name}': the panorama type {pano('panorama_type')} is not supported by "
                                f"VolPath (supported: {', '.join(_PANORAMA_TYPES)})")
        panorama_type = _PANORAMA_TYPES[pano("panorama_type")]
    # Blender's viewplane (BKE_camera_params_compute_viewplane): AUTO and HORIZONTAL fit
    # sensor_width, VERTICAL fits sensor_height; fov = 2 atan(sensor / (2 lens)).
    sensor = cam.sensor_height if cam.sensor_fit == "VERTICAL" else cam.sensor_width
    return vp.Camera(
        camera_to_world=_without_scale(np.array(camera_object.matrix_world)),
        projection=projection,
        fov=2.0 * math.atan(0.5 * sensor / cam.lens),
        ortho_scale=float(cam.ortho_scale),
        sensor_fit=cam.sensor_fit,
        shift_x=float(cam.shift_x),
        shift_y=float(cam.shift_y),
        clip_start=float(cam.clip_start),
        clip_end=float(cam.clip_end),
        name=name,
        **_depth_of_field(camera_object, projection, reporter),
        panorama_type=panorama_type,
        fisheye_fov=float(pano("fisheye_fov")),
        fisheye_lens=float(pano("fisheye_lens")),
        sensor_width=float(cam.sensor_width),
        sensor_height=float(cam.sensor_height),
        latitude_min=float(pano("latitude_min")), latitude_max=float(pano("latitude_max")),
        longitude_min=float(pano("longitude_min")), longitude_max=float(pano("longitude_max")),
        # blender_camera_sync divides the cylinder's heights by its radius
        cylinder_u_min=float(pano("central_cylindrical_range_u_min")),
        cylinder_u_max=float(pano("central_cylindrical_range_u_max")),
        cylinder_v_min=float(pano("central_cylindrical_range_v_min")) / float(pano("central_cylindrical_radius")),
        cylinder_v_max=float(pano("central_cylindrical_range_v_max")) / float(pano("central_cylindrical_radius")),
        motion_transforms=[_without_scale(m) for m in motion_transforms],
    )


def _depth_of_field(camera_object, projection: str, reporter) -> dict:
    """Cycles' lens (blender_camera_from_object): aperture radius = lens / (2 F-stop) (1 / (2
    F-stop) for orthographic cameras), F-stop at least 1e-5; the focus object's distance along the
    camera's view axis; scene/camera.cpp then keeps the focus distance >= 1e-5 and makes fewer
    than 3 blades a disk."""
    cam = camera_object.data
    name = camera_object.name
    dof = cam.dof
    if not dof.use_dof:
        return {}
    fstop = float(dof.aperture_fstop)
    if not fstop > 1e-5:
        reporter.warn(f"camera '{name}': F-stop {fstop:g} is not positive; Cycles' minimum 1e-05 is used "
                      "(an aperture so wide that nothing is in focus)")
        fstop = 1e-5
    aperture = 1.0 / (2.0 * fstop) if projection == "orthographic" else cam.lens * 1e-3 / (2.0 * fstop)
    focus = float(dof.focus_distance)
    target = dof.focus_object
    if target is not None:
        matrix = np.array(camera_object.matrix_world, dtype=np.float64)
        target_matrix = np.array(target.matrix_world, dtype=np.float64)
        bone = getattr(dof, "focus_subtarget", "")
        if bone and target.pose is not None and bone in target.pose.bones:
            target_matrix = target_matrix @ np.array(target.pose.bones[bone].matrix, dtype=np.float64)
        view = matrix[:3, 2] / max(np.linalg.norm(matrix[:3, 2]), 1e-30)
        focus = float(abs(view @ (matrix[:3, 3] - target_matrix[:3, 3])))
        if target.name == name or focus < 1e-5:
            reporter.warn(f"camera '{name}': the focus object '{target.name}' is at distance {focus:g} along the "
                          "view axis; Cycles' minimum focus distance 1e-05 m is used")
    elif focus < 1e-5:
        reporter.warn(f"camera '{name}': focus distance {focus:g} m; Cycles' minimum 1e-05 m is used")
    return dict(aperture_size=float(aperture), focus_distance=max(focus, 1e-5),
                aperture_blades=int(dof.aperture_blades), aperture_rotation=float(dof.aperture_rotation),
                aperture_ratio=float(dof.aperture_ratio))


def export_film(scene, reporter) -> vp.Film:
    render = scene.render
    # Blender's render size: resolution x percentage / 100 in integer arithmetic.
    width = render.resolution_x * render.resolution_percentage // 100
    height = render.resolution_y * render.resolution_percentage // 100
    if render.pixel_aspect_x != render.pixel_aspect_y:
        reporter.warn("non-square pixel aspect is not supported; rendered with square pixels")
    if getattr(render, "use_multiview", False):
        reporter.warn("Stereoscopy (multi-view) is not supported; rendered as one mono view")
    if render.film_transparent:
        reporter.warn("Film > Transparent is not supported; the background is rendered opaque")
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
