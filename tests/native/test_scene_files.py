"""Malformed .vpscene files: one schema check names the file and the field before anything is
built, and `python -m volpath_native render` answers with one line and an exit code, never a
traceback."""
from __future__ import annotations

import io
import json
import subprocess
import sys
import zipfile

import numpy as np
import pytest

from volpath_native import (AreaLight, Camera, Film, Material, Medium, PointLight, RenderSettings, Scene,
                            SceneError, SunLight, World, load_scene, save_scene)
from volpath_native.grid_medium import GridMedium

from native_helpers import box_mesh, camera_at


def valid_scene() -> Scene:
    grid = GridMedium("cloud", np.ones((3, 3, 3), np.float32), np.eye(4), 0.5, 0.1)
    return Scene(camera=Camera(camera_at([0, 0, 4])), film=Film(8, 6),
                 meshes=[box_mesh("box", [-1, -1, -1], [1, 1, 1], material=0),
                         box_mesh("fog", [-2, -2, -2], [2, 2, 2], material=1), grid.boundary_mesh(2)],
                 materials=[Material("diffuse", base_color=0.5), Material("fog", surface="null", medium=0),
                            Material("bounds", surface="null", medium=1)],
                 media=[Medium("m", 0.2, 0.1), grid],
                 lights=[PointLight("p", [0, 0, 2.5], power=100.0), SunLight("s", [0, 0, -1], 1.0),
                         AreaLight("a", [0, 2, 0], [1, 0, 0], [0, 0, 1], 5.0)],
                 world=World(background=0.1), settings=RenderSettings(samples=1, threads=1))


def read_archive(path) -> tuple[dict, dict]:
    """(header, {name: array}) of a .vpscene."""
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    return json.loads(bytes(arrays.pop("scene.json")).decode()), arrays


def write_archive(path, header, arrays):
    with open(path, "wb") as f:
        np.savez(f, **{"scene.json": np.frombuffer(json.dumps(header).encode(), np.uint8)}, **arrays)
    return path


@pytest.fixture(scope="module")
def valid(tmp_path_factory):
    path = save_scene(valid_scene(), tmp_path_factory.mktemp("valid") / "scene.vpscene")
    return path, read_archive(path)


def mutated(tmp_path, valid, edit, name="scene.vpscene"):
    header, arrays = json.loads(json.dumps(valid[1][0])), dict(valid[1][1])
    edit(header, arrays)
    return write_archive(tmp_path / name, header, arrays)


def _set(path, value):
    def edit(header, arrays):
        node = header
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = value
    return edit


# (edit, expected message fragment): each names the field it breaks.
MALFORMED = {
    "unknown light type": (_set(["lights", 0, "type"], "laser"), "lights[0].type: unknown light type 'laser'"),
    "missing camera": (lambda h, a: h.pop("camera"), "camera: missing"),
    "string for int": (_set(["film", "width"], "640"), "film.width: expected an integer, got '640'"),
    "unknown field": (_set(["materials", 0, "glossiness"], 0.3), "materials[0].glossiness: unknown field"),
    "huge film": (lambda h, a: (_set(["film", "width"], 10 ** 6)(h, a), _set(["film", "height"], 10 ** 6)(h, a)),
                  "film: 1000000x1000000 pixels need"),
    "medium index": (_set(["materials", 1, "medium"], 7), "materials[1].medium: index 7 out of range (2 media)"),
    "world medium index": (_set(["world", "medium"], -3), "world.medium: index -3 out of range"),
    "nan colour": (_set(["materials", 0, "base_color"], [0.5, float("nan"), 0.5]), "materials[0].base_color: non-finite"),
    "short vector": (_set(["lights", 0, "position"], [0, 1]), "lights[0].position: expected a 3-vector"),
    "bool for number": (_set(["camera", "fov"], True), "camera.fov: expected a number, got True"),
    "bad matrix": (_set(["camera", "camera_to_world"], [[1, 0, 0]]), "camera.camera_to_world: expected a 4x4 matrix"),
    "unknown filter": (_set(["film", "filter"], "mitchell"), "film.filter: unknown value 'mitchell'"),
    "negative samples": (_set(["settings", "samples"], -4), "settings.samples: -4 is outside [1, inf]"),
    "huge batch": (_set(["settings", "batch_size"], 10 ** 12), "settings.batch_size: 1000000000000 is outside"),
    "newer version": (_set(["version"], 99), "version: scene format version 99 is newer"),
    "lights not a list": (_set(["lights"], {"type": "point"}), "lights: expected a list"),
    "grid without density": (lambda h, a: a.pop("medium1.density"), "media[1].density: array 'medium1.density' is missing"),
    "triangle index": (lambda h, a: a.__setitem__("mesh0.triangles", a["mesh0.triangles"] + 100),
                       "meshes[0].triangles: vertex index"),
    "material id": (lambda h, a: a.__setitem__("mesh0.material_ids", a["mesh0.material_ids"] + 9),
                    "meshes[0].material_ids: material index 9 out of range (3 materials)"),
    "float triangles": (lambda h, a: a.__setitem__("mesh1.triangles", a["mesh1.triangles"].astype(np.float32)),
                        "meshes[1].triangles: array 'mesh1.triangles' has dtype float32, expected integers"),
    "vertex shape": (lambda h, a: a.__setitem__("mesh0.vertices", np.zeros((8, 2), np.float32)),
                     "meshes[0].vertices: array 'mesh0.vertices' has shape (8, 2)"),
    "missing mesh array": (lambda h, a: a.pop("mesh2.material_ids"), "meshes[2].material_ids: array 'mesh2.material_ids' is missing"),
    "light without type": (lambda h, a: h["lights"][0].pop("type"), "lights[0].type: missing"),
    # found by the fuzz suite: an unhashable type value raised TypeError
    "light type a list": (_set(["lights", 1, "type"], [1, 2]), "lights[1].type: unknown light type [1, 2]"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_file_names_the_field(tmp_path, valid, case):
    edit, expected = MALFORMED[case]
    path = mutated(tmp_path, valid, edit)
    with pytest.raises(SceneError) as error:
        load_scene(path)
    assert str(error.value).startswith(f"{path}: ") and expected in str(error.value), str(error.value)


def test_valid_file_round_trips_and_planted_mutations_differ(tmp_path, valid):
    scene = load_scene(valid[0])  # the unmodified file passes the schema
    assert len(scene.lights) == 3 and not scene.media[1].is_homogeneous
    # the mutation helper does change what it is asked to (else every case above could pass vacuously)
    path = mutated(tmp_path, valid, _set(["film", "width"], 9))
    assert load_scene(path).film.width == 9


def test_truncated_and_garbage_files(tmp_path, valid):
    data = valid[0].read_bytes()
    for cut in (len(data) // 3, len(data) - 40, 10, 0):
        path = tmp_path / f"cut{cut}.vpscene"
        path.write_bytes(data[:cut])
        with pytest.raises(SceneError, match=f"^{path}: "):
            load_scene(path)
    # found by the fuzz suite: a flipped byte naming an unknown compression method
    flips = []
    for position in (0.8984375, 0.5546875):  # also one in a .npy header's text (TokenError)
        flipped = bytearray(data)
        flipped[int(position * (len(data) - 1))] ^= 1
        flips.append(bytes(flipped))
    header_text = bytearray(data)
    at = header_text.find(b"{'descr'")
    header_text[at + 3] = ord("(")  # an unbalanced bracket in the first array's header
    for k, damaged in enumerate(flips + [bytes(header_text)] + [_with_method(data, m) for m in (99, 1)]):
        path = tmp_path / f"damaged{k}.vpscene"
        path.write_bytes(damaged)
        try:
            load_scene(path)
        except SceneError as error:
            assert str(error).startswith(f"{path}: ")
    path = tmp_path / "text.vpscene"
    path.write_text("not a scene")
    with pytest.raises(SceneError, match="not a readable VolPath scene"):
        load_scene(path)


def _with_method(archive: bytes, method: int) -> bytes:
    """The archive with every member's compression method set to `method` (99: unknown, 1: shrunk)."""
    data = bytearray(archive)
    for signature, offset in ((b"PK\x03\x04", 8), (b"PK\x01\x02", 10)):
        start = 0
        while (start := data.find(signature, start)) >= 0:
            data[start + offset:start + offset + 2] = method.to_bytes(2, "little")
            start += 4
    return bytes(data)


def test_an_array_claiming_more_than_the_file_holds_is_refused_before_reading(tmp_path, valid):
    """A .npy header can claim any shape: the check compares it with the bytes the archive holds,
    so nothing is allocated from it."""
    path = valid[0]
    out = tmp_path / "liar.vpscene"
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(out, "w") as dst:
        for info in src.infolist():
            payload = src.read(info)
            if info.filename == "mesh0.vertices.npy":
                payload = _claim_shape(payload, (10 ** 12, 3))
            dst.writestr(info, payload)
    with pytest.raises(SceneError, match=r"mesh0.vertices' claims shape \(1000000000000, 3\)"):
        load_scene(out)


def _claim_shape(npy: bytes, shape) -> bytes:
    """The same .npy payload with its header's shape replaced (header length kept)."""
    buffer = io.BytesIO(npy)
    version = np.lib.format.read_magic(buffer)
    _, fortran, dtype = np.lib.format.read_array_header_1_0(buffer) if version == (1, 0) else \
        np.lib.format.read_array_header_2_0(buffer)
    data = npy[buffer.tell():]
    out = io.BytesIO()
    np.lib.format.write_array_header_1_0(out, {"descr": np.lib.format.dtype_to_descr(dtype),
                                               "fortran_order": fortran, "shape": shape})
    return out.getvalue() + data


def test_pickled_arrays_are_refused(tmp_path, valid):
    header, arrays = valid[1]
    arrays = dict(arrays, **{"mesh0.vertices": np.array([object()] * 3, dtype=object)})
    path = tmp_path / "pickle.vpscene"
    with open(path, "wb") as f:
        np.savez(f, **{"scene.json": np.frombuffer(json.dumps(header).encode(), np.uint8)}, **arrays)
    with pytest.raises(SceneError, match="Python objects"):
        load_scene(path)


CLI_CASES = ["unknown light type", "missing camera", "string for int", "unknown field", "huge film",
             "triangle index"]


def test_cli_answers_malformed_files_with_one_line(tmp_path, valid):
    """The six files that once ended in tracebacks, plus a truncated one and a missing one: one
    line on stderr naming the file, exit code 2."""
    paths = [mutated(tmp_path, valid, MALFORMED[c][0], f"{i}.vpscene") for i, c in enumerate(CLI_CASES)]
    truncated = tmp_path / "truncated.vpscene"
    truncated.write_bytes(valid[0].read_bytes()[:200])
    paths += [truncated, tmp_path / "missing.vpscene"]
    for path in paths:
        run = subprocess.run([sys.executable, "-m", "volpath_native", "render", str(path), "-o",
                              str(tmp_path / "out.exr"), "--quiet"], capture_output=True, text=True, timeout=120)
        lines = run.stderr.strip().splitlines()
        assert run.returncode == 2 and len(lines) == 1 and str(path) in lines[0], (path, run.stderr)
        assert "Traceback" not in run.stderr and lines[0].startswith("error: ")
