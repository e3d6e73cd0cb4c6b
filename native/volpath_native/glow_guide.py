"""Bounce directions guided toward delta lamps that sit in a scattering medium (their glow).

Light a medium scatters around a point or spot lamp without radius reaches a surface point x along
directions near the lamp's with radiance ~ sigma_s I / (r theta) (theta: the angle between the
direction and the lamp's, r: the lamp's distance): the in-scattered light of a ray passing the lamp
at D = r theta, which the ray's equiangular next event estimates well, is ~1/D. BSDF sampling
draws theta with a density ~theta near 0, so a bounce's estimate has a second moment ~ the
integral of 1/theta: it diverges logarithmically, and a handful of bounces held a tenth of some
rows' squared error (README, session 18: the glass of liquid's worst pixel, a floor bounce passing
4.7 mm from the spot). Cycles draws such bounces from the BSDF alone; its float32 clip of segments
to a spot's cone loses the nearest ones (a small bias, README session 17), VolPath keeps them.

The remedy: at surface vertices whose closures have no delta lobe, a share GLOW_SHARE of the
bounce directions is drawn from a cone of half-angle GLOW_CONE around one glowing lamp's direction
(picked by power x sigma_s at the lamp), theta uniform -- a solid-angle density
1 / (2 pi GLOW_CONE sin theta), ~1/theta like the glow -- and the rest from the BSDF; every
direction is weighted by the mixture's pdf (one-sample MIS with the balance heuristic, Veach 1997
sect. 9.2.4): unbiased, and the glow's contribution near the lamp is bounded. Light sampling at
the same vertex weighs its directions against the same mixture pdf, so the two techniques for
hittable emitters still sum to one. Medium vertices in homogeneous media with one phase lobe mix
the same guide, toward the lamps held by the same volumes as the vertex only (a lamp in the fog
is no help to a vertex inside a milky glass sphere in that fog: measured, the glass of liquid's
error per sample rose 0.61 -> 0.66 when they were guided); their next events weigh against that
mixture too. Grid
media and phase mixtures are not guided. Media around the lamp are read at the lamp's position
(homogeneous volumes and the world's).
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from .bsdfs.closures import CLOSURE_TRANSPARENT, LABEL_DIFFUSE, LABEL_GLOSSY, LABEL_REFLECT, LABEL_TRANSMIT
from .bsdfs.closures import _is_diffuse_kind
from .bsdfs.microfacet import is_singular
from .jit import inline_stage_kernel, stage_kernel
from .sampling import local_to_world1

#: the share of bounce directions drawn toward glowing lamps where any glow. Error per sample (256
#: spp x 4 seeds) at 0.1 / 0.05 / 0.025: Cornell point 0.721 / 0.690 / 0.720, spot 0.534 / 0.496 /
#: 0.497, glass of liquid 0.639 / 0.600 / 0.592 (a smaller share wastes fewer directions where
#: nothing glows; the tail stays bounded, at GLOW_CONE / GLOW_SHARE)
GLOW_SHARE = 0.05
#: half-angle (radians) of the cone around a lamp's direction those directions fill
GLOW_CONE = 0.2

# count: glowing lamps (0: no guiding); position (K, 3); cdf (K,) of the pick by glow strength;
# stack (K, V): the volumes holding the lamp (MediaTable.stack_at's counters; none: the world's medium)
GlowTable = namedtuple("GlowTable", ["count", "position", "cdf", "stack"])


def no_glow() -> GlowTable:
    """A table without lamps: no bounce is guided."""
    return GlowTable(0, np.zeros((1, 3)), np.ones(1), np.zeros((1, 1), np.int8))


def glow_table(lights, media) -> GlowTable:
    """The delta point and spot lamps (radius 0) with scattering medium at their position: a
    homogeneous volume's (MediaTable.stack_at) or the world's. Weight: mean power x mean sigma_s."""
    from .scene import PointLight  # SpotLight derives from it
    lamps = [light for light in lights if isinstance(light, PointLight) and float(light.radius) <= 0.0]
    positions, weights, stacks_kept = [], [], []
    if lamps and media.any_medium:
        points = np.array([np.asarray(light.position, np.float64) for light in lamps]).reshape(-1, 3)
        stacks = media.stack_at(points)
        for light, point, stack in zip(lamps, points, stacks):
            inside = [v for v in range(media.n_volumes) if stack[v] > 0 and not media.volume_is_grid[v]]
            sigma_s = np.array(media.world_sigma_s, np.float64) if not inside else \
                np.sum([media.sigma_s[v] for v in inside], axis=0)
            weight = float(np.mean(light.power)) * float(np.mean(sigma_s))
            if weight > 0.0 and np.isfinite(weight):
                positions.append(point)
                weights.append(weight)
                stacks_kept.append(stack)
    if not positions:
        return no_glow()
    cdf = np.cumsum(weights) / np.sum(weights)
    cdf[-1] = 1.0
    return GlowTable(len(positions), np.ascontiguousarray(positions, np.float64), np.ascontiguousarray(cdf),
                     np.ascontiguousarray(stacks_kept, np.int8))


@inline_stage_kernel
def mixture_pdf(technique_pdf, guide_pdf):
    """The pdf of a direction drawn by the BSDF or phase function (1 - GLOW_SHARE) or the guide."""
    return (1.0 - GLOW_SHARE) * technique_pdf + GLOW_SHARE * guide_pdf


@inline_stage_kernel
def surface_has_delta(CB, count):
    """Whether a closure of the hit is a delta (transparent, or a microfacet lobe too smooth to
    evaluate): such vertices are not guided (a guided direction cannot sample the delta)."""
    for i in range(count):
        kind = CB.kind[i]
        if kind == CLOSURE_TRANSPARENT:
            return True
        if not _is_diffuse_kind(kind) and is_singular(CB.alpha_x[i], CB.alpha_y[i]):
            return True
    return False


@inline_stage_kernel
def guided_label(CB, count, wo, n_face):
    """The bounce kind of a guided direction (bounce limits): transmission below the surface,
    diffuse if the hit has a diffuse closure, glossy otherwise (Cycles labels by the sampled
    closure, which a guided direction does not have)."""
    side = LABEL_TRANSMIT if wo[0] * n_face[0] + wo[1] * n_face[1] + wo[2] * n_face[2] < 0.0 else LABEL_REFLECT
    for i in range(count):
        if _is_diffuse_kind(CB.kind[i]):
            return side | LABEL_DIFFUSE
    return side | LABEL_GLOSSY


@inline_stage_kernel
def _cone_pdf(axis, wo):
    """Solid-angle density of a direction drawn with theta uniform on [0, GLOW_CONE] around axis."""
    c = axis[0] * wo[0] + axis[1] * wo[1] + axis[2] * wo[2]
    cx = axis[1] * wo[2] - axis[2] * wo[1]
    cy = axis[2] * wo[0] - axis[0] * wo[2]
    cz = axis[0] * wo[1] - axis[1] * wo[0]
    s = np.sqrt(cx * cx + cy * cy + cz * cz)
    theta = np.arctan2(s, c)
    if not theta < GLOW_CONE:
        return 0.0
    return 1.0 / (2.0 * np.pi * GLOW_CONE * max(s, 1e-12))  # the lamp's own direction: weight ~0


@inline_stage_kernel
def _axis_to(G, k, x):
    dx, dy, dz = G.position[k, 0] - x[0], G.position[k, 1] - x[1], G.position[k, 2] - x[2]
    r = np.sqrt(dx * dx + dy * dy + dz * dz)
    if not r > 0.0:
        return (0.0, 0.0, 1.0), False
    return (dx / r, dy / r, dz / r), True


# every lamp counts (glow_pdf); a stand-in for the path stack the pdf then does not read
_ANY_STACK = np.zeros((1, 1), np.int8)


@inline_stage_kernel
def _lamps_pdf(G, C, p, here_only, x, wo):
    """Sum over the lamps (those glowing in path p's medium if here_only) of their pick
    probability x the cone's density of wo from x."""
    total = 0.0
    previous = 0.0
    for k in range(G.count):
        if not here_only or _glows_here(G, k, C, p):
            axis, ok = _axis_to(G, k, x)
            if ok:
                total += (G.cdf[k] - previous) * _cone_pdf(axis, wo)
        previous = G.cdf[k]
    return total


@inline_stage_kernel
def glow_pdf(G, x, wo):
    """The guide's solid-angle density of direction wo from x (the lamps' mixture)."""
    return _lamps_pdf(G, _ANY_STACK, 0, False, x, wo)


@inline_stage_kernel
def _toward(G, k, x, u1, u2):
    """A direction from x in the cone around lamp k, theta = GLOW_CONE u1: ((x, y, z), ok)."""
    axis, ok = _axis_to(G, k, x)
    if not ok:
        return axis, False
    theta = GLOW_CONE * u1
    phi = 2.0 * np.pi * u2
    st = np.sin(theta)
    return local_to_world1(axis[0], axis[1], axis[2], st * np.cos(phi), st * np.sin(phi), np.cos(theta)), True


@inline_stage_kernel
def glow_sample(G, x, u_pick, u1, u2):
    """A direction from x toward the cone around a lamp picked with u_pick: ((x, y, z), ok)."""
    k = G.count - 1
    for j in range(G.count):
        if u_pick < G.cdf[j]:
            k = j
            break
    return _toward(G, k, x, u1, u2)


@inline_stage_kernel
def _glows_here(G, k, C, p):
    """Whether lamp k glows in the medium of path p: the same volumes hold both (a vertex inside a
    glass sphere within the lamp's fog is not helped: its bounce must first leave the sphere)."""
    for j in range(C.shape[1]):
        if (C[p, j] > 0) != (G.stack[k, j] > 0):
            return False
    return True


@stage_kernel
def medium_glow_share(G, C, p):
    """The probability of the lamps glowing in path p's medium among all (0: no guiding here)."""
    total = 0.0
    previous = 0.0
    for k in range(G.count):
        if _glows_here(G, k, C, p):
            total += G.cdf[k] - previous
        previous = G.cdf[k]
    return total


@stage_kernel
def medium_glow_pdf(G, C, p, share, x, wo):
    """glow_pdf over the lamps glowing in path p's medium (renormalised by their share)."""
    return _lamps_pdf(G, C, p, True, x, wo) / share if share > 0.0 else 0.0


@stage_kernel
def medium_glow_sample(G, C, p, share, x, u, v):
    """A direction toward a lamp glowing in path p's medium: u picks the lamp (renormalised over
    those) and, rescaled within its share, the angle from its direction; v the azimuth."""
    target = u * share
    previous = 0.0
    seen = 0.0
    chosen = -1
    within = 0.0
    for k in range(G.count):
        if _glows_here(G, k, C, p):
            width = G.cdf[k] - previous
            chosen = k
            if target < seen + width:
                within = min(max((target - seen) / width, 0.0), 1.0 - 1e-16) if width > 0.0 else 0.0
                break
            seen += width
        previous = G.cdf[k]
    if chosen < 0:
        return (0.0, 0.0, 1.0), False
    return _toward(G, chosen, x, within, v)
