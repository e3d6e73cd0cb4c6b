"""Object motion blur (issue 20): instances with motion steps traced at each ray's shutter time.

- Embree's interpolation of a moving instance equals Cycles' decomposed interpolation (slerp of
  the rotation, linear translation and scale: util/transform.h transform_motion_array_interpolate)
  -- rays at time t hit what a static copy placed at the interpolated transform is hit, and not
  what a naive matrix lerp gives (planted).
- A black quad sliding across a white sky, seen by an orthographic camera at pixel centres: each
  pixel's expectation is the fraction of the shutter it is uncovered (closed form), z-tested per
  pixel; a planted half-speed motion fails. The quad moves as an instance (object motion) and as
  a deforming mesh (vertex_motion).
- A deforming quad tilting under a sun: the image is the shutter average of albedo / pi x cos of
  the normal of the linearly interpolated corners (Cycles motion_triangle_vertices + cross), and
  not the frame's normal (planted).
"""
from __future__ import annotations

import numpy as np
import pytest

from volpath_native import Camera, Film, Material, Mesh, RenderSettings, Scene, SunLight, World, render
from volpath_native.embree import TriangleScene
from volpath_native.embree.motion import decomposed_steps

from native_helpers import Z_LIMIT, camera_at


def _slerp(a, b, t):
    cos_theta = float(np.dot(a, b))
    if cos_theta > 0.9995:
        q = (1 - t) * a + t * b
        return q / np.linalg.norm(q)
    theta = np.arccos(np.clip(cos_theta, -1, 1))
    p = b - a * cos_theta
    return a * np.cos(theta * t) + p / np.linalg.norm(p) * np.sin(theta * t)


def _rotation(q):
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def decomposed_at(transforms, time):
    """Cycles' transform_motion_array_interpolate of the steps at `time`, as a (3, 4)."""
    steps = decomposed_steps(transforms)
    maxstep = len(steps) - 1
    step = min(int(time * maxstep), maxstep - 1)
    t = time * maxstep - step
    (qa, ta, sa), (qb, tb, sb) = steps[step], steps[step + 1]
    linear = _rotation(_slerp(qa, qb, t)) @ ((1 - t) * sa + t * sb)
    return np.concatenate([linear, ((1 - t) * ta + t * tb)[:, None]], axis=1)


def _turn(angle, scale, offset):
    c, s = np.cos(angle), np.sin(angle)
    return np.concatenate([np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.diag(scale),
                           np.asarray(offset, float)[:, None]], axis=1)


def test_moving_instance_is_traced_with_decomposed_interpolation():
    rng = np.random.default_rng(4)
    centres = rng.random((300, 3)) * 2 - 1
    vertices = (centres[:, None] + rng.normal(scale=0.15, size=(300, 3, 3))).reshape(-1, 3).astype(np.float32)
    triangles = np.arange(900, dtype=np.int32).reshape(-1, 3)
    steps = np.stack([_turn(0.0, [1, 1, 1], [0, 0, 0]), _turn(1.2, [1.5, 1, 0.7], [1, 0.5, 0]),
                      _turn(2.6, [1, 1, 1], [2, 0, 0.3])])
    prototype = TriangleScene()
    prototype.add_triangles(vertices, triangles, 0)
    prototype.commit()
    moving = TriangleScene()
    moving.add_instance(prototype, steps, 0)
    moving.commit()
    n = 4000
    origins = (rng.random((n, 3)) * [6, 6, 0] + [-2, -2.5, 5]).astype(np.float32)
    directions = np.tile(np.float32([0, 0, -1]), (n, 1))
    tfar = np.full(n, 1e30, np.float32)
    lerp_mismatch = 0
    for time in (0.0, 0.2, 0.37, 0.5, 0.81, 1.0):
        times = np.full(n, time, np.float32)
        _, prim, inst, _, _ = moving.intersect(origins, directions, tfar, times)
        for transform, expect_same in ((decomposed_at(steps, time), True),):
            placed = (vertices.astype(float) @ transform[:, :3].T + transform[:, 3]).astype(np.float32)
            static = TriangleScene()
            static.add_triangles(placed, triangles, 0)
            static.commit()
            static_prim = static.intersect(origins, directions, tfar)[1]
            assert np.mean(prim == static_prim) > 0.998, (time, np.mean(prim == static_prim))
        assert np.all(inst[prim >= 0] == 0) and 0.05 < np.mean(prim >= 0) < 0.95
        # planted: interpolating the matrices linearly places the object elsewhere
        k = min(int(time * 2), 1)
        t = time * 2 - k
        lerped = (1 - t) * steps[k] + t * steps[k + 1]
        placed = (vertices.astype(float) @ lerped[:, :3].T + lerped[:, 3]).astype(np.float32)
        static = TriangleScene()
        static.add_triangles(placed, triangles, 0)
        static.commit()
        lerp_mismatch = max(lerp_mismatch, np.mean(prim != static.intersect(origins, directions, tfar)[1]))
    assert lerp_mismatch > 0.05


def _uncovered_fraction(x, lo, hi, start, end):
    """Fraction of t in [0, 1] with x outside [lo + s(t), hi + s(t)], s(t) = start + (end - start) t."""
    speed = end - start
    # covered while lo + s <= x <= hi + s  <=>  x - hi <= s <= x - lo
    a = np.clip((x - hi - start) / speed, 0, 1)
    b = np.clip((x - lo - start) / speed, 0, 1)
    return 1.0 - np.abs(b - a)


def sliding_quad_scene(start, end, steps=3, spp=256, seed=7, how="instance"):
    corners = np.float32([[-0.4, -2, 0], [0.4, -2, 0], [0.4, 2, 0], [-0.4, 2, 0]])
    quad = Mesh("quad", corners, np.int32([[0, 1, 2], [0, 2, 3]]), np.int32([0, 0]))
    shifts = np.linspace(start, end, steps)
    if how == "instance":
        quad.motion = np.stack([[np.concatenate([np.eye(3), np.float64([[s], [0], [0]])], axis=1) for s in shifts]])
        quad.instances = quad.motion[:, steps // 2].copy()
    else:
        quad.vertex_motion = np.stack([corners + np.float32([s, 0, 0]) for s in shifts])
        quad.vertices = quad.vertex_motion[steps // 2]
        quad.__post_init__()
    camera = Camera(camera_at([0, 0, 5]), projection="orthographic", ortho_scale=4.0)
    return Scene(camera=camera, film=Film(32, 4, filter="box", filter_width=1e-6), meshes=[quad],
                 materials=[Material("black", base_color=0.0)], world=World(background=1.0),
                 settings=RenderSettings(samples=spp, seed=seed, threads=1, max_bounces=0))


@pytest.mark.parametrize("how", ["instance", "deform"])
def test_sliding_quad_is_the_shutter_average(how):
    start, end = -1.2, 0.9
    result = render(sliding_quad_scene(start, end, how=how))
    image = result.image[..., 0]
    x = ((np.arange(32) + 0.5) / 32 - 0.5) * 4.0  # pixel centres across the 4 m ortho width
    expected = np.broadcast_to(_uncovered_fraction(x, -0.4, 0.4, start, end), image.shape)
    variance = np.maximum(expected * (1 - expected), 1.0 / 256) / 256
    z = (image - expected) / np.sqrt(variance)
    assert np.any((expected > 0.2) & (expected < 0.8)) and np.any(expected < 0.7)
    assert np.abs(z).max() < Z_LIMIT, np.abs(z).max()
    planted = np.broadcast_to(_uncovered_fraction(x, -0.4, 0.4, start, start + 0.5 * (end - start)), image.shape)
    assert np.abs((image - planted) / np.sqrt(variance)).max() > 2 * Z_LIMIT


def test_tilting_quad_is_shaded_with_its_normal_at_the_ray_time():
    """A big quad whose far edge rises during the shutter (vertex_motion, 3 steps), under a sun
    shining straight down, seen from above: radiance albedo / pi x cos(normal at t)."""
    albedo, tilts = 0.5, np.array([0.0, 0.5, 1.2])
    corners = lambda a: np.float32([[-3, -3, 0], [3, -3, 0], [3, 3, 6 * np.tan(a)], [-3, 3, 6 * np.tan(a)]])
    quad = Mesh("quad", corners(tilts[1]), np.int32([[0, 1, 2], [0, 2, 3]]), np.int32([0, 0]),
                vertex_motion=np.stack([corners(a) for a in tilts]))
    camera = Camera(camera_at([0, 0, 20]), projection="orthographic", ortho_scale=1.0)
    scene = Scene(camera=camera, film=Film(4, 4, filter="box", filter_width=1e-6), meshes=[quad],
                  materials=[Material("grey", base_color=albedo)],
                  lights=[SunLight("sun", [0, 0, -1], irradiance=1.0)], world=World(background=0.0),
                  settings=RenderSettings(samples=512, seed=3, threads=1, max_bounces=1))
    result = render(scene)

    def shutter_average(normal_at):
        times = (np.arange(4096) + 0.5) / 4096
        return np.mean([albedo / np.pi * normal_at(t)[2] for t in times])

    def interpolated(t):  # corners lerped between the steps around t, then the cross product
        step = min(int(t * 2), 1)
        w = t * 2 - step
        c = (1 - w) * corners(tilts[step]).astype(float) + w * corners(tilts[step + 1]).astype(float)
        n = np.cross(c[1] - c[0], c[2] - c[0])
        return n / np.linalg.norm(n)
    expected = shutter_average(interpolated)
    pixels = result.image[..., 0]
    z = (pixels - expected) / np.sqrt(np.maximum(result.variance[..., 0], 1e-12))
    assert np.abs(z).max() < Z_LIMIT, (pixels.mean(), expected)
    frame = albedo / np.pi * interpolated(0.5)[2]  # planted: the frame's normal throughout
    assert abs(frame - expected) > 0.01
    assert np.all(np.abs((pixels - frame) / np.sqrt(np.maximum(result.variance[..., 0], 1e-12))) > Z_LIMIT)


def test_moving_instance_normals_are_the_inverse_transpose_at_the_time():
    """instance_motion.normal_map1 (the stages' normals of moving instances) against M(t)^-T n of
    the decomposed interpolation, mirrored steps included (outward stays outward)."""
    from volpath_native.instance_motion import motion_table, normal_map1, transform_at1
    steps = np.stack([_turn(0.0, [1, 1, 1], [0, 0, 0]), _turn(1.2, [1.5, 1, 0.7], [1, 0.5, 0]),
                      _turn(2.6, [1, 1, 1], [2, 0, 0.3])])
    mirrored = steps * np.array([-1.0, 1, 1, 1])  # x column negated: det < 0 at every step
    counts, table = motion_table([steps, mirrored])
    n = np.array([0.3, -0.5, 0.8])
    for k, transforms in enumerate((steps, mirrored)):
        for time in (0.0, 0.3, 0.5, 0.9, 1.0):
            expected = decomposed_at(transforms, time)
            m, offset = transform_at1(table, counts[k], k, time)
            np.testing.assert_allclose(np.reshape(m, (3, 3)), expected[:, :3], atol=1e-9)
            np.testing.assert_allclose(offset, expected[:, 3], atol=1e-9)
            got = np.array(normal_map1(table, counts[k], k, time, *n))
            want = np.linalg.inv(expected[:, :3]).T @ n
            np.testing.assert_allclose(got / np.linalg.norm(got), want / np.linalg.norm(want), atol=1e-9)
