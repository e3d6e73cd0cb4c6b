"""The course project's experiment: isotropic fog in a Cornell box lit by a ceiling lamp (a mesh
light), scattering albedo sigma_s/sigma_t in {0.2, 0.3, 0.4} x three densities.

The course renderer used kappa = sigma_t in {0.001, 0.002, 0.003} per unit in a Cornell box of
about 550 units, i.e. optical thickness tau = sigma_t * box in {0.55, 1.1, 1.65}; here the box is
2 m, so sigma_t = tau / 2 per metre (Principled Volume: Density = sigma_t, Color = albedo).

`python examples/albedo_grid.py OUT.blend` saves the middle cell; `render_grid(OUT_DIR)` renders
all nine cells with both engines into one contact sheet (examples/render_all.py calls it).
"""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb

BOX = 2.0
ALBEDOS = (0.2, 0.3, 0.4)
OPTICAL_THICKNESSES = (0.55, 1.1, 1.65)


def build(resolution=(64, 64), samples=64, albedo=0.3, optical_thickness=1.1):
    scene = sb.new_scene(resolution, samples)
    sb.add_cornell_box(scene, BOX)
    fog = sb.principled_volume_material("Fog", density=optical_thickness / BOX, color=(albedo,) * 3)
    sb.add_box(scene, "Fog", (0.0, 0.0, BOX / 2), (BOX - 0.01,) * 3, fog)
    # The course scene's lamp: an emissive quad just under the ceiling, facing down.
    lamp = sb.emission_material("Lamp", (1.0, 0.85, 0.6), 15.0)
    h, z = 0.25, BOX - 0.02
    sb.add_quad(scene, "Lamp", [(-h, -h, z), (-h, h, z), (h, h, z), (h, -h, z)], lamp)
    sb.cornell_camera(scene, BOX)
    return scene


def render_grid(out_dir, resolution=(64, 64), samples=128, runs=4, progress=print):
    """All nine cells with both engines -> OUT_DIR/albedo_grid.png (+ grid.json); returns the
    per-cell agreement summaries."""
    import json

    from addon.compare import metrics, runner, sheet

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    rows, cells, exposure = [], [], None
    for tau in OPTICAL_THICKNESSES:
        row = []
        for albedo in ALBEDOS:
            build(resolution, samples, albedo=albedo, optical_thickness=tau)
            result = runner.compare_scene(sb.bpy.context.scene, runner.CompareOptions(samples=samples, runs=runs))
            if exposure is None:  # one exposure for the whole sheet, so the cells compare
                exposure = metrics.display_exposure(result.cycles.statistics.mean)
            label = f"albedo {albedo}, tau {tau}"
            ratio = " ".join(f"{r:.3f}" for r in result.comparison.means.ratio)
            row += [sheet.render_panel(f"VolPath {label}", result.volpath.statistics.mean, exposure, f"ratio {ratio}"),
                    sheet.render_panel(f"Cycles {label}", result.cycles.statistics.mean, exposure,
                                       f"{100 * result.comparison.pixel.fraction_passed:.1f}% px agree")]
            cells.append({"albedo": albedo, "optical_thickness": tau, "agrees": result.agrees,
                          **result.comparison.summary()})
            progress(f"albedo grid: albedo {albedo}, tau {tau}: mean ratio {ratio}, agrees {result.agrees}")
        rows.append(row)
    path = sheet.write_contact_sheet(out_dir / "albedo_grid.png", rows,
                                     "Course experiment: albedo x optical thickness, VolPath | Cycles")
    (out_dir / "albedo_grid.json").write_text(json.dumps(cells, indent=1, default=float) + "\n")
    return path, cells


if __name__ == "__main__":
    sb.main_for(build)
