"""Memory of a large image texture: export + image table of one SIZE x SIZE RGBA PNG (sRGB, with
alpha), peak resident memory above the baseline, in units of the image's bytes.

    .venv/bin/python tests/benchmarks/bench_texture_memory.py [--size 16384]

Not collected by pytest (benchmarks only). The issue's bound: memory bounded by the image data.
"""
import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests" / "addon"))


def peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--size", type=int, default=4096)
    args = parser.parse_args()
    import bpy
    import OpenImageIO as oiio

    import addon
    from addon.export import images as image_export
    from addon.export.shading import Reporter
    from volpath_native.shading.images import image_table, table_nbytes

    addon.register()
    n = args.size
    with tempfile.TemporaryDirectory() as folder:
        path = str(Path(folder) / "big.png")
        out = oiio.ImageOutput.create(path)
        spec = oiio.ImageSpec(n, n, 4, oiio.UINT8)
        out.open(path, spec)
        row = (np.arange(n * 4, dtype=np.uint32) % 251).astype(np.uint8).reshape(1, n, 4)
        for y in range(0, n, 256):
            rows = min(256, n - y)
            out.write_scanlines(y, y + rows, 0, np.repeat(row, rows, axis=0))
        out.close()
        image = bpy.data.images.load(path)
        image.colorspace_settings.name = "sRGB"
        data = n * n * 4
        before = peak_mib()
        start = time.perf_counter()
        registry = image_export.ImageRegistry(Reporter())
        index = registry.index_of(image, "bench")
        table = image_table(registry.images)
        seconds = time.perf_counter() - start
        after = peak_mib()
        print(f"{n} x {n} RGBA 8-bit: image data {data / 2 ** 20:.0f} MiB, table {table_nbytes(table) / 2 ** 20:.0f} "
              f"MiB, peak RSS grew {after - before:.0f} MiB = {(after - before) * 2 ** 20 / data:.2f} x the data, "
              f"{seconds:.1f} s (index {index})")


if __name__ == "__main__":
    main()
