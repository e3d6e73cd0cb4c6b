"""Mitsuba 3 as a second peer in the equal-time benchmarks (never a test dependency).

The scene VolPath exported from the .blend (volpath_native.scene.Scene) is translated into a
Mitsuba scene dictionary and rendered with Mitsuba's `volpath` integrator, so all three engines
see the same geometry, lights and media. Only what both renderers define the same way is
translated; anything else raises Unsupported and the row shows no Mitsuba column:
- surfaces: Lambertian (Diffuse BSDF with roughness 0, or materials without nodes); volume-only
  (null) boundaries; emissive meshes as one-sided area emitters (Cycles: two-sided).
- media: homogeneous, one Henyey-Greenstein lobe, no emission; density grids (Volume objects from
  a .vdb) as a `heterogeneous` medium over a `gridvolume`, without colour or emission grids.
- lights: point (radius 0; I = P / 4 pi, lights.py), spot (radius 0, blend 0: Mitsuba's falloff is
  linear in angle where Blender's is a smoothstep in cosine), area squares/rectangles (one-sided,
  L = P / (pi A)), sun (angle 0), a constant world.
- camera: perspective without shift; film: box filter (Mitsuba has no Blackman-Harris), so the
  Mitsuba column is measured against a Mitsuba reference (its variance), and its image mean
  against Cycles' reference is printed as a check.
Known difference: Mitsuba's max_depth bounds all bounces together (Cycles and VolPath also limit
diffuse / volume bounces apart); the bench uses scenes where those limits rarely bite.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# scalar_rgb: Mitsuba's CPU renderer, a path per thread over all cores. Its vectorised llvm_ad_rgb
# backend fails here: Debian's libLLVM 15 stops in instruction selection ("Cannot select") on the
# kernels Dr.Jit generates for this CPU, even for Mitsuba's own Cornell box.
VARIANT = "scalar_rgb"


class Unsupported(ValueError):
    """The scene uses something this translation does not render as Cycles does."""


def available() -> bool:
    import importlib.util

    return importlib.util.find_spec("mitsuba") is not None


def _transform(matrix) -> dict:
    """A 4x4 matrix as plain data (the child process turns it into a ScalarTransform4f)."""
    return {"__transform__": np.asarray(matrix, float).reshape(4, 4).tolist()}


def _look_along(position, direction) -> dict:
    """Mitsuba's look_at frame (local +Z along `direction`, +X = up x direction)."""
    direction = np.asarray(direction, float) / np.linalg.norm(direction)
    up = np.array([0.0, 0.0, 1.0]) if abs(direction[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
    left = np.cross(up, direction)
    left /= np.linalg.norm(left)
    matrix = np.eye(4)
    matrix[:3, 0], matrix[:3, 1], matrix[:3, 2], matrix[:3, 3] = left, np.cross(direction, left), direction, position
    return _transform(matrix)


def _rgb(value) -> dict:
    return {"type": "rgb", "value": [float(v) for v in np.asarray(value, float).reshape(3)]}


def _write_ply(path: Path, vertices: np.ndarray, triangles: np.ndarray) -> None:
    """A binary little-endian PLY (Mitsuba's `ply` loader reads it; no normals: flat shading)."""
    vertices = np.ascontiguousarray(vertices, dtype="<f4")
    faces = np.empty(len(triangles), dtype=[("n", "u1"), ("idx", "<i4", (3,))])
    faces["n"] = 3
    faces["idx"] = triangles
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(vertices)}\n"
              "property float x\nproperty float y\nproperty float z\n"
              f"element face {len(triangles)}\nproperty list uchar int vertex_indices\nend_header\n")
    with open(path, "wb") as out:
        out.write(header.encode("ascii"))
        out.write(vertices.tobytes())
        out.write(faces.tobytes())


def _behind(vertices, triangles, gap=1e-4):
    """The triangles flipped and moved `gap` behind their faces (each with its own corners): a copy
    in the same plane would hide the front face from camera rays (coincident hits, and the null
    copy's continuation skips the front one)."""
    corners = np.asarray(vertices, float)[np.asarray(triangles)]  # (n, 3, 3)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30)
    moved = corners[:, ::-1] - gap * normals[:, None, :]
    return moved.reshape(-1, 3).astype(np.float32), np.arange(3 * len(corners)).reshape(-1, 3)


def _bsdf(material) -> dict:
    if material.surface == "null":
        return {"type": "null"}
    nodes = material.surface_nodes
    if not nodes:
        return {"type": "diffuse", "reflectance": _rgb(material.base_color)}
    if len(nodes) == 1 and nodes[0].kind == "diffuse" and nodes[0].roughness == 0.0 \
            and material.surface_program is None:
        return {"type": "diffuse", "reflectance": _rgb(nodes[0].color)}
    raise Unsupported(f"material '{material.name}': only Lambertian surfaces are translated")


def _medium(medium, folder: Path) -> dict:
    if not getattr(medium, "is_homogeneous", True):
        return _grid_medium(medium, folder)
    if medium.phase_lobes:
        raise Unsupported(f"medium '{medium.name}': only single-lobe media are translated")
    if np.any(np.asarray(medium.emission) > 0):
        raise Unsupported(f"medium '{medium.name}': emission is not translated")
    sigma_t = np.asarray(medium.sigma_s, float) + np.asarray(medium.sigma_a, float)
    albedo = np.where(sigma_t > 0, np.asarray(medium.sigma_s, float) / np.maximum(sigma_t, 1e-30), 0.0)
    scale = float(sigma_t.max())  # Mitsuba reads an RGB as a reflectance (<= 1): scale x colour
    return {"type": "homogeneous", "sigma_t": _rgb(sigma_t / max(scale, 1e-30)), "scale": scale,
            "albedo": _rgb(albedo),
            "phase": {"type": "hg", "g": float(medium.g)}}


def _grid_medium(medium, folder: Path) -> dict:
    """A density grid as Mitsuba's `heterogeneous` medium over a `gridvolume`: sigma_t = density x
    (sigma_s + sigma_a), a constant albedo. VolPath's voxel i sits at index point i and is
    interpolated between points; Mitsuba's texture is cell-centred (texel i at (i + 0.5) / n of its
    unit cube), so the unit cube maps to index space [-0.5, n - 0.5] before index_to_world; the
    padded grid's zero border makes the clamped edges agree."""
    from volpath_native.program_medium import ProgramMedium

    if isinstance(medium, ProgramMedium):
        raise Unsupported(f"medium '{medium.name}': shader-program media are not translated")
    if medium.scatter_grid is not None or medium.emission_grid is not None or np.any(medium.emission != 0):
        raise Unsupported(f"medium '{medium.name}': colour and emission grids are not translated")
    if getattr(medium, "motion", None) is not None:
        raise Unsupported(f"medium '{medium.name}': moving media are not translated")
    sigma_t = np.asarray(medium.sigma_s, float) + np.asarray(medium.sigma_a, float)
    scale = float(sigma_t.max())
    density = np.asarray(medium.density, np.float32)
    n = np.array(density.shape, float)
    texel = np.diag([*n, 1.0])
    texel[:3, 3] = -0.5
    path = folder / f"{_safe(medium.name)}.vol"
    _write_vol(path, density[..., None] * (sigma_t / max(scale, 1e-30)).astype(np.float32))
    return {"type": "heterogeneous", "scale": scale,
            "sigma_t": {"type": "gridvolume", "filename": str(path), "raw": True,
                        "to_world": _transform(np.asarray(medium.index_to_world, float) @ texel)},
            "albedo": _rgb(np.where(sigma_t > 0, np.asarray(medium.sigma_s, float) / np.maximum(sigma_t, 1e-30), 0.0)),
            "phase": {"type": "hg", "g": float(medium.g)}}


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in name)


def _write_vol(path: Path, grid) -> None:
    """Mitsuba's .vol: 'VOL', version 3, float32 encoding, x/y/z resolution, channels, a bounding
    box (unused: the volume's to_world places it), then data[((z * ny + y) * nx + x) * c + ch]."""
    nx, ny, nz, channels = grid.shape
    header = b"VOL" + bytes([3]) + np.array([1, nx, ny, nz, channels], "<i4").tobytes()
    header += np.array([0, 0, 0, 1, 1, 1], "<f4").tobytes()
    path.write_bytes(header + np.ascontiguousarray(grid.transpose(2, 1, 0, 3), "<f4").tobytes())


def _inside(point, vertices, triangles) -> bool:
    """Whether `point` is inside the closed mesh: the parity of a ray's crossings (Moller-Trumbore)."""
    direction = np.array([0.5773, 0.5774, 0.5775])  # not along any axis: no edge-on hits on boxes
    a, b, c = (vertices[triangles[:, k]].astype(float) for k in range(3))
    e1, e2 = b - a, c - a
    p = np.cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    t_vec = point - a
    u = np.einsum("ij,ij->i", t_vec, p) * inv
    q = np.cross(t_vec, e1)
    v = (q @ direction) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hits = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return bool(np.count_nonzero(hits) % 2)


def _medium_at(scene, point, skip_mesh=-1) -> int:
    """Index of the medium filling space at `point` (innermost by volume is not needed for the
    bench scenes: the first closed medium mesh containing it), else the world's."""
    for index, mesh in enumerate(scene.meshes):
        if index == skip_mesh:
            continue
        for material_id in np.unique(mesh.material_ids):
            medium = scene.materials[int(material_id)].medium
            if medium >= 0 and _inside(np.asarray(point, float), mesh.vertices,
                                       mesh.triangles[mesh.material_ids == material_id]):
                return medium
    return scene.world.medium


def _lights(scene, media: dict) -> dict:
    from volpath_native.scene import AreaLight, PointLight, SpotLight, SunLight

    emitters = {}
    for index, light in enumerate(scene.lights):
        key = f"light_{index}"
        if isinstance(light, SpotLight):
            if light.radius > 0 or light.spot_blend > 0:
                raise Unsupported(f"spot '{light.name}': radius and blend differ between the renderers")
            half = math.degrees(light.spot_size / 2)
            emitters[key] = {"type": "spot", "intensity": _rgb(light.power / (4 * np.pi)), "cutoff_angle": half,
                             "beam_width": half, "to_world": _look_along(light.position, light.direction)}
        elif isinstance(light, PointLight):
            if light.radius > 0:
                raise Unsupported(f"point light '{light.name}' has a radius (Cycles' soft sphere)")
            emitters[key] = {"type": "point", "position": list(map(float, light.position)),
                             "intensity": _rgb(light.power / (4 * np.pi))}
        elif isinstance(light, AreaLight):
            if light.shape not in ("square", "rectangle"):
                raise Unsupported(f"area light '{light.name}': shape {light.shape}")
            # Mitsuba's rectangle spans [-1, 1]^2 of its local XY and emits along the cross product
            # of the mapped X and Y: the lamp emits along -(u x v), so X and Y are v/2 and u/2
            u, v, n = light.axis_v / 2, light.axis_u / 2, light.direction
            matrix = np.eye(4)
            matrix[:3, 0], matrix[:3, 1], matrix[:3, 2], matrix[:3, 3] = u, v, n, light.position
            emitters[key] = {"type": "rectangle", "to_world": _transform(matrix),
                             "bsdf": {"type": "null"}, **_interface(media, _medium_at(scene, light.position)),
                             "emitter": {"type": "area", "radiance": _rgb(light.power / (np.pi * light.area))}}
        elif isinstance(light, SunLight):
            if light.angle > 0:
                raise Unsupported(f"sun '{light.name}' has an angular diameter")
            emitters[key] = {"type": "directional", "direction": list(map(float, light.direction)),
                             "irradiance": _rgb(light.irradiance)}
        else:
            raise Unsupported(f"light '{getattr(light, 'name', index)}' of type {type(light).__name__}")
    if np.any(scene.world.background > 0):
        emitters["world"] = {"type": "constant", "radiance": _rgb(scene.world.background)}
    return emitters


def _interface(media: dict, outside: int) -> dict:
    """A shape's exterior medium (Mitsuba needs it on every surface inside a medium; a volume-free
    surface such as a lamp in fog has the same medium on both sides)."""
    return {} if outside < 0 else {"exterior": media[outside], "interior": media[outside]}


def _camera(scene, spp: int) -> dict:
    camera, film = scene.camera, scene.film
    if camera.projection != "perspective" or camera.shift_x or camera.shift_y or camera.aperture_size > 0:
        raise Unsupported(f"camera '{camera.name}': only a pinhole perspective without shift is translated")
    # Blender's camera looks along -Z with +X right; Mitsuba's along +Z with +X left
    to_world = np.vstack([np.asarray(camera.camera_to_world, float)[:3], [0, 0, 0, 1]]) @ np.diag([-1, 1, -1, 1])
    fov_axis = {"AUTO": "larger", "HORIZONTAL": "x", "VERTICAL": "y"}[camera.sensor_fit]
    return {"type": "perspective", "fov": math.degrees(camera.fov), "fov_axis": fov_axis,
            "near_clip": float(camera.clip_start), "far_clip": float(camera.clip_end),
            "to_world": _transform(to_world),
            "film": {"type": "hdrfilm", "width": int(film.width), "height": int(film.height),
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": int(spp)}}


def scene_dict(scene, folder: Path, spp: int = 16) -> dict:
    """The Mitsuba scene dictionary of a VolPath scene (plain data: transforms as _transform());
    mesh files are written into `folder`."""
    from volpath_native.scene import SunLight

    if scene.world.medium >= 0 and (any(isinstance(light, SunLight) for light in scene.lights)
                                    or np.any(scene.world.background > 0)):
        raise Unsupported("distant light through a world volume (Cycles: none arrives)")
    settings = scene.settings
    result = {"type": "scene",
              "integrator": {"type": "volpath", "max_depth": int(settings.max_bounces) + 1,
                             "rr_depth": int(settings.russian_roulette_min_bounces) + 2},
              "sensor": _camera(scene, spp)}
    media = {index: _medium(m, folder) for index, m in enumerate(scene.media)}
    camera_medium = _medium_at(scene, np.asarray(scene.camera.camera_to_world, float)[:3, 3])
    if camera_medium >= 0:
        result["sensor"]["medium"] = media[camera_medium]
    for mesh_index, mesh in enumerate(scene.meshes):
        if mesh.instances is not None or mesh.motion is not None or mesh.vertex_motion is not None:
            raise Unsupported(f"mesh '{mesh.name}': instances and motion are not translated")
        for material_id in np.unique(mesh.material_ids):
            material = scene.materials[int(material_id)]
            triangles = mesh.triangles[mesh.material_ids == material_id]
            used, remapped = np.unique(triangles, return_inverse=True)
            path = folder / f"mesh_{mesh_index}_{int(material_id)}.ply"
            _write_ply(path, mesh.vertices[used], remapped.reshape(-1, 3))
            shape = {"type": "ply", "filename": str(path), "face_normals": True, "bsdf": _bsdf(material)}
            shape.update(_interface(media, _medium_at(scene, mesh.vertices[used].mean(axis=0), mesh_index)))
            if material.medium >= 0:
                shape["interior"] = media[material.medium]
            result[f"mesh_{mesh_index}_{int(material_id)}"] = shape
            if material.surface != "null" and np.any(np.asarray(material.emission) > 0):
                shape["emitter"] = {"type": "area", "radiance": _rgb(material.emission)}
                if material.two_sided_emission:  # Mitsuba's area emitters are one-sided: a flipped copy
                    back = folder / f"mesh_{mesh_index}_{int(material_id)}_back.ply"
                    _write_ply(back, *_behind(mesh.vertices[used], remapped.reshape(-1, 3)))
                    result[f"mesh_{mesh_index}_{int(material_id)}_back"] = dict(
                        shape, filename=str(back), bsdf={"type": "null"})
    result.update(_lights(scene, media))
    return result


@dataclass
class MitsubaRun:
    image: np.ndarray   # (H, W, 3) float32, scene-linear
    samples: int
    render_seconds: float


def render_equal_time(scene, seconds: float, reference_spp: int, seed: int = 1, calibration_spp: int = 8):
    """(equal-time run, reference run) of a VolPath scene rendered by Mitsuba in a child process:
    Mitsuba's LLVM backend and numba's llvmlite cannot share one process (instruction selection
    fails with its llvm variant). Only the renders are timed (scene load and JIT compile excluded, as Cycles' time limit
    leaves out its sync and VolPath's timing its kernel warm-up); the equal-time sample count comes
    from a short timed calibration render."""
    with tempfile.TemporaryDirectory(prefix="volpath_mitsuba_") as folder:
        folder = Path(folder)
        description = scene_dict(scene, folder)
        (folder / "scene.json").write_text(json.dumps(
            dict(scene=description, seconds=seconds, reference_spp=reference_spp, seed=seed,
                 calibration_spp=calibration_spp)))
        proc = subprocess.run([sys.executable, __file__, str(folder)], capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"Mitsuba failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
        with np.load(folder / "result.npz") as result:
            runs = [MitsubaRun(result[f"{k}_image"], int(result[f"{k}_spp"]), float(result[f"{k}_seconds"]))
                    for k in ("run", "reference")]
    return runs[0], runs[1]


def _child(folder: Path) -> None:
    import mitsuba as mi

    mi.set_variant(VARIANT)
    job = json.loads((folder / "scene.json").read_text())

    def objects(value):
        if isinstance(value, dict):
            if "__transform__" in value:
                return mi.ScalarTransform4f(value["__transform__"])
            return {k: objects(v) for k, v in value.items()}
        return value

    scene = mi.load_dict(objects(job["scene"]))

    def render(spp, seed):
        start = time.perf_counter()
        image = np.array(mi.render(scene, spp=int(spp), seed=int(seed)), dtype=np.float32)[..., :3]
        return image, time.perf_counter() - start

    render(1, 0)  # JIT compile
    _, probe_seconds = render(job["calibration_spp"], job["seed"] + 7919)
    spp = max(1, int(job["seconds"] * job["calibration_spp"] / max(probe_seconds, 1e-6)))
    run_image, run_seconds = render(spp, job["seed"])
    reference_image, reference_seconds = render(job["reference_spp"], job["seed"] + 1000)
    np.savez(folder / "result.npz", run_image=run_image, run_spp=spp, run_seconds=run_seconds,
             reference_image=reference_image, reference_spp=job["reference_spp"],
             reference_seconds=reference_seconds)


if __name__ == "__main__":
    _child(Path(sys.argv[1]))
