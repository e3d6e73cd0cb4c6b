"""Random Blender scenes for the fuzz suite: a hypothesis strategy draws a plain description (dicts
and lists, so a failure shrinks to a readable reproducer), `build` makes it with bpy calls, `check`
exports and renders it tiny and returns what broke an invariant:
- no crash: export and render raise nothing but SceneError;
- no hang: a render that has not ended after HANG_SECONDS is cancelled and counted;
- every pixel finite; no Python (numpy) warning leaks out of the exporter or renderer;
- every invalid input named: each datablock given a NaN, an infinity, FLT_MAX (Blender's inf) or a
  negative strength in a field the exporter reads appears in a warning or the error;
- a defined fallback for everything but a broken camera: no other input refuses the render.
"""
from __future__ import annotations

import math
import tempfile
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import bpy
import numpy as np
from hypothesis import strategies as st

FLT_MAX = float(np.finfo(np.float32).max)
HANG_SECONDS = 30.0

# Value classes every fuzzed number is drawn from; the invalid ones must be named when read.
INVALID = ("nan", "inf", "-inf", "flt_max")
VALUE_CLASSES = ("normal", "normal", "normal", "zero", "negative", "huge", "out_of_range") + INVALID


def number(value_class: str, normal: float, low: float = 0.0, high: float = 1.0) -> float:
    return {"normal": normal, "zero": 0.0, "negative": -abs(normal) - 0.5, "huge": 1e30,
            "out_of_range": high * 10.0 + 3.0 if high > 0 else low - 3.0, "nan": math.nan, "inf": math.inf,
            "-inf": -math.inf, "flt_max": FLT_MAX}[value_class]


def values(*names):
    """A dict {socket name: value class} for the given sockets."""
    return st.fixed_dictionaries({name: st.sampled_from(VALUE_CLASSES) for name in names})


# The sockets the exporter reads, per node, with a normal value and the socket's range.
SOCKETS = {
    "ShaderNodeBsdfDiffuse": {"Color": (0.6, 0, 1), "Roughness": (0.0, 0, 1)},
    "ShaderNodeBsdfPrincipled": {"Base Color": (0.7, 0, 1), "Metallic": (0.0, 0, 1),
                                 "Transmission Weight": (0.0, 0, 1), "Alpha": (1.0, 0, 1),
                                 "Roughness": (0.5, 0, 1), "IOR": (1.5, 1, 3), "Coat Weight": (0.0, 0, 1),
                                 "Sheen Weight": (0.0, 0, 1), "Specular IOR Level": (0.5, 0, 1),
                                 "Emission Color": (1.0, 0, 1), "Emission Strength": (0.0, 0, 10)},
    "ShaderNodeEmission": {"Color": (1.0, 0, 1), "Strength": (2.0, 0, 10)},
    "ShaderNodeVolumePrincipled": {"Color": (0.5, 0, 1), "Density": (1.0, 0, 10), "Anisotropy": (0.2, -1, 1),
                                   "Absorption Color": (0.0, 0, 1), "Emission Strength": (0.0, 0, 10),
                                   "Blackbody Intensity": (0.0, 0, 1), "Temperature": (1500.0, 0, 10000)},
    "ShaderNodeVolumeScatter": {"Color": (0.8, 0, 1), "Density": (0.5, 0, 10), "Anisotropy": (0.0, -1, 1)},
    "ShaderNodeVolumeAbsorption": {"Color": (0.4, 0, 1), "Density": (0.5, 0, 10)},
    "ShaderNodeBsdfToon": {},    # unsupported: named
    "ShaderNodeBsdfGlossy": {"Color": (0.8, 0, 1), "Roughness": (0.5, 0, 1)},
    "ShaderNodeBsdfGlass": {"Color": (1.0, 0, 1), "Roughness": (0.0, 0, 1), "IOR": (1.45, 1, 3)},
    "ShaderNodeBsdfTransparent": {"Color": (0.5, 0, 1)},
}
SURFACES = ("ShaderNodeBsdfDiffuse", "ShaderNodeBsdfPrincipled", "ShaderNodeEmission", "ShaderNodeBsdfToon",
            "ShaderNodeBsdfGlossy", "ShaderNodeBsdfGlass", "ShaderNodeBsdfTransparent")
VOLUMES = ("ShaderNodeVolumePrincipled", "ShaderNodeVolumeScatter", "ShaderNodeVolumeAbsorption")
UNSUPPORTED = ("ShaderNodeBsdfToon",)


def node(kinds):
    return st.sampled_from(kinds).flatmap(lambda kind: st.fixed_dictionaries(
        {"kind": st.just(kind), "inputs": values(*SOCKETS[kind])}))


materials = st.fixed_dictionaries({
    "surface": st.none() | node(SURFACES),
    "volume": st.none() | node(VOLUMES),
    "mix": st.none() | st.sampled_from(VALUE_CLASSES),  # a Mix Shader of the surface with an Emission
})
transform = st.fixed_dictionaries({
    "location": st.sampled_from(VALUE_CLASSES[:3] + ("nan", "inf")),
    "rotation": st.sampled_from(("normal", "normal", "zero", "huge", "nan")),
    "scale": st.sampled_from(("normal", "normal", "normal", "zero", "negative", "huge", "nan")),
})
SHAPES = ("cube", "cube", "open_cube", "plane", "text", "text_extruded", "nan_vertex", "degenerate")
objects = st.fixed_dictionaries({"shape": st.sampled_from(SHAPES), "transform": transform,
                                 "material": st.none() | st.integers(0, 3)})
lights = st.fixed_dictionaries({
    "type": st.sampled_from(("POINT", "SPOT", "AREA", "SUN")), "energy": st.sampled_from(VALUE_CLASSES),
    "size": st.sampled_from(("normal", "normal", "zero", "huge", "nan")),
    "color": st.sampled_from(("normal", "normal", "negative", "nan")), "transform": transform,
})
worlds = st.none() | st.fixed_dictionaries({"color": st.sampled_from(VALUE_CLASSES),
                                            "strength": st.sampled_from(VALUE_CLASSES),
                                            "volume": st.none() | node(VOLUMES)})
cameras = st.fixed_dictionaries({"type": st.sampled_from(("PERSP", "PERSP", "ORTHO", "PANO")),
                                 "dof": st.sampled_from(("off", "off", "normal", "zero_f_stop", "focus_self")),
                                 "motion_blur": st.booleans(),
                                 "location": st.sampled_from(("normal",) * 8 + ("nan",)),
                                 "lens": st.sampled_from(("normal", "normal", "huge", "out_of_range"))})
volume_objects = st.fixed_dictionaries({
    "density": st.sampled_from(("normal", "normal", "zero", "negative", "huge", "nan")),  # voxel values
    "material": st.none() | node(("ShaderNodeVolumePrincipled",)),
    "transform": transform,
})
scenes = st.fixed_dictionaries({
    "camera": cameras,
    "materials": st.lists(materials, min_size=1, max_size=4),
    "objects": st.lists(objects, min_size=0, max_size=4),
    "lights": st.lists(lights, min_size=1, max_size=3),
    "world": worlds,
    "volumes": st.lists(volume_objects, max_size=1),
    "resolution": st.sampled_from((6, 8, 12)),
    "samples": st.sampled_from((1, 2)),
    "volume_bounces": st.sampled_from((0, 2)),
})


# ------------------------------------------------------------------------------------------------
# Building
# ------------------------------------------------------------------------------------------------
@dataclass
class Planted:
    """What the description made invalid: datablock names that must be named in the messages,
    and whether the export must fail (a broken camera)."""

    names: set = field(default_factory=set)
    camera_broken: bool = False


def _set_input(node_obj, name, value_class, normal, low, high, planted, owner):
    socket = node_obj.inputs.get(name)
    if socket is None:
        return
    value = number(value_class, normal, low, high)
    if hasattr(socket.default_value, "__len__"):
        size = len(socket.default_value)
        socket.default_value = (value, normal, normal, 1.0)[:size] if size == 4 else (value,) * size
    else:
        socket.default_value = value
    if invalid_number(stored(socket.default_value)):  # what Blender kept (it clamps some ranges)
        planted.add(owner)


def stored(value) -> np.ndarray:
    return np.asarray(value[:] if hasattr(value, "__len__") else value, dtype=np.float64)


def invalid_number(values) -> bool:
    """NaN, infinity or FLT_MAX (Blender's inf) among the values."""
    return not np.all(np.abs(np.asarray(values, dtype=np.float64)) < FLT_MAX)


def _material(index, desc, planted_materials):
    name = f"M{index}"
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    output.target = "ALL"
    invalid = set()
    if desc["surface"] is not None:
        surface = tree.nodes.new(desc["surface"]["kind"])
        for socket, cls in desc["surface"]["inputs"].items():
            _set_input(surface, socket, cls, *SOCKETS[desc["surface"]["kind"]][socket], invalid, name)
        shader_out = surface.outputs[0]
        if desc["mix"] is not None:
            mix = tree.nodes.new("ShaderNodeMixShader")
            emit = tree.nodes.new("ShaderNodeEmission")
            _set_input(mix, "Fac", desc["mix"], 0.3, 0, 1, invalid, name)
            tree.links.new(surface.outputs[0], mix.inputs[1])
            tree.links.new(emit.outputs[0], mix.inputs[2])
            shader_out = mix.outputs[0]
        tree.links.new(shader_out, output.inputs["Surface"])
        if desc["surface"]["kind"] in UNSUPPORTED:
            invalid.add(name)
    if desc["volume"] is not None:
        volume = tree.nodes.new(desc["volume"]["kind"])
        for socket, cls in desc["volume"]["inputs"].items():
            _set_input(volume, socket, cls, *SOCKETS[desc["volume"]["kind"]][socket], invalid, name)
        tree.links.new(volume.outputs[0], output.inputs["Volume"])
    if invalid:
        planted_materials.add(name)
    return mat


CUBE_V = [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1), (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)]
CUBE_F = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]


def _object_data(index, shape):
    name = f"O{index}"
    if shape.startswith("text"):
        curve = bpy.data.curves.new(name, "FONT")
        curve.body = "Ox"
        curve.extrude = 0.2 if shape == "text_extruded" else 0.0
        return name, curve
    mesh = bpy.data.meshes.new(name)
    if shape == "plane":
        mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    elif shape == "degenerate":
        mesh.from_pydata([(0, 0, 0), (1, 0, 0), (2, 0, 0)], [], [(0, 1, 2)])
    else:
        mesh.from_pydata(CUBE_V, [], CUBE_F[:-1] if shape == "open_cube" else CUBE_F)
        if shape == "nan_vertex":
            mesh.vertices[0].co = (math.nan, 0.0, 0.0)
    mesh.update()
    return name, mesh


def _apply_transform(obj, desc, base, invalid: set) -> bool:
    """Place obj; returns False when the transform hides it (zero scale: not rendered, valid)."""
    loc = number(desc["location"], 0.0)
    obj.location = (base[0] + (0.0 if desc["location"] == "normal" else loc), base[1], base[2])
    obj.rotation_euler = (number(desc["rotation"], 0.3), 0.1, 0.2)
    scale = number(desc["scale"], 0.5)
    obj.scale = (scale, 0.5, 0.5)
    if "nan" in (desc["location"], desc["rotation"], desc["scale"]) or desc["location"] == "inf":
        invalid.add(obj.name)
        return False
    return desc["scale"] != "zero"


def build(desc) -> Planted:
    """Make the described scene in the current Blender file (emptied first)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "VOLPATH"
    sc.render.resolution_x = sc.render.resolution_y = desc["resolution"]
    sc.render.resolution_percentage = 100
    sc.volpath.samples = desc["samples"]
    sc.volpath.volume_bounces = desc["volume_bounces"]
    sc.volpath.batch_size = 1024
    sc.volpath.threads = 1
    planted = Planted()

    cam_desc = desc["camera"]
    cam = bpy.data.cameras.new("Cam")
    cam.type = cam_desc["type"]
    cam.lens = {"normal": 35.0, "huge": 1e6, "out_of_range": 0.5}[cam_desc["lens"]]
    if cam_desc["type"] == "PANO":
        cam.panorama_type = "EQUIRECTANGULAR"
    cam_obj = bpy.data.objects.new("Cam", cam)
    dof = cam_desc.get("dof", "off")  # regression descriptions predate the lens and motion blur
    if dof != "off":
        cam.dof.use_dof = True
        cam.dof.aperture_fstop = 0.0 if dof == "zero_f_stop" else 2.0
        cam.dof.focus_object = cam_obj if dof == "focus_self" else None
    sc.render.use_motion_blur = cam_desc.get("motion_blur", False)
    cam_obj.location = (0.0, -8.0 if cam_desc["location"] == "normal" else math.nan, 0.0)
    cam_obj.rotation_euler = (math.pi / 2, 0.0, 0.0)
    sc.collection.objects.link(cam_obj)
    sc.camera = cam_obj
    planted.camera_broken = cam_desc["location"] == "nan"

    bad_materials: set = set()
    mats = [_material(i, m, bad_materials) for i, m in enumerate(desc["materials"])]
    used_materials = {}
    invalid_objects: set = set()
    rendered: set = set()
    for i, o in enumerate(desc["objects"]):
        name, data = _object_data(i, o["shape"])
        obj = bpy.data.objects.new(name, data)
        sc.collection.objects.link(obj)
        if o["material"] is not None:
            mat = mats[o["material"] % len(mats)]
            data.materials.append(mat)
            used_materials.setdefault(mat.name, []).append(name)
        shown = _apply_transform(obj, o["transform"], (2.5 * (i - 1.5), 0.0, 0.0), invalid_objects)
        if shown:
            rendered.add(name)
            if o["shape"] == "nan_vertex":
                invalid_objects.add(name)
    planted.names |= invalid_objects
    for name in bad_materials:  # named if some rendered object reads it
        if any(obj in rendered for obj in used_materials.get(name, [])):
            planted.names.add(name)

    for i, l in enumerate(desc["lights"]):
        name = f"L{i}"
        light = bpy.data.lights.new(name, l["type"])
        light.energy = number(l["energy"], 200.0 if l["type"] != "SUN" else 3.0, 0, 1000)
        light.color = (number(l["color"], 1.0), 1.0, 1.0)
        size = number(l["size"], 0.3)
        for prop in ("shadow_soft_size", "size", "angle"):
            if hasattr(light, prop):
                try:
                    setattr(light, prop, size)
                except (ValueError, TypeError):
                    pass
        obj = bpy.data.objects.new(name, light)
        sc.collection.objects.link(obj)
        invalid: set = set()
        _apply_transform(obj, l["transform"], (0.0, -3.0, 3.0), invalid)
        obj.rotation_euler = (0.4 if l["transform"]["rotation"] != "nan" else math.nan, 0.0, 0.0)
        sizes = [getattr(light, p) for p in ("shadow_soft_size", "size", "angle") if hasattr(light, p)]
        kept = [light.energy, *light.color, *sizes]  # what Blender stored
        if invalid or invalid_number(kept) or light.energy < 0 or min(light.color) < 0:
            planted.names.add(name)

    w = desc["world"]
    if w is not None:
        world = bpy.data.worlds.new("W")
        if bpy.app.version < (5, 0, 0):
            world.use_nodes = True
        background = world.node_tree.nodes["Background"]
        invalid = set()
        _set_input(background, "Color", w["color"], 0.2, 0, 1, invalid, "W")
        _set_input(background, "Strength", w["strength"], 1.0, 0, 10, invalid, "W")
        color = stored(background.inputs["Color"].default_value)[:3]
        strength = float(background.inputs["Strength"].default_value)
        if not invalid_number(np.append(color, strength)) and np.any(color * strength < 0):
            invalid.add("W")  # a negative background: black, named
        if w["volume"] is not None:
            output = world.node_tree.nodes["World Output"]
            volume = world.node_tree.nodes.new(w["volume"]["kind"])
            for socket, cls in w["volume"]["inputs"].items():
                _set_input(volume, socket, cls, *SOCKETS[w["volume"]["kind"]][socket], invalid, "W")
            world.node_tree.links.new(volume.outputs[0], output.inputs["Volume"])
        sc.world = world
        planted.names |= invalid
    else:
        sc.world = None

    for i, v in enumerate(desc["volumes"]):
        _volume_object(sc, i, v, planted)
    return planted


_VDB_DIR = None


def _volume_object(sc, index, desc, planted):
    """A small OpenVDB cube of the described density, written with Blender's openvdb module."""
    from addon import export_volume_grids as evg
    global _VDB_DIR
    try:
        openvdb = evg.import_openvdb()
    except evg.OpenVDBUnavailable:
        return
    if _VDB_DIR is None:
        _VDB_DIR = Path(tempfile.mkdtemp(prefix="volpath_fuzz_"))
    density = np.full((4, 4, 4), number(desc["density"], 1.0), np.float32)
    grid = openvdb.FloatGrid()
    grid.name = "density"
    grid.copyFromArray(density)
    grid.transform = openvdb.createLinearTransform(voxelSize=0.25)
    path = _VDB_DIR / f"{desc['density']}.vdb"
    if not path.exists():
        openvdb.write(str(path), grids=[grid])
    name = f"V{index}"
    volume = bpy.data.volumes.new(name)
    volume.filepath = str(path)
    invalid: set = set()
    if desc["material"] is not None:
        bad: set = set()
        volume.materials.append(_material(100 + index, {"surface": None, "volume": desc["material"], "mix": None}, bad))
        if bad:
            invalid.add(name)
    obj = bpy.data.objects.new(name, volume)
    sc.collection.objects.link(obj)
    _apply_transform(obj, desc["transform"], (0.0, 1.0, 0.0), invalid)
    if desc["density"] == "nan":
        invalid.add(name)
    planted.names |= invalid


# ------------------------------------------------------------------------------------------------
# Checking
# ------------------------------------------------------------------------------------------------
@dataclass
class Outcome:
    crash: str = ""          # an exception other than SceneError
    hang: bool = False
    non_finite: bool = False
    unnamed: list = field(default_factory=list)  # planted datablocks no message names
    named: list = field(default_factory=list)    # planted datablocks that were named
    leaked: list = field(default_factory=list)   # Python warnings (e.g. numpy's) that got past the exporter
    error: str = ""          # the SceneError, if the scene was refused
    refused: bool = False    # ... though it had no broken camera: a fallback is missing
    rendered: bool = False
    messages: list = field(default_factory=list)
    seconds: float = 0.0

    @property
    def failed(self) -> bool:
        return bool(self.crash or self.hang or self.non_finite or self.unnamed or self.leaked or self.refused)


def check(desc) -> Outcome:
    """Build, export and render the description; what broke which invariant."""
    import volpath_native as vp
    from volpath_native.render import render

    from addon.export import export_scene

    outcome = Outcome()
    start = time.perf_counter()
    try:
        planted = build(desc)
        with warnings.catch_warnings(record=True) as leaked:
            warnings.simplefilter("always")
            try:
                scene, messages = export_scene(bpy.context.evaluated_depsgraph_get())
                outcome.messages += messages
                deadline = time.perf_counter() + HANG_SECONDS
                result = render(scene, cancel=lambda: time.perf_counter() > deadline)
            finally:
                outcome.leaked = [f"{w.category.__name__}: {w.message} ({w.filename}:{w.lineno})" for w in leaked]
        outcome.messages += result.warnings
        outcome.rendered = True
        outcome.hang = result.cancelled
        outcome.non_finite = not (np.all(np.isfinite(result.image)) and np.all(np.isfinite(result.variance)))
    except vp.SceneError as error:
        outcome.error = str(error)
        outcome.messages += list(getattr(error, "warnings", [])) + [str(error)]
    except Exception as error:  # noqa: BLE001 - the invariant under test
        import traceback
        outcome.crash = f"{type(error).__name__}: {error}\n{traceback.format_exc()}"
        return outcome
    finally:
        outcome.seconds = time.perf_counter() - start
    text = "\n".join(outcome.messages)
    outcome.refused = bool(outcome.error) and not planted.camera_broken
    if planted.camera_broken and "camera 'Cam'" not in outcome.error:
        outcome.unnamed.append("Cam")
    if not planted.camera_broken:  # (a broken camera stops the export before anything else is read)
        outcome.unnamed += sorted(n for n in planted.names if f"'{n}'" not in text)
        outcome.named += sorted(n for n in planted.names if f"'{n}'" in text)
    return outcome
