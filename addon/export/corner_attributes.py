"""Per-corner attributes of an evaluated mesh that surface programs read, as (T, 3, k) float32 arrays
over its loop triangles (names as volpath_native.surface_programs documents):

- "uv:<map>" (u, v); "uv:" is the active-render UV map (Cycles' ATTR_STD_UV);
- "tangent:<map>" (tx, ty, tz, sign): Blender's MikkTSpace tangent of that UV map (Mesh.calc_tangents,
  the same algorithm Cycles runs in blender/mesh.cpp), object space;
- "color:<name>" RGBA of a colour attribute ('' = the default colour attribute), scene-linear
  (byte colours are stored sRGB-encoded by Blender and read linear, as Cycles converts them);
- "attr:<name>" any attribute by name as (x, y, z, alpha): colours RGBA, UV maps (u, v, 0, 1),
  floats (f, f, f, 1), vectors (x, y, z, 1) -- point, corner and face domains.
A mesh without the attribute gets none (the kernel reads 0, as Cycles' ATTR_STD_NOT_FOUND), with a
warning naming the object.
"""
from __future__ import annotations

import numpy as np


def corner_attribute_arrays(obj, mesh, requests, reporter, loops, faces, corner_vertices) -> dict:
    """loops (T * 3,): the loop triangles' corners; faces (T,): their faces; corner_vertices
    (loops,): each corner's vertex (geometry.triangulate read them)."""
    n_tri = len(faces)
    mesh_tables = (faces, corner_vertices)
    out = {}
    for name in sorted(requests):
        kind, _, key = name.partition(":")
        try:
            values = _read(obj, mesh, kind, key, loops, n_tri, mesh_tables)
        except (RuntimeError, ValueError, AttributeError, TypeError) as error:
            _warn(reporter, f"object '{obj.name}': attribute '{name}' could not be read ({error}); read as 0")
            continue
        if values is None:
            what = {"uv": "UV map", "tangent": "UV map (for tangents)", "color": "colour attribute",
                    "attr": "attribute"}.get(kind, "attribute")
            label = f"'{key}'" if key else "(active render)"
            _warn(reporter, f"object '{obj.name}': no {what} {label}; read as 0 as Cycles"
                  + (" (UV (0, 0))" if kind == "uv" else ""))
            continue
        out[name] = np.ascontiguousarray(values.reshape(n_tri, 3, -1), dtype=np.float32)
    return out


def _warn(reporter, message):
    if reporter is not None:
        reporter.warn(message)


def _uv_layer(mesh, key):
    if key:
        return mesh.uv_layers.get(key)
    return next((layer for layer in mesh.uv_layers if layer.active_render), None)


def _read(obj, mesh, kind, key, loops, n_tri, mesh_tables):
    n_loops = len(mesh.loops)
    if kind == "uv":
        layer = _uv_layer(mesh, key)
        if layer is None:
            return None
        uv = np.empty(n_loops * 2, np.float32)
        layer.data.foreach_get("uv", uv)
        return uv.reshape(-1, 2)[loops]
    if kind == "tangent":
        layer = _uv_layer(mesh, key)
        if layer is None:
            return None
        mesh.calc_tangents(uvmap=layer.name)
        tangent = np.empty(n_loops * 3, np.float32)
        sign = np.empty(n_loops, np.float32)
        mesh.loops.foreach_get("tangent", tangent)
        mesh.loops.foreach_get("bitangent_sign", sign)
        return np.concatenate([tangent.reshape(-1, 3), sign[:, None]], axis=1)[loops]
    if kind == "color":
        attributes = getattr(mesh, "color_attributes", None)
        if attributes is None:
            return None
        if key:
            attribute = attributes.get(key)
        else:
            default = getattr(attributes, "default_color_name", "") or ""
            attribute = attributes.get(default) if default else None
            if attribute is None and len(attributes):
                index = getattr(attributes, "render_color_index", 0)
                attribute = attributes[index] if 0 <= index < len(attributes) else attributes[0]
        if attribute is None:
            return None
        return _per_corner(mesh, attribute, "color", 4, loops, mesh_tables)
    if kind == "attr":
        attribute = getattr(mesh, "color_attributes", {}).get(key) if key else None
        if attribute is not None:
            return _per_corner(mesh, attribute, "color", 4, loops, mesh_tables)
        layer = mesh.uv_layers.get(key) if key else None
        if layer is not None:
            uv = _read(obj, mesh, "uv", key, loops, n_tri, mesh_tables)
            return np.concatenate([uv, np.zeros((len(uv), 1), np.float32), np.ones((len(uv), 1), np.float32)], 1)
        attribute = mesh.attributes.get(key) if key else None
        if attribute is None:
            return None
        kinds = {"FLOAT": ("value", 1), "INT": ("value", 1), "BOOLEAN": ("value", 1), "FLOAT_VECTOR": ("vector", 3),
                 "FLOAT2": ("vector", 2), "FLOAT_COLOR": ("color", 4), "BYTE_COLOR": ("color", 4)}
        if attribute.data_type not in kinds:
            return None
        prop, width = kinds[attribute.data_type]
        values = _per_corner(mesh, attribute, prop, width, loops, mesh_tables)
        ones = np.ones((len(values), 1), np.float32)
        if width == 1:
            return np.concatenate([values, values, values, ones], axis=1)
        if width == 2:
            return np.concatenate([values, np.zeros_like(ones), ones], axis=1)
        if width == 3:
            return np.concatenate([values, ones], axis=1)
        return values
    return None


def _per_corner(mesh, attribute, prop, width, loops, mesh_tables):
    """The attribute's values at the triangles' corners (point, corner or face domain)."""
    n = len(attribute.data)
    if attribute.data_type in ("INT", "BOOLEAN"):
        raw = np.empty(n, np.int32 if attribute.data_type == "INT" else bool)
        attribute.data.foreach_get("value", raw)
        values = raw.astype(np.float32).reshape(-1, 1)
    else:
        values = np.empty(n * width, np.float32)
        attribute.data.foreach_get(prop, values)
        values = values.reshape(-1, width)
    domain = attribute.domain
    if domain == "CORNER":
        return values[loops]
    faces, corner_vertices = mesh_tables
    if domain == "POINT":
        return values[corner_vertices[loops]]
    if domain == "FACE":
        return np.repeat(values[faces], 3, axis=0)
    raise ValueError(f"domain {domain} is not supported")
