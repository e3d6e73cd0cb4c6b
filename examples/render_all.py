"""Batch: build every example scene, save its .blend, render it with VolPath and Cycles, compare.

    .venv/bin/python examples/render_all.py OUT_DIR [--resolution 64x64] [--spp 256] [--runs 8]
                                           [--mode equal-samples|equal-time] [--seconds 20]

Writes OUT_DIR/blend/<scene>.blend, OUT_DIR/<scene>/ (EXRs, sheet.png, report.json, report.md),
OUT_DIR/albedo_grid/albedo_grid.png (the course experiment: both engines, one sheet) and
OUT_DIR/summary.md (one line per scene). Exit status 1 if any scene disagrees.
"""
import argparse
import importlib
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

EXAMPLES = ("cornell_fog", "cornell_defaults", "spot_godrays", "area_light", "sun_window", "sun_window_godrays",
            "absorbing_medium", "anisotropic_forward", "anisotropic_backward", "emissive_medium",
            "nested_media", "heavy_density", "near_clip_in_fog", "albedo_grid", "smoke_plume", "glass_of_liquid",
            "metals_glossy", "coat_sheen", "alpha_rough_glass")


def main(argv=None) -> int:
    import addon
    from addon.compare import cli, runner
    from examples import albedo_grid, scene_builder

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--resolution", type=cli._parse_resolution, default=(64, 64))
    parser.add_argument("--spp", type=int, default=256)
    parser.add_argument("--runs", type=int, default=8)
    parser.add_argument("--mode", choices=runner.MODES, default="equal-samples")
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--only", nargs="*", choices=EXAMPLES, help="a subset of the scenes")
    args = parser.parse_args(argv)
    addon.register()

    lines = ["| scene | agrees | mean ratio R/G/B (noise +-) | pixels passing | VolPath spp/s | Cycles spp/s |",
             "|---|---|---|---|---|---|"]
    all_agree = True
    for name in args.only or EXAMPLES:
        module = importlib.import_module(f"examples.{name}")
        module.build(resolution=args.resolution, samples=args.spp)
        blend = scene_builder.save(args.out / "blend" / f"{name}.blend")
        options = runner.CompareOptions(mode=args.mode, samples=args.spp, seconds=args.seconds, runs=args.runs)
        print(f"{name}:", file=sys.stderr)
        with cli.quiet_stdout():
            result = runner.compare_file(blend, options, args.out / name, cli.TextProgress())
        means = result.comparison.means
        all_agree &= result.agrees
        lines.append(f"| [{name}]({name}/sheet.png) | {'yes' if result.agrees else '**NO**'} | "
                     + " ".join(f"{r:.3f}" for r in means.ratio) + " (+-"
                     + " ".join(f"{t:.3f}" for t in means.ratio_tolerance) + ") | "
                     f"{100 * result.comparison.pixel.fraction_passed:.1f}% | {result.volpath.spp_per_second:.1f} | "
                     f"{result.cycles.spp_per_second:.1f} |")
    if not args.only or "albedo_grid" in args.only:
        print("albedo grid (9 cells):", file=sys.stderr)
        with cli.quiet_stdout():
            sheet, _ = albedo_grid.render_grid(args.out / "albedo_grid", args.resolution, args.spp, args.runs,
                                               progress=lambda m: print(m, file=sys.stderr))
        lines.append(f"\nCourse experiment sheet: [albedo_grid.png](albedo_grid/albedo_grid.png)")
    summary = args.out / "summary.md"
    summary.write_text("# VolPath vs Cycles on the example scenes\n\n" + "\n".join(lines) + "\n")
    print(f"summary: {summary}")
    return 0 if all_agree else 1


if __name__ == "__main__":
    sys.exit(main())
