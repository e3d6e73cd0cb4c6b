"""Bad input gives a clear error or warning and never a NaN image; chromatic == grey media."""
import numpy as np
import pytest

from volpath_native import (AreaLight, Camera, Film, Material, Medium, Mesh, PointLight, RenderSettings, Scene,
                            SceneError, World, render)

from native_helpers import Z_LIMIT, box_mesh, camera_at, z_scores


def _scene(**kw):
    base = dict(camera=Camera(camera_at([0, 0, 3])), film=Film(16, 16),
                meshes=[box_mesh("box", [-1, -1, -1], [1, 1, 1], material=0)],
                materials=[Material("diffuse", base_color=0.5)],
                lights=[PointLight("p", [0, 0, 2.5], power=100.0)], settings=RenderSettings(samples=2))
    base.update(kw)
    return Scene(**base)


def test_open_mesh_bounding_a_medium_is_an_error():
    box = box_mesh("fog", [-1, -1, -1], [1, 1, 1], material=0)
    open_box = Mesh("fog", box.vertices, box.triangles[:-2], box.material_ids[:-2])
    scene = _scene(meshes=[open_box], materials=[Material("fog", surface="null", medium=0)],
                   media=[Medium("m", 1.0, 0.0)])
    with pytest.raises(SceneError, match="not closed"):
        render(scene)


def test_nan_coefficients_are_rejected_at_construction():
    with pytest.raises(SceneError, match="non-finite"):
        Medium("m", sigma_s=[np.nan, 1, 1], sigma_a=0.0)


def test_negative_coefficients_are_clamped_with_a_warning():
    scene = _scene(media=[Medium("m", sigma_s=[-1.0, 0.5, 0.5], sigma_a=[0.1, -2.0, 0.1])], world=World(medium=0))
    result = render(scene)
    assert any("negative coefficients" in w for w in result.warnings)
    assert np.all(np.isfinite(result.image)) and np.all(result.image[..., :3] >= 0)


def test_zero_size_area_light_is_an_error_and_zero_power_a_warning():
    flat = AreaLight("flat", [0, 0, 2], [1, 0, 0], [0, 0, 0], power=10.0)
    with pytest.raises(SceneError, match="zero size"):
        render(_scene(lights=[flat]))
    dark = PointLight("dark", [0, 0, 2], power=0.0)
    result = render(_scene(lights=[dark]))
    assert any("zero power" in w for w in result.warnings)
    assert np.all(result.image[..., :3] == 0)


def test_degenerate_triangles_are_ignored_with_a_warning():
    box = box_mesh("box", [-1, -1, -1], [1, 1, 1])
    tris = np.concatenate([box.triangles, [[0, 0, 1]]])
    mesh = Mesh("box", box.vertices, tris, np.zeros(len(tris)))
    result = render(_scene(meshes=[mesh]))
    assert any("degenerate" in w for w in result.warnings)
    assert np.all(np.isfinite(result.image))


def test_empty_scene_renders_black_with_a_warning():
    result = render(Scene(camera=Camera(np.eye(4)), film=Film(8, 8), settings=RenderSettings(samples=1)))
    assert any("empty" in w for w in result.warnings)
    assert result.image.shape == (8, 8, 4)
    assert np.all(result.image[..., :3] == 0) and np.all(result.image[..., 3] == 1)


@pytest.mark.parametrize("bad", [dict(samples=0), dict(volume_sampling="bogus")])
def test_bad_settings_are_errors(bad):
    scene = _scene()
    for k, v in bad.items():
        setattr(scene.settings, k, v)
    with pytest.raises(SceneError):
        render(scene)


def test_bad_camera_and_film_are_errors():
    with pytest.raises(SceneError):
        render(_scene(film=Film(0, 10)))
    with pytest.raises(SceneError):
        render(_scene(camera=Camera(camera_at([0, 0, 3]), fov=0.0)))
    with pytest.raises(SceneError):
        render(_scene(film=Film(16, 16, crop=(0.5, 0.5, 0.1, 0.9))))


def test_camera_inside_medium_and_light_inside_medium():
    """The camera's volume stack is found by ray walking; no NaN when everything sits in fog."""
    fog = box_mesh("fog", [-5, -5, -5], [5, 5, 5], material=1)
    small = box_mesh("box", [-0.3, -0.3, -0.3], [0.3, 0.3, 0.3])
    scene = _scene(meshes=[small, fog],
                   materials=[Material("d", base_color=0.5), Material("fog", surface="null", medium=0)],
                   media=[Medium("m", 0.5, 0.1, g=0.2)])
    result = render(scene)
    assert np.all(np.isfinite(result.image))
    no_fog = render(_scene(meshes=[small]))
    # fog in front of the box scatters light into otherwise-dark background pixels
    assert result.image[0, 0, :3].sum() > 0 and no_fog.image[0, 0, :3].sum() == 0


def test_grey_medium_through_the_chromatic_path_equals_grey_renders():
    """Each channel of a chromatic medium renders like a grey medium with that channel's
    coefficients (same seed, so a tight z-test on independent renders)."""
    fog = box_mesh("fog", [-2, -2, -2], [2, 2, 2], material=1)
    sigma_s = np.array([0.3, 0.9, 1.6])
    sigma_a = np.array([0.2, 0.05, 0.4])

    def scene(ss, sa, seed):
        return _scene(meshes=[box_mesh("box", [-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]), fog],
                      materials=[Material("d", base_color=0.5), Material("fog", surface="null", medium=0)],
                      media=[Medium("m", ss, sa, g=0.4)], lights=[PointLight("p", [0.8, 0.6, 1.0], power=200.0)],
                      film=Film(8, 8), settings=RenderSettings(samples=128, seed=seed, volume_bounces=2))
    chroma = render(scene(sigma_s, sigma_a, 1))
    grey_img = render(scene(np.full(3, sigma_s[1]), np.full(3, sigma_a[1]), 2))
    # a grey medium stays exactly grey through the chromatic machinery
    np.testing.assert_allclose(grey_img.image[..., 0], grey_img.image[..., 1], rtol=1e-5)
    np.testing.assert_allclose(grey_img.image[..., 2], grey_img.image[..., 1], rtol=1e-5)
    for c in (0, 2):
        grey = render(scene(np.full(3, sigma_s[c]), np.full(3, sigma_a[c]), 3 + c))
        z = z_scores(chroma.image[..., c], chroma.variance[..., c], grey.image[..., c], grey.variance[..., c])
        assert np.abs(z).max() < Z_LIMIT, (c, np.abs(z).max())
    z = z_scores(chroma.image[..., 1], chroma.variance[..., 1], grey_img.image[..., 1], grey_img.variance[..., 1])
    assert np.abs(z).max() < Z_LIMIT
