"""Grid (heterogeneous) media inside the path tracer: a constant-density grid must render like the
equivalent homogeneous medium; grids survive a save/load round trip."""
import numpy as np

from volpath_native import (Camera, Film, Material, Medium, PointLight, RenderSettings, Scene, World, load_scene,
                            render, save_scene)
from volpath_native.grid_medium import GridMedium

from native_helpers import Z_LIMIT, block_z_scores, box_mesh, camera_at, icosphere, tiny_box_film, z_scores


def _constant_grid(sigma_s, sigma_a, g=0.0, emission=0.0, n=8):
    """Density 1 on voxel centres spanning [-1, 1]^3 (exactly 1 anywhere inside [-1, 1]^3)."""
    m = np.eye(4) * (2.0 / (n - 1))
    m[3, 3] = 1.0
    m[:3, 3] = -1.0
    return GridMedium("grid", np.ones((n, n, n), np.float32), m, sigma_s, sigma_a, g=g, emission=emission)


def _through_box(medium, samples=64, seed=1):
    cam = Camera(camera_at([0, 0, 5]), projection="orthographic", ortho_scale=1.0, clip_end=100)
    return Scene(camera=cam, film=tiny_box_film(4), meshes=[box_mesh("bound", [-0.9] * 3, [0.9] * 3, material=0)],
                 materials=[Material("bound", surface="null", medium=0)], media=[medium],
                 world=World(background=1.0), settings=RenderSettings(samples=samples, seed=seed))


def test_absorbing_grid_transmittance():
    sigma_a = np.array([0.5, 1.0, 2.0])
    result = render(_through_box(_constant_grid(0.0, sigma_a)))
    expected = np.exp(-sigma_a * 1.8)
    mean = result.image[..., :3].mean(axis=(0, 1))
    var = result.variance.sum(axis=(0, 1)) / 16 ** 2
    if np.all(var < 1e-14):
        np.testing.assert_allclose(mean, expected, rtol=1e-4)
    else:
        assert np.all(np.abs(z_scores(mean, var, expected)) < Z_LIMIT), (mean, expected)


def test_scattering_grid_matches_homogeneous_medium():
    """Same coefficients as a grid and as a homogeneous medium, lit by a point light and the sky:
    the two images agree (z-test per 2x2 block)."""
    def scene(medium, seed):
        cam = Camera(camera_at([0, 0, 4]), fov=np.radians(40), clip_start=0.0)
        return Scene(camera=cam, film=Film(8, 8), meshes=[box_mesh("bound", [-0.9] * 3, [0.9] * 3, material=0),
                                                         box_mesh("floor", [-3, -3, -2], [3, 3, -1.5], material=1)],
                     materials=[Material("bound", surface="null", medium=0), Material("floor", base_color=0.6)],
                     media=[medium], lights=[PointLight("p", [0.5, 1.5, 0.2], power=150.0)],
                     world=World(background=0.2),
                     settings=RenderSettings(samples=256, seed=seed, volume_bounces=3))
    ss, sa, g = np.array([1.5, 0.8, 0.3]), np.array([0.2, 0.4, 0.1]), 0.4
    grid = render(scene(_constant_grid(ss, sa, g=g), 1))
    hom = render(scene(Medium("hom", ss, sa, g=g), 2))
    z = block_z_scores(grid, hom)
    assert np.abs(z).max() < Z_LIMIT, np.abs(z).max()
    assert hom.image[..., :3].mean() > 0.01


def test_grid_furnace():
    """A non-absorbing grid medium inside an emissive enclosure shows the wall radiance."""
    walls = icosphere("walls", radius=3.0, subdivisions=2, material=0)
    bound = box_mesh("bound", [-0.9] * 3, [0.9] * 3, material=1)
    cam = Camera(camera_at([0, 0, 2.5]), fov=np.radians(40), clip_start=0.0)
    scene = Scene(camera=cam, film=Film(8, 8), meshes=[walls, bound],
                  materials=[Material("emit", base_color=0.0, emission=1.0), Material("b", surface="null", medium=0)],
                  media=[_constant_grid([2.0, 1.0, 4.0], 0.0, g=0.3)],
                  settings=RenderSettings(samples=64, seed=3, max_bounces=1000, volume_bounces=1000))
    result = render(scene)
    mean = result.image[..., :3].mean(axis=(0, 1))
    var = result.variance.sum(axis=(0, 1)) / 64 ** 2
    assert np.all(np.abs(z_scores(mean, var, 1.0)) < Z_LIMIT), (mean, np.sqrt(var))
    assert var.max() > 0


def test_grid_scene_round_trip(tmp_path):
    scene = _through_box(_constant_grid([0.1, 0.2, 0.3], 0.5, g=0.2), samples=2)
    loaded = load_scene(save_scene(scene, tmp_path / "grid.vpscene"))
    assert isinstance(loaded.media[0], GridMedium)
    np.testing.assert_array_equal(render(loaded).image, render(scene).image)


def test_grid_cannot_be_the_world_medium():
    import pytest
    from volpath_native import SceneError
    scene = _through_box(_constant_grid(0.1, 0.1))
    scene.world.medium = 0
    with pytest.raises(SceneError, match="world"):
        render(scene)
