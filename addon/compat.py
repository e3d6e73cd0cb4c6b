"""Every difference between the Blender versions VolPath runs in (3.4 legacy add-on .. 5.x), in one
place. The rest of the add-on asks these helpers instead of testing bpy.app.version itself."""
from __future__ import annotations

import ctypes
import math
import os
import sys

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
    "roughness": ("Roughness",),
    "ior": ("IOR",),
    "diffuse_roughness": ("Diffuse Roughness",),
    "specular_tint": ("Specular Tint",),
    "coat_roughness": ("Coat Roughness", "Clearcoat Roughness"),
    "coat_ior": ("Coat IOR",),
    "coat_tint": ("Coat Tint",),
    "sheen_roughness": ("Sheen Roughness",),
    "sheen_tint": ("Sheen Tint",),
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


def _attribute_values(mesh, name: str, domain: str, data_type: str, prop: str, dtype, count: int, width: int = 1):
    """A mesh attribute read in one block copy (Blender 3.5+ keeps positions, corner vertices, face
    flags as generic attributes; their foreach_get is a memcpy, ~100x faster than the per-item
    RNA collections). None when this Blender has no such attribute."""
    attribute = mesh.attributes.get(name)
    if attribute is None or attribute.domain != domain or attribute.data_type != data_type:
        return None
    out = np.empty(count * width, dtype=dtype)
    attribute.data.foreach_get(prop, out)
    return out.reshape(-1, width) if width > 1 else out


def mesh_positions(mesh) -> np.ndarray:
    """(V, 3) float32 vertex positions."""
    out = _attribute_values(mesh, "position", "POINT", "FLOAT_VECTOR", "vector", np.float32, len(mesh.vertices), 3)
    if out is None:  # Blender < 3.5
        out = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", out)
        out = out.reshape(-1, 3)
    return out


def corner_vertices(mesh) -> np.ndarray:
    """(loops,) int32 vertex index of every face corner."""
    out = _attribute_values(mesh, ".corner_vert", "CORNER", "INT", "value", np.int32, len(mesh.loops))
    if out is None:  # Blender < 3.6
        out = np.empty(len(mesh.loops), dtype=np.int32)
        mesh.loops.foreach_get("vertex_index", out)
    return out


def triangle_corners(mesh, n_tri: int) -> np.ndarray:
    """(T * 3,) int32 face corners (loops) of the loop triangles.

    MeshLoopTriangle.loops has no block copy: foreach_get calls its getter per triangle (~0.6 s a
    million triangles). The triangles are one contiguous array in Blender (3 ints each since 4.0,
    4 with the face before; Cycles' blender/mesh.cpp reads the same array, mesh.corner_tris(), in
    C++), so it is copied from the address RNA gives for triangle 0 (as_pointer) when the item
    addresses show that layout and sampled triangles read back the same as through RNA; else the
    per-item foreach_get."""
    triangles = mesh.loop_triangles
    if n_tri >= 2:
        first, second, last = triangles[0].as_pointer(), triangles[1].as_pointer(), triangles[n_tri - 1].as_pointer()
        stride = second - first
        if stride in (12, 16) and last - first == (n_tri - 1) * stride and first:
            rows = np.ctypeslib.as_array((ctypes.c_int32 * (n_tri * stride // 4)).from_address(first))
            out = rows.reshape(n_tri, stride // 4)[:, :3].copy().reshape(-1)  # ours: Blender's may go
            samples = {0, 1, n_tri // 3, n_tri // 2, n_tri - 1}
            if all(tuple(triangles[k].loops) == tuple(out[3 * k:3 * k + 3]) for k in samples):
                return out
    out = np.empty(n_tri * 3, dtype=np.int32)
    triangles.foreach_get("loops", out)
    return out


def triangle_faces(mesh, n_tri: int) -> np.ndarray:
    """(T,) int32 face of each loop triangle."""
    out = np.empty(n_tri, dtype=np.int32)
    if hasattr(mesh, "loop_triangle_polygons"):  # Blender 3.6+: one block copy
        mesh.loop_triangle_polygons.foreach_get("value", out)
    else:
        mesh.loop_triangles.foreach_get("polygon_index", out)
    return out


def face_material_indices(mesh) -> np.ndarray:
    """(faces,) int32 material slot of each face."""
    out = _attribute_values(mesh, "material_index", "FACE", "INT", "value", np.int32, len(mesh.polygons))
    if out is None:
        out = np.empty(len(mesh.polygons), dtype=np.int32)
        if BLENDER_VERSION >= (3, 4, 0):  # an attribute since 3.4: absent means slot 0 everywhere
            out[:] = 0
        else:
            mesh.polygons.foreach_get("material_index", out)
    return out


def face_smooth(mesh) -> np.ndarray:
    """(faces,) bool: smooth shaded. Blender 4.0 stores the inverse, the 'sharp_face' attribute,
    absent when no face is flat."""
    if BLENDER_VERSION >= (4, 0, 0):
        sharp = _attribute_values(mesh, "sharp_face", "FACE", "BOOLEAN", "value", bool, len(mesh.polygons))
        return np.ones(len(mesh.polygons), dtype=bool) if sharp is None else ~sharp
    out = np.empty(len(mesh.polygons), dtype=bool)
    mesh.polygons.foreach_get("use_smooth", out)
    return out


def triangle_corner_normals(mesh, smooth: np.ndarray, tri_loops: np.ndarray, tri_faces: np.ndarray,
                            triangles: np.ndarray) -> np.ndarray:
    """(T, 3, 3) float32 shading normals at the corners of the loop triangles, as Cycles syncs them.

    Cycles 5.0 (intern/cycles/blender/mesh.cpp) asks Blender for `normals_domain(true)`: a mesh
    without custom normals or sharp edges whose faces mix flat and smooth is in the *point*
    domain there, so its smooth faces use the vertex normals (averaged over every face, flat ones
    too) and its flat faces the face normal; only otherwise does it use Blender's corner normals,
    which split the normals at flat faces (what bpy's Mesh.corner_normals returns for such a
    mesh, whose RNA normals_domain says CORNER). smooth: per-face use_smooth; tri_loops (T*3,)
    the corners of the triangles, tri_faces (T,) their faces, triangles (T, 3) their vertices."""
    n_tri = len(tri_faces)
    if not hasattr(mesh, "corner_normals"):  # Blender < 4.1: split normals must be computed first
        mesh.calc_normals_split()
        out = np.empty(len(mesh.loops) * 3, dtype=np.float32)
        mesh.loops.foreach_get("normal", out)
        return out.reshape(-1, 3)[tri_loops].reshape(n_tri, 3, 3)
    sharp_edges = _attribute_values(mesh, "sharp_edge", "EDGE", "BOOLEAN", "value", bool, len(mesh.edges))
    any_sharp_edge = sharp_edges is not None and bool(sharp_edges.any())
    if mesh.has_custom_normals or any_sharp_edge or not smooth.any():
        out = np.empty(len(mesh.loops) * 3, dtype=np.float32)
        mesh.corner_normals.foreach_get("vector", out)
        return out.reshape(-1, 3)[tri_loops].reshape(n_tri, 3, 3)
    # point domain: the vertex normals (an array copy, where corner_normals is per-item RNA)
    vertex_normals = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertex_normals.foreach_get("vector", vertex_normals)
    normals = np.take(vertex_normals.reshape(-1, 3), triangles, axis=0)  # (faster than [triangles])
    if not smooth.all():  # flat faces: the face normal at each of their corners
        face_normals = np.empty(len(mesh.polygons) * 3, dtype=np.float32)
        mesh.polygon_normals.foreach_get("vector", face_normals)
        flat = ~smooth[tri_faces]
        normals[flat] = face_normals.reshape(-1, 3)[tri_faces[flat]][:, None, :]
    return normals


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


def isolate_embree() -> bool:
    """Import embreex so that it binds to its own bundled Embree 4.

    Blender builds that link Embree 3 as a shared library (Debian's 3.4 package) export rtc*
    symbols under the same names; the embreex extension modules would bind to those and crash on
    the first ray. Loaded with RTLD_DEEPBIND they resolve against their own libraries first.
    Only done when a shared Embree is already in the process (the bpy module links it statically).
    Returns True when the isolation was applied."""
    if not sys.platform.startswith("linux") or "embreex.rtcore_scene" in sys.modules:
        return False
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as maps:
            if "libembree" not in maps.read():
                return False
    except OSError:
        return False
    flags = sys.getdlopenflags()
    sys.setdlopenflags(flags | os.RTLD_DEEPBIND)
    try:
        import embreex.rtcore  # noqa: F401
        import embreex.rtcore_scene  # noqa: F401
        import embreex.mesh_construction  # noqa: F401
    except ImportError:
        return False  # reported when the renderer itself fails to import
    finally:
        sys.setdlopenflags(flags)
    return True


def set_pass_pixels(render_pass, pixels: np.ndarray):
    """Write (N, 4) float32 pixels into RenderPass.rect. Blender 4+ takes one flat buffer with
    foreach_set; 3.x counts rect's outer dimension (pixels), so it gets the pixel rows."""
    try:
        render_pass.rect.foreach_set(np.ascontiguousarray(pixels).reshape(-1))
    except TypeError:
        render_pass.rect = pixels


def light_node_tree(light):
    """The light's shader nodes as Cycles uses them: Blender 5 whenever a tree exists, earlier
    versions only with use_nodes (research notes: blender/light.cpp sync in both versions)."""
    tree = getattr(light, "node_tree", None)
    if tree is None:
        return None
    if BLENDER_VERSION >= (5, 0, 0):
        return tree
    return tree if getattr(light, "use_nodes", False) else None


def spot_is_square(light) -> bool:
    """SpotLight.use_square (a square cone) only exists in newer Blender versions."""
    return bool(getattr(light, "use_square", False))


def volume_scatter_phase(node) -> str:
    """Volume Scatter / Coefficients phase function; Henyey-Greenstein only before Blender 4.5."""
    return str(getattr(node, "phase", "HENYEY_GREENSTEIN"))


def render_world(view_layer, scene):
    """The world Cycles renders: View Layer > Override > World (Blender 4.2+), else the scene's."""
    return getattr(view_layer, "world_override", None) or scene.world


def use_per_user_kernel_cache() -> str | None:
    """Point numba's cache of compiled render kernels (volpath_native's @kernel functions,
    cache=True) at a writable per-user folder, and return it.

    numba's default is the renderer's own folder, which an installed add-on may not be allowed to
    write (a read-only system repository), and which Blender clears on every extension upgrade.
    Must run before volpath_native is imported: numba picks a function's cache folder when the
    function is defined. Left alone (None): a NUMBA_CACHE_DIR the user set, and the repository
    checkout (`import addon`: tests, scripts), whose cache stays next to native/'s sources and is
    shared with the CLI and the native tests. NUMBA_CACHE_DIR is process-wide: another add-on's
    numba caches land there too, which is harmless (entries are keyed by source path)."""
    package = __package__ or ""
    if os.environ.get("NUMBA_CACHE_DIR") or package == "addon" or "volpath_native" in sys.modules:
        return None
    try:
        if package.startswith("bl_ext.") and hasattr(bpy.utils, "extension_path_user"):  # 4.2+
            folder = bpy.utils.extension_path_user(package, path="numba", create=True)
        else:  # legacy add-on (Blender < 4.2 has no per-extension folder and no CACHE resource)
            folder = bpy.utils.user_resource("DATAFILES", path="volpath/numba", create=True)
    except (OSError, ValueError) as error:  # numba then falls back to ~/.cache/numba itself
        print(f"VolPath: no per-user folder for compiled kernels ({error})")
        return None
    os.environ["NUMBA_CACHE_DIR"] = folder
    if "numba" in sys.modules:  # imported by another add-on: its config was read already
        sys.modules["numba"].core.config.reload_config()
    return folder


# compat is the first module the add-on package imports (addon/__init__.py), so this runs before
# anything imports the renderer and defines its kernels.
use_per_user_kernel_cache()


# Blender's defaults of the panoramic camera settings (DNA_camera_defaults.h / Cycles' properties).
_PANORAMA_DEFAULTS = {"panorama_type": "FISHEYE_EQUISOLID", "fisheye_fov": math.pi, "fisheye_lens": 10.5,
                      "latitude_min": -0.5 * math.pi, "latitude_max": 0.5 * math.pi, "longitude_min": -math.pi,
                      "longitude_max": math.pi, "central_cylindrical_range_u_min": -math.pi,
                      "central_cylindrical_range_u_max": math.pi, "central_cylindrical_range_v_min": -1.0,
                      "central_cylindrical_range_v_max": 1.0, "central_cylindrical_radius": 1.0}


def camera_panorama(camera_data, key: str):
    """A panoramic setting of a camera: on the Camera since Blender 3.5, on its Cycles settings
    (camera.cycles) before; Blender's default where neither has it (e.g. central cylindrical
    before 4.x)."""
    if hasattr(camera_data, key):
        return getattr(camera_data, key)
    cycles = getattr(camera_data, "cycles", None)
    if cycles is not None and hasattr(cycles, key):
        return getattr(cycles, key)
    return _PANORAMA_DEFAULTS[key]
