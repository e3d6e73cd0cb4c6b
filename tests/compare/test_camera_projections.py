"""Each panoramic mapping against Cycles' own directions, pixel by pixel.

Cycles renders a world whose background colour encodes the ray direction (Geometry > Position of
the background is the direction: 0.5 + 0.5 d), one sample per pixel through a box filter of 0.01 px,
so each pixel holds the direction of its centre's ray (or black where the camera has no ray). The
directions VolPath's camera (exported from the same .blend) gives the pixel centres must agree to
the filter's jitter; a pixel where the two disagree on whether there is a ray at all must lie on
the edge of a fisheye's circle. The exporter, the fixed panoramic camera matrices and projection.py
are all in the loop.
"""
import math

import numpy as np
import pytest

RESOLUTION = (24, 16)
CASES = {
    "equirectangular": dict(panorama_type="EQUIRECTANGULAR", latitude_min=-1.1, latitude_max=1.3,
                            longitude_min=-2.6, longitude_max=2.2, shift_x=0.05),
    "fisheye_equidistant": dict(panorama_type="FISHEYE_EQUIDISTANT", fisheye_fov=2.6, shift_y=-0.04),
    "fisheye_equisolid": dict(panorama_type="FISHEYE_EQUISOLID", fisheye_fov=3.0, fisheye_lens=9.0),
    "mirrorball": dict(panorama_type="MIRRORBALL"),
    "central_cylindrical": dict(panorama_type="CENTRAL_CYLINDRICAL", central_cylindrical_range_u_min=-2.0,
                                central_cylindrical_range_u_max=1.5, central_cylindrical_range_v_min=-1.5,
                                central_cylindrical_range_v_max=2.0, central_cylindrical_radius=1.5),
}
PERSPECTIVE = {"perspective_dof_off": dict()}


def _direction_world(scene):
    world = scene.world
    tree = world.node_tree
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputWorld")
    background = tree.nodes.new("ShaderNodeBackground")
    geometry = tree.nodes.new("ShaderNodeNewGeometry")
    encode = tree.nodes.new("ShaderNodeVectorMath")
    encode.operation = "MULTIPLY_ADD"
    encode.inputs[1].default_value = (0.5, 0.5, 0.5)
    encode.inputs[2].default_value = (0.5, 0.5, 0.5)
    tree.links.new(geometry.outputs["Position"], encode.inputs[0])
    tree.links.new(encode.outputs["Vector"], background.inputs["Color"])
    background.inputs["Strength"].default_value = 1.0
    tree.links.new(background.outputs["Background"], output.inputs["Surface"])


def _build(case):
    import bpy
    from examples import scene_builder as sb

    scene = sb.new_scene(RESOLUTION, 1)
    if scene.world.node_tree is None:
        scene.world.use_nodes = True
    _direction_world(scene)
    camera = sb.add_camera(scene, (0.3, -1.0, 0.7), (1.0, 2.0, 1.2), lens_mm=30.0)
    camera.rotation_euler.y += 0.4  # a roll too: the whole camera matrix is in the test
    settings = dict(CASES.get(case, {}))
    if case in CASES:
        camera.data.type = "PANO"
        for key, value in settings.items():
            if hasattr(camera.data, key):
                setattr(camera.data, key, value)
            elif not key.startswith("central_cylindrical"):
                raise AssertionError(key)
        if "central_cylindrical" in case and not hasattr(camera.data, "central_cylindrical_radius"):
            pytest.skip("central cylindrical cameras are Blender 4.x+")
    scene.cycles.pixel_filter_type = "BOX"
    scene.cycles.filter_width = 0.01
    return bpy, scene


@pytest.mark.agreement
@pytest.mark.parametrize("case", list(CASES) + list(PERSPECTIVE))
def test_directions_match_cycles(registered_addon, case):
    from addon.compare import cycles_engine, volpath_engine
    from volpath_native.camera import CameraModel

    bpy, scene = _build(case)
    native, _ = volpath_engine.export(scene)
    with cycles_engine.matched_settings(scene, cycles_engine.BounceLimits()):
        image = cycles_engine.render_once(scene, samples=1, seed=0).image[..., :3].astype(np.float64)
    cycles_seen = np.any(image > 1e-6, axis=2)
    cycles_dirs = (image - 0.5) * 2.0

    model = CameraModel(native.camera, native.film)
    h, w = image.shape[:2]
    xs, ys = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    _, dirs, _ = model.generate_rays(xs.ravel(), ys.ravel())
    dirs = dirs.reshape(h, w, 3)
    seen = np.any(dirs != 0, axis=2)
    # where the two disagree on whether there is a ray, the filter's jitter (+-0.005 px) must reach
    # the other side: VolPath's camera 0.01 px away sees it differently
    border = np.zeros_like(seen)
    for dx, dy in ((0.01, 0), (-0.01, 0), (0, 0.01), (0, -0.01)):
        _, shifted, _ = model.generate_rays(xs.ravel() + dx, ys.ravel() + dy)
        border |= np.any(shifted.reshape(h, w, 3) != 0, axis=2) != seen
    assert np.all((seen == cycles_seen) | border), np.argwhere((seen != cycles_seen) & ~border)[:5]
    both = seen & cycles_seen & ~border
    assert both.sum() > 0.4 * h * w
    angle = np.degrees(np.arccos(np.clip(np.sum(dirs[both] * cycles_dirs[both], axis=1)
                                         / np.linalg.norm(cycles_dirs[both], axis=1), -1, 1)))
    # the filter's jitter moves a direction by at most ~0.005 px of the widest mapping here
    assert angle.max() < 0.1, f"{case}: worst {angle.max():.3f} deg at {np.argwhere(both)[np.argmax(angle)]}"
