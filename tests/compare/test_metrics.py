"""The comparison statistics: calibrated when the engines agree, sensitive when one is biased."""
import numpy as np
import pytest

from addon.compare import metrics

H, W = 24, 24


@pytest.mark.parametrize("t, dof, expected", [
    (12.706, 1, 0.05), (63.657, 1, 0.01), (4.303, 2, 0.05), (4.604, 4, 0.01), (2.228, 10, 0.05),
    (3.169, 10, 0.01), (2.042, 30, 0.05), (2.5758, 1000, 0.0102), (0.0, 5, 1.0),
])
def test_student_t_matches_table(t, dof, expected):
    p = float(metrics.student_t_two_sided_p(t, dof))
    assert p == pytest.approx(expected, rel=2e-3, abs=1e-4)


def test_student_t_is_symmetric_and_monotone():
    t = np.linspace(-8, 8, 81)
    p = metrics.student_t_two_sided_p(t, 7)
    np.testing.assert_allclose(p, p[::-1], rtol=1e-12)
    assert np.all(np.diff(p[40:]) < 0)


def _runs(rng, k, mean_image, samples_per_run=16):
    """k runs, each the mean of `samples_per_run` exponential samples per pixel (a skewed,
    renderer-like distribution) with the given per-pixel mean."""
    samples = rng.exponential(1.0, size=(k, samples_per_run) + mean_image.shape)
    return list(samples.mean(axis=1) * mean_image)


def _scene_like_image(rng):
    base = np.linspace(0.05, 2.0, H * W).reshape(H, W, 1)
    return base * np.array([1.0, 0.7, 0.4]) + 0.01


def test_pixel_test_false_rejection_rate_is_calibrated():
    """With both engines unbiased, the image-level test rejects about alpha of the time. With the
    normal distribution instead of Student's t (variances from 6 runs) it would reject ~always."""
    rng = np.random.default_rng(1)
    truth = _scene_like_image(rng)
    alpha, trials = 0.2, 120
    rejections = 0
    for _ in range(trials):
        a = metrics.run_statistics(_runs(rng, 6, truth))
        b = metrics.run_statistics(_runs(rng, 6, truth))
        rejections += not metrics.pixel_t_test(a, b, alpha).passed
    # Binomial(120, 0.2): mean 24, sd 4.4; accept 5 sd either way (Welch's dof is approximate).
    assert 2 <= rejections <= 46, rejections


def test_pixel_test_passes_unbiased_and_flags_biased_image():
    rng = np.random.default_rng(2)
    truth = _scene_like_image(rng)
    a = metrics.run_statistics(_runs(rng, 8, truth, 64))
    b = metrics.run_statistics(_runs(rng, 8, truth, 64))
    assert metrics.pixel_t_test(a, b).passed
    # 60% too bright in a 4x4 corner: a localised estimator bug.
    biased = truth.copy()
    biased[:4, :4] *= 1.6
    c = metrics.run_statistics(_runs(rng, 8, biased, 64))
    result = metrics.pixel_t_test(c, b)
    assert not result.passed
    assert result.failed[:4, :4].sum() >= 8 and result.failed[4:, 4:].sum() == 0
    assert result.worst()["row"] < 4 and result.worst()["column"] < 4


def test_mean_test_detects_small_global_bias():
    rng = np.random.default_rng(3)
    truth = _scene_like_image(rng)
    a = metrics.run_statistics(_runs(rng, 8, truth, 64))
    b = metrics.run_statistics(_runs(rng, 8, truth, 64))
    same = metrics.mean_test(a, b)
    assert same.passed
    assert np.all(np.abs(same.ratio - 1) <= same.ratio_tolerance)
    c = metrics.run_statistics(_runs(rng, 8, truth * 1.03, 64))  # 3% too bright everywhere
    biased = metrics.mean_test(c, b)
    assert not biased.passed
    assert np.all(biased.ratio > 1.01)


def test_zero_variance_pixels():
    """Constant pixels (e.g. background only) agree when equal and disagree when not."""
    constant = np.full((4, 4, 3), 0.5)
    a = metrics.run_statistics([constant, constant, constant])
    assert metrics.pixel_t_test(a, a).passed
    b = metrics.run_statistics([constant * 1.01] * 3)
    assert not metrics.pixel_t_test(a, b).passed


def test_relmse_and_relative_difference():
    ref = np.full((2, 2, 3), 1.0)
    assert metrics.relmse(ref, ref) == 0.0
    assert metrics.relmse(ref * 1.1, ref) == pytest.approx(0.01 / (1 + metrics.RELMSE_EPSILON))
    diff = metrics.signed_relative_difference(ref * 1.1, ref)
    np.testing.assert_allclose(diff, 0.1 / 1.05)
    assert np.all(metrics.signed_relative_difference(ref, ref * 1.1) < 0)
    with pytest.raises(ValueError):
        metrics.relmse(ref, np.ones((3, 2, 3)))


def test_false_colour_and_scale():
    colours = metrics.false_colour(np.array([[-1.0, 0.0, 1.0, 5.0]]), 1.0)
    assert colours.shape == (1, 4, 3)
    assert colours[0, 0, 2] > colours[0, 0, 0]          # negative: blue
    assert colours[0, 2, 0] > colours[0, 2, 2]          # positive: red
    np.testing.assert_allclose(colours[0, 1], [0.97, 0.97, 0.97])
    np.testing.assert_allclose(colours[0, 3], colours[0, 2])  # clipped at the scale
    assert metrics.difference_scale(np.full((4, 4), 0.03)) == 0.05
    assert metrics.difference_scale(np.zeros((4, 4))) == 0.01


def test_contact_sheet_png(tmp_path):
    pytest.importorskip("OpenImageIO")
    from addon.compare import sheet
    from volpath_native import imageio

    rng = np.random.default_rng(4)
    a, b = rng.random((16, 20, 3)), rng.random((16, 20, 3))
    rows = [[sheet.render_panel("A", a, 0.0, "caption"), sheet.render_panel("B", b, 0.0),
             sheet.difference_panel("A - B", metrics.signed_relative_difference(a, b))]]
    path = sheet.write_contact_sheet(tmp_path / "sheet.png", rows, "title")
    pixels = imageio.read_exr(path)
    assert pixels.shape[1] >= 3 * 256 and pixels.shape[0] > 256
    assert pixels.max() > 0.5


def test_block_test_finds_regional_bias_the_pixel_test_misses():
    """A 6% bias over a 12x12 region is below what single pixels resolve at this noise level but
    clear in 4x4 / 8x8 block means; the combined verdict must catch it and pass the unbiased case."""
    rng = np.random.default_rng(5)
    truth = _scene_like_image(rng)
    biased = truth.copy()
    biased[:12, :12] *= 1.06
    reference = metrics.run_statistics(_runs(rng, 8, truth, 16))
    same = metrics.compare_runs(metrics.run_statistics(_runs(rng, 8, truth, 16)), reference)
    assert same.passed and set(same.blocks) == {4, 8}
    result = metrics.compare_runs(metrics.run_statistics(_runs(rng, 8, biased, 16)), reference)
    assert result.pixel.passed          # invisible pixel by pixel...
    assert not result.passed            # ...but not to the block tests
    assert not all(t.passed for t in result.blocks.values())


def test_block_statistics_average_runs():
    runs = [np.arange(4 * 4 * 3, dtype=float).reshape(4, 4, 3) + k for k in range(3)]
    stats = metrics.block_statistics(metrics.run_statistics(runs), 2)
    assert stats.mean.shape == (2, 2, 3)
    np.testing.assert_allclose(stats.mean[0, 0], np.mean(runs, axis=0)[:2, :2].mean(axis=(0, 1)))
    with pytest.raises(ValueError):
        metrics.block_statistics(metrics.run_statistics(runs), 8)


def test_block_relmse_test_is_calibrated_and_sees_a_spread_out_bias():
    """Agreeing engines (skewed per-sample noise, 4 and 3 runs as the fluid agreement test) pass at
    at most at the nominal rate; a 3 % bias over the whole image, which no pixel resolves (7 %
    noise per pixel and run set), fails: the relMSE sums it over the blocks."""
    rng = np.random.default_rng(6)
    truth = _scene_like_image(rng)
    alpha, trials, rejections = 0.1, 60, 0
    for _ in range(trials):
        a = metrics.run_statistics(_runs(rng, 4, truth, 8))
        b = metrics.run_statistics(_runs(rng, 3, truth, 8))
        test = metrics.block_relmse_test(a, b, 4, alpha)
        rejections += not test.passed
        assert 0.3 < test.relmse / test.expected < 3.0
    assert rejections <= 0.1 * trials + 4 * np.sqrt(0.1 * 0.9 * trials), rejections  # not anti-conservative
    reference = metrics.run_statistics(_runs(rng, 3, truth, 64))
    assert metrics.block_relmse_test(metrics.run_statistics(_runs(rng, 4, truth, 64)), reference, 4, 1e-3).passed
    biased = metrics.run_statistics(_runs(rng, 4, truth * 1.03, 64))
    test = metrics.block_relmse_test(biased, reference, 4, 1e-3)
    assert not test.passed and metrics.pixel_t_test(biased, reference).passed


def test_pixel_whose_runs_all_agree_borrows_its_neighbours_variance():
    """Stratified samples with discrete outcomes can give one value in every run at a pixel (an
    estimated variance of 0) in both engines, a step apart. Within its neighbourhood's noise this
    is no evidence of bias; without the pooling (the planted contrast) Welch's t is unbounded."""
    rng = np.random.default_rng(7)
    truth = _scene_like_image(rng)
    a_runs, b_runs = _runs(rng, 4, truth, 32), _runs(rng, 4, truth, 32)
    for run in a_runs:
        run[5, 5] = truth[5, 5]
    for run in b_runs:
        run[5, 5] = truth[5, 5] * 1.05
    a, b = metrics.run_statistics(a_runs), metrics.run_statistics(b_runs)
    assert metrics.pixel_t_test(a, b).passed
    assert not metrics.pixel_t_test(a, b, pool_neighbours=False).passed


def test_block_reached_by_rare_samples_borrows_its_neighbours_variance():
    """A 4x4 block that only the filter's rare tail samples reach: one engine's runs all give
    exactly 0, the other's a steady -1e-6 (the procedural fire's column beside negative-green
    flames). Within what its pixels' neighbourhoods imply this is no evidence of bias; the block
    test on the blocks' run variances alone (the planted contrast) rejects it."""
    rng = np.random.default_rng(8)
    truth = _scene_like_image(rng)
    a_runs, b_runs = _runs(rng, 8, truth, 32), _runs(rng, 8, truth, 32)
    for run in a_runs:
        run[4:8, 4:8] = 0.0
    for run in b_runs:
        run[4:8, 4:8] = -1e-6
    a, b = metrics.run_statistics(a_runs), metrics.run_statistics(b_runs)
    comparison = metrics.compare_runs(a, b)
    assert comparison.blocks[4].passed and comparison.blocks[8].passed
    assert not metrics.pixel_t_test(metrics.block_statistics(a, 4), metrics.block_statistics(b, 4),
                                    pool_neighbours=False).passed
