"""Test helpers for Blender fluid domains in the bpy 5.0.1 wheel.

The wheel registers Mantaflow's Python classes without their C++ base classes (every class's MRO
is (cls, object)), so its fluid scripts fail ("'LevelsetGrid' object has no attribute 'setConst'")
and a domain's runtime holds no voxels: Cycles then renders nothing, and an adaptive domain even
aborts the process. `restore_mantaflow_bases()` gives the classes their bases back (their MRO, via
ctypes, as Mantaflow declares them: Grid<T> : GridBase : PbClass, LevelsetGrid : Grid<Real>, ...);
with it the wheel's runtime loads caches exactly as Blender 3.4 does (density checked equal) and
Cycles renders fluid domains, which the agreement tests need. Only tests call it: the add-on itself
reads the cache files instead (addon/export/fluid.py).

Any process that evaluated a domain must free it before the interpreter exits (Mantaflow aborts
with "can't clean grid cache" otherwise): `free_blend_data()`; tests/conftest.py does it at the end
of the session.
"""
from __future__ import annotations

import ctypes
import shutil
import sys
from pathlib import Path

DATA = Path(__file__).resolve().parent / "addon_volume" / "data"

# Mantaflow's class hierarchy (extern/mantaflow/preprocessed/*.h), by the Python type names.
_BASES = {
    "GridBase": "PbClass", "Grid_Real": "GridBase", "Grid_Vec3": "GridBase", "Grid_int": "GridBase",
    "LevelsetGrid": "Grid_Real", "MACGrid": "Grid_Vec3", "FlagGrid": "Grid_int",
    "Grid4dBase": "PbClass", "Grid4d_Real": "Grid4dBase", "Grid4d_Vec3": "Grid4dBase",
    "Grid4d_Vec4": "Grid4dBase", "Grid4d_int": "Grid4dBase",
    "ParticleBase": "PbClass", "ParticleSystem_BasicParticleData": "ParticleBase",
    "ParticleSystem_ParticleIndexData": "ParticleBase", "ParticleSystem_TurbulenceParticleData": "ParticleBase",
    "ParticleSystem_VortexParticleData": "ParticleBase",
    "BasicParticleSystem": "ParticleSystem_BasicParticleData",
    "ParticleIndexSystem": "ParticleSystem_ParticleIndexData",
    "TurbulenceParticleSystem": "ParticleSystem_TurbulenceParticleData",
    "VortexParticleSystem": "ParticleSystem_VortexParticleData",
    "ParticleDataBase": "PbClass", "ParticleDataImpl_Real": "ParticleDataBase",
    "ParticleDataImpl_Vec3": "ParticleDataBase", "ParticleDataImpl_int": "ParticleDataBase",
    "MeshDataBase": "PbClass", "MeshDataImpl_Real": "MeshDataBase", "MeshDataImpl_Vec3": "MeshDataBase",
    "MeshDataImpl_int": "MeshDataBase", "Mesh": "PbClass", "VortexSheetMesh": "Mesh",
    "Shape": "PbClass", "NullShape": "Shape", "Box": "Shape", "Sphere": "Shape", "Cylinder": "Shape",
    "Slope": "Shape", "Solver": "PbClass", "NoiseField": "PbClass", "MovingObstacle": "PbClass",
    "Timings": "PbClass",
}
_TYPE_WORDS = 64  # pointer-sized slots of PyTypeObject searched for tp_base / tp_bases / tp_mro
_kept = []  # the new MRO/bases tuples must outlive the types


def mantaflow_broken() -> bool:
    import bpy  # noqa: F401  (registers the manta module)

    manta = sys.modules.get("manta")
    return manta is not None and not hasattr(manta.LevelsetGrid, "setConst")


def restore_mantaflow_bases() -> None:
    """Idempotent; raises if the wheel's Mantaflow classes are not what this expects."""
    if not mantaflow_broken():
        return
    manta = sys.modules["manta"]
    classes = {value.__name__: value for value in vars(manta).values() if isinstance(value, type)}
    for name in _BASES:
        cls = classes[name]
        chain, base = [cls], _BASES[name]
        while base:
            chain.append(classes[base])
            base = _BASES.get(base)
        mro, bases = tuple(chain) + (object,), (classes[_BASES[name]],)
        slots = (ctypes.c_void_p * _TYPE_WORDS).from_address(id(cls))
        found = {key: [i for i in range(_TYPE_WORDS) if slots[i] == id(value)]
                 for key, value in (("mro", cls.__mro__), ("bases", cls.__bases__), ("base", object))}
        if any(len(where) != 1 for where in found.values()):
            raise RuntimeError(f"unexpected layout of Mantaflow type {name}: {found}")
        _kept.extend((mro, bases))
        slots[found["mro"][0]], slots[found["bases"][0]] = id(mro), id(bases)
        slots[found["base"][0]] = id(bases[0])
        ctypes.pythonapi.PyType_Modified(ctypes.py_object(cls))
    if mantaflow_broken():
        raise RuntimeError("Mantaflow's classes still lack their base classes")


def free_blend_data() -> None:
    """Replace the open file by an empty one, freeing fluid runtimes while Python still runs."""
    import bpy

    bpy.ops.wm.read_homefile(use_empty=True)


def copy_data(target: Path) -> Path:
    """The baked test domains (tests/addon_volume/data) copied to `target` (renders must not
    touch the repository's copy)."""
    shutil.copytree(DATA, target, ignore=shutil.ignore_patterns("*.py", "waveletNoiseTile.bin"))
    return target


def open_domain(folder: Path, name: str, frame: int):
    """Open <folder>/<name>.blend at `frame`; returns (scene, domain object)."""
    import bpy

    bpy.ops.wm.open_mainfile(filepath=str(folder / f"{name}.blend"))
    scene = bpy.context.scene
    scene.frame_set(frame)
    return scene, bpy.data.objects["Smoke Domain"]
