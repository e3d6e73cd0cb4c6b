"""The `.vpscene` schema check: everything in a file is checked before anything is built from it.

`check_header(header, arrays, where)` walks the JSON document and the archive's array headers
(shape and dtype only: no array data is read yet) and raises SceneError at the first problem,
named by file and field, e.g. `scene.vpscene: lights[0].type: unknown light type 'laser'`.
`check_arrays(header, data, where)` then checks the loaded arrays' contents (index ranges, finite
coordinates). Sizes are checked before they are used: the film against this machine's memory, every
array against the bytes the archive really holds for it (a header may claim any shape).

The fields of each object are the dataclass fields of scene.py (so a field added there is accepted
here); the kind of value each holds comes from the table below or, for fields with a default, from
the default's type.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import scene as sc
from .bsdfs import nodes as bsdf_nodes

LIGHT_TYPES = {"point": sc.PointLight, "spot": sc.SpotLight, "area": sc.AreaLight, "sun": sc.SunLight}

# Kinds of values: "str", "int", "float", "bool", "rgb" (a number or 3 numbers), "vec3", "matrix4",
# "crop" (null or 4 numbers), "lobes" ([[rgb, g], ...]), "matrices" (a list of matrix4),
# "numbers" (a list of finite numbers), "list", "any".
_KINDS = {
    ("Camera", "camera_to_world"): "matrix4", ("Camera", "motion_transforms"): "matrices",
    ("Camera", "shutter_curve"): "numbers",
    ("Film", "width"): "int", ("Film", "height"): "int", ("Film", "crop"): "crop",
    ("Medium", "sigma_s"): "rgb", ("Medium", "sigma_a"): "rgb", ("Medium", "phase_lobes"): "lobes",
    ("PointLight", "position"): "vec3", ("PointLight", "power"): "rgb",
    ("SpotLight", "direction"): "vec3",
    ("AreaLight", "position"): "vec3", ("AreaLight", "axis_u"): "vec3", ("AreaLight", "axis_v"): "vec3",
    ("AreaLight", "power"): "rgb",
    ("SunLight", "direction"): "vec3", ("SunLight", "irradiance"): "rgb",
}
# Values some string fields must take.
_CHOICES = {
    ("Camera", "projection"): ("perspective", "orthographic", "panoramic"),
    ("Camera", "panorama_type"): sc.PANORAMA_TYPES,
    ("Camera", "sensor_fit"): ("AUTO", "HORIZONTAL", "VERTICAL"),
    ("Film", "filter"): sc.FILTERS,
    ("AreaLight", "shape"): sc.AREA_SHAPES,
    ("Material", "surface"): sc.SURFACE_KINDS + ("diffuse",),  # 'diffuse': format 1's name of 'shaded'
    ("SurfaceNode", "kind"): bsdf_nodes.KINDS,
    ("SurfaceNode", "distribution"): bsdf_nodes.DISTRIBUTIONS,
    ("SurfaceNode", "fresnel"): bsdf_nodes.FRESNEL_MODES,
    ("RenderSettings", "volume_sampling"): ("mis", "distance", "equiangular"),
    ("RenderSettings", "parallelism"): ("threads", "processes"),
}
# Inclusive ranges of numeric fields.
MAX_BATCH_SIZE = 1 << 24  # the add-on's own limit (addon/properties.py)
_RANGES = {
    ("Film", "width"): (1, None), ("Film", "height"): (1, None),
    ("RenderSettings", "samples"): (1, None), ("RenderSettings", "threads"): (0, 1024),
    ("RenderSettings", "batch_size"): (1, MAX_BATCH_SIZE),
    **{("RenderSettings", f"{kind}_bounces"): (0, 1 << 20)
       for kind in ("max", "diffuse", "glossy", "transmission", "volume", "transparent")},
    ("RenderSettings", "russian_roulette_min_bounces"): (0, 1 << 20),
    ("RenderSettings", "time_limit"): (0.0, None),
    ("Camera", "aperture_blades"): (0, 1 << 16),
}
# The header of a grid medium (grid_medium.GridMedium.to_record): field -> (kind, required).
_GRID_FIELDS = {"type": ("str", True), "name": ("str", True), "sigma_s": ("rgb", True), "sigma_a": ("rgb", True),
                "g": ("float", False), "emission": ("rgb", False), "index_to_world": ("matrix4", True),
                "majorant_resolution": ("int", False), "motion_object_to_world": ("matrix4", False)}
_GRID_ARRAYS = {"density": 3, "scatter_grid": 4, "absorb_grid": 4, "emission_grid": 4}  # name -> ndim
# A shader-program medium (program_medium.ProgramMedium.to_record); its program is checked by
# ShaderProgram.validate when loaded (opcodes and register operands).
_PROGRAM_FIELDS = {"type": ("str", True), "name": ("str", True), "g": ("float", False),
                   "object_to_world": ("matrix4", True), "bounds": ("any", True), "object_to_generated": ("any", True),
                   "majorant_resolution": ("int", False), "program_name": ("str", False),
                   "program_varying": ("bool", False), "program_attributes": ("any", False),
                   "grid_index_to_world": ("matrix4", False), "motion_object_to_world": ("matrix4", False)}
_PROGRAM_ARRAYS = {"program_code": 1, "program_init": 1, "program_tables": 1, "attributes": 4}
_MESH_FIELDS = {"name": ("str", True), "smooth": ("bool", False), "attributes": ("list", False),
                "framed": ("bool", False), "instances": ("bool", False), "motion": ("bool", False),
                "vertex_motion": ("bool", False), "corner_normal_motion": ("bool", False)}
# A material's surface program (surface_programs.SurfaceProgram.to_record): checked by its
# validate() when built; its arrays are material{i}.program_code / _init / _tables.
_SURFACE_PROGRAM_FIELDS = {"name": ("str", False), "varying": ("bool", False), "bindings": ("list", False),
                           "inputs": ("list", False), "normal": ("int", False), "tangent": ("int", False),
                           "emission": ("int", False), "bump_offsets": ("int", False), "shifts": ("list", False),
                           "shading_normal": ("int", False)}
_IMAGE_FIELDS = {"name": ("str", True), "compress_as_srgb": ("bool", False)}
_SECTIONS = ("camera", "film", "world", "settings", "materials", "media", "lights", "meshes", "images")
# Largest JSON document read (bytes): a scene of 10^5 objects is far below it.
MAX_HEADER_BYTES = 64 << 20


def _fail(where: str, path: str, message: str):
    raise sc.SceneError(f"{where}: {path}: {message}" if path else f"{where}: {message}")


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _check_value(v, kind: str, where: str, path: str):
    def numbers(values, count, what):
        if not isinstance(values, list) or len(values) != count or not all(_is_number(x) for x in values):
            _fail(where, path, f"expected {what}, got {_short(v)}")
        if not all(math.isfinite(x) for x in values):
            _fail(where, path, f"non-finite value in {_short(v)}")

    if kind == "any":
        return
    if kind == "str":
        if not isinstance(v, str):
            _fail(where, path, f"expected a string, got {_short(v)}")
    elif kind == "bool":
        if not isinstance(v, bool):
            _fail(where, path, f"expected true or false, got {_short(v)}")
    elif kind == "int":
        if isinstance(v, bool) or not isinstance(v, int):
            _fail(where, path, f"expected an integer, got {_short(v)}")
    elif kind == "float":
        if not _is_number(v):
            _fail(where, path, f"expected a number, got {_short(v)}")
        if not math.isfinite(v):
            _fail(where, path, f"non-finite value {v}")
    elif kind == "rgb":
        if _is_number(v):
            if not math.isfinite(v):
                _fail(where, path, f"non-finite value {v}")
        else:
            numbers(v, 3, "a number or an RGB triple")
    elif kind == "vec3":
        numbers(v, 3, "a 3-vector")
    elif kind == "matrix4":
        if not isinstance(v, list) or len(v) != 4:
            _fail(where, path, f"expected a 4x4 matrix (4 rows of 4 numbers), got {_short(v)}")
        for r, row in enumerate(v):
            _check_value(row, "row4", where, f"{path}[{r}]")
    elif kind == "row4":
        numbers(v, 4, "4 numbers")
    elif kind == "crop":
        if v is not None:
            numbers(v, 4, "null or [xmin, xmax, ymin, ymax]")
    elif kind == "lobes":
        if not isinstance(v, list):
            _fail(where, path, f"expected a list of [sigma_s, g] lobes, got {_short(v)}")
        for k, lobe in enumerate(v):
            if not isinstance(lobe, list) or len(lobe) != 2:
                _fail(where, f"{path}[{k}]", f"expected [sigma_s, g], got {_short(lobe)}")
            _check_value(lobe[0], "rgb", where, f"{path}[{k}][0]")
            _check_value(lobe[1], "float", where, f"{path}[{k}][1]")
    elif kind == "matrices":
        if not isinstance(v, list):
            _fail(where, path, f"expected a list of 4x4 matrices, got {_short(v)}")
        for k, matrix in enumerate(v):
            _check_value(matrix, "matrix4", where, f"{path}[{k}]")
    elif kind == "numbers":
        if not isinstance(v, list):
            _fail(where, path, f"expected a list of numbers, got {_short(v)}")
        numbers(v, len(v), "a list of numbers")
    elif kind == "list":
        if not isinstance(v, list):
            _fail(where, path, f"expected a list, got {_short(v)}")
    else:  # pragma: no cover - a kind missing from this module
        raise AssertionError(kind)


def _short(v) -> str:
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def _default_kind(f: dataclasses.Field) -> str:
    if f.default is not dataclasses.MISSING:
        value = f.default
    elif f.default_factory is not dataclasses.MISSING:
        value = f.default_factory()
    else:
        return "any"
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int):
        return "int"
    if isinstance(value, float):
        return "float"
    if isinstance(value, str):
        return "str"
    if isinstance(value, np.ndarray) and value.shape == (3,):
        return "rgb"
    if isinstance(value, list):
        return "list"
    return "any"


def dataclass_fields(cls) -> dict:
    """field -> (kind, required) for a scene.py dataclass (its subclasses' fields included)."""
    out = {}
    for f in dataclasses.fields(cls):
        owner = next((c.__name__ for c in cls.__mro__ if (c.__name__, f.name) in _KINDS), cls.__name__)
        kind = _KINDS.get((owner, f.name)) or ("str" if f.name == "name" else _default_kind(f))
        required = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        out[f.name] = (kind, required)
    return out


def _check_object(obj, fields: dict, where: str, path: str, cls_name: str = "", ignore=()):
    if not isinstance(obj, dict):
        _fail(where, path, f"expected an object, got {_short(obj)}")
    for key in obj:
        if key not in fields and key not in ignore:
            _fail(where, f"{path}.{key}", f"unknown field (expected one of: {', '.join(fields)})")
    for key, (kind, required) in fields.items():
        if key not in obj:
            if required:
                _fail(where, f"{path}.{key}", "missing")
            continue
        value = obj[key]
        _check_value(value, kind, where, f"{path}.{key}")
        choices = _CHOICES.get((cls_name, key))
        if choices is not None and value not in choices:
            _fail(where, f"{path}.{key}", f"unknown value {value!r} (expected one of: {', '.join(choices)})")
        bounds = _RANGES.get((cls_name, key))
        if bounds is not None:
            lo, hi = bounds
            if (lo is not None and value < lo) or (hi is not None and value > hi):
                _fail(where, f"{path}.{key}", f"{value} is outside [{lo}, {'inf' if hi is None else hi}]")


def _check_list(header: dict, name: str, where: str) -> list:
    items = header[name]
    if not isinstance(items, list):
        _fail(where, name, f"expected a list, got {_short(items)}")
    return items


def check_header(header, arrays: dict, where: str) -> None:
    """Check the JSON document `header` and the archive's arrays {name: (shape, dtype, bytes held)}
    (see module docstring). Raises SceneError naming `where` and the field."""
    from .render import film_memory_problem, physical_memory
    from .scene_io import FORMAT_NAME, FORMAT_VERSION

    if not isinstance(header, dict):
        _fail(where, "", "the scene document is not a JSON object")
    if header.get("format") != FORMAT_NAME:
        _fail(where, "format", f"not a VolPath scene (expected '{FORMAT_NAME}')")
    version = header.get("version")
    if isinstance(version, bool) or not isinstance(version, int):
        _fail(where, "version", f"expected an integer, got {_short(version)}")
    if version > FORMAT_VERSION:
        _fail(where, "version", f"scene format version {version} is newer than this renderer's "
                                f"({FORMAT_VERSION}); update VolPath")
    for key in header:
        if key not in _SECTIONS + ("format", "version"):
            _fail(where, key, "unknown field")
    for key in ("camera", "film"):
        if key not in header:
            _fail(where, key, "missing")
    for key, cls in (("camera", sc.Camera), ("film", sc.Film), ("world", sc.World), ("settings", sc.RenderSettings)):
        if key in header:
            _check_object(header[key], dataclass_fields(cls), where, key, cls.__name__)
    for key in ("materials", "media", "lights", "meshes"):
        header.setdefault(key, [])
    materials, media = _check_list(header, "materials", where), _check_list(header, "media", where)
    lights, meshes = _check_list(header, "lights", where), _check_list(header, "meshes", where)

    # film size before anything is allocated from it
    try:
        problem = film_memory_problem(sc.Film(**header["film"]))
    except sc.SceneError as error:  # e.g. an empty crop region
        problem = str(error)
    if problem:
        _fail(where, "film", problem)

    n_media = len(media)
    for i, m in enumerate(media):
        path = f"media[{i}]"
        if isinstance(m, dict) and m.get("type") == "grid":
            _check_object(m, _GRID_FIELDS, where, path)
            _check_grid_arrays(i, m, arrays, where)
        elif isinstance(m, dict) and m.get("type") == "program":
            _check_object(m, _PROGRAM_FIELDS, where, path)
            for name, ndim in _PROGRAM_ARRAYS.items():
                _require_array(arrays, f"medium{i}.{name}", where, f"{path}.{name}", ndim, None,
                               "iu" if name == "program_code" else "f")
            _check_box(m, where, path)
        else:
            _check_object(m, dataclass_fields(sc.Medium), where, path, "Medium")
    for i, mat in enumerate(materials):
        _check_object(mat, dataclass_fields(sc.Material), where, f"materials[{i}]", "Material")
        for k, node in enumerate(mat.get("surface_nodes", [])):
            _check_object(node, dataclass_fields(bsdf_nodes.SurfaceNode), where, f"materials[{i}].surface_nodes[{k}]",
                          "SurfaceNode")
        program = mat.get("surface_program")
        if program is not None:
            _check_object(program, _SURFACE_PROGRAM_FIELDS, where, f"materials[{i}].surface_program")
            for name in ("code", "init", "tables"):
                _require_array(arrays, f"material{i}.program_{name}", where, f"materials[{i}].surface_program.{name}",
                               1, None, "iu" if name == "code" else "f")
        medium = mat.get("medium", -1)
        if not -1 <= medium < n_media:
            _fail(where, f"materials[{i}].medium", f"index {medium} out of range ({n_media} media)")
    world_medium = header.get("world", {}).get("medium", -1)
    if not -1 <= world_medium < n_media:
        _fail(where, "world.medium", f"index {world_medium} out of range ({n_media} media)")
    for i, light in enumerate(lights):
        path = f"lights[{i}]"
        if not isinstance(light, dict):
            _fail(where, path, f"expected an object, got {_short(light)}")
        kind = light.get("type")
        if not isinstance(kind, str) or kind not in LIGHT_TYPES:
            message = "missing" if kind is None else f"unknown light type {kind!r}"
            _fail(where, f"{path}.type", f"{message} (expected one of: {', '.join(LIGHT_TYPES)})")
        cls = LIGHT_TYPES[kind]
        _check_object(light, dataclass_fields(cls), where, path, cls.__name__, ignore=("type",))
    for i, mesh in enumerate(meshes):
        _check_object(mesh, _MESH_FIELDS, where, f"meshes[{i}]")
        _check_mesh_arrays(i, mesh, arrays, where)
    for i, image in enumerate(_check_list(header, "images", where) if "images" in header else []):
        _check_object(image, _IMAGE_FIELDS, where, f"images[{i}]")
        shape = _require_array(arrays, f"image{i}.pixels", where, f"images[{i}].pixels", 3, None, "fu")
        if shape[2] not in (1, 4) or shape[0] < 1 or shape[1] < 1:
            _fail(where, f"images[{i}].pixels", f"shape {tuple(shape)}: expected (height, width, 1 or 4)")
    claimed = sum(nbytes for _, _, nbytes in arrays.values())
    memory = physical_memory()
    if memory and claimed > memory // 2:
        _fail(where, "", f"its arrays need {claimed / 2 ** 30:.3g} GiB, more than half of this machine's "
                         f"{memory / 2 ** 30:.3g} GiB of memory")


def _require_array(arrays, key, where, path, ndim, trailing=None, kinds="f"):
    if key not in arrays:
        _fail(where, path, f"array '{key}' is missing")
    shape, dtype, _ = arrays[key]
    if dtype.kind not in kinds:
        _fail(where, path, f"array '{key}' has dtype {dtype}, expected {'integers' if kinds == 'iu' else 'floats'}")
    if len(shape) != ndim or (trailing is not None and tuple(shape[1:]) != trailing):
        expected = f"(N, {', '.join(str(t) for t in trailing)})" if trailing else f"{ndim} dimensions"
        _fail(where, path, f"array '{key}' has shape {tuple(shape)}, expected {expected}")
    return shape


def _check_mesh_arrays(i: int, mesh: dict, arrays: dict, where: str):
    path = f"meshes[{i}]"
    _require_array(arrays, f"mesh{i}.vertices", where, f"{path}.vertices", 2, (3,))
    tris = _require_array(arrays, f"mesh{i}.triangles", where, f"{path}.triangles", 2, (3,), "iu")
    ids = _require_array(arrays, f"mesh{i}.material_ids", where, f"{path}.material_ids", 1, None, "iu")
    if ids[0] != tris[0]:
        _fail(where, f"{path}.material_ids", f"{ids[0]} material ids for {tris[0]} triangles")
    if mesh.get("smooth"):
        normals = _require_array(arrays, f"mesh{i}.corner_normals", where, f"{path}.corner_normals", 3, (3, 3))
        if normals[0] != tris[0]:
            _fail(where, f"{path}.corner_normals", f"{normals[0]} rows of corner normals for {tris[0]} triangles")
    for k, name in enumerate(mesh.get("attributes", [])):
        if not isinstance(name, str):
            _fail(where, f"{path}.attributes[{k}]", f"expected a name, got {_short(name)}")
        shape = _require_array(arrays, f"mesh{i}.attribute{k}", where, f"{path}.attributes[{k}]", 3)
        if shape[0] != tris[0] or shape[1] != 3 or not 1 <= shape[2] <= 4:
            _fail(where, f"{path}.attributes[{k}]", f"shape {tuple(shape)}: expected ({tris[0]}, 3, 1..4)")
    if mesh.get("framed"):
        _require_array(arrays, f"mesh{i}.object_frame", where, f"{path}.object_frame", 3, (3, 4))
    _check_placement_arrays(i, mesh, arrays, where, tris[0])


def _check_placement_arrays(i: int, mesh: dict, arrays: dict, where: str, n_tri: int):
    """Instances (K,3,4), motion (K,S,3,4), vertex_motion (S,V,3), corner_normal_motion (S,T,3,3)."""
    path = f"meshes[{i}]"
    instances = motion = steps = None
    if mesh.get("instances"):
        instances = _require_array(arrays, f"mesh{i}.instances", where, f"{path}.instances", 3, (3, 4))
    if mesh.get("motion"):
        if instances is None:
            _fail(where, f"{path}.motion", "motion needs instances")
        motion = _require_array(arrays, f"mesh{i}.motion", where, f"{path}.motion", 4)
        if motion[0] != instances[0] or motion[1] < 2 or tuple(motion[2:]) != (3, 4):
            _fail(where, f"{path}.motion", f"shape {tuple(motion)}: expected ({instances[0]}, S >= 2, 3, 4)")
    if mesh.get("vertex_motion"):
        vertices = arrays[f"mesh{i}.vertices"][0][0]
        shape = _require_array(arrays, f"mesh{i}.vertex_motion", where, f"{path}.vertex_motion", 3)
        if shape[0] < 2 or tuple(shape[1:]) != (vertices, 3):
            _fail(where, f"{path}.vertex_motion", f"shape {tuple(shape)}: expected (S >= 2, {vertices}, 3)")
        steps = shape[0]
    if mesh.get("corner_normal_motion"):
        shape = _require_array(arrays, f"mesh{i}.corner_normal_motion", where, f"{path}.corner_normal_motion", 4)
        if steps is None or tuple(shape) != (steps, n_tri, 3, 3):
            _fail(where, f"{path}.corner_normal_motion",
                  f"shape {tuple(shape)}: expected (S, {n_tri}, 3, 3) with the S steps of vertex_motion")


def _check_box(medium: dict, where: str, path: str):
    try:
        bounds = np.asarray(medium["bounds"], dtype=np.float64)
        generated = np.asarray(medium["object_to_generated"], dtype=np.float64)
    except (TypeError, ValueError):
        _fail(where, path, "bounds / object_to_generated are not numbers")
    if bounds.shape != (2, 3) or not np.all(np.isfinite(bounds)) or np.any(bounds[1] < bounds[0]):
        _fail(where, f"{path}.bounds", "expected [[xmin, ymin, zmin], [xmax, ymax, zmax]]")
    if generated.shape != (3, 4) or not np.all(np.isfinite(generated)):
        _fail(where, f"{path}.object_to_generated", "expected a finite 3x4 matrix")
    resolution = medium.get("majorant_resolution", 24)
    if not 1 <= resolution <= 256:
        _fail(where, f"{path}.majorant_resolution", f"{resolution} is outside [1, 256]")


def _check_grid_arrays(i: int, medium: dict, arrays: dict, where: str):
    path = f"media[{i}]"
    density = _require_array(arrays, f"medium{i}.density", where, f"{path}.density", 3)
    for name, ndim in _GRID_ARRAYS.items():
        key = f"medium{i}.{name}"
        if name == "density" or key not in arrays:
            continue
        shape = _require_array(arrays, key, where, f"{path}.{name}", ndim)
        if tuple(shape) != tuple(density) + (3,):
            _fail(where, f"{path}.{name}", f"array '{key}' has shape {tuple(shape)}, expected {tuple(density) + (3,)}")
    if ("medium%d.scatter_grid" % i in arrays) != ("medium%d.absorb_grid" % i in arrays):
        _fail(where, path, "scatter_grid and absorb_grid go together")
    resolution = medium.get("majorant_resolution", 32)
    if not 1 <= resolution <= 1024:
        _fail(where, f"{path}.majorant_resolution", f"{resolution} is outside [1, 1024]")


def check_arrays(header: dict, data, where: str) -> None:
    """Contents of the loaded arrays: finite vertices, vertex and material indices in range."""
    n_materials = len(header["materials"])
    for i, _ in enumerate(header["meshes"]):
        path = f"meshes[{i}]"
        vertices = data[f"mesh{i}.vertices"]
        if not np.all(np.isfinite(vertices)):
            _fail(where, f"{path}.vertices", "non-finite vertex coordinates")
        tris = data[f"mesh{i}.triangles"]
        if tris.size and (tris.min() < 0 or tris.max() >= len(vertices)):
            _fail(where, f"{path}.triangles", f"vertex index {int(tris.min() if tris.min() < 0 else tris.max())} "
                                              f"out of range ({len(vertices)} vertices)")
        for flag in ("instances", "motion", "vertex_motion", "corner_normal_motion"):
            if f"mesh{i}.{flag}" in data.files and not np.all(np.isfinite(data[f"mesh{i}.{flag}"])):
                _fail(where, f"{path}.{flag}", "non-finite values")
        ids = data[f"mesh{i}.material_ids"]
        if ids.size and (ids.min() < 0 or ids.max() >= n_materials):
            _fail(where, f"{path}.material_ids", f"material index {int(ids.min() if ids.min() < 0 else ids.max())} "
                                                 f"out of range ({n_materials} materials)")
    for i, medium in enumerate(header["media"]):
        if isinstance(medium, dict) and medium.get("type") in ("grid", "program"):
            for name in (_GRID_ARRAYS if medium["type"] == "grid" else ("program_init", "program_tables", "attributes")):
                key = f"medium{i}.{name}"
                if key in data.files and not np.all(np.isfinite(data[key])):
                    _fail(where, f"media[{i}].{name}", "non-finite voxel values")


def check_settings(settings: sc.RenderSettings) -> None:
    """The same checks for a RenderSettings object built in Python (render() calls this): integer
    fields in range, known choices. SceneError names the field."""
    values = {f.name: getattr(settings, f.name) for f in dataclasses.fields(settings)}
    values = {k: (v.item() if isinstance(v, np.generic) else v) for k, v in values.items()}
    _check_object(values, dataclass_fields(sc.RenderSettings), "render settings", "settings", "RenderSettings")
