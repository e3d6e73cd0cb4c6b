"""Program media whose lookups run the reduced program (shading/extinction_slice.py) render the
image of the full program where the Principled Volume's Color stays <= 1 (their extinction is the
same), and the roulette's correction restores the extinction where it exceeds 1 (a correction that
never runs -- the planted error -- is caught). Paired paths (the same random numbers), z-test on the difference; the
roulette's correction where the Color exceeds 1, on shadow-ray transmittance."""
import numpy as np
import pytest

from volpath_native.integrator import Integrator
from volpath_native.program_medium import ProgramMedium
from volpath_native.scene import Camera, Film, Material, PointLight, RenderSettings, Scene, World
from volpath_native.shading.builder import ProgramBuilder
from volpath_native.shading.extinction_slice import extinction_program
from volpath_native.shading.program import MATH, MIX_BLEND, TEXCO_OBJECT
from volpath_native.shading.textures.noise import NOISE_FBM

from native_helpers import box_mesh, camera_at


def _noisy_program(tint):
    """Density = 4 x Noise Fac, Color = Mix(0.3, tint, Noise Color) (> 1 where tint is large)."""
    b = ProgramBuilder("noisy")
    p = b.alloc(3)
    b.emit("TEXCO", TEXCO_OBJECT, p)
    fac, colour = b.alloc(), b.alloc(3)
    b.emit("TEX_NOISE", 3, NOISE_FBM, 1, 1, p, b.const(0.0), b.const(2.0), b.const(2.0), b.const(0.5),
           b.const(2.0), b.const(0.0), b.const(1.0), b.const(0.0), fac, colour)
    density = b.alloc()
    b.emit("MATH", MATH["MULTIPLY"], fac, b.const(4.0), b.const(0.0), density)
    mixed = b.alloc(3)
    b.emit("MIX_COLOR", MIX_BLEND["MIX"], 1, 0, b.const(0.3), b.const([tint, 0.8 * tint, 0.6 * tint]), colour, mixed)
    b.emit("PRINCIPLED_VOLUME", 0, b.const(1.0), mixed, density, b.const(0.3), b.const([0.0] * 3), b.const(0.0),
           b.const([1.0] * 3), b.const(0.0), b.const([1.0] * 3), b.const(1000.0))
    return b.build()


def _scene(medium):
    bound = box_mesh("bound", [-1, -1, -1], [1, 1, 1], material=1)
    return Scene(camera=Camera(camera_at([0, -4.0, 0.5], look_dir=(0, 1, -0.15), up=(0, 0, 1))), film=Film(6, 5),
                 meshes=[box_mesh("floor", [-3, -3, -1.4], [3, 3, -1.2]), bound],
                 materials=[Material("floor", base_color=0.6), Material("bound", surface="null", medium=0)],
                 media=[medium], lights=[PointLight("lamp", [1.5, -1.5, 2.0], power=300.0)],
                 world=World(background=0.2), settings=RenderSettings(samples=1, seed=3, volume_bounces=3))


def _paths(medium, spp):
    integrator = Integrator(_scene(medium))
    pixels = integrator.scene.film.width * integrator.scene.film.height
    k = np.arange(pixels * spp)
    values, _ = integrator.render_paths(k % pixels, k // pixels)
    return values.mean(axis=1)


def _medium(tint, reduced, correction=None):
    program = _noisy_program(tint)
    medium = ProgramMedium("noisy", program, np.eye(4), ([-1, -1, -1], [1, 1, 1]))
    medium.extinction = extinction_program(program) if reduced else None
    if correction is not None:
        medium.correction_probability = correction
    return medium


def test_a_colour_within_one_uses_the_reduced_program():
    assert _medium(0.9, True).extinction is not None
    assert ProgramMedium("noisy", _noisy_program(0.9), np.eye(4), ([-1, -1, -1], [1, 1, 1])).extinction is not None
    # a Color above 1 somewhere: the medium keeps the full program (the roulette would add variance)
    assert ProgramMedium("noisy", _noisy_program(3.0), np.eye(4), ([-1, -1, -1], [1, 1, 1])).extinction is None


def test_reduced_lookups_keep_the_image():
    reduced = _paths(_medium(0.9, True), 600)
    full = _paths(_medium(0.9, False), 600)
    difference = reduced - full
    z = difference.mean() / (difference.std() / np.sqrt(len(difference)))
    assert full.mean() > 0.01
    assert abs(z) < 4, z


@pytest.mark.parametrize("correction, planted", [(None, False), (1e-12, True)])
def test_the_roulette_restores_the_extinction_where_the_colour_exceeds_one(correction, planted):
    # tint (1.2, 0.96, 0.72): the red Color exceeds 1 over about half the box, so the reduced
    # program's red extinction (the density) is too small there and the roulette's correction must
    # restore it: shadow-ray transmittance (residual ratio tracking) as the full program's. Planted:
    # a correction that never runs (probability 1e-12).
    n = 100000
    origins = np.tile([0.0, -2.0, 0.1], (n, 1))
    directions = np.tile(np.array([0.0, 1.0, 0.05]) / np.hypot(1.0, 0.05), (n, 1))
    full = _medium(1.2, False).transmittance(origins, directions, 4.0, np.random.default_rng(2))
    reduced = _medium(1.2, True, correction).transmittance(origins, directions, 4.0, np.random.default_rng(2))
    z = (reduced.mean(0) - full.mean(0)) / np.sqrt(reduced.var(0) / n + full.var(0) / n + 1e-30)
    assert full[:, 0].mean() > 1e-3
    assert (np.abs(z).max() < 4) != planted, z
