"""A real Blender executable for the `blender --background` tests (Debian's 3.4 in CI, or $BLENDER)."""
import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BLENDER = os.environ.get("BLENDER") or shutil.which("blender") or "/usr/bin/blender"


def run_blender(cmd, env, timeout=600):
    """Run a command (Blender or make); fail with its output's tail, else return its stdout.
    (A fresh install compiles every numba kernel on the first render: ~100 s on 2 loaded cores.)"""
    proc = subprocess.run([str(c) for c in cmd], env=env, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, f"{cmd}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc.stdout


def install_volpath(home: Path):
    """(home, env): VolPath installed into $BLENDER with `make install-blender`, in a temporary
    user config (HOME, BLENDER_USER_CONFIG, BLENDER_USER_SCRIPTS), never the real user's."""
    if not Path(BLENDER).exists():
        pytest.skip("no Blender executable (set $BLENDER)")
    from volpath_native.jit import cache_root

    # the build reuses the kernels this test session compiled: their cache folder is named before
    # HOME moves (else the build compiles every kernel again, ~10 min on CI's 2 cores)
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_root(), HOME=str(home),
               BLENDER_USER_CONFIG=str(home / "config"), BLENDER_USER_SCRIPTS=str(home / "scripts"))
    env.pop("PYTHONPATH", None)
    # Blender starts as a fresh install: its kernel cache in the add-on's per-user folder, the CPU
    # target its own choice; a cold build (kernels not compiled yet) may take minutes
    run_blender(["make", "-s", "-C", ROOT, "install-blender", f"BLENDER={BLENDER}"], env, timeout=1500)
    for variable in ("NUMBA_CACHE_DIR", "NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES"):
        env.pop(variable, None)
    return home, env
