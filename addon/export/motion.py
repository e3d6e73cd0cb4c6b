"""Motion blur settings as Cycles syncs them (intern/cycles/blender/sync.cpp
BlenderSync::sync_motion, blender/camera.cpp sync_camera / sync_camera_motion, blender/object.cpp
sync_object in motion passes, blender/util.h object_motion_steps): the camera's and the objects'
transforms at their motion steps over the shutter, the shutter curve and the rolling shutter.

Lights stay at the shutter centre as in Cycles. Moving volume objects (and meshes whose volume
is a shader program) are blurred by their object transform, as Cycles shades a moving volume at
the ray's time (volpath_native/medium_motion.py); velocity-based motion blur (fluid domains, a
Volume's velocity grid) stays out with a warning.
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
    object_motion: dict = field(default_factory=dict)  # instance key -> [matrix_world at its motion steps]
    vertex_motion: dict = field(default_factory=dict)  # object name -> (S, V, 3) positions at its steps


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


#: The start of the note on a moving varying medium, a known difference (README, "Where VolPath
#: knowingly differs"); the agreement tests recognise it by this text.
CYCLES_MOVING_VOLUME_NOTE = "moves over the shutter: Cycles 5.0 may render it biased"


def moving_volume_note(label: str) -> str:
    """A moving medium whose density varies: VolPath places it at each path's time (unbiased);
    Cycles 5.0 walks its majorant octree with the object's shutter-centre transform
    (kernel/integrator/shade_volume.h volume_octree_setup: object_fetch_transform, the transform at
    the frame, not the motion transform) while its shader runs at the ray's time, so at other times the majorant can sit
    below the density it bounds. Measured: Cycles' moving smoke plume 0.46 % brighter than the mean
    of its own stills over the shutter; VolPath within 0.04 % of those stills."""
    return (f"{label} {CYCLES_MOVING_VOLUME_NOTE} (its volume majorant stays where the object stands at the "
            "frame); VolPath follows the density at each ray's time. To compare with Cycles, average Cycles "
            "stills over the shutter (the comparison's 'Cycles Motion as Stills')")


def _frame_set(frame_set, time: float):
    frame = math.floor(time)
    frame_set(int(frame), time - frame)


def instance_key(instance) -> tuple:
    """Identifies a depsgraph object instance across frames (Cycles' ObjectKey: parent, persistent
    id, object), so its transform can be followed over the shutter."""
    parent = instance.parent.name if instance.is_instance and instance.parent is not None else ""
    persistent = tuple(instance.persistent_id) if instance.is_instance else ()
    return (instance.object.name, parent, persistent)


def instance_motion_steps(instance) -> int:
    """object_motion_steps of an instance, with the instancer's setting as Cycles' blender/util.h
    object_motion_steps (the parent can switch it off and raise the step count)."""
    steps = motion_steps(instance.object)
    if steps and instance.is_instance and instance.parent is not None:
        parent_steps = motion_steps(instance.parent)
        steps = max(steps, parent_steps) if parent_steps else 0
    return steps


def relative_times(steps: int) -> list[float]:
    """Cycles' motion times of an object with `steps` transforms: -1 .. 1 over the shutter."""
    return [2.0 * k / (steps - 1) - 1.0 for k in range(steps)]


def camera_motion(scene, camera_object_at, frame_set, objects_at, reporter, deformations_at=None) -> ShutterSettings:
    """The render's motion blur, read by moving the frame with frame_set(frame, subframe) to every
    time any object needs (Cycles' BlenderSync::sync_motion visits the union of its objects' motion
    times, each object keeping the steps of its own count):
    - the camera's transforms at its motion steps;
    - `object_motion`: {instance key: [4x4 matrix_world at each of its steps]} for geometry instances
      and volume objects (kind "medium") whose transform changes during the shutter (Cycles'
      Object::motion, cleared when all equal).
    - `vertex_motion`: {object name: (S, V, 3) vertex positions} of deforming meshes (Cycles'
      blender/mesh.cpp sync_mesh_motion: only objects with deforming modifiers are read, and a mesh
      whose vertex count changes during the shutter is not blurred -- warned here).
    camera_object_at() gives the evaluated camera at the current time; objects_at() gives
    {instance key: (matrix_world, motion steps, kind)} with kind "geometry", "light" or "medium";
    deformations_at() gives {object name: (motion steps, (V, 3) positions)} of deforming meshes.
    Lights that move are named in a warning: Cycles does not blur lights either (its sync skips them
    in motion passes), they stay at the shutter centre. Leaves the frame at the shutter centre."""
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
    camera_steps = motion_steps(camera) if camera is not None else 0
    at_centre = objects_at()
    step_counts = {camera_steps} | {steps for _, steps, _ in at_centre.values()}
    times = sorted({t for steps in step_counts if steps for t in relative_times(steps)} | {0.0})
    transforms, lenses = [], []
    samples = {}  # relative time -> {key: matrix}
    shapes = {}  # relative time -> {object name: (steps, positions)}
    for time in times:
        _frame_set(frame_set, centre + time * shutter * 0.5)
        if time in (relative_times(camera_steps) if camera_steps else ()):
            camera = camera_object_at()
            if camera is not None:
                transforms.append(np.array(camera.matrix_world, dtype=np.float64))
                if camera.type == "CAMERA":
                    lenses.append((float(camera.data.lens), float(camera.data.ortho_scale)))
        samples[time] = {key: matrix for key, (matrix, _, _) in objects_at().items()}
        if deformations_at is not None:
            shapes[time] = deformations_at()
    _frame_set(frame_set, centre)
    if camera_steps and camera is not None:
        settings.camera_transforms = transforms
        if len(set(lenses)) > 1:
            reporter.warn(f"camera '{name}': its focal length or scale changes during the shutter; VolPath blurs "
                          "only its motion (Cycles also its zoom)")
    moved_lights = set()
    for key, (matrix, steps, kind) in at_centre.items():
        own_times = relative_times(steps) if steps else times
        path = [samples[t].get(key) for t in own_times]
        if any(m is None for m in path) or all(np.allclose(m, path[0], rtol=0, atol=1e-9) for m in path):
            continue  # appears or vanishes during the shutter, or does not move
        if kind in ("geometry", "medium") and steps:
            if not all(np.all(np.isfinite(m)) for m in path):
                reporter.warn(f"object '{key[0]}': its transform during the shutter is not finite; rendered without "
                              "motion blur")
                continue
            settings.object_motion[key] = path
        elif kind == "light":
            moved_lights.add(key[0])
    changed_topology = set()
    for object_name, (steps, positions) in shapes.get(0.0, {}).items():
        path = [shapes[t].get(object_name, (0, None))[1] for t in relative_times(steps)]
        if any(p is None or p.shape != positions.shape for p in path):
            changed_topology.add(object_name)
        elif not all(np.array_equal(p, positions) for p in path):
            if not all(np.all(np.isfinite(p)) for p in path):
                reporter.warn(f"object '{object_name}': vertex positions during the shutter are not finite; its "
                              "deformation is not blurred")
                continue
            settings.vertex_motion[object_name] = np.stack(path)
    if changed_topology:
        reporter.warn(f"motion blur: {_names(changed_topology)} change their vertex count during the shutter; "
                      "their deformation is not blurred (as Cycles)")
    moved_lights.discard(name)
    if moved_lights:
        reporter.warn(f"motion blur: lights {_names(moved_lights)} move during the shutter; they are rendered where "
                      "they are at the shutter centre, as Cycles does (it does not blur lights)")
    return settings


def _names(names) -> str:
    names = sorted(names)
    return ", ".join(f"'{n}'" for n in names[:8]) + (", ..." if len(names) > 8 else "")
