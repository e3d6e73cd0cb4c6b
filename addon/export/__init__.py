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

from . import camera as camera_export
from . import geometry, lights, shading

__all__ = ["export_scene", "export_settings"]


def export_scene(depsgraph, camera_object=None):
    """Returns (volpath_native.Scene, warnings: list[str]). camera_object overrides scene.camera
    (RenderEngine.camera_override)."""
    scene = depsgraph.scene
    reporter = shading.Reporter()
    table = shading.MaterialTable(reporter)

    camera_object = camera_object or scene.camera
    if camera_object is not None:
        camera_object = camera_object.evaluated_get(depsgraph)
    camera = camera_export.export_camera(camera_object, reporter)
    film = camera_export.export_film(scene, reporter)

    meshes, scene_lights = _export_instances(depsgraph, table, reporter)
    world = shading.export_world(scene.world, table)

    vp_scene = vp.Scene(camera=camera, film=film, meshes=meshes, materials=table.materials,
                        media=table.media, lights=scene_lights, world=world,
                        settings=export_settings(scene))
    validation_warnings = vp_scene.validate()  # raises SceneError for unusable input
    return vp_scene, reporter.messages + validation_warnings


def _export_instances(depsgraph, table: shading.MaterialTable, reporter):
    meshes: list[vp.Mesh] = []
    scene_lights = []
    triangulated: dict = {}  # evaluated mesh data -> LocalMesh (None: no triangles)
    for instance in depsgraph.object_instances:
        obj = instance.object
        if not instance.show_self:
            continue  # e.g. an instancer whose own geometry is hidden (Cycles' sync_objects does the same)
        matrix = np.array(instance.matrix_world, dtype=np.float64)
        if obj.type == "LIGHT":
            light = lights.export_light(obj, matrix, reporter)
            if light is not None:
                scene_lights.append(light)
            continue
        if obj.type not in geometry.GEOMETRY_TYPES:
            if obj.type in ("VOLUME", "CURVES", "POINTCLOUD", "GPENCIL", "GREASEPENCIL"):
                reporter.warn(f"object '{obj.name}': {obj.type} objects are not supported; ignored")
            continue
        if abs(np.linalg.det(matrix[:3, :3])) < 1e-30:
            continue  # scaled to nothing: invisible in Cycles too
        # Meshes shared by instances are triangulated once; other types have no shared data.
        key = obj.data.as_pointer() if obj.type == "MESH" and obj.data is not None else None
        if key is not None and key in triangulated:
            local = triangulated[key]
        else:
            local = geometry.triangulate(obj)
            if key is not None:
                triangulated[key] = local
        if local is None:
            continue
        slot_materials = np.array([table.index_of(slot.material) for slot in obj.material_slots]
                                  or [table.index_of(None)], dtype=np.int32)
        name = obj.name if not instance.is_instance else f"{instance.parent.name}/{obj.name}#{len(meshes)}"
        meshes.append(geometry.to_world(name, local, matrix, slot_materials))
    return meshes, scene_lights


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
        russian_roulette_min_bounces=props.min_bounces_russian_roulette,
        batch_size=props.batch_size,
        threads=props.threads,
    )
