"""wavefront.trace_batch (one compiled call per batch) against the same stages called one by one
from Python (Integrator.render_paths(stepwise=True)): the same radiance, bit for bit, and the same
counts, seed for seed, on scenes that take each branch of the loop -- shadow rays stepping through
null boundaries, plain occlusion queries, grid media with per-path volume stacks, moving
geometry, a scene without triangles."""
import numpy as np
import pytest

from volpath_native import wavefront
from volpath_native.grid_medium import GridMedium
from volpath_native.integrator import Integrator
from volpath_native.scene import (AreaLight, Camera, Film, Material, Medium, Mesh, PointLight, RenderSettings, Scene,
                                  SpotLight, SunLight, World)
from volpath_native.bsdfs.nodes import SurfaceNode

from native_helpers import box_mesh, camera_at, lit_box_in_fog


def _fog(**settings):
    """A lit box in fog inside a null boundary: shadow rays step through it."""
    return lit_box_in_fog(**settings)


def _surfaces():
    """No null boundaries (occlusion queries), every lamp type and the sky (light tree), glass,
    metal and principled BSDFs."""
    lights = [PointLight("lamp", [0.0, 0.0, 2.5], power=100.0), SpotLight("spot", [0.0, 1.0, 2.5], power=100.0),
              AreaLight("area", np.array([0.0, -1.0, 2.5]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), power=50.0),
              SunLight("sun", [0.2, 0.1, -1.0], irradiance=2.0, angle=0.1)]
    kinds = [SurfaceNode.for_kind(kind) for kind in ("principled", "glass", "metallic")]
    floor = box_mesh("floor", [-3, -3, -2], [3, 3, -1.5])
    return Scene(camera=Camera(camera_at([0, 0, 6])), film=Film(12, 8),
                 meshes=[floor, box_mesh("block", [-0.5, -0.5, -0.5], [0.5, 0.5, 0.5], material=1)],
                 materials=[Material("floor"), Material("block", surface_nodes=kinds)], lights=lights,
                 world=World(background=0.1), settings=RenderSettings(samples=1, seed=2))


def _grid_from_inside():
    """A voxel grid the orthographic camera sits in (per-path stacks, grid tracking)."""
    density = np.linspace(0.0, 1.0, 27, dtype=np.float32).reshape(3, 3, 3)
    to_world = np.eye(4)
    to_world[:3, 3] = -1.0
    inside = np.eye(4)
    inside[:3, 3] = [0.0, 0.0, 0.5]
    return Scene(camera=Camera(inside, projection="orthographic", ortho_scale=1.0), film=Film(12, 8),
                 meshes=[box_mesh("floor", [-3, -3, -2], [3, 3, -1.5]),
                         box_mesh("cloud", [-1, -1, -1], [1, 1, 1], material=1)],
                 materials=[Material("floor"), Material("cloud", surface="null", medium=0)],
                 media=[GridMedium("cloud", density, to_world, np.full(3, 2.0), np.full(3, 0.5))],
                 lights=[PointLight("lamp", [0.0, 0.0, 2.5], power=100.0)], world=World(background=0.2),
                 settings=RenderSettings(samples=1, seed=3))


def _moving():
    """A quad moving over the shutter (rays carry their times to Embree) in front of fog."""
    corners = np.float32([[-0.4, -2, 0], [0.4, -2, 0], [0.4, 2, 0], [-0.4, 2, 0]])
    quad = Mesh("quad", corners, np.int32([[0, 1, 2], [0, 2, 3]]), np.int32([0, 0]))
    quad.vertex_motion = np.stack([corners + np.float32([s, 0, 0]) for s in (-0.5, 0.0, 0.5)])
    quad.vertices = quad.vertex_motion[1]
    quad.__post_init__()
    fog = box_mesh("fog", [-1.5, -2.5, -1.5], [1.5, 2.5, 1.5], material=1)
    return Scene(camera=Camera(camera_at([0, 0, 5])), film=Film(12, 8), meshes=[quad, fog],
                 materials=[Material("quad", base_color=0.5), Material("fog", surface="null", medium=0)],
                 media=[Medium("m", 0.3, 0.05)], lights=[PointLight("p", [0.5, 1.2, 1.0], power=300.0)],
                 world=World(background=0.5), settings=RenderSettings(samples=1, seed=5))


def _no_triangles():
    return Scene(camera=Camera(camera_at([0, 0, 4])), film=Film(12, 8), meshes=[], materials=[],
                 lights=[PointLight("p", [0.5, 1.2, 1.0], power=300.0)], world=World(background=0.5),
                 settings=RenderSettings(samples=1, seed=6))


SCENES = {"fog": _fog, "surfaces": _surfaces, "grid": _grid_from_inside, "moving": _moving,
          "no_triangles": _no_triangles}


def _batch(integrator, spp=6):
    pixels = integrator.scene.film.width * integrator.scene.film.height
    k = np.arange(pixels * spp)
    return k % pixels, k // pixels


@pytest.mark.parametrize("name", list(SCENES))
def test_one_call_per_batch_is_the_stage_by_stage_image(name):
    integrator = Integrator(SCENES[name]())
    pixel, sample = _batch(integrator)
    stepwise, stepwise_stats = integrator.render_paths(pixel, sample, stepwise=True)
    integrator.set_cull_opaque_first(None)  # decided anew: the same shadow queries as stepwise
    fused, fused_stats = integrator.render_paths(pixel, sample)
    assert np.array_equal(fused, stepwise)
    for counter in ("rays", "shadow_rays", "vertices", "paths", "dropped"):
        assert fused_stats[counter] == stepwise_stats[counter], counter
    assert np.array_equal(fused_stats["budget"], stepwise_stats["budget"])
    assert fused.any()


def test_a_changed_argument_of_the_batch_call_is_caught(monkeypatch):
    # planted error: shadow rays stop 1e-6 shorter of the light in the compiled loop only
    original = wavefront.trace_batch

    def shifted_margin(*args):
        args = list(args)
        args[22] += 1e-6  # margin
        return original(*args)
    monkeypatch.setattr(wavefront, "trace_batch", shifted_margin)
    integrator = Integrator(_fog())
    pixel, sample = _batch(integrator)
    stepwise, _ = integrator.render_paths(pixel, sample, stepwise=True)
    fused, _ = integrator.render_paths(pixel, sample)
    assert not np.array_equal(fused, stepwise)


def test_stop_flag_abandons_the_batch():
    integrator = Integrator(_fog())
    pixel, sample = _batch(integrator)
    integrator.request_stop()
    radiance, stats = integrator.render_paths(pixel, sample)
    assert stats["rays"] == 0 and not radiance.any()
