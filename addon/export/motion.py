"""Motion blur settings as Cycles syncs them (intern/cycles/blender/sync.cpp
BlenderSync::sync_motion, blender/camera.cpp sync_camera / sync_camera_motion, blender/util.h
object_motion_steps): the camera's transform at its motion steps over the shutter, the shutter
curve and the rolling shutter.

Only the camera moves in VolPath's renders: objects, lights and media that move during the shutter
are rendered where they are at the frame's shutter centre, and named in a warning (Cycles blurs
their transforms and deformations; velocity-based fluid motion blur likewise stays out).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

RAMP_TABLE_SIZE = 256  # Cycles kernel/types.h: the shutter curve's samples


@dataclass
class ShutterSettings:
    """What export_camera and the camera need from the render's motion blur settings."""
    camera_transforms: list = field(default_factory=list)  # camera_to_world at the motion steps
    shutter_curve: list = field(default_factory=list)
    rolling_shutter: bool = False
    rolling_shutter_duration: float = 0.1


def motion_steps(obj) -> int:
    """Cycles' object_motion_steps: (2 << (steps - 1)) + 1 transforms for an object with motion
    blur on (Object > Motion Blur, Cycles' per-object setting; on with 1 step by default), 0 off."""
    settings = getattr(obj, "cycles", None)
    if settings is not None and not getattr(settings, "use_motion_blur", True):
        return 0
    steps = max(1, int(getattr(settings, "motion_steps", 1)))
    return (2 << (steps - 1)) + 1


def shutter_curve(render) -> list:
    """Blender's shutter curve at RAMP_TABLE_SIZE evenly spaced times (Cycles' curvemapping_to_array);
    [] when it is constant (the same shutter table)."""
    mapping = render.motion_blur_shutter_curve
    try:
        mapping.initialize()
        values = [float(mapping.evaluate(mapping.curves[0], i / (RAMP_TABLE_SIZE - 1))) for i in range(RAMP_TABLE_SIZE)]
    except (AttributeError, RuntimeError, IndexError):
        return []
    values = [v if math.isfinite(v) else 0.0 for v in values]
    if max(values) - min(values) <= 0.0 and values[0] > 0:
        return []
    return values


def shutter_times(scene) -> tuple[float, float]:
    """(centre frame, shutter length in frames) Cycles syncs around: the current frame + subframe,
    moved by half the shutter for a shutter that starts or ends on the frame."""
    render = scene.render
    shutter = float(render.motion_blur_shutter)
    centre = scene.frame_current + float(scene.frame_subframe)
    position = getattr(render, "motion_blur_position", "CENTER")
    if position == "START":
        centre += 0.5 * shutter
    elif position == "END":
        centre -= 0.5 * shutter
    return centre, shutter


def _frame_set(frame_set, time: float):
    frame = math.floor(time)
    frame_set(int(frame), time - frame)


def camera_motion(scene, camera_object_at, frame_set, objects_at, reporter) -> ShutterSettings:
    """The render's motion blur: the camera's transforms at its motion steps (Cycles' relative
    times -1 .. 1 over the shutter), read by moving the frame with frame_set(frame, subframe).
    camera_object_at() and objects_at() read the evaluated camera and {name: matrix_world} of the
    scene's objects at the current time; objects that move are named in a warning. Leaves the
    frame at the centre of the shutter."""
    render = scene.render
    settings = ShutterSettings()
    if not render.use_motion_blur:
        return settings
    centre, shutter = shutter_times(scene)
    camera = camera_object_at()
    name = camera.name if camera is not None else "(none)"
    cycles = getattr(scene, "cycles", None)
    settings.shutter_curve = shutter_curve(render)
    settings.rolling_shutter = getattr(cycles, "rolling_shutter_type", "NONE") == "TOP"
    settings.rolling_shutter_duration = float(getattr(cycles, "rolling_shutter_duration", 0.1))
    if shutter <= 0.0:
        reporter.warn(f"camera '{name}': motion blur with a shutter of 0 frames blurs nothing (as Cycles)")
    steps = motion_steps(camera) if camera is not None else 0
    relative = [2.0 * k / (steps - 1) - 1.0 for k in range(steps)] if steps else [-1.0, 0.0, 1.0]
    transforms, lenses, moved = [], [], set()
    before = None
    for time in relative:
        _frame_set(frame_set, centre + time * shutter * 0.5)
        camera = camera_object_at()
        if camera is not None:
            transforms.append(np.array(camera.matrix_world, dtype=np.float64))
            if camera.type == "CAMERA":
                lenses.append((float(camera.data.lens), float(camera.data.ortho_scale)))
        current = objects_at()
        if before is not None:
            moved |= {key for key, matrix in current.items()
                      if key in before and not np.allclose(matrix, before[key], rtol=0, atol=1e-9)}
        before = current
    _frame_set(frame_set, centre)
    if steps and camera is not None:
        settings.camera_transforms = transforms
        if len(set(lenses)) > 1:
            reporter.warn(f"camera '{name}': its focal length or scale changes during the shutter; VolPath blurs "
                          "only its motion (Cycles also its zoom)")
    moved.discard(name)
    if moved:
        names = ", ".join(f"'{n}'" for n in sorted(moved)[:8]) + (", ..." if len(moved) > 8 else "")
        reporter.warn(f"motion blur: {names} move during the shutter; VolPath blurs only the camera's motion and "
                      "renders objects, lights and media where they are at the shutter centre")
    return settings
