"""Regenerate the BSDF lookup tables (bsdfs/data/*.npy) by Monte Carlo with our own samplers.

    python -m volpath_native.bsdfs.precompute [--scale S] [--only NAME ...]

What each cell integrates follows Cycles 5.0 app/cycles_precompute.cpp (the grid, the clamps and
the estimator: the closure's own sampler, value eval / pdf, rejected samples count as 0); the code
and the numbers are ours. One deliberate reproduction: Cycles' glass tables were generated in June
2023 (commit 34125e1d) by a glass sampler that did not yet reject refracted directions leaving on
the incident side (its Ng test was commented out); Cycles 5.0 rejects them but ships those
tables. The glass terms here use that 2023 estimator (_glass_2023) so the energy compensation is
Cycles' -- otherwise rough glass seen from inside (ior < 1) would render up to ~2x brighter near
grazing than Cycles. ggx_glass_* with --glass-current use today's sampler instead. Each cell averages a randomly shifted Kronecker sequence (Roberts' R_d,
golden-ratio generalisation) over the closure's random numbers, so the smooth integrands converge
about as 1/N. Default sample counts keep the whole run to ~1-2 minutes on one core; --scale
multiplies them.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from ..jit import kernel
from .fresnel import FRESNEL_DIELECTRIC, FRESNEL_GENERALIZED_SCHLICK, FRESNEL_NONE, ior_from_F0
from .fresnel import fresnel_dielectric
from .microfacet import GGX, ggx_sample_vndf, lambda_iso, microfacet_sample
from .tables import DATA_DIR, TABLE_SHAPES

TERM_E, TERM_GLASS_E, TERM_IOR_S, TERM_SCHLICK_S, TERM_GLASS_CURRENT = range(5)

# samples per cell (Cycles uses 2^23 .. 2^26 with Sobol; these are enough for ~1e-4 here)
SAMPLES = {"ggx_E": 1 << 16, "ggx_Eavg": 1 << 20, "ggx_glass_E": 1 << 15, "ggx_glass_Eavg": 1 << 18,
           "ggx_glass_inv_E": 1 << 15, "ggx_glass_inv_Eavg": 1 << 18,
           "ggx_gen_schlick_ior_s": 1 << 14, "ggx_gen_schlick_s": 1 << 14}


def _kronecker_alphas(d: int) -> np.ndarray:
    """1 / phi_d^k, k = 1..d, with phi_d the positive root of x^(d+1) = x + 1 (Roberts 2018)."""
    phi = 2.0
    for _ in range(64):
        phi = (1.0 + phi) ** (1.0 / (d + 1))
    return np.array([phi ** -(k + 1) for k in range(d)])


_ALPHA4 = _kronecker_alphas(4)


@kernel
def _glass_2023(rough, mu, eta, u1, u2, u3):
    """eval / pdf of one GGX glass sample as Cycles' sampler of June 2023 computed it (exact
    dielectric Fresnel, reflect with probability F, reflections below the surface rejected,
    refractions accepted on either side): F / P and T / P cancel, leaving G2 / G1. Deltas (its
    threshold alpha^2 <= 5e-7, and refraction with |eta - 1| < 1e-4) give exactly 1."""
    alpha = rough * rough
    a2 = alpha * alpha
    if a2 <= 5e-7:
        return 1.0
    wi = (np.sqrt(max(1.0 - mu * mu, 0.0)), 0.0, mu)
    h = ggx_sample_vndf(wi, alpha, alpha, u1, u2)
    cos_hi = h[0] * wi[0] + h[2] * wi[2]
    f, cos_t = fresnel_dielectric(cos_hi, eta)
    if f < 1.0 and u3 >= f:
        if abs(eta - 1.0) < 1e-4:
            return 1.0
        k = cos_hi / eta + cos_t
        wo_z = k * h[2] - wi[2] / eta
        wo_x = k * h[0] - wi[0] / eta
        wo_y = k * h[1]
        cos_no = wo_z / np.sqrt(wo_x * wo_x + wo_y * wo_y + wo_z * wo_z)
    else:
        cos_no = 2.0 * cos_hi * h[2] - wi[2]
        if cos_no <= 0.0:
            return 0.0
    lam_i = lambda_iso(GGX, a2, mu)
    return (1.0 + lam_i) / (1.0 + lam_i + lambda_iso(GGX, a2, cos_no))


@kernel
def _one_sample(term, rough, mu, eta, exponent, u1, u2, u3):
    one = (1.0, 1.0, 1.0)
    zero = (0.0, 0.0, 0.0)
    x, y, n = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
    wi = (np.sqrt(max(1.0 - mu * mu, 0.0)), 0.0, mu)
    alpha = rough * rough
    if term == TERM_E or term == TERM_SCHLICK_S:
        wo, ev, pdf, refracted, singular, ok = microfacet_sample(
            GGX, True, False, alpha, alpha, 1.0, x, y, n, n, wi, u1, u2, u3,
            FRESNEL_NONE, one, one, zero, one, one, zero, zero)
        if not ok or pdf == 0.0:
            return 0.0
        if term == TERM_E:
            return (ev[0] + ev[1] + ev[2]) / (3.0 * pdf)
        hx, hy, hz = wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]
        hl = np.sqrt(hx * hx + hy * hy + hz * hz)
        cos_hi = (hx * wi[0] + hz * wi[2]) / hl
        return min(max(1.0 - cos_hi, 0.0), 1.0) ** exponent
    if term == TERM_GLASS_E:
        return _glass_2023(rough, mu, eta, u1, u2, u3)
    if term == TERM_GLASS_CURRENT:
        wo, ev, pdf, refracted, singular, ok = microfacet_sample(
            GGX, True, True, alpha, alpha, eta, x, y, n, n, wi, u1, u2, u3,
            FRESNEL_DIELECTRIC, one, one, zero, one, one, zero, zero)
        if not ok or pdf == 0.0:
            return 0.0
        return (ev[0] + ev[1] + ev[2]) / (3.0 * pdf)
    # TERM_IOR_S: channel 0 has f0 = 0, f90 = 1, channel 1 has F = 1; their ratio is s
    wo, ev, pdf, refracted, singular, ok = microfacet_sample(
        GGX, True, False, alpha, alpha, eta, x, y, n, n, wi, u1, u2, u3,
        FRESNEL_GENERALIZED_SCHLICK, (0.0, 1.0, 0.0), (1.0, 1.0, 0.0), zero, one, one, zero, zero)
    if not ok or pdf == 0.0 or ev[1] <= 0.0:
        return 0.0
    return min(max(ev[0] / ev[1], 0.0), 1.0)


@kernel
def _cell(term, rough, mu, eta, exponent, average_mu, samples, shift, alpha):
    """Mean over `samples` points of the shifted Kronecker sequence; with average_mu the fourth
    coordinate is mu and the value is weighted by 2 mu (the cosine-weighted average E_avg)."""
    total = 0.0
    for i in range(samples):
        u1 = (shift[0] + (i + 1) * alpha[0]) % 1.0
        u2 = (shift[1] + (i + 1) * alpha[1]) % 1.0
        u3 = (shift[2] + (i + 1) * alpha[2]) % 1.0
        if average_mu:
            m = max((shift[3] + (i + 1) * alpha[3]) % 1.0, 1e-9)
            v = 2.0 * m * _one_sample(term, rough, m, eta, exponent, u1, u2, u3)
        else:
            v = _one_sample(term, rough, mu, eta, exponent, u1, u2, u3)
        if v == v:  # NaN counts as 0, as Cycles
            total += v
    return min(max(total / samples, 0.0), 1.0)


def _ior_of(zi: int, nz: int) -> float:
    z = min(max(zi / (nz - 1), 1e-4), 0.99)
    ior = float(ior_from_F0(z ** 4))
    # Cycles computes this in float32, where the first cell (z = 1e-4, ior - 1 = 2e-8) is exactly 1
    return 1.0 if ior - 1.0 < 1e-7 else ior


def compute(name: str, scale: float = 1.0, seed: int = 2025, glass_current: bool = False) -> np.ndarray:
    shape = TABLE_SHAPES[name]
    samples = max(int(SAMPLES[name] * scale), 64)
    rng = np.random.default_rng([seed, sum(map(ord, name))])
    average_mu = name.endswith("Eavg")
    term = {"ggx_E": TERM_E, "ggx_Eavg": TERM_E, "ggx_gen_schlick_ior_s": TERM_IOR_S,
            "ggx_gen_schlick_s": TERM_SCHLICK_S}.get(name, TERM_GLASS_CURRENT if glass_current else TERM_GLASS_E)
    inverse = "_inv_" in name
    if len(shape) == 3:
        nz, ny, nx = shape
    elif average_mu:
        (nz, nx), ny = (shape if len(shape) == 2 else (1,) + shape), 1
    else:
        nz, (ny, nx) = 1, shape
    out = np.zeros((nz, ny, nx))
    for zi in range(nz):
        eta, exponent = 1.0, 0.0
        if term in (TERM_GLASS_E, TERM_GLASS_CURRENT, TERM_IOR_S) and nz > 1:
            eta = _ior_of(zi, nz)
            if inverse:
                eta = 1.0 / eta
        if term == TERM_SCHLICK_S:
            z = min(max(zi / (nz - 1), 1e-4), 0.99)
            exponent = 5.0 * (1.0 - z) / z
        for yi in range(ny):
            mu = min(max(yi / (ny - 1), 1e-4), 1.0) if ny > 1 else 0.0
            for xi in range(nx):
                rough = min(max(xi / (nx - 1), 1e-4), 1.0)
                out[zi, yi, xi] = _cell(term, rough, mu, eta, exponent, average_mu, samples, rng.random(4), _ALPHA4)
    return out.reshape(shape)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scale", type=float, default=1.0, help="multiply every sample count")
    parser.add_argument("--only", nargs="*", default=None, help="table names to regenerate")
    parser.add_argument("--out", default=str(DATA_DIR))
    parser.add_argument("--glass-current", action="store_true",
                        help="glass tables from today's sampler instead of Cycles' 2023 estimator")
    args = parser.parse_args(argv)
    names = args.only or list(SAMPLES)
    from pathlib import Path
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in names:
        if name == "sheen_ltc":
            from .sheen_fit import compute_sheen_ltc
            t0 = time.perf_counter()
            table = compute_sheen_ltc(scale=args.scale)
        else:
            t0 = time.perf_counter()
            table = compute(name, args.scale, glass_current=args.glass_current)
        np.save(out / f"{name}.npy", table.astype(np.float32))
        print(f"{name}: {table.shape} in {time.perf_counter() - t0:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
