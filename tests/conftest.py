"""Shared test set-up: the repository root on sys.path so `import addon` works (the native package
is installed editable into .venv by `make venv`)."""
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def pytest_sessionfinish(session, exitstatus):
    """Free Blender's data (fluid domains' Mantaflow runtimes) before the interpreter exits: the
    bpy wheel's Mantaflow aborts the process at exit otherwise (tests/fluid_runtime.py)."""
    if "bpy" in sys.modules:
        sys.modules["bpy"].ops.wm.read_homefile(use_empty=True)



@pytest.fixture(scope="session")
def installed_blender(tmp_path_factory):
    """(home, env): VolPath installed into $BLENDER under a temporary user home, once per session
    (tests/blender_process.py); the first render there compiles the kernels, later ones load them."""
    from blender_process import install_volpath

    return install_volpath(tmp_path_factory.mktemp("blender_home"))
