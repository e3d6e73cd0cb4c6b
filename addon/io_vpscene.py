"""File > Export > VolPath Scene (.vpscene): the exported scene, renderable without Blender by
`python -m volpath_native render SCENE.vpscene -o out.exr` (format: volpath_native/scene_io.py)."""
from __future__ import annotations

import bpy
from bpy.props import StringProperty
from bpy_extras.io_utils import ExportHelper


class VOLPATH_OT_export_scene(bpy.types.Operator, ExportHelper):
    """Export the scene as VolPath sees it (evaluated geometry, materials, lights, camera, settings)"""

    bl_idname = "volpath.export_scene"
    bl_label = "Export VolPath Scene"
    filename_ext = ".vpscene"
    filter_glob: StringProperty(default="*.vpscene", options={"HIDDEN"})

    def execute(self, context):
        import volpath_native as vp

        from .export import export_scene

        try:
            scene, warnings = export_scene(context.evaluated_depsgraph_get())
            vp.save_scene(scene, self.filepath)
        except vp.SceneError as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        except OSError as error:
            self.report({"ERROR"}, f"cannot write {self.filepath}: {error}")
            return {"CANCELLED"}
        for message in warnings:
            self.report({"WARNING"}, message)
        self.report({"INFO"}, f"VolPath scene written to {self.filepath}")
        return {"FINISHED"}


def _menu_entry(self, context):
    self.layout.operator(VOLPATH_OT_export_scene.bl_idname, text="VolPath Scene (.vpscene)")


def register():
    bpy.utils.register_class(VOLPATH_OT_export_scene)
    bpy.types.TOPBAR_MT_file_export.append(_menu_entry)


def unregister():
    bpy.types.TOPBAR_MT_file_export.remove(_menu_entry)
    bpy.utils.unregister_class(VOLPATH_OT_export_scene)
