"""Statistics for the BSDF tests: Mitsuba 3's chi-square test of a sampler against its pdf
(mitsuba/python/chi2.py: histogram the samples on a grid over the sphere, integrate the pdf over
each cell for the expected counts, pool cells expecting fewer than 5), and white-furnace
estimates. Directions are binned in (cos theta, phi) about the shading normal, so cells have
equal solid angle."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from volpath_native.bsdfs.batch import Hit

from native_helpers import chi2_critical

Z_CHI2 = 4.265  # normal quantile of p = 1e-5 per chi-square test


def frame(n):
    n = np.asarray(n, float) / np.linalg.norm(n)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t = np.cross(n, helper)
    t /= np.linalg.norm(t)
    return t, np.cross(n, t), n


@dataclass
class Chi2Result:
    statistic: float
    dof: int
    critical: float
    n_samples: int
    valid_fraction: float  # samples with pdf > 0 (not rejected, not deltas)
    pdf_integral: float  # integral of the pdf over the sphere
    quadrature_error: float  # |integral at k nodes - integral at k+2 nodes|

    @property
    def passed(self) -> bool:
        return self.statistic < self.critical

    def __str__(self):
        return (f"chi2 {self.statistic:.1f} (dof {self.dof}, critical {self.critical:.1f}), valid "
                f"{self.valid_fraction:.5f}, pdf integral {self.pdf_integral:.5f}")


def _cell_integrals(pdf_fn, t, s, n, z_edges, phi_edges, k):
    """Integral of pdf over each (z, phi) cell by k x k Gauss-Legendre points."""
    x, w = np.polynomial.legendre.leggauss(k)
    dz = np.diff(z_edges)
    dphi = np.diff(phi_edges)
    zs = (z_edges[:-1, None] + 0.5 * dz[:, None] * (x[None, :] + 1)).reshape(-1)
    ps = (phi_edges[:-1, None] + 0.5 * dphi[:, None] * (x[None, :] + 1)).reshape(-1)
    Z, P = np.meshgrid(zs, ps, indexing="ij")
    r = np.sqrt(np.clip(1 - Z * Z, 0, None))
    d = (r * np.cos(P))[..., None] * t + (r * np.sin(P))[..., None] * s + Z[..., None] * n
    pdf = np.asarray(pdf_fn(d.reshape(-1, 3))).reshape(Z.shape)
    wz = (0.5 * dz[:, None] * w[None, :]).reshape(-1)
    wp = (0.5 * dphi[:, None] * w[None, :]).reshape(-1)
    cell = (pdf * wz[:, None] * wp[None, :]).reshape(len(dz), k, len(dphi), k).sum(axis=(1, 3))
    return cell


def chi2_test(hit: Hit, n_samples=400_000, seed=1, res_z=32, res_phi=64, k=4, pdf_fn=None, z=Z_CHI2,
              n=None) -> Chi2Result:
    """Chi-square of hit.sample() against hit's pdf (or pdf_fn(wo) -> pdf, to plant errors)."""
    rng = np.random.default_rng(seed)
    wo, weight, pdf, label = hit.sample(rng.random((n_samples, 3)))
    ok = (label != 0) & (pdf > 0)
    t, s, nz = frame(hit.n if n is None else n)
    zc = np.clip(wo[ok] @ nz, -1, 1)
    phi = np.arctan2(wo[ok] @ s, wo[ok] @ t)
    z_edges = np.linspace(-1, 1, res_z + 1)
    phi_edges = np.linspace(-np.pi, np.pi, res_phi + 1)
    observed, _, _ = np.histogram2d(zc, phi, bins=[z_edges, phi_edges])
    fn = pdf_fn or (lambda d: hit.eval(d)[1])
    cells = _cell_integrals(fn, t, s, nz, z_edges, phi_edges, k)
    finer = _cell_integrals(fn, t, s, nz, z_edges, phi_edges, k + 2)
    expected = cells * n_samples
    small = expected < 5
    obs = list(observed[~small])
    exp = list(expected[~small])
    if small.any():
        obs.append(observed[small].sum())
        exp.append(expected[small].sum())
    obs, exp = np.array(obs), np.array(exp)
    keep = exp > 0
    stat = float((((obs - exp) ** 2)[keep] / exp[keep]).sum())
    if (obs[~keep] > 0).any():
        stat = np.inf  # samples where the pdf says none can be
    dof = int(keep.sum()) - 1
    return Chi2Result(stat, dof, float(chi2_critical(dof, z)), n_samples, float(ok.mean()),
                      float(cells.sum()), float(abs(cells.sum() - finer.sum())))


def albedo(hit: Hit, n_samples=200_000, seed=3):
    """Directional albedo E = mean sample weight (deltas included) and its standard error."""
    rng = np.random.default_rng(seed)
    _, w, _, _ = hit.sample(rng.random((n_samples, 3)))
    return w.mean(axis=0), w.std(axis=0) / np.sqrt(n_samples)


def direction(theta_deg, phi_deg=0.0):
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])
