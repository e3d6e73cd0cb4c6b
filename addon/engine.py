"""The VolPath render engine: F12 / `blender -b -E VOLPATH` export the evaluated scene and render
it progressively into Blender's Render Result.

Runs on Blender's render thread: no bpy.context here, only the depsgraph it is given.
"""
from __future__ import annotations

import time
import traceback

import bpy
import numpy as np

from . import compat, kernel_status


_kernels_ready = False  # volpath_native.warm_up() has run in this Blender session


class VolpathRenderEngine(bpy.types.RenderEngine):
    bl_idname = "VOLPATH"
    bl_label = "VolPath"
    bl_use_preview = False  # no material previews: those stay with EEVEE
    bl_use_postprocess = True  # compositing and sequencer still apply
    bl_use_eevee_viewport = True  # Material Preview in the viewport uses EEVEE, not us
    bl_use_shading_nodes_custom = False  # Blender's own shader nodes are our materials

    def render(self, depsgraph):
        compat.isolate_embree()
        try:
            import volpath_native as vp
            from volpath_native.render import render as render_scene
        except ImportError as error:  # e.g. the extension's wheels did not install
            self._fail(f"VolPath's renderer could not be loaded ({error}); reinstall the add-on")
            return
        from .export import ExportCancelled, export_scene

        if not self._prepare_kernels(vp):
            return
        started = time.perf_counter()
        try:
            scene, warnings = export_scene(depsgraph, camera_object=self.camera_override, cancel=self.cancel_requested,
                                           frame_set=lambda frame, subframe: self.frame_set(frame, subframe=subframe))
            _, _, width, height = _crop_window(scene.film)
        except ExportCancelled:
            self.update_stats("", "VolPath | cancelled while exporting")
            return
        except vp.SceneError as error:
            for message in getattr(error, "warnings", []):  # the scene's other problems, also named
                self.report({"WARNING"}, message)
            self._fail(str(error))
            return
        except Exception as error:  # an exporter bug must not take Blender down
            traceback.print_exc()
            self._fail(f"VolPath could not export the scene: {type(error).__name__}: {error}")
            return
        for message in warnings:
            self.report({"WARNING"}, message)
        if scene.images:  # texture memory, counted once per image (shading/images.py)
            self.report({"INFO"}, f"VolPath: {len(scene.images)} image textures, "
                                  f"{sum(image.nbytes for image in scene.images) / 2 ** 20:.1f} MiB")
        export_seconds = time.perf_counter() - started

        layer_name = depsgraph.view_layer.name
        _free_blender_memory(self, depsgraph)  # the depsgraph is gone after this
        del depsgraph
        # The Render Result covers the border region only (Blender crops it itself); its rows run
        # bottom-up.
        result = self.begin_result(0, 0, width, height, layer=layer_name)
        total = scene.settings.samples
        self.update_stats("", f"VolPath | exported in {export_seconds:.2f} s | rendering")

        time_limit = scene.settings.time_limit

        def progress(done, samples_total, stats):
            fraction = done / max(samples_total, 1)
            if time_limit > 0.0:  # whichever of the two ends the render first
                fraction = max(fraction, stats.get("seconds", 0.0) / time_limit)
            self.update_progress(min(fraction, 1.0))
            rays = stats.get("rays_per_second", 0.0)
            self.update_stats("", f"VolPath | Sample {done}/{samples_total} | "
                                  f"{stats.get('seconds', 0.0):.1f} s | {rays / 1e6:.2f} M rays/s")

        def partial(image):
            if not _write_combined(result, image):
                self._report_size_mismatch(image, result)
            self.update_result(result)

        try:
            output = render_scene(scene, progress=progress, cancel=self.cancel_requested, partial=partial)
        except vp.SceneError as error:
            self.end_result(result)
            self._fail(str(error))
            return
        except Exception as error:
            traceback.print_exc()
            self.end_result(result)
            self._fail(f"VolPath failed while rendering: {type(error).__name__}: {error}")
            return
        for message in output.warnings:
            if message not in warnings:
                self.report({"WARNING"}, message)
        if not _write_combined(result, output.image):
            self._report_size_mismatch(output.image, result)
        self.end_result(result)
        done = "cancelled" if output.cancelled else "done"
        self.update_stats("", f"VolPath | {done}: {output.samples}/{total} samples in {output.seconds:.1f} s")

    def _prepare_kernels(self, vp) -> bool:
        """Compile the renderer's numba kernels, or load them from numba's on-disk cache, once per
        Blender session and before the render clock starts. Compiling after an install takes tens
        of seconds, hence the status text. Returns False if cancelled or (error reported) failed."""
        global _kernels_ready
        if _kernels_ready:
            return True
        from volpath_native import kernel_compile

        if kernel_status.busy():
            # enabling the add-on started the compile (kernel_status): wait for it; Esc stops
            # waiting, not the compile
            def waiting(seconds):
                self.update_stats("", f"VolPath | Compiling render kernels in the background "
                                      f"({int(seconds)} s so far; Esc cancels the render)")
            if not kernel_status.wait(self.cancel_requested, on_wait=waiting):
                self.update_stats("", "VolPath | cancelled while the render kernels compile")
                return False
        if not kernel_compile.kernels_cached():
            # Compiling takes minutes and numba cannot be interrupted: compile in a child process
            # that Esc can kill (kernel_compile); then load what it cached.
            self.update_stats("", "VolPath | Compiling render kernels (first render only; Esc cancels)")
            if kernel_compile.compile_in_child(self.cancel_requested) is False:
                self.update_stats("", "VolPath | cancelled while compiling the render kernels")
                return False
        self.update_stats("", "VolPath | Loading render kernels")
        try:
            vp.warm_up()
        except Exception as error:
            traceback.print_exc()
            self._fail(f"VolPath could not compile its render kernels: {type(error).__name__}: {error}")
            return False
        _kernels_ready = True
        return True

    def cancel_requested(self) -> bool:
        """Esc in Blender (polled by the renderer several times a second)."""
        return self.test_break()

    def _report_size_mismatch(self, image, result):
        if not getattr(self, "_size_reported", False):
            self._size_reported = True
            self.report({"WARNING"}, f"VolPath rendered {image.shape[1]}x{image.shape[0]} pixels for a "
                                     f"{result.resolution_x}x{result.resolution_y} result; image cropped/padded")

    def _fail(self, message: str):
        self.report({"ERROR"}, message)
        self.error_set(message)


def _free_blender_memory(engine, depsgraph):
    """Everything is exported: let Blender free the render's evaluated scene (its modifier
    results, often the largest part of a big mesh's memory) as Cycles does in background renders
    of a single view (blender/session.cpp, BlenderSession::render -> free_blender_memory_if_possible;
    Blender keeps it with Persistent Data). Interactive renders keep it, as Cycles."""
    render = depsgraph.scene.render
    if bpy.app.background and not render.use_multiview and hasattr(engine, "free_blender_memory"):
        engine.free_blender_memory()


def _crop_window(film):
    """(x0, y0 from the top, width, height) of the rendered region, as the renderer computes it."""
    from volpath_native.camera import crop_window

    return crop_window(film)


def _write_combined(result, image: np.ndarray) -> bool:
    """Put an (H, W, 4) top-down RGBA image into the result's Combined pass (bottom-up rows).
    Returns False (after writing the overlap) if the sizes disagree, which would be a bug."""
    combined = result.layers[0].passes["Combined"]
    height, width = result.resolution_y, result.resolution_x
    pixels = np.zeros((height, width, 4), dtype=np.float32)
    h, w = min(height, image.shape[0]), min(width, image.shape[1])
    pixels[:h, :w] = image[:h, :w, :4]
    compat.set_pass_pixels(combined, pixels[::-1].reshape(-1, 4))
    return image.shape[:2] == (height, width)


CLASSES = (VolpathRenderEngine,)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
