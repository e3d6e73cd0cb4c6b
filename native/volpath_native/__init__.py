"""VolPath's renderer: a wavefront volumetric path tracer (numba-compiled stages, Embree queries
in bulk). Never imports bpy."""
from . import kernel_target  # noqa: F401  (first: the kernels' CPU target is set before numba loads)
from .scene import (AreaLight, Camera, Film, Material, Medium, Mesh, PointLight, RenderSettings,
                    Scene, SceneError, SpotLight, SunLight, World)
from .scene_io import load_scene, save_scene

__version__ = "0.1.0"
from .integrator import warm_up
from .render import RenderResult, render
