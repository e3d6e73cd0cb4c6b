"""A smoke plume: a procedural density written to .vdb, as a Volume object lit by a sun and a point light.

The density (a rising column that widens, thins out and swirls with height, on a 48 x 48 x 96 grid
of 2.5 cm voxels) is written with the `openvdb` module Blender bundles; the Volume object loads it
and carries a Principled Volume (density 10, grey-blue colour, slight forward scattering). A diffuse
floor catches the plume's shadow from the sun; a warm point light sits beside the plume.

    python examples/smoke_plume.py OUT.blend [--fire]   (writes OUT_density.vdb next to the .blend)

--fire adds Blender's fire setup at the plume's base: 'temperature' and 'flame' grids, blackbody
emission (Blackbody Intensity 1) and flame emission (Attribute 'flame' -> Emission Strength).
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


def plume_fire(density: np.ndarray) -> tuple:
    """(temperature, flame) grids of a fire at the plume's base, as a fluid simulation writes them:
    temperature a multiplier of the material's Temperature (1 to 2.6 in the hot core), flame (the
    emission strength) 0 to 4, both fading out with height."""
    nz = density.shape[2]
    h = (np.arange(nz) / (nz - 1))[None, None, :]
    core = np.clip(density * 2.0, 0.0, 1.0)
    temperature = np.where(density > 0, 1.0 + 1.6 * core * np.exp(-5.0 * h), 0.0)
    flame = 4.0 * core * np.clip(1.0 - 3.0 * h, 0.0, 1.0)
    return temperature.astype(np.float32), flame.astype(np.float32)


def write_plume_vdb(path, shape=GRID_SHAPE, voxel_size=VOXEL_SIZE, fire=False) -> Path:
    """The plume as a 'density' FloatGrid (with fire: also 'temperature' and 'flame' on the same
    voxels); the base centre sits at the object origin."""
    openvdb = import_openvdb()
    density = plume_density(shape)
    arrays = {"density": density}
    if fire:
        arrays["temperature"], arrays["flame"] = plume_fire(density)
    grids = []
    for name, array in arrays.items():
        grid = openvdb.FloatGrid()
        grid.name = name
        grid.copyFromArray(array, ijk=(-shape[0] // 2, -shape[1] // 2, 0))
        grid.transform = openvdb.createLinearTransform(voxelSize=voxel_size)
        grids.append(grid)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    openvdb.write(str(path), grids=grids)
    return path


def default_vdb_path(shape=GRID_SHAPE, voxel_size=VOXEL_SIZE, fire=False) -> Path:
    """A stable cache file for build() without an explicit path (content is deterministic)."""
    key = hashlib.sha1(repr((tuple(shape), voxel_size, SEED, fire)).encode()).hexdigest()[:10]
    return Path(tempfile.gettempdir()) / "volpath_examples" / f"smoke_plume_{key}.vdb"


def smoke_material(density=10.0, color=(0.75, 0.78, 0.85), anisotropy=0.3, fire=False):
    """Principled Volume reading 'density'; with fire, Blender's fire setup: Blackbody Intensity 1
    on the 'temperature' grid (Temperature 1000 K) plus flame emission, an Attribute node 'flame'
    into Emission Strength with an orange Emission Color."""
    material = sb.principled_volume_material("Smoke", density=density, color=color, anisotropy=anisotropy,
                                             emission_color=(1.0, 0.45, 0.1))
    if fire:
        tree = material.node_tree
        principled = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeVolumePrincipled")
        principled.inputs["Blackbody Intensity"].default_value = 1.0
        principled.inputs["Temperature"].default_value = 1000.0
        flame = tree.nodes.new("ShaderNodeAttribute")
        flame.attribute_name = "flame"
        tree.links.new(flame.outputs["Fac"], principled.inputs["Emission Strength"])
    return material


def build(resolution=(64, 64), samples=64, vdb_path=None, density=10.0, grid_shape=GRID_SHAPE, fire=False):
    """The plume scene. grid_shape: voxels per axis; the plume keeps its size (1.2 x 1.2 x 2.4 m at
    the default shape), so a coarser grid has larger voxels (cheap test variants). fire: a
    blackbody + flame fire at the plume's base (temperature and flame grids)."""
    scene = sb.new_scene(resolution, samples)
    voxel_size = VOXEL_SIZE * GRID_SHAPE[2] / grid_shape[2]
    vdb_path = Path(vdb_path) if vdb_path is not None else default_vdb_path(grid_shape, voxel_size, fire)
    write_plume_vdb(vdb_path, tuple(grid_shape), voxel_size, fire)

    floor = sb.diffuse_material("Floor", (0.6, 0.6, 0.6))
    sb.add_quad(scene, "Floor", [(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], floor)

    volume = bpy.data.volumes.new("Plume")
    volume.filepath = str(vdb_path.resolve())
    volume.materials.append(smoke_material(density=density, fire=fire))
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
    fire = "--fire" in argv
    argv = [a for a in argv if a != "--fire"]
    if len(argv) != 1 or not argv[0].endswith(".blend"):
        raise SystemExit("usage: python examples/smoke_plume.py OUT.blend [--fire]")
    out = Path(argv[0]).resolve()
    build(vdb_path=out.with_name(out.stem + "_density.vdb"), fire=fire)
    bpy.context.preferences.filepaths.save_version = 0  # no OUT.blend1 from the second save
    out = sb.save(out)
    bpy.ops.file.make_paths_relative()  # the .vdb travels with the .blend
    bpy.ops.wm.save_mainfile()
    print(f"wrote {out}")
    return out


if __name__ == "__main__":
    main()
