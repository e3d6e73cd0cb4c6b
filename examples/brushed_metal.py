"""Anisotropic metals: a brushed Principled sphere (Metallic 1, Anisotropic 0.8, Anisotropic
Rotation 0.1) whose tangent is Cycles' default -- the radial tangent around the Z axis of its
Generated coordinates -- and a brushed Metallic BSDF plate whose Tangent input is a Tangent node
along its UV map (Anisotropy 0.8, Rotation 0.125), on a grey floor under an area light and a dim
sky. The stretched highlights depend on the tangent frame and the rotation (issue 10)."""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb
from examples.textured_surfaces import set_uvs


def brushed_sphere_material(name: str):
    return sb.bsdf_material(name, Base_Color=(0.9, 0.75, 0.5), Metallic=1.0, Roughness=0.35, Anisotropic=0.8,
                            Anisotropic_Rotation=0.1)


def brushed_plate_material(name: str):
    mat = sb.bsdf_material(name, node_type="ShaderNodeBsdfMetallic", Base_Color=(0.8, 0.8, 0.85), Roughness=0.4,
                           Anisotropy=0.8, Rotation=0.125)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = next(n for n in nodes if n.type == "BSDF_METALLIC")
    tangent = nodes.new("ShaderNodeTangent")
    tangent.direction_type = "UV_MAP"
    tangent.uv_map = "UVMap"
    links.new(tangent.outputs["Tangent"], bsdf.inputs["Tangent"])
    return mat


def build(resolution=(64, 64), samples=64):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.5, 0.5, 0.5))
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    sb.add_uv_sphere(scene, "Brushed sphere", (-0.55, 0.2, 0.5), 0.5, brushed_sphere_material("Brushed sphere"))
    plate = sb.add_quad(scene, "Brushed plate", [(0.15, -0.5, 0.02), (1.25, -0.5, 0.02), (1.25, 0.9, 0.02),
                                                  (0.15, 0.9, 0.02)], brushed_plate_material("Brushed plate"))
    set_uvs(plate, lambda co: ((co.x - 0.15) / 1.1, (co.y + 0.5) / 1.4))
    sb.add_area_light(scene, (0.3, 1.6, 2.2), (0.0, 0.0, 0.3), power_w=300.0, size=1.2)
    sb.set_world_background(scene, (0.6, 0.7, 0.9), 0.15)
    sb.add_camera(scene, (0.2, -3.0, 1.6), (0.2, 0.2, 0.3), lens_mm=32.0)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
