"""VolPath's Render Properties panels, its Render button, and VolPath's entry in the COMPAT_ENGINES
of Blender's own camera / light / material / world / output panels (as Blender's add-ons and
BlendLuxCore do), removed again on unregister."""
from __future__ import annotations

import bpy

from . import compat, kernel_status

ENGINE = "VOLPATH"
COMPARE_OPERATOR = "volpath.compare_with_cycles"

# Blender panels that edit data VolPath reads. Matched by class-name prefix, among panels that
# Blender's own engines use (Cycles' panels read Cycles-only settings and stay Cycles-only).
_SHARED_PANEL_PREFIXES = (
    "DATA_PT_camera", "DATA_PT_lens", "DATA_PT_camera_display", "DATA_PT_context_camera",
    "DATA_PT_light", "DATA_PT_context_light", "DATA_PT_EEVEE_light", "DATA_PT_spot", "DATA_PT_area",
    "MATERIAL_PT_", "EEVEE_MATERIAL_PT_", "WORLD_PT_", "EEVEE_WORLD_PT_",
    "RENDER_PT_format", "RENDER_PT_frame_range", "RENDER_PT_time_stretching", "RENDER_PT_output",
    "RENDER_PT_encoding", "RENDER_PT_post_processing", "RENDER_PT_stamp", "RENDER_PT_dimensions",
    "RENDER_PT_color_management", "RENDER_PT_format_presets", "RENDER_PT_stereoscopy",
    "RENDER_PT_views",
)
# EEVEE-only settings among those (prefixes): light probes, shadow maps, material render settings.
_EEVEE_ONLY_SETTINGS = ("EEVEE_MATERIAL_PT_settings", "EEVEE_MATERIAL_PT_viewport_settings",
                        "EEVEE_MATERIAL_PT_thickness", "EEVEE_MATERIAL_PT_lightprobe",
                        "EEVEE_MATERIAL_PT_displacement", "EEVEE_WORLD_PT_settings",
                        "EEVEE_WORLD_PT_lightprobe", "EEVEE_WORLD_PT_sun", "EEVEE_WORLD_PT_mist",
                        "DATA_PT_EEVEE_light_distance", "DATA_PT_EEVEE_shadow",
                        "DATA_PT_EEVEE_light_shadow", "DATA_PT_EEVEE_light_influence",
                        "DATA_PT_lightprobe", "DATA_PT_context_lightprobe", "MATERIAL_PT_freestyle",
                        "RENDER_PT_stereoscopy", "DATA_PT_camera_stereoscopy",
                        "MATERIAL_PT_preview", "MATERIAL_PT_gpencil")  # no previews, no grease pencil

_added_to: list = []


def _all_panels():
    seen, stack = set(), list(bpy.types.Panel.__subclasses__())
    while stack:
        panel = stack.pop()
        if panel not in seen:
            seen.add(panel)
            stack.extend(panel.__subclasses__())
    return seen


def _shared_panels():
    for panel in _all_panels():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        name = panel.__name__
        if not isinstance(engines, set) or not engines & compat.BLENDER_ENGINE_IDS:
            continue
        if name.startswith(_SHARED_PANEL_PREFIXES) and not name.startswith(_EEVEE_ONLY_SETTINGS):
            yield panel


def operator_available(idname: str) -> bool:
    """Whether an operator (e.g. a colleague's optional one) is registered."""
    module, name = idname.split(".")
    try:
        getattr(getattr(bpy.ops, module), name).get_rna_type()
    except (AttributeError, KeyError):
        return False
    return True


class VolpathPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class VOLPATH_PT_render(VolpathPanel, bpy.types.Panel):
    bl_label = "VolPath"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.volpath
        row = layout.row(align=True)
        row.scale_y = 1.4
        row.operator(VOLPATH_OT_render.bl_idname, icon="RENDER_STILL")
        if operator_available(COMPARE_OPERATOR):
            row.operator(COMPARE_OPERATOR, icon="IMAGE_REFERENCE")
        status = kernel_status.status_line()
        if status is not None and status[1] != "CHECKMARK":  # say nothing once they are ready
            layout.label(text=status[0], icon=status[1])
        col = layout.column(align=True)
        col.prop(settings, "samples")
        col.prop(settings, "time_limit")
        col.prop(settings, "seed")
        col.prop(settings, "use_animated_seed")
        layout.prop(settings, "use_light_tree")


class VOLPATH_PT_light_paths(VolpathPanel, bpy.types.Panel):
    bl_label = "Light Paths"
    bl_parent_id = "VOLPATH_PT_render"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.volpath
        col = layout.column(align=True)
        for name in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces",
                     "volume_bounces", "transparent_bounces"):
            col.prop(settings, name)
        layout.prop(settings, "min_bounces_russian_roulette")


class VOLPATH_PT_volumes(VolpathPanel, bpy.types.Panel):
    bl_label = "Volumes"
    bl_parent_id = "VOLPATH_PT_render"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(context.scene.volpath, "volume_sampling")


class VOLPATH_PT_performance(VolpathPanel, bpy.types.Panel):
    bl_label = "Performance"
    bl_parent_id = "VOLPATH_PT_render"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.volpath
        layout.prop(settings, "threads")
        layout.prop(settings, "batch_size")


class VOLPATH_OT_render(bpy.types.Operator):
    """Render the current frame with VolPath into the Render Result (F12)"""

    bl_idname = "volpath.render"
    bl_label = "Render"

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def execute(self, context):
        if context.scene.render.engine != ENGINE:
            context.scene.render.engine = ENGINE
        return bpy.ops.render.render("INVOKE_DEFAULT")


CLASSES = (VOLPATH_OT_render, VOLPATH_PT_render, VOLPATH_PT_light_paths, VOLPATH_PT_volumes,
           VOLPATH_PT_performance)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    for panel in _shared_panels():
        if ENGINE not in panel.COMPAT_ENGINES:
            panel.COMPAT_ENGINES.add(ENGINE)
            _added_to.append(panel)


def unregister():
    while _added_to:
        _added_to.pop().COMPAT_ENGINES.discard(ENGINE)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
