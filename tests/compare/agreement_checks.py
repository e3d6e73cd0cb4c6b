"""The agreement assertions every VolPath-vs-Cycles case of the suite shares."""
import json


def assert_engines_agree(result, label, tmp_path):
    """Assert the comparison's verdict part by part (means, pixels, tiles) with the numbers needed to
    find the culprit; on failure the EXRs and sheet are written to tmp_path for inspection."""
    from addon.compare import runner

    summary = result.comparison.summary()
    details = json.dumps({k: summary[k] for k in (
        "channel_means_a", "channel_means_b", "channel_mean_ratio", "channel_mean_ratio_tolerance",
        "channel_mean_p_values", "pixel_fraction_passed", "worst_pixel")}, indent=1)
    if not result.agrees:
        runner.write_outputs(result, tmp_path)
        details += f"\noutputs in {tmp_path}"
    assert not result.warnings, result.warnings
    assert result.comparison.means.passed, f"{label}: image means differ (VolPath / Cycles)\n{details}"
    assert result.comparison.pixel.passed, f"{label}: pixels differ (VolPath / Cycles)\n{details}"
    for size, test in result.comparison.blocks.items():
        assert test.passed, f"{label}: {size}x{size} blocks differ (VolPath / Cycles): worst {test.worst()}\n{details}"
    # Guard against a vacuous pass: the scene must actually be lit.
    assert min(summary["channel_means_b"]) > 1e-3
