"""The headline surfaces scene: a glass of coloured liquid in fog, lit by a spot.

A closed cylinder whose material has a Glass BSDF surface (IOR 1.33, smooth) and a Volume
Absorption inside: rays refract in, are absorbed along their way through the amber liquid
(Beer-Lambert inside, Fresnel at both faces) and refract out; the fog around it scatters the
spot's cone, and the glass blocks shadow rays (Cycles 5.0). Beside it a smooth glass sphere with
a scattering (milky) interior and a rough Principled floor.
"""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb


def build(resolution=(64, 64), samples=64, fog_density=0.08, liquid_density=3.0):
    scene = sb.new_scene(resolution, samples)
    floor = sb.bsdf_material("Floor", Base_Color=(0.55, 0.55, 0.55), Roughness=0.35)
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    back = sb.diffuse_material("Wall", (0.5, 0.5, 0.6))
    sb.add_quad(scene, "Wall", [(-3, 1.5, 0), (3, 1.5, 0), (3, 1.5, 3), (-3, 1.5, 3)], back)
    liquid = sb.bsdf_material("Liquid in glass", "ShaderNodeBsdfGlass", IOR=1.33, Roughness=0.0,
                              Color=(1.0, 1.0, 1.0),
                              volume=("ShaderNodeVolumeAbsorption",
                                      {"Color": (0.9, 0.45, 0.1), "Density": liquid_density}))
    sb.add_cylinder(scene, "Glass", (-0.35, 0.0, 0.01), 0.3, 0.8, liquid)  # off the floor: no coplanar faces
    milky = sb.bsdf_material("Milky glass", "ShaderNodeBsdfGlass", IOR=1.5, Roughness=0.0,
                             volume=("ShaderNodeVolumeScatter", {"Color": (0.9, 0.9, 0.9), "Density": 4.0}))
    sb.add_uv_sphere(scene, "Sphere", (0.45, -0.1, 0.3), 0.3, milky)
    fog = sb.principled_volume_material("Fog", density=fog_density, color=(0.9, 0.9, 0.9))
    sb.add_box(scene, "Fog", (0.0, 0.0, 1.5), (5.9, 5.9, 2.98), fog)
    sb.add_spot_light(scene, (0.8, -0.9, 2.6), (0.0, 0.0, 0.3), power_w=900.0, spot_size_deg=40.0, blend=0.2)
    sb.set_world_background(scene, (0.6, 0.7, 1.0), 0.15)
    sb.add_camera(scene, (0.0, -3.4, 1.2), (0.0, 0.0, 0.45), lens_mm=40.0)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
