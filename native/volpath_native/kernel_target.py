"""The CPU the numba kernels are compiled for: a portable x86-64, not this machine's exact model.

numba keys every cached kernel by (target triple, CPU name, CPU feature string); by default the
name and the ~1000-character feature string are the host's (e.g. znver3), so a cache built on one
machine is never used on another, and code built for a newer CPU could crash an older one. With
NUMBA_CPU_NAME=generic (and NUMBA_CPU_FEATURES="", numba's default for generic) the code targets
baseline x86-64 and the key is the same on every x86-64 Linux machine: the kernel cache built by
`make extension` and shipped in the volpath_native wheel (jit.py) is then found wherever it is
installed. numba's docs (envvars.rst, NUMBA_CPU_NAME) recommend exactly this for portable caches.
The render-speed cost was measured (README.md, Performance).

Must run before numba is imported (numba reads the variables when its configuration loads, and
again before each compile); volpath_native/__init__.py imports this module first. A
NUMBA_CPU_NAME the user set wins, and VOLPATH_KERNEL_CPU=host leaves numba's default (this
machine's CPU: no shipped cache, a first render compiles; used to measure the difference). The
setting is process-wide: other numba users in the same process (another Blender add-on) compile
for the portable target too, which is correct code, only possibly slower.
"""
from __future__ import annotations

import os
import sys

PORTABLE_CPU_NAME = "generic"


def choose_portable_target() -> str:
    """Set NUMBA_CPU_NAME to the portable target unless the user chose one; returns the name used."""
    if os.environ.get("NUMBA_CPU_NAME"):
        return os.environ["NUMBA_CPU_NAME"]
    if os.environ.get("VOLPATH_KERNEL_CPU", "").lower() == "host":
        return "host"
    os.environ["NUMBA_CPU_NAME"] = PORTABLE_CPU_NAME
    os.environ.pop("NUMBA_CPU_FEATURES", None)  # generic implies no extra features
    return PORTABLE_CPU_NAME


CPU_NAME = choose_portable_target()
if "numba" in sys.modules:  # imported first (another add-on, a test runner): read the variables now,
    # before our kernels are decorated (numba creates its codegen then, with the CPU it is told)
    sys.modules["numba"].core.config.reload_config()
