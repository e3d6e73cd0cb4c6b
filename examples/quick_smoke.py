"""Blender's Quick Smoke: a Mantaflow gas domain above a cube, baked to an OpenVDB cache, lit by a sun.

Object > Quick Effects > Quick Smoke on a 2 m cube, as a new user would do it: the operator makes
the domain (a box around the cube, Principled Volume with Density 5; for "Smoke + Fire" Blackbody
Intensity 1 on the 'temperature' attribute), the cube becomes the flow object. The script bakes the
simulation (cache type All, OpenVDB files next to the .blend), hides the emitter cube from renders
(its default material is a Principled BSDF, which VolPath renders as its diffuse layer only) and
adds a diffuse floor, a sun, a dim sky and a camera.

Baking needs a Blender whose Mantaflow works: Debian's Blender 3.4 or an official build
(the `bpy` 5.0.1 wheel cannot bake). Rendering the baked file works in both.

    blender -b -P examples/quick_smoke.py -- OUT.blend [--fire] [--resolution 32] [--frames 30]
    blender -b OUT.blend -E VOLPATH -o //render_ -a
"""
from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import bpy  # noqa: E402

from examples import scene_builder as sb  # noqa: E402

DOMAIN = "Smoke Domain"  # the name Quick Smoke gives the domain object


def domain_settings(obj):
    """The FluidDomainSettings of a fluid domain object (None for other objects)."""
    for modifier in obj.modifiers:
        if modifier.type == "FLUID" and modifier.fluid_type == "DOMAIN":
            return modifier.domain_settings
    return None


def build(fire=False, resolution_max=32, frame_end=30, cache_directory="//quick_smoke_cache",
          image_resolution=(64, 64), samples=64):
    """The scene in a fresh file, not baked yet: returns (scene, domain object)."""
    scene = sb.new_scene(image_resolution, samples)
    bpy.ops.mesh.primitive_cube_add(size=2.0, location=(0.0, 0.0, 0.0))
    emitter = bpy.context.active_object
    emitter.name = "Emitter"
    bpy.ops.object.quick_smoke(style="BOTH" if fire else "SMOKE")
    emitter.hide_render = True  # the flow object keeps emitting while hidden from renders
    domain = bpy.data.objects[DOMAIN]
    settings = domain_settings(domain)
    settings.resolution_max = int(resolution_max)
    settings.cache_type = "ALL"  # bake once; renders only read (Replay would simulate while rendering)
    settings.cache_data_format = "OPENVDB"
    settings.openvdb_cache_compress_type = "ZIP"
    settings.cache_directory = cache_directory
    settings.cache_frame_start, settings.cache_frame_end = 1, int(frame_end)
    scene.frame_start, scene.frame_end = 1, int(frame_end)
    scene.frame_set(1)

    floor = sb.diffuse_material("Floor", (0.5, 0.5, 0.5))
    bottom = domain.matrix_world.translation.z - domain.scale.z  # the domain box's floor
    sb.add_quad(scene, "Floor", [(-12, -12, bottom), (12, -12, bottom), (12, 12, bottom), (-12, 12, bottom)], floor)
    sb.add_sun_light(scene, direction=(-0.45, 0.5, -0.74), strength=4.0, angle_deg=3.0)
    sb.set_world_background(scene, (0.35, 0.42, 0.55), 0.25)
    sb.add_camera(scene, (0.0, -10.0, 1.6), (0.0, 0.0, 0.8), lens_mm=45.0)
    return scene, domain


def bake(domain) -> None:
    """Bake every frame of the domain's cache range (Fluid > Cache > Bake All)."""
    view_layer = bpy.context.view_layer
    for obj in view_layer.objects:
        obj.select_set(obj == domain)
    view_layer.objects.active = domain
    if bpy.ops.fluid.bake_all() != {"FINISHED"}:
        raise SystemExit(f"baking '{domain.name}' failed")
    settings = domain_settings(domain)
    if not settings.has_cache_baked_data:
        raise SystemExit(f"'{domain.name}' has no baked data: this Blender's Mantaflow cannot bake "
                         "(the bpy 5.0.1 wheel cannot); use Debian's Blender 3.4 or an official build")


def hide_emitter() -> None:
    """After baking, hide the emitter in the viewport too: the cache no longer needs it, and the
    comparison tool exports the viewport's depsgraph, where hide_render does not apply."""
    bpy.data.objects["Emitter"].hide_viewport = True


def main(argv=None) -> Path:
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--" in argv:
        argv = argv[argv.index("--") + 1:]
    fire = "--fire" in argv
    argv = [a for a in argv if a != "--fire"]
    options = {"--resolution": 32, "--frames": 30}
    for key in options:
        if key in argv:
            i = argv.index(key)
            options[key] = int(argv[i + 1])
            del argv[i:i + 2]
    if len(argv) != 1 or not argv[0].endswith(".blend"):
        raise SystemExit("usage: blender -b -P examples/quick_smoke.py -- OUT.blend [--fire] "
                         "[--resolution N] [--frames N]")
    out = Path(argv[0]).resolve()
    scene, domain = build(fire=fire, resolution_max=options["--resolution"], frame_end=options["--frames"],
                          cache_directory=f"//{out.stem}_cache")
    bpy.context.preferences.filepaths.save_version = 0  # no OUT.blend1 from the second save
    out = sb.save(out)  # the cache path is relative to the saved file
    bake(domain)
    hide_emitter()
    scene.frame_set(scene.frame_end)
    sb.save(out)
    print(f"wrote {out} (cache in {out.parent / (out.stem + '_cache')})")
    return out


if __name__ == "__main__":
    main()
