"""Heterogeneous media from dense voxel grids: lookup, majorant grid, DDA, delta and ratio tracking.

A GridMedium is what a Blender Volume object (OpenVDB grids) becomes: a dense float32 density grid
with an index->world affine transform, per-unit-density scattering/absorption coefficients (the
Principled Volume conversion, see `principled_volume_coefficients`), optional per-voxel colour and
emission grids, and a coarse majorant grid for unbiased free-flight sampling.

Conventions (those of OpenVDB and Cycles):
- Voxel (i, j, k) of an array holds the value at *index-space* point (i, j, k) (voxel centres sit
  on integer index coordinates); `index_to_world` maps index space to world space.
- Lookups are trilinear in index space with floor(), as Cycles' default "Linear" interpolation
  (intern/cycles/kernel/util/image_3d.h, kernel_image_interp_trilinear_nanovdb). Values outside
  the array are the grid background, 0. Cycles 5.x evaluates volume attributes stochastically
  (one trilinear corner picked with the trilinear weights, kernel/geom/primitive.h,
  primitive_volume_attribute(..., stochastic=true)); its expectation is exactly the trilinear
  interpolation of the *per-voxel* quantity, which is why per-voxel nonlinear terms (clamping,
  colour-dependent absorption) are applied before interpolation here.
- Ray parameters t are world-space distances when directions are unit vectors (an affine map
  preserves the ray parameter), so all coefficients are per world metre.

Tracking follows Cycles' null-scattering path (intern/cycles/kernel/integrator/shade_volume.h,
volume_null_event_coefficients / volume_scatter_probability: a scalar majorant = max channel,
scatter-vs-null decision with throughput-weighted channel pdf, absorption never sampled but carried
in the weights) and pbrt-v4's SampleT_maj / DDAMajorantIterator (src/pbrt/media.h) for walking the
majorant grid cell by cell. Lookups and tracking run per ray in compiled numba kernels
(grid_kernels, on the arrays of `GridMedium.tables`), which the integrator's kernels call directly;
the methods below are loops over those kernels for numpy callers.

Using it from a path tracer (all distances from the segment origin, directions unit length):
- free flight on a segment [0, t_seg]: `f = medium.sample_free_flight(o, d, t_seg, rng, beta)`;
  add `beta * f.emission` to L; multiply beta by `f.weight`; where `f.scattered`, the path
  scatters at `o + d * f.t` with the medium's HG phase `g` (f.weight already holds sigma_s/pdf).
- shadow rays: multiply by `medium.transmittance(o, d, dist, rng)`.
- inside a numba kernel, per ray: `grid_kernels.grid_free_flight(G, ...)`,
  `grid_transmittance(G, ...)` and `grid_scattering(G, x, y, z)` with `G = medium.tables`, random
  numbers from (key, stream); check `G.flags` afterwards with `medium.check_flags(G)`.
- a homogeneous medium overlapping the grid: sample its distance analytically first and track
  the grid only up to it (the earlier of two independent collision processes is the first event
  of their sum); shadow transmittances multiply.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from .grid_kernels import (FLAG_BUDGET, FLAG_LOOKUPS, FLAG_MAJORANT, FLAG_RESIDUAL, N_FLAGS, TRACKING_BUDGET, GridTables,
                           box_interval_many, coefficients_many, dda_cells1, density_many, track_many)
from . import grid_kernels
from .medium_motion import motion_fields
from .scene import Mesh, SceneError, rgb
from .shading.images import empty_image_table

__all__ = ["GridMedium", "FreeFlight", "MajorantTooLowError", "principled_volume_coefficients",
           "volume_object_density_factor", "blackbody_rec709", "blackbody_emission"]

#: Default number of majorant cells along each axis (capped by the grid resolution). Measured on
#: the 128^3 cloud of bench_cloud.py (micro-benchmark of the trackers): 32 instead of pbrt-v4's 16
#: takes 25 % fewer free-flight lookups and, with RESIDUAL_MARGIN 4, 1/9 of the shadow-ray variance
#: per unit time; 64 gains nothing more (the DDA's steps cost what the lookups save).
DEFAULT_MAJORANT_RESOLUTION = 32
#: Residual ratio tracking's rate as a multiple of the cell's half range (>= 1: factors stay in
#: [1 - 1/margin, 1 + 1/margin]): more (cheap, trilinear) lookups, less variance (exponent:
#: integral of (sigma_t - control)^2 / rate); measured best near 4 on the cloud.
RESIDUAL_MARGIN = 4.0


class MajorantTooLowError(RuntimeError):
    """Debug mode found sigma_t above the majorant: tracking would be biased."""


def principled_volume_coefficients(color=0.5, density=1.0, absorption_color=0.0,
                                   object_density_factor=1.0, mix_weight=1.0):
    """Per-unit-density (sigma_s, sigma_a) of a Principled Volume, as Cycles computes them.

    intern/cycles/kernel/svm/closure.h, svm_node_principled_volume:
      rho = mix_weight * object_volume_density * max(Density, 0)  (x density attribute)
      sigma_s = Color * rho;  sigma_a = rho * max(1 - Color, 0) * max(1 - sqrt(Absorption), 0).
    object_density_factor: `volume_object_density_factor` for Volume objects, 1 for meshes.
    Returns two RGB float64 arrays; multiply by the density attribute to get coefficients in 1/m.
    """
    color = rgb(color, "principled volume color")
    absorption = np.maximum(np.sqrt(np.maximum(rgb(absorption_color, "absorption color"), 0.0)), 0.0)
    rho = float(mix_weight) * float(object_density_factor) * max(float(density), 0.0)
    sigma_s = color * rho
    sigma_a = rho * np.maximum(1.0 - color, 0.0) * np.maximum(1.0 - absorption, 0.0)
    return sigma_s, sigma_a


def volume_object_density_factor(object_to_world, object_space: bool = True) -> float:
    """Cycles' density scaling of Volume objects: 1 / |M (1,1,1)/sqrt(3)| when the volume's render
    space is 'OBJECT' (Blender's default), else 1 (intern/cycles/scene/object.cpp,
    object_volume_density; Blender side sets object_space in intern/cycles/blender/volume.cpp)."""
    if not object_space:
        return 1.0
    linear = np.asarray(object_to_world, dtype=np.float64).reshape(4, 4)[:3, :3]
    length = float(np.linalg.norm(linear @ (np.ones(3) / np.sqrt(3.0))))
    if not np.isfinite(length) or length <= 0.0:
        raise SceneError("volume object transform is degenerate: cannot compute its density scale")
    return 1.0 / length


from .shading.blackbody import BLACKBODY_SIGMA, blackbody_rec709  # noqa: E402  (one implementation)


def blackbody_emission(temperature, blackbody_intensity, tint=1.0) -> np.ndarray:
    """Principled Volume blackbody emission per unit length, W/(m^3 sr), shape (..., 3):
    tint x sigma/pi x mix(1, T^4, intensity) x blackbody_rec709(T), T = max(temperature, 0)
    (kernel/svm/closure.h svm_node_principled_volume; zero when intensity <= 0, as Cycles skips it).
    Not scaled by density; multiply by the mix weight and object density factor."""
    t = np.maximum(np.asarray(temperature, dtype=np.float64), 0.0)
    intensity = float(blackbody_intensity)
    if not intensity > 0.0:
        return np.zeros(t.shape + (3,))
    power = BLACKBODY_SIGMA * ((1.0 - intensity) + intensity * t ** 4)
    emission = power[..., None] * blackbody_rec709(t) * rgb(tint, "blackbody tint")
    return np.where((power > 0.0)[..., None], emission, 0.0)


@dataclass
class FreeFlight:
    """Result of `GridMedium.sample_free_flight` for N rays.

    t: (N,) distance of the event (t_max where no scatter happened).
    scattered: (N,) True where a real scattering collision was sampled at t.
    weight: (N,3) factor for the path throughput: at a scatter vertex it already contains
        sigma_s / pdf (the integrator then samples the phase function); otherwise it is an
        unbiased transmittance estimate over [t_min, t_max] (exactly 1 for rays missing the grid).
    emission: (N,3) estimate of the emitted radiance collected along [t_min, t]; multiply by the
        path throughput *before* this segment.
    """

    t: np.ndarray
    scattered: np.ndarray
    weight: np.ndarray
    emission: np.ndarray


class GridMedium:
    """A heterogeneous medium: sigma_s(x) = density(x) * sigma_s, sigma_a(x) = density(x) * sigma_a.

    density: (nx, ny, nz) voxel values (negative values clamp to 0 per voxel, as Cycles' stochastic
        lookup of max(density * attribute, 0)).
    index_to_world: 4x4 affine map of index space (voxel (i,j,k) at point (i,j,k)) to world.
    sigma_s, sigma_a: RGB coefficients per unit density, 1/m (see principled_volume_coefficients).
    scatter_grid, absorb_grid: optional (nx, ny, nz, 3) per-voxel RGB factors replacing sigma_s /
        sigma_a (colour attributes: see `with_color_grid`); both or neither.
    emission: constant RGB emitted radiance per unit length W/(m^3 sr), *not* scaled by density
        (Cycles' Principled Volume emission), applied inside the medium's box, index space
        [-1, n + 1] per axis of the given arrays: Cycles' volume bounds (see the padding below).
    emission_grid: optional (nx, ny, nz, 3) per-voxel emission added to it (blackbody, flame), interpolated
        trilinearly: the expectation of Cycles' stochastic lookup of the per-voxel value.
    g: Henyey-Greenstein anisotropy.
    majorant_resolution: majorant cells per axis (at most one cell per voxel interval).
    debug: check at every density evaluation that sigma_t <= majorant; raise MajorantTooLowError.
    """

    is_homogeneous = False
    motion = None  # (S, 3, 4) object -> world over the shutter: set_motion
    motion_object_to_world = None

    def __init__(self, name: str, density, index_to_world, sigma_s, sigma_a, *, g: float = 0.0,
                 emission=0.0, scatter_grid=None, absorb_grid=None, emission_grid=None,
                 majorant_resolution: int = DEFAULT_MAJORANT_RESOLUTION, debug: bool = False):
        self.name = name
        self.g = float(np.clip(np.nan_to_num(float(g)), -0.999, 0.999))
        self.sigma_s = np.maximum(rgb(sigma_s, f"grid medium '{name}' sigma_s"), 0.0)
        self.sigma_a = np.maximum(rgb(sigma_a, f"grid medium '{name}' sigma_a"), 0.0)
        # Emission is not clamped: Cycles' blackbody colour has small negative green/blue below
        # ~1000 K and the Principled Volume adds it as is (kernel/svm/closure.h).
        self.emission = rgb(emission, f"grid medium '{name}' emission")
        self.debug = bool(debug)

        density = np.asarray(density, dtype=np.float32)
        if density.ndim != 3 or min(density.shape) < 1:
            raise SceneError(f"grid medium '{name}': density must be a non-empty 3D array, got {density.shape}")
        if not np.all(np.isfinite(density)):
            raise SceneError(f"grid medium '{name}': density grid has non-finite values")
        if (scatter_grid is None) != (absorb_grid is None):
            raise SceneError(f"grid medium '{name}': scatter_grid and absorb_grid go together")
        transform = np.asarray(index_to_world, dtype=np.float64).reshape(4, 4)
        if not np.all(np.isfinite(transform)) or abs(np.linalg.det(transform[:3, :3])) < 1e-30:
            raise SceneError(f"grid medium '{name}': index_to_world is singular or not finite")

        # Zero padding, one voxel below and two above: the trilinear interpolant falls to the
        # background (0) inside the array, so lookups never special-case the border, and the
        # padded box [lo - 1, hi + 2] (index space) is exactly Cycles' volume bounds mesh for
        # linear interpolation (scene/volume.cpp VolumeMeshBuilder: bounding box of the active
        # voxels dilated by one; measured with Blender 5.0.1 Cycles: constant emission of a
        # Volume object fills exactly [lo - 1, hi + 2]).
        def pad(grid, clamp=True):  # written in place: no second full-size temporary
            out = np.zeros(tuple(np.add(grid.shape[:3], 3)) + grid.shape[3:], dtype=np.float32)
            if clamp:
                np.maximum(grid, 0.0, out=out[1:-2, 1:-2, 1:-2])
            else:
                out[1:-2, 1:-2, 1:-2] = grid
            return out

        self.density = pad(density)
        self.shape = np.array(self.density.shape, dtype=np.int64)
        shift = np.eye(4)
        shift[:3, 3] = -1.0  # padded index p corresponds to original index p - 1
        self.source_index_to_world = transform
        self.index_to_world = transform @ shift
        self.world_to_index = np.linalg.inv(self.index_to_world)

        self.scatter_grid = self.absorb_grid = self.emission_grid = None
        if scatter_grid is not None:
            self.scatter_grid = pad(self._checked_rgb_grid(scatter_grid, density.shape, "scatter_grid"))
            self.absorb_grid = pad(self._checked_rgb_grid(absorb_grid, density.shape, "absorb_grid"))
        if emission_grid is not None:
            self.emission_grid = pad(self._checked_rgb_grid(emission_grid, density.shape, "emission_grid"),
                                     clamp=False)
        self.majorant_resolution = int(majorant_resolution)
        self._build_majorant_grid(self.majorant_resolution)
        # What the kernels record when called through `tables` (bound violations, calls ended by
        # the step budget), and the flag that abandons tracking (set when a render is cancelled).
        self._flags = np.zeros(N_FLAGS, dtype=np.int64)
        self._violation = np.zeros((2, 5))
        self._stop = np.zeros(1, dtype=np.int64)
        self.lookups = np.zeros(3, dtype=np.int64)  # coefficient lookups per tracking mode (check_flags)

    # ------------------------------------------------------------------------------------------
    # Construction helpers
    # ------------------------------------------------------------------------------------------
    def _checked_rgb_grid(self, grid, shape, what):
        grid = np.asarray(grid, dtype=np.float32)
        if grid.shape != tuple(shape) + (3,):
            raise SceneError(f"grid medium '{self.name}': {what} has shape {grid.shape}, expected {tuple(shape) + (3,)}")
        if not np.all(np.isfinite(grid)):
            raise SceneError(f"grid medium '{self.name}': {what} has non-finite values")
        return grid  # negative scatter/absorb factors clamp to 0 when padded (emission stays signed)

    @classmethod
    def with_color_grid(cls, name, density, color_grid, index_to_world, *, color=0.5, density_scale=1.0,
                        absorption_color=0.0, object_density_factor=1.0, mix_weight=1.0, **kwargs):
        """A Principled Volume whose Color is multiplied by a colour attribute grid (nx,ny,nz,3).

        Per voxel C = Color * attribute, sigma_s = rho C, sigma_a = rho max(1 - C, 0)(1 - sqrt(A)),
        interpolated after the per-voxel nonlinearity (matches Cycles' stochastic lookup in
        expectation; kernel/svm/closure.h svm_node_principled_volume)."""
        rho = float(mix_weight) * float(object_density_factor) * max(float(density_scale), 0.0)
        voxel_color = np.asarray(color_grid, dtype=np.float32) * rgb(color, "color").astype(np.float32)
        absorption = np.maximum(1.0 - np.sqrt(np.maximum(rgb(absorption_color, "absorption color"), 0.0)), 0.0)
        scatter = voxel_color
        absorb = np.maximum(1.0 - voxel_color, 0.0) * absorption.astype(np.float32)
        return cls(name, density, index_to_world, np.full(3, rho), np.full(3, rho),
                   scatter_grid=scatter, absorb_grid=absorb, **kwargs)

    def _build_majorant_grid(self, resolution: int):
        """Per cell: max over the cell of each channel's sigma_t, conservatively.

        The trilinear interpolant on a box is a convex combination of the lattice values whose
        voxels touch it, so the max over lattice points floor(lo)..ceil(hi) bounds it; the product
        of the maxima of density and extinction factor bounds the max of their product."""
        extent = self.shape - 1  # index-space box [0, shape-1] of the padded array
        self.majorant_shape = np.minimum(max(resolution, 1), extent).astype(np.int64)
        self.cell_size = extent / self.majorant_shape  # in index units, per axis
        ranges = []
        for axis in range(3):
            cells = np.arange(self.majorant_shape[axis])
            lo = np.floor(cells * self.cell_size[axis]).astype(np.int64)
            hi = np.minimum(np.ceil((cells + 1) * self.cell_size[axis]).astype(np.int64), extent[axis])
            ranges.append((lo, hi))

        def cell_reduce(grid, reduce):
            for axis in range(3):
                lo, hi = ranges[axis]
                slabs = [reduce(np.take(grid, np.arange(a, b + 1), axis=axis), axis=axis) for a, b in zip(lo, hi)]
                grid = np.stack(slabs, axis=axis)
            return grid

        cell_max = lambda grid: cell_reduce(grid, np.max)
        max_density, min_density = cell_max(self.density), cell_reduce(self.density, np.min)
        if self.scatter_grid is not None:
            extinction = self.scatter_grid * self.sigma_s + self.absorb_grid * self.sigma_a
            max_factor, min_factor = cell_max(extinction), cell_reduce(extinction, np.min)
        else:
            max_factor = min_factor = (self.sigma_s + self.sigma_a)[None, None, None, :]
        self.majorant_density = max_density
        # Per channel bounds of sigma_t per cell (the minorant bounds the min the same way).
        self.majorant_rgb = (max_density[..., None] * max_factor).astype(np.float64)
        self.minorant_rgb = (min_density[..., None] * min_factor).astype(np.float64)
        # Residual ratio tracking: the control is the middle of each channel's range and the rate
        # (one for all channels) the largest half width, so |sigma_t - control| <= rate and every
        # factor lies in [0, 2] (grid_kernels._track mode 1).
        self._set_residual(0.5 * (self.majorant_rgb + self.minorant_rgb),
                           RESIDUAL_MARGIN * 0.5 * (self.majorant_rgb - self.minorant_rgb).max(axis=-1))
        self.extinction_extrema = np.stack([self.minorant_rgb.min(axis=-1), self.majorant_rgb.max(axis=-1)], axis=-1)
        # Scalar majorant (max channel), as Cycles: one free-flight distribution for all channels.
        majorant = self.majorant_rgb.max(axis=-1)
        # Emission is collected at tentative collisions (E / majorant each): as Cycles, the
        # majorant is the larger of extinction and emission (C5 kernel/bake/bake.h
        # kernel_volume_density_evaluate: max(maxchan sigma_t, maxchan emission)), a bound here
        # (the constant part plus the grid's cell maximum). Extra null collisions only: unbiased.
        glow = np.full(majorant.shape, float(np.abs(self.emission).max()))
        if self.emission_grid is not None:
            glow = glow + cell_max(np.abs(self.emission_grid).max(axis=-1))
        majorant = np.maximum(majorant, glow)
        self.majorant_grid = majorant.astype(np.float64)
        # emissive_media draws points in proportion to each cell's mean emission
        mean = np.full(majorant.shape, float(np.abs(self.emission).max()))
        if self.emission_grid is not None:
            mean = mean + cell_reduce(np.abs(self.emission_grid).max(axis=-1), np.mean)
        self.emission_weight = mean

    # ------------------------------------------------------------------------------------------
    # Geometry
    # ------------------------------------------------------------------------------------------
    def world_bounds(self):
        """(lo, hi) world AABB of the region where the density can be non-zero."""
        corners = np.array([[x, y, z, 1.0] for x in (0, 1) for y in (0, 1) for z in (0, 1)])
        corners[:, :3] *= (self.shape - 1)
        world = corners @ self.index_to_world.T
        return world[:, :3].min(axis=0), world[:, :3].max(axis=0)

    def box_corners_world(self) -> np.ndarray:
        """(8,3) world corners of the medium's box (index corners ordered x-major, then y, z), for a
        boundary mesh around it."""
        corners = np.array([[x, y, z, 1.0] for x in (0, 1) for y in (0, 1) for z in (0, 1)])
        corners[:, :3] *= (self.shape - 1)
        return (corners @ self.index_to_world.T)[:, :3]

    # Faces of the corner cube above (corner index = 4x + 2y + z), counter-clockwise from outside.
    _BOX_TRIANGLES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5],    # x = 0, x = 1
                               [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],    # y = 0, y = 1
                               [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])   # z = 0, z = 1

    def set_motion(self, transforms, object_to_world):
        """Move the medium with its object over the shutter, as Cycles shades a moving volume
        (medium_motion.py): transforms (S >= 2, 3|4, 4) object -> world at S evenly spaced shutter
        steps; object_to_world (3|4, 4) is the transform the medium was built at (its
        index_to_world = object_to_world @ index_to_object; the exporter's shutter centre)."""
        transforms = np.asarray(transforms, dtype=np.float64)
        reference = np.asarray(object_to_world, dtype=np.float64)
        if transforms.ndim != 3 or len(transforms) < 2 or transforms.shape[1] not in (3, 4) \
                or transforms.shape[2] != 4 or reference.shape not in ((3, 4), (4, 4)):
            raise SceneError(f"medium '{self.name}': motion must be (S >= 2, 3 or 4, 4) transforms and a (4, 4) "
                             f"reference, got {transforms.shape} and {reference.shape}")
        linear = transforms[:, :3, :3]
        if not (np.all(np.isfinite(transforms)) and np.all(np.isfinite(reference))) \
                or np.min(np.abs(np.linalg.det(linear))) < 1e-30 or abs(np.linalg.det(reference[:3, :3])) < 1e-30:
            raise SceneError(f"medium '{self.name}': its motion transforms are singular or not finite")
        self.motion = np.ascontiguousarray(transforms[:, :3, :])
        self.motion_object_to_world = np.vstack([reference[:3], [0.0, 0.0, 0.0, 1.0]])

    def boundary_mesh(self, material_id: int) -> Mesh:
        """A closed box mesh (outward normals) around the medium, for a null-surface material whose
        medium is this grid: the volume-stack boundary, as Cycles' volume bounds mesh. A moving
        medium's box is an object-space mesh placed by its motion steps (as a moving fog box)."""
        triangles = self._BOX_TRIANGLES
        materials = np.full(len(triangles), int(material_id), dtype=np.int32)
        if self.motion is None:
            if np.linalg.det(self.index_to_world[:3, :3]) < 0:  # a mirroring transform flips winding
                triangles = triangles[:, ::-1]
            return Mesh(f"{self.name} bounds", self.box_corners_world(), triangles, materials)
        to_object = np.linalg.inv(self.motion_object_to_world)
        if np.linalg.det((to_object @ self.index_to_world)[:3, :3]) < 0:  # instances flip their own mirroring
            triangles = triangles[:, ::-1]
        corners = self.box_corners_world() @ to_object[:3, :3].T + to_object[:3, 3]
        return Mesh(f"{self.name} bounds", corners, triangles, materials,
                    instances=self.motion_object_to_world[None, :3], motion=self.motion[None])

    # ------------------------------------------------------------------------------------------
    # Serialisation (for the .vpscene format: a JSON header plus named arrays)
    # ------------------------------------------------------------------------------------------
    def to_record(self):
        """(header, arrays): JSON-ready scalars/lists and float32 arrays that `from_record` turns
        back into an identical medium (grids stored without the internal padding)."""
        inner = (slice(1, -2),) * 3
        header = {"type": "grid", "name": self.name, "sigma_s": self.sigma_s.tolist(),
                  "sigma_a": self.sigma_a.tolist(), "g": self.g, "emission": self.emission.tolist(),
                  "index_to_world": self.source_index_to_world.tolist(),
                  "majorant_resolution": self.majorant_resolution}
        arrays = {"density": self.density[inner]}
        for key in ("scatter_grid", "absorb_grid", "emission_grid"):
            grid = getattr(self, key)
            if grid is not None:
                arrays[key] = grid[inner]
        self._motion_record(header, arrays)
        return header, arrays

    def _motion_record(self, header: dict, arrays: dict):
        """A moving medium's record: its motion steps (array "motion") and reference transform."""
        if self.motion is not None:
            header["motion_object_to_world"] = self.motion_object_to_world.tolist()
            arrays["motion"] = self.motion

    def _load_motion(self, header: dict, arrays: dict):
        if "motion" in arrays or "motion_object_to_world" in header:
            if "motion" not in arrays or "motion_object_to_world" not in header:
                raise SceneError(f"medium record '{self.name}': motion and motion_object_to_world go together")
            self.set_motion(arrays["motion"], header["motion_object_to_world"])

    @classmethod
    def from_record(cls, header: dict, arrays: dict, debug: bool = False) -> "GridMedium":
        if header.get("type") != "grid" or "density" not in arrays:
            raise SceneError(f"grid medium record '{header.get('name')}' is incomplete")
        medium = cls(header["name"], arrays["density"], np.asarray(header["index_to_world"]),
                     header["sigma_s"], header["sigma_a"], g=header.get("g", 0.0),
                     emission=header.get("emission", 0.0), scatter_grid=arrays.get("scatter_grid"),
                     absorb_grid=arrays.get("absorb_grid"), emission_grid=arrays.get("emission_grid"),
                     majorant_resolution=header.get("majorant_resolution", DEFAULT_MAJORANT_RESOLUTION),
                     debug=debug)
        medium._load_motion(header, arrays)
        return medium

    def _set_residual(self, control_rgb, residual_rate) -> None:
        """Residual ratio tracking's control extinction (R0, R1, R2, 3) and rate (R0, R1, R2) per
        cell, packed into one array (residual_cells: a tracker's cell step reads both from one
        cache line; as two arrays those two loads were ~30 % of the fire's tracking time, README
        session 24); control_rgb and residual_rate are views of it (edits show through)."""
        cells = np.empty(np.shape(residual_rate) + (4,))
        cells[..., 0] = residual_rate
        cells[..., 1:] = control_rgb
        self.residual_cells = cells
        self.residual_rate, self.control_rgb = cells[..., 0], cells[..., 1:]

    def memory_bytes(self) -> int:
        arrays = [self.density, self.scatter_grid, self.absorb_grid, self.emission_grid, self.majorant_grid,
                  self.majorant_density, self.majorant_rgb, self.minorant_rgb, self.control_rgb,
                  self.residual_rate, self.extinction_extrema]
        return int(sum(a.nbytes for a in arrays if a is not None))

    # ------------------------------------------------------------------------------------------
    # Tables for the compiled kernels (grid_kernels)
    # ------------------------------------------------------------------------------------------
    @property
    def tables(self) -> GridTables:
        """The arrays and scalars grid_kernels' functions take, in the layouts they are compiled for.

        The arrays are the medium's own (no copies): edits of majorant_grid etc. in place show
        through. tables.flags / tables.violation are this medium's shared bound-violation and
        step-budget record (see grid_kernels); `check_flags(tables)` reads it."""
        no_grid = self._NO_GRID
        return GridTables(
            density=self.density,
            scatter_grid=self.scatter_grid if self.scatter_grid is not None else no_grid,
            absorb_grid=self.absorb_grid if self.absorb_grid is not None else no_grid,
            emission_grid=self.emission_grid if self.emission_grid is not None else no_grid,
            has_color=self.scatter_grid is not None,
            has_emission_grid=self.emission_grid is not None,
            has_emission=bool(np.any(self.emission != 0)),
            world_to_index=np.ascontiguousarray(self.world_to_index[:3], dtype=np.float64),
            shape=self.shape,
            sigma_s=self.sigma_s, sigma_a=self.sigma_a, emission=self.emission,
            majorant=self.majorant_grid, residual_cells=self.residual_cells,
            extrema=self.extinction_extrema,
            cell_shape=self.majorant_shape,
            index_to_cell=self.majorant_shape / (self.shape - 1).astype(np.float64),
            g=self.g, nee_uniform_share=grid_kernels.NEE_UNIFORM_SHARE,
            flags=self._flags, violation=self._violation, stop=self._stop,
            **self._program_tables(),
            **motion_fields(self.motion, self.motion_object_to_world, self.world_to_index),
            emission_sampled=False, emission_density=self._NO_DENSITY)

    _NO_GRID = np.zeros((1, 1, 1, 3), dtype=np.float32)
    _NO_DENSITY = np.zeros((1, 1, 1))
    _NO_PROGRAM = dict(has_program=False, camera_boost=False, program_code=np.zeros(1, np.int32),
                       program_init=np.zeros(1), program_tables=np.zeros(1), registers=np.zeros(1),
                       frame=np.zeros((2, 3, 4)), attributes=np.zeros((1, 1, 1, 1), np.float32),
                       images=empty_image_table(),
                       has_extinction_program=False, extinction_code=np.zeros(1, np.int32),
                       extinction_init=np.zeros(1), correction_probability=1.0)

    def _program_tables(self) -> dict:
        """The GridTables fields of a shader-program medium (none here: program_medium.py)."""
        return self._NO_PROGRAM

    def _call_tables(self) -> GridTables:
        """Tables with a fresh violation record and their own frames (a moving medium rewrites
        them per path: medium_motion.py), private to one call or batch."""
        tables = self.tables
        return tables._replace(flags=np.zeros(N_FLAGS, dtype=np.int64), violation=np.zeros((2, 5)),
                               registers=np.zeros(max(tables.program_init.shape[0],
                                                      tables.extinction_init.shape[0])),
                               world_to_index=tables.world_to_index.copy(), frame=tables.frame.copy())

    def check_flags(self, tables: GridTables) -> int:
        """Read and clear what the kernels recorded in tables.flags. Returns how many tracking calls
        the step budget ended (those rays were treated as opaque: see grid_kernels). Bound
        violations raise MajorantTooLowError in debug mode (unchecked otherwise, as the bounds are
        conservative by construction)."""
        flags, violation = tables.flags.copy(), tables.violation.copy()
        tables.flags[:] = 0
        self.lookups += flags[FLAG_LOOKUPS:FLAG_LOOKUPS + 3]
        if self.debug and flags[FLAG_MAJORANT]:
            value, bound, *point = violation[FLAG_MAJORANT]
            raise MajorantTooLowError(
                f"grid medium '{self.name}': sigma_t {value:.6g} exceeds the majorant {bound:.6g} at {point} "
                f"({int(flags[FLAG_MAJORANT])} points): tracking is biased")
        if self.debug and flags[FLAG_RESIDUAL]:
            value, bound, *point = violation[FLAG_RESIDUAL]
            raise MajorantTooLowError(
                f"grid medium '{self.name}': |sigma_t - control| {value:.6g} exceeds the residual rate {bound:.6g} "
                f"at {point} ({int(flags[FLAG_RESIDUAL])} points): residual tracking is biased")
        return int(flags[FLAG_BUDGET])

    def budget_message(self, count: int) -> str:
        """The user-facing warning for `count` tracking calls ended by the step budget."""
        return (f"grid medium '{self.name}': {count} rays would have needed more than {TRACKING_BUDGET} "
                f"collisions (majorant up to {float(self.majorant_grid.max()):.3g} per m: is the Density "
                "extreme?) and were treated as opaque")

    # ------------------------------------------------------------------------------------------
    # Lookups (loops over the scalar kernels)
    # ------------------------------------------------------------------------------------------
    def density_at(self, points_world) -> np.ndarray:
        """(M,) interpolated density at world points (M,3)."""
        points = _points(points_world)
        out = np.empty(len(points))
        density_many(self.tables, points, out)
        return out

    def coefficients(self, points_world, tables=None):
        """(sigma_s, sigma_t, emission), each (M,3) float64, at world points (M,3) (of `tables`
        when given: the medium's with another program, ProgramMedium._extinction_agrees)."""
        points = _points(points_world)
        sigma_s, sigma_t, emission = (np.empty((len(points), 3)) for _ in range(3))
        coefficients_many(self.tables if tables is None else tables, points, sigma_s, sigma_t, emission)
        return sigma_s, sigma_t, emission

    # ------------------------------------------------------------------------------------------
    # DDA and tracking (loops over the scalar kernels)
    # ------------------------------------------------------------------------------------------
    def dda_cells(self, origin, direction, t_min=0.0, t_max=np.inf):
        """Majorant cells a single ray visits, in order, with their [t0, t1) intervals: a list of
        ((i, j, k), t0, t1). For tests and debugging; the trackers run the same stepping."""
        o, d = _points(np.atleast_2d(origin))[0], _points(np.atleast_2d(direction))[0]
        limit = int(self.majorant_shape.sum()) + 3  # a straight line crosses each plane at most once
        cells, spans = np.empty((limit, 3), dtype=np.int64), np.empty((limit, 2))
        count = dda_cells1(self.tables, o[0], o[1], o[2], d[0], d[1], d[2], float(t_min), float(t_max),
                           cells, spans)
        return [(tuple(int(v) for v in cells[i]), float(spans[i, 0]), float(spans[i, 1])) for i in range(count)]

    def _run_tracking(self, origins, dirs, t_min, t_max, rng, mode, throughput=None):
        origins, dirs = _points(origins), _points(dirs)
        n = len(origins)
        t_min = np.ascontiguousarray(np.broadcast_to(np.asarray(t_min, dtype=np.float64), (n,)))
        t_max = np.ascontiguousarray(np.broadcast_to(np.asarray(t_max, dtype=np.float64), (n,)))
        throughput = np.ones((n, 3)) if throughput is None else _points(throughput)
        # One key per ray from the caller's generator, stream 0: reproducible for a generator state.
        keys = rng.integers(0, 2 ** 63, n, dtype=np.int64).astype(np.uint64)
        t_out, scattered = np.empty(n), np.empty(n, dtype=np.bool_)
        weight, emission = np.empty((n, 3)), np.empty((n, 3))
        tables = self._call_tables()
        track_many(tables, origins, dirs, t_min, t_max, keys, 0, mode, throughput, t_out, scattered, weight,
                   emission)
        ended = self.check_flags(tables)
        if ended:
            warnings.warn(self.budget_message(ended), RuntimeWarning)
        return FreeFlight(t_out, scattered, weight, emission)

    def sample_free_flight(self, origins, dirs, t_max, rng: np.random.Generator, throughput=None,
                           t_min=0.0, camera: bool = False) -> FreeFlight:
        """Delta tracking with null collisions along N rays on [t_min, t_max]
        (grid_kernels.grid_free_flight per ray).

        origins, dirs: (N,3) world space, dirs unit length; t_max: (N,) or scalar (may be inf).
        throughput: optional (N,3) current path throughput, for the channel pdf of the
            scatter-vs-null decision (Cycles: volume_sample_channel_pdf of albedo x throughput).
        rng: numpy Generator (one key per ray is drawn from it); results are reproducible for a
            given generator state and batch.
        camera: the rays leave the camera (grid_kernels.CAMERA_COLLISION_BOOST).
        """
        return self._run_tracking(origins, dirs, t_min, t_max, rng, 3 if camera else 0, throughput)

    def transmittance(self, origins, dirs, t_max, rng: np.random.Generator, t_min=0.0,
                      residual: bool = True) -> np.ndarray:
        """(N,3) unbiased estimate of the transmittance along [t_min, t_max].

        residual=True (default, grid_kernels.grid_transmittance): residual ratio tracking (Novak et
        al. 2014) with a per-cell control extinction (the middle of the cell's range): T =
        exp(-control depth) x prod(1 - (sigma_t - control) / rate), rate = the cell's largest half
        width; fewer lookups and lower variance where the density is smooth, exact where it is
        constant; factors in [0, 2]. residual=False: plain ratio tracking against the majorant,
        prod(1 - sigma_t / majorant) (Cycles' null_event_coefficients), factors in [0, 1]. Shadow
        rays stop when all channels reach 0."""
        return self._run_tracking(origins, dirs, t_min, t_max, rng, 1 if residual else 2).weight

    def optical_depth(self, origins, dirs, t_max, steps: int = 1024, t_min=0.0) -> np.ndarray:
        """(N,3) deterministic midpoint-rule optical depth over the part of [t_min, t_max] inside the
        grid's box (a reference for tests and debugging)."""
        origins, dirs = _points(origins), _points(dirs)
        n = len(origins)
        lo, hi = np.empty(n), np.empty(n)
        box_interval_many(self.tables, origins, dirs,
                          np.ascontiguousarray(np.broadcast_to(np.asarray(t_min, dtype=np.float64), (n,))),
                          np.ascontiguousarray(np.broadcast_to(np.asarray(t_max, dtype=np.float64), (n,))), lo, hi)
        tau = np.zeros((n, 3))
        for k in range(steps):
            t = lo + (hi - lo) * (k + 0.5) / steps
            _, sigma_t, _ = self.coefficients(origins + dirs * t[:, None])
            tau += sigma_t * ((hi - lo) / steps)[:, None]
        return tau


def _points(a) -> np.ndarray:
    """(N,3) C-contiguous float64 rows, the layout the kernel loops take."""
    return np.ascontiguousarray(np.asarray(a, dtype=np.float64).reshape(-1, 3))
