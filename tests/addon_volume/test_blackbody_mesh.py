"""Blackbody emission of homogeneous (mesh) volumes: the Principled Volume's constant Temperature
and Blackbody Intensity, exported and checked against Cycles (kernel/svm/closure.h)."""
import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from examples import scene_builder as sb  # noqa: E402
from volpath_native.grid_medium import BLACKBODY_SIGMA, blackbody_emission, blackbody_rec709  # noqa: E402

# (Temperature K, Blackbody Intensity, tint, Emission Strength): table branches, T < 800 K, T >= 12000 K,
# intensity < 1 (mix(1, T^4, b)), a tint, and plain emission added on top.
CASES = [(700.0, 1.0, (1, 1, 1), 0.0), (1300.0, 1.0, (1, 1, 1), 0.0), (2500.0, 0.5, (1, 0.5, 0.25), 0.0),
         (4000.0, 1.0, (1, 1, 1), 0.7), (13000.0, 1.0, (0.1, 0.1, 0.1), 0.0)]


@pytest.fixture(scope="module")
def registered_addon():
    import addon

    if not hasattr(bpy.types.Scene, "volpath"):  # another test package may have registered it
        addon.register()
    return bpy


def test_blackbody_formula():
    t = np.array([650.0, 3000.0, 12500.0])
    np.testing.assert_allclose(blackbody_emission(t, 1.0), (BLACKBODY_SIGMA * t ** 4)[:, None] * blackbody_rec709(t))
    np.testing.assert_allclose(blackbody_emission(2000.0, 0.25), BLACKBODY_SIGMA * (0.75 + 0.25 * 2000.0 ** 4)
                               * blackbody_rec709(2000.0))
    assert not np.any(blackbody_emission(5000.0, 0.0))  # intensity 0: Cycles skips the closure
    # Cycles' fit is continuous at its breakpoints (checks the table rows and their order).
    for t in (965.0, 1167.0, 1449.0, 1902.0, 3315.0, 6365.0):
        np.testing.assert_allclose(blackbody_rec709(t - 1e-3), blackbody_rec709(t), rtol=2e-3, atol=2e-3)


def build_scene():
    scene = sb.new_scene((8 * len(CASES), 8), 4)
    for i, (temperature, intensity, tint, strength) in enumerate(CASES):
        material = sb.principled_volume_material(f"Fire{i}", density=0.0)
        node = next(n for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeVolumePrincipled")
        node.inputs["Temperature"].default_value = temperature
        node.inputs["Blackbody Intensity"].default_value = intensity
        node.inputs["Blackbody Tint"].default_value = tuple(tint) + (1.0,)
        node.inputs["Emission Strength"].default_value = strength
        sb.add_box(scene, f"Fire{i}", (i + 0.5, 0.0, 0.0), (1.0, 1.0, 1.0), material)
    camera_data = bpy.data.cameras.new("Ortho")
    camera_data.type, camera_data.ortho_scale = "ORTHO", float(len(CASES))
    camera = bpy.data.objects.new("Ortho", camera_data)
    scene.collection.objects.link(camera)
    scene.camera = camera
    camera.location, camera.rotation_euler = (len(CASES) / 2, -5.0, 0.0), (math.pi / 2, 0.0, 0.0)
    return scene


def expected_radiance():
    """Per box: emission per unit length x 1 m (density 0: nothing attenuates)."""
    return np.array([blackbody_emission(t, b, tint) + s * np.ones(3) for t, b, tint, s in CASES])


def test_homogeneous_blackbody_is_exported(registered_addon):
    from addon.export import export_scene

    scene = build_scene()
    native, warnings = export_scene(bpy.context.evaluated_depsgraph_get())
    assert not [w for w in warnings if "lackbody" in w], warnings
    emissions = {m.name: np.asarray(m.emission) for m in native.media}
    found = [next(e for name, e in emissions.items() if f"Fire{i}" in name) for i in range(len(CASES))]
    np.testing.assert_allclose(found, expected_radiance(), rtol=1e-6)


def test_homogeneous_blackbody_matches_cycles(registered_addon, tmp_path):
    """Cycles integrates a homogeneous emitting segment analytically: the centre pixels of each
    box are exact (up to float), so the tolerance is float precision, not noise."""
    from volpath_native import imageio

    scene = build_scene()
    scene.render.engine = "CYCLES"
    scene.cycles.device, scene.cycles.use_denoising = "CPU", False
    scene.render.filepath = str(tmp_path / "cycles.exr")
    bpy.ops.render.render(write_still=True, scene=scene.name)
    image = imageio.read_exr(tmp_path / "cycles.exr")
    measured = np.array([image[3:5, 8 * i + 3:8 * i + 5, :3].reshape(-1, 3).mean(axis=0) for i in range(len(CASES))])
    np.testing.assert_allclose(measured, expected_radiance(), rtol=2e-4, atol=1e-6)
