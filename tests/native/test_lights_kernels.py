"""The scalar light kernels (light_kernels) that the compiled integrator calls per path: equal to
LightSet's array API row by row, sampling consistent with evaluation (the pdf a ray finds when it
hits an emitter is the pdf with which light sampling picks that direction, which MIS needs), and
the warps they sample with (sampling.concentric_disk1, uniform_cone1, uniform_sphere1) uniform
where they claim to be (chi-square)."""
import numpy as np
import pytest

from volpath_native import (AreaLight, Camera, Film, Material, Mesh, PointLight, RenderSettings, Scene,
                            SpotLight, SunLight, World)
from volpath_native.accel import Accelerator
from volpath_native.jit import kernel
from volpath_native.light_kernels import (AREA_ELLIPSE, AREA_RECT, DISK, POINT, SPHERE, SUN, TRIANGLE, WORLD,
                                          distant_emission, escaped_emission_mis, lamp_crossing,
                                          light_has_position, light_position, sample_light, select_light,
                                          triangle_emission)
from volpath_native.lights import LightSet
from volpath_native.sampling import concentric_disk1, uniform_cone1, uniform_sphere1

from native_helpers import chi2_critical

POWER = np.array([100.0, 200.0, 50.0])


def _every_kind():
    """A LightSet with every kind of row: point, spot, soft point (disk) with and without spot,
    sphere with and without spot, rectangle, ellipse hidden from the camera, sun cones (one
    hidden), delta sun, one- and two-sided emissive triangles, constant world."""
    h = 2.0
    panel = Mesh("panel", np.array([[-1, -0.5, h], [1.5, -0.5, h], [1.5, 1, h], [-1, 1, h]], float),
                 np.array([[0, 1, 2], [0, 2, 3]]), np.array([1, 2]))
    floor = Mesh("floor", np.array([[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]], float),
                 np.array([[0, 1, 2], [0, 2, 3]]), np.array([0, 0]))
    materials = [Material("floor", base_color=0.5),
                 Material("two", base_color=0.0, emission=[2.0, 1.0, 0.5], two_sided_emission=True),
                 Material("one", base_color=0.0, emission=[1.0, 3.0, 0.5], two_sided_emission=False)]
    lights = [
        PointLight("point", [0, 0, 3], POWER, radius=0.0),
        SpotLight("spot", [1, 0, 3], POWER, radius=0.0, direction=[0, 0, -1], spot_size=np.radians(60),
                  spot_blend=0.3),
        PointLight("disk", [0, 1, 3], POWER, radius=0.4, soft_falloff=True),
        SpotLight("spot_disk", [0, -1, 3], POWER, radius=0.3, soft_falloff=True, direction=[0, 0.3, -1],
                  spot_size=np.radians(80), spot_blend=0.5),
        PointLight("sphere", [-1, 0, 2.5], POWER, radius=0.5, soft_falloff=False),
        SpotLight("spot_sphere", [-2, 1, 2.5], POWER, radius=0.4, soft_falloff=False, direction=[0.2, 0, -1],
                  spot_size=np.radians(70), spot_blend=0.4),
        AreaLight("rect", [0.5, 0.5, 2.8], [1.2, 0, 0], [0, 0.8, 0], POWER, shape="rectangle"),
        AreaLight("ellipse", [-0.5, 0.5, 2.6], [0.9, 0, 0], [0, 0.6, 0], POWER, shape="ellipse",
                  visible_camera=False),
        SunLight("sun", [0.2, 0.1, -1], [3.0, 2.0, 1.0], angle=np.radians(10)),
        SunLight("hidden_sun", [-0.3, 0.1, -1], [1.0, 2.0, 1.0], angle=np.radians(20), visible_camera=False),
        SunLight("delta_sun", [0, 0.3, -1], [1.0, 1.0, 1.0], angle=0.0),
    ]
    scene = Scene(camera=Camera(np.eye(4)), film=Film(4, 4), meshes=[floor, panel], materials=materials,
                  lights=lights, world=World(background=[0.2, 0.3, 0.5]), settings=RenderSettings(samples=1))
    lights = LightSet(scene, Accelerator(scene.meshes))
    assert set(lights.kind) == {POINT, DISK, SPHERE, AREA_RECT, AREA_ELLIPSE, SUN, TRIANGLE, WORLD}
    return lights


@pytest.fixture(scope="module")
def lights():
    return _every_kind()


def _points(lights, n, seed):
    """Shading points around the lamps, some of them close to (or inside) a lamp."""
    rng = np.random.default_rng(seed)
    rows = np.arange(n) % lights.count
    p = rng.uniform([-3, -3, 0], [3, 3, 4], (n, 3))
    p[::5] = lights.position[rows[::5]] + 0.3 * rng.normal(size=(len(p[::5]), 3))
    return rng, rows, p


@kernel
def _sample_rows(T, rows, p, u1, u2, out):
    for i in range(rows.shape[0]):
        out[i] = sample_light(T, rows[i], p[i, 0], p[i, 1], p[i, 2], u1[i], u2[i], 0.5)


@kernel
def _select_rows(T, u, out):
    for i in range(u.shape[0]):
        out[i] = select_light(T, u[i])


@kernel
def _position_rows(T, rows, has, pos):
    for i in range(rows.shape[0]):
        has[i] = light_has_position(T, rows[i])
        pos[i] = light_position(T, rows[i])


def test_scalar_kernels_equal_the_array_api(lights):
    rng, rows, p = _points(lights, 4000, 1)
    u1, u2 = rng.random(len(rows)), rng.random(len(rows))
    out = np.zeros((len(rows), 8))
    _sample_rows(lights.tables, rows, p, u1, u2, out)
    ls = lights.sample(rows, p, u1, u2)
    expected = np.column_stack([ls.wi, ls.dist, ls.value, ls.pdf])
    np.testing.assert_array_equal(out, expected)
    assert np.all(np.isfinite(out[:, [0, 1, 2, 4, 5, 6, 7]]))
    # delta lights have pdf 0, and so does the constant world beside other emitters (never
    # selected, as Cycles' disabled background light); every other kind a positive pdf somewhere
    assert lights.select_prob[lights.world_row] == 0.0 and lights.tree.leaf_of_row[lights.world_row] == -1
    for row in range(lights.count):
        delta = lights.kind[row] == POINT or (lights.kind[row] == SUN and lights.cos_half[row] == 1.0)
        assert (out[rows == row, 7].max() == 0) == (delta or row == lights.world_row)

    u = np.concatenate([rng.random(1000), lights.select_cdf, [0.0, np.nextafter(1.0, 0)]])
    selected = np.zeros(len(u), np.int64)
    _select_rows(lights.tables, u, selected)
    np.testing.assert_array_equal(selected, lights.select(u))
    np.testing.assert_array_equal(selected, np.minimum(np.searchsorted(lights.select_cdf, u, "right"),
                                                       lights.count - 1))
    has, pos = np.zeros(len(rows), bool), np.zeros((len(rows), 3))
    _position_rows(lights.tables, rows, has, pos)
    np.testing.assert_array_equal(has, lights.has_position(rows))
    np.testing.assert_array_equal(has, (lights.kind[rows] != SUN) & (lights.kind[rows] != WORLD))
    np.testing.assert_array_equal(pos, lights.position[rows])


@kernel
def _crossings(T, k, o, d, tmin, tmax, out):
    for i in range(o.shape[0]):
        out[i] = lamp_crossing(T, k, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], tmin[i], tmax[i])


@kernel
def _escaped(T, d, prev_pdf, camera_ray, out):
    for i in range(d.shape[0]):
        out[i] = escaped_emission_mis(T, d[i, 0], d[i, 1], d[i, 2], prev_pdf[i], camera_ray[i])


def _power_heuristic(a, b):
    return np.where(a > 0, a * a / np.maximum(a * a + b * b, 1e-300), 1.0)


def test_lamp_crossing_and_escaped_emission_equal_the_array_api(lights):
    rng, _, o = _points(lights, 6000, 2)
    n = len(o)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    # aim a third of the rays at lamps, suns and the sky region of the sun cones
    aim = np.arange(0, n, 3)
    d[aim] = lights.sample(aim % lights.count, o[aim], rng.random(len(aim)), rng.random(len(aim))).wi
    tmin = rng.uniform(0.0, 0.5, n)
    tmax = tmin + rng.uniform(0.0, 5.0, n)
    tmax[::4] = np.inf

    crossed = lights.intersect_lamps(o, d, tmin, tmax)
    assert len(crossed) == len(lights.hittable_rows)  # every lamp is crossed by some ray
    for k in range(len(lights.hittable_rows)):
        out = np.zeros((n, 5))
        _crossings(lights.tables, k, o, d, tmin, tmax, out)
        t, radiance, pdf, camera_visible = crossed[k]
        assert camera_visible == lights.camera_visible[lights.hittable_rows[k]]
        np.testing.assert_array_equal(out[:, 0], t)
        np.testing.assert_array_equal(out[:, 1:4], radiance)
        np.testing.assert_array_equal(out[:, 4], pdf)
        hit = np.isfinite(t)
        assert 20 < hit.sum() < n and np.all((t[hit] > tmin[hit]) & (t[hit] <= tmax[hit]))
        assert np.all(pdf[hit] > 0) and np.all(radiance[~hit] == 0)

    prev_pdf = np.where(rng.random(n) < 0.3, 0.0, rng.uniform(0.01, 50.0, n))
    camera_ray = rng.random(n) < 0.5
    expected = np.zeros((n, 3))
    for radiance, lpdf, camera_visible in lights.escaped_emission(d):
        w = _power_heuristic(prev_pdf, lpdf) * (camera_visible | ~camera_ray)
        expected += radiance * w[:, None]
    out = np.zeros((n, 3))
    _escaped(lights.tables, d, prev_pdf, camera_ray, out)
    np.testing.assert_allclose(out, expected, rtol=1e-12, atol=0)
    # every distant emitter, hidden sun included, shows up along some direction
    assert np.all(out.max(axis=0) > lights.world_radiance)


@kernel
def _evaluate_samples(T, rows, p, wi, dist, out):
    """What a ray from p along wi finds at the sampled light: (t, r, g, b, pdf)."""
    for i in range(rows.shape[0]):
        row = rows[i]
        kind = T.kind[row]
        out[i, 0] = np.inf
        if kind == TRIANGLE:
            # front: the ray arrives against the triangle's normal
            front = wi[i, 0] * T.normal[row, 0] + wi[i, 1] * T.normal[row, 1] + wi[i, 2] * T.normal[row, 2] < 0
            r, g, b, pdf = triangle_emission(T, T.triangle[row], p[i, 0], p[i, 1], p[i, 2],
                                             wi[i, 0], wi[i, 1], wi[i, 2], dist[i], front, 0.5)
            out[i] = (dist[i], r, g, b, pdf)
        elif kind == SUN or kind == WORLD:
            r, g, b, pdf = distant_emission(T, row, wi[i, 0], wi[i, 1], wi[i, 2])
            out[i] = (np.inf, r, g, b, pdf)
        else:
            for k in range(T.hittable_rows.shape[0]):
                if T.hittable_rows[k] == row:
                    out[i] = lamp_crossing(T, k, p[i, 0], p[i, 1], p[i, 2], wi[i, 0], wi[i, 1], wi[i, 2],
                                           0.0, np.inf)


def test_sampled_directions_evaluate_to_the_same_pdf_and_radiance(lights):
    """Light sampling and emitter evaluation agree: a ray along a sampled direction hits the
    sampled light at the sampled distance with the sampled pdf, and value * pdf is the radiance
    it finds (spot masks aside: sampling masks per sampled point, evaluation per lamp centre)."""
    rng, rows, p = _points(lights, 8000, 3)
    ls = lights.sample(rows, p, rng.random(len(rows)), rng.random(len(rows)))
    out = np.zeros((len(rows), 5))
    _evaluate_samples(lights.tables, rows, p, ls.wi, ls.dist, out)
    sampled = ls.pdf > 0
    kind = lights.kind[rows]
    found = sampled & (out[:, 4] > 0)
    # grazing cone directions may miss the sphere numerically; nothing else may be lost
    lost = sampled & ~found
    assert np.all(kind[lost] == SPHERE) and lost.sum() < 0.002 * sampled.sum(), np.unique(kind[lost])
    np.testing.assert_allclose(out[found, 4], ls.pdf[found], rtol=1e-6)
    finite = found & np.isfinite(ls.dist)
    np.testing.assert_allclose(out[finite, 0], ls.dist[finite], rtol=1e-7)
    no_spot = found & (lights.spot_smooth[rows] == 0)
    np.testing.assert_allclose(out[no_spot, 1:4], ls.value[no_spot] * ls.pdf[no_spot, None], rtol=1e-9)
    for k in (DISK, SPHERE, AREA_RECT, AREA_ELLIPSE, SUN, TRIANGLE):  # the world: selection pdf 0 here
        assert found[kind == k].sum() > 100, k


# ---- warps ------------------------------------------------------------------------------------
@kernel
def _warp_samples(axis, cos_max, u1, u2, disk, cone, sphere):
    for i in range(u1.shape[0]):
        disk[i, 0], disk[i, 1] = concentric_disk1(u1[i], u2[i])
        cone[i, 0], cone[i, 1], cone[i, 2] = uniform_cone1(axis[0], axis[1], axis[2], cos_max, u1[i], u2[i])
        sphere[i, 0], sphere[i, 1], sphere[i, 2] = uniform_sphere1(u1[i], u2[i])


def _chi2_unit_square(a, b, bins=10):
    """Chi-square of points (a, b) against the uniform law on [0, 1]^2, bins x bins cells."""
    counts, _, _ = np.histogram2d(a, b, bins=bins, range=[[0, 1], [0, 1]])
    expected = len(a) / counts.size
    return ((counts - expected) ** 2 / expected).sum(), counts.size - 1


def test_warps_are_uniform_on_disk_cone_and_sphere():
    """Uniform by area on the unit disk: r^2 and the azimuth are independent and uniform; uniform
    by solid angle in a cone / on the sphere: cos(theta) and the azimuth are."""
    rng = np.random.default_rng(5)
    n = 100_000
    axis = np.array([0.3, -0.5, 0.81]) / np.linalg.norm([0.3, -0.5, 0.81])
    cos_max = np.cos(np.radians(35.0))
    disk, cone, sphere = np.zeros((n, 2)), np.zeros((n, 3)), np.zeros((n, 3))
    _warp_samples(tuple(axis), cos_max, rng.random(n), rng.random(n), disk, cone, sphere)
    turn = lambda y, x: (np.arctan2(y, x) / (2 * np.pi)) % 1.0

    r2 = (disk ** 2).sum(axis=1)
    assert r2.max() <= 1.0 + 1e-12
    chi2, dof = _chi2_unit_square(r2, turn(disk[:, 1], disk[:, 0]))
    assert chi2 < chi2_critical(dof), chi2
    # the test has power: the polar map with radius u (not sqrt(u)) crowds the centre
    u = rng.random(n)
    chi2, dof = _chi2_unit_square(u ** 2, rng.random(n))
    assert chi2 > chi2_critical(dof), chi2

    np.testing.assert_allclose(np.linalg.norm(cone, axis=1), 1.0, atol=1e-12)
    cos = cone @ axis
    assert cos.min() >= cos_max - 1e-12
    helper = np.cross(axis, [1.0, 0.0, 0.0])
    t = helper / np.linalg.norm(helper)
    chi2, dof = _chi2_unit_square((1.0 - cos) / (1.0 - cos_max), turn(cone @ np.cross(axis, t), cone @ t))
    assert chi2 < chi2_critical(dof), chi2

    np.testing.assert_allclose(np.linalg.norm(sphere, axis=1), 1.0, atol=1e-12)
    chi2, dof = _chi2_unit_square(0.5 * (1.0 - sphere[:, 2]), turn(sphere[:, 1], sphere[:, 0]))
    assert chi2 < chi2_critical(dof), chi2
