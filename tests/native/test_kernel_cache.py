"""Compiled kernels are found wherever the package is installed (jit.KernelCacheLocator: keyed by
a hash of the sources, not by file times or paths), and a shipped copy (jit.PREBUILT_DIR) seeds
an empty per-user cache, so that a first render after an install loads instead of compiling."""
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

from volpath_native import jit, kernel_compile, kernel_target
from volpath_native.sampling import uniform1

# A child Python imports the package from `root`, calls one kernel and prints the key its sources
# hash to and whether the kernel came from the cache or was compiled.
_CHILD = """
import sys
sys.path.insert(0, sys.argv[1])
import numpy as np
import volpath_native
from volpath_native import jit
from volpath_native.sampling import uniform1
assert volpath_native.__file__.startswith(sys.argv[1]), volpath_native.__file__
uniform1(np.uint64(7), 1)
print("KEY", jit.CACHE_KEY, "HITS", sum(uniform1.stats.cache_hits.values()),
      "MISSES", sum(uniform1.stats.cache_misses.values()), "SEEDED", jit.KERNELS_SEEDED)
"""


def _copy_package(destination: Path) -> Path:
    """The installed package copied elsewhere with fresh file times (as an unzipped install)."""
    target = destination / "volpath_native"
    shutil.copytree(jit.PACKAGE_DIR, target, ignore=shutil.ignore_patterns("__pycache__", jit.PREBUILT_DIR.name))
    later = time.time() + 3600
    for path in target.rglob("*"):
        os.utime(path, (later, later))
    return destination


def _child(root: Path, cache_root: Path) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_root))
    proc = subprocess.run([sys.executable, "-c", _CHILD, str(root)], env=env, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    words = proc.stdout.split()
    return {"key": words[words.index("KEY") + 1], "hits": int(words[words.index("HITS") + 1]),
            "misses": int(words[words.index("MISSES") + 1]), "seeded": int(words[words.index("SEEDED") + 1])}


def test_portable_cpu_target_is_chosen_before_numba_loads():
    import numba

    assert kernel_target.CPU_NAME == os.environ["NUMBA_CPU_NAME"]
    if not os.environ.get("VOLPATH_KERNEL_CPU"):
        assert numba.config.CPU_NAME == "generic" and numba.config.CPU_FEATURES == ""
        assert kernel_compile.codegen_key()[1:] == ("generic", "")


def test_cache_is_found_from_another_path_with_other_file_times(tmp_path):
    import numpy as np

    uniform1(np.uint64(7), 1)  # compiled or loaded here: the session's cache has it now
    copy = _copy_package(tmp_path / "elsewhere")
    found = _child(copy, Path(jit.cache_root()))
    assert found["key"] == jit.CACHE_KEY
    assert found["hits"] == 1 and found["misses"] == 0, found


def test_an_edited_source_is_a_fresh_cache(tmp_path):
    """The planted change: one byte more in one source must not load the old machine code."""
    copy = _copy_package(tmp_path / "edited")
    sampling = copy / "volpath_native" / "sampling.py"
    sampling.write_text(sampling.read_text() + "\n")
    empty_root = tmp_path / "cache"
    shutil.copytree(jit.KERNEL_CACHE_DIR, empty_root / jit.CACHE_KEY)  # the unedited cache, under its key
    found = _child(copy, empty_root)
    assert found["key"] != jit.CACHE_KEY
    assert found["hits"] == 0 and found["misses"] == 1, found


def test_shipped_kernels_seed_an_empty_cache(tmp_path):
    import numpy as np

    uniform1(np.uint64(7), 1)
    copy = _copy_package(tmp_path / "installed")
    prebuilt = copy / "volpath_native" / jit.PREBUILT_DIR.name / jit.CACHE_KEY
    shutil.copytree(jit.KERNEL_CACHE_DIR, prebuilt)
    empty_root = tmp_path / "fresh_user"
    found = _child(copy, empty_root)
    assert found["seeded"] > 0 and found["hits"] == 1 and found["misses"] == 0, found
    assert kernel_compile.kernels_cached(str(empty_root / jit.CACHE_KEY)) == kernel_compile.kernels_cached()
    again = _child(copy, empty_root)  # seeded once: nothing more to copy
    assert again["seeded"] == 0 and again["hits"] == 1, again


def test_kernels_cached_rejects_another_cpu_target(tmp_path, monkeypatch):
    """An index compiled for another CPU (name, features) would compile on load: not cached."""
    import numba
    import volpath_native

    volpath_native.warm_up()
    assert kernel_compile.kernels_cached()
    try:
        monkeypatch.setenv("NUMBA_CPU_NAME", "haswell")
        monkeypatch.setenv("NUMBA_CPU_FEATURES", "+avx2")
        assert not kernel_compile.kernels_cached()
    finally:  # numba's configuration back to this process' target before anything compiles
        monkeypatch.undo()
        numba.core.config.reload_config()
    assert kernel_compile.kernels_cached()
