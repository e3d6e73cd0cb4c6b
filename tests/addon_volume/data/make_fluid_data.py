"""Regenerate the baked Mantaflow domains the fluid tests read (Blender 3.4, whose Mantaflow bakes):

    blender -b -P tests/addon_volume/data/make_fluid_data.py

Each case is examples/quick_smoke.py's scene, baked over frames 1..N; only the last frames'
cache files are kept and the domain's cache range is narrowed to them (Blender keeps the bake
flags, so the runtime loads exactly those frames), which keeps the folder under 2 MB:

- smoke.blend     Quick Smoke, resolution 32, frames 28-30 (the -a test renders 27-31)
- fire.blend      Quick Smoke "Smoke + Fire" with noise upres x2 (resolution 24 -> 48), frame 30
- adaptive.blend  Quick Smoke with an adaptive domain (box and resolution change per frame), frame 12
- texspace.blend  the domain's scale applied to its mesh and the mesh off-centre, so the texture
                  space is L = (0.5, 0, 1), S = (2, 2, 3) instead of (0, 0, 0), (1, 1, 1); frame 10
"""
import shutil
import sys
from pathlib import Path

import bpy

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[2]))

from examples import quick_smoke  # noqa: E402

CASES = {  # name: (fire, resolution_max, last frame, frames kept, adjust(domain) before baking)
    "smoke": (False, 32, 30, 3, None),
    "fire": (True, 24, 30, 1, None),
    "adaptive": (False, 24, 12, 1, "adaptive"),
    "texspace": (False, 16, 10, 1, "texspace"),
}


def adjust(domain, how):
    settings = quick_smoke.domain_settings(domain)
    if how == "adaptive":
        settings.use_adaptive_domain = True
        settings.additional_res = 0
        settings.adapt_margin = 2
    elif how == "texspace":
        # Same world box, but the scale lives in the mesh and the mesh sits off the object origin.
        offset = (0.5, 0.0, 1.0)
        scale = tuple(domain.scale)
        for vertex in domain.data.vertices:
            vertex.co = tuple(c * s + o for c, s, o in zip(vertex.co, scale, offset))
        domain.scale = (1.0, 1.0, 1.0)
        domain.location = tuple(l - o for l, o in zip(domain.location, offset))


def trim(cache: Path, keep_from: int):
    """Delete every frame's files before keep_from (data, noise, config)."""
    for folder in ("data", "noise", "config"):
        for path in (cache / folder).glob("*"):
            frame = int(path.stem.rsplit("_", 1)[1])
            if frame < keep_from:
                path.unlink()
    for folder in ("guiding", "mesh", "particles"):
        shutil.rmtree(cache / folder, ignore_errors=True)


def make(name, fire, resolution, last, kept, how):
    blend = HERE / f"{name}.blend"
    cache = HERE / f"{name}_cache"
    shutil.rmtree(cache, ignore_errors=True)
    scene, domain = quick_smoke.build(fire=fire, resolution_max=resolution, frame_end=last,
                                      cache_directory=f"//{name}_cache", image_resolution=(32, 32), samples=16)
    if how:
        adjust(domain, how)
    bpy.context.preferences.filepaths.save_version = 0
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), compress=True)
    quick_smoke.bake(domain)
    quick_smoke.hide_emitter()
    first = last - kept + 1
    trim(cache, first)
    settings = quick_smoke.domain_settings(domain)
    settings.cache_frame_start, settings.cache_frame_end = first, last
    scene.frame_start, scene.frame_end = first, last
    scene.frame_set(last)
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), compress=True)
    print(f"{name}: frames {first}-{last}, {sum(p.stat().st_size for p in cache.rglob('*') if p.is_file())} bytes")


for case, spec in CASES.items():
    make(case, *spec)
