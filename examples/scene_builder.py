"""Common pieces of the example scenes, built from plain bpy calls (no operators that need a UI).

Every example script builds its scene into a fresh, empty Blender file with these helpers so the
scenes share one camera/box/material vocabulary. Materials use the nodes whose Cycles conversion
VolPath implements: Diffuse BSDF (roughness 0 = Lambertian), Principled BSDF and the other BSDF
nodes (bsdf_material), Emission, Principled Volume, Volume Scatter and Volume Absorption. Filter
Glossy is 0 (VolPath does not blur glossy paths; README). Lights have radius 0 unless stated, which makes Cycles'
point/spot lights true point sources (no soft falloff ambiguity).
"""
from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Optional, Sequence

import bpy
from mathutils import Vector

# Volume bounces large enough that multiple scattering is visible, identical for both engines.
DEFAULT_BOUNCES = dict(max_bounces=16, diffuse_bounces=4, glossy_bounces=4, transmission_bounces=12,
                       volume_bounces=8, transparent_bounces=16)


# ------------------------------------------------------------------------------------------------
# Scene and render settings
# ------------------------------------------------------------------------------------------------
def new_scene(resolution: Sequence[int] = (64, 64), samples: int = 64, seed: int = 0,
              bounces: Optional[dict] = None) -> bpy.types.Scene:
    """Empty the current file and return its scene configured for VolPath and Cycles alike."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = int(resolution[0]), int(resolution[1])
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    set_samples_and_bounces(scene, samples, seed, bounces or DEFAULT_BOUNCES)
    scene.cycles.blur_glossy = 0.0
    world = bpy.data.worlds.new("World")
    scene.world = world
    set_world_background(scene, (0.0, 0.0, 0.0), 0.0)
    return scene


def set_samples_and_bounces(scene, samples: int, seed: int, bounces: dict) -> None:
    """Write the sampling/bounce settings to Cycles and, when the add-on is registered, VolPath."""
    cycles = scene.cycles
    cycles.samples = int(samples)
    cycles.seed = int(seed)
    for key, value in bounces.items():
        setattr(cycles, "transparent_max_bounces" if key == "transparent_bounces" else key, int(value))
    volpath = getattr(scene, "volpath", None)
    if volpath is not None:
        volpath.samples = int(samples)
        volpath.seed = int(seed)
        for key, value in bounces.items():
            if hasattr(volpath, key):
                setattr(volpath, key, int(value))


def save(path) -> Path:
    path = Path(path).resolve()
    path.parent.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(path), check_existing=False, compress=True)
    return path


def main_for(build, argv: Optional[list] = None) -> Path:
    """`python examples/X.py OUT.blend`: build the scene with `build()` and save it."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--" in argv:  # `blender -b -P X.py -- OUT.blend`
        argv = argv[argv.index("--") + 1:]
    if len(argv) != 1 or not argv[0].endswith(".blend"):
        raise SystemExit("usage: python examples/<script>.py OUT.blend")
    build()
    out = save(argv[0])
    print(f"wrote {out}")
    return out


# ------------------------------------------------------------------------------------------------
# Camera
# ------------------------------------------------------------------------------------------------
def add_camera(scene, location, target, lens_mm: float = 35.0, name: str = "Camera"):
    cam_data = bpy.data.cameras.new(name)
    cam_data.lens = lens_mm
    cam_data.sensor_fit = "AUTO"
    cam = bpy.data.objects.new(name, cam_data)
    scene.collection.objects.link(cam)
    look_at(cam, location, target)
    scene.camera = cam
    return cam


def look_at(obj, location, target) -> None:
    obj.location = Vector(location)
    direction = Vector(target) - Vector(location)
    # Blender cameras and lamps look down their local -Z with +Y up.
    obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()


# ------------------------------------------------------------------------------------------------
# Materials
# ------------------------------------------------------------------------------------------------
def _material(name: str):
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:  # Blender < 5.0 creates materials without nodes
        mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    output = nodes.new("ShaderNodeOutputMaterial")
    return mat, nodes, mat.node_tree.links, output


def diffuse_material(name: str, color) -> bpy.types.Material:
    mat, nodes, links, output = _material(name)
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.0
    links.new(bsdf.outputs["BSDF"], output.inputs["Surface"])
    return mat


def _set_inputs(node, inputs: dict) -> None:
    """Node inputs by socket name; RGB triples get alpha 1; 'distribution' etc. are node properties."""
    for key, value in inputs.items():
        if key in ("distribution", "fresnel_type"):
            setattr(node, key, value)
            continue
        socket = node.inputs[key]
        if isinstance(value, (tuple, list)) and len(value) == 3 and len(socket.default_value) == 4:
            value = (*value, 1.0)
        socket.default_value = value


def bsdf_material(name: str, node_type: str = "ShaderNodeBsdfPrincipled", volume=None,
                  **inputs) -> bpy.types.Material:
    """A material with one BSDF node (Principled by default) set from `inputs` (socket names with
    spaces replaced by underscores, e.g. Base_Color=(1, 0, 0), Roughness=0.2), and optionally a
    volume node (a (node type, inputs) pair) on the Volume output: glass containing a liquid."""
    mat, nodes, links, output = _material(name)
    bsdf = nodes.new(node_type)
    _set_inputs(bsdf, {k.replace("_", " ") if k not in ("distribution", "fresnel_type") else k: v
                       for k, v in inputs.items()})
    links.new(bsdf.outputs[0], output.inputs["Surface"])
    if volume is not None:
        volume_type, volume_inputs = volume
        vol = nodes.new(volume_type)
        _set_inputs(vol, volume_inputs)
        links.new(vol.outputs[0], output.inputs["Volume"])
    return mat


def emission_material(name: str, color, strength: float) -> bpy.types.Material:
    mat, nodes, links, output = _material(name)
    emit = nodes.new("ShaderNodeEmission")
    emit.inputs["Color"].default_value = (*color, 1.0)
    emit.inputs["Strength"].default_value = float(strength)
    links.new(emit.outputs["Emission"], output.inputs["Surface"])
    return mat


def principled_volume_material(name: str, *, density: float, color=(0.5, 0.5, 0.5),
                               absorption_color=(0.0, 0.0, 0.0), anisotropy: float = 0.0,
                               emission_color=(1.0, 1.0, 1.0), emission_strength: float = 0.0):
    """A volume-only material (Surface unconnected: the mesh is an invisible medium boundary).

    With absorption_color black: sigma_t = density and albedo = color (Cycles svm/closure.h).
    """
    mat, nodes, links, output = _material(name)
    vol = nodes.new("ShaderNodeVolumePrincipled")
    vol.inputs["Density"].default_value = float(density)
    vol.inputs["Color"].default_value = (*color, 1.0)
    vol.inputs["Absorption Color"].default_value = (*absorption_color, 1.0)
    vol.inputs["Anisotropy"].default_value = float(anisotropy)
    vol.inputs["Emission Color"].default_value = (*emission_color, 1.0)
    vol.inputs["Emission Strength"].default_value = float(emission_strength)
    links.new(vol.outputs["Volume"], output.inputs["Volume"])
    return mat


def scatter_volume_material(name: str, *, density: float, color, anisotropy: float = 0.0):
    """Volume Scatter: sigma_s = sigma_t = color * density, no absorption."""
    mat, nodes, links, output = _material(name)
    vol = nodes.new("ShaderNodeVolumeScatter")
    vol.inputs["Density"].default_value = float(density)
    vol.inputs["Color"].default_value = (*color, 1.0)
    vol.inputs["Anisotropy"].default_value = float(anisotropy)
    links.new(vol.outputs["Volume"], output.inputs["Volume"])
    return mat


def absorption_volume_material(name: str, *, density: float, color):
    """Volume Absorption: sigma_a = (1 - color) * density."""
    mat, nodes, links, output = _material(name)
    vol = nodes.new("ShaderNodeVolumeAbsorption")
    vol.inputs["Density"].default_value = float(density)
    vol.inputs["Color"].default_value = (*color, 1.0)
    links.new(vol.outputs["Volume"], output.inputs["Volume"])
    return mat


# ------------------------------------------------------------------------------------------------
# Geometry
# ------------------------------------------------------------------------------------------------
def add_mesh(scene, name: str, vertices, faces, material) -> bpy.types.Object:
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(v) for v in vertices], [], [tuple(f) for f in faces])
    mesh.validate()
    mesh.update()
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj


# Corner order of an axis-aligned box; faces wound counter-clockwise seen from outside.
_BOX_FACES = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]


def box_vertices(center, size):
    cx, cy, cz = center
    sx, sy, sz = (size, size, size) if isinstance(size, (int, float)) else size
    hx, hy, hz = sx / 2, sy / 2, sz / 2
    return [(cx - hx, cy - hy, cz - hz), (cx + hx, cy - hy, cz - hz), (cx + hx, cy + hy, cz - hz),
            (cx - hx, cy + hy, cz - hz), (cx - hx, cy - hy, cz + hz), (cx + hx, cy - hy, cz + hz),
            (cx + hx, cy + hy, cz + hz), (cx - hx, cy + hy, cz + hz)]


def add_box(scene, name: str, center, size, material) -> bpy.types.Object:
    """A closed box with outward normals (a valid medium boundary)."""
    return add_mesh(scene, name, box_vertices(center, size), _BOX_FACES, material)


def add_uv_sphere(scene, name: str, center, radius: float, material, segments: int = 32, rings: int = 16,
                  smooth: bool = True) -> bpy.types.Object:
    """A closed UV sphere (outward normals), smooth-shaded by default."""
    cx, cy, cz = center
    vertices = [(cx, cy, cz + radius)]
    for i in range(1, rings):
        theta = math.pi * i / rings
        for j in range(segments):
            phi = 2.0 * math.pi * j / segments
            vertices.append((cx + radius * math.sin(theta) * math.cos(phi),
                             cy + radius * math.sin(theta) * math.sin(phi), cz + radius * math.cos(theta)))
    vertices.append((cx, cy, cz - radius))
    bottom = len(vertices) - 1
    faces = [(0, 1 + j, 1 + (j + 1) % segments) for j in range(segments)]
    for i in range(rings - 2):
        a, b = 1 + i * segments, 1 + (i + 1) * segments
        faces += [(a + j, b + j, b + (j + 1) % segments, a + (j + 1) % segments) for j in range(segments)]
    last = 1 + (rings - 2) * segments
    faces += [(last + j, bottom, last + (j + 1) % segments) for j in range(segments)]
    obj = add_mesh(scene, name, vertices, faces, material)
    for polygon in obj.data.polygons:
        polygon.use_smooth = smooth
    return obj


def add_cylinder(scene, name: str, base_center, radius: float, height: float, material, segments: int = 32,
                 smooth: bool = True) -> bpy.types.Object:
    """A closed cylinder along +Z (outward normals); the side smooth-shaded, the caps flat."""
    cx, cy, cz = base_center
    ring = [(math.cos(2 * math.pi * j / segments), math.sin(2 * math.pi * j / segments)) for j in range(segments)]
    vertices = [(cx + radius * x, cy + radius * y, cz) for x, y in ring]
    vertices += [(cx + radius * x, cy + radius * y, cz + height) for x, y in ring]
    sides = [(j, (j + 1) % segments, segments + (j + 1) % segments, segments + j) for j in range(segments)]
    caps = [tuple(reversed(range(segments))), tuple(range(segments, 2 * segments))]
    obj = add_mesh(scene, name, vertices, sides + caps, material)
    for polygon in obj.data.polygons[:segments]:
        polygon.use_smooth = smooth
    return obj


def add_quad(scene, name: str, corners, material) -> bpy.types.Object:
    """A one-quad mesh; corners counter-clockwise seen from the side the normal points to."""
    return add_mesh(scene, name, corners, [(0, 1, 2, 3)], material)


def add_cornell_box(scene, size: float = 2.0, white=(0.8, 0.8, 0.8), left=(0.8, 0.1, 0.1),
                    right=(0.1, 0.8, 0.1)) -> dict:
    """An open-front Cornell box centred on the origin, floor at z = 0, opening towards -Y.

    Returns the wall objects by name. The camera goes on the -Y side looking at +Y.
    """
    h = size / 2
    mats = {"white": diffuse_material("White", white), "red": diffuse_material("Red", left),
            "green": diffuse_material("Green", right)}
    walls = {
        # Normals point into the box.
        "floor": ([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], "white"),
        "ceiling": ([(-h, -h, size), (-h, h, size), (h, h, size), (h, -h, size)], "white"),
        "back": ([(-h, h, 0), (h, h, 0), (h, h, size), (-h, h, size)], "white"),
        "left": ([(-h, -h, 0), (-h, h, 0), (-h, h, size), (-h, -h, size)], "red"),
        "right": ([(h, -h, 0), (h, -h, size), (h, h, size), (h, h, 0)], "green"),
    }
    return {name: add_quad(scene, name.capitalize(), corners, mats[m]) for name, (corners, m) in walls.items()}


def cornell_camera(scene, size: float = 2.0, lens_mm: float = 35.0):
    """Camera in front of the Cornell box opening, framing the whole box."""
    distance = size * 1.45
    return add_camera(scene, (0.0, -size / 2 - distance, size / 2), (0.0, 0.0, size / 2), lens_mm)


# ------------------------------------------------------------------------------------------------
# Lights and world
# ------------------------------------------------------------------------------------------------
def _light_object(scene, name: str, light_data, location, target=None):
    obj = bpy.data.objects.new(name, light_data)
    scene.collection.objects.link(obj)
    if target is None:
        obj.location = Vector(location)
    else:
        look_at(obj, location, target)
    return obj


def add_point_light(scene, location, power_w: float, color=(1.0, 1.0, 1.0), radius: float = 0.0,
                    name: str = "Point"):
    light = bpy.data.lights.new(name, "POINT")
    light.energy = float(power_w)
    light.color = color
    light.shadow_soft_size = float(radius)
    return _light_object(scene, name, light, location)


def add_spot_light(scene, location, target, power_w: float, spot_size_deg: float = 30.0,
                   blend: float = 0.15, color=(1.0, 1.0, 1.0), radius: float = 0.0, name: str = "Spot"):
    light = bpy.data.lights.new(name, "SPOT")
    light.energy = float(power_w)
    light.color = color
    light.shadow_soft_size = float(radius)
    light.spot_size = math.radians(spot_size_deg)
    light.spot_blend = float(blend)
    return _light_object(scene, name, light, location, target)


def add_area_light(scene, location, target, power_w: float, size: float = 0.5, shape: str = "SQUARE",
                   size_y: Optional[float] = None, color=(1.0, 1.0, 1.0), name: str = "Area"):
    """An area light; like Cycles' default it is visible to camera rays (VolPath's too)."""
    light = bpy.data.lights.new(name, "AREA")
    light.energy = float(power_w)
    light.color = color
    light.shape = shape
    light.size = float(size)
    if size_y is not None:
        light.size_y = float(size_y)
    return _light_object(scene, name, light, location, target)


def add_sun_light(scene, direction, strength: float, angle_deg: float = 0.0, color=(1.0, 1.0, 1.0),
                  name: str = "Sun"):
    """direction: where the sunlight travels (the lamp's -Z)."""
    light = bpy.data.lights.new(name, "SUN")
    light.energy = float(strength)
    light.color = color
    light.angle = math.radians(angle_deg)
    obj = bpy.data.objects.new(name, light)
    scene.collection.objects.link(obj)
    obj.rotation_euler = Vector(direction).to_track_quat("-Z", "Y").to_euler()
    return obj


def set_world_background(scene, color, strength: float, volume_material=None) -> None:
    """World = Background(color, strength) and optionally a world volume (a volume-only material's
    Principled Volume / Volume Scatter node tree rebuilt in the world)."""
    world = scene.world
    if world.node_tree is None:  # Blender < 5.0
        world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    nodes.clear()
    output = nodes.new("ShaderNodeOutputWorld")
    background = nodes.new("ShaderNodeBackground")
    background.inputs["Color"].default_value = (*color, 1.0)
    background.inputs["Strength"].default_value = float(strength)
    links.new(background.outputs["Background"], output.inputs["Surface"])
    if volume_material is not None:
        source = next(n for n in volume_material.node_tree.nodes if n.outputs and n.outputs[0].name == "Volume")
        node = nodes.new(source.bl_idname)
        for socket in source.inputs:
            if hasattr(socket, "default_value") and socket.name in node.inputs:
                node.inputs[socket.name].default_value = socket.default_value
        links.new(node.outputs["Volume"], output.inputs["Volume"])
