"""The wavefront volumetric path tracer.

Each iteration runs the stages of pbrt-v4's wavefront integrator (src/pbrt/wavefront/
integrator.cpp) over the whole batch of live paths: closest hit (Embree, in bulk) -> the path
stage (medium segment with emission, next-event estimation and free flight; lamps crossed;
escaped rays; volume scattering or surface interaction), which queues shadow rays -> shadow rays
(Embree, in bulk, stepping through null boundaries) -> compaction. The stages are compiled
(path_kernels.py, numba) and a batch runs them all in one compiled call (wavefront.py); this
module owns the scene tables, the buffers and the camera rays of a batch, and keeps the same loop
stage by stage from Python for profiling. The estimators and their references are listed in
path_kernels.py.
"""
from __future__ import annotations

import mmap
import threading

import numpy as np

from . import path_kernels as pk
from . import wavefront
from .accel import ALL_MASK, MASK_OPAQUE, MASK_SEE_THROUGH, Accelerator
from .bsdfs import bsdf_tables
from .bsdfs.closures import new_closure_buffer
from .bsdfs.nodes import surface_node_table
from .camera import CameraModel, crop_window
from .film import PixelFilter
from .emissive_media import emissive_media, no_emissive_media
from .glow_guide import glow_table
from .grid_medium import GridMedium
from .grid_slots import GRID_SLOTS  # the grid tuple is padded to this many (grid_slots.py)
from .lights import LightSet
from .media import MediaTable
from .sampling import seed_key
from .scene import Scene
from .shading.images import empty_image_table, image_table
from .surface_programs import new_surface_scratch, surface_program_tables


class Cancelled(Exception):
    pass


def scene_tables(scene: Scene, accel: Accelerator, media: MediaTable) -> pk.SceneTables:
    """Flat arrays of everything the compiled stages read about the scene (no emissive media
    sampled: Integrator sets its emissive_media table)."""
    st = scene.settings
    mats = scene.materials
    ids = accel.material_ids
    mat_null = np.array([m.surface == "null" for m in mats], dtype=bool)
    mat_transparent = np.array([_may_pass_shadows(m) for m in mats], dtype=bool)
    mat_emissive = np.array([m.is_emissive and m.surface != "null" for m in mats], dtype=bool)
    n_tri = accel.triangle_count
    has_tris = bool(len(mats)) and n_tri > 0
    n_vol = max(media.n_volumes, 1)

    def per_volume(a, shape):
        out = np.zeros(shape)
        out[:media.n_volumes] = a[:media.n_volumes]
        return out
    k = max(len(media.phase_g_values), 1)
    phase_g = np.zeros(k)
    phase_g[:len(media.phase_g_values)] = media.phase_g_values
    lobe_sigma = np.zeros((n_vol, k, 3))
    world_lobe = np.zeros((k, 3))
    if len(media.phase_g_values):
        lobe_sigma[:] = media._volume_lobe_sigma.reshape(n_vol, k, 3)
        world_lobe[:] = media._world_lobe_sigma
    is_grid = np.zeros(n_vol, bool)
    is_grid[:media.n_volumes] = media.volume_is_grid
    vol_grid = np.full(n_vol, -1, np.int64)
    for index, (v, _) in enumerate(media.grid_volumes):
        vol_grid[v] = index
    return pk.SceneTables(
        tri_null=np.ascontiguousarray(mat_null[ids] if has_tris else np.zeros(n_tri, bool)),
        tri_emissive=np.ascontiguousarray(mat_emissive[ids] if has_tris else np.zeros(n_tri, bool)),
        tri_material=np.ascontiguousarray(ids if has_tris else np.zeros(n_tri), dtype=np.int32),
        tri_transparent=np.ascontiguousarray(mat_transparent[ids] if has_tris else np.zeros(n_tri, bool)),
        normals=np.ascontiguousarray(accel.normals, dtype=np.float64),
        corner_normals=np.ascontiguousarray(accel.corner_normals if accel.has_smooth else np.zeros((0, 3, 3)),
                                            dtype=np.float32),
        has_smooth=bool(accel.has_smooth),
        inst_normal=np.ascontiguousarray(accel.instance_normals, dtype=np.float64),
        inst_frame_base=int(accel.instance_frame_base),
        inst_steps=np.ascontiguousarray(accel.instance_steps, dtype=np.int64),
        inst_motion=np.ascontiguousarray(accel.instance_motion, dtype=np.float64), has_motion=bool(accel.has_motion),
        has_deformation=bool(accel.has_deformation), deform_rows=accel.deform_rows,
        deform_corners=accel.deform_corners, deform_normals=accel.deform_normals,
        tri_volume=np.ascontiguousarray(media.tri_volume, dtype=np.int32),
        vol_sigma_s=per_volume(media.sigma_s, (n_vol, 3)), vol_sigma_a=per_volume(media.sigma_a, (n_vol, 3)),
        vol_emission=per_volume(media.emission, (n_vol, 3)), vol_g=per_volume(media.g, n_vol),
        vol_is_grid=is_grid, vol_grid=vol_grid, has_grids=bool(media.has_grids),
        world_sigma_s=np.asarray(media.world_sigma_s, np.float64), world_sigma_a=np.asarray(media.world_sigma_a, np.float64),
        world_emission=np.asarray(media.world_emission, np.float64), world_g=float(media.world_g),
        phase_g=phase_g, vol_lobe_sigma=lobe_sigma, world_lobe_sigma=world_lobe,
        mixed_phase=bool(media.mixed_phase), epsilon=float(accel.epsilon), any_medium=bool(media.any_medium),
        max_bounces=int(st.max_bounces), diffuse_bounces=int(st.diffuse_bounces),
        volume_bounces=int(st.volume_bounces), glossy_bounces=int(st.glossy_bounces),
        transmission_bounces=int(st.transmission_bounces), transparent_bounces=int(st.transparent_bounces),
        rr_min_bounces=int(st.russian_roulette_min_bounces),
        volume_sampling=pk.VOLUME_SAMPLING[st.volume_sampling], grid_equiangular_share=float(pk.GRID_EQUIANGULAR_SHARE),
        glow=glow_table(scene.lights, media), emitters=no_emissive_media())


def _may_pass_shadows(material) -> bool:
    """Whether shadow rays may pass the material's surface (Transparent BSDF, Principled alpha < 1:
    Cycles' closure_transparent_extinction); glass does not (Cycles 5.0). A surface program that
    drives an alpha or a mix weight may make any hit transparent."""
    nodes = material.bsdf_nodes()
    program = getattr(material, "surface_program", None)
    if program is not None and any(field in ("alpha", "weight") for _, field in program.drives(nodes)) \
            and any(node.kind in ("transparent", "principled") for node in nodes):
        return True
    return any(node.weight > 0 and (node.kind == "transparent" or (node.kind == "principled" and node.alpha < 1))
               for node in nodes)


class Integrator:
    """Everything prepared once per scene; render_paths() may run in several threads."""

    def __init__(self, scene: Scene):
        self.scene = scene
        self.settings = scene.settings
        film = scene.film
        self.accel = Accelerator(scene.meshes, scene.materials,
                                 camera_samples=int(film.width) * int(film.height) * max(int(scene.settings.samples), 1),
                                 see_through=np.array([m.surface == "null" or _may_pass_shadows(m)
                                                       for m in scene.materials], bool))
        self.lights = LightSet(scene, self.accel)
        self.media = MediaTable(scene, self.accel)
        self.camera = CameraModel(scene.camera, scene.film)
        self.filter = PixelFilter(scene.film)
        self.crop = crop_window(scene.film)
        self.tables = scene_tables(scene, self.accel, self.media)
        # emissive grid media sampled as lights from surface vertices, and each one's point density
        # per majorant cell for the grid tables (render_paths)
        self.emitters, self._emission_density = emissive_media(self.media, self.accel,
                                                               bool(self.tables.tri_transparent.any()))
        self.tables = self.tables._replace(emitters=self.emitters)
        self.surface_nodes = surface_node_table([m.bsdf_nodes() for m in scene.materials])
        self.images = image_table(scene.images)  # one copy of every image, however many nodes read it
        self.surface_programs = surface_program_tables(scene.materials, self.accel, self.images)
        self.bsdf_tables = bsdf_tables()
        self.grids = [grid for _, grid in self.media.grid_volumes]
        # shadow rays step through null boundaries and transparent surfaces (closest hits)
        self.has_null = bool(self.tables.tri_null.any() or self.tables.tri_transparent.any())
        self.warnings = self.accel.warnings + self.lights.warnings + self.media.warnings
        # Each path starts in the volume stack of its ray's origin, on the near clip plane (Cycles
        # kernel/integrator/intersect_volume_stack.h integrator_volume_stack_init walks from the
        # camera ray's P, which kernel/camera/camera.h has moved to the near clip). Perspective
        # rays share the camera position's stack unless a volume boundary passes between the
        # camera and the near clip plane (Cycles' is_inside_volume test on the viewplane bounds,
        # scene/camera.cpp device_update_volume); orthographic rays start from different points.
        # A lens, a panoramic camera or camera motion moves the origins too: near_bounds holds them all.
        # Moving volume boundaries: each path's stack at its own shutter time (Cycles walks with
        # the camera ray's time).
        self._stack_per_path = bool(self.media.n_volumes) and (
            scene.camera.projection == "orthographic" or self.media.boundaries_move
            or self.media.boundary_meets_box(*self.camera.near_bounds(self.filter.support + 1.0)))
        self._camera_stack = self.media.empty_stack(1)[0]
        if self.media.n_volumes and not self._stack_per_path:
            self._camera_stack = self.media.stack_at(self.camera.position[None, :])[0]
        self._seed_key = seed_key(self.settings.seed)
        embree = self.accel.embree
        self._ray_queries = wavefront.RayQueries(
            scene=int(embree.handle) if embree is not None else 0, has_scene=embree is not None,
            geom_base=embree.geom_base if embree is not None else np.zeros(1, np.int32),
            inst_base=embree.inst_base if embree is not None else np.zeros(1, np.int32),
            inst_index=embree.inst_index if embree is not None else np.zeros(1, np.int32),
            has_motion=bool(self.accel.has_motion), masked=bool(self.accel.masked))
        self._thread_buffers = threading.local()
        # whether shadow rays ask about opaque geometry first (wavefront.CULL_DECISION_SHADOWS)
        self._cull_state = wavefront.new_cull_state(self.accel.masked)
        # Set by request_stop() to abandon the batches in flight: grid tracking (the only per-path
        # work without a bound in time) polls it. Anonymous shared memory, so forked render
        # workers see the parent's write.
        self._stop = np.frombuffer(mmap.mmap(-1, 8), dtype=np.int64)

    @property
    def culls_opaque_first(self):
        """Whether shadow rays ask about opaque geometry first (wavefront.CULL_DECISION_SHADOWS):
        True, False, or None while undecided."""
        decided = int(self._cull_state[wavefront.CULL_DECIDED])
        return None if decided == wavefront.CULL_UNDECIDED else bool(decided)

    def set_cull_opaque_first(self, cull):
        """Fix the choice (True / False) or start deciding anew (None); the image is the same."""
        self._cull_state[:] = wavefront.new_cull_state(self.accel.masked)
        if cull is not None:
            self._cull_state[wavefront.CULL_DECIDED] = int(bool(cull) and self.accel.masked)

    def request_stop(self, stop: bool = True):
        """Make render_paths calls in flight (any thread or forked worker) end soon: they raise
        Cancelled if given a cancel callback, else return with the batch's estimates biased."""
        self._stop[0] = 1 if stop else 0

    # -----------------------------------------------------------------------------------------
    def _buffers(self, n: int) -> "_Buffers":
        """This thread's path state and shadow queue for n paths."""
        buffers = getattr(self._thread_buffers, "buffers", None)
        if buffers is None or buffers.capacity < n:
            buffers = self._thread_buffers.buffers = _Buffers(n, len(self._camera_stack))
            buffers.surface = new_surface_scratch(self.scene.materials, self.surface_programs)
        return buffers

    def _start_paths(self, pixel: np.ndarray, sample: np.ndarray, buffers: "_Buffers"):
        """Camera rays of the paths; returns the path state and how many paths live (paths the
        camera has no ray for, outside a fisheye's circle, are compacted away: their pixels get
        nothing from them, as Cycles' zero camera sensitivity)."""
        n = len(pixel)
        F, I, K, C = buffers.F[:n], buffers.I[:n], buffers.K[:n], buffers.C[:n]
        o32, d32, t32 = buffers.o32[:n], buffers.d32[:n], buffers.t32[:n]
        alive = buffers.alive[:n]
        x0, y0, crop_width, _ = self.crop
        unseen = pk.start_paths(self.tables, self.camera.tables, self.filter.inverse, self._seed_key,
                                (x0, y0, crop_width), self.scene.film.width, np.ascontiguousarray(pixel, np.int64),
                                np.ascontiguousarray(sample, np.int64), self._camera_stack, F, I, K, C, o32, d32,
                                t32, alive)
        if self._stack_per_path:
            C[:] = self.media.stack_at(F[:, pk.O:pk.O + 3], F[:, pk.TIME])
            pk.initial_coefficients(self.tables, C, F, n)
        live = pk.compact(F, I, K, C, n, alive, o32, d32, t32) if unseen else n
        return F, I, K, C, o32, d32, t32, live

    def render_paths(self, pixel: np.ndarray, sample: np.ndarray, cancel=None, stepwise: bool = False,
                     reuse_radiance: bool = False):
        """Radiance estimates (N,3) for paths (crop-region pixel index, sample index) and stats:
        counters (rays, shadow_rays, vertices, paths), `dropped` (contributions with a component
        that was not finite or beyond float32's range, zeroed as Cycles does: path_kernels
        _add_radiance) and `budget` (per grid medium, tracking calls the step budget ended).

        The batch is traced by one compiled call (wavefront.trace_batch), which polls the stop
        flag (request_stop; render() sets it on a cancel); cancel() is polled before and after.
        stepwise: run the same stages one call each from Python (the same image, bit for bit;
        slower: for profiling per stage and for tests/benchmarks' query recorder).
        reuse_radiance: the estimates are a view of this thread's buffer, valid until its next call
        (render() adds them to the film at once; a fresh array per batch is a fresh mapping, whose
        page faults and unmapping cost two threads ~5 % on a cheap scene)."""
        n = len(pixel)
        stats = dict(rays=0, shadow_rays=0, vertices=0, paths=n)
        buffers = self._buffers(n)
        F, I, K, C, o32, d32, t32, live = self._start_paths(pixel, sample, buffers)
        if reuse_radiance:
            L = buffers.radiance[:n]
            L[:] = 0.0
        else:
            L = np.zeros((n, 4))  # RGB and the count of dropped contributions
        alive = buffers.alive[:n]
        alive[:] = True
        margin = 2.0 * self.accel.epsilon
        # grid tables with a violation record private to this batch (threads never share it),
        # padded so that scenes with up to GRID_SLOTS grids share one compiled signature
        grid_tables = tuple(self._sampled(slot, grid._call_tables()._replace(stop=self._stop))
                            for slot, grid in enumerate(self.grids))
        grid_tables += (_no_grid_tables(),) * max(GRID_SLOTS - len(grid_tables), 0)
        if cancel is not None and cancel():
            raise Cancelled()
        counts = np.zeros(wavefront.N_COUNTS, np.int64)
        if stepwise:
            self._trace_stepwise(buffers, grid_tables, live, F, I, K, C, o32, d32, t32, L, alive, margin, counts,
                                 cancel)
        else:
            wavefront.trace_batch(self.tables, self.lights.tables, grid_tables, self.surface_nodes, self.bsdf_tables,
                                  buffers.closures, self.surface_programs, buffers.surface, self._ray_queries,
                                  buffers.hits, live, F, I, K, C, o32, d32, t32, alive, L, buffers.queue,
                                  self.has_null, margin, self._stop, counts, self._cull_state)
        stats.update(vertices=int(counts[wavefront.VERTICES]), rays=int(counts[wavefront.RAYS]),
                     shadow_rays=int(counts[wavefront.SHADOW_RAYS]))
        if cancel is not None and cancel():
            raise Cancelled()  # tracking may have been abandoned part-way: discard the batch
        stats["dropped"] = int(L[:, 3].sum())
        stats["budget"] = np.array([grid.check_flags(tables) for grid, tables in zip(self.grids, grid_tables)],
                                   dtype=np.int64)
        return L[:, :3], stats

    def _sampled(self, slot, tables):
        """Grid tables with emissive_media's point density when the medium is sampled as a light."""
        density = self._emission_density.get(slot)
        return tables if density is None else tables._replace(emission_sampled=True, emission_density=density)

    def _trace_stepwise(self, buffers, grid_tables, n, F, I, K, C, o32, d32, t32, L, alive, margin, counts, cancel):
        """wavefront.trace_batch's loop with each stage called from Python (counts: its N_COUNTS)."""
        Q = buffers.queue
        iteration = 0
        while n:
            if cancel is not None and cancel():
                raise Cancelled()
            hits = self.accel.intersect_raw(o32[:n], d32[:n], t32[:n], self._times(F, pk.TIME, n))
            counts[wavefront.RAYS] += n
            m = pk.shade(self.tables, self.lights.tables, grid_tables, self.surface_nodes, self.bsdf_tables,
                         buffers.closures, self.surface_programs, buffers.surface, n, iteration, F, I, K, C, hits.t,
                         hits.prim, hits.inst, hits.u, hits.v, L, alive, Q,
                         counts[wavefront.VERTICES:wavefront.VERTICES + 1], o32, d32, t32)
            self._trace_shadows(grid_tables, buffers, Q, m, margin, L, counts, iteration, cancel)
            n = pk.compact(F, I, K, C, n, alive, o32, d32, t32)
            iteration += 1

    def _times(self, fields: np.ndarray, column: int, n: int):
        """The shutter times of n queued rays for Embree (None when nothing in the scene moves)."""
        return fields[:n, column].astype(np.float32) if self.accel.has_motion else None

    def _trace_shadows(self, grid_tables, buffers, Q, m, margin, L, counts, iteration, cancel=None):
        """Transmittance of queued shadow rays, added to L where the light is reached."""
        if not m:
            return
        if not self.has_null:
            blocked = self.accel.occluded_raw(Q.o32[:m], Q.d32[:m], Q.t32[:m], self._times(Q.F, pk.S_TIME, m))
            counts[wavefront.SHADOW_RAYS] += m
            pk.shadow_unoccluded(Q.F, Q.I, m, blocked, margin, L)
            return
        queued, state = m, self._cull_state
        learning = state[wavefront.CULL_DECIDED] == wavefront.CULL_UNDECIDED
        mask = ALL_MASK
        # opaque first, then only see-through (direct emissive-media samples end at the first)
        if self.accel.masked and (state[wavefront.CULL_DECIDED] == 1 or self.emitters.direct):
            blocked = self.accel.occluded_raw(Q.o32[:m], Q.d32[:m], Q.t32[:m], self._times(Q.F, pk.S_TIME, m),
                                              MASK_OPAQUE)
            counts[wavefront.SHADOW_RAYS] += m
            m = pk.drop_blocked(Q, m, blocked, L)
            mask = MASK_SEE_THROUGH
        for step in range(pk.MAX_VOLUME_BOUNDS):
            if not m:
                break
            if cancel is not None and cancel():
                raise Cancelled()
            hits = self.accel.intersect_raw(Q.o32[:m], Q.d32[:m], Q.t32[:m], self._times(Q.F, pk.S_TIME, m), mask)
            counts[wavefront.SHADOW_RAYS] += m
            m = pk.shadow_step(self.tables, grid_tables, self.surface_nodes, self.bsdf_tables, buffers.closures,
                               self.surface_programs, buffers.surface, Q, m, hits.t, hits.prim, hits.inst, hits.u, hits.v,
                               margin, L, iteration, step,
                               state[wavefront.CULL_BLOCKED_STEPS:wavefront.CULL_BLOCKED_STEPS + 1])
        # rays still crossing boundaries after the limit count as blocked (Cycles VOLUME_BOUNDS_MAX)
        if learning:
            wavefront.learn_cull(state, queued)


class _Buffers:
    """Path state (path_kernels' layout) and shadow queue for up to `capacity` paths, kept per
    thread and reused by its batches: fresh arrays for every batch cost a page fault per 4 KiB
    (the kernel zeroes each new page), several per cent of a render."""

    def __init__(self, capacity: int, volumes: int):
        self.capacity = capacity
        self.F, self.I = np.empty((capacity, pk.NF)), np.empty((capacity, pk.NI), np.int64)
        self.K, self.C = np.empty(capacity, np.uint64), np.empty((capacity, volumes), np.int8)
        self.o32, self.d32 = np.empty((capacity, 3), np.float32), np.empty((capacity, 3), np.float32)
        self.t32 = np.empty(capacity, np.float32)
        self.alive = np.empty(capacity, bool)
        self.radiance = np.empty((capacity, 4))  # render_paths(reuse_radiance=True)
        self.hits = wavefront.new_hit_buffers(3 * capacity)  # Embree's answers, for paths or shadow rays
        self.closures = new_closure_buffer()  # the lobes of the surface being shaded
        # up to three shadow rays per path and iteration (medium NEE + surface NEE + emissive media)
        q = 3 * capacity
        self.queue = pk.ShadowQueue(np.empty((q, pk.NSF)), np.empty((q, pk.NSI), np.int64), np.empty(q, np.uint64),
                                    np.empty((q, volumes), np.int8), np.empty((q, 3), np.float32),
                                    np.empty((q, 3), np.float32), np.empty(q, np.float32))


_NO_GRID_TABLES = None


def _no_grid_tables():
    """Placeholder grid tables that pad the grid tuple (never indexed: no volume maps to them)."""
    global _NO_GRID_TABLES
    if _NO_GRID_TABLES is None:
        _NO_GRID_TABLES = GridMedium("none", np.zeros((2, 2, 2), np.float32), np.eye(4), np.zeros(3),
                                     np.zeros(3)).tables
    return _NO_GRID_TABLES


def warm_up(thorough: bool = False) -> float:
    """Compile every stage kernel (or load them from the on-disk cache) by rendering a tiny scene
    with a medium inside a null boundary; returns the seconds it took. Renders call this
    implicitly; the add-on calls it first so that it can tell the user what the wait is.

    thorough: also render, through render() as the add-on does, the variants that compile other
    kernels or signatures: shadow rays without null boundaries, a heterogeneous grid medium the
    camera sits in (per-path volume stacks), every light type and an orthographic camera. `make
    extension` ships the kernels this compiles (jit.py), so a first render finds them all."""
    import time
    from .grid_medium import GridMedium
    from .render import render
    from .scene import (AreaLight, Camera, Film, Material, Medium, Mesh, PointLight, RenderSettings,
                        SpotLight, SunLight, World)
    from .bsdfs.nodes import SurfaceNode
    start = time.perf_counter()
    corners = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])
    box = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                    [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    floor = Mesh("floor", np.array([[-3, -3, -1.5], [3, -3, -1.5], [3, 3, -1.5], [-3, 3, -1.5]], float),
                 np.array([[0, 1, 2], [0, 2, 3]]), np.zeros(2, int))
    fog = Mesh("fog", corners, box, np.ones(12, int))
    camera = np.eye(4)
    camera[:3, 3] = [0.0, 0.0, 6.0]
    scene = Scene(camera=Camera(camera, fov=0.8), film=Film(4, 4), meshes=[floor, fog],
                  materials=[Material("floor"), Material("fog", surface="null", medium=0)],
                  media=[Medium("fog", sigma_s=0.5, sigma_a=0.1)],
                  lights=[PointLight("lamp", [0.0, 0.0, 2.5], power=100.0)],
                  settings=RenderSettings(samples=1, threads=1))
    Integrator(scene).render_paths(np.arange(16) % 16, np.zeros(16, np.int64))
    from .render import _Film
    # render()'s film sums (a compiled kernel): values as a worker process returns them (contiguous)
    # and as a thread does (the RGB columns of its radiance array)
    _Film(1).add(np.zeros(1, np.int64), np.zeros((1, 3)))
    _Film(1).add(np.zeros(1, np.int64), np.zeros((1, 4))[:, :3])
    if not thorough:
        return time.perf_counter() - start
    lights = [PointLight("lamp", [0.0, 0.0, 2.5], power=100.0),
              SpotLight("spot", [0.0, 1.0, 2.5], power=100.0),
              AreaLight("area", np.array([0.0, -1.0, 2.5]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]),
                        power=50.0),
              SunLight("sun", [0.2, 0.1, -1.0], irradiance=2.0, angle=0.1)]
    kinds = [SurfaceNode.for_kind(kind) for kind in ("principled", "glass", "metallic")]
    solid = Scene(camera=Camera(camera, fov=0.8), film=Film(4, 4), meshes=[floor, Mesh("block", corners * 0.5, box, np.ones(12, int))],
                  materials=[Material("floor"), Material("block", surface_nodes=kinds)], lights=lights,
                  world=World(background=0.1), settings=RenderSettings(samples=1, threads=1))
    render(solid)
    density = np.linspace(0.0, 1.0, 27, dtype=np.float32).reshape(3, 3, 3)
    to_world = np.diag([1.0, 1.0, 1.0, 1.0])
    to_world[:3, 3] = -1.0
    inside = np.eye(4)  # orthographic, from inside the grid's boundary: per-path volume stacks
    inside[:3, 3] = [0.0, 0.0, 0.5]
    cloud = Scene(camera=Camera(inside, projection="orthographic", ortho_scale=1.0), film=Film(4, 4),
                  meshes=[floor, fog], materials=[Material("floor"), Material("cloud", surface="null", medium=0)],
                  media=[GridMedium("cloud", density, to_world, np.full(3, 2.0), np.full(3, 0.5))],
                  lights=lights[:1], settings=RenderSettings(samples=1, threads=1))
    render(cloud)
    _warm_up_programs(floor, fog, lights[:1])
    return time.perf_counter() - start


def _warm_up_programs(floor, fog, lights):
    """Compile the shader-program entry points outside the stages: the majorant builder of
    procedural media (ProgramMedium) and the batch evaluator the exporter uses."""
    from .program_medium import ProgramMedium
    from .render import render
    from .scene import Camera, Film, Material, RenderSettings
    from .shading import program as P
    from .shading.builder import ProgramBuilder
    from .shading.interpreter import run_program_many

    b = ProgramBuilder("warm-up")
    position, density = b.alloc(3), b.alloc(1)
    b.emit("TEXCO", P.TEXCO_OBJECT, position)
    b.emit("VECTOR_TO_FLOAT", position, density)
    b.emit("VOLUME_SCATTER", 0, b.const(1.0), b.const([0.8, 0.8, 0.8]), density, b.const(0.0))
    program = b.build()
    run_program_many(program.code, program.init, program.tables, np.zeros(program.n_registers),
                     np.zeros((2, 3, 4)), np.zeros((1, 1, 1, 1), np.float32), np.zeros((3, 4)), np.zeros((1, 3)),
                     np.zeros((1, 4)), P.R_LOBES, 4, empty_image_table())
    medium = ProgramMedium("warm-up", program, np.eye(4), ([-1, -1, -1], [1, 1, 1]), majorant_resolution=2)
    camera = np.eye(4)
    camera[:3, 3] = [0.0, 0.0, 6.0]
    render(Scene(camera=Camera(camera, fov=0.8), film=Film(4, 4), meshes=[floor, fog],
                 materials=[Material("floor"), Material("fog", surface="null", medium=0)], media=[medium],
                 lights=lights, settings=RenderSettings(samples=1, threads=1)))
