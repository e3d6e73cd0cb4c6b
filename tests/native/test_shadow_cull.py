"""Shadow rays through null boundaries that first ask whether anything opaque lies on them (one
occlusion query over the geometry masked accel.MASK_OPAQUE; Integrator.CULL_DECISION_SHADOWS):
the image is the one without the query, bit for bit, in the compiled loop and stage by stage;
fewer rays are traced where most shadow rays are blocked, and the integrator switches the query
on there and only there."""
import numpy as np
import pytest

from volpath_native import integrator as integrator_module
from volpath_native.accel import ALL_MASK, MASK_OPAQUE, MASK_SEE_THROUGH, Accelerator
from volpath_native.integrator import Integrator
from volpath_native.scene import Camera, Film, Material, Medium, RenderSettings, Scene, SunLight

from native_helpers import box_mesh, camera_at, lit_box_in_fog


def _shaded_fog():
    """A fog box (null boundary) under an opaque roof with a slot in it, lit by a sun from above:
    most shadow rays leave the fog and then hit the roof (the sun-through-a-window row)."""
    fog = box_mesh("fog", [-1.5, -1.5, -1.5], [1.5, 1.5, 1.5], material=1)
    roof_left = box_mesh("roof left", [-3, -3, 2.0], [-0.2, 3, 2.2])
    roof_right = box_mesh("roof right", [0.2, -3, 2.0], [3, 3, 2.2])
    floor = box_mesh("floor", [-3, -3, -2.2], [3, 3, -2.0])
    return Scene(camera=Camera(camera_at([0, -5, 0], look_dir=(0, 1, 0), up=(0, 0, 1))), film=Film(12, 8),
                 meshes=[floor, roof_left, roof_right, fog],
                 materials=[Material("d", base_color=0.6), Material("fog", surface="null", medium=0)],
                 media=[Medium("m", 0.3, 0.05)],
                 lights=[SunLight("sun", [0.05, 0.1, -1.0], irradiance=5.0, angle=0.02)],
                 settings=RenderSettings(samples=1, seed=7))


SCENES = {"shaded fog": _shaded_fog, "lamp in fog": lit_box_in_fog}


def _batch(integrator, spp=8):
    pixels = integrator.scene.film.width * integrator.scene.film.height
    k = np.arange(pixels * spp)
    return k % pixels, k // pixels


def _render(integrator, cull, stepwise=False):
    integrator.set_cull_opaque_first(cull)
    return integrator.render_paths(*_batch(integrator), stepwise=stepwise)


def test_geometry_masks_pick_what_a_query_sees():
    # two triangles on one ray: the nearer see-through, the farther opaque
    quad = np.float32([[-1, -1, 0], [1, -1, 0], [0, 1, 0]])
    far = quad + np.float32([0, 0, -1])
    from volpath_native.embree import TriangleScene
    scene = TriangleScene()
    scene.add_triangles(quad, np.int32([[0, 1, 2]]), 0, int(MASK_SEE_THROUGH))
    scene.add_triangles(far, np.int32([[0, 1, 2]]), 1, int(MASK_OPAQUE))
    scene.commit()
    o, d, t = np.float32([[0, 0, 1]]), np.float32([[0, 0, -1]]), np.float32([10])
    assert scene.intersect(o, d, t)[1][0] == 0
    assert scene.intersect(o, d, t, mask=MASK_OPAQUE)[1][0] == 1
    assert scene.intersect(o, d, t, mask=MASK_SEE_THROUGH)[1][0] == 0
    assert scene.occluded(o, d, np.float32([1.5]), mask=MASK_OPAQUE)[0] == np.False_
    assert scene.occluded(o, d, np.float32([1.5]), mask=ALL_MASK)[0]
    assert scene.occluded(o, d, t, mask=MASK_OPAQUE)[0]


def test_accelerator_masks_runs_of_each_class():
    meshes = [box_mesh("a", [0, 0, 0], [1, 1, 1]), box_mesh("fog", [-2, -2, -2], [2, 2, 2], material=1),
              box_mesh("b", [3, 0, 0], [4, 1, 1])]
    accel = Accelerator(meshes, see_through=np.array([False, True]))
    runs = accel._mask_runs(0, accel.world_triangle_count)
    assert [(a, b, m) for a, b, m in runs] == [(0, 12, MASK_OPAQUE), (12, 24, MASK_SEE_THROUGH),
                                             (24, 36, MASK_OPAQUE)]
    assert not Accelerator(meshes).masked  # classes unknown: one geometry seen by every query


@pytest.mark.parametrize("name", list(SCENES))
@pytest.mark.parametrize("stepwise", [False, True])
def test_the_opaque_query_keeps_the_image(name, stepwise):
    integrator = Integrator(SCENES[name]())
    plain, plain_stats = _render(integrator, False, stepwise)
    culled, culled_stats = _render(integrator, True, stepwise)
    assert plain.any()
    assert np.array_equal(plain, culled)
    assert culled_stats["rays"] == plain_stats["rays"]
    if name == "shaded fog":  # one query instead of two or more closest hits per blocked ray
        assert culled_stats["shadow_rays"] < 0.8 * plain_stats["shadow_rays"]


def test_an_occlusion_query_over_every_geometry_is_caught(monkeypatch):
    # planted error: the cull asks about see-through boundaries too, dropping rays that reach the sun
    monkeypatch.setattr(integrator_module, "MASK_OPAQUE", ALL_MASK)
    integrator = Integrator(_shaded_fog())
    plain, _ = _render(integrator, False, stepwise=True)
    culled, _ = _render(integrator, True, stepwise=True)
    assert not np.array_equal(plain, culled)


@pytest.mark.parametrize("name, expected", [("shaded fog", True), ("lamp in fog", False)])
def test_the_query_is_switched_on_where_it_pays(name, expected):
    integrator = Integrator(SCENES[name]())
    assert integrator.culls_opaque_first is None
    pixel, sample = _batch(integrator, spp=64)
    for _ in range(20):
        integrator.render_paths(pixel, sample)
        if integrator.culls_opaque_first is not None:
            break
    assert integrator.culls_opaque_first == expected
