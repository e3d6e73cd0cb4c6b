"""Our own regeneration of the sheen LTC table (tables.sheen_ltc) by the method of Zeltner, Burley
& Chiang 2022 ("Practical Multiple-Scattering Sheen Using Linearly Transformed Cosines", whose
published fit is what Cycles 5.0 ships as table_sheen_ltc; the method is described in the
authors' repository github.com/tizian/ltc-sheen, fitting/README.md and fitting/python/*.py):

1. Reference BRDF: a unit-thickness, unit-density, non-absorbing (albedo 1) volumetric layer of
   fiber-like SGGX microflakes (Heitz et al. 2015, "The SGGX Microflake Distribution") whose fibers
   stand along the normal, S = diag(1, 1, sigma^2) with sigma = alpha^2, specular microflake phase
   function, black below; a random walk of at most 16 scattering events from wi. A walk that
   leaves through the top (or ends after 16 events heading up) is a reflection.
2. Tabulate its reflectance R and the reflected density f cos on 32 x 32 (theta_o, phi_o) bin
   centres over the upper half-space (phi folded to [0, pi]), for mu = cos(theta_i) and alpha on
   max(0.01, linspace(0, 1, 32)).
3. Fit the inverse transform M^-1 = [[a, 0, b], [0, a, 0], [0, 0, 1]] of R D_cos(M^-1 wo) |M^-1| /
   |M^-1 wo|^3 to that data by Nelder-Mead on the summed cubed error, for each mu from alpha = 1
   down, each fit starting from the previous one (smooth tables); cells with R < 3e-6 stay
   (0, 0, R) and Cycles drops the closure there.

The authors ran ~5e9 walks per cell (two days); the default here is ~5.2e5 (a few minutes on one
core), so our table carries Monte-Carlo noise of a few 1e-3 in R and ~1e-2 in a, b at low
roughness; tests/native/test_bsdfs_sheen.py measures it against the closed-form properties.
"""
from __future__ import annotations

import numpy as np

from ..jit import kernel
from ..sampling import _mix64

RES = 32
MAX_BOUNCES = 16
_INV_2_53 = 1.0 / float(1 << 53)
_GOLD = np.uint64(0x9E3779B97F4A7C15)


def grid() -> np.ndarray:
    return np.maximum(0.01, np.linspace(0.0, 1.0, RES))


@kernel
def _next(state):
    """splitmix64 stream: (new state, uniform in [0, 1))."""
    state = state + _GOLD
    return state, np.float64(_mix64(state) >> np.uint64(11)) * _INV_2_53


@kernel
def _sggx_sample_visible(wx, wy, wz, sig, u1, u2):
    """A microflake normal of S = diag(1, 1, sig^2) visible from direction w (unit): SGGX's
    normals are those of the ellipsoid x^T S x = 1 (projected area proportional to
    sqrt(w^T S w)). With x = S^(-1/2) y, y on the unit sphere, the normal is S^(1/2) y and a ray
    along w becomes one along S^(1/2) w; a uniform point of the sphere's disk seen along that
    direction, lifted onto its visible side, is mapped back to a normal drawn in proportion to
    its visible projected area (the SGGX paper's projected-ellipsoid sampling, in sphere space)."""
    dx, dy, dz = wx, wy, sig * wz
    inv = 1.0 / np.sqrt(dx * dx + dy * dy + dz * dz)
    dx, dy, dz = dx * inv, dy * inv, dz * inv
    sign = 1.0 if dz >= 0.0 else -1.0
    a = -1.0 / (sign + dz)
    b = dx * dy * a
    e1 = (1.0 + sign * dx * dx * a, sign * b, -sign * dx)
    e2 = (b, sign + dy * dy * a, -dy)
    r = np.sqrt(u1)
    phi = 2.0 * np.pi * u2
    u, v = r * np.cos(phi), r * np.sin(phi)
    h = np.sqrt(max(1.0 - u * u - v * v, 0.0))
    yx = u * e1[0] + v * e2[0] + h * dx
    yy = u * e1[1] + v * e2[1] + h * dy
    yz = u * e1[2] + v * e2[2] + h * dz
    mx, my, mz = yx, yy, sig * yz
    inv = 1.0 / np.sqrt(mx * mx + my * my + mz * mz)
    return mx * inv, my * inv, mz * inv


@kernel
def _walk(mu, sig, state):
    """One random walk; returns (state, reflected, theta_o, phi_o in [0, 2 pi))."""
    wx, wy, wz = np.sqrt(max(1.0 - mu * mu, 0.0)), 0.0, mu
    dx, dy, dz = -wx, -wy, -wz  # propagation direction
    depth = 0.0
    bounces = 0
    while True:
        st = np.sqrt(dx * dx + dy * dy + sig * sig * dz * dz)
        state, u = _next(state)
        dist = -np.log(1.0 - u) / st if st > 0.0 else np.inf
        depth += dist * -dz
        if depth < 0.0 or depth > 1.0:
            break
        # specular microflake: reflect the incident direction -d about a visible normal
        state, u1 = _next(state)
        state, u2 = _next(state)
        mx, my, mz = _sggx_sample_visible(-dx, -dy, -dz, sig, u1, u2)
        c = 2.0 * (mx * -dx + my * -dy + mz * -dz)
        dx, dy, dz = c * mx + dx, c * my + dy, c * mz + dz
        inv = 1.0 / np.sqrt(dx * dx + dy * dy + dz * dz)
        dx, dy, dz = dx * inv, dy * inv, dz * inv
        bounces += 1
        if bounces >= MAX_BOUNCES:
            break
    if dz < 0.0:
        return state, False, 0.0, 0.0
    theta = np.arccos(min(dz, 1.0))
    phi = np.arctan2(dy, dx)
    if phi < 0.0:
        phi += 2.0 * np.pi
    return state, True, theta, phi


@kernel
def _tabulate(mu, alpha, n_walks, seed, hist):
    """Reflectance and the folded (theta, phi) density histogram of the reference layer."""
    sig = alpha * alpha
    state = _mix64(np.uint64(seed))
    res_t, res_p = hist.shape
    reflected = 0
    for _ in range(n_walks):
        state, ok, theta, phi = _walk(mu, sig, state)
        if not ok:
            continue
        reflected += 1
        if phi > np.pi:
            phi = 2.0 * np.pi - phi
        it = min(int(theta / (0.5 * np.pi) * res_t), res_t - 1)
        ip = min(int(phi / np.pi * res_p), res_p - 1)
        s = np.sin(theta)
        if s > 0.0:
            hist[it, ip] += 1.0 / s
    scale = res_t * res_p / (np.pi * np.pi * n_walks)
    for i in range(res_t):
        for j in range(res_p):
            hist[i, j] *= scale
    return reflected / n_walks


def _bin_directions(res=RES):
    theta = (np.arange(res) + 0.5) / res * 0.5 * np.pi
    phi = (np.arange(res) + 0.5) / res * np.pi
    p, t = np.meshgrid(phi, theta)
    return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)


def ltc_value(a, b, R, wo):
    """R D_cos(M^-1 wo / |M^-1 wo|) |M^-1| / |M^-1 wo|^3 for the upper-half-space directions wo."""
    x = a * wo[..., 0] + b * wo[..., 2]
    y = a * wo[..., 1]
    z = wo[..., 2]
    length = np.sqrt(x * x + y * y + z * z)
    return R * np.maximum(z / length, 0.0) / np.pi * abs(a * a) / length ** 3


def nelder_mead(f, x0, step=0.1, tol=1e-6, max_iter=4000):
    """Downhill simplex (Nelder & Mead 1965) with the usual coefficients (1, 2, 0.5, 0.5)."""
    x0 = np.asarray(x0, float)
    simplex = [x0] + [x0 + step * np.eye(len(x0))[i] for i in range(len(x0))]
    values = [f(x) for x in simplex]
    for _ in range(max_iter):
        order = np.argsort(values)
        simplex = [simplex[i] for i in order]
        values = [values[i] for i in order]
        if abs(values[-1] - values[0]) <= tol * (abs(values[0]) + 1e-30) and \
                max(np.abs(s - simplex[0]).max() for s in simplex[1:]) < 1e-9:
            break
        centroid = np.mean(simplex[:-1], axis=0)
        xr = centroid + (centroid - simplex[-1])
        fr = f(xr)
        if fr < values[0]:
            xe = centroid + 2.0 * (centroid - simplex[-1])
            fe = f(xe)
            simplex[-1], values[-1] = (xe, fe) if fe < fr else (xr, fr)
        elif fr < values[-2]:
            simplex[-1], values[-1] = xr, fr
        else:
            xc = centroid + 0.5 * (simplex[-1] - centroid) if fr >= values[-1] else centroid + 0.5 * (xr - centroid)
            fc = f(xc)
            if fc < min(fr, values[-1]):
                simplex[-1], values[-1] = xc, fc
            else:
                simplex = [simplex[0]] + [simplex[0] + 0.5 * (s - simplex[0]) for s in simplex[1:]]
                values = [values[0]] + [f(s) for s in simplex[1:]]
    return simplex[int(np.argmin(values))]


def compute_sheen_ltc(scale: float = 1.0, walks: int = 1 << 19, seed: int = 22, progress=None) -> np.ndarray:
    """The (3, alpha, mu) table: a, b, R (tables.sheen_ltc layout)."""
    n = max(int(walks * scale), 1000)
    mus, alphas = grid(), grid()
    wo = _bin_directions()
    table = np.zeros((3, RES, RES))
    for mi, mu in enumerate(mus):
        x = np.array([1.0, 0.0])
        for ai in range(RES - 1, -1, -1):
            hist = np.zeros((RES, RES))
            R = _tabulate(mu, alphas[ai], n, seed * 1000003 + mi * RES + ai, hist)
            hist[0, :] = hist[0, :].mean()  # near the pole phi carries no information
            table[2, ai, mi] = R
            if R < 3e-6:
                continue
            x = nelder_mead(lambda p: float(np.sum(np.abs(ltc_value(p[0], p[1], R, wo) - hist) ** 3)), x)
            table[0, ai, mi], table[1, ai, mi] = x
        if progress:
            progress(mi)
    return table
