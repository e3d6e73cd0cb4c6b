"""Emissive grid media sampled as lights from surface vertices (emissive_media): the point sampler's
pdf is the density of its points (chi-square over cells, a planted pdf error caught), the image is
the one bounce rays alone make (a z-test on paired paths, with a planted error it catches), the
floor under a glowing medium is less noisy, and media that cannot be sampled are left alone."""
import numpy as np
import pytest

from volpath_native.emissive_media import alias_table, no_emissive_media, sample_emissive_point
from volpath_native.grid_medium import GridMedium
from volpath_native.integrator import Integrator
from volpath_native.scene import Camera, Film, Material, Medium, RenderSettings, Scene, World

from native_helpers import box_mesh, camera_at, chi2_critical, icosphere


def _glow(n=10, moving=False):
    """A 1.2 m cube of absorbing medium over the floor whose emission is a ball of glow off its
    centre (a voxel emission grid: no glow in most cells)."""
    m = np.eye(4) * (1.2 / (n - 1))
    m[3, 3] = 1.0
    m[:3, 3] = [-0.6, -0.6, 0.3]
    i = np.indices((n, n, n)).transpose(1, 2, 3, 0) / (n - 1)
    r = np.linalg.norm(i - [0.6, 0.45, 0.4], axis=-1)
    emission = np.clip(1.0 - r / 0.35, 0.0, None)[..., None] * np.array([4.0, 2.0, 0.5])
    density = (0.5 + 0.5 * np.cos(6.0 * i[..., 0]) * np.cos(5.0 * i[..., 2])).astype(np.float32)
    grid = GridMedium("glow", density, m, np.zeros(3), np.full(3, 0.8), emission_grid=emission.astype(np.float32),
                      majorant_resolution=6)
    if moving:
        shifted = np.eye(4)
        shifted[0, 3] = 0.2
        grid.set_motion(np.stack([np.eye(4), shifted]), np.eye(4))
    return grid


def _scene(grid, shaped=False, film=(6, 4), inset=0.0, camera=None, haze=False):
    """The floor under the medium; its boundary a sphere (shaped), its box, or a box `inset` m inside
    it; haze: a box of absorbing haze beside it too (a volume not sampled: shadow rays step through
    the boundaries)."""
    lo, hi = grid.box_corners_world().min(axis=0), grid.box_corners_world().max(axis=0)
    bounds = (icosphere("bounds", 0.6, 2, material=1, centre=(0.0, 0.0, 0.9)) if shaped
              else box_mesh("bounds", lo + inset, hi - inset, material=1) if inset else grid.boundary_mesh(1))
    camera = camera or Camera(camera_at([0.0, -3.2, 1.6], look_dir=(0, 1, -0.55), up=(0, 0, 1)))
    return Scene(camera=camera,
                 film=Film(*film), meshes=[box_mesh("floor", [-3, -3, -0.2], [3, 3, 0.0]), bounds]
                 + ([box_mesh("haze", [-1.5, -1.2, 0.05], [1.5, -0.7, 1.0], material=2)] if haze else []),
                 materials=[Material("floor", base_color=0.7), Material("bounds", surface="null", medium=0)]
                 + ([Material("haze", surface="null", medium=1)] if haze else []),
                 media=[grid] + ([Medium("haze", 0.0, 0.6)] if haze else []), world=World(background=0.0),
                 settings=RenderSettings(samples=1, seed=5))


def _table(grid, **scene_args):
    integrator = Integrator(_scene(grid, **scene_args))
    return integrator, integrator.emitters


def _draws(table, n, seed):
    rng = np.random.default_rng(seed)
    out = np.empty((n, 3))
    pdf = np.empty(n)
    for k, (a, b, c, d) in enumerate(rng.random((n, 4))):
        # the vertices that take a sample (u < share); their points' density is pdf / share
        slot, x, pdf[k] = sample_emissive_point(table, a * table.share, b, c, d)
        assert slot == 0
        out[k] = x
    assert sample_emissive_point(table, table.share, 0.5, 0.5, 0.5)[0] == -1  # u >= share: no sample
    return out, pdf / table.share


def _alias_probabilities(keep, alias):
    """Each entry's pick probability under the table: kept at its own slot, or taken as an alias."""
    n = len(keep)
    return (keep + np.bincount(alias, weights=1.0 - keep, minlength=n)) / n


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_alias_table_picks_each_cell_by_its_weight(seed):
    """The cells' alias table (emissive_media.alias_table) gives each cell weight / sum exactly
    (cells without weight never), on weights spanning orders of magnitude with empty cells;
    planted: another cell's weight 5 % off is told apart."""
    rng = np.random.default_rng(seed)
    weights = rng.random(13824) ** 6 * (rng.random(13824) < 0.6)
    keep, alias = alias_table(weights)
    assert np.all((keep >= 0) & (keep <= 1)) and np.all((alias >= 0) & (alias < len(weights)))
    probabilities = _alias_probabilities(keep, alias)
    expected = weights / weights.sum()
    assert np.allclose(probabilities, expected, rtol=1e-9, atol=1e-15)
    assert np.all(probabilities[weights == 0] < 1e-15)
    planted = weights.copy()
    planted[np.argmax(weights)] *= 1.05
    assert not np.allclose(probabilities, planted / planted.sum(), rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("inset, planted", [(0.0, 1.0), (0.0, 1.15), (0.17, 1.0), (0.17, 1.15)])
def test_the_point_pdf_is_the_density_of_the_points(inset, planted):
    # inset: the boundary mesh a box inside the medium's (a program medium's padded box): points
    # only in it, cells partly in it picked by their part
    grid = _glow()
    _, table = _table(grid, inset=inset)
    assert table.count == 1
    points, pdf = _draws(table, 20000, 1)
    lo, hi = grid.box_corners_world().min(axis=0) + inset, grid.box_corners_world().max(axis=0) - inset
    assert np.all(points >= lo - 1e-9) and np.all(points <= hi + 1e-9)
    index = (np.c_[points, np.ones(len(points))] @ grid.world_to_index.T)[:, :3]
    cell = np.minimum((index / grid.cell_size).astype(int), grid.majorant_shape - 1)
    assert np.all(grid.emission_weight[cell[:, 0], cell[:, 1], cell[:, 2]] > 0)
    # chi-square of the cell counts against the pdf (constant per cell) x the cell's part in the box
    to_world = np.abs(np.diag(grid.index_to_world)[:3])
    box_lo, box_hi = (lo - grid.index_to_world[:3, 3]) / to_world, (hi - grid.index_to_world[:3, 3]) / to_world
    part = np.ones(len(points))
    for axis in range(3):
        a, b = cell[:, axis] * grid.cell_size[axis], (cell[:, axis] + 1) * grid.cell_size[axis]
        part *= (np.minimum(b, box_hi[axis]) - np.maximum(a, box_lo[axis])) * to_world[axis]
    flat = np.ravel_multi_index(cell.T, tuple(grid.majorant_shape))
    expected = np.zeros(grid.emission_weight.size)
    expected[flat] = planted * pdf * part
    counts = np.bincount(flat, minlength=expected.size)
    used = expected > 0
    chi2 = (((counts[used] - len(points) * expected[used]) ** 2) / (len(points) * expected[used])).sum()
    fits = chi2 < chi2_critical(used.sum() - 1)
    # E[1 / pdf] = the volume where points are drawn (every cell's part; the planted pdf is off)
    estimate = 1.0 / (planted * pdf)
    volume = np.zeros(grid.emission_weight.size)
    volume[flat] = part
    z = (estimate.mean() - volume.sum()) / (estimate.std() / np.sqrt(len(estimate)))
    if planted == 1.0:
        assert fits and abs(z) < 4, (chi2, z)
    else:  # the chi-square catches a pdf 15 % off (1 / pdf is heavy-tailed where cells glow faintly)
        assert not fits, chi2


def test_media_that_cannot_be_sampled_are_left_to_the_bounces():
    assert _table(_glow(), shaped=True)[1].count == 0  # a sphere's medium: its box is no part of it
    assert _table(_glow(moving=True))[1].count == 0
    dark = _glow()
    dark.emission_weight[:] = 0.0
    assert _table(dark)[1].count == 0


def _paired(integrator, spp, sampled):
    """Per-path radiance (mean of RGB) of spp samples per pixel, with or without the emission sample."""
    tables, density = integrator.tables, integrator._emission_density
    if not sampled:
        integrator.tables, integrator._emission_density = tables._replace(emitters=no_emissive_media()), {}
    try:
        pixels = integrator.scene.film.width * integrator.scene.film.height
        k = np.arange(pixels * spp)
        values, _ = integrator.render_paths(k % pixels, k // pixels)
    finally:
        integrator.tables, integrator._emission_density = tables, density
    return values.mean(axis=1)


@pytest.mark.parametrize("haze, planted", [(False, False), (False, True), (True, False), (True, True)])
def test_sampled_glow_keeps_the_image(haze, planted):
    # without haze the samples' transmittance is tracked where they are drawn and their shadow rays
    # ask about opaque geometry only (direct); with it they step through the boundaries as a lamp's
    integrator, table = _table(_glow(), haze=haze)
    assert table.count == 1 and table.direct != haze
    if planted:  # the point sample divides by a pdf 30 % too large
        integrator.tables = integrator.tables._replace(emitters=table._replace(cell_density=1.3 * table.cell_density))
    sampled, plain = _paired(integrator, 3000, True), _paired(integrator, 3000, False)
    assert plain.mean() > 0.0
    difference = sampled - plain
    z = difference.mean() / (difference.std() / np.sqrt(len(difference)))
    assert (abs(z) < 4) != planted, z


def test_sampled_glow_calms_the_floor():
    # a view of the floor in front of the medium: every path's radiance is glow reaching it by a bounce
    integrator, _ = _table(_glow(), camera=Camera(camera_at([0.0, -3.2, 1.6], look_dir=(0, 0.3, -1), up=(0, 1, 0)),
                                                  fov=0.3))
    sampled, plain = _paired(integrator, 3000, True), _paired(integrator, 3000, False)
    assert plain.mean() > 0.0
    assert sampled.var() < 0.25 * plain.var(), (sampled.var(), plain.var())
