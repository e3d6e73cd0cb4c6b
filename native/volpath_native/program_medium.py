"""Media whose coefficients come from a shader program: procedural density, colour and emission.

A ProgramMedium is what a volume material whose nodes vary over space becomes (a Principled Volume
whose Density is a Noise Texture through a Color Ramp, a height fog from Texture Coordinate ->
Separate XYZ -> Map Range, ...). Cycles 5.0 evaluates such a shader at every tentative collision of
its null-scattering tracker and every shadow-ray step (kernel/integrator/shade_volume.h,
volume_shader_sample); so does VolPath: the grid trackers of grid_kernels run unchanged, and
grid_coefficients runs the program (shading/interpreter.py) instead of reading voxels.

The medium's box is the bounding box of its object (object space, mapped to the world by the
object's transform), as Cycles bounds a volume by its mesh; the path's volume stack confines it to
the mesh itself. The majorant grid over the box is *sampled* (as Cycles' octree is: C5
src/scene/volume.cpp, VolumeManager::build_octree evaluates 16 points per cell of a 128^3 grid):
each cell's bound is the largest extinction found at stratified points of the cell and its
neighbours (a one-cell dilation), times MAJORANT_MARGIN, and at least MAJORANT_FLOOR of the medium's
largest value (in an emissive medium, at least EMISSION_FLOOR of its largest emission: collisions
estimate the glow). Where the true extinction still exceeds it, the trackers use signed null-collision
and ratio-tracking weights (grid_kernels: weighted delta tracking, Kutz et al. 2017), so the image
stays unbiased -- only noisier; such events are counted and reported (Cycles instead raises the
majorant locally and notes that this is "not really unbiased", shade_volume.h).
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .grid_kernels import FLAG_MAJORANT, FLAG_RESIDUAL, N_FLAGS, TRACKING_BUDGET
from .grid_medium import GridMedium
from .jit import stage_kernel
from .sampling import seed_key, uniform1
from .scene import SceneError
from .shading.images import empty_image_table
from .shading.extinction_slice import extinction_program
from .shading.interpreter import closure_coefficients, run_program, run_program_many
from .shading.program import LOBE_STRIDE, MAX_LOBES, R_EMISSION, R_LOBES, ShaderProgram

#: majorant cells along each axis of the box of a medium without emission: finer cells bound its
#: extinction more tightly (fewer null collisions) and the next event's distance and residual
#: tracking's control follow it more closely. Measured (tests/benchmarks/bench_majorant_resolution.py,
#: 128 spp x 6 seeds), error per sample 24^3 / 32^3 / 40^3 / 48^3: noise cloud 0.0380 / 0.0375 /
#: 0.0348 / 0.0348, height fog 0.156 / - / 0.149 / 0.151, at the same CPU per sample (within the
#: VM's noise; 12^3 and 16^3 worse); equal time, paired: height fog 0.92x, noise cloud ~0.93x its time.
DEFAULT_MAJORANT_RESOLUTION = 40
#: ... of a medium that emits: its collisions estimate the glow, and the tighter bounds of finer
#: cells take fewer of them (procedural fire, error per sample 24^3 / 32^3 / 40^3: 0.157 / 0.167 / 0.171)
EMISSIVE_MAJORANT_RESOLUTION = 24
#: random points of the box where the program runs to tell whether the medium emits, and whether
#: its reduced program's extinction agrees with the full one's
PROBE_POINTS = 4096
#: stratified samples along each axis of a cell when building the majorant
SAMPLES_PER_CELL_AXIS = 4
#: safety factor on the sampled maximum
MAJORANT_MARGIN = 1.25
#: every cell's majorant is at least this fraction of the medium's largest sampled extinction,
#: so features the sampling missed are still reached by collisions (unbiased, see the docstring)
MAJORANT_FLOOR = 1e-3
#: ... and at least this fraction of its largest sampled emission: the collisions estimate the
#: emission (E / majorant at each), whose relative variance along a ray falls as 1 / its expected
#: collisions, so faint glow needs some. Measured on the procedural fire (128 spp x 4 seeds, one
#: thread): error x time 0.73 (1e-3, the extinction floor alone) -> 0.61 (3e-2), 0.76 (0.1);
#: media without emission are unchanged.
EMISSION_FLOOR = 3e-2
#: residual ratio tracking (shadow rays): the control is the middle of the cell's sampled range
#: per channel, the rate its largest half width x this margin. A larger rate takes more lookups
#: but lowers the variance (exponent: integral of (sigma_t - control)^2 / rate); measured on the
#: noise cloud and height fog (tests/benchmarks), relvar x time fell up to a margin of ~4-6.
RESIDUAL_MARGIN = 4.0
#: an axis of the majorant grid along which every cell's sampled bounds stay within this fraction of
#: their own value becomes one cell (_collapse_flat_axes)
FLAT_AXIS_TOLERANCE = 0.1
#: ... ranges taken over the cell and its neighbours (True) or the cell alone: measured, the
#: neighbourhood's middle is a worse control (5-20x the variance on the noise cloud)
RESIDUAL_DILATION = False
#: how often a lookup through the reduced program (extinction_slice) also runs the full one, whose
#: extinction it then adds as a roulette correction (grid_kernels.program_extinction)
CORRECTION_PROBABILITY = 0.125


@stage_kernel
def _cell_extrema(code, init, tables, regs, frame, attributes, world_to_index, index_to_world, cells, n_axis,
                  key, max_extinction, max_emission, mean_emission, low_rgb, high_rgb, bad, images, i_start, i_end,
                  first_draw):
    """Per majorant cell of the slab i_start <= i < i_end: the largest max-channel sigma_t and
    |emission|, the mean max-channel |emission|, and each channel's smallest and largest sigma_t (low_rgb, high_rgb) over n_axis^3
    stratified jittered points (index space cell i spans [i, i + 1] x cell size), their jitter from
    draw first_draw on (_slab_first_draw); bad[0] counts evaluations with non-finite or negative
    coefficients before sanitising."""
    ry, rz = max_extinction.shape[1], max_extinction.shape[2]
    dimension = np.uint64(first_draw)
    for i in range(i_start, i_end):
        for j in range(ry):
            for k in range(rz):
                best_t = 0.0
                best_e = 0.0
                sum_e = 0.0
                lo0 = lo1 = lo2 = np.inf
                hi0 = hi1 = hi2 = 0.0
                for a in range(n_axis):
                    for b in range(n_axis):
                        for c in range(n_axis):
                            u0 = uniform1(key, dimension)
                            u1 = uniform1(key, dimension + np.uint64(1))
                            u2 = uniform1(key, dimension + np.uint64(2))
                            dimension += np.uint64(3)
                            x = (i + (a + u0) / n_axis) * cells[0]
                            y = (j + (b + u1) / n_axis) * cells[1]
                            z = (k + (c + u2) / n_axis) * cells[2]
                            m = index_to_world
                            px = m[0, 0] * x + m[0, 1] * y + m[0, 2] * z + m[0, 3]
                            py = m[1, 0] * x + m[1, 1] * y + m[1, 2] * z + m[1, 3]
                            pz = m[2, 0] * x + m[2, 1] * y + m[2, 2] * z + m[2, 3]
                            run_program(code, init, tables, regs, frame, attributes, world_to_index, px, py, pz,
                                        images)
                            for q in range(MAX_LOBES):
                                base = R_LOBES + q * LOBE_STRIDE
                                for ch in range(3):
                                    v = regs[base + ch]
                                    if not v >= 0.0:
                                        bad[0] += 1
                            c9 = closure_coefficients(regs)
                            best_t = max(best_t, max(c9[3], max(c9[4], c9[5])))
                            e = max(abs(c9[6]), max(abs(c9[7]), abs(c9[8])))
                            best_e = max(best_e, e)
                            sum_e += e
                            lo0, lo1, lo2 = min(lo0, c9[3]), min(lo1, c9[4]), min(lo2, c9[5])
                            hi0, hi1, hi2 = max(hi0, c9[3]), max(hi1, c9[4]), max(hi2, c9[5])
                max_extinction[i, j, k] = best_t
                max_emission[i, j, k] = best_e
                mean_emission[i, j, k] = sum_e / (n_axis * n_axis * n_axis)
                low_rgb[i, j, k, 0], low_rgb[i, j, k, 1], low_rgb[i, j, k, 2] = lo0, lo1, lo2
                high_rgb[i, j, k, 0], high_rgb[i, j, k, 1], high_rgb[i, j, k, 2] = hi0, hi1, hi2


def _slab_first_draw(i_start: int, shape, n_axis: int) -> int:
    """The first random draw of the slab of cells from x = i_start: where one walk over every cell
    in order would be there (3 draws per point), so slabs run in parallel give the same bounds."""
    return int(i_start) * int(shape[1]) * int(shape[2]) * n_axis ** 3 * 3


def _neighbourhood(grid, reduce):
    """reduce over each cell and its 26 neighbours (a separable 3x3x3 filter on the first 3 axes)."""
    out = grid
    for axis in range(3):
        n = grid.shape[axis]
        padded = np.pad(out, [(1, 1) if a == axis else (0, 0) for a in range(grid.ndim)], mode="edge")
        out = reduce(reduce(np.take(padded, range(0, n), axis=axis), np.take(padded, range(1, n + 1), axis=axis)),
                     np.take(padded, range(2, n + 2), axis=axis))
    return out


def _collapse_flat_axes(max_extinction, max_emission, low_rgb, high_rgb, mean_emission):
    """Merge the majorant cells along each axis where the sampled bounds hardly change along it (a
    height fog varies only in z): every walk of the grid (free flight, shadow transmittance, the
    next-event distance) steps through fewer cells. An axis merges when no cell's bounds (largest
    extinction and emission, each channel's extinction range) move by more than
    FLAT_AXIS_TOLERANCE x the cell's own largest value (at least MAJORANT_FLOOR of the medium's).
    The mean emission follows (averaged along a merged axis) without a say."""
    arrays = [(max_extinction, np.max), (max_emission, np.max), (low_rgb, np.min), (high_rgb, np.max),
              (mean_emission, np.mean)]
    for axis in range(3):
        if max_extinction.shape[axis] == 1:
            continue
        scale = np.maximum(arrays[0][0], arrays[1][0])
        scale = np.maximum(scale, MAJORANT_FLOOR * max(float(scale.max()), 1e-300))
        merged = [reduce(a, axis=axis, keepdims=True) for a, reduce in arrays]
        flat = all(np.all(np.abs(m - a) <= FLAT_AXIS_TOLERANCE * (scale if a.ndim == 3 else scale[..., None]))
                   for m, (a, _) in zip(merged[:4], arrays[:4]))
        if flat:
            arrays = [(np.ascontiguousarray(m), reduce) for m, (_, reduce) in zip(merged, arrays)]
    return tuple(a for a, _ in arrays)


class ProgramMedium(GridMedium):
    """A medium inside an object's bounding box whose sigma_s, sigma_a and emission are a shader
    program's volume closures at each point.

    program: shading.ShaderProgram (volume closures; program.varying should be True, else a
        homogeneous Medium does the same for less).
    object_to_world: 4x4 of the object the material is on (Texture Coordinate > Object).
    bounds: (lo, hi) object-space box of the object's geometry; the medium is evaluated inside it.
    object_to_generated: 3x4 affine map to Generated texture coordinates (mesh texture space
        (P - L) / 2S + 0.5; identity for Cycles 5.0's Volume geometry).
    g: Henyey-Greenstein anisotropy of its scattering (constant over the medium).
    attributes: optional (nx, ny, nz, c) float32 grid attributes in the box's index space
        (index i of n_voxels spans the box evenly), channels in program.attributes order.
    """

    def __init__(self, name: str, program: ShaderProgram, object_to_world, bounds, object_to_generated=None,
                 *, g: float = 0.0, attributes=None, majorant_resolution: int | None = None,
                 grid_index_to_world=None, debug: bool = False):
        self.name = name
        self.program = program
        program.validate()
        self.g = float(np.clip(np.nan_to_num(float(g)), -0.999, 0.999))
        self.debug = bool(debug)
        self.object_to_world = np.asarray(object_to_world, dtype=np.float64).reshape(4, 4)
        if not np.all(np.isfinite(self.object_to_world)) or abs(np.linalg.det(self.object_to_world[:3, :3])) < 1e-30:
            raise SceneError(f"program medium '{name}': object transform is singular or not finite")
        lo, hi = (np.asarray(b, dtype=np.float64).reshape(3) for b in bounds)
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(hi >= lo)):
            raise SceneError(f"program medium '{name}': bounds {lo.tolist()} .. {hi.tolist()} are not a box")
        # A flat object still gets a thin box (its rays cross it in no time).
        self.object_bounds = (lo, hi)
        pad = np.maximum((hi - lo) * 1e-4, 1e-6)
        self.bounds = (lo - pad, hi + pad)
        auto_resolution = majorant_resolution is None
        resolution = max(int(DEFAULT_MAJORANT_RESOLUTION if auto_resolution else majorant_resolution), 1)
        n_channels = sum(width for _, width in program.attributes)
        self.grid_index_to_world = None
        if grid_index_to_world is not None:
            # A Volume object: the box is its grids' padded index box [0, n - 1] (attributes are
            # given padded, one zero voxel below and two above, as GridMedium pads its grids).
            self.grid_index_to_world = np.asarray(grid_index_to_world, dtype=np.float64).reshape(4, 4)
            self.index_to_world = self.grid_index_to_world
            self.shape = np.array(np.asarray(attributes).shape[:3], dtype=np.int64)
            self.source_index_to_world = self.index_to_world
            self.world_to_index = np.linalg.inv(self.index_to_world)
        else:
            self._box_index_space(resolution)
        self.density = np.zeros((2, 2, 2), np.float32)  # unused: the program gives the coefficients
        self.scatter_grid = self.absorb_grid = self.emission_grid = None
        self.sigma_s = self.sigma_a = self.emission = np.zeros(3)
        world_to_object = np.linalg.inv(self.object_to_world)[:3]
        generated = np.eye(4)[:3] if object_to_generated is None else np.asarray(object_to_generated, np.float64)
        self.frame = np.ascontiguousarray(np.stack([world_to_object, generated.reshape(3, 4)]), dtype=np.float64)
        if attributes is None:
            attributes = np.zeros((1, 1, 1, max(n_channels, 1)), np.float32)
        self.attributes = np.ascontiguousarray(attributes, dtype=np.float32)
        if self.attributes.ndim != 4 or self.attributes.shape[3] < n_channels:
            raise SceneError(f"program medium '{name}': attributes must be (nx, ny, nz, {n_channels}), "
                             f"got {self.attributes.shape}")
        # lookups that need sigma_t and emission only run a copy without the Principled Volume's
        # colour nodes (extinction_slice), where the sampled points find both programs' extinction equal
        self.extinction = extinction_program(program)
        self.correction_probability = CORRECTION_PROBABILITY
        self._registers = np.zeros(program.n_registers + 3)
        self.images = empty_image_table()  # image textures inside volumes: not yet bound
        self._flags = np.zeros(N_FLAGS, dtype=np.int64)
        self.lookups = np.zeros(3, dtype=np.int64)
        self._violation = np.zeros((2, 5))
        self._stop = np.zeros(1, dtype=np.int64)
        self.invalid_evaluations = 0
        self.violation_count = 0  # tentative collisions above the sampled majorant (check_flags)
        self.residual_violation_count = 0  # shadow-ray lookups with |sigma_t - control| above the rate
        # whether the program glows: the majorant grid's resolution, and no camera collision boost
        # (grid_kernels.CAMERA_COLLISION_BOOST: collisions would cut the camera ray's glow short)
        self.emits = self._emits()
        if auto_resolution and self.emits:
            resolution = EMISSIVE_MAJORANT_RESOLUTION
            if self.grid_index_to_world is None:
                self._box_index_space(resolution)
        self.majorant_resolution = resolution
        self._build_majorant_grid(resolution)
        if self.extinction is not None and not self._extinction_agrees():
            self.extinction = None

    # ------------------------------------------------------------------------------------------
    def _box_index_space(self, resolution: int):
        """Index space [0, R] per axis spanning the object's box (a mesh-bounded medium)."""
        box_to_object = np.eye(4)
        box_to_object[:3, :3] = np.diag((self.bounds[1] - self.bounds[0]) / resolution)
        box_to_object[:3, 3] = self.bounds[0]
        self.index_to_world = self.object_to_world @ box_to_object
        self.shape = np.full(3, resolution + 1, dtype=np.int64)
        self.source_index_to_world = self.index_to_world
        self.world_to_index = np.linalg.inv(self.index_to_world)

    def _probe_points(self) -> np.ndarray:
        """PROBE_POINTS random world points of the medium's box (the same ones every time): the
        object's box, or a Volume object's grid index box."""
        rng = np.random.default_rng(0x5EED)
        if self.grid_index_to_world is not None:
            m = self.index_to_world
            index = (self.shape - 1) * rng.random((PROBE_POINTS, 3))
            return np.ascontiguousarray(index @ m[:3, :3].T + m[:3, 3])
        lo, hi = self.object_bounds
        local = lo + (hi - lo) * rng.random((PROBE_POINTS, 3))
        return np.ascontiguousarray(local @ self.object_to_world[:3, :3].T + self.object_to_world[:3, 3])

    def _emits(self) -> bool:
        """Whether the full program gives emission at any probe point (picks the majorant grid's
        resolution; a glow the probe misses is still rendered, on the finer grid)."""
        p = self.program
        emission = np.zeros((PROBE_POINTS, 3))
        run_program_many(p.code, p.init, p.tables, np.zeros_like(self._registers), self.frame, self.attributes,
                         np.ascontiguousarray(self.world_to_index[:3]), self._probe_points(), emission, R_EMISSION, 3,
                         self.images)
        return bool(np.any(np.nan_to_num(np.abs(emission)) > 0.0))

    def _program_tables(self) -> dict:
        p = self.program
        reduced = self.extinction
        return dict(has_program=True, program_code=p.code, program_init=p.init, program_tables=p.tables,
                    registers=self._registers, frame=self.frame, attributes=self.attributes,
                    images=self.images, has_extinction_program=reduced is not None,
                    extinction_code=reduced.code if reduced is not None else np.zeros(1, np.int32),
                    extinction_init=reduced.init if reduced is not None else np.zeros(1),
                    correction_probability=self.correction_probability, camera_boost=not self.emits)

    def _build_majorant_grid(self, resolution: int):
        """Sampled per-cell maxima, dilated by one cell, with a margin and a floor (module docstring);
        the control extinction and residual rate of residual ratio tracking from the sampled ranges."""
        extent = self.shape - 1
        shape = tuple(int(v) for v in np.minimum(resolution, np.maximum(extent, 1)))
        cells = extent / np.array(shape, dtype=np.float64)  # index units per majorant cell
        max_extinction, max_emission, mean_emission = np.zeros(shape), np.zeros(shape), np.zeros(shape)
        low_rgb, high_rgb = np.zeros(shape + (3,)), np.zeros(shape + (3,))
        p = self.program
        world_to_index = np.ascontiguousarray(self.world_to_index[:3])
        index_to_world = np.ascontiguousarray(self.index_to_world[:3])
        # slabs of cells along x on every core (the kernel releases the GIL): the same bounds as one
        # serial walk, bit for bit, in a fraction of the first render's wait
        slabs = np.linspace(0, shape[0], min(os.cpu_count() or 1, shape[0]) + 1).astype(np.int64)
        bad = np.zeros((len(slabs) - 1, 1), np.int64)

        def sample_slab(n):
            _cell_extrema(p.code, p.init, p.tables, np.zeros_like(self._registers), self.frame, self.attributes,
                          world_to_index, index_to_world, cells, SAMPLES_PER_CELL_AXIS, seed_key(0x5EED),
                          max_extinction, max_emission, mean_emission, low_rgb, high_rgb, bad[n], self.images, slabs[n],
                          slabs[n + 1], _slab_first_draw(slabs[n], shape, SAMPLES_PER_CELL_AXIS))

        with ThreadPoolExecutor(max_workers=len(slabs) - 1) as pool:
            list(pool.map(sample_slab, range(len(slabs) - 1)))
        self.invalid_evaluations = int(bad.sum())
        max_extinction, max_emission, low_rgb, high_rgb, mean_emission = _collapse_flat_axes(
            max_extinction, max_emission, low_rgb, high_rgb, mean_emission)
        shape = max_extinction.shape
        cells = extent / np.array(shape, dtype=np.float64)
        dilated = _neighbourhood(max_extinction, np.maximum)
        peak = float(dilated.max())
        # The larger of extinction and emission, as GridMedium._build_majorant_grid (Cycles' rule;
        # on the procedural fire 0.5x or 2x the emission lost 20 % or 5 % in error x time).
        glow = _neighbourhood(max_emission, np.maximum)
        peak_any = max(peak, float(glow.max()))
        floor = max(MAJORANT_FLOOR * peak_any, EMISSION_FLOOR * float(glow.max()))
        majorant = np.maximum(np.maximum(dilated, glow) * MAJORANT_MARGIN, floor)
        # the sampled mean per cell: emissive_media draws points in proportion to it (where the
        # dilated bound above was ~4x the emission at points drawn by it on the procedural fire,
        # this follows it)
        self.emission_weight = mean_emission
        self.majorant_shape = np.array(shape, dtype=np.int64)
        self.cell_size = cells
        self.majorant_grid = majorant.astype(np.float64)
        self.majorant_density = self.majorant_grid
        self.majorant_rgb = np.repeat(self.majorant_grid[..., None], 3, axis=-1)
        self.minorant_rgb = low_rgb
        # the sampled extinction range per cell, without margin (telescoping_transmittance's segments)
        self.extinction_extrema = np.stack([low_rgb.min(axis=-1), high_rgb.max(axis=-1)], axis=-1)
        # The control and residual rate are sampled too: where sigma_t leaves control +- rate the
        # ratio factors of residual tracking leave [0, 2] (signed), which keeps it unbiased.
        if RESIDUAL_DILATION:
            low_rgb, high_rgb = _neighbourhood(low_rgb, np.minimum), _neighbourhood(high_rgb, np.maximum)
        half_width = 0.5 * (high_rgb - low_rgb).max(axis=-1)
        self._set_residual(0.5 * (low_rgb + high_rgb), np.maximum(half_width * RESIDUAL_MARGIN, MAJORANT_FLOOR * peak))

    def _extinction_agrees(self) -> bool:
        """Whether the reduced program's extinction equals the full one's at the PROBE_POINTS
        random points of the box (it differs where a Color exceeds 1: the roulette's correction
        would then add variance at every lookup, so the medium keeps the full program). Either
        way the estimate is unbiased: this only chooses the cheaper one."""
        points = self._probe_points()
        full = self.coefficients(points)[1]
        reduced = self.coefficients(points, self.tables._replace(program_code=self.extinction.code,
                                                                 program_init=self.extinction.init))[1]
        scale = max(float(np.abs(full).max()), 1e-300)
        return bool(np.all(np.abs(full - reduced) <= 1e-9 * scale))

    def check_flags(self, tables) -> int:
        """As GridMedium.check_flags, but majorant and residual-rate violations are expected (the
        bounds are sampled) and only counted; the tracking stays unbiased."""
        self.violation_count += int(tables.flags[FLAG_MAJORANT])
        self.residual_violation_count += int(tables.flags[FLAG_RESIDUAL])
        tables.flags[FLAG_MAJORANT] = tables.flags[FLAG_RESIDUAL] = 0
        return super().check_flags(tables)

    def warnings(self) -> list:
        messages = []
        if self.invalid_evaluations:
            messages.append(f"volume '{self.name}': its shader gave negative or non-finite scattering at "
                            f"{self.invalid_evaluations} of the points sampled for its majorant; read as 0")
        return messages

    def budget_message(self, count: int) -> str:
        return (f"volume '{self.name}': {count} rays would have needed more than {TRACKING_BUDGET} "
                "collisions through its procedural density and were treated as opaque")

    def set_motion(self, transforms, object_to_world=None):
        """GridMedium.set_motion; the reference defaults to the medium's object transform."""
        super().set_motion(transforms, self.object_to_world if object_to_world is None else object_to_world)

    def boundary_mesh(self, material_id: int):
        """Volume objects: the box of their grids, as GridMedium; meshes bound their own medium."""
        if self.grid_index_to_world is None:
            raise SceneError(f"program medium '{self.name}' is bounded by its own mesh")
        return super().boundary_mesh(material_id)

    def box_mesh(self, material_id: int):
        """The closed box mesh around the medium's box (a world volume's bounds)."""
        return super().boundary_mesh(material_id)

    def to_record(self):
        p = self.program
        header = {"type": "program", "name": self.name, "g": self.g, "object_to_world": self.object_to_world.tolist(),
                  "bounds": [self.object_bounds[0].tolist(), self.object_bounds[1].tolist()],
                  "object_to_generated": self.frame[1].tolist(), "majorant_resolution": self.majorant_resolution,
                  "program_name": p.name, "program_varying": bool(p.varying),
                  "program_attributes": [[n, int(w)] for n, w in p.attributes]}
        if self.grid_index_to_world is not None:
            header["grid_index_to_world"] = self.grid_index_to_world.tolist()
        arrays = {"program_code": p.code, "program_init": p.init, "program_tables": p.tables,
                  "attributes": self.attributes}
        self._motion_record(header, arrays)
        return header, arrays

    @classmethod
    def from_record(cls, header: dict, arrays: dict, debug: bool = False) -> "ProgramMedium":
        program = ShaderProgram(header.get("program_name", header["name"]), arrays["program_code"],
                                arrays["program_init"], arrays["program_tables"],
                                varying=bool(header.get("program_varying", True)),
                                attributes=[(str(n), int(w)) for n, w in header.get("program_attributes", [])])
        try:
            program.validate()
        except ValueError as error:
            raise SceneError(str(error))
        lo, hi = header["bounds"]
        medium = cls(header["name"], program, np.asarray(header["object_to_world"]), (lo, hi),
                     np.asarray(header["object_to_generated"]), g=header.get("g", 0.0),
                     attributes=arrays.get("attributes"), majorant_resolution=header.get("majorant_resolution"),
                     grid_index_to_world=header.get("grid_index_to_world"), debug=debug)
        medium._load_motion(header, arrays)
        return medium
