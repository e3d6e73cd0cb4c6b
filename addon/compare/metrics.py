"""Image statistics for comparing two Monte Carlo renderers. Pure numpy: no bpy, no image I/O.

Every image here is scene-linear float (H, W, C); only the first three channels (RGB) are compared.

The statistical model: each engine renders the same frame K times with independent seeds. The mean
of the K runs estimates each pixel, and their sample variance / K estimates the variance of that
mean with K - 1 degrees of freedom. Two engines agree at a pixel when Welch's t-test on the two
means does not reject equality; with one test per pixel and channel, the per-test significance is
Sidak-corrected so the whole image is rejected with probability `alpha` when the engines agree
(as mitsuba's and mitsuba-blender's render test fixtures do, there with a normal z-test and a known
sample count). The t distribution (not the normal) is used because variances estimated from a few
runs make the normal test reject far too often.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np

# A pixel whose estimated variance is (almost) zero in both engines (e.g. it only sees a constant
# emitter) still carries float32 rounding of a whole path's arithmetic (Cycles computes in float32:
# ray distances, exp(), products of tens of factors, each ~6e-8 relative): differences below this
# relative size count as equal.
FLOAT32_RELATIVE_NOISE = 1e-5
# relMSE's guard against division by ~0 in dark pixels (the value used by Rousselle et al. and
# most denoising papers).
RELMSE_EPSILON = 1e-2
# Welch degrees of freedom above this are treated as this many: the t distribution is then within
# ~1% of the normal in the tails we test, and capping is conservative (heavier tails).
MAX_DEGREES_OF_FREEDOM = 1000


def rgb(image: np.ndarray) -> np.ndarray:
    """The RGB channels of an (H, W, C>=3) image as float64."""
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] < 3:
        raise ValueError(f"expected an (H, W, 3+) image, got shape {image.shape}")
    return image[..., :3].astype(np.float64)


# ------------------------------------------------------------------------------------------------
# Independent runs -> per-pixel mean and variance of the mean
# ------------------------------------------------------------------------------------------------
@dataclass
class RunStatistics:
    """K independent renders of one frame by one engine, summarised."""

    mean: np.ndarray            # (H, W, 3) mean over runs
    variance_of_mean: np.ndarray  # (H, W, 3) sample variance over runs / K
    degrees_of_freedom: int     # K - 1
    run_channel_means: np.ndarray  # (K, 3) each run's image-wide RGB mean
    run_images: Optional[np.ndarray] = field(default=None, repr=False)  # (K, H, W, 3), for block tests

    @property
    def runs(self) -> int:
        return self.degrees_of_freedom + 1

    @property
    def channel_means(self) -> np.ndarray:
        return self.run_channel_means.mean(axis=0)

    @property
    def channel_mean_standard_error(self) -> np.ndarray:
        return self.run_channel_means.std(axis=0, ddof=1) / math.sqrt(self.runs)


def run_statistics(runs) -> RunStatistics:
    """Summarise a sequence of K >= 2 images (each (H, W, C>=3)) rendered with independent seeds."""
    stack = np.stack([rgb(image) for image in runs])
    if stack.shape[0] < 2:
        raise ValueError("at least two independent runs are needed to estimate the variance")
    k = stack.shape[0]
    return RunStatistics(mean=stack.mean(axis=0),
                         variance_of_mean=stack.var(axis=0, ddof=1) / k,
                         degrees_of_freedom=k - 1,
                         run_channel_means=stack.mean(axis=(1, 2)),
                         run_images=stack)


def block_statistics(stats: RunStatistics, block: int) -> RunStatistics:
    """The same runs averaged over block x block pixel tiles (edge pixels that do not fill a tile
    are dropped). Averaging each run before estimating the variance keeps the test valid when
    neighbouring pixels are correlated, and gains power against biases spread over a region."""
    if stats.run_images is None:
        raise ValueError("block statistics need the individual runs")
    k, h, w, c = stats.run_images.shape
    hb, wb = h // block, w // block
    if hb < 1 or wb < 1:
        raise ValueError(f"a {block}x{block} block does not fit a {w}x{h} image")
    tiles = stats.run_images[:, :hb * block, :wb * block].reshape(k, hb, block, wb, block, c).mean(axis=(2, 4))
    return run_statistics(tiles)


# ------------------------------------------------------------------------------------------------
# Student's t distribution (numpy has none; scipy is not a dependency)
# ------------------------------------------------------------------------------------------------
def student_t_two_sided_p(t, dof) -> np.ndarray:
    """P(|T| >= |t|) for Student's t with integer `dof` >= 1 (elementwise, arrays broadcast).

    Closed form for integer degrees of freedom, Abramowitz & Stegun 26.7.3 / 26.7.4: with
    theta = atan(|t| / sqrt(nu)), P(|T| < t) is a finite series in sin/cos theta.
    """
    t = np.abs(np.asarray(t, dtype=np.float64))
    dof = np.asarray(dof)
    nu = np.clip(np.floor(dof), 1, MAX_DEGREES_OF_FREEDOM).astype(np.int64)
    t, nu = np.broadcast_arrays(t, nu)
    theta = np.arctan(t / np.sqrt(nu))
    s, c2 = np.sin(theta), np.cos(theta) ** 2
    inside = np.empty_like(t)
    odd = (nu % 2) == 1
    # Odd nu: (2/pi) [theta + sin cos (1 + 2/3 cos^2 + 2*4/(3*5) cos^4 + ... up to cos^(nu-3))].
    # Even nu: sin [1 + 1/2 cos^2 + 1*3/(2*4) cos^4 + ... up to cos^(nu-2)].
    term_odd = np.where(odd & (nu > 1), 1.0, 0.0)
    sum_odd = term_odd.copy()
    term_even = np.where(~odd, 1.0, 0.0)
    sum_even = term_even.copy()
    max_nu = int(nu.max()) if nu.size else 1
    for k in range(1, (max_nu - 1) // 2 + 1):
        # odd series term k: prod_{j=1..k} (2j)/(2j+1) cos^(2k); present while 2k+1 <= nu-2.
        term_odd = term_odd * (2 * k) / (2 * k + 1) * c2
        sum_odd += np.where(odd & (2 * k + 1 <= nu - 2), term_odd, 0.0)
        # even series term k: prod (2j-1)/(2j) cos^(2k); present while 2k <= nu-2.
        term_even = term_even * (2 * k - 1) / (2 * k) * c2
        sum_even += np.where(~odd & (2 * k <= nu - 2), term_even, 0.0)
    inside[odd] = (2 / np.pi) * (theta + s * np.sqrt(c2) * sum_odd)[odd]
    inside[~odd] = (s * sum_even)[~odd]
    return np.clip(1.0 - inside, 0.0, 1.0)


def sidak_alpha(alpha: float, tests: int) -> float:
    """Per-test significance giving family-wise rejection probability `alpha` over `tests` tests."""
    return 1.0 - (1.0 - alpha) ** (1.0 / max(int(tests), 1))


# ------------------------------------------------------------------------------------------------
# Per-pixel agreement
# ------------------------------------------------------------------------------------------------
@dataclass
class PixelTest:
    """Result of the per-pixel, per-channel Welch t-test between two engines."""

    p_values: np.ndarray        # (H, W, 3)
    t_statistic: np.ndarray     # (H, W, 3) signed (a - b) / standard error
    alpha: float                # family-wise significance
    alpha_per_test: float       # Sidak-corrected
    tests: int

    @property
    def failed(self) -> np.ndarray:
        """(H, W) True where any channel rejects equality."""
        return np.any(self.p_values < self.alpha_per_test, axis=2)

    @property
    def fraction_passed(self) -> float:
        return float(1.0 - self.failed.mean())

    @property
    def passed(self) -> bool:
        """The image-level verdict: no test rejects at the Sidak-corrected level."""
        return not bool(self.failed.any())

    def worst(self) -> dict:
        index = np.unravel_index(int(np.argmin(self.p_values)), self.p_values.shape)
        return {"row": int(index[0]), "column": int(index[1]), "channel": "RGB"[index[2]],
                "p_value": float(self.p_values[index]), "t": float(self.t_statistic[index])}


def _moderated_variance(stats: RunStatistics) -> tuple[np.ndarray, int]:
    """Each pixel's variance of the mean pooled with its 8 neighbours' mean variance, with equal
    weight, and the degrees of freedom the pooling carries: the moderated t of limma (Smyth 2004)
    with the neighbourhood as the prior. Samples are stratified (Sobol'-Burley in both engines),
    so with a few runs a pixel whose few contributing samples have discrete outcomes -- 0, 1 or 2
    of 32 reach the floor through the filter's tail -- can give the same value in every run: an
    estimated variance of ~0 its neighbours do not share, with which Welch's t grows without
    bound."""
    variance = stats.variance_of_mean
    padded = np.pad(variance, ((1, 1), (1, 1), (0, 0)), mode="edge")
    h, w = variance.shape[:2]
    neighbours = (sum(padded[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3)) - variance) / 8.0
    return 0.5 * (variance + neighbours), 2 * stats.degrees_of_freedom


def pixel_t_test(a: RunStatistics, b: RunStatistics, alpha: float = 0.01, pool_neighbours: bool = True) -> PixelTest:
    """Welch's t-test of mean(a) == mean(b) at every pixel and channel, Sidak-corrected; with
    pool_neighbours, on variances moderated by the neighbourhood's (_moderated_variance)."""
    if a.mean.shape != b.mean.shape:
        raise ValueError(f"image sizes differ: {a.mean.shape} vs {b.mean.shape}")
    difference = a.mean - b.mean
    if pool_neighbours:
        (va, dof_a), (vb, dof_b) = _moderated_variance(a), _moderated_variance(b)
    else:
        va, dof_a, vb, dof_b = a.variance_of_mean, a.degrees_of_freedom, b.variance_of_mean, b.degrees_of_freedom
    variance = va + vb
    # Welch-Satterthwaite effective degrees of freedom (where variance is zero, any value works).
    denominator = va ** 2 / dof_a + vb ** 2 / dof_b
    with np.errstate(divide="ignore", invalid="ignore"):
        dof = np.where(denominator > 0, variance ** 2 / np.where(denominator > 0, denominator, 1.0),
                       MAX_DEGREES_OF_FREEDOM)
    rounding = (FLOAT32_RELATIVE_NOISE * np.maximum(np.abs(a.mean), np.abs(b.mean))) ** 2
    standard_error = np.sqrt(np.maximum(variance, rounding))
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(standard_error > 0, difference / np.where(standard_error > 0, standard_error, 1.0),
                     0.0)
    p = student_t_two_sided_p(t, dof)
    tests = int(np.prod(difference.shape))
    return PixelTest(p_values=p, t_statistic=t, alpha=alpha, alpha_per_test=sidak_alpha(alpha, tests),
                     tests=tests)


# ------------------------------------------------------------------------------------------------
# Image-wide channel means
# ------------------------------------------------------------------------------------------------
@dataclass
class MeanTest:
    """Per-channel image means of both engines, their ratio and a Welch t-test on them."""

    means_a: np.ndarray
    means_b: np.ndarray
    standard_error_a: np.ndarray
    standard_error_b: np.ndarray
    p_values: np.ndarray
    degrees_of_freedom: np.ndarray  # Welch-Satterthwaite, per channel
    alpha: float
    alpha_per_test: float

    @property
    def ratio(self) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.means_a / self.means_b

    @property
    def ratio_tolerance(self) -> np.ndarray:
        """Half-width of the ratio's interval at the Sidak-corrected level (delta method, with the
        same Student t quantile as the test): the tolerance the noise allows, reported next to the
        ratio, so a ratio inside it is exactly a passing test."""
        z = _student_t_quantile_two_sided(self.alpha_per_test, self.degrees_of_freedom)
        with np.errstate(divide="ignore", invalid="ignore"):
            relative = np.sqrt((self.standard_error_a / self.means_a) ** 2
                               + (self.standard_error_b / self.means_b) ** 2)
        return z * np.abs(self.ratio) * relative

    @property
    def passed(self) -> bool:
        return bool(np.all(self.p_values >= self.alpha_per_test))


def mean_test(a: RunStatistics, b: RunStatistics, alpha: float = 0.01) -> MeanTest:
    """Welch's t-test per channel on the image-wide means of the runs (Sidak over the channels).

    Uses each run's image mean as one sample, so correlations between pixels (pixel filter,
    blue-noise sample patterns) cannot make the test overconfident.
    """
    se_a, se_b = a.channel_mean_standard_error, b.channel_mean_standard_error
    va, vb = se_a ** 2, se_b ** 2
    variance = va + vb
    denominator = va ** 2 / a.degrees_of_freedom + vb ** 2 / b.degrees_of_freedom
    dof = np.where(denominator > 0, variance ** 2 / np.where(denominator > 0, denominator, 1.0),
                   MAX_DEGREES_OF_FREEDOM)
    rounding = (FLOAT32_RELATIVE_NOISE * np.maximum(np.abs(a.channel_means), np.abs(b.channel_means))) ** 2
    t = (a.channel_means - b.channel_means) / np.sqrt(np.maximum(variance, np.maximum(rounding, 1e-300)))
    return MeanTest(means_a=a.channel_means, means_b=b.channel_means, standard_error_a=se_a,
                    standard_error_b=se_b, p_values=student_t_two_sided_p(t, dof),
                    degrees_of_freedom=np.floor(dof), alpha=alpha,
                    alpha_per_test=sidak_alpha(alpha, 3))


def _student_t_quantile_two_sided(p: float, dof) -> np.ndarray:
    """t with P(|T| > t) = p for each entry of `dof`, by bisection on student_t_two_sided_p."""
    dof = np.asarray(dof, dtype=np.float64)
    lo, hi = np.zeros_like(dof), np.full_like(dof, 1e4)
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        above = student_t_two_sided_p(mid, dof) > p
        lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
    return 0.5 * (lo + hi)


# ------------------------------------------------------------------------------------------------
# Error measures and difference images
# ------------------------------------------------------------------------------------------------
def relmse(test: np.ndarray, reference: np.ndarray, epsilon: float = RELMSE_EPSILON) -> float:
    """Relative mean squared error mean((test - ref)^2 / (ref^2 + epsilon)) over pixels and RGB."""
    x, y = rgb(test), rgb(reference)
    if x.shape != y.shape:
        raise ValueError(f"image sizes differ: {x.shape} vs {y.shape}")
    return float(np.mean((x - y) ** 2 / (y ** 2 + epsilon)))


@dataclass
class BlockErrorTest:
    """relMSE between two engines' block means against what their noise alone would give.

    relmse: mean over blocks and channels of (a - b)^2 / (b^2 + epsilon), on block x block tile
    means; expected: its expectation if the engines agree, mean of (var_a + var_b) / (b^2 + epsilon)
    with each tile mean's variance summed from its pixels' (pixels are sampled independently);
    tolerance: the 1 - alpha quantile of that sum, one chi-square(1) term per block (a tile's
    channels come from the same paths: treated as fully correlated, which is conservative), by
    Satterthwaite's scaled chi-square and Wilson-Hilferty. Differences confined to a region
    (a thinner or denser part of a thick medium, a shadow) add up here while an image-wide mean
    can stay put."""

    block: int
    relmse: float
    expected: float
    tolerance: float
    blocks: int

    @property
    def passed(self) -> bool:
        return self.relmse <= self.tolerance

    def summary(self) -> dict:
        return {"block": self.block, "relmse": self.relmse, "expected": self.expected,
                "tolerance": self.tolerance, "blocks": self.blocks, "agree": self.passed}


def block_relmse_test(a: RunStatistics, b: RunStatistics, block: int, alpha: float = 0.01,
                      epsilon: float = RELMSE_EPSILON) -> BlockErrorTest:
    """BlockErrorTest of engine a against engine b (b's block means are the reference)."""
    if a.mean.shape != b.mean.shape:
        raise ValueError(f"image sizes differ: {a.mean.shape} vs {b.mean.shape}")
    h, w = a.mean.shape[:2]
    hb, wb = h // block, w // block
    if hb < 1 or wb < 1:
        raise ValueError(f"a {block}x{block} block does not fit a {w}x{h} image")

    def tiles(image):
        return image[:hb * block, :wb * block].reshape(hb, block, wb, block, -1)

    mean_a, mean_b = tiles(a.mean).mean(axis=(1, 3)), tiles(b.mean).mean(axis=(1, 3))
    pixels = block * block
    var_a = tiles(a.variance_of_mean).sum(axis=(1, 3)) / pixels ** 2
    var_b = tiles(b.variance_of_mean).sum(axis=(1, 3)) / pixels ** 2
    # The variances are estimated (pixels x (K - 1) degrees of freedom per tile): E[t^2] = nu / (nu - 2).
    nu = pixels * min(a.degrees_of_freedom, b.degrees_of_freedom)
    inflation = nu / (nu - 2.0) if nu > 2 else 3.0
    scale = mean_b ** 2 + epsilon
    terms = (mean_a - mean_b) ** 2 / scale
    weights = (inflation * (var_a + var_b) / scale).sum(axis=-1).ravel()  # per block, channels summed
    count = terms.size
    total, squares = float(weights.sum()), float((weights ** 2).sum())
    if total <= 0.0:  # no noise at all: only float rounding may differ
        return BlockErrorTest(block, float(terms.mean()), 0.0, FLOAT32_RELATIVE_NOISE ** 2, hb * wb)
    g, h_dof = squares / total, total ** 2 / squares
    z = _normal_quantile(1.0 - alpha)
    c = 2.0 / (9.0 * h_dof)
    quantile = g * h_dof * max(1.0 - c + z * math.sqrt(c), 0.0) ** 3
    return BlockErrorTest(block, float(terms.mean()), total / count, quantile / count, hb * wb)


def _normal_quantile(p: float) -> float:
    """z with P(Z <= z) = p, by bisection on erfc."""
    lo, hi = -40.0, 40.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if 0.5 * math.erfc(-mid / math.sqrt(2.0)) < p else (lo, mid)
    return 0.5 * (lo + hi)


def signed_relative_difference(a: np.ndarray, b: np.ndarray, epsilon: float = 1e-3) -> np.ndarray:
    """(H, W) (a - b) / mean(a, b) on the pixels' RGB average: > 0 where `a` is brighter."""
    ya, yb = rgb(a).mean(axis=2), rgb(b).mean(axis=2)
    return (ya - yb) / np.maximum(0.5 * (np.abs(ya) + np.abs(yb)), epsilon)


# Blue (negative) -> white (zero) -> red (positive); a perceptually ordered diverging map.
_DIVERGING_STOPS = np.array([[0.02, 0.19, 0.38], [0.26, 0.58, 0.76], [0.97, 0.97, 0.97],
                             [0.84, 0.38, 0.30], [0.40, 0.0, 0.12]])


def false_colour(values: np.ndarray, scale: float) -> np.ndarray:
    """Map signed values in [-scale, scale] to display RGB (H, W, 3) in [0, 1] (not scene-linear)."""
    x = np.clip(np.nan_to_num(np.asarray(values, dtype=np.float64)) / max(scale, 1e-12), -1.0, 1.0)
    position = (x + 1.0) * 0.5 * (len(_DIVERGING_STOPS) - 1)
    out = np.empty(x.shape + (3,))
    stops = np.arange(len(_DIVERGING_STOPS))
    for channel in range(3):
        out[..., channel] = np.interp(position, stops, _DIVERGING_STOPS[:, channel])
    return out


def colour_bar(width: int, height: int) -> np.ndarray:
    """A horizontal (height, width, 3) display-RGB ramp from -1 (left) to +1 (right)."""
    ramp = np.linspace(-1.0, 1.0, max(width, 2))[None, :].repeat(max(height, 1), axis=0)
    return false_colour(ramp, 1.0)


def difference_scale(relative_difference: np.ndarray) -> float:
    """A readable symmetric colour scale: the 99th percentile of |difference|, rounded up to
    1-2-5 steps, at least 1%."""
    magnitude = float(np.percentile(np.abs(np.nan_to_num(relative_difference)), 99)) if relative_difference.size else 0.0
    for step in (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0):
        if magnitude <= step:
            return step
    return 2.0


def display_exposure(image: np.ndarray, target: float = 0.8, percentile: float = 99.0) -> float:
    """Exposure in stops mapping the given percentile of the RGB average to `target` (for
    previews; both engines' panels use the same value)."""
    luminance = rgb(image).mean(axis=2)
    level = float(np.percentile(luminance, percentile)) if luminance.size else 0.0
    return float(np.log2(target / level)) if level > 0 else 0.0


# Tile sizes of the block tests run next to the per-pixel test (when the image holds >= 4 tiles).
BLOCK_SIZES = (4, 8)


@dataclass
class Comparison:
    """Everything the report needs about two engines' runs of one frame.

    The verdict combines the per-pixel test, block tests (BLOCK_SIZES) and the mean test; each is
    run at a Sidak share of the family-wise alpha so that the combined false-alarm rate is alpha.
    """

    pixel: PixelTest
    means: MeanTest
    relmse_a_vs_b: float
    relative_difference: np.ndarray = field(repr=False)
    blocks: dict = field(default_factory=dict)  # block size -> PixelTest on block means

    @property
    def passed(self) -> bool:
        return self.pixel.passed and self.means.passed and all(t.passed for t in self.blocks.values())

    def summary(self) -> dict:
        return {
            "channel_means_a": self.means.means_a.tolist(),
            "channel_means_b": self.means.means_b.tolist(),
            "channel_mean_standard_error_a": self.means.standard_error_a.tolist(),
            "channel_mean_standard_error_b": self.means.standard_error_b.tolist(),
            "channel_mean_ratio": self.means.ratio.tolist(),
            "channel_mean_ratio_tolerance": self.means.ratio_tolerance.tolist(),
            "channel_mean_p_values": self.means.p_values.tolist(),
            "means_agree": self.means.passed,
            "relmse_a_vs_b": self.relmse_a_vs_b,
            "pixel_fraction_passed": self.pixel.fraction_passed,
            "pixels_agree": self.pixel.passed,
            "pixel_alpha": self.pixel.alpha,
            "pixel_alpha_per_test": self.pixel.alpha_per_test,
            "pixel_tests": self.pixel.tests,
            "worst_pixel": self.pixel.worst(),
            "blocks": {str(size): {"fraction_passed": t.fraction_passed, "agree": t.passed,
                                   "tests": t.tests, "worst": t.worst()}
                       for size, t in self.blocks.items()},
            "agrees": self.passed,
        }


# A block's run variance below this quantile of its chi-square spread around what its pixels
# imply is treated as that bound (see _block_statistics_floored).
BLOCK_VARIANCE_FLOOR_QUANTILE = 1e-3


def _block_statistics_floored(stats: RunStatistics, block: int) -> RunStatistics:
    """block_statistics with each block's variance of the mean kept above the 0.1 % quantile of
    the chi-square spread around what its pixels' moderated variances imply for independent pixels
    (their sum / pixels^2). A block that only the filter's tail reaches beside bright pixels (the
    procedural fire's, ~1e-6 beside -1e-3) gets a nearly fixed number of stratified tail samples
    per run: its run variance can be ~0 in one engine while its pixels' neighbourhoods say
    otherwise. Correlated pixels only raise the true variance above the implied one, and a run
    variance is below the bound 0.1 % of the time, so the test keeps its power and its level."""
    blocks = block_statistics(stats, block)
    pixel_variance, _ = _moderated_variance(stats)
    hb, wb, c = blocks.mean.shape
    implied = pixel_variance[:hb * block, :wb * block].reshape(hb, block, wb, block, c).sum(axis=(1, 3)) / block ** 4
    return replace(blocks, variance_of_mean=np.maximum(
        blocks.variance_of_mean, implied * _chi_square_lower_fraction(BLOCK_VARIANCE_FLOOR_QUANTILE,
                                                                       blocks.degrees_of_freedom)))


def _chi_square_lower_fraction(p: float, dof: int) -> float:
    """The p quantile of chi-square(dof) / dof (Wilson-Hilferty; ~15 % low at dof 7 for p = 1e-3,
    on the safe side here)."""
    a = 2.0 / (9.0 * dof)
    return max(0.0, 1.0 - a + _normal_quantile(p) * math.sqrt(a)) ** 3


def compare_runs(a: RunStatistics, b: RunStatistics, alpha: float = 0.01) -> Comparison:
    """All agreement tests between two engines' runs; the family (pixels, each block size, means)
    shares `alpha` by Sidak's rule."""
    h, w = a.mean.shape[:2]
    sizes = [size for size in BLOCK_SIZES
             if a.run_images is not None and b.run_images is not None and (h // size) * (w // size) >= 4]
    share = sidak_alpha(alpha, 2 + len(sizes))
    blocks = {size: pixel_t_test(_block_statistics_floored(a, size), _block_statistics_floored(b, size), share,
                                 pool_neighbours=False)
              for size in sizes}
    return Comparison(pixel=pixel_t_test(a, b, share), means=mean_test(a, b, share),
                      relmse_a_vs_b=relmse(a.mean, b.mean),
                      relative_difference=signed_relative_difference(a.mean, b.mean), blocks=blocks)
