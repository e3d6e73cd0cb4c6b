"""Compilation settings shared by every numba kernel of the renderer.

Why numba: the wavefront keeps its shape (queues of paths, Embree queries in bulk between
stages), but each stage's per-path arithmetic runs as one compiled loop instead of dozens of numpy
passes with temporaries and gathers -- the numpy version spent ~5x Embree's time on bookkeeping
(native/README.md, Performance). pbrt-v4's CPU wavefront (src/pbrt/wavefront/) likewise runs each
stage as a compiled ParallelFor over its queue.

- cache=True: compiled machine code is kept on disk, so only the first render after a change
  pays for compilation. numba invalidates a cached function only when its own file changes, not
  when a function it calls from another module does, so the cache lives in a folder named after
  numba's version and a hash of all this package's sources (sub-packages and .npy tables
  included): any edit starts a fresh cache. The folder's parent is NUMBA_CACHE_DIR if set (the
  Blender add-on points it at Blender's user folders), else ~/.cache/volpath/numba.
- Kernels found after an install: numba's own locators stamp a cache with the source file's
  mtime and place it by the source's absolute path, so a cache built elsewhere is never used
  (numba/core/caching.py, _SourceFileBackedLocatorMixin.get_source_stamp, get_suitable_cache_subpath).
  KernelCacheLocator instead places it by the path inside this package and stamps it with the
  source hash and the module name (a cache pickles its module's name; another name must be a
  clean miss, not an import error). `make extension` builds the cache for the portable CPU target
  (kernel_target.py) and ships it inside the package (PREBUILT_DIR); on import, a missing per-user
  cache is seeded from it (seed_from_prebuilt), so a first render loads instead of compiling.
- nogil=True: kernels release the GIL, so render threads run them in parallel.
- error_model="numpy": division by zero gives inf/nan like numpy instead of raising, and no
  per-division checks slow the loops; kernels guard their divisions explicitly.
"""
from __future__ import annotations

import glob
import hashlib
import os
import shutil
from pathlib import Path

import numba
import numba.core.typing.templates
from numba.core import caching


PACKAGE_DIR = Path(__file__).resolve().parent
# Where `make extension` puts the shipped kernels: PREBUILT_DIR/<CACHE_KEY>/ mirrors the cache.
PREBUILT_DIR = PACKAGE_DIR / "prebuilt_kernels"


def source_hash() -> str:
    """sha1 of every source and table file of the package (paths and contents)."""
    sources = hashlib.sha1()
    # sub-packages too (bsdfs/), and the data files compiled code may depend on
    for path in sorted(p for p in PACKAGE_DIR.rglob("*") if p.suffix in (".py", ".npy")
                       and "__pycache__" not in p.parts and PREBUILT_DIR.name not in p.parts):
        sources.update(path.relative_to(PACKAGE_DIR).as_posix().encode())
        sources.update(path.read_bytes())
    return sources.hexdigest()


SOURCE_HASH = source_hash()
CACHE_KEY = f"{numba.__version__}-{SOURCE_HASH[:16]}"


def cache_root() -> str:
    return os.environ.get("NUMBA_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "volpath", "numba")


class KernelCacheLocator(caching._CacheLocator):
    """numba cache locator for this package's kernels: <cache root>/<CACHE_KEY>/<sub-package>/,
    valid while the sources hash and the module name are the same, wherever the package lives."""

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._module = py_func.__module__
        relative = Path(py_file).resolve().parent.relative_to(PACKAGE_DIR)
        self._cache_path = os.path.join(KERNEL_CACHE_DIR, *relative.parts)

    def get_cache_path(self):
        return self._cache_path

    def get_source_stamp(self):
        return ("volpath_native sources", SOURCE_HASH, self._module)

    def get_disambiguator(self):
        return str(self._lineno)

    @classmethod
    def from_function(cls, py_func, py_file):
        try:
            Path(py_file).resolve().relative_to(PACKAGE_DIR)
        except (ValueError, OSError):
            return None  # not one of ours: numba's own locators decide
        locator = cls(py_func, py_file)
        try:
            locator.ensure_cache_path()
        except OSError:
            return None  # not writable: numba falls back to its own locators (and compiles)
        return locator


def seed_from_prebuilt(target: str, prebuilt: Path | None = None) -> int:
    """Copy the shipped kernels for these sources into the cache folder `target`: each index
    (.nbi) that is missing there, with its data files. An index already there (compiled here, or
    seeded before) is left alone. Returns the number of indexes copied."""
    source = (prebuilt or PREBUILT_DIR) / CACHE_KEY
    if not source.is_dir():
        return 0
    copied = 0
    for index in source.rglob("*.nbi"):
        relative = index.relative_to(source)
        destination = Path(target) / relative
        if destination.exists():
            continue
        try:
            destination.parent.mkdir(parents=True, exist_ok=True)
            stem = index.name[:-len(".nbi")]
            for data in index.parent.glob(glob.escape(stem) + ".*.nbc"):
                shutil.copyfile(data, destination.parent / data.name)
            # the index last, so that a reader never sees an index without its data
            partial = destination.with_name(destination.name + ".part")
            shutil.copyfile(index, partial)
            os.replace(partial, destination)
            copied += 1
        except OSError:
            return copied  # read-only or full: kernels compile as without a shipped cache
    return copied


KERNEL_CACHE_DIR = os.path.join(cache_root(), CACHE_KEY)
KERNELS_SEEDED = seed_from_prebuilt(KERNEL_CACHE_DIR)
# numba's own locators for anything else (and for us when the folder is not writable); set
# before any kernel is decorated: numba picks a function's locator when caching is enabled.
numba.config.CACHE_DIR = KERNEL_CACHE_DIR
if KernelCacheLocator not in caching.CacheImpl._locator_classes:
    caching.CacheImpl._locator_classes.insert(0, KernelCacheLocator)

def widened_scalar(t):
    """The one type a kernel parameter is compiled for when a caller passes scalar type t:
    literals lose their value (a constant 0 or a closure kind is a run-time int64) and narrower
    signed ints become int64. float32 stays float32: the texture kernels compute in float32 on
    purpose, to match Cycles' float arithmetic bit for bit (tests/shading). Arrays, tuples and
    records are unchanged."""
    t = numba.types.unliteral(t)
    if isinstance(t, numba.types.Integer) and t.signed and t.bitwidth < 64:
        return numba.types.int64
    return t


_numba_get_call_template = numba.core.dispatcher.Dispatcher.get_call_template


def _get_call_template(self, args, kws):
    """Dispatcher.get_call_template for kernels called from kernels: one compiled signature per
    parameter's scalar kind. numba compiles a callee for the argument types as it sees them
    during type inference, and those include transient ones -- `count = 0` before a loop is
    first Literal[int](0), a constant argument is Literal[int](k), hit arrays give int32 --
    so a callee, and all it calls, compiled up to 16 times. Here it compiles once for
    the widened types and numba converts the caller's values to them (the template resolves the
    call against the compiled signatures). A callee that cannot type with widened arguments
    (one needing a literal) is compiled for the arguments as given, as numba does."""
    if not (self._can_compile and getattr(self.py_func, "__module__", "").startswith(_OUR_MODULES)):
        return _numba_get_call_template(self, args, kws)
    pysig, folded = self._compiler.fold_argument_types(args, kws)
    widened = tuple(widened_scalar(a) for a in folded)
    try:
        self.compile(widened)
    except numba.core.errors.TypingError:
        return _numba_get_call_template(self, args, kws)
    name = self.py_func.__name__
    template = numba.core.typing.templates.make_concrete_template(
        f"CallTemplate({name})", key=name, signatures=self.nopython_signatures)
    return template, pysig, folded, {}


_OUR_MODULES = __package__ + "."
numba.core.dispatcher.Dispatcher.get_call_template = _get_call_template


kernel = numba.njit(cache=True, nogil=True, error_model="numpy")
# The per-path stage loops: no allocation inside (callers pass every buffer), hence no reference
# counting of the many table arrays they touch -- with it, passing the scene tables to a callee
# cost more than the callee's arithmetic. inline="always" for large helpers of a stage that take
# the tables (LLVM would not inline them and every call would copy the tables' descriptors).
stage_kernel = numba.njit(cache=True, nogil=True, error_model="numpy", _nrt=False)
inline_stage_kernel = numba.njit(cache=True, nogil=True, error_model="numpy", _nrt=False, inline="always")
