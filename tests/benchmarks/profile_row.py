"""Profile one equal-time row's render with perf, with the numba kernels' symbols (not collected by
pytest; how session 16 found the stack copies table_ref.py removed).

numba's cached kernels carry no symbols perf can see. Imported before numba loads any kernel, this
script keeps each cached object file as numba hands it to LLVM; after a first render it reads their
symbols (`nm`: functions are weak symbols in `.ltext`), places them at the address each library
was loaded to, and writes /tmp/perf-PID.map, which `perf report` reads.

    perf record -F 1999 -g -o row.data python tests/benchmarks/profile_row.py ROW [SPP]
    mkfifo /tmp/ctl; PERF_CONTROL=/tmp/ctl perf record --control=fifo:/tmp/ctl -D -1 -F 1999 -g \
        -o row.data python tests/benchmarks/profile_row.py ROW [SPP]   (the measured render only)
    python tests/benchmarks/profile_row.py --report row.data [FUNCTION]

The report lists the kernels by their share of the compiled code's samples and, per kernel, the
share spent on stack <-> register integer moves (argument copies); with FUNCTION (a substring of a
symbol) it attributes that function's copies to the call they precede. Rows: see
bench_equal_time_table.ROWS (48x48, one thread). Needs perf and binutils (nm, objdump).
"""
from __future__ import annotations

import argparse
import bisect
import collections
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

OBJECTS = Path(tempfile.gettempdir()) / "volpath_profile_objects"
_COPY = re.compile(r"mov\s+(0x[0-9a-f]+\(%rsp\),%r\w+|%r\w+,0x[0-9a-f]+\(%rsp\))$")
_kept = []


def _keep_object_code():
    from numba.core import codegen

    original = codegen.CPUCodeLibrary._object_getbuffer_hook.__func__

    def hook(cls, ll_module):
        buf = original(cls, ll_module)
        if buf:
            _kept.append((getattr(ll_module, "_CPUCodeLibrary__library", None), bytes(buf)))
        return buf

    codegen.CPUCodeLibrary._object_getbuffer_hook = classmethod(hook)


def _executable_memory() -> list:
    """(start, bytes) of this process's anonymous executable mappings: where LLVM's loader put
    the kernels' code."""
    import ctypes

    regions = []
    for line in Path("/proc/self/maps").read_text().splitlines():
        parts = line.split()
        if len(parts) == 5 and parts[1] == "r-xp":
            lo, hi = (int(x, 16) for x in parts[0].split("-"))
            regions.append((lo, ctypes.string_at(lo, hi - lo)))
    return regions


def _load_address(path: Path, regions) -> int | None:
    """Where the object's code section (numba emits one, .ltext) was loaded: found by its own
    bytes. (The engine's symbol lookup cannot tell: a function linked into several kernels has one
    copy in each, and the lookup returns one of them for all.)"""
    code = subprocess.run(["objcopy", "-O", "binary", "--only-section=.ltext", str(path), "/dev/stdout"],
                          capture_output=True).stdout
    for offset in range(0, max(len(code) - 32, 1), 97):  # a window without relocations
        probe = code[offset:offset + 32]
        found = [lo + i - offset for lo, memory in regions for i in [memory.find(probe)] if i >= 0]
        if len(found) == 1 and all(memory.count(probe) <= 1 for _, memory in regions):
            return found[0]
    return None


def _write_map():
    OBJECTS.mkdir(exist_ok=True)
    lines, index = [], []
    regions = _executable_memory()
    for number, (library, buf) in enumerate(_kept):
        if library is None:
            continue
        path = OBJECTS / f"{number}.o"
        path.write_bytes(buf)
        base = _load_address(path, regions)
        if base is None:
            continue
        for line in subprocess.run(["nm", "-S", "--defined-only", str(path)], capture_output=True,
                                   text=True).stdout.splitlines():
            parts = line.split()
            if len(parts) == 4 and parts[2] in "TtWw":
                value, size, name = int(parts[0], 16), int(parts[1], 16), parts[3]
                lines.append(f"{base + value:x} {size:x} {name}")
                index.append((name, base + value, size, number, value))
    Path(f"/tmp/perf-{os.getpid()}.map").write_text("\n".join(lines) + "\n")
    (OBJECTS / "index.json").write_text(json.dumps(index))
    print(f"perf map: {len(lines)} symbols", flush=True)


def _perf_control(command: str) -> None:
    """Tell `perf record --control=fifo:PATH -D -1` to start or stop sampling (PERF_CONTROL=PATH),
    so that a profile holds the measured render, not the kernels' loading and the export."""
    fifo = os.environ.get("PERF_CONTROL")
    if fifo:
        with open(fifo, "w") as control:
            control.write(command + "\n")


def record(row: str, spp: int) -> None:
    _keep_object_code()
    root = Path(__file__).resolve().parents[2]
    for path in (str(root), str(root / "native"), str(Path(__file__).resolve().parent)):
        if path not in sys.path:
            sys.path.insert(0, path)
    import addon
    import bench_equal_time_table as table
    import volpath_native
    from addon.compare import volpath_engine
    from volpath_native.render import render

    addon.register()
    volpath_native.warm_up()
    for name, _, scene, _ in table.row_scenes(argparse.Namespace(rows=row, resolution=48), volpath_engine):
        scene.settings.samples, scene.settings.threads, scene.settings.seed = 4, 1, 1
        render(scene)  # most kernels loaded
        scene.settings.samples = spp
        _perf_control("enable")
        start = time.process_time()
        render(scene)
        cpu = time.process_time() - start
        _perf_control("disable")
        _write_map()  # after the render: kernels it loaded (more rounds, other signatures) included
        print(f"{name}: {cpu / (spp * scene.film.width * scene.film.height) * 1e6:.3f} us CPU per sample", flush=True)


def _disassembly(number: int, start: int = 0, stop: int = 0):
    """{offset: (instruction, relocation target or None)} of a kept object (a function's range)."""
    args = ["objdump", "-d", "-r", "--no-show-raw-insn"]
    if stop:
        args += [f"--start-address={start}", f"--stop-address={stop}"]
    out, last = {}, None
    for line in subprocess.run(args + [str(OBJECTS / f"{number}.o")], capture_output=True,
                               text=True).stdout.splitlines():
        relocation = re.match(r"\s+[0-9a-f]+: R_X86_64_64\s+(\S+)", line)
        if relocation and last is not None:
            out[last] = (out[last][0], relocation.group(1))
            continue
        instruction = re.match(r"\s+([0-9a-f]+):\s+(.*)", line)
        if instruction:
            last = int(instruction.group(1), 16)
            out[last] = (instruction.group(2).strip(), None)
    return out


def _short(symbol: str) -> str:
    return re.sub(r"B\d+v\d+B.*", "", symbol or "?")


def report(data: str, function: str | None) -> None:
    index = json.loads((OBJECTS / "index.json").read_text())
    starts = sorted((entry[1], entry) for entry in index)
    keys = [s for s, _ in starts]
    ips = [int(v, 16) for v in subprocess.run(["perf", "script", "-i", data, "-F", "ip", "-G"], capture_output=True,
                                              text=True).stdout.split() if re.fullmatch(r"[0-9a-f]+", v)]
    disassembled, per, copies = {}, collections.Counter(), collections.Counter()
    jit = 0
    for ip in ips:
        i = bisect.bisect_right(keys, ip) - 1
        if i < 0:
            continue
        name, start, size, number, value = starts[i][1]
        if not start <= ip < start + size:
            continue
        jit += 1
        if number not in disassembled:
            disassembled[number] = _disassembly(number)
        text = disassembled[number].get(ip - start + value, ("?", None))[0]
        per[name] += 1
        copies[name] += bool(_COPY.match(text))
    print(f"compiled code: {jit} of {len(ips)} samples; stack <-> register moves "
          f"{100 * sum(copies.values()) / max(jit, 1):.1f} % of it")
    for name, count in per.most_common(15):
        print(f"  {100 * count / jit:5.1f} %  {_short(name)[-60:]}  (moves {100 * copies[name] / count:.0f} %)")
    if not function:
        return
    name, start, size, number, value = max((e for e in index if function in e[0]),
                                           key=lambda e: sum(e[1] <= ip < e[1] + e[2] for ip in ips))
    code = _disassembly(number, value, value + size)
    offsets = sorted(code)
    calls, target = [], None
    for offset in offsets:
        text, relocation = code[offset]
        if text.startswith("movabs") and relocation:
            target = relocation
        if text.startswith("call"):
            calls.append((offset, target))
    call_offsets = [o for o, _ in calls]
    before, total = collections.Counter(), 0
    for ip in ips:
        if not start <= ip < start + size:
            continue
        total += 1
        offset = ip - start + value
        if _COPY.match(code.get(offset, ("", None))[0]):
            j = bisect.bisect_left(call_offsets, offset)
            before[_short(calls[j][1]) if j < len(calls) else "?"] += 1
    print(f"{_short(name)}: {total} samples; stack copies by the call they precede:")
    for callee, count in before.most_common(10):
        print(f"  {100 * count / max(total, 1):5.1f} %  {callee}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("row", nargs="?", help="a row of bench_equal_time_table.ROWS")
    parser.add_argument("spp", nargs="?", type=int, default=1024)
    parser.add_argument("--report", metavar="PERF_DATA")
    parser.add_argument("function", nargs="?", help="with --report: a symbol substring")
    args = parser.parse_args(argv)
    if args.report:
        report(args.report, args.row)  # the positional after --report DATA is the function
        return 0
    if not args.row:
        parser.error("a row, or --report PERF_DATA")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # idle BLAS threads spin and inflate process_time
    record(args.row, args.spp)
    return 0


if __name__ == "__main__":
    sys.exit(main())
