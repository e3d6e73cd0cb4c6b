"""Surfaces in the integrator against closed forms: smooth glass slabs holding an absorbing
liquid (Fresnel at both faces, Beer-Lambert inside, the volume entered and left on
transmission), dielectric and transparent furnaces, and shadow rays through transparent cards.

Each test has a planted error the same statistic must reject (a 3 % change of the expected
value), so it can fail."""
import numpy as np
import pytest

from volpath_native import Camera, Material, Medium, Mesh, RenderSettings, Scene, World, render
from volpath_native.bsdfs.nodes import SurfaceNode

from native_helpers import Z_LIMIT, box_mesh, camera_at, icosphere, tiny_box_film, z_scores


def _fresnel_normal(eta):
    return ((eta - 1.0) / (eta + 1.0)) ** 2


def _slab_scene(eta, sigma_a, thickness, samples, glass_color=1.0):
    """An orthographic camera looking straight down through a wide glass slab filled with an
    absorbing liquid at an emissive floor (radiance 1); black world, so only light that went
    through the slab (possibly after internal reflections) reaches the camera."""
    glass = Material("liquid in glass", surface_nodes=[SurfaceNode.for_kind("glass", ior=eta, roughness=0.0,
                                                                   color=np.full(3, glass_color))],
                     medium=0)
    emitter = Material("floor", base_color=0.0, emission=1.0)
    slab = box_mesh("slab", [-50, -50, 1.0], [50, 50, 1.0 + thickness], material=0)
    floor = Mesh("floor", np.array([[-60, -60, 0], [60, -60, 0], [60, 60, 0], [-60, 60, 0]], float),
                 np.array([[0, 1, 2], [0, 2, 3]]), np.array([1, 1]))
    cam = Camera(camera_at([0.0, 0.0, 5.0], look_dir=(0, 0, -1)), projection="orthographic", ortho_scale=2.0,
                 clip_start=0.0)
    return Scene(camera=cam, film=tiny_box_film(8), meshes=[slab, floor], materials=[glass, emitter],
                 media=[Medium("liquid", sigma_s=0.0, sigma_a=sigma_a)],
                 settings=RenderSettings(samples=samples, seed=3, max_bounces=64, transmission_bounces=64,
                                         glossy_bounces=64, russian_roulette_min_bounces=64))


def _slab_transmittance(eta, sigma_a, thickness, color=1.0):
    """Normal incidence through a slab: (c (1-F))^2 T / (1 - (c F T)^2), c the Glass tint applied
    at every interface event (Cycles' Glass BSDF colour multiplies reflection and transmission)."""
    f = _fresnel_normal(eta)
    t = np.exp(-np.asarray(sigma_a, float) * thickness)
    return (color * (1.0 - f)) ** 2 * t / (1.0 - (color * f * t) ** 2)


def _image_z(result, expected):
    rgb = result.image[..., :3].astype(np.float64)
    n = rgb.shape[0] * rgb.shape[1]
    return z_scores(rgb.mean(axis=(0, 1)), result.variance.sum(axis=(0, 1)) / n ** 2, expected)


@pytest.mark.parametrize("eta", [1.33, 1.5])
def test_glass_slab_of_absorbing_liquid_matches_closed_form(eta):
    sigma_a, thickness = np.array([0.2, 1.0, 3.0]), 0.5
    result = render(_slab_scene(eta, sigma_a, thickness, samples=256))
    expected = _slab_transmittance(eta, sigma_a, thickness)
    z = _image_z(result, expected)
    assert np.all(np.abs(z) < Z_LIMIT), (result.image[..., :3].mean(axis=(0, 1)), expected, z)
    # planted error: a 3 % error of the expectation (e.g. a missing Fresnel term) is rejected
    assert np.any(np.abs(_image_z(result, expected * 1.03)) > Z_LIMIT)


def test_glass_tint_applies_at_every_interface():
    sigma_a, thickness, color = np.array([0.5, 0.5, 0.5]), 0.4, 0.8
    result = render(_slab_scene(1.5, sigma_a, thickness, samples=256, glass_color=color))
    expected = _slab_transmittance(1.5, sigma_a, thickness, color)
    assert np.all(np.abs(_image_z(result, expected)) < Z_LIMIT)
    assert np.any(np.abs(_image_z(result, _slab_transmittance(1.5, sigma_a, thickness, np.sqrt(color)))) > Z_LIMIT)


def _furnace(material, samples=64, size=8):
    """A closed emissive sphere (radiance 1) around an object made of `material`, viewed from inside:
    an energy-conserving surface leaves the radiance at 1 everywhere."""
    walls = icosphere("walls", radius=3.0, subdivisions=2, material=0)
    ball = icosphere("ball", radius=1.0, subdivisions=3, material=1)
    cam = Camera(camera_at([0.0, -2.5, 0.0], look_dir=(0, 1, 0)), fov=np.radians(40), clip_start=0.0)
    return Scene(camera=cam, film=tiny_box_film(size), meshes=[walls, ball],
                 materials=[Material("walls", base_color=0.0, emission=1.0), material],
                 settings=RenderSettings(samples=samples, seed=5, max_bounces=256, transmission_bounces=256,
                                         glossy_bounces=256, transparent_bounces=256,
                                         russian_roulette_min_bounces=256))


@pytest.mark.parametrize("node", [
    SurfaceNode.for_kind("glass", ior=1.5, roughness=0.0),
    SurfaceNode.for_kind("glass", ior=1.33, roughness=0.0),
    SurfaceNode.for_kind("transparent", color=np.ones(3)),
    SurfaceNode.for_kind("refraction", ior=1.5, roughness=0.0),  # Fresnel NONE: always transmits
], ids=["glass-1.5", "glass-1.33", "transparent", "refraction"])
def test_lossless_surfaces_in_a_furnace_keep_radiance_one(node):
    result = render(_furnace(Material("ball", surface_nodes=[node])))
    z = _image_z(result, 1.0)
    assert np.all(np.abs(z) < Z_LIMIT), (result.image[..., :3].mean(axis=(0, 1)), z)


def test_smooth_mirror_furnace_keeps_radiance_one():
    """A Glossy BSDF (no Fresnel) of colour 1 and roughness 0 is a perfect mirror."""
    result = render(_furnace(Material("ball", surface_nodes=[SurfaceNode.for_kind("glossy", roughness=0.0,
                                                                         color=np.ones(3))])))
    z = _image_z(result, 1.0)
    assert np.all(np.abs(z) < Z_LIMIT), z
    # a 0.97 mirror darkens the furnace measurably
    tinted = render(_furnace(Material("ball", surface_nodes=[SurfaceNode.for_kind("glossy", roughness=0.0,
                                                                         color=np.full(3, 0.97))])))
    assert np.all(np.abs(_image_z(tinted, 1.0)) > Z_LIMIT)


def test_shadow_rays_pass_transparent_cards_with_their_colour():
    """A point light above a tinted Transparent card over a white diffuse floor: the floor under
    the card receives the light times the card's colour (shadow rays pass it, Cycles'
    closure_transparent_extinction), and the card seen from above transmits the floor too."""
    tint = np.array([0.9, 0.5, 0.2])
    card = Material("card", surface_nodes=[SurfaceNode.for_kind("transparent", color=tint)])
    floor_mat = Material("floor", base_color=1.0)
    floor = Mesh("floor", np.array([[-20, -20, 0], [20, -20, 0], [20, 20, 0], [-20, 20, 0]], float),
                 np.array([[0, 1, 2], [0, 2, 3]]), np.array([0, 0]))
    card_mesh = Mesh("card", np.array([[-20, -20, 1], [20, -20, 1], [20, 20, 1], [-20, 20, 1]], float),
                     np.array([[0, 1, 2], [0, 2, 3]]), np.array([1, 1]))
    from volpath_native import PointLight
    cam = Camera(camera_at([0.0, 0.0, 3.0], look_dir=(0, 0, -1)), projection="orthographic", ortho_scale=0.2,
                 clip_start=0.0)
    scene = Scene(camera=cam, film=tiny_box_film(8), meshes=[floor, card_mesh], materials=[floor_mat, card],
                  lights=[PointLight("lamp", [0.0, 0.0, 2.0], power=4.0 * np.pi)],
                  settings=RenderSettings(samples=64, seed=9, max_bounces=1, diffuse_bounces=0))
    result = render(scene)
    # direct light only (diffuse bounces 0), through the card twice (lamp -> floor -> camera); the
    # samples go through pixel centres, so each pixel is exact: E = I cos / r^2, L = E / pi.
    centres = (np.arange(8) + 0.5) / 8 * 0.2 - 0.1
    x, y = np.meshgrid(centres, centres)
    r2 = x * x + y * y + 4.0
    expected = (2.0 / np.sqrt(r2) / r2 / np.pi)[..., None] * tint * tint
    # rtol: shadow rays start epsilon (2e-4 m here) off the surface, 2 m from the lamp
    np.testing.assert_allclose(result.image[..., :3], expected, rtol=1e-3)
    assert not np.allclose(result.image[..., :3], expected * np.sqrt(tint), rtol=1e-2)


def test_surface_nodes_survive_the_vpscene_file_and_bad_records_are_named(tmp_path):
    from volpath_native.scene import SceneError
    from volpath_native.scene_io import load_scene, save_scene
    import json
    import zipfile

    scene = _slab_scene(1.5, np.array([0.2, 1.0, 3.0]), 0.5, samples=4)
    path = save_scene(scene, tmp_path / "slab.vpscene")
    loaded = load_scene(path)
    node = loaded.materials[0].surface_nodes[0]
    assert node.kind == "glass" and node.ior == pytest.approx(1.5) and loaded.materials[0].medium == 0
    np.testing.assert_array_equal(render(loaded).image, render(scene).image)

    # a node of an unknown kind: one error naming file, material and node
    with zipfile.ZipFile(path) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    header = json.loads(np.load(path)["scene.json"].tobytes().decode())
    header["materials"][0]["surface_nodes"][0]["kind"] = "velvet"
    arrays = dict(np.load(path))
    arrays["scene.json"] = np.frombuffer(json.dumps(header).encode(), np.uint8)
    bad = tmp_path / "bad.vpscene"
    with open(bad, "wb") as f:
        np.savez(f, **arrays)
    assert members  # the archive was read
    with pytest.raises(SceneError, match=r"materials\[0\]\.surface_nodes\[0\]\.kind.*velvet"):
        load_scene(bad)
