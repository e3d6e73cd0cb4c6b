"""Per-point light selection (light_tree, Cycles' light tree): the probability tree_pdf gives any
light is the frequency with which tree_select picks it (chi-square, with a planted wrong pdf the
test must reject), the probabilities over all lights sum to 1 at every surface point and volume
segment, the static selection is what the tree falls back to, and a multi-light fog scene renders
the same image (z-test) with per-point and with static selection."""
import numpy as np
import pytest

from volpath_native import (AreaLight, Camera, Material, Medium, Mesh, PointLight, RenderSettings, Scene, SpotLight,
                            SunLight, World, render)
from volpath_native.accel import Accelerator
from volpath_native.light_tree import MODE_SURFACE, MODE_SURFACE_TRANSMIT, MODE_VOLUME
from volpath_native.lights import LightSet

from native_helpers import Z_LIMIT, block_z_scores, box_mesh, camera_at, chi2_critical, tiny_box_film
from test_lights_kernels import _every_kind


def _emissive_strip(n=40):
    """n small emissive triangles along a curve (a tree of several levels), alternately one- and
    two-sided."""
    v, f = [], []
    for i in range(n):
        a = 2 * np.pi * i / n
        c = np.array([2.5 * np.cos(a), 2.5 * np.sin(a), 1.0 + 0.5 * np.sin(3 * a)])
        k = len(v)
        v += [c, c + [0.2 * np.cos(a), 0.2 * np.sin(a), 0.0], c + [0, 0, 0.25]]
        f.append([k, k + 1, k + 2])
    return np.array(v), np.array(f)


def _many_lights(tree=True):
    v, f = _emissive_strip()
    strip = Mesh("strip", v, f, np.arange(len(f)) % 2 + 1)
    floor = Mesh("floor", np.array([[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]], float),
                 np.array([[0, 1, 2], [0, 2, 3]]), np.array([0, 0]))
    materials = [Material("floor", base_color=0.5),
                 Material("two", base_color=0.0, emission=[2.0, 1.0, 0.5], two_sided_emission=True),
                 Material("one", base_color=0.0, emission=[1.0, 3.0, 0.5], two_sided_emission=False)]
    lights = [PointLight(f"p{i}", [np.cos(i), np.sin(i), 2.0 + 0.1 * i], [50.0 + 10 * i] * 3) for i in range(6)]
    lights += [SpotLight("spot", [0, 0, 3], [300.0] * 3, direction=[0.2, 0, -1], spot_size=np.radians(40),
                         spot_blend=0.2),
               SunLight("sun", [0.3, 0.2, -1], [2.0, 2.0, 2.0], angle=np.radians(5))]
    scene = Scene(camera=Camera(np.eye(4)), film=tiny_box_film(4), meshes=[floor, strip], materials=materials,
                  lights=lights, world=World(background=[0.1, 0.2, 0.3]),
                  settings=RenderSettings(samples=1, light_tree=tree))
    return LightSet(scene, Accelerator(scene.meshes))


def _apart():
    """Four lamps far apart: leaves of one emitter, which the selection takes without weighing them
    again (light_tree.tree_select / tree_pdf). The constant sky beside them is no next-event light
    (Cycles disables such a background light, lights.LightSet) and so holds no leaf."""
    floor = Mesh("floor", np.array([[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]], float),
                 np.array([[0, 1, 2], [0, 2, 3]]), np.array([0, 0]))
    lights = [SpotLight("spot", [-3, 0, 2.5], [400.0] * 3, direction=[0.3, 0, -1], spot_size=np.radians(50),
                        spot_blend=0.3),
              PointLight("point", [3, 0, 2], [150.0] * 3),
              AreaLight("area", [0, 3, 2.5], [0.8, 0, 0], [0, 0, -0.6], [200.0] * 3),  # facing -y
              PointLight("near", [0, -3, 2.2], [60.0] * 3)]
    scene = Scene(camera=Camera(np.eye(4)), film=tiny_box_film(4), meshes=[floor],
                  materials=[Material("floor", base_color=0.5)], lights=lights,
                  world=World(background=[0.3, 0.4, 0.5]), settings=RenderSettings(samples=1))
    return LightSet(scene, Accelerator(scene.meshes))


@pytest.fixture(scope="module", params=["every_kind", "many", "apart"])
def lights(request):
    return {"every_kind": _every_kind, "many": _many_lights, "apart": _apart}[request.param]()


def test_leaves_of_one_emitter_are_exercised():
    """The 'apart' lights put every lamp in a leaf of its own (the shortcut path); the sky has none."""
    lights = _apart()
    tree = lights.tree
    assert tree.leaf_of_row[lights.world_row] == -1
    from volpath_native.light_tree import N_COUNT
    counts = tree.node_i[:, N_COUNT]
    assert np.count_nonzero(counts == 1) == 4, counts


def _queries(n, seed):
    """Surface points with normals (opaque and transmitting) and volume segments (finite and
    unbounded), all around the lights."""
    rng = np.random.default_rng(seed)
    p = rng.uniform([-3, -3, -0.5], [3, 3, 3.5], (n, 3))
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    t = np.where(rng.random(n) < 0.2, np.inf, rng.uniform(0.01, 6.0, n))
    mode = rng.integers(0, 3, n)
    return p, nrm, np.where(mode == MODE_VOLUME, t, 0.0), mode


def test_tree_spans_every_light(lights):
    assert lights.use_tree
    assert np.all(lights.tree.leaf_of_row[lights.tree_energy > 0] >= 0)
    assert np.sort(lights.tree.leaf_rows).tolist() == np.nonzero(lights.tree_energy > 0)[0].tolist()


def test_pdf_over_all_lights_sums_to_one_and_matches_the_selection(lights):
    """Over all lights the probabilities sum to 1 in volumes and on transmitting surfaces. On an
    opaque surface a branch whose bounds face the point may hold only lights behind it: there
    the selection finds no light (Cycles: light_tree_sample returns false), and the sum is 1
    minus exactly that chance (stratified draws measure it)."""
    p, nrm, t, mode = _queries(90, 1)
    rows = np.arange(lights.count)
    draws = 1000
    u_strata = (np.arange(draws) + 0.5) / draws
    for m in (MODE_SURFACE, MODE_SURFACE_TRANSMIT, MODE_VOLUME):
        k = mode == m
        pk, nk, tk = p[k], nrm[k], t[k]
        totals = np.zeros(len(pk))
        for row in rows:
            pdf = lights.tree_pdf(np.full(len(pk), row), pk, nk, tk, m)
            assert np.all(np.isfinite(pdf)) and np.all(pdf >= 0)
            totals += pdf
        assert np.all(totals <= 1.0 + 1e-9)
        if m != MODE_SURFACE:
            np.testing.assert_allclose(totals, 1.0, rtol=1e-9)
        for i in range(len(pk)):
            chosen, sel = lights.tree_select(u_strata, np.tile(pk[i], (draws, 1)), np.tile(nk[i], (draws, 1)),
                                             np.full(draws, tk[i]), m)
            found = chosen >= 0
            assert abs(found.mean() - totals[i]) < 4e-3
            np.testing.assert_allclose(sel[found], lights.tree_pdf(chosen[found], np.tile(pk[i], (found.sum(), 1)),
                                                                   np.tile(nk[i], (found.sum(), 1)),
                                                                   np.full(found.sum(), tk[i]), m), rtol=1e-12)


def _chi_square(lights, p, n, t, m, pdf, draws=40000, seed=3):
    u = np.random.default_rng(seed).random(draws)
    rows, _ = lights.tree_select(u, np.tile(p, (draws, 1)), np.tile(n, (draws, 1)), np.full(draws, t), m)
    # the last bin: no light found (see above)
    counts = np.bincount(np.where(rows < 0, lights.count, rows), minlength=lights.count + 1)
    expected = np.append(pdf, max(1.0 - pdf.sum(), 0.0)) * draws
    keep = expected > 5
    assert counts[~keep].sum() <= max(20, 3 * expected[~keep].sum() + 10)
    stat = float(((counts[keep] - expected[keep]) ** 2 / expected[keep]).sum())
    return stat, int(keep.sum()) - 1


@pytest.mark.parametrize("m", [MODE_SURFACE, MODE_SURFACE_TRANSMIT, MODE_VOLUME])
def test_selection_frequencies_follow_the_pdf(lights, m):
    p = np.array([0.3, -0.4, 1.2])
    n = np.array([0.2, 0.1, 1.0]) / np.linalg.norm([0.2, 0.1, 1.0])
    t = 3.0 if m == MODE_VOLUME else 0.0
    if m == MODE_VOLUME:
        n = np.array([1.0, 0.3, 0.2]) / np.linalg.norm([1.0, 0.3, 0.2])
    rows = np.arange(lights.count)
    pdf = lights.tree_pdf(rows, np.tile(p, (len(rows), 1)), np.tile(n, (len(rows), 1)), np.full(len(rows), t), m)
    assert pdf.sum() == pytest.approx(1.0) or m == MODE_SURFACE
    assert np.count_nonzero(pdf > 0.02) >= 3  # a test with teeth: several lights compete
    stat, dof = _chi_square(lights, p, n, t, m, pdf)
    assert stat < chi2_critical(max(dof, 5)), (stat, dof)
    # planted error: the static probabilities (or the tree's with two lights' probabilities
    # moved by 10 %) must be rejected
    wrong = pdf.copy()
    big = np.argsort(pdf)[-2:]
    wrong[big[0]] *= 1.1
    wrong[big[1]] = pdf[big[1]] - (wrong[big[0]] - pdf[big[0]])
    stat_wrong, dof = _chi_square(lights, p, n, t, m, wrong)
    assert stat_wrong > chi2_critical(max(dof, 5)), (stat_wrong, dof)


def test_static_selection_when_the_tree_is_off():
    lights = _many_lights(tree=False)
    p, nrm, t, mode = _queries(50, 4)
    for row in range(lights.count):
        pdf = lights.tree_pdf(np.full(len(p), row), p, nrm, t, MODE_SURFACE)
        np.testing.assert_array_equal(pdf, lights.select_prob[row])
    u = np.random.default_rng(5).random(len(p))
    rows, sel = lights.tree_select(u, p, nrm, t, MODE_VOLUME)
    np.testing.assert_array_equal(rows, lights.select(u))
    np.testing.assert_array_equal(sel, lights.select_prob[rows])


def _fog_scene(tree, samples):
    """Fog in a box over a floor, lit by a sun, a spot, a point light and the sky; a small
    emissive panel (a mesh light) in the fog."""
    fog = box_mesh("fog", [-2, -2, 0], [2, 2, 2], material=1)
    floor = Mesh("floor", np.array([[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]], float),
                 np.array([[0, 1, 2], [0, 2, 3]]), np.array([0, 0]))
    panel = Mesh("panel", np.array([[-1.5, 1.0, 0.5], [-1.0, 1.0, 0.5], [-1.0, 1.0, 1.0], [-1.5, 1.0, 1.0]], float),
                 np.array([[0, 1, 2], [0, 2, 3]]), np.array([2, 2]))
    materials = [Material("floor", base_color=0.6), Material("fog", surface="null", medium=0),
                 Material("panel", base_color=0.0, emission=[4.0, 3.0, 2.0])]
    lights = [SunLight("sun", [0.4, 0.3, -1.0], [3.0, 3.0, 3.0], angle=np.radians(4)),
              SpotLight("spot", [0.8, -0.5, 1.8], [150.0, 120.0, 100.0], direction=[0.0, 0.1, -1.0],
                        spot_size=np.radians(35), spot_blend=0.3),
              PointLight("point", [-0.8, -1.0, 1.2], [40.0, 60.0, 80.0], radius=0.1)]
    return Scene(camera=Camera(camera_at([0.0, -6.0, 2.5], look_dir=[0.0, 1.0, -0.35]), fov=0.7),
                 film=tiny_box_film(8), meshes=[floor, fog, panel], materials=materials,
                 media=[Medium("fog", sigma_s=0.6, sigma_a=0.05, g=0.3)], lights=lights,
                 world=World(background=[0.05, 0.08, 0.12]),
                 settings=RenderSettings(samples=samples, seed=11 if tree else 12, volume_bounces=2, threads=1,
                                         light_tree=tree))


def test_per_point_selection_renders_the_static_image():
    """The light tree changes the noise, not the image (z-test against the static selection)."""
    tree = render(_fog_scene(True, 192))
    static = render(_fog_scene(False, 192))
    z = block_z_scores(tree, static, block=2)
    assert np.abs(z).max() < Z_LIMIT, np.abs(z).max()
    assert np.all(np.isfinite(tree.image))
    # and it pays: less variance over the image at the same sample count
    assert tree.variance.sum() < static.variance.sum()


def test_per_point_selection_is_deterministic_across_threads_and_batches():
    import dataclasses
    scene = _fog_scene(True, 8)
    a = render(scene)
    scene.settings = dataclasses.replace(scene.settings, threads=2, batch_size=100)
    b = render(scene)
    np.testing.assert_array_equal(a.image, b.image)
