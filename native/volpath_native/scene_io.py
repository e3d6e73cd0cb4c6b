"""Saved-scene format (`.vpscene`): lets the renderer run without Blender.

A `.vpscene` file is a numpy `.npz` archive (uncompressed zip) holding
- `scene.json`: a UTF-8 JSON document (stored as a uint8 array) with
  `{"format": "volpath-scene", "version": FORMAT_VERSION, "camera": {...}, "film": {...},
  "world": {...}, "settings": {...}, "materials": [...], "media": [...], "lights": [...],
  "meshes": [{"name": ..., "smooth": bool}, ...]}`; every object's fields are exactly the
  dataclass fields of `scene.py` (a material's `surface_nodes` as SurfaceNode.to_record() dicts,
  additive to version 1) (RGB triples and vectors as JSON lists), and each light carries a
  `"type"`: "point", "spot", "area" or "sun".
- for mesh i: arrays `mesh{i}.vertices` (V,3 float32), `mesh{i}.triangles` (T,3 int32),
  `mesh{i}.material_ids` (T int32) and, when smooth, `mesh{i}.corner_normals` (T,3,3 float32);
  additive to version 1, each with a header flag of its name set true: `mesh{i}.instances`
  (K,3,4 float64), `mesh{i}.motion` (K,S,3,4 float64), `mesh{i}.vertex_motion` (S,V,3 float32),
  `mesh{i}.corner_normal_motion` (S,T,3,3 float32) (scene.Mesh documents them).

Readers reject files whose version is newer than theirs; older versions are upgraded here.
"""
from __future__ import annotations

import dataclasses
import json
import struct
import zipfile
import zlib
from pathlib import Path

import numpy as np

from . import scene as sc
from .scene_schema import LIGHT_TYPES as _LIGHT_TYPES

FORMAT_NAME = "volpath-scene"
FORMAT_VERSION = 1

_LIGHT_NAMES = {cls: name for name, cls in _LIGHT_TYPES.items()}
_PLACEMENT_FLAGS = ("instances", "motion", "vertex_motion", "corner_normal_motion")


def _jsonable(value):
    if isinstance(value, sc.SurfaceNode):
        return _jsonable(value.to_record())
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (tuple, list)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _to_json(obj) -> dict:
    return {f.name: _jsonable(getattr(obj, f.name)) for f in dataclasses.fields(obj)}


def _material_header(index: int, material, arrays: dict) -> dict:
    """A material's fields; its surface program (if any) as a header whose arrays are
    `material{i}.program_code / _init / _tables` (additive to version 1)."""
    header = {f.name: _jsonable(getattr(material, f.name)) for f in dataclasses.fields(material)
              if f.name != "surface_program"}
    if material.surface_program is not None:
        program, program_arrays = material.surface_program.to_record()
        header["surface_program"] = program
        for key, value in program_arrays.items():
            arrays[f"material{index}.program_{key}"] = value
    return header


def _mesh_header(mesh) -> dict:
    header = {"name": mesh.name, "smooth": mesh.corner_normals is not None}
    if mesh.corner_attributes:  # additive to version 1
        header["attributes"] = list(mesh.corner_attributes)
    if mesh.object_frame is not None:
        header["framed"] = True
    for flag, values in _PLACEMENT_ARRAYS(mesh).items():  # additive to version 1
        if values is not None:
            header[flag] = True
    return header


def _PLACEMENT_ARRAYS(mesh) -> dict:
    """Header flag (= array suffix) -> the mesh's instancing / motion array or None."""
    return {"instances": mesh.instances, "motion": mesh.motion, "vertex_motion": mesh.vertex_motion,
            "corner_normal_motion": mesh.corner_normal_motion}


# The camera fields of format 1's first files; the others (depth of field, panoramic, motion
# blur) are additive and written only where they differ from their defaults, so scenes without
# them stay readable by earlier readers.
_FIRST_CAMERA_FIELDS = ("camera_to_world", "projection", "fov", "ortho_scale", "sensor_fit", "shift_x", "shift_y",
                        "clip_start", "clip_end")


def _camera_header(camera) -> dict:
    header = _to_json(camera)
    defaults = _to_json(sc.Camera(np.eye(4)))
    return {k: v for k, v in header.items() if k in _FIRST_CAMERA_FIELDS or v != defaults[k]}


def _medium_header(index: int, medium, arrays: dict) -> dict:
    """Homogeneous media are plain JSON; grid media (type "grid") keep their voxel arrays as
    `medium{i}.<name>` entries (additive to format version 1: older files have none)."""
    if getattr(medium, "is_homogeneous", True):
        header = _to_json(medium)
        if not header.get("phase_lobes"):
            header.pop("phase_lobes", None)  # additive to version 1: single-lobe files stay as before
        return header
    header, grids = medium.to_record()
    for key, value in grids.items():
        arrays[f"medium{index}.{key}"] = value
    return header


def _load_medium(index: int, entry: dict, data) -> object:
    if entry.get("type") == "grid":
        from .grid_medium import GridMedium
        prefix = f"medium{index}."
        grids = {k[len(prefix):]: data[k] for k in data.files if k.startswith(prefix)}
        return GridMedium.from_record(entry, grids)
    if entry.get("type") == "program":
        from .program_medium import ProgramMedium
        prefix = f"medium{index}."
        arrays = {k[len(prefix):]: data[k] for k in data.files if k.startswith(prefix)}
        return ProgramMedium.from_record(entry, arrays)
    return sc.Medium(**entry)


def save_scene(scene: sc.Scene, path) -> Path:
    path = Path(path)
    arrays = {}
    header = {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "camera": _camera_header(scene.camera),
        "film": _to_json(scene.film),
        "world": _to_json(scene.world),
        "settings": _to_json(scene.settings),
        "materials": [_material_header(i, m, arrays) for i, m in enumerate(scene.materials)],
        "media": [_medium_header(i, m, arrays) for i, m in enumerate(scene.media)],
        "lights": [dict(_to_json(light), type=_LIGHT_NAMES[type(light)]) for light in scene.lights],
        "meshes": [_mesh_header(m) for m in scene.meshes],
    }
    if scene.images:  # additive to version 1: files without images have no section
        header["images"] = [{"name": im.name, "compress_as_srgb": im.compress_as_srgb} for im in scene.images]
        for i, image in enumerate(scene.images):
            arrays[f"image{i}.pixels"] = image.pixels
    arrays["scene.json"] = np.frombuffer(json.dumps(header).encode("utf-8"), dtype=np.uint8)
    for i, mesh in enumerate(scene.meshes):
        arrays[f"mesh{i}.vertices"] = mesh.vertices
        arrays[f"mesh{i}.triangles"] = mesh.triangles
        arrays[f"mesh{i}.material_ids"] = mesh.material_ids
        if mesh.corner_normals is not None:
            arrays[f"mesh{i}.corner_normals"] = mesh.corner_normals
        for k, values in enumerate(mesh.corner_attributes.values()):
            arrays[f"mesh{i}.attribute{k}"] = values
        if mesh.object_frame is not None:
            arrays[f"mesh{i}.object_frame"] = mesh.object_frame
        for flag, values in _PLACEMENT_ARRAYS(mesh).items():
            if values is not None:
                arrays[f"mesh{i}.{flag}"] = values
    with open(path, "wb") as f:  # a file object keeps numpy from appending ".npz"
        np.savez(f, **arrays)
    return path


def load_scene(path) -> sc.Scene:
    """Read a .vpscene file. Every problem with it -- not a zip archive, truncated, malformed JSON,
    a field of the wrong type, an unknown field, an index out of range, an array whose claimed size
    the file does not hold -- raises SceneError naming the file and the field (scene_schema), before
    anything is built. OSError if the file cannot be opened."""
    from . import scene_schema

    path = Path(path)
    where = str(path)
    with open(path, "rb") as stream:  # OSError (missing, unreadable) passes through
        try:
            members = _array_headers(stream, where)
        except sc.SceneError:
            raise
        except _DAMAGED as error:
            raise sc.SceneError(f"{where}: not a readable VolPath scene (truncated or not a .vpscene "
                                f"archive: {error})") from None
    if "scene.json" not in members:
        raise sc.SceneError(f"{where}: not a VolPath scene (no scene.json)")
    try:
        with np.load(path, allow_pickle=False) as data:
            raw = data["scene.json"]
            if raw.dtype != np.uint8 or raw.ndim != 1:
                raise sc.SceneError(f"{where}: scene.json: expected a uint8 byte array")
            try:
                header = json.loads(bytes(raw).decode("utf-8"))
            except (UnicodeDecodeError, json.JSONDecodeError) as error:
                raise sc.SceneError(f"{where}: scene.json: not valid JSON ({error})") from None
            scene_schema.check_header(header, members, where)
            scene_schema.check_arrays(header, data, where)
            return _build(header, data, where)
    except sc.SceneError:
        raise
    except _DAMAGED as error:
        raise sc.SceneError(f"{where}: damaged archive ({type(error).__name__}: {error})") from None


# What zipfile, zlib and numpy raise on damaged bytes (a flipped byte may name an unknown
# compression method -- NotImplementedError -- or an encrypted member -- RuntimeError).
_DAMAGED = (zipfile.BadZipFile, EOFError, ValueError, OSError, KeyError, struct.error, zlib.error,
            NotImplementedError, RuntimeError, OverflowError)


def _array_headers(stream, where: str) -> dict:
    """{array name: (shape, dtype, bytes)} from the archive's .npy headers, without reading any
    array data; an array claiming more bytes than its archive member holds is refused."""
    from .scene_schema import MAX_HEADER_BYTES

    members = {}
    with zipfile.ZipFile(stream) as archive:
        for info in archive.infolist():
            if not info.filename.endswith(".npy"):
                continue
            name = info.filename[:-4]
            with archive.open(info) as member:
                shape, dtype = _npy_header(member, where, name)
                offset = member.tell()
            if dtype.hasobject:
                raise sc.SceneError(f"{where}: array '{name}' holds Python objects (refused: files stay pickle-free)")
            nbytes = int(np.prod(shape, dtype=object)) * dtype.itemsize
            if nbytes > info.file_size - offset:
                raise sc.SceneError(f"{where}: array '{name}' claims shape {shape} ({nbytes} bytes) but the file holds "
                                    f"{max(info.file_size - offset, 0)} bytes for it (truncated or damaged)")
            if name == "scene.json" and nbytes > MAX_HEADER_BYTES:
                raise sc.SceneError(f"{where}: scene.json is {nbytes} bytes, more than {MAX_HEADER_BYTES}")
            members[name] = (shape, dtype, nbytes)
    return members


def _npy_header(member, where: str, name: str):
    """(shape, dtype) of one .npy member, read without its data. numpy parses the header text with
    Python's tokenizer and ast, whose errors on damaged bytes (TokenError, SyntaxError, ...) are not
    a documented set: any of them is a damaged file."""
    try:
        version = np.lib.format.read_magic(member)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(member)
        elif version in ((2, 0), (3, 0)):
            shape, _, dtype = np.lib.format.read_array_header_2_0(member)
        else:
            raise sc.SceneError(f"{where}: array '{name}': unsupported .npy version {version}")
    except sc.SceneError:
        raise
    except Exception as error:  # noqa: BLE001 - see the docstring
        raise sc.SceneError(f"{where}: array '{name}': damaged .npy header ({type(error).__name__})") from None
    return shape, dtype


def _build(header: dict, data, where: str) -> sc.Scene:
    """The Scene of a checked header and archive (SceneError from the constructors named by file)."""
    try:
        media = [_load_medium(i, m, data) for i, m in enumerate(header["media"])]
        meshes = []
        for i, info in enumerate(header["meshes"]):
            meshes.append(sc.Mesh(
                name=info["name"],
                vertices=data[f"mesh{i}.vertices"],
                triangles=data[f"mesh{i}.triangles"],
                material_ids=data[f"mesh{i}.material_ids"],
                corner_normals=data[f"mesh{i}.corner_normals"] if info.get("smooth") else None,
                corner_attributes={name: data[f"mesh{i}.attribute{k}"]
                                   for k, name in enumerate(info.get("attributes", []))},
                object_frame=data[f"mesh{i}.object_frame"] if info.get("framed") else None,
                **{flag: data[f"mesh{i}.{flag}"] for flag in _PLACEMENT_FLAGS if info.get(flag)},
            ))
        from .shading.images import Image
        from .surface_programs import SurfaceProgram
        images = [Image(entry["name"], data[f"image{i}.pixels"], bool(entry.get("compress_as_srgb", False)))
                  for i, entry in enumerate(header.get("images", []))]
        materials = []
        for i, entry in enumerate(header["materials"]):
            entry = dict(entry)
            program = entry.pop("surface_program", None)
            if program is not None:
                arrays = {key: data[f"material{i}.program_{key}"] for key in ("code", "init", "tables")}
                entry["surface_program"] = SurfaceProgram.from_record(program, arrays)
            materials.append(sc.Material(**entry))
        film = dict(header["film"])
        if film.get("crop") is not None:
            film["crop"] = tuple(film["crop"])
        lights = []
        for entry in header["lights"]:
            entry = dict(entry)
            lights.append(_LIGHT_TYPES[entry.pop("type")](**entry))
        return sc.Scene(
            camera=sc.Camera(**header["camera"]),
            film=sc.Film(**film),
            meshes=meshes,
            materials=materials,
            media=media,
            lights=lights,
            world=sc.World(**header.get("world", {})),
            settings=sc.RenderSettings(**header.get("settings", {})),
            images=images,
        )
    except sc.SceneError as error:
        raise sc.SceneError(f"{where}: {error}") from None
