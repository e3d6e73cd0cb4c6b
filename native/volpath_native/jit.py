"""Compilation settings shared by every numba kernel of the renderer.

Why numba: the wavefront keeps its shape (queues of paths, Embree queries in bulk between
stages), but each stage's per-path arithmetic runs as one compiled loop instead of dozens of numpy
passes with temporaries and gathers -- the numpy version spent ~5x Embree's time on bookkeeping
(native/README.md, Performance). pbrt-v4's CPU wavefront (src/pbrt/wavefront/) likewise runs each
stage as a compiled ParallelFor over its queue.

- cache=True: compiled machine code is kept on disk, so only the first render after an install
  or change pays for compilation. numba invalidates a cached function only when its own file
  changes, not when a function it calls from another module does, so the cache lives in a folder
  named after a hash of all this package's sources, sub-packages and .npy tables included: any
  edit starts a fresh cache. The folder's parent is NUMBA_CACHE_DIR if set (the Blender add-on
  points it at Blender's user folders), else ~/.cache/volpath/numba.
- nogil=True: kernels release the GIL, so render threads run them in parallel.
- error_model="numpy": division by zero gives inf/nan like numpy instead of raising, and no
  per-division checks slow the loops; kernels guard their divisions explicitly.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numba


def _cache_dir() -> str:
    sources = hashlib.sha1()
    package = Path(__file__).parent
    # sub-packages too (bsdfs/), and the data files compiled code may depend on
    for path in sorted(p for p in package.rglob("*") if p.suffix in (".py", ".npy") and "__pycache__" not in p.parts):
        sources.update(path.relative_to(package).as_posix().encode())
        sources.update(path.read_bytes())
    base = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "volpath", "numba")
    return os.path.join(base, f"{numba.__version__}-{sources.hexdigest()[:16]}")


# set before any kernel is decorated: numba reads it when a cached function is created
numba.config.CACHE_DIR = _cache_dir()

kernel = numba.njit(cache=True, nogil=True, error_model="numpy")
# The per-path stage loops: no allocation inside (callers pass every buffer), hence no reference
# counting of the many table arrays they touch -- with it, passing the scene tables to a callee
# cost more than the callee's arithmetic. inline="always" for large helpers of a stage that take
# the tables (LLVM would not inline them and every call would copy the tables' descriptors).
stage_kernel = numba.njit(cache=True, nogil=True, error_model="numpy", _nrt=False)
inline_stage_kernel = numba.njit(cache=True, nogil=True, error_model="numpy", _nrt=False, inline="always")
