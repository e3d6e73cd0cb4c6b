"""Compiling the kernels where a cancel can reach them: in a child interpreter.

numba compiles in the calling thread and cannot be interrupted, so a first render after an install
(~100 s of compiling) could not be cancelled. `compile_in_child(cancel)` runs warm_up() in a child
Python with the same sys.path and NUMBA_CACHE_DIR, polling cancel(): on a cancel the child is
killed and waited for, so control returns at once and nothing is left running. The child writes
numba's on-disk cache; the caller then loads the kernels from it in about half a second.
`kernels_cached()` tells, without compiling anything, whether that cache (compiled here, or
shipped with the package: jit.py) holds kernels this process can load.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pickle

import numba
from numba.core import config
from numba.core.registry import cpu_target

from . import jit

_CHILD = ("import sys, volpath_native; "
          "sys.exit(3) if sys.version_info[:2] != ({major}, {minor}) else volpath_native.warm_up(thorough=True)")
# The child could not run our Python (another version, numpy or numba missing): compile in-process.
_CHILD_UNUSABLE = 3


def codegen_key() -> tuple:
    """numba's codegen.magic_tuple() in this process (target triple, CPU name, CPU features): the
    key under which it loads and saves compiled kernels. The features are fixed when the codegen
    is created; the name is read from the configuration each time (reloaded here as before a
    compile)."""
    config.reload_config()
    return tuple(cpu_target.target_context.codegen().magic_tuple())


def kernels_cached(cache_dir: str | None = None) -> bool:
    """True if numba's cache holds the path stage for this Python, numba and CPU target (the
    kernels then load in ~0.5 s); False when loading would compile."""
    folder = Path(cache_dir or jit.KERNEL_CACHE_DIR)
    if not folder.is_dir():
        return False
    python = f".py{sys.version_info[0]}{sys.version_info[1]}"
    key = codegen_key()
    for index in folder.rglob(f"path_kernels.shade-*{python}.nbi"):
        try:
            with open(index, "rb") as f:
                if pickle.load(f) != numba.__version__:
                    continue
                _, overloads = pickle.loads(f.read())
        except Exception:  # unreadable or from another numba: loading would compile
            continue
        if any(tuple(entry[1]) == key for entry in overloads):
            return True
    return False


def python_executable() -> str | None:
    """A Python interpreter for the child: sys.executable when it is one (inside Blender it is the
    bundled Python since 2.91, or the system's for a distribution build)."""
    exe = sys.executable
    if exe and Path(exe).name.lower().startswith("python") and os.access(exe, os.X_OK):
        return exe
    return None


def compile_in_child(cancel, poll: float = 0.05, env: dict | None = None):
    """Compile the kernels in a child process. Returns True when compiled, False when cancel()
    became true (the child was killed and reaped), None when no child could do it (the caller
    then compiles in-process, where a cancel cannot reach)."""
    python = python_executable()
    if python is None:
        return None
    child_env = dict(os.environ if env is None else env)
    child_env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p)
    child_env.setdefault("NUMBA_CACHE_DIR", jit.cache_root())
    code = _CHILD.format(major=sys.version_info[0], minor=sys.version_info[1])
    try:
        child = subprocess.Popen([python, "-c", code], env=child_env, stdin=subprocess.DEVNULL,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        return None
    try:
        while child.poll() is None:
            if cancel():
                child.kill()
                return False
            time.sleep(poll)
    finally:
        if child.poll() is None:
            child.kill()
        child.wait()
    return True if child.returncode == 0 else None
