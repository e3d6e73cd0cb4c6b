"""numpy front ends of the surface shader for tests, quadratures and the precompute: one hit
(fixed wi, n, ng) evaluated or sampled for many directions. The compiled stages call the scalar
functions of closures.py directly."""
from __future__ import annotations

import numpy as np

from ..jit import kernel
from .closures import new_closure_buffer, setup_surface_tangent, surface_blur, surface_eval, surface_sample
from .microfacet import D_aniso, microfacet_eval
from .nodes import SurfaceNode, surface_node_table
from .tables import bsdf_tables


def _vec(v):
    v = np.asarray(v, np.float64)
    return (float(v[0]), float(v[1]), float(v[2]))


class Hit:
    """One shading point of one material, set up once; eval/sample many directions."""

    def __init__(self, nodes, wi, n=(0.0, 0.0, 1.0), ng=None, backfacing=False, tangent=(0.0, 0.0, 0.0)):
        if isinstance(nodes, SurfaceNode):
            nodes = [nodes]
        self.SN = surface_node_table([list(nodes)])
        self.BT = bsdf_tables()
        self.CB = new_closure_buffer()
        self.wi, self.n = _vec(wi), _vec(n)
        self.ng = self.n if ng is None else _vec(ng)
        self.count = int(_setup(self.SN, self.BT, 0, self.wi, self.n, self.ng, bool(backfacing), _vec(tangent),
                                self.CB))

    def blur(self, roughness: float):
        """Filter Glossy: raise every microfacet alpha to at least `roughness`."""
        _blur(self.CB, self.count, float(roughness))
        return self

    @property
    def emission(self) -> np.ndarray:
        return np.array(self.CB.emission)

    def eval(self, wo: np.ndarray):
        wo = np.ascontiguousarray(np.atleast_2d(wo), np.float64)
        f, pdf = np.empty((len(wo), 3)), np.empty(len(wo))
        _eval_many(self.CB, self.count, self.BT, self.wi, self.n, self.ng, wo, f, pdf)
        return f, pdf

    def sample(self, u: np.ndarray):
        """u (N, 3): (u_pick, u1, u2). Returns (wo, weight, pdf, label)."""
        u = np.ascontiguousarray(u, np.float64)
        k = len(u)
        wo, w, pdf, label = np.empty((k, 3)), np.empty((k, 3)), np.empty(k), np.empty(k, np.int64)
        _sample_many(self.CB, self.count, self.BT, self.wi, self.n, self.ng, u, wo, w, pdf, label)
        return wo, w, pdf, label


@kernel
def _setup(SN, BT, material, wi, n, ng, backfacing, tangent, CB):
    return setup_surface_tangent(SN, BT, material, wi, n, ng, backfacing, tangent, CB)


@kernel
def _blur(CB, count, roughness):
    surface_blur(CB, count, roughness)


@kernel
def _eval_many(CB, count, BT, wi, n, ng, wo, f, pdf):
    for k in range(wo.shape[0]):
        v, p = surface_eval(CB, count, BT, wi, (wo[k, 0], wo[k, 1], wo[k, 2]), n, ng)
        f[k, 0], f[k, 1], f[k, 2] = v
        pdf[k] = p


@kernel
def _sample_many(CB, count, BT, wi, n, ng, u, wo, w, pdf, label):
    for k in range(u.shape[0]):
        d, v, p, lab = surface_sample(CB, count, BT, wi, n, ng, u[k, 0], u[k, 1], u[k, 2])
        wo[k, 0], wo[k, 1], wo[k, 2] = d
        w[k, 0], w[k, 1], w[k, 2] = v
        pdf[k] = p
        label[k] = lab


# --- single lobes, for quadratures (local frame: x, y, n = the coordinate axes) -------------------
@kernel
def distribution_many(distribution, alpha_x, alpha_y, h, out):
    for k in range(h.shape[0]):
        out[k] = D_aniso(distribution, alpha_x, alpha_y, (h[k, 0], h[k, 1], h[k, 2]))


@kernel
def microfacet_eval_many(distribution, has_reflection, has_transmission, alpha_x, alpha_y, ior, wi, wo,
                         fresnel_type, f0, f90, f82_b, reflection_tint, transmission_tint, conductor_n,
                         conductor_k, f, pdf):
    x, y, n = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
    for k in range(wo.shape[0]):
        v, p = microfacet_eval(distribution, has_reflection, has_transmission, alpha_x, alpha_y, ior, x, y, n, wi,
                               (wo[k, 0], wo[k, 1], wo[k, 2]), fresnel_type, f0, f90, f82_b, reflection_tint,
                               transmission_tint, conductor_n, conductor_k)
        f[k, 0], f[k, 1], f[k, 2] = v
        pdf[k] = p
