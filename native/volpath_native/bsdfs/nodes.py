"""BSDF node instances of a material, as the exporter reads them from Blender (plain Python, no
numba), and their packing into the arrays the kernels read.

One SurfaceNode is one BSDF node reached from the material output, with `weight` = the product
of the Mix/Add factors on its way (Cycles' mix_weight). Field names follow the node sockets; the
defaults are Blender's Principled BSDF defaults (`SurfaceNode.for_kind` gives each node type's own
defaults, from Blender source/blender/nodes/shader/nodes/node_shader_bsdf_*.cc).

`sanitize()` clamps every input where Cycles 5.0 clamps it (kernel/svm/closure.h: saturate,
max(ior, 1e-5), max(colour, 0), ...) and replaces non-finite numbers by the node default; it
returns one warning per change, without the material name (the caller prefixes it).
"""
from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass, field, fields, replace

import numpy as np

KINDS = ("diffuse", "principled", "glossy", "glass", "refraction", "metallic", "transparent", "translucent",
         "sheen")
KIND_CODES = {name: i for i, name in enumerate(KINDS)}
NODE_DIFFUSE, NODE_PRINCIPLED, NODE_GLOSSY, NODE_GLASS, NODE_REFRACTION, NODE_METALLIC, NODE_TRANSPARENT, \
    NODE_TRANSLUCENT, NODE_SHEEN = range(len(KINDS))

DISTRIBUTIONS = ("ggx", "beckmann", "multi_ggx")
DISTRIBUTION_CODES = {name: i for i, name in enumerate(DISTRIBUTIONS)}
DIST_GGX, DIST_BECKMANN, DIST_MULTI_GGX = range(3)

FRESNEL_MODES = ("f82", "physical")
FRESNEL_MODE_CODES = {name: i for i, name in enumerate(FRESNEL_MODES)}
METAL_F82, METAL_PHYSICAL = range(2)

MAX_CLOSURES = 16  # closures per hit (closures.py); Cycles drops the ones beyond its own limit likewise

RGB_FIELDS = ("color", "specular_tint", "coat_tint", "sheen_tint", "edge_tint", "conductor_n", "conductor_k",
              "emission_color")
FLOAT_FIELDS = ("weight", "roughness", "metallic", "ior", "alpha", "diffuse_roughness", "specular_ior_level",
                "transmission", "coat_weight", "coat_roughness", "coat_ior", "sheen_weight", "sheen_roughness",
                "anisotropic", "anisotropic_rotation", "subsurface_weight", "emission_strength")


def _rgb(*v):
    return field(default_factory=lambda: np.array(v, dtype=np.float64))


@dataclass
class SurfaceNode:
    kind: str = "principled"
    weight: float = 1.0
    color: np.ndarray = _rgb(0.8, 0.8, 0.8)
    roughness: float = 0.5
    metallic: float = 0.0
    ior: float = 1.5
    alpha: float = 1.0
    diffuse_roughness: float = 0.0
    specular_ior_level: float = 0.5
    specular_tint: np.ndarray = _rgb(1.0, 1.0, 1.0)
    transmission: float = 0.0
    coat_weight: float = 0.0
    coat_roughness: float = 0.03
    coat_ior: float = 1.5
    coat_tint: np.ndarray = _rgb(1.0, 1.0, 1.0)
    sheen_weight: float = 0.0
    sheen_roughness: float = 0.5
    sheen_tint: np.ndarray = _rgb(1.0, 1.0, 1.0)
    edge_tint: np.ndarray = _rgb(0.695, 0.726, 0.770)
    conductor_n: np.ndarray = _rgb(2.757, 2.513, 2.231)
    conductor_k: np.ndarray = _rgb(3.867, 3.404, 3.009)
    fresnel: str = "f82"
    distribution: str = "multi_ggx"
    anisotropic: float = 0.0
    anisotropic_rotation: float = 0.0
    subsurface_weight: float = 0.0
    # optional: Principled emission (surface_emission applies Cycles' layer attenuation to it)
    emission_color: np.ndarray = _rgb(1.0, 1.0, 1.0)
    emission_strength: float = 0.0

    def __post_init__(self):
        for name in RGB_FIELDS:
            v = np.asarray(getattr(self, name), dtype=np.float64).reshape(-1)
            if v.size == 1:
                v = np.repeat(v, 3)
            setattr(self, name, v[:3].copy())

    @classmethod
    def for_kind(cls, kind: str, **overrides) -> "SurfaceNode":
        """A node of `kind` with that Blender node's defaults, then `overrides`."""
        if kind not in KIND_CODES:
            raise ValueError(f"unknown BSDF node kind {kind!r} (known: {', '.join(KINDS)})")
        values = dict(_KIND_DEFAULTS.get(kind, {}))
        values.update(overrides)
        return cls(kind=kind, **values)

    # -- sanitising ------------------------------------------------------------------------------
    def sanitize(self) -> list[str]:
        """Clamp in place as Cycles does; return the warnings (empty when nothing changed)."""
        warnings: list[str] = []
        if self.kind not in KIND_CODES:
            warnings.append(f"unknown BSDF node kind {self.kind!r}: shaded as Diffuse BSDF")
            self.kind = "diffuse"
        default = SurfaceNode.for_kind(self.kind)
        for name in RGB_FIELDS:
            v = np.array(getattr(self, name), dtype=np.float64)
            bad = ~np.isfinite(v)
            if bad.any():
                v[bad] = getattr(default, name)[bad]
                warnings.append(f"{self._label(name)} is not finite: using the default {_fmt(getattr(default, name))}")
            if (v < 0).any():
                warnings.append(f"{self._label(name)} {_fmt(v)} is negative: clamped to 0 as Cycles")
                v = np.maximum(v, 0.0)
            setattr(self, name, v)
        for name in FLOAT_FIELDS:
            v = float(getattr(self, name))
            if not math.isfinite(v):
                d = float(getattr(default, name))
                warnings.append(f"{self._label(name)} is not finite: using the default {d:g}")
                setattr(self, name, d)
        for name, (lo, hi) in self._ranges().items():
            v = float(getattr(self, name))
            c = min(max(v, lo), hi)
            if c != v:
                warnings.append(f"{self._label(name)} {v:g} is outside [{lo:g}, {hi:g}]: clamped to {c:g} as Cycles")
                setattr(self, name, c)
        if self.kind == "refraction" and self.roughness < 0.0:
            # Cycles squares the Refraction roughness before saturating it: -r acts as r
            warnings.append(f"{self._label('roughness')} {self.roughness:g} is negative: Cycles uses its square, "
                            f"same as {-self.roughness:g}")
            self.roughness = -self.roughness
        if self.fresnel not in FRESNEL_MODE_CODES:
            warnings.append(f"unknown Metallic fresnel mode {self.fresnel!r}: using 'f82'")
            self.fresnel = "f82"
        if self.distribution not in DISTRIBUTION_CODES:
            fallback = "multi_ggx" if self.kind in ("principled", "glossy", "glass", "metallic") else "ggx"
            warnings.append(f"distribution {self.distribution!r} is not supported: using {fallback!r}")
            self.distribution = fallback
        if self.kind == "principled" and self.distribution == "beckmann":
            warnings.append("the Principled BSDF has no Beckmann distribution: using 'multi_ggx'")
            self.distribution = "multi_ggx"
        if self.kind == "refraction" and self.distribution == "multi_ggx":
            warnings.append("the Refraction BSDF has no Multiscatter GGX: using 'ggx'")
            self.distribution = "ggx"
        if self.kind == "principled" and self.subsurface_weight > 1e-5:
            warnings.append(f"Subsurface Weight {self.subsurface_weight:g}: subsurface scattering is not "
                            "simulated, that part is shaded as diffuse with the clamped Base Color")
        return warnings

    validate = sanitize  # the same sanitiser under the name callers may expect

    def sanitized(self) -> tuple["SurfaceNode", list[str]]:
        node = self.copy()
        return node, node.sanitize()

    def _ranges(self) -> dict:
        unit = (0.0, 1.0)
        r = {"weight": (0.0, math.inf), "ior": (1e-5, math.inf)}
        if self.kind == "principled":
            r.update(roughness=unit, metallic=unit, alpha=unit, diffuse_roughness=unit, transmission=unit,
                     anisotropic=unit, subsurface_weight=unit, coat_roughness=unit, sheen_roughness=unit,
                     specular_ior_level=(0.0, math.inf), coat_weight=(0.0, math.inf),
                     sheen_weight=(0.0, math.inf), coat_ior=(1.0, math.inf))
        elif self.kind == "glossy":
            r.update(roughness=unit, anisotropic=(-0.99, 0.99))
        elif self.kind == "metallic":
            r.update(roughness=unit, anisotropic=unit)
        elif self.kind == "refraction":
            r.update(roughness=(-1.0, 1.0))
        elif self.kind in ("glass", "sheen", "diffuse"):
            r.update(roughness=unit)
        return r

    def _label(self, name: str) -> str:
        return f"{self.kind.capitalize()} BSDF {name.replace('_', ' ').title()}"

    def copy(self) -> "SurfaceNode":
        return replace(self, **{n: np.array(getattr(self, n)) for n in RGB_FIELDS})

    # -- records (JSON-able dicts for .vpscene) ---------------------------------------------------
    def to_record(self) -> dict:
        rec = {}
        for f in fields(self):
            v = getattr(self, f.name)
            rec[f.name] = [float(c) for c in v] if f.name in RGB_FIELDS else (v if isinstance(v, str) else float(v))
        return rec

    @classmethod
    def from_record(cls, record: dict) -> "SurfaceNode":
        """Inverse of to_record; missing keys take the defaults of the record's kind, unknown keys
        are ignored."""
        kind = record.get("kind", "principled")
        known = {f.name for f in fields(cls)} - {"kind"}
        values = {k: v for k, v in record.items() if k in known}
        if kind not in KIND_CODES:
            return cls(kind=kind, **values)  # sanitize() reports it
        return cls.for_kind(kind, **values)


def _fmt(v) -> str:
    return "(" + ", ".join(f"{c:g}" for c in np.asarray(v).reshape(-1)) + ")"


# Blender 5.0 node defaults that differ from the Principled BSDF's
_KIND_DEFAULTS = {
    "diffuse": dict(roughness=0.0),
    "glossy": dict(roughness=0.5),
    "glass": dict(color=(1.0, 1.0, 1.0), roughness=0.0, ior=1.5),
    "refraction": dict(color=(1.0, 1.0, 1.0), roughness=0.0, ior=1.45, distribution="beckmann"),
    "metallic": dict(color=(0.617, 0.577, 0.540), roughness=0.5),
    "transparent": dict(color=(1.0, 1.0, 1.0)),
    "translucent": dict(),
    "sheen": dict(roughness=0.5),
}


def closure_count_bound(node: SurfaceNode) -> int:
    """At most how many closures the node expands into (Principled: one per active layer)."""
    if node.kind != "principled":
        return 1
    return (1 + (node.alpha < 1.0) + (node.sheen_weight > 1e-5) + (node.coat_weight > 1e-5)
            + (node.metallic > 1e-5) + (node.transmission > 1e-5) + 1 + (node.subsurface_weight > 1e-5))


def check_material(nodes: list[SurfaceNode]) -> list[str]:
    """Sanitise every node in place; the warnings of all of them, plus one if the material may
    exceed MAX_CLOSURES (the extra closures would be dropped, as Cycles drops them)."""
    warnings = []
    for node in nodes:
        warnings += node.sanitize()
    bound = sum(closure_count_bound(n) for n in nodes if n.weight != 0.0)
    if bound > MAX_CLOSURES:
        warnings.append(f"{len(nodes)} BSDF nodes may expand into {bound} closures, more than the {MAX_CLOSURES} "
                        "a hit holds: the last ones are dropped")
    return warnings


# ---------------------------------------------------------------------------------------------
# Arrays for the kernels
# ---------------------------------------------------------------------------------------------
TABLE_FIELDS = ["node_start", "node_count", "kind", "fresnel", "distribution"] + list(FLOAT_FIELDS) + list(RGB_FIELDS)
SurfaceNodeTable = namedtuple("SurfaceNodeTable", TABLE_FIELDS)


def surface_node_table(materials_nodes: list[list[SurfaceNode]]) -> SurfaceNodeTable:
    """Pack every material's nodes: material m owns rows node_start[m] .. + node_count[m].
    Nodes are sanitised copies (call sanitize() yourself first to collect the warnings)."""
    flat = []
    start = np.zeros(len(materials_nodes), np.int32)
    count = np.zeros(len(materials_nodes), np.int32)
    for m, nodes in enumerate(materials_nodes):
        start[m] = len(flat)
        count[m] = len(nodes)
        for node in nodes:
            clean, _ = node.sanitized()
            flat.append(clean)
    j = len(flat)
    cols = {
        "node_start": start, "node_count": count,
        "kind": np.array([KIND_CODES[n.kind] for n in flat], np.int32).reshape(j),
        "fresnel": np.array([FRESNEL_MODE_CODES[n.fresnel] for n in flat], np.int32).reshape(j),
        "distribution": np.array([DISTRIBUTION_CODES[n.distribution] for n in flat], np.int32).reshape(j),
    }
    for name in FLOAT_FIELDS:
        cols[name] = np.array([getattr(n, name) for n in flat], np.float64).reshape(j)
    for name in RGB_FIELDS:
        cols[name] = np.array([getattr(n, name) for n in flat], np.float64).reshape(j, 3)
    return SurfaceNodeTable(**cols)


def node_records(nodes: list[SurfaceNode]) -> list[dict]:
    return [n.to_record() for n in nodes]


def nodes_from_records(records: list[dict]) -> list[SurfaceNode]:
    return [SurfaceNode.from_record(r) for r in records]
