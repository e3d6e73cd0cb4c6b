"""Medium next-event estimation samples its distance only where the chosen light can reach
(light_segment.py, Cycles volume_valid_direct_ray_segment): the clipped segment holds every lit
point of the ray (brute force over random rays, planted too-narrow cone and ignored lamp radius
must fail), fog lit by a hard narrow spot and by a one-sided area light still matches
single-scattering quadrature, and the clipped equiangular estimator is less noisy than the
unclipped one (same run)."""
import numpy as np
import pytest

from volpath_native import (AreaLight, Camera, Material, Medium, Mesh, PointLight, RenderSettings, Scene, SpotLight,
                            World, render)
from volpath_native.accel import Accelerator
from volpath_native.camera import CameraModel
from volpath_native.grid_medium import GridMedium
from volpath_native.jit import kernel
from volpath_native.light_kernels import equiangular_centre, sample_light
from volpath_native.light_segment import light_segment
from volpath_native.lights import LightSet
from volpath_native.media import equiangular_pdf1, equiangular_sample1, equiangular_setup1
from volpath_native.phase import hg_eval

from native_helpers import Z_LIMIT, block_z_scores, box_mesh, camera_at, chi2_critical, tiny_box_film, z_scores

POWER = np.array([100.0, 200.0, 50.0])


def _light_set():
    lights = [
        SpotLight("hard", [1, 0, 3], POWER, radius=0.0, direction=[0.3, 0, -1], spot_size=np.radians(20),
                  spot_blend=0.0),
        SpotLight("wide", [0, 1, 2], POWER, radius=0.0, direction=[0, -1, 0.2], spot_size=np.radians(150),
                  spot_blend=0.2),
        SpotLight("disk", [0, -1, 3], POWER, radius=0.4, soft_falloff=True, direction=[0, 0.3, -1],
                  spot_size=np.radians(30), spot_blend=0.5),
        SpotLight("sphere", [-2, 1, 2.5], POWER, radius=0.5, soft_falloff=False, direction=[0.2, 0, -1],
                  spot_size=np.radians(40), spot_blend=0.0),
        AreaLight("rect", [0.5, 0.5, 2.8], [1.2, 0, 0], [0, 0.8, 0.3], POWER, shape="rectangle"),
        AreaLight("ellipse", [-0.5, 0.5, 1.6], [0.9, 0, 0], [0, 0.6, 0], POWER, shape="ellipse"),
        PointLight("point", [0, 0, 1], POWER, radius=0.0),
    ]
    floor = Mesh("floor", np.array([[-5, -5, -9], [5, -5, -9], [5, 5, -9], [-5, 5, -9]], float),
                 np.array([[0, 1, 2], [0, 2, 3]]), np.array([0, 0]))
    scene = Scene(camera=Camera(np.eye(4)), film=tiny_box_film(4), meshes=[floor], materials=[Material("m")],
                  lights=lights, settings=RenderSettings(samples=1))
    return LightSet(scene, Accelerator(scene.meshes))


@kernel
def _segments(T, row, o, d, t_end, out):
    for i in range(o.shape[0]):
        out[i] = light_segment(T, row, (o[i, 0], o[i, 1], o[i, 2]), (d[i, 0], d[i, 1], d[i, 2]), t_end[i])


@kernel
def _lit(T, row, points, n_samples, seed, out):
    """Whether any of n_samples light samples from each point carries light (the lamp's own
    sampling: the spot mask per sampled lamp point, the area light's side)."""
    np.random.seed(seed)
    for i in range(points.shape[0]):
        lit = False
        for _ in range(n_samples):
            s = sample_light(T, row, points[i, 0], points[i, 1], points[i, 2], np.random.random(),
                             np.random.random(), 0.5)
            if s[4] > 0.0 or s[5] > 0.0 or s[6] > 0.0:
                lit = True
                break
        out[i] = lit


def _rays(lights, row, n, seed):
    """Random rays, most of them aimed at points in front of light `row` (its cone or side)."""
    rng = np.random.default_rng(seed)
    o = rng.uniform([-4, -4, -2], [4, 4, 5], (n, 3))
    target = (lights.position[row] + rng.uniform(0.2, 6.0, (n, 1)) * lights.normal[row]
              + rng.normal(scale=0.6, size=(n, 3)))
    d = np.where(rng.random((n, 1)) < 0.7, target - o, rng.normal(size=(n, 3)))
    d /= np.linalg.norm(d, axis=1)[:, None]
    t_end = np.where(rng.random(n) < 0.3, np.inf, rng.uniform(0.5, 12.0, n))
    return o, d, t_end


def _segment_errors(lights, T_segment, row, n_rays=400, n_t=200, n_samples=48):
    """(lit points outside the clipped segment, unlit points inside it) over random rays: the
    first must be 0 (the clip never loses light); the second counts how loose it is."""
    o, d, t_end = _rays(lights, row, n_rays, seed=row)
    seg = np.empty((n_rays, 2))
    _segments(T_segment, row, o, d, t_end, seg)
    span = np.minimum(t_end, 25.0)
    t = span[:, None] * (np.arange(n_t) + 0.5)[None, :] / n_t
    points = (o[:, None, :] + t[..., None] * d[:, None, :]).reshape(-1, 3)
    lit = np.empty(len(points), np.bool_)
    _lit(lights.tables, row, points, n_samples, 7, lit)
    lit = lit.reshape(n_rays, n_t)
    inside = (t >= seg[:, :1]) & (t <= seg[:, 1:])
    assert np.all((seg[:, 0] >= 0.0) | (seg[:, 1] < seg[:, 0]))
    return int((lit & ~inside).sum()), int((~lit & inside).sum()), int(lit.sum())


@pytest.fixture(scope="module")
def lights():
    return _light_set()


NAMES = ["hard", "wide", "disk", "sphere", "rect", "ellipse", "point"]  # _light_set's rows


@pytest.mark.parametrize("name", NAMES)
def test_clipped_segment_holds_every_lit_point(lights, name):
    row = NAMES.index(name)
    lost, loose, n_lit = _segment_errors(lights, lights.tables, row)
    assert n_lit > 1000  # the rays do cross the lit region
    assert lost == 0, (lost, n_lit)
    if name in ("hard", "wide", "rect", "ellipse"):
        # exact for radius-0 spots and half-spaces: (almost) nothing unlit inside the segment
        assert loose <= 0.002 * n_lit, (loose, n_lit)


def test_planted_wrong_cones_lose_light(lights):
    # a cone of 0.8x the spot's half-angle, and a lamp radius ignored when placing the apex
    T = lights.tables
    cos_half = T.cos_half.copy()
    cos_half[0] = np.cos(0.8 * np.arccos(cos_half[0]))
    assert _segment_errors(lights, T._replace(cos_half=cos_half), 0)[0] > 50
    radius = T.radius.copy()
    radius[2] = 0.0
    assert _segment_errors(lights, T._replace(radius=radius), 2)[0] > 50
    # the area light's side flipped
    normal = T.normal.copy()
    normal[4] *= -1
    assert _segment_errors(lights, T._replace(normal=normal), 4)[0] > 50


# ---------------------------------------------------------------------------------------------
# Fog lit by a hard narrow spot / a one-sided area light vs single-scattering quadrature
# ---------------------------------------------------------------------------------------------
SIGMA_S = np.array([0.3, 0.5, 0.8])
SIGMA_A = np.array([0.1, 0.05, 0.2])
SIGMA_T = SIGMA_S + SIGMA_A
G = 0.3
SIZE = 8
SPOT = dict(position=np.array([1.6, 0.2, -3.0]), direction=np.array([-1.0, 0.0, 0.25]), size=np.radians(16))
AREA = dict(position=np.array([0.3, 2.2, -3.0]), u=np.array([0.6, 0.0, 0.0]), v=np.array([0.0, 0.45, -0.45]))


@kernel
def _centres_and_light_points(T, row, x, u1, u2, out):
    """Per (u1, u2): the equiangular centre and the light point the next event from x connects to."""
    for i in range(u1.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = equiangular_centre(T, row, u1[i], u2[i], 0.5)
        s = sample_light(T, row, x[0], x[1], x[2], u1[i], u2[i], 0.5)
        out[i, 3], out[i, 4], out[i, 5] = x[0] + s[0] * s[3], x[1] + s[1] * s[3], x[2] + s[2] * s[3]


@pytest.mark.parametrize("name", NAMES)
def test_equiangular_aims_at_the_light_point_the_next_event_connects_to(lights, name):
    """Area lamps: equiangular sampling aims at a point of the lamp drawn with the next event's
    numbers (Cycles' ls->P), spread over it; the ellipse, sampled by area from anywhere, is then
    connected to that very point (the rectangle is sampled by solid angle from the vertex); the
    other lights: their centre."""
    row = NAMES.index(name)
    rng = np.random.default_rng(row)
    u1, u2 = rng.random(64), rng.random(64)
    out = np.empty((64, 6))
    _centres_and_light_points(lights.tables, row, (0.3, -0.2, 0.4), u1, u2, out)
    centres = out[:, :3]
    if name in ("rect", "ellipse"):
        if name == "ellipse":
            np.testing.assert_allclose(centres, out[:, 3:], atol=1e-9)
        on_lamp = (centres - lights.position[row]) @ lights.normal[row]
        np.testing.assert_allclose(on_lamp, 0.0, atol=1e-9)
        assert np.ptp(centres, axis=0).max() > 0.5  # across the lamp, not its middle
    else:
        np.testing.assert_allclose(centres, np.broadcast_to(lights.position[row], centres.shape))


def _fog_scene(light, samples, seed, sampling="mis"):
    cam = Camera(camera_at([0, 0, 0]), fov=np.radians(50), clip_start=0.0, clip_end=1e4)
    return Scene(camera=cam, film=tiny_box_film(SIZE), media=[Medium("fog", SIGMA_S, SIGMA_A, g=G)],
                 world=World(medium=0), lights=[light],
                 settings=RenderSettings(samples=samples, seed=seed, volume_bounces=0, volume_sampling=sampling))


def _spot(size=SPOT["size"]):
    return SpotLight("spot", SPOT["position"], 4 * np.pi * POWER / 10, radius=0.0, direction=SPOT["direction"],
                     spot_size=size, spot_blend=0.0)


def _area():
    return AreaLight("area", AREA["position"], AREA["u"], AREA["v"], 4 * POWER, shape="rectangle")


def _camera_rays(scene):
    cam = CameraModel(scene.camera, scene.film)
    ys, xs = np.mgrid[0:SIZE, 0:SIZE] + 0.5
    o, d, _ = cam.generate_rays(xs.ravel(), ys.ravel())
    return o, d


def _along_ray(oi, di, centre, n):
    """Midpoint nodes t in [0, inf) and weights, uniform in the angle seen from `centre`."""
    delta = (centre - oi) @ di
    D = np.linalg.norm(oi + delta * di - centre)
    ta, tb = np.arctan2(-delta, D), 0.5 * np.pi
    th = ta + (np.arange(n) + 0.5) * (tb - ta) / n
    return delta + D * np.tan(th), (tb - ta) / n * D / np.cos(th) ** 2


def _spot_quadrature(scene, light, n=40000):
    """L = int e^{-st t} ss p I mask e^{-st r} / r^2 dt; many nodes: the hard edge makes the
    integrand jump."""
    o, d = _camera_rays(scene)
    intensity = light.power / (4 * np.pi)
    cos_half = np.cos(0.5 * light.spot_size)
    out = np.zeros((len(d), 3))
    for i, (oi, di) in enumerate(zip(o, d)):
        t, w = _along_ray(oi, di, light.position, n)
        to_light = light.position - (oi + t[:, None] * di)
        r = np.linalg.norm(to_light, axis=1)
        mask = (-(to_light @ light.direction) / r) > cos_half
        f = np.exp(-np.outer(t + r, SIGMA_T)) * SIGMA_S * (hg_eval(G, (to_light @ di) / r) * mask / r ** 2)[:, None]
        out[i] = (f * (w[:, None] * intensity)).sum(axis=0)
    return out.reshape(SIZE, SIZE, 3)


def _area_quadrature(scene, light, n=3000, m=16):
    """L = int e^{-st t} ss int_A Le p max(cos_l, 0) e^{-st r} / r^2 dA dt (Gauss-Legendre over
    the lamp)."""
    o, d = _camera_rays(scene)
    x, wx = np.polynomial.legendre.leggauss(m)
    a, b = np.meshgrid(0.5 * x, 0.5 * x)
    ys = light.position + a.ravel()[:, None] * light.axis_u + b.ravel()[:, None] * light.axis_v
    wy = np.outer(0.5 * wx, 0.5 * wx).ravel() * light.area
    radiance = light.power / (np.pi * light.area)
    n_l = light.direction
    out = np.zeros((len(d), 3))
    for i, (oi, di) in enumerate(zip(o, d)):
        t, w = _along_ray(oi, di, light.position, n)
        xs = oi + t[:, None] * di
        to_y = ys[None, :, :] - xs[:, None, :]
        r = np.linalg.norm(to_y, axis=2)
        cos_l = np.maximum(-(to_y @ n_l) / r, 0.0)
        phase = hg_eval(G, (to_y @ di) / r)
        g = np.exp(-SIGMA_T[None, None, :] * (t[:, None, None] + r[..., None])) * \
            (phase * cos_l / r ** 2 * wy)[..., None]
        out[i] = (g.sum(axis=1) * w[:, None]).sum(axis=0) * SIGMA_S * radiance
    return out.reshape(SIZE, SIZE, 3)


def _assert_matches(result, expected):
    z = z_scores(result.image[..., :3], result.variance, expected)
    assert np.abs(z).max() < Z_LIMIT, np.abs(z).max()
    chi2 = (z ** 2).sum(axis=(0, 1))
    assert np.all(chi2 < chi2_critical(SIZE * SIZE)), chi2
    # power: 10 % less light would be seen in the image's sum
    diff = (result.image[..., :3] - 0.9 * expected).sum(axis=(0, 1))
    assert np.all(diff / np.sqrt(result.variance.sum(axis=(0, 1))) > Z_LIMIT)


@pytest.mark.parametrize("sampling", ["mis", "equiangular"])
def test_fog_lit_by_hard_spot_matches_quadrature(sampling):
    scene = _fog_scene(_spot(), samples=1024, seed=4, sampling=sampling)
    expected = _spot_quadrature(scene, scene.lights[0])
    lit = expected[..., 1] > 0
    assert 8 < lit.sum() < SIZE * SIZE - 8  # the cone crosses part of the view only
    # planted: light lost at the cone's edge (a 10 % narrower cone) is detected
    result = render(scene)
    wrong = _spot_quadrature(scene, _spot(0.9 * SPOT["size"]))
    z = z_scores(result.image[..., :3], result.variance, wrong)
    assert np.any((z ** 2).sum(axis=(0, 1)) > chi2_critical(SIZE * SIZE))
    _assert_matches(result, expected)


@pytest.mark.parametrize("sampling", ["mis", "equiangular"])
def test_fog_lit_by_one_sided_area_light_matches_quadrature(sampling):
    scene = _fog_scene(_area(), samples=1024, seed=6, sampling=sampling)
    _assert_matches(render(scene), _area_quadrature(scene, scene.lights[0]))


def test_mis_next_event_stays_on_the_lit_segment():
    """One-sample MIS of distance and equiangular next events: both techniques draw on the lit part
    of the segment (Cycles volume_integrate_homogeneous) and one number picks the technique and its
    distance. Under a hard spot in unbounded fog MIS is then 0.07x pure equiangular's summed pixel
    variance; before (the distance technique over the whole ray, a separate technique number) it
    was 144x (measured with the old kernels: the planted error this test catches)."""
    variance = {}
    for sampling in ("mis", "equiangular"):
        result = render(_fog_scene(_spot(), samples=256, seed=9, sampling=sampling))
        variance[sampling] = result.variance[..., :3].sum()
    ratio = variance["mis"] / variance["equiangular"]
    print("summed pixel variance, MIS / equiangular", ratio)
    assert ratio < 1.0, ratio


# ---------------------------------------------------------------------------------------------
# Variance: equiangular over the clipped segment vs over the whole segment, same run
# ---------------------------------------------------------------------------------------------
@kernel
def _single_scatter_estimates(T, row, o, d, t_end, sigma_t, light, cos_half, axis, clip, u, out):
    """f(t) / pdf(t) with f = T(t) I mask / r^2 T(r), t equiangular toward the spot on the
    whole segment or on light_segment's part of it."""
    t0, t1 = 0.0, t_end
    if clip:
        t0, t1 = light_segment(T, row, o, d, t_end)
    setup = equiangular_setup1(o, d, t0, t1, light)
    for i in range(u.shape[0]):
        t = equiangular_sample1(setup, u[i])
        lx, ly, lz = light[0] - o[0] - d[0] * t, light[1] - o[1] - d[1] * t, light[2] - o[2] - d[2] * t
        r = np.sqrt(lx * lx + ly * ly + lz * lz)
        inside = -(lx * axis[0] + ly * axis[1] + lz * axis[2]) / r > cos_half
        f = np.exp(-sigma_t * (t + r)) / (r * r) if inside else 0.0
        out[i] = f / equiangular_pdf1(setup, t)


def test_clipped_equiangular_is_unbiased_and_less_noisy():
    spot = _spot()
    scene = _fog_scene(spot, 1, 1)
    lights = LightSet(scene, Accelerator(scene.meshes))
    T = lights.tables
    o, d = (0.0, 0.0, 0.0), (0.0, 0.0, -1.0)  # a camera ray crossing the spot's narrow cone
    n = 200_000
    u = np.random.default_rng(11).random(n)
    est = {}
    for clip in (False, True):
        out = np.empty(n)
        _single_scatter_estimates(T, 0, o, d, 30.0, 0.4, tuple(SPOT["position"]), np.cos(0.5 * spot.spot_size),
                                  tuple(spot.direction), clip, u, out)
        est[clip] = out
    a, b = est[False], est[True]
    z = (a.mean() - b.mean()) / np.sqrt(a.var() / n + b.var() / n)
    assert abs(z) < Z_LIMIT, z
    assert b.mean() > 0
    ratio = b.var() / a.var()
    print("variance clipped / unclipped", ratio)
    assert ratio < 0.2, ratio


# ---------------------------------------------------------------------------------------------
# Grid media NEE clips the same way: a constant grid renders like the homogeneous medium
# ---------------------------------------------------------------------------------------------
def _boxed_fog(medium, light, seed):
    cam = Camera(camera_at([0, 0, 4]), fov=np.radians(40), clip_start=0.0)
    return Scene(camera=cam, film=tiny_box_film(8), meshes=[box_mesh("bound", [-0.9] * 3, [0.9] * 3, material=0)],
                 materials=[Material("bound", surface="null", medium=0)], media=[medium], lights=[light],
                 world=World(background=0.0), settings=RenderSettings(samples=512, seed=seed, volume_bounces=0))


@pytest.mark.parametrize("light", ["spot", "area"])
def test_grid_medium_lit_by_spot_or_area_matches_homogeneous(light):
    if light == "spot":
        make = lambda size=np.radians(30): SpotLight("s", [1.6, 0.3, 0.0], 40 * POWER, radius=0.0,  # noqa: E731
                                                     direction=[-1, 0, 0.1], spot_size=size, spot_blend=0.0)
    else:
        make = lambda: AreaLight("a", [0.2, 1.3, 0.5], [0.6, 0, 0], [0, 0.45, -0.45], 20 * POWER)  # noqa: E731
    ss, sa, g = np.array([1.5, 0.8, 0.3]), np.array([0.2, 0.4, 0.1]), 0.4
    n = 8
    m = np.eye(4) * (2.0 / (n - 1))
    m[3, 3], m[:3, 3] = 1.0, -1.0
    grid = GridMedium("grid", np.ones((n, n, n), np.float32), m, ss, sa, g=g)
    a = render(_boxed_fog(grid, make(), 1))
    b = render(_boxed_fog(Medium("hom", ss, sa, g=g), make(), 2))
    z = block_z_scores(a, b)
    assert np.abs(z).max() < Z_LIMIT, np.abs(z).max()
    assert b.image[..., :3].max() > 0.01 and (b.image[..., 1] <= 0.0).sum() < 60  # lit pixels exist
    if light == "spot":
        # planted: a 20 % narrower cone in one render is seen
        c = render(_boxed_fog(Medium("hom", ss, sa, g=g), make(0.8 * np.radians(30)), 3))
        assert np.abs(block_z_scores(a, c)).max() > Z_LIMIT
