"""Blender fluid (Mantaflow) gas domains -> ExportedVolume grids, read and placed as Cycles' Blender sync does.

What Cycles 5.0 does with a domain (blender/blender intern/cycles/blender/):
- `object_fluid_gas_domain_find` (util.h) makes `determine_geom_type` (geometry.cpp) sync a gas
  domain as a Volume: its mesh (the domain box) is never shaded.
- `sync_smoke_volume` (volume.cpp) loads grids only when cache_frame_start <= frame <=
  cache_frame_end; outside, the attributes are empty and nothing renders.
- `BlenderSmokeLoader` copies the RNA arrays of the *evaluated* FluidDomainSettings
  (makesrna/intern/rna_fluid.cc getters): density_grid, flame_grid, color_grid (RGBA, rgb
  premultiplied by density, or (active colour, 1) without colour grids), temperature_grid
  (flame > 0.01 ? ignition + flame x (max temp - ignition) : 0), heat_grid (heat x 0.5, always the
  base resolution). With noise upres the others are res x noise_scale. Layout x fastest:
  index = i + nx (j + ny k). Values with |v| <= the domain's Clipping become background.
- Placement (Cycles v5.0.0 src/scene/image_vdb.cpp create_grid, the inverse of
  util.h mesh_texture_space): value i sits at x_obj = (L - S) + 2 S i / N + 1 / N per axis, L and
  S the texture space of the evaluated mesh (an adaptive domain's box of the frame), N the grid
  resolution. (The intended cell centre is S / N; 5.0 adds 1 / N. Checked against Cycles 5.0.1:
  tests/addon_volume/test_fluid_domains.py.)
- Smoke domains are not object-space volumes: the density factor is 1 (scene/object.cpp).

Where the grids come from, in order (FLUID_SOURCES):
1. the domain's OpenVDB cache files for the frame (data/fluid_data_NNNN.vdb, noise/fluid_noise_NNNN.vdb),
   read with Blender's `openvdb` module. They hold Mantaflow's own grids ('density'/'density_noise',
   'flame'/'flame_noise', 'color_r/g/b'(_noise), 'temperature' = heat); the getters' conversions
   above are applied, which gives exactly the runtime's arrays (tests/addon_volume/test_fluid_domains.py).
   First, because the runtime cannot always be trusted: the bpy 5.0.1 wheel's Mantaflow cannot load
   a cache at all (its Python classes lack their C++ base classes: all zeros), and Blender's runtime
   keeps the previous frame's grids when a frame's file is missing or corrupt (seen in 3.4 and
   in the repaired 5.0.1 wheel).
   A missing, corrupt or mismatched cache file is bad input: nothing renders.
2. the fluid runtime, the evaluated domain's RNA arrays as Cycles reads them, when this Blender
   cannot read the cache (Debian's Blender 3.4 has no openvdb module; Uni/Raw caches), provided
   the frame's cache file exists.
The source used is logged (printed) once per domain and frame.

Not supported, each with a warning naming the object and nothing drawn: liquid domains, fluid
particle systems, velocity motion blur (the smoke is rendered at the frame). Bad input (an unbaked
domain, a missing cache folder or file, a corrupt or mismatched cache file, non-finite voxels) gives
a warning naming the domain and the frame and nothing rendered for it (non-finite voxels: 0).
"""
from __future__ import annotations

import os
from typing import Callable, Optional

import bpy
import numpy as np

from .grid_media import DenseGrid, ExportedVolume, material_grid_names
from .motion import instance_key

#: Where grids are read from, in order; tests pin one source.
FLUID_SOURCES = ("cache", "runtime")

# Cycles' smoke attributes (blender/volume.cpp BlenderSmokeLoader): name -> (RNA array, channels,
# at the noise resolution when noise upres is on). Velocity is only read for motion blur.
SMOKE_ATTRIBUTES = {
    "density": ("density_grid", 1, True),
    "color": ("color_grid", 4, True),
    "flame": ("flame_grid", 1, True),
    "heat": ("heat_grid", 1, False),
    "temperature": ("temperature_grid", 1, True),
}
# Cycles un-premultiplies colour attributes when alpha > this and != 1 (kernel/geom/volume.h).
_COLOR_ALPHA_EPSILON = 1e-6
# rna_fluid.cc rna_FluidModifier_temperature_grid_get: flame below this is 0 K.
_FLAME_THRESHOLD = 0.01
# Particle settings types of Mantaflow's secondary and FLIP particles.
_FLUID_PARTICLE_TYPES = {"FLIP", "SPRAY", "BUBBLE", "FOAM", "TRACER", "SPRAYFOAM", "SPRAYBUBBLE",
                         "FOAMBUBBLE", "SPRAYFOAMBUBBLE"}


def domain_modifier(obj):
    """The object's Fluid modifier of type Domain, or None."""
    for modifier in getattr(obj, "modifiers", ()):
        if modifier.type == "FLUID" and modifier.fluid_type == "DOMAIN":
            return modifier
    return None


def is_fluid_domain(obj) -> bool:
    """True for gas and liquid domains: their meshes are not exported as surfaces."""
    return obj.type == "MESH" and domain_modifier(obj) is not None


def export_fluid_domains(depsgraph, warnings: list, log: Callable[[str], None] = print) -> list:
    """ExportedVolume for every rendered gas domain instance at the depsgraph's frame; warnings
    for what cannot be rendered; `log` receives one line per domain saying where the grids came from."""
    scene = depsgraph.scene
    frame = scene.frame_current
    exported = []
    for instance in depsgraph.object_instances:
        obj = instance.object
        if not is_fluid_domain(obj) or (not instance.is_instance and not instance.show_self):
            continue
        settings = domain_modifier(obj).domain_settings
        if settings.domain_type != "GAS":
            warnings.append(f"object '{obj.name}': liquid fluid domains are not supported; not rendered")
            continue
        _warn_unsupported(obj, scene, warnings)
        volume = export_domain(obj, np.array(instance.matrix_world, dtype=np.float64), frame, warnings, log)
        if volume is not None:
            volume.instance_key = instance_key(instance)
            exported.append(volume)
    return exported


def _warn_unsupported(obj, scene, warnings):
    for system in obj.particle_systems:
        if system.settings.type in _FLUID_PARTICLE_TYPES:
            warnings.append(f"object '{obj.name}': fluid particles ('{system.name}') are not supported; not rendered")
    if scene.render.use_motion_blur:
        warnings.append(f"fluid domain '{obj.name}': velocity motion blur is not supported; "
                        "the smoke is rendered at the frame")


def export_domain(obj, object_to_world, frame: int, warnings: list,
                  log: Callable[[str], None] = print, sources=None) -> Optional[ExportedVolume]:
    """The grids of one *evaluated* gas domain object at `frame`, or None (with a warning) when
    nothing renders. sources: override FLUID_SOURCES."""
    label = f"fluid domain '{obj.name}' (frame {frame})"
    modifier = domain_modifier(obj)
    settings = modifier.domain_settings
    if not modifier.show_render:
        warnings.append(f"{label}: its Fluid modifier is disabled for renders; not rendered")
        return None
    start, end = settings.cache_frame_start, settings.cache_frame_end
    if not start <= frame <= end:  # blender/volume.cpp sync_smoke_volume: empty grids outside
        warnings.append(f"{label}: the frame is outside the cache range {start}-{end}; not rendered (as Cycles)")
        return None
    material = obj.active_material
    names = sorted(material_grid_names(material) & set(SMOKE_ATTRIBUTES))
    if not names:
        warnings.append(f"{label}: its material reads none of the smoke grids {sorted(SMOKE_ATTRIBUTES)}; "
                        "not rendered (as Cycles)")
        return None
    layout = DomainLayout.of(obj, settings)
    if layout is None:
        warnings.append(f"{label}: the domain has no resolution or texture space yet (never simulated); "
                        "not rendered")
        return None

    grids, source, reasons = None, None, []
    for name in (sources or FLUID_SOURCES):
        try:
            grids = _READERS[name](settings, layout, names, frame, obj)
        except _Unreadable as why:  # this Blender cannot use this source: try the next one
            reasons.append(str(why))
            continue
        except _BadCache as why:  # the cache is wrong for this frame: another source would be stale
            warnings.append(f"{label}: {why}; not rendered")
            return None
        source = name
        break
    if grids is None:
        warnings.append(f"{label}: {'; '.join(reasons)}; not rendered")
        return None
    origin = ("the fluid runtime (evaluated domain)" if source == "runtime" else
              f"the OpenVDB cache files in {cache_folder(settings, obj)}")
    log(f"VolPath: {label}: grids {names} from {origin}" + (f" ({'; '.join(reasons)})" if reasons else ""))
    dense = _dense_grids(grids, layout, object_to_world, float(settings.clipping), label, warnings)
    if dense is None:
        warnings.append(f"{label}: every grid is empty at this frame; nothing rendered")
        return None
    return ExportedVolume(obj.name, object_to_world, dense, density_factor=1.0, material=material,
                          label=f"fluid domain '{obj.name}'")


# ----------------------------------------------------------------------------------------------
# Placement
# ----------------------------------------------------------------------------------------------
class DomainLayout:
    """Resolution and texture space of an evaluated domain at the current frame."""

    def __init__(self, base_resolution, noise_scale: int, texspace_location, texspace_size):
        self.base_resolution = tuple(int(n) for n in base_resolution)
        self.noise_scale = int(noise_scale)  # 1 without noise upres
        self.texspace_location = np.asarray(texspace_location, dtype=np.float64)
        self.texspace_size = np.asarray(texspace_size, dtype=np.float64)

    @classmethod
    def of(cls, obj, settings) -> Optional["DomainLayout"]:
        resolution = tuple(settings.domain_resolution)
        mesh = obj.data
        if min(resolution) < 1 or mesh is None:
            return None
        scale = int(settings.noise_scale) if settings.use_noise else 1
        return cls(resolution, scale, mesh.texspace_location, mesh.texspace_size)

    def resolution(self, name: str) -> tuple:
        """Grid resolution of a smoke attribute (heat stays at the base resolution)."""
        upres = self.noise_scale if SMOKE_ATTRIBUTES[name][2] else 1
        return tuple(n * upres for n in self.base_resolution)

    def index_to_object(self, resolution) -> np.ndarray:
        """4x4 map of grid index (i, j, k) to object space: (L - S) + 2 S i / N + 1 / N per axis
        (Cycles 5.0, scene/image_vdb.cpp create_grid with blender/util.h mesh_texture_space)."""
        n = np.asarray(resolution, dtype=np.float64)
        location, size = self.texspace_location, self.texspace_size
        matrix = np.eye(4)
        matrix[:3, :3] = np.diag(2.0 * size / n)
        matrix[:3, 3] = location - size + 1.0 / n
        return matrix


# ----------------------------------------------------------------------------------------------
# Grid sources: name -> array indexed [i, j, k] (x fastest in Blender's flat arrays)
# ----------------------------------------------------------------------------------------------
def _from_flat(flat: np.ndarray, resolution, channels: int) -> np.ndarray:
    nx, ny, nz = resolution
    shape = (nz, ny, nx) + ((channels,) if channels > 1 else ())
    grid = flat.reshape(shape)
    return grid.transpose((2, 1, 0, 3) if channels > 1 else (2, 1, 0))


class _Unreadable(Exception):
    """This Blender cannot read the grids this way (no openvdb module, another cache format)."""


class _BadCache(Exception):
    """The domain's cache is missing, incomplete or broken for the frame."""


def _frame_file(settings, obj, kind: str, frame: int, extension: str) -> str:
    # Cache types All/Modular load frame - offset (blenkernel/intern/fluid.cc processDomain);
    # Mantaflow names files <kind>/fluid_<kind>_####.<ext> (intern/mantaflow/intern/MANTA_main.cpp).
    if settings.cache_type in ("ALL", "MODULAR"):
        frame -= settings.cache_frame_offset
    return os.path.join(cache_folder(settings, obj), kind, f"fluid_{kind}_{frame:04d}{extension}")


_EXTENSIONS = {"OPENVDB": ".vdb", "UNI": ".uni", "RAW": ".raw"}


def _runtime_grids(settings, layout: DomainLayout, names, frame, obj) -> dict:
    """The evaluated domain's RNA arrays. A frame whose cache file is missing or unreadable keeps
    the previous frame's grids in Blender's runtime (seen in 3.4 and 5.0): the file must exist."""
    folder = cache_folder(settings, obj)
    if not os.path.isdir(folder):
        raise _BadCache(f"the cache folder {folder} does not exist (not baked?)")
    data = _frame_file(settings, obj, "data", frame, _EXTENSIONS.get(settings.cache_data_format, ".vdb"))
    if not os.path.isfile(data):
        raise _BadCache(f"no data cache file {data} (not baked for this frame?)")
    grids = {}
    for name in names:
        prop, channels, _ = SMOKE_ATTRIBUTES[name]
        resolution = layout.resolution(name)
        array = getattr(settings, prop)
        expected = int(np.prod(resolution)) * channels
        if len(array) != expected:  # Cycles: "Unexpected smoke volume resolution, skipping"
            continue
        flat = np.empty(expected, dtype=np.float32)
        array.foreach_get(flat)
        grids[name] = _from_flat(flat, resolution, channels)
    # Without colour grids the colour is a constant (alpha 1) everywhere: not a sign of data.
    if not any(np.any(grid != 0) for name, grid in grids.items() if name != "color"):
        raise _BadCache("the fluid runtime handed over no voxels")
    return grids


def cache_folder(settings, obj) -> str:
    library = getattr(obj.original, "library", None) if hasattr(obj, "original") else None
    return os.path.normpath(bpy.path.abspath(settings.cache_directory, library=library))


def _cache_grids(settings, layout: DomainLayout, names, frame, obj) -> dict:
    """The grids of the frame from its OpenVDB cache files, with the getters' conversions."""
    from .. import export_volume_grids as volume_grids  # Blender's openvdb module

    if settings.cache_data_format != "OPENVDB":
        raise _Unreadable(f"its {settings.cache_data_format} cache files cannot be read (only OpenVDB)")
    try:
        openvdb = volume_grids.import_openvdb()
    except volume_grids.OpenVDBUnavailable:
        raise _Unreadable("this Blender has no openvdb module to read its cache files") from None
    folder = cache_folder(settings, obj)
    if not os.path.isdir(folder):
        raise _BadCache(f"the cache folder {folder} does not exist (not baked?)")
    files = {"data": _frame_file(settings, obj, "data", frame, ".vdb")}
    if layout.noise_scale > 1 and any(SMOKE_ATTRIBUTES[n][2] for n in names):
        files["noise"] = _frame_file(settings, obj, "noise", frame, ".vdb")
    listed = {}  # file kind -> names of the grids it holds
    for kind, path in files.items():
        if not os.path.isfile(path):
            raise _BadCache(f"no {kind} cache file {path} (not baked for this frame?)")
        try:
            listed[kind] = {grid.name for grid in openvdb.readAllGridMetadata(path)}
        except Exception as error:  # noqa: BLE001 - openvdb raises RuntimeError/IOError/...
            raise _BadCache(f"the cache file {path} cannot be read ({type(error).__name__}: {error})") from None

    suffix, kind = ("_noise", "noise") if "noise" in files else ("", "data")
    base = layout.base_resolution
    upres = layout.resolution("density") if "noise" in files else base

    def read(file_kind, grid_name, resolution):
        """One grid of a file (only those the material needs: velocity is the largest) as an array."""
        if grid_name not in listed[file_kind]:
            return None
        try:
            grid = openvdb.read(files[file_kind], grid_name)
        except Exception as error:  # noqa: BLE001
            raise _BadCache(f"the cache file {files[file_kind]} cannot be read "
                            f"({type(error).__name__}: {error})") from None
        # Mantaflow records its grid resolution; an adaptive domain's changes per frame.
        stored = tuple(int(v) for v in grid.metadata.get("file_base_resolution", resolution))
        if stored != tuple(resolution):
            raise _BadCache(f"the cache's '{grid_name}' grid is {stored} voxels, the domain {tuple(resolution)} "
                            "(a cache from another bake?)")
        if grid.valueTypeName not in ("float", "double"):
            raise _BadCache(f"the cache's '{grid_name}' grid holds {grid.valueTypeName} values, not floats")
        array = np.zeros(tuple(resolution), dtype=np.float64 if grid.valueTypeName == "double" else np.float32)
        if grid.activeVoxelCount():
            lo, hi = grid.evalActiveVoxelBoundingBox()
            if min(lo) < 0 or any(h >= n for h, n in zip(hi, resolution)):
                raise _BadCache(f"the cache's '{grid_name}' voxels {lo}..{hi} lie outside the domain's "
                                f"{tuple(resolution)} (a cache from another bake?)")
            grid.copyToArray(array, ijk=(0, 0, 0))
        return array.astype(np.float32, copy=False)

    density = read(kind, "density" + suffix, upres)
    if density is None:
        raise _BadCache(f"the cache file {files[kind]} has no '{'density' + suffix}' grid")
    flame = read(kind, "flame" + suffix, upres)
    grids = {}
    for name in names:
        if name == "density":
            grids[name] = density
        elif name == "flame" and flame is not None:
            grids[name] = flame
        elif name == "temperature" and flame is not None:
            # rna_fluid.cc rna_FluidModifier_temperature_grid_get
            ignition, hottest = float(settings.flame_ignition), float(settings.flame_max_temp)
            grids[name] = np.where(flame > _FLAME_THRESHOLD, ignition + flame * (hottest - ignition),
                                   0.0).astype(np.float32)
        elif name == "heat":
            heat = read("data", "temperature", base)  # Mantaflow's heat, saved as 'temperature'
            if heat is not None:
                grids[name] = heat * np.float32(0.5)  # rna_FluidModifier_heat_grid_get: -2..2 -> -1..1
        elif name == "color":
            channels = [read(kind, f"color_{c}{suffix}", upres) for c in "rgb"]
            if all(c is not None for c in channels):  # manta_fluid_API.cpp get_rgba
                grids[name] = np.stack([c * density for c in channels] + [density], axis=-1)
            else:  # get_rgba_fixed_color: the flows' smoke colour, alpha 1
                grids[name] = np.broadcast_to(np.append(_active_color(obj), 1.0).astype(np.float32),
                                              tuple(upres) + (4,))
    return grids


_READERS = {"cache": _cache_grids, "runtime": _runtime_grids}


def _active_color(domain) -> np.ndarray:
    """The domain's smoke colour without colour grids (DNA active_color, not in RNA): the smoke
    colour of its flows, as blenkernel/intern/fluid.cc update_flowsflags sets it."""
    settings = domain_modifier(domain).domain_settings
    collection = settings.fluid_group
    objects = collection.all_objects if collection is not None else bpy.data.objects
    for obj in objects:
        for modifier in obj.modifiers:
            if modifier.type == "FLUID" and modifier.fluid_type == "FLOW":
                flow = modifier.flow_settings
                if flow.flow_type != "FIRE" and flow.density != 0.0:
                    return np.array(flow.smoke_color[:3], dtype=np.float64)
    return np.zeros(3)


# ----------------------------------------------------------------------------------------------
# Dense grids on the domain lattice
# ----------------------------------------------------------------------------------------------
def _dense_grids(grids: dict, layout: DomainLayout, object_to_world, clipping: float, label: str,
                 warnings: list) -> Optional[dict]:
    """DenseGrid per attribute, cropped to the union of the active boxes of the grids sharing a
    lattice (Cycles' bounds mesh is built from the active voxels); None when all are empty."""
    cleaned, active = {}, {}
    for name, grid in grids.items():
        grid = np.array(grid, dtype=np.float32)
        bad = ~np.isfinite(grid)
        if bad.any():
            # Cycles' fmaxf(density * NaN, 0) is 0 (kernel/svm/closure.h); +-inf would make
            # the path tracer's weights non-finite: both become 0.
            count = int(bad.reshape(grid.shape[:3] + (-1,)).any(axis=-1).sum())
            warnings.append(f"{label}: grid '{name}' has {count} non-finite voxels (NaN/inf), treated as 0")
            grid[bad] = 0.0
        # copyFromDense with tolerance = clipping (scene/image_vdb.cpp create_grid): background.
        small = np.abs(grid) <= clipping
        if grid.ndim == 4:
            small = small.all(axis=-1, keepdims=True) & np.ones_like(small)
        grid[small] = 0.0
        cleaned[name] = grid
        active[name] = np.argwhere(grid.reshape(grid.shape[:3] + (-1,)).any(axis=-1))
    dense = {}
    for resolution in {layout.resolution(name) for name in cleaned}:
        members = [n for n in cleaned if layout.resolution(n) == resolution and len(active[n])]
        if not members:
            continue
        points = np.concatenate([active[n] for n in members])
        lo, hi = points.min(axis=0), points.max(axis=0)
        index_to_object = layout.index_to_object(resolution)
        shift = np.eye(4)
        shift[:3, 3] = lo
        for name in members:
            data = cleaned[name][lo[0]:hi[0] + 1, lo[1]:hi[1] + 1, lo[2]:hi[2] + 1]
            if name == "color":
                data = _unpremultiplied(data)
            dense[name] = DenseGrid(name, np.ascontiguousarray(data), object_to_world @ index_to_object @ shift,
                                    tuple(int(v) for v in lo), index_to_object)
    return dense or None


def _unpremultiplied(rgba: np.ndarray) -> np.ndarray:
    """RGB of a smoke colour attribute as Cycles uses it: rgb / alpha when alpha > 1e-6 and != 1
    (kernel/geom/volume.h volume_attribute_value<float3>). Cycles divides the value its stochastic
    lookup picked, one voxel, so doing it per voxel matches in expectation."""
    alpha = rgba[..., 3:4]
    divide = (alpha > _COLOR_ALPHA_EPSILON) & (alpha != 1.0)
    return np.where(divide, rgba[..., :3] / np.where(divide, alpha, 1.0), rgba[..., :3]).astype(np.float32)
