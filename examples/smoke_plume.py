"""A smoke plume: a procedural density written to .vdb, as a Volume object lit by a sun and a point light.

The density (a rising column that widens, thins out and swirls with height, on a 48 x 48 x 96 grid
of 2.5 cm voxels) is written with the `openvdb` module Blender bundles; the Volume object loads it
and carries a Principled Volume (density 10, grey-blue colour, slight forward scattering). A diffuse
floor catches the plume's shadow from the sun; a warm point light sits beside the plume.

    python examples/smoke_plume.py OUT.blend     (writes OUT_density.vdb next to the .blend)
"""
from __future__ import annotations

import hashlib
import os
import sys
import tempfile
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import bpy  # noqa: E402
import numpy as np  # noqa: E402

from examples import scene_builder as sb  # noqa: E402

GRID_SHAPE = (48, 48, 96)
VOXEL_SIZE = 0.025  # m
SEED = 7


def import_openvdb():
    """Blender's bundled openvdb (imports directly inside Blender; the bpy module needs its path)."""
    try:
        import openvdb
    except ImportError:
        bundled = os.path.join(bpy.utils.resource_path("LOCAL"), "python", "lib",
                               f"python{sys.version_info.major}.{sys.version_info.minor}", "site-packages")
        sys.path.append(bundled)
        try:
            import openvdb
        except ImportError:
            raise SystemExit(f"smoke_plume needs the openvdb module Blender bundles; this Blender has none "
                             f"(looked in {bundled}). Use the bpy module or an official Blender build.") from None
    return openvdb


def plume_density(shape=GRID_SHAPE, seed=SEED) -> np.ndarray:
    """Deterministic plume density in [0, 1] (float32, zero on the grid border)."""
    rng = np.random.default_rng(seed)
    nx, ny, nz = shape
    x = (np.arange(nx) - (nx - 1) / 2) / (nx / 2)  # -1..1
    y = (np.arange(ny) - (ny - 1) / 2) / (ny / 2)
    h = np.arange(nz) / (nz - 1)  # 0 at the base, 1 at the top
    X, Y, H = np.meshgrid(x, y, h, indexing="ij")
    # The column drifts and swirls with height; a few random-phase sines make it turbulent.
    drift_x = 0.25 * H ** 1.5 + 0.08 * np.sin(7.0 * H + 1.3)
    drift_y = 0.06 * np.sin(5.0 * H + 0.4)
    turbulence = np.zeros_like(X)
    for octave in range(4):
        k = 2.0 ** octave * 3.0
        phase = rng.uniform(0, 2 * np.pi, 3)
        turbulence += 0.5 ** octave * np.sin(k * X + phase[0] + 2.0 * H) * np.sin(k * Y + phase[1]) \
            * np.sin(1.5 * k * H + phase[2])
    radius = 0.3 + 0.5 * H  # widens upward
    r = np.sqrt((X - drift_x) ** 2 + (Y - drift_y) ** 2)
    profile = np.clip(1.0 - (r / radius) ** 2, 0.0, None)
    density = profile * (1.0 - 0.6 * H) * np.clip(1.0 + 0.6 * turbulence, 0.0, None)
    density *= np.clip(H * 12.0, 0.0, 1.0)  # fade in at the source
    density[[0, -1], :, :] = density[:, [0, -1], :] = density[:, :, [0, -1]] = 0.0
    return np.clip(density, 0.0, 1.0).astype(np.float32)


def write_plume_vdb(path, shape=GRID_SHAPE, voxel_size=VOXEL_SIZE) -> Path:
    """The plume as a 'density' FloatGrid; the base centre sits at the object origin."""
    openvdb = import_openvdb()
    grid = openvdb.FloatGrid()
    grid.name = "density"
    grid.copyFromArray(plume_density(shape), ijk=(-shape[0] // 2, -shape[1] // 2, 0))
    grid.transform = openvdb.createLinearTransform(voxelSize=voxel_size)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    openvdb.write(str(path), grids=[grid])
    return path


def default_vdb_path(shape=GRID_SHAPE, voxel_size=VOXEL_SIZE) -> Path:
    """A stable cache file for build() without an explicit path (content is deterministic)."""
    key = hashlib.sha1(repr((tuple(shape), voxel_size, SEED)).encode()).hexdigest()[:10]
    return Path(tempfile.gettempdir()) / "volpath_examples" / f"smoke_plume_{key}.vdb"


def smoke_material(density=10.0, color=(0.75, 0.78, 0.85), anisotropy=0.3):
    return sb.principled_volume_material("Smoke", density=density, color=color, anisotropy=anisotropy)


def build(resolution=(64, 64), samples=64, vdb_path=None, density=10.0, grid_shape=GRID_SHAPE):
    """The plume scene. grid_shape: voxels per axis; the plume keeps its size (1.2 x 1.2 x 2.4 m at
    the default shape), so a coarser grid has larger voxels (cheap test variants)."""
    scene = sb.new_scene(resolution, samples)
    voxel_size = VOXEL_SIZE * GRID_SHAPE[2] / grid_shape[2]
    vdb_path = Path(vdb_path) if vdb_path is not None else default_vdb_path(grid_shape, voxel_size)
    write_plume_vdb(vdb_path, tuple(grid_shape), voxel_size)

    floor = sb.diffuse_material("Floor", (0.6, 0.6, 0.6))
    sb.add_quad(scene, "Floor", [(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], floor)

    volume = bpy.data.volumes.new("Plume")
    volume.filepath = str(vdb_path.resolve())
    volume.materials.append(smoke_material(density=density))
    plume = bpy.data.objects.new("Plume", volume)
    scene.collection.objects.link(plume)
    plume.location = (0.0, 0.0, 0.02)

    sb.add_sun_light(scene, direction=(-0.5, 0.4, -0.75), strength=3.0, angle_deg=2.0)
    sb.add_point_light(scene, (0.8, -0.5, 1.5), power_w=60.0, color=(1.0, 0.75, 0.5))
    sb.set_world_background(scene, (0.05, 0.06, 0.08), 1.0)
    sb.add_camera(scene, (0.0, -3.8, 1.4), (0.15, 0.0, 1.1), lens_mm=35.0)
    return scene


def main(argv=None) -> Path:
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--" in argv:  # `blender -b -P smoke_plume.py -- OUT.blend`
        argv = argv[argv.index("--") + 1:]
    if len(argv) != 1 or not argv[0].endswith(".blend"):
        raise SystemExit("usage: python examples/smoke_plume.py OUT.blend")
    out = Path(argv[0]).resolve()
    build(vdb_path=out.with_name(out.stem + "_density.vdb"))
    bpy.context.preferences.filepaths.save_version = 0  # no OUT.blend1 from the second save
    out = sb.save(out)
    bpy.ops.file.make_paths_relative()  # the .vdb travels with the .blend
    bpy.ops.wm.save_mainfile()
    print(f"wrote {out}")
    return out


if __name__ == "__main__":
    main()
