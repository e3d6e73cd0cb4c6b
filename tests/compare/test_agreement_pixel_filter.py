"""The pixel filter against Cycles: an emissive half-plane whose edge lies a quarter pixel off the
pixel grid, seen by an orthographic camera, one pixel per unit. A pixel's value is the share of
its samples that land past the edge, P(offset > d) for the pixel centre's distance d to the edge:
the filter's own distribution, read off Cycles' image and VolPath's. Each row of the image is an
independent estimate of every column's value (each pixel scrambles its own sample sequence), so
the spread over rows gives the standard errors. VolPath samples Cycles' filter table (film.py);
an exact inverse of the Blackman-Harris profile, the planted error, puts about half as many
samples 1.25 px out (4.3e-4 of them against Cycles' 7.8e-4) and must fail. Horizontal edges check
the y axis: Cycles' raster y grows upwards, and its table is not quite symmetric."""
import numpy as np
import pytest

from addon.compare import cycles_engine, volpath_engine

WIDTH, HEIGHT, SAMPLES = 8, 48, 2048
Z_LIMIT = 4.5  # over 8 columns x 3 filters


def _edge_scene(filter_type: str, filter_width: float, vertical_edge: bool = True):
    """The lit half-plane right of x = 0.25 (a vertical edge, a quarter pixel right of the
    boundary between columns 3 and 4), or, transposed, above y = 0.25 (rows 3 and 4)."""
    import bpy
    from examples import scene_builder as sb

    width, height = (WIDTH, HEIGHT) if vertical_edge else (HEIGHT, WIDTH)
    scene = sb.new_scene((width, height), SAMPLES)
    glow = sb.emission_material("Glow", (1.0, 1.0, 1.0), 1.0)
    corners = [(0.25, -100, 0), (100, -100, 0), (100, 100, 0), (0.25, 100, 0)]
    if not vertical_edge:
        corners = [(-x, y, z) for y, x, z in corners]  # (x, y) -> (-y, x): a quarter turn
    sb.add_quad(scene, "HalfPlane", corners, glow)
    camera = sb.add_camera(scene, (0.0, 0.0, 10.0), (0.0, 0.0, 0.0))
    camera.data.type = "ORTHO"
    camera.data.ortho_scale = float(max(WIDTH, HEIGHT))  # one unit per pixel
    camera.rotation_euler = (0.0, 0.0, 0.0)  # looking down -z, rows along y
    scene.cycles.pixel_filter_type = filter_type
    scene.cycles.filter_width = filter_width
    bpy.context.view_layer.update()
    return scene


def _column_statistics(image):
    """Per column: the mean over rows and its standard error from the rows' spread."""
    values = np.asarray(image, np.float64)[..., 0]
    if values.shape[0] < values.shape[1]:  # a horizontal edge: rows become the columns
        values = values.T
    return values.mean(axis=0), values.std(axis=0, ddof=1) / np.sqrt(values.shape[0])


def _z(volpath_image, cycles_image):
    mv, sv = _column_statistics(volpath_image)
    mc, sc = _column_statistics(cycles_image)
    spread = np.sqrt(sv ** 2 + sc ** 2)
    differs = np.abs(mv - mc) > 1e-6  # columns entirely on one side are exactly 0 or 1 in both
    return np.where(differs, (mv - mc) / np.maximum(spread, 1e-12), 0.0), mv, mc


def _renders(scene, seed=3):
    native_scene, _ = volpath_engine.export(scene)
    volpath = volpath_engine.render_runs(native_scene, runs=1, samples=SAMPLES, base_seed=seed)[0].image
    bounces = cycles_engine.BounceLimits.from_settings(native_scene.settings)
    cycles = cycles_engine.render_runs(scene, runs=1, samples=SAMPLES, base_seed=seed + 100, bounces=bounces)[0].image
    return volpath, cycles


@pytest.mark.agreement
@pytest.mark.parametrize("vertical_edge", [True, False], ids=["vertical", "horizontal"])
@pytest.mark.parametrize("filter_type,filter_width", [("BLACKMAN_HARRIS", 1.5), ("GAUSSIAN", 1.5), ("BOX", 1.0)])
def test_pixel_filter_matches_cycles_at_an_edge(registered_addon, filter_type, filter_width, vertical_edge):
    volpath, cycles = _renders(_edge_scene(filter_type, filter_width, vertical_edge))
    z, mv, mc = _z(volpath, cycles)
    assert np.all(np.abs(z) < Z_LIMIT), (filter_type, np.round(z, 2), mv, mc)
    # the edge's column (the fourth from the lit side's far end) is partly lit: the test sees the filter
    assert 0.0 < mc[4 if vertical_edge else 3] < 1.0


@pytest.mark.agreement
def test_an_exact_filter_inverse_disagrees_with_cycles(registered_addon, monkeypatch):
    from volpath_native import film

    def exact_table(func, width, size=film._TABLE_SIZE):
        xs, cdf = film.profile_cdf(func, width)
        return (np.interp(np.arange(size) / (size - 1), cdf, xs) + 0.5).astype(np.float32)

    monkeypatch.setattr(film, "cycles_filter_table", exact_table)
    volpath, cycles = _renders(_edge_scene("BLACKMAN_HARRIS", 1.5))
    z, mv, mc = _z(volpath, cycles)
    assert np.max(np.abs(z)) > Z_LIMIT, (np.round(z, 2), mv, mc)
