"""VolPath: a volumetric path tracer for Blender, compared against Cycles.

This package is the Blender side (everything that imports bpy). It is loaded three ways, so it
only uses relative imports: `import addon` from the repository (tests, scripts), the extension
`bl_ext.<repo>.volpath` (Blender 4.2+), and the legacy add-on `volpath` (Blender 3.4 .. 4.1).
The renderer itself is the bpy-free package `volpath_native`.
"""

bl_info = {  # read by Blender < 4.2; 4.2+ reads blender_manifest.toml
    "name": "VolPath",
    "author": "VolPath developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Render > Render Engine > VolPath",
    "description": "Volumetric path tracer for participating media (fog, smoke, absorbing liquids)",
    "category": "Render",
}

import bpy  # noqa: E402  (bl_info must come first for Blender's legacy add-on scanner)

from . import compat, engine, io_vpscene, kernel_status, properties, ui  # noqa: E402

_registered = False
_compare = None  # the optional comparison package (addon/compare), when present


def _load_compare():
    """The colleague's comparison tools are optional: a failure there must not stop the engine."""
    try:
        from . import compare
    except ImportError:
        return None
    except Exception as error:  # broken optional package: report, keep the engine usable
        print(f"VolPath: comparison tools unavailable: {type(error).__name__}: {error}")
        return None
    return compare if hasattr(compare, "register") else None


def register():
    """Register the engine, its settings and UI (idempotent: a second call does nothing)."""
    global _registered, _compare
    if _registered:
        return
    compat.isolate_embree()  # before anything (the comparison tools too) imports the renderer
    properties.register()
    engine.register()
    ui.register()
    io_vpscene.register()
    kernel_status.register()  # kernels compile in the background now if no cache can serve them
    _compare = _load_compare()
    if _compare is not None:
        try:
            _compare.register()
        except Exception as error:
            print(f"VolPath: comparison tools failed to register: {type(error).__name__}: {error}")
            _compare = None
    _registered = True


def unregister():
    global _registered, _compare
    if not _registered:
        return
    if _compare is not None:
        try:
            _compare.unregister()
        except Exception as error:
            print(f"VolPath: comparison tools failed to unregister: {type(error).__name__}: {error}")
        _compare = None
    kernel_status.unregister()
    io_vpscene.unregister()
    ui.unregister()
    engine.unregister()
    properties.unregister()
    _registered = False
