"""Every difference between the Blender versions VolPath runs in (3.4 legacy add-on .. 5.x), in one
place. The rest of the add-on asks these helpers instead of testing bpy.app.version itself."""
from __future__ import annotations

import bpy
import numpy as np

BLENDER_VERSION = tuple(bpy.app.version)

# Principled BSDF sockets renamed in Blender 4.0: first name that exists wins.
_PRINCIPLED_SOCKETS = {
    "emission_color": ("Emission Color", "Emission"),
    "emission_strength": ("Emission Strength",),
    "base_color": ("Base Color",),
    "metallic": ("Metallic",),
    "specular": ("Specular IOR Level", "Specular"),
    "transmission": ("Transmission Weight", "Transmission"),
    "coat": ("Coat Weight", "Clearcoat"),
    "sheen": ("Sheen Weight", "Sheen"),
    "subsurface": ("Subsurface Weight", "Subsurface"),
    "alpha": ("Alpha",),
}

# Blender's own engines whose properties panels VolPath reuses (EEVEE's id changed in 4.2 and 5.0).
BLENDER_ENGINE_IDS = frozenset({"BLENDER_RENDER", "BLENDER_EEVEE", "BLENDER_EEVEE_NEXT"})


def principled_socket(node, key: str):
    """The Principled BSDF input for `key` (see _PRINCIPLED_SOCKETS), or None if this Blender has none."""
    for name in _PRINCIPLED_SOCKETS[key]:
        socket = node.inputs.get(name)
        if socket is not None:
            return socket
    return None


def material_node_tree(material):
    """The node tree Cycles would use, or None when the material is not node-based.
    Blender 5.0 always uses nodes and deprecates Material.use_nodes."""
    if material is None:
        return None
    if BLENDER_VERSION >= (5, 0, 0):
        return material.node_tree
    return material.node_tree if material.use_nodes else None


def world_node_tree(world):
    if world is None:
        return None
    if BLENDER_VERSION >= (5, 0, 0):
        return world.node_tree
    return world.node_tree if world.use_nodes else None


def corner_normals(mesh) -> np.ndarray:
    """(loops, 3) float32 shading normals per face corner (smooth, sharp edges, custom normals)."""
    out = np.empty(len(mesh.loops) * 3, dtype=np.float32)
    if hasattr(mesh, "corner_normals"):  # Blender 4.1+
        mesh.corner_normals.foreach_get("vector", out)
    else:  # Blender < 4.1: split normals must be computed first
        mesh.calc_normals_split()
        mesh.loops.foreach_get("normal", out)
    return out.reshape(-1, 3)


def light_color_factor(light) -> np.ndarray:
    """Colour x 2^exposure x temperature colour: the factor Cycles multiplies the energy with
    (intern/cycles/blender/light.cpp, BlenderSync::sync_light: strength = colour x energy x
    exp2(exposure), colour x temperature_color when use_temperature). Exposure is Blender 4.0+,
    temperature 4.5+; older versions have neither, i.e. factor 1."""
    color = np.array(light.color[:3], dtype=np.float64)
    if getattr(light, "use_temperature", False):
        color *= np.array(light.temperature_color[:3], dtype=np.float64)
    return color * 2.0 ** float(getattr(light, "exposure", 0.0))


def light_is_normalized(light) -> bool:
    """Light.normalize (Blender 4.1+): False means the strength is not divided by the area."""
    return bool(getattr(light, "normalize", True))


def light_soft_falloff(light) -> bool:
    """Blender 4.0 made point/spot lights true spheres and added "Soft Falloff" (default on) to
    keep the earlier behaviour; before 4.0 that earlier behaviour is the only one."""
    return bool(getattr(light, "use_soft_falloff", True))
