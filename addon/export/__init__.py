"""Blender scene -> volpath_native.Scene.

    scene, warnings = export_scene(depsgraph)

reads the evaluated depsgraph (modifiers, instancing and geometry-nodes instances applied), never
bpy.context, so it runs inside RenderEngine.render and from scripts alike. Unusable input raises
volpath_native.SceneError with a message for the user; input rendered with a documented fallback
is listed in `warnings` (the scene's own validate() warnings included).
"""
from __future__ import annotations

import numpy as np

import volpath_native as vp

from .. import compat
from . import camera as camera_export
from . import fluid, geometry, grid_media, instancing, lights, motion, procedural_media, shading, validate

__all__ = ["export_scene", "export_settings", "ExportCancelled"]


def export_scene(depsgraph, camera_object=None, cancel=None, frame_set=None):
    """Returns (volpath_native.Scene, warnings: list[str]). camera_object overrides scene.camera
    (RenderEngine.camera_override). cancel() is polled between objects: ExportCancelled when true.
    A SceneError carries the warnings collected before it in `error.warnings`.
    With motion blur on, the camera is read at the shutter's times by moving the frame with
    frame_set(frame, subframe) (RenderEngine.frame_set inside a render; default: the scene's
    frame_set, which re-evaluates the view layer's depsgraph); the frame comes back afterwards."""
    reporter = shading.Reporter()
    scene = depsgraph.scene
    if frame_set is None:
        def frame_set(frame, subframe):
            scene.frame_set(frame, subframe=subframe)
    original_frame = (scene.frame_current, float(scene.frame_subframe))
    try:
        # Invalid numbers are named and replaced by the exporter itself (export/validate.py):
        # numpy's own floating-point warnings would only repeat them, unnamed.
        with np.errstate(all="ignore"):
            vp_scene = _export(depsgraph, camera_object, reporter, cancel, frame_set)
            validation_warnings = vp_scene.validate()  # raises SceneError for unusable input
    except vp.SceneError as error:
        error.warnings = list(reporter.messages)  # what else was wrong, for the user to see too
        raise
    finally:
        if scene.render.use_motion_blur and (scene.frame_current, float(scene.frame_subframe)) != original_frame:
            frame_set(*original_frame)
    return vp_scene, reporter.messages + validation_warnings


class ExportCancelled(Exception):
    """cancel() became true during the export."""


def _export(depsgraph, camera_object, reporter, cancel, frame_set):
    scene = depsgraph.scene
    table = shading.MaterialTable(reporter)

    camera_object = camera_object or scene.camera

    def camera_now():
        return camera_object.evaluated_get(depsgraph) if camera_object is not None else None

    def objects_now():
        return _instance_transforms(depsgraph)
    # Motion blur first: it moves the frame, and leaves it at the shutter's centre for the rest.
    shutter = motion.camera_motion(scene, camera_now, frame_set, objects_now, reporter,
                                   lambda: _deforming_positions(depsgraph))
    evaluated_camera = camera_now()
    if evaluated_camera is not None and evaluated_camera.type == "CAMERA":
        validate.check_camera(evaluated_camera)
        for k, matrix in enumerate(shutter.camera_transforms):
            if not np.all(np.isfinite(matrix)):
                raise vp.SceneError(f"camera '{evaluated_camera.name}': its transform at motion step {k} is not finite")
    camera = camera_export.export_camera(evaluated_camera, reporter, shutter.camera_transforms)
    camera.shutter_curve = shutter.shutter_curve
    camera.rolling_shutter = shutter.rolling_shutter
    camera.rolling_shutter_duration = shutter.rolling_shutter_duration
    film = camera_export.export_film(scene, reporter)

    meshes, scene_lights, grid_sources = _export_instances(depsgraph, table, reporter, cancel, shutter.object_motion,
                                                           shutter.vertex_motion)
    if grid_sources:
        meshes += _export_grid_media(depsgraph, grid_sources, table, reporter, shutter.object_motion)
    validate.close_volume_boundaries(meshes, table.materials, reporter)
    world_datablock = compat.render_world(depsgraph.view_layer, scene)
    world = validate.world_background(shading.export_world(world_datablock, table), world_datablock, reporter)
    if table.procedural.world_program is not None:  # a varying world volume, boxed around the scene
        anchors = [camera.camera_to_world[:3, 3]] + [getattr(light, "position", np.zeros(3)) for light in scene_lights]
        meshes += procedural_media.world_medium_box(table.procedural, meshes, anchors, world_datablock.name_full)

    return vp.Scene(camera=camera, film=film, meshes=meshes, materials=table.materials,
                    media=table.media, lights=scene_lights, world=world, settings=export_settings(scene),
                    images=table.images.images)


def _instance_transforms(depsgraph) -> dict:
    """{instance key: (matrix_world, motion steps, kind)} of the instances motion blur follows."""
    out = {}
    for instance in depsgraph.object_instances:
        obj = instance.object
        if not instance.show_self or obj.type == "CAMERA":
            continue
        if obj.type == "LIGHT":
            kind = "light"
        elif obj.type == "VOLUME" or fluid.is_fluid_domain(obj):
            kind = "medium"
        elif obj.type in geometry.GEOMETRY_TYPES:
            kind = "geometry"
        else:
            continue
        out[motion.instance_key(instance)] = (np.array(instance.matrix_world, dtype=np.float64),
                                              motion.instance_motion_steps(instance), kind)
    return out


def _deforming_positions(depsgraph) -> dict:
    """{object name: (motion steps, (V, 3) positions)} of meshes whose modifiers deform them (Cycles'
    blender/mesh.cpp sync_mesh_motion reads only those) with deformation blur on (Object > Motion
    Blur > Deformation, blender/util.h object_use_deform_motion)."""
    scene = depsgraph.scene
    out = {}
    for obj in depsgraph.objects:
        if obj.type != "MESH" or not getattr(getattr(obj, "cycles", None), "use_deform_motion", True):
            continue
        steps = motion.motion_steps(obj)
        if not steps or not obj.original.is_deform_modified(scene, "RENDER"):
            continue
        mesh = obj.to_mesh()
        try:
            out[obj.name] = (steps, compat.mesh_positions(mesh).copy()) if mesh is not None else (steps, None)
        finally:
            obj.to_mesh_clear()
    return out


def _export_instances(depsgraph, table: shading.MaterialTable, reporter, cancel=None, object_motion=None,
                      object_deformation=None):
    object_motion = object_motion or {}
    object_deformation = object_deformation or {}
    scene_lights = []
    triangulated: dict = {}  # evaluated mesh data -> LocalMesh (None: no triangles)
    grid_sources = set()  # "volume" / "fluid": grid media exported by _export_grid_media
    material_override = depsgraph.view_layer.material_override
    groups = instancing.InstanceGroups(validate.MemoryBudget())
    for instance in depsgraph.object_instances:
        if cancel is not None and cancel():
            raise ExportCancelled()
        obj = instance.object
        if instance.show_particles and any(system.settings.type == "HAIR" for system in obj.particle_systems):
            reporter.warn(f"object '{obj.name}': hair particles are not supported; not rendered")
        if not instance.show_self:
            continue  # e.g. an instancer whose own geometry is hidden (Cycles' sync_objects does the same)
        matrix = np.array(instance.matrix_world, dtype=np.float64)
        _warn_unsupported_visibility(obj, reporter)
        if obj.type in ("LIGHT", "VOLUME") or obj.type in geometry.GEOMETRY_TYPES:
            if not validate.finite_transform(obj, matrix, reporter):
                continue
        if obj.type == "LIGHT":
            light = validate.checked_light(lambda: lights.export_light(obj, matrix, reporter), obj, reporter)
            if light is not None:
                scene_lights.append(light)
            continue
        if obj.type == "VOLUME":
            grid_sources.add("volume")
            continue
        if fluid.is_fluid_domain(obj):  # a volume in Cycles (blender/geometry.cpp): its box is not drawn
            grid_sources.add("fluid")
            continue
        if obj.type not in geometry.GEOMETRY_TYPES:
            if obj.type in ("CURVES", "POINTCLOUD", "GPENCIL", "GREASEPENCIL"):
                reporter.warn(f"object '{obj.name}': {obj.type} objects are not supported; ignored")
            continue
        if abs(np.linalg.det(matrix[:3, :3])) < 1e-30:
            continue  # scaled to nothing: invisible in Cycles too
        if material_override is not None:  # View Layer > Override > Material replaces every slot
            slot_materials = np.array([table.index_of(material_override)], dtype=np.int32)
        else:
            slot_materials = np.array([table.index_of(slot.material) for slot in obj.material_slots]
                                      or [table.index_of(None)], dtype=np.int32)
        # per-corner attributes (UV maps, colours, tangents) the slots' surface programs read
        requests = frozenset().union(*[table.corner_requests.get(int(m), ()) for m in slot_materials])
        # Meshes shared by instances are triangulated once; other types have no shared data.
        key = obj.data.as_pointer() if obj.type == "MESH" and obj.data is not None else None
        if key is not None and (key, requests) in triangulated:
            local = triangulated[(key, requests)]
        else:
            local = geometry.triangulate(obj, requests, reporter)
            if key is not None:
                triangulated[(key, requests)] = local
        if local is None:
            continue
        if instance.is_instance:
            parent = instance.parent.name if instance.parent is not None else "instance"
            name = f"{parent}/{obj.name}#{groups.instance_count}"
        else:
            name = obj.name
        path = object_motion.get(motion.instance_key(instance))
        deformation = object_deformation.get(obj.name) if not instance.is_instance else None
        if deformation is not None and deformation.shape[1] != len(local.vertices):
            deformation = None  # read from another evaluation (e.g. a different modifier stack): not blurred
        # a varying volume moves with its object (its medium placed at each path's time)
        bound = table.procedural.bind(slot_materials, obj, name, matrix, local.vertices, path, deformation)
        groups.add(None if key is None else (key, requests), name, obj.name, local, bound, matrix, path,
                   deformation)
    return groups.meshes(reporter), scene_lights, grid_sources
    return meshes, scene_lights, grid_sources


# Object > Visibility > Ray Visibility flags VolPath cannot honour (camera is honoured for lights).
_RAY_VISIBILITY = (("visible_diffuse", "Diffuse"), ("visible_volume_scatter", "Volume Scatter"),
                   ("visible_shadow", "Shadow"))


def _warn_unsupported_visibility(obj, reporter):
    flags = list(_RAY_VISIBILITY) + ([] if obj.type == "LIGHT" else [("visible_camera", "Camera")])
    hidden = [label for prop, label in flags if not getattr(obj, prop)]
    if hidden:
        reporter.warn(f"object '{obj.name}': ray visibility off for {', '.join(hidden)} is not "
                      "supported by VolPath; rendered as visible")
    if obj.type == "LIGHT":
        return  # Blender flags lights as shadow catchers by default; it means nothing for them
    for prop, label in (("is_holdout", "holdout"), ("is_shadow_catcher", "shadow catcher")):
        if getattr(obj, prop):
            reporter.warn(f"object '{obj.name}': {label} is not supported; rendered as a normal object")


def _export_grid_media(depsgraph, sources: set, table: shading.MaterialTable, reporter, object_motion=None) -> list:
    """Volume objects (OpenVDB grids, addon/export_volume_grids.py) and fluid gas domains
    (addon/export/fluid.py) -> grid media through one converter (grid_media.py), each inside its
    padded bounding box, an invisible boundary mesh (as Cycles' volume bounds mesh). Those that
    move over the shutter (object_motion, by instance key) move with their box."""
    object_motion = object_motion or {}
    messages: list[str] = []
    meshes = []
    exported = []
    if "volume" in sources:
        from .. import export_volume_grids as volume_grids  # reads grids with Blender's openvdb

        try:
            exported += volume_grids.export_volume_objects(depsgraph, messages)
        except volume_grids.OpenVDBUnavailable as error:
            reporter.warn(f"Volume objects are skipped: {error}")
    if "fluid" in sources:
        exported += fluid.export_fluid_domains(depsgraph, messages)
    for volume in exported:
        material = f"material '{volume.material.name}'" if volume.material is not None else "no material"
        problems, notes = validate.volume_material_problems(volume.material)
        if problems:  # Volume objects read their material's sockets themselves: checked here
            messages.append(f"volume '{volume.object_name}' ({material}): {'; '.join(problems)}; "
                            "the object is not rendered")
            continue
        for note in notes:
            messages.append(f"volume '{volume.object_name}' ({material}): {note}; rendered as that number")
        try:
            medium = grid_media.grid_medium_from_volume(volume, messages)
        except vp.SceneError as error:
            messages.append(f"volume '{volume.object_name}' ({material}): {error}; the object is not rendered")
            continue
        if medium is None:
            continue
        path = object_motion.get(volume.instance_key)
        if path is not None:
            try:
                medium.set_motion(path, volume.object_to_world)
                messages.append(motion.moving_volume_note(f"volume '{volume.object_name}'"))
            except vp.SceneError as error:  # e.g. scaled to nothing at a step
                messages.append(f"{error}; rendered where it is at the shutter centre")
        table.media.append(medium)
        table.materials.append(vp.Material(name=f"{volume.object_name} (volume bounds)", surface="null",
                                           base_color=np.zeros(3), medium=len(table.media) - 1))
        meshes.append(medium.boundary_mesh(len(table.materials) - 1))
    for message in messages:
        reporter.warn(message)
    return meshes


def export_settings(scene) -> vp.RenderSettings:
    """scene.volpath -> RenderSettings (defaults when the add-on's properties are not registered)."""
    props = getattr(scene, "volpath", None)
    if props is None:
        return vp.RenderSettings()
    seed = props.seed + (scene.frame_current if props.use_animated_seed else 0)
    return vp.RenderSettings(
        samples=props.samples,
        seed=seed,
        max_bounces=props.max_bounces,
        diffuse_bounces=props.diffuse_bounces,
        glossy_bounces=props.glossy_bounces,
        transmission_bounces=props.transmission_bounces,
        volume_bounces=props.volume_bounces,
        transparent_bounces=props.transparent_bounces,
        volume_sampling=props.volume_sampling.lower(),
        light_tree=bool(getattr(props, "use_light_tree", True)),
        russian_roulette_min_bounces=props.min_bounces_russian_roulette,
        batch_size=props.batch_size,
        threads=props.threads,
        time_limit=float(getattr(props, "time_limit", 0.0)),
    )
