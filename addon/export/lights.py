"""Blender lights -> VolPath lights, with Cycles' conversions.

Strength S = colour x energy x 2^exposure (x temperature colour): intern/cycles/blender/light.cpp
(BlenderSync::sync_light), see compat.light_color_factor. Cycles turns S into radiance by dividing
by pi x area only when the light is normalised (intern/cycles/scene/light.cpp, *::copy_to_kernel:
invarea = normalize ? 1/area : 1). VolPath's model always takes the normalised quantity (power,
or irradiance for the sun), so an unnormalised light is exported with S x area.
"""
from __future__ import annotations

import math

import numpy as np

import volpath_native as vp

from .. import compat
from . import shading

_AREA_SHAPES = {"SQUARE": "square", "RECTANGLE": "rectangle", "DISK": "disk", "ELLIPSE": "ellipse"}


def _point_area(radius: float) -> float:
    # scene/light.cpp PointLight::area: sphere area, or 4 for r = 0 (so that I = S / (4 pi)).
    area = 4.0 * math.pi * radius * radius
    return area if area > 0.0 else 4.0


def _sun_area(angle: float) -> float:
    # scene/light.cpp SunLight::area: the sun disk's projected solid angle, 1 for a point sun.
    return math.pi * math.sin(angle * 0.5) ** 2 if angle > 0.0 else 1.0


def _node_factor(light, name: str, reporter) -> np.ndarray:
    """The light's node tree multiplies its strength by its Emission closure (colour x strength);
    no tree: 1. Same node reading (and warnings for what cannot be evaluated) as materials."""
    tree = compat.light_node_tree(light)
    if tree is None:
        return np.ones(3)
    output = tree.get_output_node("CYCLES")
    if output is None:
        reporter.warn(f"light '{name}': node tree without an active Light Output; the light is dark (as Cycles)")
        return np.zeros(3)
    reader = shading.NodeReader(f"light '{name}'", reporter)
    before = len(reporter.messages)
    surface = shading.surface_terms(reader, shading._shader_node, output.inputs["Surface"])
    if len(reporter.messages) > before or surface.nodes:
        reporter.warn(f"light '{name}': its node tree is not fully supported; rendered without it "
                      "(colour x power only)")
        return np.ones(3)
    return surface.emission


def export_light(obj, matrix_world: np.ndarray, reporter):
    """The VolPath light for a Blender light object at `matrix_world` (4x4), or None."""
    light = obj.data
    name = obj.name
    strength = compat.light_color_factor(light) * float(light.energy) * _node_factor(light, name, reporter)
    normalized = compat.light_is_normalized(light)
    position = matrix_world[:3, 3]
    direction = -matrix_world[:3, 2]  # a lamp shines down its local -Z
    # Object > Visibility > Camera: hides the lamp itself from camera rays, lighting unchanged.
    visible_camera = bool(obj.visible_camera)
    if not light.use_shadow:
        reporter.warn(f"light '{name}': 'Cast Shadow' off is not supported; it casts shadows")

    if light.type in ("POINT", "SPOT"):
        radius = max(float(light.shadow_soft_size), 0.0)
        power = strength if normalized else strength * _point_area(radius)
        common = dict(name=name, position=position, power=power, radius=radius,
                      soft_falloff=compat.light_soft_falloff(light), visible_camera=visible_camera)
        if light.type == "POINT":
            return vp.PointLight(**common)
        scale_x, scale_y = np.linalg.norm(matrix_world[:3, 0]), np.linalg.norm(matrix_world[:3, 1])
        if abs(scale_x - scale_y) > 1e-4 * max(scale_x, scale_y):
            reporter.warn(f"light '{name}': non-uniform object scale makes Cycles' spot cone elliptical; "
                          "VolPath renders it round")
        if compat.spot_is_square(light):
            reporter.warn(f"light '{name}': square spot cones are not supported; rendered round")
        # blender/light.cpp: spot_angle = spot_size (full cone), spot_smooth = spot_blend.
        return vp.SpotLight(**common, direction=direction, spot_size=float(light.spot_size),
                            spot_blend=float(light.spot_blend))

    if light.type == "AREA":
        shape = _AREA_SHAPES[light.shape]
        size_u = float(light.size)
        size_v = float(light.size_y) if shape in ("rectangle", "ellipse") else size_u
        # scene/light.cpp AreaLight: extent = object axis (with scale) x size.
        axis_u = matrix_world[:3, 0] * size_u
        axis_v = matrix_world[:3, 1] * size_v
        if np.dot(np.cross(axis_u, axis_v), direction) > 0.0:  # mirrored transform: keep -Z
            axis_v = -axis_v
        area = float(np.linalg.norm(axis_u) * np.linalg.norm(axis_v))
        if shape in ("disk", "ellipse"):
            area *= math.pi / 4.0
        if float(light.spread) < math.pi - 1e-6:
            reporter.warn(f"light '{name}': spread {math.degrees(light.spread):.1f} deg is not "
                          "supported; rendered with 180 deg")
        power = strength if normalized else strength * area
        return vp.AreaLight(name=name, position=position, axis_u=axis_u, axis_v=axis_v,
                            power=power, shape=shape, visible_camera=visible_camera)

    if light.type == "SUN":
        angle = float(light.angle)
        irradiance = strength if normalized else strength * _sun_area(angle)
        return vp.SunLight(name=name, direction=direction, irradiance=irradiance, angle=angle,
                           visible_camera=visible_camera)

    reporter.warn(f"light '{name}': type {light.type} is not supported; ignored")
    return None
