"""Single scattering of a point light in an infinite homogeneous medium vs quadrature, and the
equiangular + distance MIS against distance-only sampling."""
import numpy as np
import pytest

from volpath_native import Camera, Medium, PointLight, RenderSettings, Scene, World, render
from volpath_native.camera import CameraModel
from volpath_native.phase import hg_eval

from native_helpers import Z_LIMIT, chi2_critical, camera_at, tiny_box_film, z_scores

SIGMA_S = np.array([0.3, 0.5, 0.8])
SIGMA_A = np.array([0.1, 0.05, 0.2])
LIGHT = np.array([0.4, 0.3, -2.0])
POWER = 4 * np.pi * 10.0  # intensity 10 W/sr
SIZE = 8


def _scene(g, sampling="mis", samples=64, seed=5, light=LIGHT):
    cam = Camera(camera_at([0, 0, 0]), fov=np.radians(50), clip_start=0.0, clip_end=1e4)
    return Scene(camera=cam, film=tiny_box_film(SIZE), media=[Medium("air", SIGMA_S, SIGMA_A, g=g)],
                 world=World(medium=0), lights=[PointLight("p", light, power=POWER, radius=0.0)],
                 settings=RenderSettings(samples=samples, seed=seed, volume_bounces=0, volume_sampling=sampling))


def _hg_scattering(g, sigma_s=SIGMA_S):
    """sigma_s x HG(g) per channel, as a function of cos(theta) (shape (...) -> (..., 3))."""
    return lambda cos: sigma_s * hg_eval(g, cos)[..., None]


def _quadrature(scene, g, scattering=None, sigma_t=SIGMA_S + SIGMA_A, light=LIGHT):
    """L = int_0^inf e^{-st t} ss p(theta) I e^{-st r} / r^2 dt, by Gauss-Legendre on t = tan(x)
    split around the point closest to the light. scattering(cos) -> sigma_s x phase (..., 3)
    replaces SIGMA_S x HG(g) (e.g. for mixtures of overlapping media)."""
    scattering = scattering or _hg_scattering(g)
    cam = CameraModel(scene.camera, scene.film)
    ys, xs = np.mgrid[0:SIZE, 0:SIZE] + 0.5
    o, d, _ = cam.generate_rays(xs.ravel(), ys.ravel())
    st = sigma_t
    intensity = POWER / (4 * np.pi)
    x, w = np.polynomial.legendre.leggauss(400)
    out = np.zeros((len(d), 3))
    for i, (oi, di) in enumerate(zip(o, d)):
        delta = (light - oi) @ di
        dist = np.linalg.norm(oi + delta * di - light)
        # equiangular substitution t = delta + D tan(theta) makes the integrand smooth
        ta, tb = np.arctan2(-delta, dist), np.pi / 2
        th = 0.5 * (tb - ta) * x + 0.5 * (tb + ta)
        t = delta + dist * np.tan(th)
        jac = 0.5 * (tb - ta) * dist / np.cos(th) ** 2
        p = oi + t[:, None] * di
        to_light = light - p
        r = np.linalg.norm(to_light, axis=1)
        cos = (to_light @ di) / r
        f = np.exp(-np.outer(t + r, st)) * scattering(cos) * (intensity / r ** 2)[:, None]
        out[i] = (f * (w * jac)[:, None]).sum(axis=0)
    return out.reshape(SIZE, SIZE, 3)


@pytest.mark.parametrize("g", [-0.5, 0.0, 0.7])
def test_single_scattering_matches_quadrature(g):
    scene = _scene(g, samples=256)
    result = render(scene)
    expected = _quadrature(scene, g)
    z = z_scores(result.image[..., :3], result.variance, expected)
    assert np.abs(z).max() < Z_LIMIT, np.abs(z).max()
    # chi-square per channel (the channels of one pixel share paths, so they are not pooled)
    chi2 = (z ** 2).sum(axis=(0, 1))
    assert np.all(chi2 < chi2_critical(SIZE * SIZE)), chi2
    # and the test has power: a 10 % error in the light's intensity would be detected
    z_wrong = z_scores(result.image[..., :3], result.variance, 1.1 * expected)
    assert np.all((z_wrong ** 2).sum(axis=(0, 1)) > chi2_critical(SIZE * SIZE))


def test_image_changes_with_anisotropy():
    back, fwd = _quadrature(_scene(-0.5), -0.5), _quadrature(_scene(0.7), 0.7)
    assert np.abs(back - fwd).max() > 0.1 * fwd.max()
    a, b = render(_scene(-0.5, samples=64)), render(_scene(0.7, samples=64))
    z = z_scores(a.image[..., :3], a.variance, b.image[..., :3], b.variance)
    assert np.abs(z).max() > Z_LIMIT
    assert np.all((z ** 2).sum(axis=(0, 1)) > chi2_critical(SIZE * SIZE))


def test_equiangular_mis_agrees_with_distance_sampling_and_has_lower_variance():
    near = np.array([0.05, -0.03, -1.0])  # right next to the central camera rays
    mis = render(_scene(0.3, "mis", samples=64, seed=1, light=near))
    dist = render(_scene(0.3, "distance", samples=64, seed=2, light=near))
    z = z_scores(mis.image[..., :3], mis.variance, dist.image[..., :3], dist.variance)
    assert np.abs(z).max() < Z_LIMIT, np.abs(z).max()
    # near the light (the brightest quarter of the pixels: rays passing closest) MIS is much less noisy
    near_px = mis.image[..., 1] >= np.quantile(mis.image[..., 1], 0.75)
    var_mis, var_dist = mis.variance[near_px].mean(), dist.variance[near_px].mean()
    assert var_mis < 0.25 * var_dist, (var_mis, var_dist)
    equi = render(_scene(0.3, "equiangular", samples=64, seed=3, light=near))
    z = z_scores(equi.image[..., :3], equi.variance, dist.image[..., :3], dist.variance)
    assert np.abs(z).max() < Z_LIMIT, np.abs(z).max()


def _quadrature_extended(scene, g, radius, sphere, scattering=None, sigma_t=SIGMA_S + SIGMA_A, light=LIGHT):
    """Single scattering from a sphere light (sphere=True, radiance L over its visible cone) or a
    soft-falloff disk (facing each point) of radius r: 2D Gauss-Legendre over the light for each
    point of a 1D Gauss-Legendre along the camera ray. scattering as in _quadrature."""
    scattering = scattering or _hg_scattering(g)
    cam = CameraModel(scene.camera, scene.film)
    ys, xs = np.mgrid[0:SIZE, 0:SIZE] + 0.5
    o, d, _ = cam.generate_rays(xs.ravel(), ys.ravel())
    st = sigma_t
    radiance = POWER / (4 * np.pi ** 2 * radius ** 2)
    xt, wt = np.polynomial.legendre.leggauss(160)
    xa, wa = np.polynomial.legendre.leggauss(16)
    out = np.zeros((len(d), 3))
    for i, (oi, di) in enumerate(zip(o, d)):
        delta = (light - oi) @ di
        dist = max(np.linalg.norm(oi + delta * di - light), radius * 1.01)
        ta, tb = np.arctan2(-delta, dist), np.pi / 2
        th = 0.5 * (tb - ta) * xt + 0.5 * (tb + ta)
        t = delta + dist * np.tan(th)
        jac_t = 0.5 * (tb - ta) * dist / np.cos(th) ** 2
        p = oi + t[:, None] * di
        to_c = light - p
        D = np.linalg.norm(to_c, axis=1)
        axis = to_c / D[:, None]
        # tangent frame around the axis
        helper = np.where(np.abs(axis[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        u = np.cross(axis, helper)
        u /= np.linalg.norm(u, axis=1)[:, None]
        v = np.cross(axis, u)
        phi = np.pi * (xa + 1)            # [0, 2 pi)
        wphi = np.pi * wa
        if sphere:
            # outside: the lamp's cone; inside: every direction meets the sphere (Cycles
            # kernel/light/point.h samples the whole sphere there for volumes)
            inside = D <= radius
            alpha = np.where(inside, np.pi, np.arcsin(np.clip(radius / D, 0, 1)))
            theta = 0.5 * alpha[:, None] * (xa[None, :] + 1)          # (T, A)
            wth = 0.5 * alpha[:, None] * wa[None, :] * np.sin(theta)
            ct, stt = np.cos(theta), np.sin(theta)
            w_dir = (ct[:, :, None, None] * axis[:, None, None, :]
                     + stt[:, :, None, None] * (np.cos(phi)[None, None, :, None] * u[:, None, None, :]
                                               + np.sin(phi)[None, None, :, None] * v[:, None, None, :]))
            chord = np.sqrt(np.maximum(radius ** 2 - (D[:, None] * stt) ** 2, 0))
            s = D[:, None] * ct + np.where(inside[:, None], chord, -chord)
            s = np.broadcast_to(s[:, :, None], w_dir.shape[:3])
            weight = wth[:, :, None] * wphi[None, None, :]
        else:
            rho = 0.5 * radius * (xa + 1)
            wrho = 0.5 * radius * wa * rho
            pts = (light[None, None, None, :] + rho[None, :, None, None] *
                   (np.cos(phi)[None, None, :, None] * u[:, None, None, :] + np.sin(phi)[None, None, :, None] * v[:, None, None, :]))
            vec = pts - p[:, None, None, :]
            s = np.linalg.norm(vec, axis=3)
            w_dir = vec / s[..., None]
            weight = (wrho[None, :, None] * wphi[None, None, :]) * D[:, None, None] / s ** 3  # dA cos / s^2
        cos = np.einsum("tabk,k->tab", w_dir, di)
        inner = np.einsum("tabc,tab,tabc->tc", scattering(cos), weight, np.exp(-s[..., None] * st))
        out[i] = (np.exp(-np.outer(t, st)) * radiance * inner * (wt * jac_t)[:, None]).sum(axis=0)
    return out.reshape(SIZE, SIZE, 3)


@pytest.mark.parametrize("sphere", [True, False])
def test_single_scattering_from_sphere_and_soft_falloff_lights(sphere):
    """The lamps Blender creates by default (radius 0.1 m, soft falloff) and true spheres are hit
    by phase-sampled rays too: light-sampling NEE and phase sampling must combine to the exact
    single scattering (quadrature over the lamp and along the ray)."""
    from volpath_native import PointLight as PL
    radius, g = 0.4, 0.5
    scene = _scene(g, samples=256)
    scene.lights = [PL("lamp", LIGHT, power=POWER, radius=radius, soft_falloff=not sphere, visible_camera=False)]
    result = render(scene)
    expected = _quadrature_extended(scene, g, radius, sphere)
    z = z_scores(result.image[..., :3], result.variance, expected)
    assert np.abs(z).max() < Z_LIMIT, (np.abs(z).max(), result.image[..., 1].mean(), expected[..., 1].mean())
    # the image mean too: a bias confined to a few pixels (rays through the lamp) hides in per-pixel noise
    z_mean = z_scores(result.image[..., :3].mean(axis=(0, 1)), result.variance.sum(axis=(0, 1)) / SIZE ** 4,
                      expected.mean(axis=(0, 1)))
    assert np.all(np.abs(z_mean) < Z_LIMIT), z_mean
    z_wrong = z_scores(result.image[..., :3], result.variance, 1.1 * expected)
    assert np.all((z_wrong ** 2).sum(axis=(0, 1)) > chi2_critical(SIZE * SIZE))


def test_volume_bounce_limit_has_cycles_meaning():
    """volume_bounces = 0 is exactly single scattering (checked against quadrature above); each
    extra bounce adds multiple scattering, so the image grows, and the growth shrinks."""
    imgs = [render(_scene(0.0, samples=128, seed=7 + b)) for b in (0,)]
    for b in (1, 4):
        scene = _scene(0.0, samples=128, seed=7 + b)
        scene.settings.volume_bounces = b
        imgs.append(render(scene))
    means = [r.image[..., :3].mean(axis=(0, 1)) for r in imgs]
    errs = [np.sqrt(r.variance.sum(axis=(0, 1))) / SIZE ** 2 for r in imgs]
    assert np.all(means[1] - means[0] > Z_LIMIT * np.hypot(errs[1], errs[0])), (means, errs)
    assert np.all(means[2] - means[1] > -Z_LIMIT * np.hypot(errs[2], errs[1]))


def test_equiangular_share_follows_how_flat_the_segment_is():
    """The next event's equiangular share (path_kernels._equiangular_share): ~1 where the light is
    far within a mean free path of the ray and the phase is isotropic, 1/2 (Cycles' fixed share) in
    dense media and for peaked phases, never outside [1/2, 1] (a share of 0 or 1 drops a technique;
    the quadrature test above checks the mixture stays unbiased, and its variance is what the share
    changes: README, session 17)."""
    from volpath_native.path_kernels import _equiangular_share

    grey = (1.0 / 3.0,) * 3
    thin, dense = (0.25,) * 3, (50.0,) * 3
    assert _equiangular_share(0.01, grey, thin, 0.0) > 0.99
    assert abs(_equiangular_share(1.0, grey, dense, 0.0) - 0.5) < 1e-9
    assert _equiangular_share(0.01, grey, thin, 0.9) < 0.51
    assert _equiangular_share(0.01, grey, thin, -0.9) < 0.51
    shares = [_equiangular_share(D, grey, thin, g) for D in (0.0, 0.5, 2.0, 8.0) for g in (0.0, 0.4)]
    assert all(0.5 <= s <= 1.0 for s in shares)
    assert shares[0] > shares[2] > shares[4] > shares[6] and shares[1] > shares[3]  # falls with sigma D
