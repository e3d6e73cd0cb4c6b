"""The Embree 4 library embreex ships, loaded through ctypes (RTLD_LOCAL): the set-up calls made
from Python (device, scenes, geometries, buffers, commits) go through its handle, and the query
entry points are registered in LLVM's symbol table under names of our own (llvmlite add_symbol:
"volpath_rtcIntersect1" -> this library's rtcIntersect1), so compiled query loops call them by
name. Calls by name keep those loops in numba's on-disk cache (a ctypes function pointer would be
a constant address baked into the code, which numba refuses to cache; the name is resolved again
when the cached code is loaded). Names of our own because a process may hold another Embree:
Debian's Blender 3.4 links libembree3, whose rtcIntersect1 (another signature) a lookup by the
plain name finds first.

Enum values and struct layouts: Embree 4's public headers (include/embree4/rtcore_common.h,
rtcore_buffer.h, rtcore_geometry.h, rtcore_scene.h, rtcore_ray.h, rtcore_quaternion.h); the ray
and hit layouts are checked on the loaded library by tests/native/test_embree_binding.py.
"""
from __future__ import annotations

import ctypes
import glob
import os
from pathlib import Path

# rtcore_geometry.h RTCGeometryType
GEOMETRY_TYPE_TRIANGLE = 0
GEOMETRY_TYPE_INSTANCE = 121
# rtcore_buffer.h RTCBufferType
BUFFER_TYPE_INDEX = 0
BUFFER_TYPE_VERTEX = 1
# rtcore_common.h RTCFormat
FORMAT_UINT3 = 0x5003
FORMAT_FLOAT3 = 0x9003
FORMAT_FLOAT3X4_ROW_MAJOR = 0x9134
# rtcore_common.h RTCBuildQuality
BUILD_QUALITY_LOW, BUILD_QUALITY_MEDIUM, BUILD_QUALITY_HIGH = 0, 1, 2
# rtcore_scene.h RTCSceneFlags
SCENE_FLAG_COMPACT = 1 << 1
SCENE_FLAG_ROBUST = 1 << 2
# rtcore_common.h RTC_INVALID_GEOMETRY_ID
INVALID_ID = 0xFFFFFFFF

# rtcore_ray.h: RTCRayHit = RTCRay (48 bytes: org, tnear, dir, time, tfar, mask, id, flags) then
# RTCHit (Ng, u, v, primID, geomID, instID[RTC_MAX_INSTANCE_LEVEL_COUNT = 1 in embreex's build]
# and, with instance arrays compiled in, instPrimID[1]); 16-byte aligned. Offsets in 4-byte words.
RAY_ORG, RAY_TNEAR, RAY_DIR, RAY_TIME, RAY_TFAR, RAY_MASK, RAY_ID, RAY_FLAGS = 0, 3, 4, 7, 8, 9, 10, 11
HIT_NG, HIT_U, HIT_V, HIT_PRIM, HIT_GEOM, HIT_INST = 12, 15, 16, 17, 18, 19
RAYHIT_WORDS = 24  # room for instPrimID and the alignment padding (96 bytes)


class RTCQuaternionDecomposition(ctypes.Structure):
    """rtcore_quaternion.h: M = translation * rotation(quaternion) * (scale/skew upper triangle + shift)."""
    _fields_ = [(name, ctypes.c_float) for name in (
        "scale_x", "scale_y", "scale_z", "skew_xy", "skew_xz", "skew_yz", "shift_x", "shift_y", "shift_z",
        "quaternion_r", "quaternion_i", "quaternion_j", "quaternion_k",
        "translation_x", "translation_y", "translation_z")]


def library_path() -> str:
    """The libembree4 shared library inside the installed embreex wheel (VOLPATH_EMBREE_LIBRARY
    overrides it)."""
    override = os.environ.get("VOLPATH_EMBREE_LIBRARY")
    if override:
        return override
    import importlib.util
    spec = importlib.util.find_spec("embreex")  # located, not imported (its modules are not needed)
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("embreex is not installed: it provides the Embree 4 library")
    root = Path(list(spec.submodule_search_locations)[0]).resolve().parent
    for pattern in ("embreex.libs/libembree4*.so*", "embreex/.dylibs/libembree4*.dylib", "embreex/embree4.dll",
                    "embreex.libs/embree4*.dll", "embreex/libembree4*.so*"):
        found = sorted(glob.glob(str(root / pattern)))
        if found:
            return found[0]
    raise ImportError(f"no Embree 4 library found in the embreex installation at {root}")


PATH = library_path()
_lib = ctypes.CDLL(PATH)

_VP, _U, _SZ, _F = ctypes.c_void_p, ctypes.c_uint, ctypes.c_size_t, ctypes.c_float
_SIGNATURES = {
    "rtcNewDevice": (_VP, [ctypes.c_char_p]),
    "rtcReleaseDevice": (None, [_VP]),
    "rtcGetDeviceError": (ctypes.c_int, [_VP]),
    "rtcGetDeviceLastErrorMessage": (ctypes.c_char_p, [_VP]),
    "rtcNewScene": (_VP, [_VP]),
    "rtcReleaseScene": (None, [_VP]),
    "rtcSetSceneFlags": (None, [_VP, ctypes.c_int]),
    "rtcSetSceneBuildQuality": (None, [_VP, ctypes.c_int]),
    "rtcCommitScene": (None, [_VP]),
    "rtcAttachGeometry": (_U, [_VP, _VP]),
    "rtcNewGeometry": (_VP, [_VP, ctypes.c_int]),
    "rtcReleaseGeometry": (None, [_VP]),
    "rtcCommitGeometry": (None, [_VP]),
    "rtcSetGeometryBuildQuality": (None, [_VP, ctypes.c_int]),
    "rtcSetGeometryMask": (None, [_VP, _U]),
    "rtcSetSharedGeometryBuffer": (None, [_VP, ctypes.c_int, _U, ctypes.c_int, _VP, _SZ, _SZ, _SZ]),
    "rtcSetGeometryTimeStepCount": (None, [_VP, _U]),
    "rtcSetGeometryInstancedScene": (None, [_VP, _VP]),
    "rtcSetGeometryTransform": (None, [_VP, _U, ctypes.c_int, _VP]),
    "rtcSetGeometryTransformQuaternion": (None, [_VP, _U, ctypes.POINTER(RTCQuaternionDecomposition)]),
    "rtcGetSceneBounds": (None, [_VP, _VP]),
}


class _Api:
    def __init__(self):
        for name, (restype, argtypes) in _SIGNATURES.items():
            function = getattr(_lib, name)
            function.restype, function.argtypes = restype, argtypes
            setattr(self, name[3:], function)  # rtcNewScene -> api.NewScene


api = _Api()


QUERY_SYMBOLS = ("rtcIntersect1", "rtcOccluded1")
SYMBOL_PREFIX = "volpath_"


def register_symbols():
    """Make this library's query entry points resolvable as volpath_<name> in numba-compiled code
    (explicit symbols are searched before any loaded library; idempotent)."""
    import llvmlite.binding as llvm
    for name in QUERY_SYMBOLS:
        llvm.add_symbol(SYMBOL_PREFIX + name, ctypes.cast(getattr(_lib, name), ctypes.c_void_p).value)


register_symbols()
