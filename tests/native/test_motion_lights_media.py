"""Moving emitters and moving medium boundaries (issue 20): traced, sampled and entered at each
ray's shutter time, as Cycles (kernel/light/triangle.h triangle_world_space_vertices at the ray's
time; integrator_volume_stack_init walks with the camera ray's time).

- A tilting, sliding emissive quad over a diffuse floor, seen from above by an orthographic camera
  at pixel centres: each pixel's expectation is the shutter average of the emitter's radiance where
  it covers the pixel, else albedo / pi x the floor's irradiance from the quad placed at the
  decomposed-interpolated transform (the polygon's closed-form irradiance). Light sampling, MIS
  hits and camera hits all see the emitter at the ray's time; the emitter left at the frame's place
  (what VolPath did before) fails.
- A fog box (absorbing) sliding away from a perspective camera that sits inside it for the first
  third of the shutter: each path starts in the box's volume stack at its own time. The
  expectation is 1/3 exp(-sigma d) + 2/3; a stack taken at the frame's time fails.
"""
from __future__ import annotations

import numpy as np

from volpath_native import Camera, Film, Material, Medium, Mesh, RenderSettings, Scene, World, render

from native_helpers import Z_LIMIT, box_mesh, camera_at
from test_object_motion import decomposed_at

QUAD = np.float64([[-0.3, -0.3, 0], [0.3, -0.3, 0], [0.3, 0.3, 0], [-0.3, 0.3, 0]])


def _tilt(angle, x):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0, s, x], [0, 1, 0, 0.1], [-s, 0, c, 0.8]])


STEPS = np.stack([_tilt(0.0, -0.7), _tilt(0.6, 0.0), _tilt(1.3, 0.6)])


def _polygon_irradiance(points, polygon):
    """Irradiance at `points` (N, 3) on an upward (+z) surface from a unit-radiance Lambertian
    polygon (K, 3), either face (Lambert's formula: 1/2 sum of edge angles x the z of the edges'
    unit normals)."""
    r = polygon[None, :, :] - points[:, None, :]
    r /= np.linalg.norm(r, axis=2, keepdims=True)
    s = np.roll(r, -1, axis=1)
    angle = np.arccos(np.clip(np.einsum("nki,nki->nk", r, s), -1, 1))
    cross = np.cross(r, s)
    cross /= np.maximum(np.linalg.norm(cross, axis=2, keepdims=True), 1e-30)
    return np.abs(0.5 * np.sum(angle * cross[..., 2], axis=1))


def _inside(points, polygon):
    """Whether (x, y) of points lie under the convex polygon's projection (vertical rays)."""
    inside = np.ones(len(points), bool)
    sign = None
    for a, b in zip(polygon, np.roll(polygon, -1, axis=0)):
        side = (b[0] - a[0]) * (points[:, 1] - a[1]) - (b[1] - a[1]) * (points[:, 0] - a[0])
        sign = np.sign(side) if sign is None else sign
        inside &= np.sign(side) == sign
    return inside


def _expected_emitter_image(pixels, radiance, albedo, transform_at, times):
    total = np.zeros(len(pixels))
    for time in times:
        m = transform_at(time)
        polygon = QUAD @ m[:, :3].T + m[:, 3]
        floor = albedo / np.pi * radiance * _polygon_irradiance(pixels, polygon)
        total += np.where(_inside(pixels, polygon), radiance, floor)
    return total / len(times)


def test_moving_emitter_is_the_shutter_average_of_static_ones():
    radiance, albedo, size, width = 3.0, 0.8, 8, 2.4
    emitter = Mesh("emitter", QUAD, np.int32([[0, 1, 2], [0, 2, 3]]), np.int32([1, 1]),
                   instances=STEPS[1][None], motion=STEPS[None])
    floor = Mesh("floor", np.float64([[-4, -4, 0], [4, -4, 0], [4, 4, 0], [-4, 4, 0]]),
                 np.int32([[0, 1, 2], [0, 2, 3]]), np.int32([0, 0]))
    camera = Camera(camera_at([0, 0, 5]), projection="orthographic", ortho_scale=width)
    scene = Scene(camera=camera, film=Film(size, size, filter="box", filter_width=1e-6), meshes=[floor, emitter],
                  materials=[Material("floor", base_color=albedo),
                             Material("emitter", base_color=0.0, emission=radiance)],
                  world=World(background=0.0),
                  settings=RenderSettings(samples=256, seed=11, threads=1, max_bounces=1))
    result = render(scene)
    assert not any("motion" in w for w in result.warnings), result.warnings
    centres = ((np.arange(size) + 0.5) / size - 0.5) * width
    x, y = np.meshgrid(centres, -centres)  # row 0 is the top of the image (+y)
    pixels = np.stack([x.ravel(), y.ravel(), np.zeros(size * size)], axis=1)
    times = (np.arange(1024) + 0.5) / 1024
    expected = _expected_emitter_image(pixels, radiance, albedo, lambda t: decomposed_at(STEPS, t), times)
    expected = expected.reshape(size, size)
    image, variance = result.image[..., 0], np.maximum(result.variance[..., 0], 1e-8)
    z = (image - expected) / np.sqrt(variance)
    assert np.abs(z).max() < Z_LIMIT, np.abs(z).max()
    # planted: the emitter left where it is at the frame (rendered still)
    still = _expected_emitter_image(pixels, radiance, albedo, lambda t: STEPS[1], [0.5]).reshape(size, size)
    assert np.abs((image - still) / np.sqrt(variance)).max() > 3 * Z_LIMIT


def _box_length(directions, lo, hi):
    """Length of the rays from the origin along unit directions (N, 3) inside the box [lo, hi]."""
    with np.errstate(divide="ignore", invalid="ignore"):
        a, b = lo / directions, hi / directions
    near = np.nanmax(np.minimum(a, b), axis=1)
    far = np.nanmin(np.maximum(a, b), axis=1)
    return np.maximum(far - np.maximum(near, 0.0), 0.0)


def test_paths_start_in_a_moving_fog_box_at_their_own_time():
    sigma, size, fov = 1.5, 4, 0.1
    box = box_mesh("fog", [-1, -1, -1], [1, 1, 1], material=0)
    shift = lambda s: np.array([[1, 0, 0, s], [0, 1, 0, 0], [0, 0, 1, 0]], float)
    box.instances, box.motion = shift(1.5)[None], np.stack([shift(0.0), shift(1.5), shift(3.0)])[None]
    camera = Camera(camera_at([0, 0, 0]), fov=fov, clip_start=1e-4, clip_end=100)
    scene = Scene(camera=camera, film=Film(size, size, filter="box", filter_width=1e-6), meshes=[box],
                  materials=[Material("fog", surface="null", medium=0)],
                  media=[Medium("fog", sigma_s=0.0, sigma_a=sigma)], world=World(background=1.0),
                  settings=RenderSettings(samples=256, seed=5, threads=1))
    result = render(scene)
    image, spread = result.image[..., 0], np.sqrt(np.maximum(result.variance[..., 0], 1e-8))
    # pixel-centre rays; the box [s - 1, s + 1] x [-1, 1]^2 at s = 3 t holds the camera while t < 1/3
    centres = ((np.arange(size) + 0.5) / size * 2 - 1) * np.tan(0.5 * fov)
    x, y = np.meshgrid(centres, -centres)
    d = np.stack([x.ravel(), y.ravel(), -np.ones(size * size)], axis=1)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    times = (np.arange(4096) + 0.5) / 4096
    expected = np.mean([np.exp(-sigma * _box_length(d, np.array([3 * t - 1, -1, -1]), np.array([3 * t + 1, 1, 1])))
                        for t in times], axis=0).reshape(size, size)
    assert np.all(expected < 0.8) and np.all(expected > 0.7)
    z = (image - expected) / spread
    assert np.abs(z).max() < Z_LIMIT, (image, expected)
    # planted: the stack taken at the frame's time (the box has left the camera then): 1 everywhere
    assert np.all((1.0 - image) / spread > 2 * Z_LIMIT)


def _object_textured_strip(motion_steps):
    """A long diffuse strip whose colour is a 4-texel image read at its Texture Coordinate Object
    (repeat, closest), moving along x, under a white sky, seen from above at pixel centres."""
    from volpath_native.bsdfs.nodes import SurfaceNode
    from volpath_native.shading import program as P
    from volpath_native.shading.builder import ProgramBuilder
    from volpath_native.shading.images import EXT_REPEAT, INTERP_CLOSEST, Image
    from volpath_native.surface_programs import SurfaceProgram
    b = ProgramBuilder("object strip")
    co = b.alloc(3)
    b.emit("TEXCO", P.TEXCO_OBJECT, co)
    color, alpha = b.alloc(3), b.alloc()
    b.emit("IMAGE_TEXTURE", 0, 0, 0, INTERP_CLOSEST, EXT_REPEAT, 0, 0, co, color, alpha)
    program = SurfaceProgram(b.build(), bindings=[(0, "color", color)])
    texels = np.array([[[40, 40, 40, 255], [250, 250, 250, 255], [120, 120, 120, 255], [190, 190, 190, 255]]],
                      np.uint8)
    strip = Mesh("strip", np.float64([[-6, -1, 0], [6, -1, 0], [6, 1, 0], [-6, 1, 0]]),
                 np.int32([[0, 1, 2], [0, 2, 3]]), np.int32([0, 0]),
                 instances=motion_steps[len(motion_steps) // 2][None], motion=motion_steps[None])
    material = Material("strip", surface_nodes=[SurfaceNode.for_kind("diffuse")], surface_program=program)
    camera = Camera(camera_at([0, 0, 5]), projection="orthographic", ortho_scale=2.0)
    scene = Scene(camera=camera, film=Film(8, 1, filter="box", filter_width=1e-6), meshes=[strip],
                  materials=[material], world=World(background=1.0),
                  images=[Image("texels", texels, compress_as_srgb=False)],
                  settings=RenderSettings(samples=1024, seed=2, threads=1, max_bounces=0))
    return scene, texels[0, :, 0] / 255.0


def test_object_coordinates_of_a_moving_object_follow_it_over_the_shutter():
    """The strip slides by 0.5 m over the shutter: each pixel averages the texels passing under it
    (object x = world x - shift(t)); the frame's object coordinates throughout (VolPath before)
    fail."""
    shift = lambda s: np.array([[1, 0, 0, s], [0, 1, 0, 0], [0, 0, 1, 0]], float)
    scene, albedo = _object_textured_strip(np.stack([shift(0.0), shift(0.25), shift(0.5)]))
    result = render(scene)
    x = ((np.arange(8) + 0.5) / 8 - 0.5) * 2.0
    times = (np.arange(4096) + 0.5) / 4096

    def texel(u):
        return albedo[np.floor(np.mod(u, 1.0) * 4).astype(int)]
    expected = np.mean([texel(x - 0.5 * t) for t in times], axis=0)
    frame = texel(x - 0.25)
    image, variance = result.image[0, :, 0], np.maximum(result.variance[0, :, 0], 1e-10)
    # a diffuse surface under a white sky: albedo x a path weight of mean 1 (MIS of sky and BSDF)
    assert np.abs((image - expected) / np.sqrt(variance)).max() < Z_LIMIT, (image, expected)
    assert np.abs((image - frame) / np.sqrt(variance)).max() > 3 * Z_LIMIT
