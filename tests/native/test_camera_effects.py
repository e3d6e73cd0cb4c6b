"""Depth of field, motion blur and panoramic cameras against closed forms.

Depth of field: a camera focused at f sees an emissive square at depth z through a lens point L
where the ray aimed at the pinhole ray's focus point crosses depth z; the pixel at unit-depth
position q gets Le x |aperture n square(q z f / (z - f), h f / (z - f))| / |aperture| (exact convex
geometry), so the image is the aperture's shape -- the circle of confusion, a blade polygon, an
anamorphic ellipse -- scaled by A (z - f) / (z f). Motion blur: a camera sliding past an emissive
square sees it for the part of the shutter its pixel ray crosses the square, weighted by the
shutter curve. Each test also checks a planted error (a wrong aperture, a turned polygon, a flat
shutter) that the statistic must reject.
"""
import numpy as np
import pytest
from native_helpers import camera_at, chi2_critical

import volpath_native as vp
from volpath_native.camera import CameraModel, ray_time1
from volpath_native.camera_motion import interpolate_motion1, shutter_table

SPP = 64
LE = 2.0


def _square(name, half, depth, material=0):
    v = np.array([[-half, -half, -depth], [half, -half, -depth], [half, half, -depth], [-half, half, -depth]])
    return vp.Mesh(name, v, np.array([[0, 1, 2], [0, 2, 3]]), np.array([material, material]))


def _scene(camera, size, meshes, spp=SPP, seed=3):
    return vp.Scene(camera=camera, film=vp.Film(size, size, filter="box", filter_width=1e-6), meshes=meshes,
                    materials=[vp.Material("emitter", base_color=np.zeros(3), emission=np.full(3, LE))],
                    settings=vp.RenderSettings(samples=spp, seed=seed, threads=1, max_bounces=0))


def _unit_depth_centres(size, fov):
    pixel = 2.0 * np.tan(0.5 * fov) / size
    centres = (np.arange(size) + 0.5 - 0.5 * size) * pixel
    return centres[None, :], -centres[:, None]  # x right, y up; rows from the top


def _clip(poly, axis, bound, keep_below):
    out = []
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        ina = a[axis] <= bound if keep_below else a[axis] >= bound
        inb = b[axis] <= bound if keep_below else b[axis] >= bound
        if ina:
            out.append(a)
        if ina != inb:
            t = (bound - a[axis]) / (b[axis] - a[axis])
            out.append(a + t * (b - a))
    return out


def _area(poly):
    if len(poly) < 3:
        return 0.0
    p = np.array(poly)
    return 0.5 * abs(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1)))


def _aperture_polygon(radius, blades, rotation, ratio):
    """Cycles' aperture (camera_sample_aperture): a regular polygon with corners at rotation +
    (2k + 1) pi / blades (a disk: a 720-gon), x divided by the ratio."""
    n = blades if blades >= 3 else 720
    angles = rotation + (2 * np.arange(n) + 1) * np.pi / n
    return [np.array([radius * np.cos(a) / ratio, radius * np.sin(a)]) for a in angles]


def _dof_expectation(size, fov, aperture, focus, depth, half, blades=0, rotation=0.0, ratio=1.0):
    """Le x the fraction of the aperture whose ray hits the square, per pixel centre."""
    qx, qy = _unit_depth_centres(size, fov)
    scale = depth * focus / (depth - focus)
    s = half * focus / (depth - focus)
    polygon = _aperture_polygon(aperture, blades, rotation, ratio)
    total = _area(polygon)
    out = np.zeros((size, size))
    for r in range(size):
        for c in range(size):
            cx, cy = qx[0, c] * scale, qy[r, 0] * scale
            p = polygon
            for axis, bound, below in ((0, cx + s, True), (0, cx - s, False), (1, cy + s, True), (1, cy - s, False)):
                p = _clip(p, axis, bound, below)
                if not p:
                    break
            out[r, c] = _area(p) / total
    return out


def _chi2_against(image, probability, spp=SPP):
    """Chi-square of the per-pixel hit counts against probabilities, over pixels expecting at
    least 5 hits and 5 misses; and whether a pixel that cannot be hit was. The variance is the
    binomial one of independent samples: a pixel's samples are stratified (sample_pattern), so
    its count scatters less and the statistic is conservative for the right answer, while a planted
    error must show in the bias term alone (hence more samples where the error is small)."""
    hits = np.rint(image[..., 0] / LE * spp)
    expected = probability * spp
    keep = (expected >= 5) & (spp - expected >= 5)
    var = expected * (1 - probability)
    chi2 = np.sum((hits[keep] - expected[keep]) ** 2 / var[keep])
    impossible = np.any(hits[probability == 0] > 0)
    return chi2, int(keep.sum()), impossible


DOF_CASES = {
    "circle": dict(blades=0),
    "pentagon": dict(blades=5, rotation=0.3),
    "anamorphic": dict(blades=0, ratio=2.0),
}


@pytest.mark.parametrize("case", list(DOF_CASES))
def test_bokeh_of_a_square_behind_the_focus_plane(case):
    params = DOF_CASES[case]
    size, aperture, focus, depth, half = 32, 0.05, 2.0, 4.0, 0.03
    fov = 2.0 * np.arctan(16 * 1.6e-3)
    camera = vp.Camera(camera_at([0, 0, 0]), fov=fov, aperture_size=aperture, focus_distance=focus,
                       aperture_blades=params["blades"], aperture_rotation=params.get("rotation", 0.0),
                       aperture_ratio=params.get("ratio", 1.0))
    spp = 256  # a 25 % wider aperture changes a hit probability by a few % only
    image = vp.render(_scene(camera, size, [_square("sq", half, depth)], spp=spp)).image
    true = _dof_expectation(size, fov, aperture, focus, depth, half, **params)
    chi2, dof, impossible = _chi2_against(image, true, spp)
    assert not impossible
    assert dof > 100 and chi2 < chi2_critical(dof), (chi2, dof)
    # planted errors: a 25 % wider aperture; the polygon turned by half a blade; a round, unsqueezed lens
    planted = dict(params)
    if case == "pentagon":
        planted["rotation"] = params["rotation"] + np.pi / 5
    elif case == "anamorphic":
        planted["ratio"] = 1.0
    wrong = [_dof_expectation(size, fov, aperture * 1.25, focus, depth, half, **params)]
    if case != "circle":
        wrong.append(_dof_expectation(size, fov, aperture, focus, depth, half, **planted))
    for probability in wrong:
        chi2_wrong, dof_wrong, impossible_wrong = _chi2_against(image, probability, spp)
        assert impossible_wrong or chi2_wrong > chi2_critical(dof_wrong, z=6.0), chi2_wrong


def test_focus_plane_is_sharp():
    """A square at the focus distance images exactly as through a pinhole: every sample of a pixel
    well inside (outside) it hits (misses), whatever the lens point."""
    size, fov = 16, 0.3
    camera = vp.Camera(camera_at([0, 0, 0]), fov=fov, aperture_size=0.2, focus_distance=3.0, aperture_blades=6)
    image = vp.render(_scene(camera, size, [_square("sq", 0.2, 3.0)], spp=16)).image[..., 0]
    qx, qy = _unit_depth_centres(size, fov)
    inside = (np.abs(qx) * 3.0 < 0.2 - 0.02) & (np.abs(qy) * 3.0 < 0.2 - 0.02)
    outside = (np.abs(qx) * 3.0 > 0.2 + 0.02) | (np.abs(qy) * 3.0 > 0.2 + 0.02)
    assert inside.sum() > 4 and outside.sum() > 4
    np.testing.assert_allclose(image[inside], LE, rtol=1e-5)
    assert np.all(image[outside] == 0)


# -------------------------------------------------------------------------------------------------
# Motion blur
# -------------------------------------------------------------------------------------------------
def test_flat_shutter_table_is_cycles_quirk():
    """A constant shutter curve gives Cycles' table: times (255/256)(255 u + 1/2)/256, not quite [0, 1]."""
    table = shutter_table([])
    u = np.linspace(0, 1, 1001)
    times = np.interp(u * 255, np.arange(256), table)
    np.testing.assert_allclose(times, 255 / 256 * (255 * u + 0.5) / 256, atol=1e-12)


def test_shutter_table_inverts_the_curve():
    curve = np.linspace(0.0, 1.0, 256) ** 2  # opening slowly
    table = shutter_table(curve)
    times = np.interp(np.linspace(0, 1, 20001) * 255, np.arange(256), table)
    for t in (0.3, 0.5, 0.8):  # P(time < t) = t^3 for a density proportional to t^2
        assert np.mean(times < t) == pytest.approx(t ** 3, abs=0.01)


def _rotation_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


@pytest.mark.parametrize("end_deg, half_way_deg", [(120.0, 60.0), (200.0, -80.0)])
def test_rotation_slerps_the_short_way(end_deg, half_way_deg):
    from volpath_native.camera_motion import decompose_motion
    quats, positions = decompose_motion([_rotation_z(0.0), _rotation_z(np.radians(end_deg))],
                                        [[0, 0, 0], [2.0, 0, 0]])
    rotation, position = interpolate_motion1(quats, positions, 0.5)
    np.testing.assert_allclose(np.array(rotation).reshape(3, 3), _rotation_z(np.radians(half_way_deg)), atol=1e-9)
    np.testing.assert_allclose(position, [1.0, 0, 0])
    rotation, _ = interpolate_motion1(quats, positions, 0.25)
    np.testing.assert_allclose(np.array(rotation).reshape(3, 3), _rotation_z(np.radians(half_way_deg / 2)), atol=1e-9)


def _motion_probability(size, fov, depth, half, x0, x1, table):
    """P(the pixel ray hits the square) for a camera sliding from x0 to x1: the shutter-time
    measure of {t : |x(t) + qx depth| < half} with the table's time distribution."""
    qx, qy = _unit_depth_centres(size, fov)
    def u_of(t):  # the inverse of the piecewise linear time(u): time(j / 255) = table[j]
        return np.interp(t, table, np.linspace(0, 1, 256))
    # x(t) = x0 + (x1 - x0) t; hit for t in (a, b)
    lo = (-half - qx * depth - x0) / (x1 - x0)
    hi = (half - qx * depth - x0) / (x1 - x0)
    a, b = np.minimum(lo, hi), np.maximum(lo, hi)
    p = u_of(np.clip(b, 0, 1)) - u_of(np.clip(a, 0, 1))
    p = np.where(np.abs(qy) * depth < half, p, 0.0)
    return np.broadcast_to(p, (size, size))


@pytest.mark.parametrize("curve", ["flat", "ramp"])
def test_camera_sliding_past_a_square(curve):
    size, depth, half, fov = 24, 4.0, 0.5, 0.6
    x0, x1 = -0.8, 0.8
    shutter = [] if curve == "flat" else list(np.linspace(0.0, 1.0, 256))
    steps = [camera_at([x, 0, 0]) for x in (x0, 0.5 * (x0 + x1), x1)]
    camera = vp.Camera(camera_at([0, 0, 0]), fov=fov, motion_transforms=steps, shutter_curve=shutter)
    image = vp.render(_scene(camera, size, [_square("sq", half, depth)])).image
    true = _motion_probability(size, fov, depth, half, x0, x1, shutter_table(shutter))
    chi2, dof, impossible = _chi2_against(image, true)
    assert not impossible and dof > 50 and chi2 < chi2_critical(dof), (chi2, dof)
    planted = _motion_probability(size, fov, depth, half, x0, x1, shutter_table([] if shutter else np.linspace(0, 1, 256)))
    chi2_wrong, dof_wrong, impossible_wrong = _chi2_against(image, planted)
    assert impossible_wrong or chi2_wrong > chi2_critical(dof_wrong, z=6.0), chi2_wrong


def test_motion_blur_is_the_time_average_of_static_renders():
    """The blurred image's expectation is the shutter average of the still images at the camera's
    interpolated poses (rotation included); each still pinhole image at pixel centres is exact:
    a ray-square test."""
    size, fov, depth, half = 12, 0.5, 4.0, 0.6
    steps = [camera_at([x, 0.0, 0.0], look_dir=(np.sin(a), 0.0, -np.cos(a))) for x, a in ((-0.3, -0.1), (0, 0.05), (0.2, 0.15))]
    camera = vp.Camera(camera_at([0, 0, 0]), fov=fov, motion_transforms=steps)
    blurred = vp.render(_scene(camera, size, [_square("sq", half, depth)], spp=256)).image[..., 0] / LE
    model = CameraModel(camera, vp.Film(size, size))
    times = np.interp((np.arange(2048) + 0.5) / 2048 * 255, np.arange(256), model.tables.shutter)  # stratified
    xs, ys = np.meshgrid(np.arange(size) + 0.5, np.arange(size) + 0.5)
    average = np.zeros(size * size)
    for t in times:
        rotation, position = model._pose(t)
        pose = np.eye(4)
        pose[:3, :3], pose[:3, 3] = rotation, position
        o, d, _ = CameraModel(vp.Camera(pose, fov=fov), vp.Film(size, size)).generate_rays(xs.ravel(), ys.ravel())
        hit = o + d * ((-depth - o[:, 2]) / d[:, 2])[:, None]
        average += (np.abs(hit[:, 0]) < half) & (np.abs(hit[:, 1]) < half)
    average = (average / len(times)).reshape(size, size)
    z = (blurred - average) / np.sqrt(np.maximum(average * (1 - average), 1e-3) / 256)
    assert np.abs(z).max() < 4.5, np.abs(z).max()
    assert np.any((average > 0.1) & (average < 0.9))
    # planted: the still images at the shutter's centre only (no blur)
    centre = CameraModel(vp.Camera(steps[1], fov=fov), vp.Film(size, size)).generate_rays(xs.ravel(), ys.ravel())
    hit = centre[0] + centre[1] * ((-depth - centre[0][:, 2]) / centre[1][:, 2])[:, None]
    sharp = ((np.abs(hit[:, 0]) < half) & (np.abs(hit[:, 1]) < half)).reshape(size, size).astype(float)
    assert np.abs((blurred - sharp) / np.sqrt(np.maximum(average * (1 - average), 1e-3) / 256)).max() > 6


def test_rolling_shutter_time_runs_down_the_frame():
    camera = vp.Camera(camera_at([0, 0, 0]), rolling_shutter=True, rolling_shutter_duration=0.0)
    tables = CameraModel(camera, vp.Film(10, 10)).tables
    assert ray_time1(tables, 0, 0.3) == pytest.approx(0.1)  # top row: Cycles' 1 - y / height, y = 9
    assert ray_time1(tables, 9, 0.3) == pytest.approx(1.0)
    half = CameraModel(vp.Camera(camera_at([0, 0, 0]), rolling_shutter=True, rolling_shutter_duration=0.5),
                       vp.Film(10, 10)).tables
    t = ray_time1(tables._replace(rolling_shutter=False), 0, 0.3)
    assert ray_time1(half, 0, 0.3) == pytest.approx((t - 0.5) * 0.5 + (0.1 - 0.5) * 0.5 + 0.5)


# -------------------------------------------------------------------------------------------------
# Panoramic cameras, files and bad input
# -------------------------------------------------------------------------------------------------
def test_fisheye_sees_nothing_outside_its_circle():
    camera = vp.Camera(camera_at([0, 0, 0]), projection="panoramic", panorama_type="fisheye_equidistant",
                       fisheye_fov=np.pi)
    scene = vp.Scene(camera=camera, film=vp.Film(16, 16, filter="box", filter_width=1e-6),
                     world=vp.World(background=np.array([0.5, 0.5, 0.5])),
                     settings=vp.RenderSettings(samples=2, threads=1))
    image = vp.render(scene).image[..., 0]
    centres = (np.arange(16) + 0.5) / 16 - 0.5
    r = 2 * np.hypot(centres[None, :], centres[:, None])
    np.testing.assert_allclose(image[r < 0.99], 0.5, rtol=1e-6)
    assert np.all(image[r > 1.01] == 0)


def test_equirectangular_directions_cover_the_sphere():
    """Equirectangular's image centre looks along the camera's view axis (-z), up is +y."""
    camera = vp.Camera(camera_at([0, 0, 0]), projection="panoramic", panorama_type="equirectangular")
    model = CameraModel(camera, vp.Film(8, 4))
    _, d, _ = model.generate_rays(np.array([4.0, 4.0, 6.0]), np.array([2.0, 0.0, 2.0]))
    np.testing.assert_allclose(d[0], [0, 0, -1], atol=1e-9)  # centre
    np.testing.assert_allclose(d[1], [0, 1, 0], atol=1e-9)   # top edge: the zenith
    np.testing.assert_allclose(d[2], [1, 0, 0], atol=1e-9)   # a quarter of the width right: the right


def test_vpscene_round_trip(tmp_path):
    from volpath_native.scene_io import load_scene, save_scene
    camera = vp.Camera(camera_at([0, 0, 1]), projection="panoramic", panorama_type="mirrorball", aperture_size=0.01,
                       focus_distance=2.5, aperture_blades=7, motion_transforms=[camera_at([0, 0, 1]), camera_at([1, 0, 1])],
                       shutter_curve=[0.0, 1.0, 0.5], rolling_shutter=True, name="Cam")
    scene = vp.Scene(camera=camera, film=vp.Film(4, 4))
    loaded = load_scene(save_scene(scene, tmp_path / "c.vpscene")).camera
    for key in ("projection", "panorama_type", "aperture_size", "focus_distance", "aperture_blades", "shutter_curve",
                "rolling_shutter", "name"):
        assert getattr(loaded, key) == getattr(camera, key)
    np.testing.assert_allclose(loaded.motion_transforms, camera.motion_transforms)
    # defaults stay out of the file: a plain camera is written as format 1's first files were
    import json
    import zipfile
    save_scene(vp.Scene(camera=vp.Camera(np.eye(4)), film=vp.Film(4, 4)), tmp_path / "p.vpscene")
    with zipfile.ZipFile(tmp_path / "p.vpscene") as archive:
        header = json.loads(np.load(archive.open("scene.json.npy")).tobytes())
    assert "aperture_size" not in header["camera"] and "motion_transforms" not in header["camera"]


@pytest.mark.parametrize("field, value, message", [
    ("panorama_type", "cubemap", "panorama_type: unknown value"),
    ("motion_transforms", [[1, 0, 0]], "motion_transforms\\[0\\]"),
    ("shutter_curve", [0.5, "x"], "shutter_curve"),
    ("aperture_blades", -1, "aperture_blades"),
])
def test_vpscene_camera_fields_are_checked(tmp_path, field, value, message):
    from volpath_native.scene_io import load_scene, save_scene
    path = save_scene(vp.Scene(camera=vp.Camera(np.eye(4), projection="panoramic"), film=vp.Film(4, 4)),
                      tmp_path / "c.vpscene")
    _rewrite_camera(path, {field: value})
    with pytest.raises(vp.SceneError, match=f"camera.{message}"):
        load_scene(path)


def _rewrite_camera(path, changes):
    import json
    data = dict(np.load(path))
    header = json.loads(data["scene.json"].tobytes())
    header["camera"].update(changes)
    data["scene.json"] = np.frombuffer(json.dumps(header).encode(), np.uint8)
    with open(path, "wb") as f:
        np.savez(f, **data)


def test_bad_lens_numbers_take_cycles_values_with_a_warning():
    camera = vp.Camera(np.eye(4), aperture_size=-0.1, name="Lens")
    assert any("camera 'Lens'" in w and "pinhole" in w for w in camera.validate())
    assert camera.aperture_size == 0.0
    camera = vp.Camera(np.eye(4), aperture_size=0.1, focus_distance=0.0, name="Lens")
    assert any("camera 'Lens'" in w and "1e-05" in w for w in camera.validate())
    assert camera.focus_distance == 1e-5
    camera = vp.Camera(np.eye(4), shutter_curve=[0.0, 0.0], name="Lens")
    assert any("camera 'Lens'" in w and "closed" in w for w in camera.validate()) and camera.shutter_curve == []
    with pytest.raises(vp.SceneError, match="camera 'Lens'.*aperture ratio"):
        vp.Camera(np.eye(4), aperture_ratio=0.0, name="Lens").validate()


def test_huge_aperture_and_tiny_focus_render_finite_pixels():
    """Cycles' values for an F-stop of 0 and a focus distance of 0 (aperture lens / 2e-5, focus
    1e-5): nothing is in focus, but every pixel is finite."""
    camera = vp.Camera(camera_at([0, 0, 3]), fov=0.8, aperture_size=0.05 / 2e-5, focus_distance=1e-5,
                       aperture_blades=5)
    scene = _scene(camera, 8, [_square("sq", 1.0, 0.0)], spp=4)
    scene.world = vp.World(background=np.array([0.2, 0.2, 0.2]))
    assert np.all(np.isfinite(vp.render(scene).image))


@pytest.mark.parametrize("kind", ["perspective", "orthographic", "panoramic"])
def test_near_bounds_hold_every_ray_origin(kind):
    """The box the volume-stack decision looks at holds the origin of every camera ray: any film
    position the filter reaches, lens sample and shutter time."""
    steps = [camera_at([0.0, 0.0, 2.0]), camera_at([0.4, 0.1, 2.0], look_dir=(0.2, 0.0, -1.0)),
             camera_at([0.9, 0.1, 2.2], look_dir=(0.3, 0.1, -1.0))]
    camera = vp.Camera(camera_at([0, 0, 2]), projection=kind, fov=1.2, ortho_scale=2.0, clip_start=0.5,
                       aperture_size=0.3, focus_distance=0.7, aperture_blades=5, aperture_ratio=0.5,
                       panorama_type="equirectangular", motion_transforms=steps)
    model = CameraModel(camera, vp.Film(12, 8))
    lo, hi = model.near_bounds(pad=1.5)
    rng = np.random.default_rng(5)
    n = 20000
    o, _, _ = model.generate_rays(rng.uniform(-1.5, 13.5, n), rng.uniform(-1.5, 9.5, n), rng.random(n), rng.random(n),
                                  rng.random(n))
    assert np.all(o >= lo - 1e-9) and np.all(o <= hi + 1e-9)
    assert np.all(hi - lo < 10.0)  # and it is not everything


def test_lens_reaching_into_fog_finds_each_paths_stack():
    """A camera just outside a fog box whose lens reaches into it: paths start in the stack of
    their own origin (Cycles: the camera counts as inside a volume, per-path stack init)."""
    from volpath_native.integrator import Integrator
    from native_helpers import box_mesh

    fog = box_mesh("fog", [-1, -1, -1], [1, 1, 1])
    scene = vp.Scene(camera=vp.Camera(camera_at([0, 0, 1.05]), fov=0.5, clip_start=0.01, aperture_size=0.2,
                                      focus_distance=1.0),
                     film=vp.Film(4, 4), meshes=[fog], materials=[vp.Material("fog", surface="null", medium=0)],
                     media=[vp.Medium("fog", sigma_s=1.0, sigma_a=0.0)])
    assert Integrator(scene)._stack_per_path
    scene.camera.aperture_size = 0.0
    assert not Integrator(scene)._stack_per_path
