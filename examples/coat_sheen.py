"""Layered Principled BSDFs: a clear coat over a red diffuse base, a sheen cloth (Sheen BSDF) and
a Principled dielectric with Sheen, Specular Tint and a lower IOR level, in thin fog."""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb


def build(resolution=(64, 64), samples=64):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.5, 0.5, 0.5))
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    coat = sb.bsdf_material("Coated red", Base_Color=(0.8, 0.05, 0.05), Roughness=0.6, Coat_Weight=1.0,
                            Coat_Roughness=0.05, Coat_Tint=(0.9, 0.9, 1.0))
    sb.add_uv_sphere(scene, "Coated", (-0.6, 0.0, 0.35), 0.35, coat)
    cloth = sb.bsdf_material("Cloth", "ShaderNodeBsdfSheen", Color=(0.2, 0.4, 0.9), Roughness=0.4)
    sb.add_quad(scene, "Cloth", [(-0.1, 0.4, 0.0), (1.3, 0.4, 0.0), (1.3, 0.9, 1.0), (-0.1, 0.9, 1.0)], cloth)
    velvet = sb.bsdf_material("Velvet", Base_Color=(0.1, 0.5, 0.2), Roughness=0.4, Sheen_Weight=1.0,
                              Sheen_Tint=(1.0, 0.9, 0.7), Specular_IOR_Level=0.3, Specular_Tint=(0.8, 1.0, 0.8))
    sb.add_uv_sphere(scene, "Velvet", (0.6, -0.3, 0.3), 0.3, velvet)
    fog = sb.principled_volume_material("Fog", density=0.05, color=(0.9, 0.9, 0.9))
    sb.add_box(scene, "Fog", (0.0, 0.0, 1.5), (5.9, 5.9, 2.98), fog)
    sb.add_area_light(scene, (-0.5, -1.2, 2.0), (0.0, 0.0, 0.3), power_w=200.0, size=0.8)
    sb.set_world_background(scene, (0.6, 0.6, 0.6), 0.2)
    sb.add_camera(scene, (0.0, -3.0, 1.2), (0.0, 0.0, 0.4), lens_mm=40.0)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
