"""Fixtures for the add-on tests: Blender (the bpy module) with VolPath registered and a fresh
small scene per test (builders in addon_scenes.py)."""
from __future__ import annotations

import pytest

bpy = pytest.importorskip("bpy")

import addon  # noqa: E402  (tests/conftest.py puts the repository root on sys.path)
from addon_scenes import add_camera  # noqa: E402


@pytest.fixture(scope="session", autouse=True)
def volpath_registered():
    addon.register()
    yield
    # left registered: other test packages in the same process may use the engine too


@pytest.fixture
def scene(volpath_registered):
    """An empty scene rendered by VolPath at 24x24, camera at (0, -6, 0) looking along +Y."""
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "VOLPATH"
    sc.render.resolution_x = sc.render.resolution_y = 24
    sc.render.resolution_percentage = 100
    sc.volpath.samples = 4
    sc.volpath.seed = 7
    add_camera(sc)
    sc.world = None
    return sc
