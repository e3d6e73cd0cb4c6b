"""Bounces guided toward delta lamps glowing in a medium (glow_guide): the guide's pdf is the
density of its samples, the image is the unguided one (the same expectation: a z-test on paired
paths, and a planted pdf error it catches), and the glow's heavy tail is gone."""
import numpy as np
import pytest

from volpath_native.glow_guide import (GLOW_CONE, GlowTable, glow_pdf, glow_sample, glow_table, medium_glow_pdf,
                                      medium_glow_sample, medium_glow_share, no_glow)
from volpath_native.integrator import Integrator
from volpath_native.media import MediaTable
from volpath_native.accel import Accelerator
from volpath_native.scene import Camera, Film, Material, Medium, PointLight, RenderSettings, Scene, SpotLight, World

from native_helpers import box_mesh, camera_at

LAMPS = GlowTable(2, np.array([[0.0, 0.0, 2.0], [1.5, 0.3, 0.4]]), np.array([0.7, 1.0]), np.zeros((2, 2), np.int8))
ORIGIN = (0.1, -0.2, 0.0)


def _draws(table, n, seed):
    rng = np.random.default_rng(seed)
    out = np.empty((n, 3))
    pdf = np.empty(n)
    for i, (a, b, c) in enumerate(rng.random((n, 3))):
        wo, ok = glow_sample(table, ORIGIN, a, b, c)
        assert ok
        out[i] = wo
        pdf[i] = glow_pdf(table, ORIGIN, wo)
    return out, pdf


def test_samples_are_unit_directions_near_the_lamps():
    wo, pdf = _draws(LAMPS, 2000, 1)
    assert np.allclose(np.linalg.norm(wo, axis=1), 1.0)
    axes = LAMPS.position - np.array(ORIGIN)
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    angles = np.arccos(np.clip(wo @ axes.T, -1, 1)).min(axis=1)
    assert angles.max() <= GLOW_CONE + 1e-9
    assert np.all(pdf > 0)


@pytest.mark.parametrize("planted", [1.0, 1.1])
def test_the_pdf_is_the_density_of_the_samples(planted):
    # E[1 / pdf] over the guide's samples = the solid angle it covers: two cones of half-angle
    # GLOW_CONE that do not overlap here. planted 1.1: a pdf 10 % off, which the test must catch.
    _, pdf = _draws(LAMPS, 20000, 2)
    estimate = 1.0 / (planted * pdf)
    solid_angle = 2 * 2 * np.pi * (1 - np.cos(GLOW_CONE))
    z = (estimate.mean() - solid_angle) / (estimate.std() / np.sqrt(len(estimate)))
    assert (abs(z) < 4) == (planted == 1.0), z
    # and the pdf integrates to one over the sphere (uniform directions)
    rng = np.random.default_rng(3)
    v = rng.normal(size=(200000, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    values = np.array([glow_pdf(LAMPS, ORIGIN, tuple(w)) for w in v]) * 4 * np.pi
    assert abs(values.mean() - 1.0) < 4 * values.std() / np.sqrt(len(values)) + 1e-3


def test_medium_vertices_aim_at_the_lamps_of_their_own_medium():
    table = LAMPS._replace(stack=np.array([[1, 0], [1, 1]], np.int8))  # the second lamp inside volume 1 in 0
    stack = np.array([[1, 0]], np.int8)  # the path is in volume 0 alone: only the first lamp glows there
    share = medium_glow_share(table, stack, 0)
    assert share == pytest.approx(0.7)
    rng = np.random.default_rng(4)
    inverse = []
    for u, v in rng.random((20000, 2)):
        wo, ok = medium_glow_sample(table, stack, 0, share, ORIGIN, u, v)
        assert ok
        inverse.append(1.0 / medium_glow_pdf(table, stack, 0, share, ORIGIN, wo))
    inverse = np.array(inverse)
    z = (inverse.mean() - 2 * np.pi * (1 - np.cos(GLOW_CONE))) / (inverse.std() / np.sqrt(len(inverse)))
    assert abs(z) < 4  # one cone's solid angle: the samples and the pdf cover the first lamp only
    assert medium_glow_share(table, np.array([[0, 0]], np.int8), 0) == 0.0  # in neither volume


def _fog_lamps(lamp_radius=0.0, lamp_position=(0.3, 0.2, 0.6), others=True):
    """A floor and a block in a fog box lit by a delta point lamp in the fog (its glow) and, with
    `others`, a soft sphere lamp and the world (hittable emitters: both MIS techniques)."""
    fog = box_mesh("fog", [-2.5, -2.5, -0.5], [2.5, 2.5, 2.5], material=1)
    return Scene(camera=Camera(camera_at([0, -2.2, 1.4], look_dir=(0, 1, -0.45), up=(0, 0, 1))), film=Film(8, 6),
                 meshes=[box_mesh("floor", [-2, -2, -0.2], [2, 2, 0.0]), box_mesh("block", [-0.8, 0.3, 0], [-0.3, 0.8, 0.5]),
                         fog],
                 materials=[Material("floor", base_color=0.6), Material("fog", surface="null", medium=0)],
                 media=[Medium("fog", 0.25, 0.02, g=0.2)],
                 lights=[PointLight("glowing", list(lamp_position), power=200.0, radius=lamp_radius)]
                 + ([PointLight("soft", [-1.0, -0.5, 1.6], power=80.0, radius=0.2)] if others else []),
                 world=World(background=0.3 if others else 0.0),
                 settings=RenderSettings(samples=1, seed=11, volume_bounces=4))  # medium vertices guided too


def test_only_delta_lamps_in_scattering_media_glow():
    scene = _fog_lamps()
    scene.lights.append(SpotLight("outside", [0.0, 0.0, 3.0], power=50.0))
    scene.validate()
    accel = Accelerator(scene.meshes, scene.materials)
    table = glow_table(scene.lights, MediaTable(scene, accel))
    assert table.count == 1 and np.allclose(table.position[0], [0.3, 0.2, 0.6])  # not the soft lamp nor the one outside
    assert table.stack.tolist() == [[1]]  # it glows in the fog box


def _paired(integrator, spp, glow):
    tables = integrator.tables
    integrator.tables = tables._replace(glow=glow) if glow is not None else tables
    try:
        pixels = integrator.scene.film.width * integrator.scene.film.height
        k = np.arange(pixels * spp)
        values, _ = integrator.render_paths(k % pixels, k // pixels)
    finally:
        integrator.tables = tables
    return values.mean(axis=1)


@pytest.mark.parametrize("planted", [False, True])
def test_guided_bounces_keep_the_image(planted):
    integrator = Integrator(_fog_lamps())
    assert integrator.tables.glow.count == 1
    guide = integrator.tables.glow
    if planted:  # a cdf ending at 8: at surfaces the samples fill the cone's inner eighth, the pdf claims all
        guide = guide._replace(cdf=np.array([8.0]))
    off = no_glow()
    guided, plain = _paired(integrator, 1500, guide), _paired(integrator, 1500, off)
    difference = guided - plain
    z = difference.mean() / (difference.std() / np.sqrt(len(difference)))
    assert (abs(z) < 4) != planted, z


def test_guided_bounces_tame_the_glow():
    # one pixel on the floor 0.5 m below the delta lamp, seen at a grazing angle from afar (camera
    # rays pass the lamp no closer than ~0.4 m): floor bounces passing the lamp closely carry its
    # glow ~1/D. Without the guide a few are hundreds of times the mean; with it they are bounded.
    scene = _fog_lamps(lamp_position=(0.0, -1.0, 0.5), others=False)
    look = np.array([-3.0, 1.0, -0.4]) / np.linalg.norm([-3.0, 1.0, -0.4])
    scene.camera = Camera(camera_at([3.0, -2.0, 0.4], look_dir=tuple(look), up=(0, 0, 1)), fov=0.02)
    scene.film = Film(1, 1)
    integrator = Integrator(scene)
    off = no_glow()
    guided, plain = _paired(integrator, 40000, None), _paired(integrator, 40000, off)
    assert guided.max() < 6 * guided.mean()
    assert plain.max() > 4 * guided.max()
    assert guided.var() < plain.var()
