"""Run every tests/benchmarks/bench_*.py in turn (`make bench`); extra arguments are passed on."""
import runpy
import sys
import time
from pathlib import Path

here = Path(__file__).resolve().parent
root = here.parent.parent
for p in (str(root), str(root / "native")):
    if p not in sys.path:
        sys.path.insert(0, p)
failed = []
for script in sorted(here.glob("bench_*.py")):
    print(f"==> {script.name}", flush=True)
    start = time.perf_counter()
    try:
        runpy.run_path(str(script), run_name="__main__")
    except SystemExit as exc:
        if exc.code not in (0, None):
            failed.append(script.name)
    except Exception as exc:  # keep going: one broken benchmark must not hide the others
        print(f"{script.name} failed: {exc!r}")
        failed.append(script.name)
    print(f"<== {script.name} ({time.perf_counter() - start:.1f} s)\n", flush=True)
sys.exit(1 if failed else 0)
