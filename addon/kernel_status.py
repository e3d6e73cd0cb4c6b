"""The render kernels in this Blender session: compiled in the background as soon as the add-on is
enabled when no cache can serve them, and their state for the render panel and the engine.

The kernels usually come compiled with the add-on (`make extension` ships numba's cache for a
portable CPU target: volpath_native/jit.py) and load in about a second. When that cache cannot
serve this machine (another numba or Python, NUMBA_CPU_NAME set by the user), compiling takes
minutes: rather than on the first F12, it starts in a child process when the add-on is enabled
(volpath_native.kernel_compile), the panel shows how long it has been running, and a render
started meanwhile waits for it (Esc stops the wait, not the compile). Disabling the add-on stops
the child. Not started in background sessions (blender -b: a render compiles in its own child,
and scripts that do not render must not leave a compiler running), unless
VOLPATH_COMPILE_ON_ENABLE=1.
"""
from __future__ import annotations

import os
import threading
import time

import bpy

CHECKING, COMPILING, READY, FAILED, STOPPED = "checking", "compiling", "ready", "failed", "stopped"


class _Job:
    def __init__(self):
        self.phase = CHECKING
        self.started = time.monotonic()
        self.finished = None
        self.message = ""
        self.stop = False
        self.thread = None


_job: _Job | None = None
_lock = threading.Lock()


def compile_on_enable() -> bool:
    """Whether enabling the add-on starts the background check/compile (see the module doc)."""
    return not bpy.app.background or os.environ.get("VOLPATH_COMPILE_ON_ENABLE") == "1"


def start() -> bool:
    """Check the kernel cache and, if it cannot serve, compile in a child process; in a thread, so
    Blender stays responsive. Returns False if a job is already running."""
    global _job
    with _lock:
        if _job is not None and _job.thread.is_alive():
            return False
        job = _job = _Job()
        job.thread = threading.Thread(target=_run, args=(job,), name="VolPath kernel compile", daemon=True)
        job.thread.start()
    if not bpy.app.background:
        bpy.app.timers.register(_redraw_while_busy, first_interval=1.0)
    return True


def _run(job: _Job):
    try:
        from volpath_native import kernel_compile

        if kernel_compile.kernels_cached():
            job.phase = READY
            return
        job.phase = COMPILING
        outcome = kernel_compile.compile_in_child(lambda: job.stop)
        if outcome is True:
            job.phase = READY
        elif outcome is False:
            job.phase = STOPPED
        else:  # no usable child Python: the first render compiles in-process instead
            job.phase, job.message = FAILED, "no Python interpreter to compile in; the first render compiles"
    except Exception as error:  # e.g. the renderer did not import: the render reports it properly
        job.phase, job.message = FAILED, f"{type(error).__name__}: {error}"
    finally:
        job.finished = time.monotonic()


def stop():
    """Stop a running background compile (kills its child) and wait for the thread."""
    job = _job
    if job is not None and job.thread.is_alive():
        job.stop = True
        job.thread.join(timeout=10.0)


def phase() -> str | None:
    """None (never started), or CHECKING / COMPILING / READY / FAILED / STOPPED."""
    return None if _job is None else _job.phase


def busy() -> bool:
    return _job is not None and _job.thread.is_alive()


def wait(cancel, on_wait=None, poll: float = 0.1) -> bool:
    """Wait for a running background job. Returns False if cancel() became true first (the job
    goes on), True otherwise (finished, or none running). on_wait(seconds_running) is called
    once per second while waiting."""
    job = _job
    last = 0.0
    while job is not None and job.thread.is_alive():
        if cancel():
            return False
        now = time.monotonic()
        if on_wait is not None and now - last >= 1.0:
            last = now
            on_wait(now - job.started)
        job.thread.join(timeout=poll)
    return True


def status_line() -> tuple[str, str] | None:
    """(text, icon) for the render panel, or None when there is nothing to say."""
    job = _job
    if job is None:
        return None
    if job.phase == COMPILING:
        seconds = int(time.monotonic() - job.started)
        return (f"Compiling render kernels in the background ({seconds // 60}:{seconds % 60:02d}, "
                "usually 2-5 min)", "SORTTIME")
    if job.phase == CHECKING:
        return ("Checking the render kernels", "SORTTIME")
    if job.phase == READY:
        return ("Render kernels ready", "CHECKMARK")
    if job.phase == FAILED:
        return (f"Render kernels not compiled in the background: {job.message}", "ERROR")
    return ("Render kernel compile stopped; the first render compiles", "INFO")


def _redraw_while_busy():
    """Timer: redraw the Properties editors once a second while a job runs, once more at the end."""
    try:
        for window in bpy.context.window_manager.windows:
            for area in window.screen.areas:
                if area.type == "PROPERTIES":
                    area.tag_redraw()
    except (AttributeError, ReferenceError):
        pass
    return 1.0 if busy() else None


def register():
    if compile_on_enable():
        start()


def unregister():
    stop()
    if bpy.app.timers.is_registered(_redraw_while_busy):
        bpy.app.timers.unregister(_redraw_while_busy)
