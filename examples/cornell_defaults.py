"""The Cornell fog box with Blender's and Cycles' defaults where they matter most: a point light of
radius 0.1 m with soft falloff (Blender 4.0+'s new-light defaults) and the Cycles add-on's bounce
limits (volume bounces 0: one scattering vertex with direct light, then only attenuation).
"""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb

BOX = 2.0
CYCLES_DEFAULT_BOUNCES = dict(max_bounces=12, diffuse_bounces=4, glossy_bounces=4, transmission_bounces=12,
                              volume_bounces=0, transparent_bounces=8)


def build(resolution=(64, 64), samples=64, density=0.6, albedo=0.7):
    scene = sb.new_scene(resolution, samples, bounces=CYCLES_DEFAULT_BOUNCES)
    sb.add_cornell_box(scene, BOX)
    fog = sb.principled_volume_material("Fog", density=density, color=(albedo,) * 3)
    sb.add_box(scene, "Fog", (0.0, 0.0, BOX / 2), (BOX - 0.01,) * 3, fog)
    lamp = sb.add_point_light(scene, (0.0, 0.0, BOX * 0.8), power_w=100.0, radius=0.1)
    lamp.data.use_soft_falloff = True
    sb.cornell_camera(scene, BOX)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
