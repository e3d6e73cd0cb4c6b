"""Fixtures for the comparison tests: the add-on registered in this bpy session."""
import pytest


def pytest_configure(config):
    config.addinivalue_line("markers", "agreement: VolPath vs Cycles statistical agreement on an example scene")


@pytest.fixture(scope="session")
def registered_addon():
    bpy = pytest.importorskip("bpy")
    import addon

    addon.register()
    from addon.compare import cycles_engine

    if not cycles_engine.cycles_available():
        pytest.skip("Cycles is not available in this bpy build")
    return bpy
