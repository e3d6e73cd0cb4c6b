"""A first render's kernel compile runs in a child process that a cancel kills at once."""
import os
import time

from volpath_native import kernel_compile


def test_cancel_kills_the_compiling_child_within_a_second(tmp_path):
    """A fresh cache: the child would compile for ~100 s; cancelled after 1 s it is gone at once
    and nothing was cached."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    assert not kernel_compile.kernels_cached(str(tmp_path))
    start = time.perf_counter()
    cancel_at = start + 1.0
    outcome = kernel_compile.compile_in_child(lambda: time.perf_counter() > cancel_at, env=env)
    returned = time.perf_counter()
    assert outcome is False and returned - cancel_at < 1.0, (outcome, returned - cancel_at)
    assert not kernel_compile.kernels_cached(str(tmp_path))


def test_kernels_cached_sees_this_sessions_cache():
    import volpath_native
    volpath_native.warm_up()
    assert kernel_compile.kernels_cached()
    # with a cache present, the child only loads it and succeeds
    assert kernel_compile.compile_in_child(lambda: False) is True
