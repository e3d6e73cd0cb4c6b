"""Benchmark: the kernels' cold compile (not collected by pytest).

Runs `volpath_native.warm_up(thorough=True)` -- what `make extension` ships and what a first render
without shipped kernels pays -- in a child process with an empty NUMBA_CACHE_DIR, and reports its
CPU seconds (this child only: other load on the machine shifts wall time, much less CPU time),
the kernels that took longest (numba's compile events, time with the kernels they call
subtracted) and every kernel compiled more than once (one compile per distinct argument-type
tuple: jit.py compiles kernels called from kernels once per parameter kind). The baseline in the
same run: the CPU seconds numba takes to compile a fixed reference function (not our sources),
so the ratio compares runs on machines of different speed.

    python tests/benchmarks/bench_compile.py [--top 15]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

_CHILD = r'''
import json, resource, sys, time
from numba.core import event

def name_of(ev):
    f = ev.data["dispatcher"].py_func
    return f"{f.__module__}.{f.__qualname__}"

marks = []
class Recorder(event.Listener):
    def on_start(self, ev):
        marks.append((time.process_time(), True, name_of(ev), str(ev.data["args"])))
    def on_end(self, ev):
        marks.append((time.process_time(), False, name_of(ev), None))

def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime

mode = sys.argv[1]
if mode == "reference":
    import numba
    source = "def reference(x, y):\n    a = 0.0\n" + "".join(
        f"    if x > {k}:\n        a += math.sin(x * {k}.5 + y) * math.exp(-y * {k})\n    else:\n"
        f"        a -= math.sqrt(abs(x - {k})) / (1.0 + y * y)\n" for k in range(60)) + "    return a\n"
    scope = {"math": __import__("math")}
    exec(source, scope)
    start = cpu()
    numba.njit(scope["reference"]).compile("float64(float64, float64)")
    print(json.dumps({"cpu": cpu() - start}))
else:
    event.register("numba:compile", Recorder())
    start = cpu()
    import volpath_native
    volpath_native.warm_up(thorough=True)
    total = cpu() - start
    exclusive, signatures, stack = {}, {}, []
    for t, starting, name, args in marks:
        if starting:
            stack.append([name, t, 0.0])
            signatures.setdefault(name, []).append(args)
        else:
            name, t0, inner = stack.pop()
            exclusive[name] = exclusive.get(name, 0.0) + (t - t0) - inner
            if stack:
                stack[-1][2] += t - t0
    print(json.dumps({"cpu": total, "exclusive": exclusive, "signatures": signatures}))
'''


def _child(mode: str, cache: str) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "native"), env.get("PYTHONPATH", "")])
    out = subprocess.run([sys.executable, "-c", _CHILD, mode], env=env, check=True, capture_output=True,
                         text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--top", type=int, default=15)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="volpath_bench_compile_") as cache:
        reference = _child("reference", cache)["cpu"]
        result = _child("kernels", cache)
    total = result["cpu"]
    print(f"cold warm_up(thorough=True): {total:.1f} CPU-s; reference function {reference:.2f} CPU-s; "
          f"ratio {total / reference:.0f}")
    print(f"{'CPU-s':>8}  kernel (its callees' compile subtracted)")
    for name, seconds in sorted(result["exclusive"].items(), key=lambda kv: -kv[1])[:args.top]:
        print(f"{seconds:8.1f}  {name}")
    repeated = {n: s for n, s in result["signatures"].items() if len(s) > 1}
    print(f"kernels compiled more than once: {len(repeated)}")
    for name, sigs in sorted(repeated.items(), key=lambda kv: -len(kv[1])):
        print(f"  {len(sigs)}x {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
