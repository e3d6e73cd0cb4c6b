"""VolPath's render settings, stored per scene at scene.volpath. Bounce limits mean what Cycles'
do (intern/cycles/kernel/integrator/path_state.h) and default to the Cycles add-on's defaults."""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty


class VolpathRenderSettings(bpy.types.PropertyGroup):
    samples: IntProperty(name="Samples", description="Samples per pixel", default=64, min=1,
                         soft_max=4096, max=1 << 20)
    time_limit: FloatProperty(
        name="Time Limit", default=0.0, min=0.0, unit="TIME_ABSOLUTE",
        description="Stop rendering after this many seconds, or at the sample count if that comes first "
                    "(scene export and kernel loading not counted, as Cycles' Time Limit). 0: no limit")
    seed: IntProperty(name="Seed", description="Seed of the random sequences (fixed seed: same image)",
                      default=0, min=0)
    use_animated_seed: BoolProperty(name="Animated Seed", default=False,
                                    description="Add the frame number to the seed, so the noise changes per frame")
    max_bounces: IntProperty(name="Total", description="Maximum number of bounces of any kind",
                             default=12, min=0, max=1024)
    diffuse_bounces: IntProperty(name="Diffuse", description="Maximum number of diffuse bounces",
                                 default=4, min=0, max=1024)
    glossy_bounces: IntProperty(name="Glossy", description="Maximum number of glossy bounces",
                                default=4, min=0, max=1024)
    transmission_bounces: IntProperty(name="Transmission", description="Maximum number of transmission bounces",
                                      default=12, min=0, max=1024)
    volume_bounces: IntProperty(
        name="Volume", default=0, min=0, max=1024,
        description="Maximum number of volume scattering events (0: single scattering with direct light, as Cycles)")
    transparent_bounces: IntProperty(
        name="Transparent", default=8, min=0, max=1024,
        description="Maximum number of invisible medium boundaries a path may cross")
    min_bounces_russian_roulette: IntProperty(
        name="Russian Roulette Start", default=6, min=0, max=1024,
        description="Bounce after which paths are terminated randomly by their throughput")
    volume_sampling: EnumProperty(
        name="Volume Sampling", default="MIS",
        description="How distances are sampled in media",
        items=[("MIS", "Multiple Importance", "Distance and equiangular sampling combined (Cycles' default)"),
               ("DISTANCE", "Distance", "Free-flight distance sampling"),
               ("EQUIANGULAR", "Equiangular", "Sample distances towards lights")])
    use_light_tree: BoolProperty(
        name="Light Tree", default=True,
        description="Choose a light per shading point by distance and orientation (Cycles' light tree); "
                    "off: by power alone, the same image with more noise where several lights compete")
    batch_size: IntProperty(name="Batch Size", default=1 << 14, min=1024, max=1 << 24,
                            description="Paths traced together (memory grows with it)")
    threads: IntProperty(name="Threads", default=0, min=0, max=1024,
                         description="Render threads (0: all cores)")


CLASSES = (VolpathRenderSettings,)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.volpath = PointerProperty(type=VolpathRenderSettings, name="VolPath")


def unregister():
    del bpy.types.Scene.volpath
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
