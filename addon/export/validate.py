"""Invalid input the exporter meets, each named (datablock and field) with the fallback it takes.

The exporter calls these at its edges; each either returns the sanitised value and warns, or
raises volpath_native.SceneError when there is no sensible fallback (a broken camera):
- a non-finite socket value (NaN -> 0, +-inf -> +-FLT_MAX: Blender itself stores an inf typed into a
  field as FLT_MAX) -- `finite_socket_value`, called by shading.NodeReader for every input it reads;
- an object whose transform is not finite (skipped) -- `finite_transform`;
- mesh vertices that are not finite (their triangles dropped) -- `finite_mesh`;
- a light whose numbers make no usable light (skipped) -- `checked_light`;
- a negative world background (black where negative, as Cycles renders it) -- `world_background`;
- a mesh that bounds a volume but is open (its volume dropped) -- `close_volume_boundaries`;
- a Volume object's Principled Volume inputs that are not finite -- `volume_material_problems`;
- a camera with non-finite numbers (SceneError naming the camera and field) -- `check_camera`.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

import volpath_native as vp

from .. import compat

FLT_MAX = float(np.finfo(np.float32).max)


def _describe(value) -> str:
    values = np.atleast_1d(np.asarray(value, dtype=np.float64))
    if np.isnan(values).any():
        return "NaN"
    return "infinite" if np.isinf(values).any() else "largest-float (inf typed in)"


def finite_socket_value(value, warn, socket_name: str):
    """A socket's value with NaN -> 0 and +-inf -> +-FLT_MAX; warn(message) says which and why
    (also for FLT_MAX itself, which is how Blender stores an inf typed into a field)."""
    array = np.asarray(value, dtype=np.float64)
    if np.all(np.isfinite(array)):
        if np.any(np.abs(array) >= FLT_MAX):
            warn(f"input '{socket_name}' is the largest float ({np.round(array, 6).tolist()}, what Blender "
                 "stores for an inf typed in); rendered as that number")
        return value
    warn(f"input '{socket_name}' is {_describe(array)} ({np.round(array, 6).tolist()}); "
         "rendered with NaN as 0 and infinity as the largest float (as Blender stores an inf typed in)")
    clean = np.nan_to_num(array, nan=0.0, posinf=FLT_MAX, neginf=-FLT_MAX)
    return clean if isinstance(value, np.ndarray) else float(clean)


def finite_transform(obj, matrix: np.ndarray, reporter) -> bool:
    """False (and a warning naming the object) when its world matrix is not finite or reaches
    FLT_MAX (where Blender stores an inf typed into Location or Scale)."""
    if np.all(np.abs(matrix) < FLT_MAX):
        return True
    fields = [name for name in ("location", "rotation_euler", "scale", "delta_location", "delta_rotation_euler",
                                "delta_scale")
              if hasattr(obj, name) and not all(abs(v) < FLT_MAX for v in getattr(obj, name))]
    where = f" (non-finite {', '.join(fields)})" if fields else " (from a parent, constraint or driver)"
    reporter.warn(f"object '{obj.name}': its transform (matrix_world) has {_describe(matrix)} values{where}; "
                  "the object is not rendered")
    return False


def finite_mesh(mesh: vp.Mesh, object_name: str, reporter):
    """The mesh without triangles that touch non-finite vertices (None if none are left)."""
    bad_vertex = ~np.isfinite(mesh.vertices).all(axis=1)
    if not bad_vertex.any():
        return mesh
    bad = bad_vertex[mesh.triangles].any(axis=1)
    reporter.warn(f"object '{object_name}': {int(bad_vertex.sum())} vertices with non-finite coordinates "
                  f"(modifiers or geometry nodes?); their {int(bad.sum())} triangles are not rendered")
    if bad.all():
        return None
    keep = ~bad
    vertices = mesh.vertices.copy()
    vertices[bad_vertex] = 0.0  # no triangle uses them any more
    return dataclasses.replace(
        mesh, vertices=vertices, triangles=mesh.triangles[keep], material_ids=mesh.material_ids[keep],
        corner_normals=None if mesh.corner_normals is None else mesh.corner_normals[keep],
        corner_attributes={name: values[keep] for name, values in mesh.corner_attributes.items()})


def checked_light(export, obj, reporter):
    """export() -> a light, or None with a warning naming the light when its numbers are unusable
    (e.g. a power that overflows to infinity, a non-finite size or angle)."""
    try:
        light = export()
    except vp.SceneError as error:
        text = str(error)
        reporter.warn(f"{text if text.startswith(f'light {obj.name!r}') else f'light {obj.name!r}: {text}'}; "
                      "the light is not rendered")
        return None
    if light is None:
        return None
    numbers = [value for value in vars(light).values() if isinstance(value, (float, np.ndarray))]
    if not all(np.all(np.isfinite(v)) for v in numbers):
        reporter.warn(f"light '{obj.name}': non-finite size, angle or spot setting; the light is not rendered")
        return None
    power = light.irradiance if isinstance(light, vp.SunLight) else light.power
    if np.any(np.abs(power) >= FLT_MAX):
        # Cycles' float32 strength is inf there, and every contribution of the light is dropped
        reporter.warn(f"light '{obj.name}': power/strength {np.round(power, 6).tolist()} is beyond float32's "
                      "range (Strength x colour x 2^exposure); the light is not rendered (as in Cycles, where it "
                      "overflows)")
        return None
    if np.any(power < 0):
        # Cycles renders no light from a negative strength (measured with Blender 5.0.1 Cycles).
        reporter.warn(f"light '{obj.name}': negative power/strength {np.round(power, 6).tolist()}; "
                      "rendered as 0 where negative (as Cycles)")
        power = np.maximum(power, 0.0)
        if isinstance(light, vp.SunLight):
            light.irradiance = power
        else:
            light.power = power
    try:
        vp.scene.validate_light(light)  # e.g. a zero-size area light: no light, as in Cycles
    except vp.SceneError as error:
        reporter.warn(f"{error}; the light is not rendered")
        return None
    return light


def world_background(world: vp.World, datablock, reporter) -> vp.World:
    """Negative background radiance (a negative Strength or colour) is clamped to 0 with a warning:
    Blender 5.0.1's Cycles renders such a background black (measured)."""
    if np.any(world.background < 0):
        name = datablock.name_full if datablock is not None else "world"
        reporter.warn(f"world '{name}': Background Color x Strength is negative "
                      f"({np.round(world.background, 6).tolist()}); rendered black where negative (as Cycles)")
        world.background = np.maximum(world.background, 0.0)
    return world


def close_volume_boundaries(meshes: list, materials: list, reporter) -> None:
    """Meshes whose faces bound a medium but that do not close it (open edges after welding) would
    let rays enter the medium and never leave: those faces get a copy of their material without
    the medium (the volume is not rendered; the surface is), with a warning naming the object and
    material. In place. (Cycles renders such a mesh with whatever its volume stack makes of it.)"""
    without_medium: dict = {}  # material index -> index of its copy with medium -1
    has_medium = np.array([material.medium >= 0 for material in materials], dtype=bool)
    for mesh in meshes:
        if not len(mesh.triangles) or not len(has_medium):
            continue
        medium_faces = has_medium[mesh.material_ids]
        if not medium_faces.any():
            continue
        open_edges = mesh.open_edge_count(medium_faces)  # coincident vertices merged
        if not open_edges:
            continue
        names = sorted({materials[i].name for i in mesh.material_ids[medium_faces]})
        reporter.warn(f"object '{mesh.name}': bounds the volume of material {', '.join(repr(n) for n in names)} "
                      f"but is not closed ({open_edges} open edges); rays would enter the volume and never leave, "
                      "so its volume is not rendered")
        ids = mesh.material_ids.copy()
        for index in np.unique(mesh.material_ids[medium_faces]):
            if index not in without_medium:
                source = materials[index]
                copy = vp.Material(name=f"{source.name} (no volume)", surface=source.surface,
                                   base_color=source.base_color, emission=source.emission,
                                   two_sided_emission=source.two_sided_emission, medium=-1)
                materials.append(copy)
                without_medium[index] = len(materials) - 1
            ids[mesh.material_ids == index] = without_medium[index]
        mesh.material_ids = ids


def volume_material_problems(material) -> tuple:
    """(problems, notes): "node 'N' input 'I' is NaN" for every non-finite input of the nodes
    feeding the material's active Volume output, and "... is the largest float" for FLT_MAX
    (Volume objects read these sockets themselves, outside NodeReader)."""
    from .. import compat

    tree = compat.material_node_tree(material)
    output = tree.get_output_node("CYCLES") if tree is not None else None
    if output is None:
        return [], []
    problems, notes, seen = [], [], set()
    pending = [link.from_node for link in output.inputs["Volume"].links]
    while pending:
        node = pending.pop()
        if node.name in seen:
            continue
        seen.add(node.name)
        for socket in node.inputs:
            pending += [link.from_node for link in socket.links]
            value = getattr(socket, "default_value", None)
            if value is None or isinstance(value, str):
                continue
            try:
                array = np.asarray(value[:] if hasattr(value, "__len__") else value, dtype=np.float64)
            except (TypeError, ValueError):
                continue
            if not np.all(np.isfinite(array)):
                problems.append(f"node '{node.name}' input '{socket.name}' is {_describe(array)}")
            elif np.any(np.abs(array) >= FLT_MAX):
                notes.append(f"node '{node.name}' input '{socket.name}' is the largest float (what Blender "
                             "stores for an inf typed in)")
    return problems, notes


def check_camera(camera_object) -> None:
    """SceneError naming the camera and the field when a number the camera needs is not finite."""
    name = camera_object.name
    matrix = np.array(camera_object.matrix_world, dtype=np.float64)
    if not np.all(np.isfinite(matrix)):
        raise vp.SceneError(f"camera '{name}': its transform (matrix_world) has {_describe(matrix)} values")
    cam = camera_object.data
    for field in ("lens", "sensor_width", "sensor_height", "ortho_scale", "shift_x", "shift_y", "clip_start",
                  "clip_end"):
        value = float(getattr(cam, field))
        if not math.isfinite(value):
            raise vp.SceneError(f"camera '{name}': {field} is {_describe(value)}")
    lens = {f: getattr(cam.dof, f) for f in ("aperture_fstop", "focus_distance", "aperture_rotation", "aperture_ratio")}
    pano = {f: compat.camera_panorama(cam, f) for f in (
        "fisheye_fov", "fisheye_lens", "latitude_min", "latitude_max", "longitude_min", "longitude_max",
        "central_cylindrical_range_u_min", "central_cylindrical_range_u_max", "central_cylindrical_range_v_min",
        "central_cylindrical_range_v_max", "central_cylindrical_radius")}
    for field, value in {**lens, **pano}.items():
        if not math.isfinite(float(value)):
            raise vp.SceneError(f"camera '{name}': {field} is {_describe(float(value))}")


# Memory a triangle takes from export to render (world-space mesh arrays, the Accelerator's
# per-triangle tables, Embree's BVH), measured with tests/benchmarks/bench_scene_load.py: peak
# resident memory of a 1M-triangle smooth mesh render over its triangle count (415), rounded up.
BYTES_PER_TRIANGLE = 450


def available_memory() -> int | None:
    """Bytes of memory the system can still give this process (Linux MemAvailable), or None."""
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError):
        pass
    return None


class MemoryBudget:
    """Stops an export whose triangles would need more memory than is available, before it
    allocates it (Blender would be killed by the system): SceneError naming the objects with the
    most triangles. Checked as each object is placed in the world."""

    def __init__(self, available: int | None = None):
        self.available = available_memory() if available is None else available
        self.triangles = 0
        self.per_object: dict = {}  # object name -> [triangles, instances]

    def add(self, object_name: str, triangles: int) -> None:
        self.triangles += triangles
        entry = self.per_object.setdefault(object_name, [0, 0])
        entry[0] += triangles
        entry[1] += 1
        if self.available is None or self.triangles * BYTES_PER_TRIANGLE <= 0.9 * self.available:
            return
        largest = sorted(self.per_object.items(), key=lambda item: -item[1][0])[:5]
        names = ", ".join(f"'{name}' ({count:,} triangles" + (f" in {copies} instances)" if copies > 1 else ")")
                          for name, (count, copies) in largest)
        raise vp.SceneError(
            f"the scene is too large for the memory available: {self.triangles / 1e6:.1f}M triangles so far "
            f"would need about {self.triangles * BYTES_PER_TRIANGLE / 1e9:.1f} GB, and {self.available / 1e9:.1f} GB "
            f"are free; the largest objects: {names}. Lower their subdivision levels or instance counts")
