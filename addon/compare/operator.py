"""The "Compare with Cycles" button: operator `volpath.compare_with_cycles`.

Renders the current scene with VolPath and with Cycles (matched settings, the user's settings
restored after), writes the EXRs, the sheet and the reports, and opens the sheet in an Image
Editor. The work blocks Blender while it runs, with the window manager's progress indicator.
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import bpy
from bpy.props import EnumProperty, FloatProperty, IntProperty, StringProperty

from . import cycles_engine, runner


def _output_folder(path_setting: str) -> Path:
    """'//' paths are relative to the .blend; an unsaved file writes to the temp folder."""
    if path_setting.startswith("//") and not bpy.data.filepath:
        return Path(tempfile.gettempdir()) / "volpath_compare"
    return Path(bpy.path.abspath(path_setting))


def show_image(context, path: Path):
    """Load (or reload) `path` and show it in an Image Editor: an open one, else a new window."""
    image = bpy.data.images.load(str(path), check_existing=True)
    image.reload()
    if bpy.app.background or context.window_manager is None:
        return image
    for window in context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == "IMAGE_EDITOR":
                area.spaces.active.image = image
                return image
    try:
        bpy.ops.wm.window_new()
        area = context.window_manager.windows[-1].screen.areas[0]
        area.type = "IMAGE_EDITOR"
        area.spaces.active.image = image
    except RuntimeError:
        pass  # no window could be opened: the image is still in bpy.data.images
    return image


class VOLPATH_OT_compare_with_cycles(bpy.types.Operator):
    """Render this scene with VolPath and Cycles (matched settings) and compare them"""

    bl_idname = "volpath.compare_with_cycles"
    bl_label = "Compare with Cycles"
    bl_options = {"REGISTER"}

    mode: EnumProperty(name="Mode", default="equal-samples",
                       items=[("equal-samples", "Equal Samples", "Both engines render the same samples per pixel"),
                              ("equal-time", "Equal Time", "Both engines get the same wall-clock time")])
    samples: IntProperty(name="Samples", default=64, min=2, max=1 << 16,
                         description="Equal samples: total samples per pixel per engine")
    seconds: FloatProperty(name="Seconds", default=10.0, min=0.1, max=3600.0,
                           description="Equal time: wall-clock seconds per engine")
    runs: IntProperty(name="Runs", default=8, min=2, max=64,
                      description="Independent renders per engine (their spread gives the per-pixel variance)")
    reference: StringProperty(name="Reference", subtype="FILE_PATH", default="",
                              description="Optional high-sample reference EXR (same resolution)")
    cycles_motion_as_stills: IntProperty(
        name="Cycles Motion as Stills", default=0, min=0, max=64,
        description="Equal samples: Cycles' motion blur as this many stills per run over the shutter (Cycles' own "
                    "blur of moving volumes is biased); 0 renders Cycles' motion blur")
    output: StringProperty(name="Output", subtype="DIR_PATH", default="//volpath_compare/",
                           description="Folder for the EXRs, the sheet and the reports")

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.scene.camera is not None

    def invoke(self, context, event):
        volpath = getattr(context.scene, "volpath", None)
        if volpath is not None:
            self.samples = max(int(volpath.samples), self.runs)
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context):
        scene = context.scene
        try:
            cycles_engine.require_cycles(scene)
        except cycles_engine.CyclesUnavailable as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        options = runner.CompareOptions(mode=self.mode, samples=max(self.samples, self.runs),
                                        seconds=self.seconds, runs=self.runs, seed=0,
                                        reference=bpy.path.abspath(self.reference) if self.reference else None,
                                        cycles_motion_as_stills=self.cycles_motion_as_stills)
        out_dir = _output_folder(self.output)
        wm = context.window_manager
        wm.progress_begin(0, 100)

        def progress(fraction: float, message: str) -> None:
            wm.progress_update(int(100 * fraction))
            if context.workspace is not None:
                context.workspace.status_text_set(f"Compare with Cycles: {message}")

        try:
            result = runner.compare_scene(scene, options, out_dir, progress)
        except (ValueError, RuntimeError, OSError, InterruptedError) as error:
            self.report({"ERROR"}, f"Comparison failed: {error}")
            return {"CANCELLED"}
        finally:
            wm.progress_end()
            if context.workspace is not None:
                context.workspace.status_text_set(None)
        for warning in result.warnings:
            self.report({"WARNING"}, warning)
        show_image(context, result.outputs["sheet_png"])
        ratio = " ".join(f"{r:.3f}" for r in result.comparison.means.ratio)
        self.report({"INFO"} if result.agrees else {"WARNING"},
                    f"VolPath/Cycles mean ratio {ratio}; {100 * result.comparison.pixel.fraction_passed:.1f}% "
                    f"of pixels agree; report in {out_dir}")
        return {"FINISHED"}


CLASSES = (VOLPATH_OT_compare_with_cycles,)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
