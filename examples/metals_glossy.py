"""Conductors and glossy reflection: gold (Metallic BSDF, F82) and copper (Metallic BSDF,
physical conductor IOR/extinction) spheres and a Principled metal on a Glossy floor, under an
area light and a dim sky."""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb


def build(resolution=(64, 64), samples=64):
    scene = sb.new_scene(resolution, samples)
    floor = sb.bsdf_material("Glossy floor", "ShaderNodeBsdfGlossy", Color=(0.6, 0.6, 0.6), Roughness=0.3)
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    back = sb.diffuse_material("Wall", (0.7, 0.7, 0.7))
    sb.add_quad(scene, "Wall", [(-3, 1.2, 0), (3, 1.2, 0), (3, 1.2, 3), (-3, 1.2, 3)], back)
    gold = sb.bsdf_material("Gold", "ShaderNodeBsdfMetallic", Base_Color=(1.0, 0.78, 0.34),
                            Edge_Tint=(1.0, 0.95, 0.8), Roughness=0.25)
    copper = sb.bsdf_material("Copper", "ShaderNodeBsdfMetallic", fresnel_type="PHYSICAL_CONDUCTOR",
                              IOR=(0.27, 0.68, 1.22), Extinction=(3.61, 2.63, 2.29), Roughness=0.1)
    steel = sb.bsdf_material("Brushed steel", Base_Color=(0.6, 0.6, 0.62), Metallic=1.0, Roughness=0.45)
    sb.add_uv_sphere(scene, "Gold", (-0.75, 0.0, 0.3), 0.3, gold)
    sb.add_uv_sphere(scene, "Copper", (0.0, 0.2, 0.3), 0.3, copper)
    sb.add_uv_sphere(scene, "Steel", (0.75, 0.0, 0.3), 0.3, steel)
    sb.add_area_light(scene, (0.5, -1.0, 2.2), (0.0, 0.0, 0.3), power_w=250.0, size=1.0)
    sb.set_world_background(scene, (0.5, 0.6, 0.8), 0.3)
    sb.add_camera(scene, (0.0, -3.2, 1.1), (0.0, 0.0, 0.35), lens_mm=40.0)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
