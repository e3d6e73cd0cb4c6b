"""Overlapping media with different Henyey-Greenstein g: the phase function is the mixture
sum_k sigma_s,k HG(g_k) / sigma_s per channel (not HG of a mean g). The renderer's mixture
sampling and evaluation (path_kernels._phase_mixture_sample / _phase_mixture_eval on the scene
tables of two overlapping media) vs the analytic mixture (chi-square), and single scattering of
two overlapping media vs quadrature."""
import numpy as np
import pytest

from volpath_native import Camera, Material, Medium, PointLight, RenderSettings, Scene, World, render
from volpath_native.accel import Accelerator
from volpath_native.integrator import scene_tables
from volpath_native.jit import kernel
from volpath_native.media import MediaTable
from volpath_native.path_kernels import _component_sigma, _phase_is_mixed, _phase_mixture_eval, _phase_mixture_sample
from volpath_native.phase import hg_eval, hg_sample

from native_helpers import Z_LIMIT, block_z_scores, box_mesh, camera_at, chi2_critical, tiny_box_film, z_scores
from test_phase import _hg_cdf, tangents
from test_single_scattering import LIGHT, POWER, SIZE, _quadrature, _quadrature_extended

# A world fog of g 0.8 overlapped by a box fog of g -0.6. Components are picked with probability
# proportional to their mean sigma_s (Cycles volume_shader_phase_pick by sample weight): 0.3 and 0.7.
G = np.array([0.8, -0.6])
WEIGHTS = np.array([0.3, 0.7])
MIX_SS = (np.array([0.2, 0.4, 0.3]), np.array([0.9, 0.5, 0.7]))  # per-channel sigma_s, means = WEIGHTS
INSIDE_BOX = np.array([[1]], np.int8)  # volume-stack counters of a path inside the box
OUTSIDE_BOX = np.array([[0]], np.int8)


def _tables(scene):
    """(MediaTable, the SceneTables the compiled stages read) of a scene."""
    scene.validate()
    accel = Accelerator(scene.meshes)
    media = MediaTable(scene, accel)
    return media, scene_tables(scene, accel, media)


def _mixture_tables():
    scene = _overlap_scene(1, 1, PointLight("p", LIGHT, power=POWER, radius=0.0))
    scene.media = [Medium("world fog", MIX_SS[0], 0.05, g=G[0]), Medium("box fog", MIX_SS[1], 0.05, g=G[1])]
    media, tables = _tables(scene)
    assert media.mixed_phase
    return tables


@kernel
def _mixture_samples(S, C, d, u1, u2, wo, f, pdf):
    for i in range(u1.shape[0]):
        w, fi, pdf[i] = _phase_mixture_sample(S, C, 0, (d[0], d[1], d[2]), u1[i], u2[i])
        wo[i, 0], wo[i, 1], wo[i, 2] = w
        f[i, 0], f[i, 1], f[i, 2] = fi


@kernel
def _mixture_values(S, C, cos_theta, f, pdf):
    for i in range(cos_theta.shape[0]):
        fi, pdf[i] = _phase_mixture_eval(S, C, 0, cos_theta[i])
        f[i, 0], f[i, 1], f[i, 2] = fi


def _mixture_cdf(mu, weights=WEIGHTS, gs=G):
    return sum(w * _hg_cdf(g, mu) for w, g in zip(weights, gs))


def _chi2_against(mu, phi, cdf):
    """Chi-square of samples (mu, phi) against a rotationally symmetric law with CDF cdf(mu):
    16 equal-probability bins in mu x 8 in azimuth."""
    grid = np.linspace(-1, 1, 200_001)
    c = cdf(grid)
    mu_edges = np.interp(np.linspace(0, 1, 17), c / c[-1], grid)
    counts, _, _ = np.histogram2d(mu, phi, bins=[mu_edges, np.linspace(-np.pi, np.pi, 9)])
    expected = len(mu) / counts.size
    return ((counts - expected) ** 2 / expected).sum(), counts.size - 1


AXIS = np.array([0.3, -0.5, 0.81]) / np.linalg.norm([0.3, -0.5, 0.81])


def _sample_mixture(n, seed, counts=INSIDE_BOX, u=None):
    """n renderer mixture samples around AXIS: (wo, f (RGB), pdf, mu, azimuth)."""
    rng = np.random.default_rng(seed)
    u1, u2 = u if u is not None else (rng.random(n), rng.random(n))
    wo, f, pdf = np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
    _mixture_samples(_mixture_tables(), counts, AXIS, u1, u2, wo, f, pdf)
    t, s = tangents(AXIS)
    return wo, f, pdf, wo @ AXIS, np.arctan2(wo @ s, wo @ t)


def test_mixture_sampling_chi_square():
    n = 200_000
    wo, f, pdf, mu, phi = _sample_mixture(n, 11)
    np.testing.assert_allclose(np.linalg.norm(wo, axis=1), 1.0, atol=1e-9)
    # the returned pdf is the whole mixture's (for MIS), the value sum_k sigma_s,k HG(g_k) per channel
    hg = [hg_eval(g, mu) for g in G]
    np.testing.assert_allclose(pdf, WEIGHTS[0] * hg[0] + WEIGHTS[1] * hg[1], rtol=1e-9)
    np.testing.assert_allclose(f, np.outer(hg[0], MIX_SS[0]) + np.outer(hg[1], MIX_SS[1]), rtol=1e-9)
    chi2, dof = _chi2_against(mu, phi, _mixture_cdf)
    assert chi2 < chi2_critical(dof), chi2
    # the evaluated mixture pdf integrates to 1 with mean cosine sum_k w_k g_k, the value to sigma_s
    grid = np.linspace(-1, 1, 400_001)
    values, density = np.empty((len(grid), 3)), np.empty(len(grid))
    _mixture_values(_mixture_tables(), INSIDE_BOX, grid, values, density)
    w = 2 * np.pi * density
    assert abs(np.trapz(w, grid) - 1) < 1e-3
    assert abs(np.trapz(w * grid, grid) - WEIGHTS @ G) < 1e-3
    np.testing.assert_allclose(np.trapz(2 * np.pi * values, grid, axis=0), MIX_SS[0] + MIX_SS[1], rtol=1e-3)


def test_mixture_chi_square_rejects_the_mean_g_approximation():
    """The test above has power: HG of the weighted mean g (-0.18) does not pass as the mixture,
    nor do the mixture's samples pass with the component weights swapped."""
    n = 200_000
    _, _, _, mu, phi = _sample_mixture(n, 12)
    mean_g = WEIGHTS @ G
    chi2, dof = _chi2_against(mu, phi, lambda m: _hg_cdf(mean_g, m))
    assert chi2 > chi2_critical(dof), chi2
    swapped, dof = _chi2_against(mu, phi, lambda m: _mixture_cdf(m, WEIGHTS[::-1]))
    assert swapped > chi2_critical(dof), swapped


def test_single_component_mixture_is_plain_hg():
    """Outside the box only the world's g scatters: mixture sampling is plain HG(0.8) sampling
    with the same random numbers."""
    rng = np.random.default_rng(3)
    n = 1000
    u1, u2 = rng.random(n), rng.random(n)
    wo, f, pdf, _, _ = _sample_mixture(n, 0, OUTSIDE_BOX, (u1, u2))
    wo_hg, pdf_hg = hg_sample(np.tile(AXIS, (n, 1)), G[0], u1, u2)
    np.testing.assert_allclose(wo, wo_hg, atol=1e-9)
    np.testing.assert_allclose(pdf, pdf_hg, rtol=1e-9)
    np.testing.assert_allclose(f, np.outer(pdf_hg, MIX_SS[0]), rtol=1e-9)


# ---- rendering: a forward-scattering world medium overlapped by a back-scattering box ---------
# Per-channel sigma_s ratios differ, so the mixture weights are chromatic.
WORLD_SS, WORLD_SA, WORLD_G = np.array([0.35, 0.10, 0.25]), np.array([0.05, 0.10, 0.05]), 0.8
BOX_SS, BOX_SA, BOX_G = np.array([0.10, 0.45, 0.30]), np.array([0.05, 0.05, 0.10]), -0.6
SIGMA_T = WORLD_SS + WORLD_SA + BOX_SS + BOX_SA
BOX_HALF = 40.0  # light leaving the box is attenuated by > e^-20: the quadrature's infinite medium


def _overlap_scene(samples, seed, light):
    cam = Camera(camera_at([0, 0, 0]), fov=np.radians(50), clip_start=0.0, clip_end=1e4)
    media = [Medium("world fog", WORLD_SS, WORLD_SA, g=WORLD_G), Medium("box fog", BOX_SS, BOX_SA, g=BOX_G)]
    return Scene(camera=cam, film=tiny_box_film(SIZE), media=media, world=World(medium=0),
                 materials=[Material("box boundary", surface="null", medium=1)],
                 meshes=[box_mesh("box", [-BOX_HALF] * 3, [BOX_HALF] * 3, material=0)],
                 lights=[light],
                 settings=RenderSettings(samples=samples, seed=seed, volume_bounces=0))


def _mixture_scattering(cos):
    return WORLD_SS * hg_eval(WORLD_G, cos)[..., None] + BOX_SS * hg_eval(BOX_G, cos)[..., None]


def _mean_g_scattering(cos):
    """What the renderer used to do: HG of the (channel-averaged) sigma_s-weighted mean g."""
    mean_g = (WORLD_SS.mean() * WORLD_G + BOX_SS.mean() * BOX_G) / (WORLD_SS.mean() + BOX_SS.mean())
    return (WORLD_SS + BOX_SS) * hg_eval(mean_g, cos)[..., None]


# Lamp just outside the view: no camera ray passes through or near the sphere lamp, where
# _quadrature_extended is only approximate (it clamps the closest approach to 1.01 r).
SIDE_LIGHT = np.array([2.0, 0.3, -2.0])


def _sphere_lamp(radius):
    return PointLight("lamp", SIDE_LIGHT, power=POWER, radius=radius, soft_falloff=False, visible_camera=False)


def _check(result, expected, wrong):
    z = z_scores(result.image[..., :3], result.variance, expected)
    assert np.abs(z).max() < Z_LIMIT, (np.abs(z).max(), result.image[..., :3].mean(axis=(0, 1)),
                                       expected.mean(axis=(0, 1)))
    chi2 = (z ** 2).sum(axis=(0, 1))
    assert np.all(chi2 < chi2_critical(SIZE * SIZE)), chi2
    # the image mean too (pixels are independent): small biases hide in per-pixel noise
    z_mean = z_scores(result.image[..., :3].mean(axis=(0, 1)), result.variance.sum(axis=(0, 1)) / SIZE ** 4,
                      expected.mean(axis=(0, 1)))
    assert np.all(np.abs(z_mean) < Z_LIMIT), z_mean
    # the old mean-g approximation differs by far more than the noise: this test would catch it
    z_old = z_scores(result.image[..., :3], result.variance, wrong)
    assert np.any((z_old ** 2).sum(axis=(0, 1)) > chi2_critical(SIZE * SIZE)), (z_old ** 2).sum(axis=(0, 1))


def test_overlapping_media_point_light_matches_mixture_quadrature():
    """Next-event estimation with the mixture value (point light: light sampling only)."""
    scene = _overlap_scene(256, 21, PointLight("p", LIGHT, power=POWER, radius=0.0))
    result = render(scene)
    expected = _quadrature(scene, None, _mixture_scattering, SIGMA_T)
    _check(result, expected, _quadrature(scene, None, _mean_g_scattering, SIGMA_T))


def test_overlapping_media_sphere_light_matches_mixture_quadrature():
    """A sphere lamp is also reached by phase-sampled rays: mixture sampling, its value / pdf
    weight and its pdf in the power heuristic must combine with NEE to the exact integral."""
    radius = 0.4
    scene = _overlap_scene(256, 22, _sphere_lamp(radius))
    result = render(scene)
    expected = _quadrature_extended(scene, None, radius, True, _mixture_scattering, SIGMA_T, SIDE_LIGHT)
    _check(result, expected, _quadrature_extended(scene, None, radius, True, _mean_g_scattering, SIGMA_T, SIDE_LIGHT))


# ---- multiple scattering ------------------------------------------------------------------------
def test_overlapping_media_of_different_g_in_emissive_enclosure_show_wall_radiance():
    """Furnace: two partly overlapping non-absorbing media (g 0.8 and -0.6, chromatic sigma_s)
    inside walls of radiance 1. Any throughput weight of the mixture sampling other than
    value / pdf (per channel) would show up as a deviation from 1."""
    from native_helpers import icosphere
    from test_furnace import _assert_uniform
    walls = icosphere("walls", radius=2.0, subdivisions=2, material=0)
    fog_a = icosphere("fog a", radius=1.9, subdivisions=2, material=1)
    fog_b = icosphere("fog b", radius=1.2, subdivisions=2, material=2, centre=(0.4, 0.1, -0.3))
    materials = [Material("emitter", base_color=0.0, emission=1.0),
                 Material("fog a", surface="null", medium=0), Material("fog b", surface="null", medium=1)]
    # Chromatic weights multiply the throughput by f_c / pdf, a factor of mean 1 per bounce whose
    # spread grows with how much the channels' mixtures differ; over the many bounces of a
    # non-absorbing medium the product is heavy-tailed, so the media are kept optically moderate.
    media = [Medium("a", sigma_s=[0.6, 0.3, 0.8], sigma_a=0.0, g=0.8),
             Medium("b", sigma_s=[0.3, 0.6, 0.2], sigma_a=0.0, g=-0.6)]
    cam = Camera(camera_at([0.3, -0.2, 0.5], look_dir=(0.2, 0.1, -1)), fov=np.radians(90), clip_start=0.0)
    from volpath_native import Film
    scene = Scene(camera=cam, film=Film(16, 16), meshes=[walls, fog_a, fog_b], materials=materials, media=media,
                  settings=RenderSettings(samples=64, seed=13, max_bounces=1000, volume_bounces=1000,
                                          diffuse_bounces=1000, russian_roulette_min_bounces=3))
    result = render(scene)
    assert result.variance.max() > 0
    _assert_uniform(result, 1.0)


def test_grid_overlapping_media_of_different_g_matches_homogeneous_equivalent():
    """A constant-density grid (g 0.3) inside a forward-scattering world fog overlapped by a
    back-scattering box: the grid's own HG joins the homogeneous components of the mixture
    (NEE, MIS pdf, sampling), so the image equals the same scene with the grid replaced by a
    homogeneous medium of equal coefficients (three-component homogeneous mixture, checked
    against quadrature above). Multiple scattering, z-test per 2x2 block."""
    from volpath_native import Film
    from test_grid_integration import _constant_grid
    ss, sa, g = np.array([1.2, 0.4, 0.8]), np.array([0.1, 0.3, 0.1]), 0.3

    def scene(inner, seed):
        cam = Camera(camera_at([0, 0, 4]), fov=np.radians(40), clip_start=0.0)
        media = [Medium("world fog", [0.10, 0.05, 0.15], 0.02, g=0.8), Medium("box fog", [0.3, 0.6, 0.2], 0.05, g=-0.6),
                 inner]
        return Scene(camera=cam, film=Film(8, 8), media=media, world=World(medium=0, background=0.2),
                     meshes=[box_mesh("box", [-1.5, -1.5, -1.5], [1.5, 1.5, 1.5], material=0),
                             box_mesh("bound", [-0.9] * 3, [0.9] * 3, material=1)],
                     materials=[Material("box", surface="null", medium=1), Material("bound", surface="null", medium=2)],
                     lights=[PointLight("p", [0.5, 1.2, 0.2], power=150.0)],
                     settings=RenderSettings(samples=256, seed=seed, volume_bounces=3))
    grid = render(scene(_constant_grid(ss, sa, g=g), 31))
    hom = render(scene(Medium("hom", ss, sa, g=g), 32))
    z = block_z_scores(grid, hom)
    assert np.abs(z).max() < Z_LIMIT, np.abs(z).max()
    assert hom.image[..., :3].mean() > 0.01


# ---- one medium with several lobes (Medium.phase_lobes) -------------------------------------------
def _two_lobe_world_scene(samples, seed, light):
    scene = _overlap_scene(samples, seed, light)
    scene.meshes, scene.materials = [], []
    scene.media = [Medium("two-lobe fog", WORLD_SS + BOX_SS, WORLD_SA + BOX_SA,
                          phase_lobes=[(WORLD_SS, WORLD_G), (BOX_SS, BOX_G)])]
    return scene


def test_two_lobe_medium_matches_mixture_quadrature():
    """A single medium listing two HG lobes is the same mixture as two overlapping media."""
    radius = 0.4
    scene = _two_lobe_world_scene(256, 23, _sphere_lamp(radius))
    result = render(scene)
    assert not result.warnings, result.warnings
    expected = _quadrature_extended(scene, None, radius, True, _mixture_scattering, SIGMA_T, SIDE_LIGHT)
    _check(result, expected, _quadrature_extended(scene, None, radius, True, _mean_g_scattering, SIGMA_T, SIDE_LIGHT))


def test_phase_lobes_validation_and_round_trip(tmp_path):
    from volpath_native import SceneError, load_scene, save_scene
    scene = _two_lobe_world_scene(2, 1, PointLight("p", LIGHT, power=POWER, radius=0.0))
    scene.media[0].sigma_s = np.array([9.0, 9.0, 9.0])  # inconsistent with the lobes
    scene.media[0].phase_lobes[1] = (BOX_SS, 1.5)        # outside (-1, 1)
    warnings = scene.validate()
    assert any("not the sum of its phase lobes" in w for w in warnings), warnings
    assert any("clamped to 0.999" in w for w in warnings), warnings
    np.testing.assert_allclose(scene.media[0].sigma_s, WORLD_SS + BOX_SS)
    loaded = load_scene(save_scene(scene, tmp_path / "lobes.vpscene"))
    assert [g for _, g in loaded.media[0].phase_lobes] == [WORLD_G, 0.999]
    np.testing.assert_array_equal(render(loaded).image, render(scene).image)
    with pytest.raises(SceneError, match="phase lobe 0"):
        Medium("bad", 1.0, 0.0, phase_lobes=[(1.0,)])
    # single-lobe media are saved exactly as before (no phase_lobes key)
    single = _overlap_scene(2, 1, PointLight("p", LIGHT, power=POWER, radius=0.0))
    import json
    path = save_scene(single, tmp_path / "single.vpscene")
    header = json.loads(bytes(np.load(path)["scene.json"]).decode())
    assert all("phase_lobes" not in m for m in header["media"])


def test_stacks_with_one_g_keep_the_fast_path():
    """Overlapping media that share g (and lobes of equal g) never build mixture components;
    media of different g do, and only their overlap is mixed."""
    stacks = np.array([[0], [1]], np.int8)  # outside, inside the box
    scene = _overlap_scene(1, 1, PointLight("p", LIGHT, power=POWER, radius=0.0))
    scene.media[1].g = WORLD_G
    media, tables = _tables(scene)
    assert not media.mixed_phase and not tables.mixed_phase
    assert not any(_phase_is_mixed(tables, stacks, p) for p in range(2))
    scene.media[1] = Medium("box fog", BOX_SS, BOX_SA, phase_lobes=[(BOX_SS / 2, WORLD_G), (BOX_SS / 2, WORLD_G)])
    assert not _tables(scene)[0].mixed_phase
    scene.media[1] = Medium("box fog", BOX_SS, BOX_SA, g=BOX_G)
    scene.world.medium = -1  # only the box scatters: one g inside it, nothing outside
    scene.media.append(Medium("other", WORLD_SS, WORLD_SA, g=WORLD_G))  # unused medium: no effect
    assert not _tables(scene)[0].mixed_phase
    scene.world.medium = 0
    media, tables = _tables(scene)
    assert media.mixed_phase and tables.mixed_phase
    assert [_phase_is_mixed(tables, stacks, p) for p in range(2)] == [False, True]
    g_k = list(tables.phase_g)
    np.testing.assert_allclose(g_k, sorted([WORLD_G, BOX_G]))
    np.testing.assert_allclose(_component_sigma(tables, stacks, 1, g_k.index(BOX_G)), BOX_SS)
    np.testing.assert_allclose(_component_sigma(tables, stacks, 1, g_k.index(WORLD_G)), WORLD_SS)
    np.testing.assert_allclose(_component_sigma(tables, stacks, 0, g_k.index(BOX_G)), 0.0)
