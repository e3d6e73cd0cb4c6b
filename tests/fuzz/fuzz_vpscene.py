"""Random malformed .vpscene files for the fuzz suite: valid scenes mutated (wrong types, missing and
extra fields, out-of-range indices, arrays of the wrong dtype or shape, arrays claiming more than
the file holds, truncation, flipped bytes). `check` loads each and, if it loads, renders it tiny:
- load_scene either returns a Scene or raises SceneError naming the file; nothing else;
- a loaded scene renders without any other exception, without hanging, with every pixel finite.
"""
from __future__ import annotations

import copy
import io
import json
import math
import time
import warnings
import zipfile
from dataclasses import dataclass, field

import numpy as np
from hypothesis import strategies as st

from volpath_native import (AreaLight, Camera, Film, Material, Medium, PointLight, RenderSettings, Scene,
                            SceneError, SpotLight, SunLight, World, load_scene, save_scene)
from volpath_native.grid_medium import GridMedium
from volpath_native.render import render

from native_helpers import box_mesh, camera_at, icosphere

HANG_SECONDS = 30.0
MAX_RENDERED_PIXELS = 4096  # loaded films larger than this are checked but not rendered


def seed_scenes() -> list:
    """Valid scenes the mutations start from: every light type, both media kinds, smooth normals."""
    grid = GridMedium("cloud", np.random.default_rng(3).random((4, 5, 3)).astype(np.float32),
                      np.diag([0.5, 0.5, 0.5, 1.0]), 0.8, 0.2, emission=0.1)
    sphere = icosphere("ball", 0.5, 1, material=0, centre=(1.0, 0.0, 0.0))
    normals = sphere.vertices[sphere.triangles] - np.array([1.0, 0.0, 0.0])
    sphere.corner_normals = normals / np.linalg.norm(normals, axis=-1, keepdims=True)  # smooth shading
    one = Scene(camera=Camera(camera_at([0, 0, 4])), film=Film(8, 6, crop=(0.0, 1.0, 0.0, 1.0)),
                meshes=[box_mesh("box", [-1, -1, -1], [1, 1, 1], 0), box_mesh("fog", [-2, -2, -2], [2, 2, 2], 1),
                        grid.boundary_mesh(2), sphere],
                materials=[Material("diffuse", base_color=0.5), Material("fog", surface="null", medium=0),
                           Material("bounds", surface="null", medium=1),
                           Material("lamp", base_color=0.0, emission=[4.0, 3.0, 2.0])],
                media=[Medium("m", [0.2, 0.3, 0.4], 0.1, g=0.3, phase_lobes=[([0.1, 0.1, 0.2], 0.5), ([0.1, 0.2, 0.2], -0.2)]),
                       grid],
                lights=[PointLight("p", [0, 0, 2.5], power=100.0, radius=0.1), SunLight("s", [0, 0, -1], 1.0, angle=0.1),
                        AreaLight("a", [0, 2, 0], [1, 0, 0], [0, 0, 1], 5.0, shape="disk"),
                        SpotLight("spot", [0, -2, 1], power=50.0, direction=[0, 1, 0])],
                world=World(background=0.1, medium=-1), settings=RenderSettings(samples=1, threads=1))
    two = Scene(camera=Camera(camera_at([0, 0, 6]), projection="orthographic", ortho_scale=4.0),
                film=Film(7, 7, filter="gaussian"), meshes=[box_mesh("box", [-1, -1, -1], [1, 1, 1], 0)],
                materials=[Material("d", base_color=[0.2, 0.5, 0.8])], media=[Medium("world fog", 0.05, 0.01)],
                lights=[PointLight("p", [0, 0, 3], power=80.0)], world=World(medium=0),
                settings=RenderSettings(samples=1, threads=1, volume_bounces=2))
    # the camera's optional fields: a lens, a panorama, motion steps, a shutter curve
    three = Scene(camera=Camera(camera_at([0, 0, 3]), projection="panoramic", panorama_type="fisheye_equisolid",
                                aperture_size=0.05, focus_distance=2.0, aperture_blades=5, aperture_ratio=1.5,
                                motion_transforms=[camera_at([0, 0, 3]), camera_at([0.2, 0, 3]), camera_at([0.4, 0, 3])],
                                shutter_curve=[0.0, 1.0, 0.5], rolling_shutter=True, name="fisheye"),
                  film=Film(6, 5), meshes=[box_mesh("box", [-1, -1, -1], [1, 1, 1], 0)],
                  materials=[Material("d", base_color=0.5)], lights=[PointLight("p", [0, 0, 2.5], power=50.0)],
                  world=World(background=0.2), settings=RenderSettings(samples=1, threads=1))
    return [one, two, three]


# Values a mutation writes: every JSON type, extremes and near-misses.
JUNK = [None, True, False, 0, -1, 1, 7, 10 ** 6, 10 ** 12, -(10 ** 12), 0.5, -0.5, 1e30, -1e30, math.nan, math.inf,
        "", "laser", "640", "point", [], [1, 2], [0.5, 0.5, 0.5], [[1, 0, 0, 0]] * 4, [math.nan] * 3, {}, {"x": 1},
        [1e308, 1e308, 1e308]]

mutation = st.one_of(
    st.tuples(st.just("json_set"), st.integers(0, 10 ** 6), st.sampled_from(JUNK)),
    st.tuples(st.just("json_delete"), st.integers(0, 10 ** 6)),
    st.tuples(st.just("json_extra"), st.integers(0, 10 ** 6), st.sampled_from(JUNK)),
    st.tuples(st.just("array_delete"), st.integers(0, 10 ** 6)),
    st.tuples(st.just("array_dtype"), st.integers(0, 10 ** 6), st.sampled_from(["float16", "int8", "uint64", "bool", "complex64"])),
    st.tuples(st.just("array_shape"), st.integers(0, 10 ** 6), st.sampled_from([(0,), (1,), (2, 2), (3, 3, 3, 3), (0, 3)])),
    st.tuples(st.just("array_values"), st.integers(0, 10 ** 6), st.sampled_from([-1, 10 ** 6, math.nan, math.inf, 1e30])),
    st.tuples(st.just("array_claim"), st.integers(0, 10 ** 6), st.sampled_from([(10 ** 12, 3), (2 ** 31, 2 ** 31), (10 ** 7,)])),
    st.tuples(st.just("truncate"), st.floats(0.0, 1.0)),
    st.tuples(st.just("flip"), st.floats(0.0, 1.0), st.integers(1, 255)),
)
cases = st.tuples(st.integers(0, 1), st.lists(mutation, min_size=1, max_size=3))


def _nodes(value, path=()):
    """Every (path, container) position in a JSON document, depth first."""
    out = [path]
    if isinstance(value, dict):
        for key, child in value.items():
            out += _nodes(child, path + (key,))
    elif isinstance(value, list):
        for index, child in enumerate(value):
            out += _nodes(child, path + (index,))
    return out


def _parent(doc, path):
    node = doc
    for key in path[:-1]:
        node = node[key]
    return node


def mutate(scene_bytes: bytes, mutations) -> bytes:
    """Apply the mutations to a saved scene (archive-level ones last). numpy's cast warnings are
    what the mutations are for: silenced."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return _mutate(scene_bytes, mutations)


def _mutate(scene_bytes: bytes, mutations) -> bytes:
    with np.load(io.BytesIO(scene_bytes), allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    header = json.loads(bytes(arrays.pop("scene.json")).decode())
    claims = {}
    for m in mutations:
        kind = m[0]
        if kind.startswith("json"):
            paths = [p for p in _nodes(header) if p]
            path = paths[m[1] % len(paths)]
            parent = _parent(header, path)
            value = copy.deepcopy(m[2] if len(m) > 2 else None)  # never share (a list could hold itself)
            if kind == "json_set":
                parent[path[-1]] = value
            elif kind == "json_delete":
                del parent[path[-1]]
            else:
                target = _parent(header, path + ("x",))
                if isinstance(target, dict):
                    target[f"extra{m[1] % 7}"] = value
                elif isinstance(target, list):
                    target.append(value)
        elif kind.startswith("array") and arrays:
            name = sorted(arrays)[m[1] % len(arrays)]
            if kind == "array_delete":
                del arrays[name]
            elif kind == "array_dtype":
                arrays[name] = arrays[name].astype(m[2])
            elif kind == "array_shape":
                arrays[name] = np.zeros(m[2], arrays[name].dtype)
            elif kind == "array_values" and arrays[name].size:
                a = arrays[name].copy()
                try:
                    a.reshape(-1)[m[1] % a.size] = m[2]
                except (OverflowError, ValueError):
                    pass
                arrays[name] = a
            elif kind == "array_claim":
                claims[name] = m[2]
    out = io.BytesIO()
    np.savez(out, **{"scene.json": np.frombuffer(json.dumps(header).encode(), np.uint8)}, **arrays)
    data = out.getvalue()
    if claims:
        data = _claim_shapes(data, claims)
    for m in mutations:
        if m[0] == "truncate":
            data = data[:int(m[1] * len(data))]
        elif m[0] == "flip" and data:
            position = int(m[1] * (len(data) - 1))
            data = data[:position] + bytes([data[position] ^ m[2]]) + data[position + 1:]
    return data


def _claim_shapes(archive: bytes, claims: dict) -> bytes:
    """Rewrite .npy headers so arrays claim shapes their bytes do not hold."""
    out = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(archive)) as src, zipfile.ZipFile(out, "w") as dst:
        for info in src.infolist():
            payload = src.read(info)
            name = info.filename[:-4]
            if name in claims:
                buffer = io.BytesIO(payload)
                np.lib.format.read_magic(buffer)
                _, fortran, dtype = np.lib.format.read_array_header_1_0(buffer)
                head = io.BytesIO()
                np.lib.format.write_array_header_1_0(head, {"descr": np.lib.format.dtype_to_descr(dtype),
                                                            "fortran_order": fortran, "shape": claims[name]})
                payload = head.getvalue() + payload[buffer.tell():]
            dst.writestr(info, payload)
    return out.getvalue()


@dataclass
class Outcome:
    crash: str = ""
    hang: bool = False
    non_finite: bool = False
    unnamed: list = field(default_factory=list)  # errors that do not start with the file's path
    loaded: bool = False
    rendered: bool = False
    error: str = ""

    @property
    def failed(self) -> bool:
        return bool(self.crash or self.hang or self.non_finite or self.unnamed)


_SEEDS: list = []


def seed_bytes(index: int) -> bytes:
    """The saved bytes of seed scene `index` (made once)."""
    if not _SEEDS:
        import tempfile
        from pathlib import Path
        with tempfile.TemporaryDirectory() as folder:
            for k, scene in enumerate(seed_scenes()):
                _SEEDS.append(save_scene(scene, Path(folder) / f"seed{k}.vpscene").read_bytes())
    return _SEEDS[index % len(_SEEDS)]


def check(case, path) -> Outcome:
    """Write the mutated file to `path`, load it, render it tiny if it loads."""
    seed, mutations = case
    path.write_bytes(mutate(seed_bytes(seed), mutations))
    outcome = Outcome()
    try:
        scene = load_scene(path)
    except SceneError as error:
        outcome.error = str(error)
        if not outcome.error.startswith(f"{path}: "):
            outcome.unnamed.append(outcome.error)
        return outcome
    except Exception as error:  # noqa: BLE001 - the invariant under test
        import traceback
        outcome.crash = f"load: {type(error).__name__}: {error}\n{traceback.format_exc()}"
        return outcome
    outcome.loaded = True
    from volpath_native.camera import crop_window
    try:
        _, _, width, height = crop_window(scene.film)
    except SceneError as error:
        outcome.error = str(error)
        return outcome
    if width * height > MAX_RENDERED_PIXELS:
        return outcome
    s = scene.settings
    s.samples, s.threads, s.batch_size, s.parallelism = 1, 1, 1024, "threads"
    s.max_bounces, s.volume_bounces, s.diffuse_bounces = min(s.max_bounces, 8), min(s.volume_bounces, 4), \
        min(s.diffuse_bounces, 4)
    deadline = time.perf_counter() + HANG_SECONDS
    try:
        result = render(scene, cancel=lambda: time.perf_counter() > deadline)
    except SceneError as error:
        outcome.error = str(error)
        return outcome
    except Exception as error:  # noqa: BLE001
        import traceback
        outcome.crash = f"render: {type(error).__name__}: {error}\n{traceback.format_exc()}"
        return outcome
    outcome.rendered = True
    outcome.hang = result.cancelled
    outcome.non_finite = not (np.all(np.isfinite(result.image)) and np.all(np.isfinite(result.variance)))
    return outcome
