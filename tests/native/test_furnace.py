"""Furnace tests: closed emissive enclosures whose exact radiance is known."""
import numpy as np

from volpath_native import Camera, Film, Material, Medium, RenderSettings, Scene, render

from native_helpers import Z_LIMIT, camera_at, icosphere, box_mesh, z_scores


def _enclosure(medium, size=16, samples=32, sphere=True):
    # Black, emitting walls (radiance 1, two-sided) filled with a medium through a null boundary
    # just inside them.
    walls = icosphere("walls", radius=2.0, subdivisions=2, material=0) if sphere else \
        box_mesh("walls", [-2, -2, -2], [2, 2, 2], material=0, inward=True)
    fog = icosphere("fog", radius=1.9, subdivisions=2, material=1) if sphere else \
        box_mesh("fog", [-1.9, -1.9, -1.9], [1.9, 1.9, 1.9], material=1)
    materials = [Material("emitter", base_color=0.0, emission=1.0), Material("fog", surface="null", medium=0)]
    cam = Camera(camera_at([0.3, -0.2, 0.5], look_dir=(0.2, 0.1, -1)), fov=np.radians(90), clip_start=0.0)
    return Scene(camera=cam, film=Film(size, size), meshes=[walls, fog], materials=materials, media=[medium],
                 settings=RenderSettings(samples=samples, seed=11, max_bounces=1000, volume_bounces=1000,
                                         diffuse_bounces=1000, russian_roulette_min_bounces=3))


def _assert_uniform(result, value):
    """Every 4x4 block of pixels and the whole image agree with `value` (z-tests). Blocks rather
    than single pixels: multiple-scattering estimators are heavy-tailed, and 32 samples per pixel
    are too few for a per-pixel normal approximation; 512 per block are enough."""
    rgb = result.image[..., :3].astype(np.float64)
    var = result.variance.astype(np.float64)
    h, w, _ = rgb.shape
    block_mean = rgb.reshape(h // 4, 4, w // 4, 4, 3).mean(axis=(1, 3))
    block_var = var.reshape(h // 4, 4, w // 4, 4, 3).sum(axis=(1, 3)) / 16 ** 2
    z = z_scores(block_mean, block_var, value)
    assert np.abs(z).max() < Z_LIMIT, np.abs(z).max()
    z_all = z_scores(rgb.mean(axis=(0, 1)), var.sum(axis=(0, 1)) / (h * w) ** 2, value)
    assert np.all(np.abs(z_all) < Z_LIMIT), z_all


def test_non_absorbing_medium_in_emissive_enclosure_shows_wall_radiance():
    result = render(_enclosure(Medium("fog", sigma_s=[1.0, 2.0, 4.0], sigma_a=0.0, g=0.5)))
    assert result.variance.max() > 0  # the medium really scatters
    _assert_uniform(result, 1.0)


def test_absorbing_emitting_medium_in_equilibrium():
    """Kirchhoff: a medium emitting sigma_a * L_wall keeps the radiance field at L_wall."""
    sigma_a = np.array([0.5, 1.0, 0.2])
    result = render(_enclosure(Medium("fog", sigma_s=[1.0, 0.3, 2.0], sigma_a=sigma_a, g=-0.3, emission=sigma_a),
                             samples=64))
    _assert_uniform(result, 1.0)


def test_absorbing_sphere_closed_form():
    """Camera at the centre of an emissive sphere filled with an absorber: L = exp(-sigma_a * d)
    with d the exact distance to the (tessellated) null boundary, plus exp(-...) for nothing else."""
    sigma_a = np.array([0.2, 0.7, 1.5])
    scene = _enclosure(Medium("absorber", sigma_s=0.0, sigma_a=sigma_a), size=8, samples=4)
    scene.camera.camera_to_world = camera_at([0, 0, 0], look_dir=(0.1, 0.2, -1))
    scene.film.filter, scene.film.filter_width = "box", 1e-6
    from volpath_native.accel import Accelerator
    from volpath_native.camera import CameraModel
    cam = CameraModel(scene.camera, scene.film)
    ys, xs = np.mgrid[0:8, 0:8] + 0.5
    o, d, _ = cam.generate_rays(xs.ravel(), ys.ravel())
    dist = Accelerator([scene.meshes[1]]).intersect(o, d).t
    expected = np.exp(-np.outer(dist, sigma_a)).reshape(8, 8, 3)
    result = render(scene)
    # Cycles' filter table sends the last 1/1023 of each axis' samples up to half a pixel from the
    # centre whatever the width (film.py): a few of these 4-sample pixels hold one such sample
    off = np.abs(result.image[..., :3] / expected - 1.0)
    assert np.mean(off > 2e-4) < 0.03 and off.max() < 3e-3, (np.mean(off > 2e-4), off.max())
