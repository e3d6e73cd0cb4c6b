"""The comparison's JSON report and its short Markdown summary. No bpy."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def _plain(value):
    """JSON-safe copy: numpy scalars/arrays to Python, non-finite floats to None."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    if isinstance(value, Path):
        return str(value)
    return value


def write_json(path, report: dict) -> Path:
    path = Path(path)
    path.write_text(json.dumps(_plain(report), indent=2) + "\n", encoding="utf-8")
    return path


def _fmt(values, digits: int = 4) -> str:
    return " / ".join("n/a" if v is None else f"{v:.{digits}g}" for v in values)


def markdown_summary(report: dict) -> str:
    """A human summary of the report (the JSON stays the complete record)."""
    stats = report["agreement"]
    engines = report["engines"]
    lines = [
        f"# VolPath vs Cycles: {report.get('scene', '')}",
        "",
        f"Mode **{report['mode']}**, {report['resolution'][0]}x{report['resolution'][1]} px, "
        f"{report['runs']} independent runs per engine (seeds {report['seed']}..{report['seed'] + report['runs'] - 1}).",
        "",
        "| | VolPath | Cycles |",
        "|---|---|---|",
        f"| mean R / G / B | {_fmt(stats['channel_means_a'])} | {_fmt(stats['channel_means_b'])} |",
        f"| std. error of mean | {_fmt(stats['channel_mean_standard_error_a'], 2)} | "
        f"{_fmt(stats['channel_mean_standard_error_b'], 2)} |",
        f"| samples per pixel (total) | {engines['volpath']['samples_per_pixel']} | {engines['cycles']['samples_per_pixel']} |",
        f"| render time (s) | {engines['volpath']['seconds']:.2f} | {engines['cycles']['seconds']:.2f} |",
        f"| warm-up before timing (s) | {engines['volpath'].get('warm_up_seconds', 0.0):.2f} (kernels) | - |",
        f"| samples per pixel per second | {engines['volpath']['spp_per_second']:.1f} | {engines['cycles']['spp_per_second']:.1f} |",
    ]
    reference = report.get("reference")
    if reference:
        lines.append(f"| relMSE vs reference | {reference['relmse_volpath']:.4g} | {reference['relmse_cycles']:.4g} |")
    ratio = stats["channel_mean_ratio"]
    tolerance = stats["channel_mean_ratio_tolerance"]
    lines += [
        "",
        f"- Mean ratio VolPath/Cycles R/G/B: {_fmt(ratio)} (noise allows +-{_fmt(tolerance, 2)}); "
        f"means agree: **{'yes' if stats['means_agree'] else 'NO'}**.",
        f"- Per-pixel Welch t-test (Sidak-corrected to {stats['pixel_alpha']:.3g} for the pixels): "
        f"{100 * stats['pixel_fraction_passed']:.2f}% of pixels pass; pixels agree: "
        f"**{'yes' if stats['pixels_agree'] else 'NO'}** (worst pixel p = {stats['worst_pixel']['p_value']:.3g}).",
    ]
    for size, block in stats.get("blocks", {}).items():
        lines.append(f"- {size}x{size}-pixel blocks: {100 * block['fraction_passed']:.2f}% pass; agree: "
                     f"**{'yes' if block['agree'] else 'NO'}**.")
    lines += [
        f"- **Verdict: {'VolPath and Cycles agree' if stats.get('agrees') else 'VolPath and Cycles DISAGREE'}** "
        f"(pixels, blocks and means together at family-wise significance {report.get('alpha', 0.01):g}).",
        f"- relMSE VolPath vs Cycles: {stats['relmse_a_vs_b']:.4g}.",
    ]
    if reference:
        lines.append(f"- Error ratio (relMSE VolPath / relMSE Cycles, vs the reference): "
                     f"{reference['error_ratio']:.3g} ({'VolPath' if reference['error_ratio'] < 1 else 'Cycles'} is closer "
                     f"for this {'time' if report['mode'] == 'equal-time' else 'sample count'}).")
    if report.get("warnings"):
        lines += ["", "Warnings:"] + [f"- {w}" for w in report["warnings"]]
    outputs = report.get("outputs", {})
    if outputs:
        lines += ["", "Files: " + ", ".join(f"[{k}]({Path(v).name})" for k, v in outputs.items() if k != "report_md")]
    return "\n".join(lines) + "\n"


def write_markdown(path, report: dict) -> Path:
    path = Path(path)
    path.write_text(markdown_summary(report), encoding="utf-8")
    return path
