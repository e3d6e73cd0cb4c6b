"""The scene model: what the renderer consumes and what the Blender add-on exports.

Everything is in world space, metres, scene-linear RGB. Units are physical; the conversion from
Blender's numbers is the exporter's job (addon/), but this module documents exactly what it
expects so the renderer can be driven without Blender (see scene_io for the file format).

Conventions
- Directions of lights are the direction the light *travels* (a Blender lamp's local -Z).
- Cameras look down their local -Z with +Y up (Blender's convention); camera_to_world has no scale.
- RGB triples are float64 numpy arrays of shape (3,).

Construction never silently accepts bad data: ``Scene.validate()`` raises ``SceneError`` for
unusable input and returns a list of warning strings for input that renders with a defined
fallback (the add-on shows both to the user).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Union

import numpy as np

from .bsdfs.nodes import SurfaceNode
from .triangle_geometry import normals_and_doubled_areas


class SceneError(ValueError):
    """Input that cannot be rendered; the message names the offending object."""


def rgb(value, name: str = "value") -> np.ndarray:
    """A finite RGB triple from a scalar or a 3-sequence (raises SceneError otherwise)."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(3, float(arr))
    if arr.shape != (3,):
        raise SceneError(f"{name}: expected an RGB triple, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise SceneError(f"{name}: non-finite value {arr.tolist()}")
    return arr


def vec3(value, name: str = "vector") -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise SceneError(f"{name}: expected a finite 3-vector, got {np.asarray(value).tolist()}")
    return arr


def unit(value, name: str = "direction") -> np.ndarray:
    v = vec3(value, name)
    n = np.linalg.norm(v)
    if n < 1e-12:
        raise SceneError(f"{name}: zero-length direction")
    return v / n


# ----------------------------------------------------------------------------------------------
# Media
# ----------------------------------------------------------------------------------------------
@dataclass
class Medium:
    """A homogeneous participating medium.

    sigma_s, sigma_a: scattering / absorption coefficients in 1/m (RGB).
    g: Henyey-Greenstein anisotropy in (-1, 1); > 0 scatters forward.
    emission: emitted radiance per unit length, W/(m^3 sr) (RGB), as Cycles' volume emission.
    phase_lobes: optional [(sigma_s_k RGB, g_k), ...] for a medium whose scattering is several
        Henyey-Greenstein lobes (e.g. a Mix Shader of volume shaders with different anisotropy;
        Cycles keeps one closure per lobe): phase = sum_k sigma_s_k HG(g_k) / sigma_s per channel.
        When given, sigma_s must equal the sum of the lobes' sigma_s (validate() warns and uses
        the sum) and g is only informative (set to the sigma_s-weighted mean). Empty: one lobe
        (sigma_s, g).
    """

    name: str
    sigma_s: np.ndarray
    sigma_a: np.ndarray
    g: float = 0.0
    emission: np.ndarray = field(default_factory=lambda: np.zeros(3))
    phase_lobes: list = field(default_factory=list)

    # Scene.media may also hold heterogeneous grid_medium.GridMedium objects (is_homogeneous False),
    # bounded by a closed null mesh like any medium; they cannot be the world medium.
    is_homogeneous = True

    def __post_init__(self):
        self.sigma_s = rgb(self.sigma_s, f"medium '{self.name}' sigma_s")
        self.sigma_a = rgb(self.sigma_a, f"medium '{self.name}' sigma_a")
        self.emission = rgb(self.emission, f"medium '{self.name}' emission")
        self.g = float(self.g)
        lobes = []
        for k, lobe in enumerate(self.phase_lobes or []):
            try:
                lobe_sigma_s, lobe_g = lobe
            except (TypeError, ValueError):
                raise SceneError(f"medium '{self.name}' phase lobe {k}: expected (sigma_s RGB, g), got {lobe!r}")
            lobe_g = float(lobe_g)
            if not np.isfinite(lobe_g):
                raise SceneError(f"medium '{self.name}' phase lobe {k}: non-finite g {lobe_g}")
            lobes.append((rgb(lobe_sigma_s, f"medium '{self.name}' phase lobe {k} sigma_s"), lobe_g))
        self.phase_lobes = lobes

    @property
    def sigma_t(self) -> np.ndarray:
        return self.sigma_s + self.sigma_a

    def validate(self) -> list[str]:
        warnings = []
        if np.any(self.sigma_s < 0) or np.any(self.sigma_a < 0):
            warnings.append(f"medium '{self.name}': negative coefficients clamped to 0")
            self.sigma_s = np.maximum(self.sigma_s, 0.0)
            self.sigma_a = np.maximum(self.sigma_a, 0.0)
        if not np.isfinite(self.g) or abs(self.g) >= 1.0:
            clamped = float(np.clip(np.nan_to_num(self.g), -0.999, 0.999))
            warnings.append(f"medium '{self.name}': anisotropy {self.g} clamped to {clamped}")
            self.g = clamped
        if self.phase_lobes:
            warnings += self._validate_lobes()
        return warnings

    def _validate_lobes(self) -> list[str]:
        warnings = []
        lobes = []
        for k, (lobe_sigma_s, lobe_g) in enumerate(self.phase_lobes):
            if np.any(lobe_sigma_s < 0):
                warnings.append(f"medium '{self.name}': negative sigma_s of phase lobe {k} clamped to 0")
            if abs(lobe_g) >= 1.0:
                clamped = float(np.clip(lobe_g, -0.999, 0.999))  # as Cycles' HG setup
                warnings.append(f"medium '{self.name}': anisotropy {lobe_g} of phase lobe {k} clamped to {clamped}")
                lobe_g = clamped
            lobes.append((np.maximum(lobe_sigma_s, 0.0), lobe_g))
        self.phase_lobes = lobes
        total = np.sum([s for s, _ in lobes], axis=0)
        if not np.allclose(total, self.sigma_s, rtol=1e-6, atol=1e-12):
            warnings.append(f"medium '{self.name}': sigma_s {self.sigma_s.tolist()} is not the sum of its phase "
                            f"lobes {total.tolist()}; the lobes' sum is used")
            self.sigma_s = total
        weights = np.array([s.mean() for s, _ in lobes])
        if weights.sum() > 0:
            self.g = float(weights @ np.array([g for _, g in lobes]) / weights.sum())
        return warnings

    def lobes(self) -> list:
        """[(sigma_s_k RGB, g_k)]: the phase lobes, or the single lobe (sigma_s, g)."""
        return list(self.phase_lobes) if self.phase_lobes else [(self.sigma_s, self.g)]


# ----------------------------------------------------------------------------------------------
# Surfaces
# ----------------------------------------------------------------------------------------------
SURFACE_KINDS = ("shaded", "null")


@dataclass
class Material:
    """What a triangle is made of.

    surface: 'shaded' (scattered by the BSDF nodes `surface_nodes`; without nodes, a Lambertian
        surface of albedo base_color) or 'null' (no surface at all: an invisible boundary of the
        interior medium, as a Cycles volume-only material). 'diffuse', the name of format 1, is
        read as 'shaded'.
    surface_nodes: bsdfs.nodes.SurfaceNode list, each with its mix weight (the exporter's reading
        of the node tree); the kernel expands them into lobes at each hit as Cycles' SVM does.
    emission: emitted radiance W/(m^2 sr) (RGB) of the surface (mesh light).
    two_sided_emission: Cycles' mesh lights emit from both faces (True, the default).
    medium: index into Scene.media of the medium inside the closed mesh (-1: none). Entered on a
        front-face hit, left on a back-face hit; for shaded surfaces, on a transmission through
        the surface (glass containing a liquid: Cycles' volume_stack_enter_exit).
    surface_program: optional surface_programs.SurfaceProgram: node inputs driven per hit by
        textures, attributes and node math (Cycles' SVM nodes before the closures).
    """

    name: str
    surface: str = "shaded"
    base_color: np.ndarray = field(default_factory=lambda: np.full(3, 0.8))
    emission: np.ndarray = field(default_factory=lambda: np.zeros(3))
    two_sided_emission: bool = True
    medium: int = -1
    surface_nodes: list = field(default_factory=list)
    surface_program: Optional[object] = None

    def __post_init__(self):
        if self.surface == "diffuse":
            self.surface = "shaded"
        self.base_color = rgb(self.base_color, f"material '{self.name}' base_color")
        self.emission = rgb(self.emission, f"material '{self.name}' emission")
        self.medium = int(self.medium)
        self.surface_nodes = [node if isinstance(node, SurfaceNode) else SurfaceNode.from_record(node)
                              for node in self.surface_nodes]

    def bsdf_nodes(self) -> list:
        """The nodes that shade this material: surface_nodes, or a Lambertian of base_color."""
        if self.surface != "shaded":
            return []
        if self.surface_nodes:
            return self.surface_nodes
        return [SurfaceNode.for_kind("diffuse", color=self.base_color)] if np.any(self.base_color > 0) else []

    @property
    def is_emissive(self) -> bool:
        return bool(np.any(self.emission > 0))


# ----------------------------------------------------------------------------------------------
# Geometry
# ----------------------------------------------------------------------------------------------
def padded_rows(values: np.ndarray, dtype=np.float32) -> np.ndarray:
    """values as a contiguous (N, 3) array whose memory extends at least 16 bytes past its end
    inside the same numpy allocation (Embree reads vertex buffers with 16-byte loads,
    rtcSetSharedGeometryBuffer): values itself when it already does, else a padded copy."""
    values = np.ascontiguousarray(values, dtype=dtype).reshape(-1, 3)
    owner = values
    while isinstance(owner.base, np.ndarray):
        owner = owner.base
    start = owner.__array_interface__["data"][0]
    end = values.__array_interface__["data"][0] + values.nbytes
    if owner is not values and owner.flags.c_contiguous and end + 16 <= start + owner.nbytes:
        return values
    padded = np.zeros((len(values) + 2, 3), dtype)
    padded[:len(values)] = values
    return padded[:len(values)]


def _affine_rows(values, name: str, ndim: int) -> np.ndarray:
    """float64 (..., 3, 4) affine maps of (..., 3, 4) or (..., 4, 4) input with `ndim` dimensions."""
    values = np.asarray(values, dtype=np.float64)
    if values.ndim != ndim or values.shape[-2:] not in ((3, 4), (4, 4)):
        raise SceneError(f"{name}: expected {ndim} dimensions ending in (3, 4) or (4, 4), got shape {values.shape}")
    return np.ascontiguousarray(values[..., :3, :])


def doubled_areas(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(T,) float64 twice the area of each triangle (one compiled pass, no temporaries)."""
    return normals_and_doubled_areas(vertices, triangles, with_normals=False)[1]


@dataclass
class Mesh:
    """A triangle mesh in world space, or a prototype in object space placed by instances.

    vertices: (V, 3) float32; triangles: (T, 3) int32 vertex indices (counter-clockwise seen
    from the front, so the geometric normal points outward for closed meshes);
    material_ids: (T,) int32 indices into Scene.materials;
    corner_normals: optional (T, 3, 3) float32 shading normals per triangle corner (smooth and
    custom split normals); None means flat shading.
    corner_attributes: per-corner values read by surface programs, {name: (T, 3, k) float32}
        (surface_programs.py names them: "uv:<map>", "uv:" the active-render UV map,
        "color:<name>", "tangent:<map>" as xyz + sign in object space).
    object_frame: optional (2, 3, 4): world -> object and object -> Generated texture space of
        the object the mesh came from (Texture Coordinate Object / Generated / Normal); None: the
        world frame and the mesh's bounding box as texture space. For an instanced mesh the
        first part maps *prototype* space to the object's texture frame (identity when the
        vertices are the object's own coordinates, as the exporter writes them): each instance's
        world -> object is the inverse of its transform, composed with it.

    Instancing (Cycles' object instancing: one BVH per unique mesh, an instance per object):
    instances: optional (K, 3, 4) float64 object -> world affine maps (rows of a 4x4 without its
        last row [0 0 0 1]; (K, 4, 4) is taken too, its last row dropped); the mesh's vertices, corner_normals and "tangent:" attributes are
        then in object space and the mesh appears K times. None (default): the vertices are in
        world space and the mesh appears once (what every exporter wrote before). Memory grows
        with the unique meshes, not with K. An emitting or medium-bounding instanced mesh is
        expanded into world copies (the light table and volume stacks index world triangles;
        with `motion`, each copy deforms through its transform's steps). The exporter groups
        depsgraph object instances by their evaluated mesh datablock (collection instances, particle/geometry-nodes instances
        and linked duplicates alike) and fills one Mesh per unique mesh with every
        instance.matrix_world[:3] (float64) here.
    motion: optional (K, S, 3, 4) float64 object -> world of every instance at S >= 2 shutter
        times evenly spaced from the shutter's opening (step 0) to its closing (step S - 1),
        the same steps as Camera.motion_transforms (Cycles' object motion steps: S from the
        object's Motion Blur steps, blender/util.h object_motion_steps, the middle step the
        frame itself, Object::motion_time spacing them over the shutter; interpolated
        decomposed: quaternion slerp of the rotation, linear scale and translation, as Cycles'
        transform_motion_decompose / Embree's rtcSetGeometryTransformQuaternion). Requires
        `instances` (the transforms at the frame itself: bounds, light sampling, renders without
        motion). A moving object that is not instanced is exported as a mesh with K = 1.
    vertex_motion: optional (S, V, 3) float32 vertex positions (in the space of `vertices`) at S
        >= 2 shutter times evenly spaced as above, for a deforming mesh whose topology is the same
        at every step (Cycles' motion vertex attribute, ATTR_STD_MOTION_VERTEX_POSITION; Blender
        gives up deformation blur when the topology changes: the exporter then leaves it None
        and warns). `vertices` stays the frame's positions (light sampling, bounds).
    corner_normal_motion: optional (S, T, 3, 3) float32 corner normals at the same S steps
        (smooth meshes with vertex_motion; Cycles' ATTR_STD_MOTION_VERTEX_NORMAL). Without it a
        deforming smooth mesh shades with its frame's corner_normals.
    """

    name: str
    vertices: np.ndarray
    triangles: np.ndarray
    material_ids: np.ndarray
    corner_normals: Optional[np.ndarray] = None
    corner_attributes: dict = field(default_factory=dict)
    object_frame: Optional[np.ndarray] = None
    instances: Optional[np.ndarray] = None
    motion: Optional[np.ndarray] = None
    vertex_motion: Optional[np.ndarray] = None
    corner_normal_motion: Optional[np.ndarray] = None

    def __post_init__(self):
        self.vertices = padded_rows(self.vertices)  # Embree shares it (embree.TriangleScene)
        self.triangles = np.ascontiguousarray(self.triangles, dtype=np.int32).reshape(-1, 3)
        self.material_ids = np.ascontiguousarray(self.material_ids, dtype=np.int32).reshape(-1)
        if self.corner_normals is not None:
            self.corner_normals = np.ascontiguousarray(self.corner_normals, dtype=np.float32).reshape(-1, 3, 3)
        attributes = {}
        for name, values in (self.corner_attributes or {}).items():
            values = np.asarray(values, dtype=np.float32)
            if values.ndim == 2:
                values = values[:, :, None]
            attributes[str(name)] = np.ascontiguousarray(values)
        self.corner_attributes = attributes
        if self.object_frame is not None:
            self.object_frame = np.ascontiguousarray(self.object_frame, dtype=np.float64).reshape(2, 3, 4)
        if self.instances is not None:  # 4x4 matrices (Blender's matrix_world) lose their last row
            self.instances = _affine_rows(self.instances, f"mesh '{self.name}' instances", 3)
        if self.motion is not None:
            self.motion = _affine_rows(self.motion, f"mesh '{self.name}' motion", 4)
        if self.vertex_motion is not None:
            vertex_motion = np.ascontiguousarray(self.vertex_motion, dtype=np.float32)
            self.vertex_motion = vertex_motion.reshape(vertex_motion.shape[0], -1, 3) if vertex_motion.ndim >= 1 \
                else vertex_motion
        if self.corner_normal_motion is not None:
            normals = np.ascontiguousarray(self.corner_normal_motion, dtype=np.float32)
            self.corner_normal_motion = normals.reshape(normals.shape[0], -1, 3, 3) if normals.ndim >= 1 else normals
        self._triangle_normals = None  # (vertices, triangles, normals, doubled areas): triangle_normals()

    def triangle_normals(self) -> tuple:
        """((T, 3) float64 unit geometric normals, (T,) float64 doubled areas) of the triangles,
        computed once for these vertex and triangle arrays: validate() counts the degenerate
        ones, the Accelerator keeps the rest and takes the normals over (release_triangle_normals)."""
        cached = self._triangle_normals
        if cached is None or cached[0] is not self.vertices or cached[1] is not self.triangles:
            normals, lengths = normals_and_doubled_areas(self.vertices, self.triangles)
            cached = self._triangle_normals = (self.vertices, self.triangles, normals, lengths)
        return cached[2], cached[3]

    def release_triangle_normals(self):
        self._triangle_normals = None

    @property
    def instance_count(self) -> int:
        """How many times the mesh appears (1 when not instanced)."""
        return 1 if self.instances is None else len(self.instances)

    @property
    def motion_steps(self) -> int:
        """Shutter steps of the instances' transforms (0: no object motion)."""
        return 0 if self.motion is None else int(self.motion.shape[1])

    @property
    def vertex_motion_steps(self) -> int:
        """Shutter steps of the vertex positions (0: no deformation motion)."""
        return 0 if self.vertex_motion is None else int(self.vertex_motion.shape[0])

    def frame(self) -> np.ndarray:
        """object_frame, or the world frame with the bounding box as Generated texture space."""
        if self.object_frame is not None:
            return self.object_frame
        frame = np.zeros((2, 3, 4))
        frame[0, :, :3] = np.eye(3)
        lo = self.vertices.min(axis=0).astype(np.float64) if len(self.vertices) else np.zeros(3)
        hi = self.vertices.max(axis=0).astype(np.float64) if len(self.vertices) else np.ones(3)
        size = np.where(hi - lo > 0, hi - lo, 1.0)
        frame[1, :, :3] = np.diag(1.0 / size)
        frame[1, :, 3] = -lo / size
        return frame

    def validate(self, n_materials: int) -> list[str]:
        n_tri = len(self.triangles)
        if len(self.material_ids) != n_tri:
            raise SceneError(f"mesh '{self.name}': {len(self.material_ids)} material ids for {n_tri} triangles")
        if n_tri and (self.triangles.min() < 0 or self.triangles.max() >= len(self.vertices)):
            raise SceneError(f"mesh '{self.name}': triangle index out of range")
        if n_tri and (self.material_ids.min() < 0 or self.material_ids.max() >= n_materials):
            raise SceneError(f"mesh '{self.name}': material id out of range")
        if not np.all(np.isfinite(self.vertices)):
            raise SceneError(f"mesh '{self.name}': non-finite vertex coordinates")
        if self.corner_normals is not None and self.corner_normals.shape != (n_tri, 3, 3):
            raise SceneError(f"mesh '{self.name}': corner_normals must have shape ({n_tri}, 3, 3)")
        for name, values in self.corner_attributes.items():
            if values.ndim != 3 or values.shape[:2] != (n_tri, 3) or not 1 <= values.shape[2] <= 4:
                raise SceneError(f"mesh '{self.name}': corner attribute '{name}' must have shape ({n_tri}, 3, 1..4), "
                                 f"got {values.shape}")
        if self.object_frame is not None and not np.all(np.isfinite(self.object_frame)):
            raise SceneError(f"mesh '{self.name}': object_frame is not finite")
        warnings = self._validate_placement(n_tri)
        if n_tri:
            n_degenerate = int(np.count_nonzero(self.triangle_normals()[1] <= 1e-20))
            if n_degenerate:
                warnings.append(f"mesh '{self.name}': {n_degenerate} degenerate triangles ignored")
        return warnings

    def world_copies(self) -> list["Mesh"]:
        """The mesh as world-space meshes: itself when not instanced, else one copy per instance
        (its transform at the frame; singular ones skipped) with normals transformed by the
        inverse transpose and the object frame composed with the instance's inverse; a moving
        instance's copy deforms through its transform's steps (instance_motion.placed_motion).
        What the renderer traces for emissive and medium-bounding instances (light sampling and
        volume stacks index world triangles), and the reference of the instancing tests."""
        if self.instances is None:
            return [self]
        base = self.frame() if self.object_frame is None else self.object_frame
        copies = []
        for k, transform in enumerate(self.instances):
            linear, offset = transform[:, :3], transform[:, 3]
            if abs(np.linalg.det(linear)) <= 1e-30:
                continue
            inverse = np.linalg.inv(linear)
            vertices = (self.vertices.astype(np.float64) @ linear.T + offset).astype(np.float32)
            triangles = self.triangles if np.linalg.det(linear) > 0 else self.triangles[:, ::-1]
            normals = attributes = None
            if self.corner_normals is not None:
                normals = self.corner_normals.astype(np.float64) @ inverse  # n' = M^-T n, rows
                normals /= np.maximum(np.linalg.norm(normals, axis=2, keepdims=True), 1e-30)
                if np.linalg.det(linear) < 0:
                    normals = normals[:, ::-1]
            attributes = self.corner_attributes if np.linalg.det(linear) > 0 else \
                {name: values[:, ::-1] for name, values in self.corner_attributes.items()}
            vertex_motion = None if self.vertex_motion is None else \
                (self.vertex_motion.astype(np.float64) @ linear.T + offset).astype(np.float32)
            normal_motion = None
            if self.motion is not None and not np.allclose(self.motion[k], self.motion[k, :1], rtol=0, atol=0):
                # a moving instance: a deforming world mesh at steps of its interpolated transform
                from .instance_motion import placed_motion
                vertex_motion, normal_motion = placed_motion(self.motion[k], self.vertices, self.vertex_motion,
                                                             self.corner_normals, self.corner_normal_motion)
                if normal_motion is not None and np.linalg.det(linear) < 0:
                    normal_motion = normal_motion[:, :, ::-1]
            elif self.corner_normal_motion is not None:
                normal_motion = self.corner_normal_motion.astype(np.float64) @ inverse
                normal_motion /= np.maximum(np.linalg.norm(normal_motion, axis=3, keepdims=True), 1e-30)
                if np.linalg.det(linear) < 0:
                    normal_motion = normal_motion[:, :, ::-1]
            frame = np.array(base, dtype=np.float64)
            # world -> object = (prototype -> object frame) o (world -> prototype)
            world_to_proto = np.concatenate([inverse, (-inverse @ offset)[:, None]], axis=1)
            frame[0, :, :3] = base[0, :, :3] @ world_to_proto[:, :3]
            frame[0, :, 3] = base[0, :, :3] @ world_to_proto[:, 3] + base[0, :, 3]
            copies.append(Mesh(f"{self.name}[{k}]", vertices, triangles, self.material_ids, normals, attributes,
                               frame, vertex_motion=vertex_motion, corner_normal_motion=normal_motion))
        return copies

    def _validate_placement(self, n_tri: int) -> list[str]:
        """Shapes and finiteness of instances / motion / vertex_motion (SceneError); warnings for
        what renders with a fallback."""
        name, warnings = self.name, []
        if self.instances is not None and not np.all(np.isfinite(self.instances)):
            raise SceneError(f"mesh '{name}': instances are not finite")
        if self.motion is not None:
            if self.instances is None:
                raise SceneError(f"mesh '{name}': motion needs instances (the transforms at the frame)")
            if self.motion.ndim != 4 or self.motion.shape[0] != len(self.instances) or self.motion.shape[1] < 2 \
                    or self.motion.shape[2:] != (3, 4):
                raise SceneError(f"mesh '{name}': motion must have shape ({len(self.instances)}, S >= 2, 3, 4), "
                                 f"got {self.motion.shape}")
            if not np.all(np.isfinite(self.motion)):
                raise SceneError(f"mesh '{name}': motion transforms are not finite")
        if self.vertex_motion is not None:
            shape = self.vertex_motion.shape
            if self.vertex_motion.ndim != 3 or shape[0] < 2 or shape[1:] != (len(self.vertices), 3):
                raise SceneError(f"mesh '{name}': vertex_motion must have shape (S >= 2, {len(self.vertices)}, 3), "
                                 f"got {shape}")
            if not np.all(np.isfinite(self.vertex_motion)):
                raise SceneError(f"mesh '{name}': vertex_motion is not finite")
        if self.corner_normal_motion is not None:
            steps = self.vertex_motion_steps
            shape = self.corner_normal_motion.shape
            if not steps or self.corner_normal_motion.ndim != 4 or shape != (steps, n_tri, 3, 3):
                raise SceneError(f"mesh '{name}': corner_normal_motion must have shape (S, {n_tri}, 3, 3) with "
                                 f"the S steps of vertex_motion, got {shape}")
            if not np.all(np.isfinite(self.corner_normal_motion)):
                raise SceneError(f"mesh '{name}': corner_normal_motion is not finite")
        if self.instances is not None:
            linear = self.instances[:, :, :3]
            det = np.linalg.det(linear) if len(linear) else np.zeros(0)
            singular = int(np.count_nonzero(np.abs(det) <= 1e-30))
            if singular:
                warnings.append(f"mesh '{name}': {singular} instances with a singular transform ignored")
        return warnings

    def open_edge_count(self, triangle_mask: Optional[np.ndarray] = None) -> int:
        """Edges used by exactly one triangle once coincident vertices are merged: 0 for a closed
        (watertight) surface, also when it is split at seams (extruded text, Edge Split, UV seams)."""
        tris = self.triangles if triangle_mask is None else self.triangles[triangle_mask]
        if len(tris) == 0:
            return 0
        _, weld = np.unique(self.vertices, axis=0, return_inverse=True)
        tris = weld.reshape(-1)[tris]
        edges = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
        _, counts = np.unique(edges, axis=0, return_counts=True)
        return int(np.count_nonzero(counts == 1))


# ----------------------------------------------------------------------------------------------
# Lights (power in W, colour folded in: power is an RGB triple)
# ----------------------------------------------------------------------------------------------
@dataclass
class PointLight:
    """Point light of total power `power` W (RGB). radius > 0 makes it a sphere light.

    radius 0: radiant intensity I = power / (4 pi) W/sr (Cycles, scene/light.cpp).
    soft_falloff: Blender 4.0+'s default for sphere lights (falloff 1/(d^2 + r^2) near the light).
    visible_camera: whether camera rays see the lamp itself (Blender's Object.visible_camera;
        lighting is unaffected). Added in format version 1 files as an optional field.
    """

    name: str
    position: np.ndarray
    power: np.ndarray
    radius: float = 0.0
    soft_falloff: bool = True
    visible_camera: bool = True

    def __post_init__(self):
        self.position = vec3(self.position, f"light '{self.name}' position")
        self.power = rgb(self.power, f"light '{self.name}' power")
        self.radius = float(self.radius)


@dataclass
class SpotLight(PointLight):
    """A point/sphere light masked by a cone around `direction`.

    spot_size: full cone angle in radians (Blender's spot_size); spot_blend in [0, 1] smooths the
    edge with smoothstep as Cycles. Power is not renormalised into the cone (Cycles).
    """

    direction: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -1.0]))
    spot_size: float = np.pi / 4
    spot_blend: float = 0.15

    def __post_init__(self):
        super().__post_init__()
        self.direction = unit(self.direction, f"light '{self.name}' direction")
        self.spot_size = float(self.spot_size)
        self.spot_blend = float(self.spot_blend)


AREA_SHAPES = ("square", "rectangle", "disk", "ellipse")


@dataclass
class AreaLight:
    """A one-sided area light emitting along `direction` (the lamp's local -Z).

    axis_u, axis_v: world-space vectors spanning the full width and height of the light (the
    lamp's local X and Y scaled by size and object scale). Radiance L = power / (pi * area).
    """

    name: str
    position: np.ndarray
    axis_u: np.ndarray
    axis_v: np.ndarray
    power: np.ndarray
    shape: str = "square"
    visible_camera: bool = True  # camera rays see the emitting surface (Object.visible_camera)

    def __post_init__(self):
        self.position = vec3(self.position, f"light '{self.name}' position")
        self.axis_u = vec3(self.axis_u, f"light '{self.name}' axis_u")
        self.axis_v = vec3(self.axis_v, f"light '{self.name}' axis_v")
        self.power = rgb(self.power, f"light '{self.name}' power")

    @property
    def direction(self) -> np.ndarray:
        n = np.cross(self.axis_u, self.axis_v)
        return -n / max(np.linalg.norm(n), 1e-30)

    @property
    def area(self) -> float:
        a = float(np.linalg.norm(np.cross(self.axis_u, self.axis_v)))
        return a * np.pi / 4 if self.shape in ("disk", "ellipse") else a


@dataclass
class SunLight:
    """Distant light. irradiance: W/m^2 on a surface facing the sun (RGB), angle: angular diameter."""

    name: str
    direction: np.ndarray
    irradiance: np.ndarray
    angle: float = 0.0
    visible_camera: bool = True  # camera rays see the sun disk (angle > 0; Object.visible_camera)

    def __post_init__(self):
        self.direction = unit(self.direction, f"light '{self.name}' direction")
        self.irradiance = rgb(self.irradiance, f"light '{self.name}' irradiance")
        self.angle = float(self.angle)


Light = Union[PointLight, SpotLight, AreaLight, SunLight]


# ----------------------------------------------------------------------------------------------
# Camera, film, world
# ----------------------------------------------------------------------------------------------
# Cycles' panorama types VolPath renders (projection.py); Blender's names in lower case.
PANORAMA_TYPES = ("equirectangular", "fisheye_equidistant", "fisheye_equisolid", "mirrorball", "central_cylindrical")


@dataclass
class Camera:
    """Blender-style camera, with Cycles' depth of field, panoramic projections and camera motion.

    projection: 'perspective', 'orthographic' or 'panoramic'.
    fov: full field of view in radians across the fitted sensor axis (perspective).
    ortho_scale: width in metres across the fitted axis (orthographic).
    sensor_fit: 'AUTO' (fit the larger image side), 'HORIZONTAL' or 'VERTICAL'.
    shift_x, shift_y: lens shift in units of the fitted image dimension (Blender's); for panoramic
        cameras in units of the image (Cycles' panoramic viewplane).
    Depth of field (Cycles' camera: aperturesize, focaldistance, blades, bladesrotation,
    aperture_ratio): aperture_size is the lens radius in metres (0: a pinhole); focus_distance the
    distance of the plane of focus (along the ray for panoramic cameras; below 1e-5: 1e-5, as
    Cycles); aperture_blades >= 3 makes the aperture a regular polygon turned by
    aperture_rotation (radians); aperture_ratio > 0 squeezes the lens's x (anamorphic bokeh).
    Panoramic (Cycles' panorama types): panorama_type one of projection.PANORAMA_TYPES;
    fisheye_fov (radians) and fisheye_lens (mm) for fisheyes; sensor_width / sensor_height (mm)
    for the equisolid fisheye; latitude / longitude ranges (radians) for equirectangular;
    cylinder_u_min/max (radians) and cylinder_v_min/max (heights over the cylinder's radius) for
    central cylindrical.
    Motion blur: motion_transforms, camera_to_world at evenly spaced times from the shutter's
    opening to its closing (empty: no camera motion; Cycles' camera motion steps);
    shutter_curve, the shutter's opening over that interval at evenly spaced times (empty: fully
    open throughout; Blender's motion_blur_shutter_curve); rolling_shutter with its
    rolling_shutter_duration (Cycles' rolling shutter type 'TOP').
    name: the camera's name in warnings.
    """

    camera_to_world: np.ndarray
    projection: str = "perspective"
    fov: float = np.radians(39.6)
    ortho_scale: float = 6.0
    sensor_fit: str = "AUTO"
    shift_x: float = 0.0
    shift_y: float = 0.0
    clip_start: float = 0.1
    clip_end: float = 1000.0
    name: str = "Camera"
    aperture_size: float = 0.0
    focus_distance: float = 10.0
    aperture_blades: int = 0
    aperture_rotation: float = 0.0
    aperture_ratio: float = 1.0
    panorama_type: str = "fisheye_equisolid"
    fisheye_fov: float = float(np.pi)
    fisheye_lens: float = 10.5
    sensor_width: float = 36.0
    sensor_height: float = 24.0
    latitude_min: float = -0.5 * float(np.pi)
    latitude_max: float = 0.5 * float(np.pi)
    longitude_min: float = -float(np.pi)
    longitude_max: float = float(np.pi)
    cylinder_u_min: float = -float(np.pi)
    cylinder_u_max: float = float(np.pi)
    cylinder_v_min: float = -1.0
    cylinder_v_max: float = 1.0
    motion_transforms: list = field(default_factory=list)
    shutter_curve: list = field(default_factory=list)
    rolling_shutter: bool = False
    rolling_shutter_duration: float = 0.1

    def __post_init__(self):
        self.camera_to_world = np.asarray(self.camera_to_world, dtype=np.float64).reshape(4, 4)

    def validate(self) -> list[str]:
        """SceneError for a camera that cannot be rendered; Cycles' values, with a warning naming
        the camera, for the numbers Cycles itself corrects."""
        name = f"camera '{self.name}'"
        if self.projection not in ("perspective", "orthographic", "panoramic"):
            raise SceneError(f"{name}: unknown projection '{self.projection}'")
        if not np.all(np.isfinite(self.camera_to_world)):
            raise SceneError(f"{name}: transform is not finite")
        numbers = {f: getattr(self, f) for f in ("aperture_size", "focus_distance", "aperture_rotation",
                                                  "aperture_ratio", "fisheye_fov", "fisheye_lens", "sensor_width",
                                                  "sensor_height", "latitude_min", "latitude_max", "longitude_min",
                                                  "longitude_max", "cylinder_u_min", "cylinder_u_max",
                                                  "cylinder_v_min", "cylinder_v_max", "rolling_shutter_duration")}
        for key, value in numbers.items():
            if not np.isfinite(value):
                raise SceneError(f"{name}: {key} is not finite ({value})")
        warnings = []
        if self.aperture_size < 0:  # Cycles: a lens only for aperturesize > 0
            warnings.append(f"{name}: negative aperture size {self.aperture_size}; rendered as a pinhole (as Cycles)")
            self.aperture_size = 0.0
        if self.aperture_size > 0 and self.focus_distance < 1e-5:
            warnings.append(f"{name}: focus distance {self.focus_distance} m; Cycles' minimum 1e-05 m is used")
            self.focus_distance = 1e-5
        if not self.aperture_ratio > 0:
            raise SceneError(f"{name}: aperture ratio {self.aperture_ratio} must be positive")
        if self.projection == "panoramic":
            if self.panorama_type not in PANORAMA_TYPES:
                raise SceneError(f"{name}: unknown panorama type '{self.panorama_type}' (expected one of: "
                                 f"{', '.join(PANORAMA_TYPES)})")
            for key in ("fisheye_fov", "fisheye_lens", "sensor_width", "sensor_height"):
                if not getattr(self, key) > 0:
                    raise SceneError(f"{name}: {key} {getattr(self, key)} must be positive")
        motion = []
        for k, matrix in enumerate(self.motion_transforms):
            matrix = np.asarray(matrix, dtype=np.float64)
            if matrix.shape != (4, 4) or not np.all(np.isfinite(matrix)):
                raise SceneError(f"{name}: motion_transforms[{k}] is not a finite 4x4 matrix")
            motion.append(matrix)
        if len(motion) == 1:
            raise SceneError(f"{name}: one motion transform; motion needs at least two (or none)")
        self.motion_transforms = motion
        curve = np.asarray(self.shutter_curve, dtype=np.float64).ravel()
        if curve.size and (not np.all(np.isfinite(curve)) or np.any(curve < 0)):
            raise SceneError(f"{name}: the shutter curve must be finite and non-negative")
        if curve.size and not np.any(curve > 0):
            warnings.append(f"{name}: the shutter curve is closed throughout; rendered with the shutter open "
                            "throughout")
            curve = np.zeros(0)
        self.shutter_curve = curve.tolist()
        return warnings


FILTERS = ("blackman-harris", "box", "gaussian")


@dataclass
class Film:
    """Output resolution and pixel filter.

    crop: optional (xmin, xmax, ymin, ymax) fractions of the frame, Blender's border convention
        (y measured from the bottom). Only the crop region is rendered.
    filter: 'blackman-harris' (Cycles' default; filter_width is Blender's number, 1.5 px, which
        Cycles doubles internally to a +-1.5 px support), 'gaussian' or 'box' (width in px).
    """

    width: int
    height: int
    crop: Optional[tuple] = None
    filter: str = "blackman-harris"
    filter_width: float = 1.5


@dataclass
class World:
    """Constant background radiance (RGB, W/(m^2 sr)) and the medium that fills all space outside
    closed media (-1: vacuum)."""

    background: np.ndarray = field(default_factory=lambda: np.zeros(3))
    medium: int = -1

    def __post_init__(self):
        self.background = rgb(self.background, "world background")
        self.medium = int(self.medium)


@dataclass
class RenderSettings:
    """Sampling and bounce limits, with Cycles' meaning.

    Bounce counts as Cycles' (kernel/integrator/path_state.h): volume_bounces = 0 still allows one
    scattering vertex with next-event estimation. Crossings of null (volume-only) boundaries are
    not transparent bounces (Cycles kernel/bvh/intersect_filter.h counts only surfaces without
    SD_HAS_ONLY_VOLUME); transparent_bounces is kept for transparent BSDFs, which have no kind yet.
    volume_sampling: 'mis' (distance + equiangular, one-sample MIS, Cycles' default for
    materials), 'distance' or 'equiangular'.
    """

    samples: int = 16
    seed: int = 0
    max_bounces: int = 12
    diffuse_bounces: int = 4
    glossy_bounces: int = 4
    transmission_bounces: int = 12
    volume_bounces: int = 0
    transparent_bounces: int = 8
    volume_sampling: str = "mis"
    # per-point light selection (Cycles' light tree, its use_light_tree default); False: lights
    # chosen by power alone (Cycles' light distribution), the same image with more noise
    light_tree: bool = True
    # Russian roulette from the 7th scattering on: later than Cycles (from the 2nd; its Min Light
    # Bounces 0 is kernel min_bounce 1, scene/integrator.cpp, path_state.h
    # path_state_continuation_probability). Measured at equal time (README, Benchmarks, session 15):
    # starting after bounce 1 or 3 cost error per sample in fog; after 6, less error for fewer samples.
    russian_roulette_min_bounces: int = 6
    batch_size: int = 1 << 14  # a batch's path state stays in cache: see round_schedule / README session 20
    threads: int = 0  # 0: all cores
    # seconds of rendering after which no further round starts (0: none), Cycles' Time Limit
    # (render_scheduler.cpp: scene synchronisation left out, the samples still cap the render)
    time_limit: float = 0.0
    # 'threads' (default; safe inside Blender) or 'processes' (forked workers, Linux/macOS; numpy's
    # Python-level overhead holds the GIL, so processes scale better outside Blender).
    parallelism: str = "threads"


@dataclass
class Scene:
    camera: Camera
    film: Film
    meshes: list = field(default_factory=list)
    materials: list = field(default_factory=list)
    media: list = field(default_factory=list)
    lights: list = field(default_factory=list)
    world: World = field(default_factory=World)
    settings: RenderSettings = field(default_factory=RenderSettings)
    #: shading.images.Image list read by the surface programs' image textures (by index)
    images: list = field(default_factory=list)

    def validate(self) -> list[str]:
        """Raise SceneError for unusable input; fix up and return warnings for recoverable input."""
        warnings: list[str] = []
        for what in ("width", "height"):
            value = getattr(self.film, what)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise SceneError(f"film {what} must be an integer, got {value!r}")
        if self.film.width < 1 or self.film.height < 1:
            raise SceneError(f"film resolution {self.film.width}x{self.film.height} is empty")
        if self.film.filter not in FILTERS:
            raise SceneError(f"unknown pixel filter '{self.film.filter}' (expected one of {FILTERS})")
        warnings += self.camera.validate()
        for medium in self.media:
            if getattr(medium, "is_homogeneous", True):
                warnings += medium.validate()
        n_media = len(self.media)
        for material in self.materials:
            if material.surface not in SURFACE_KINDS:
                raise SceneError(f"material '{material.name}': unknown surface '{material.surface}'")
            if not -1 <= material.medium < n_media:
                raise SceneError(f"material '{material.name}': medium index {material.medium} out of range")
            for node in material.surface_nodes:
                warnings += [f"material '{material.name}': {w}" for w in node.sanitize()]
            if material.surface_program is not None:
                try:
                    material.surface_program.validate(material.bsdf_nodes(), f"material '{material.name}'")
                except ValueError as error:
                    raise SceneError(str(error))
            if np.any(material.base_color < 0) or np.any(material.emission < 0):
                warnings.append(f"material '{material.name}': negative colour clamped to 0")
                material.base_color = np.maximum(material.base_color, 0.0)
                material.emission = np.maximum(material.emission, 0.0)
        if not -1 <= self.world.medium < n_media:
            raise SceneError(f"world medium index {self.world.medium} out of range")
        if self.world.medium >= 0 and not getattr(self.media[self.world.medium], "is_homogeneous", True):
            raise SceneError("a grid (heterogeneous) medium cannot fill the world; bound it with a closed mesh")
        for mesh in self.meshes:
            warnings += mesh.validate(len(self.materials))
            medium_faces = np.array([m.medium >= 0 for m in self.materials], dtype=bool)
            if len(mesh.triangles) and medium_faces.size and medium_faces[mesh.material_ids].any():
                open_edges = mesh.open_edge_count(medium_faces[mesh.material_ids])
                if open_edges:
                    raise SceneError(
                        f"mesh '{mesh.name}' bounds a medium but is not closed ({open_edges} open edges): "
                        "rays would enter the medium and never leave it")
        for light in self.lights:
            warnings += validate_light(light)
        if not self.meshes and not self.lights and not np.any(self.world.background > 0):
            warnings.append("the scene is empty: nothing emits light, the image is black")
        return warnings


def validate_light(light) -> list[str]:
    """SceneError for a light that cannot be rendered, warnings for one that renders as nothing."""
    name = f"light '{light.name}'"
    power = light.irradiance if isinstance(light, SunLight) else light.power
    if np.any(power < 0):
        raise SceneError(f"{name}: negative power {power.tolist()}")
    if isinstance(light, AreaLight):
        if light.shape not in AREA_SHAPES:
            raise SceneError(f"{name}: unknown area shape '{light.shape}'")
        if light.area <= 1e-12:
            raise SceneError(f"{name}: area light has zero size")
    if isinstance(light, PointLight) and light.radius < 0:
        raise SceneError(f"{name}: negative radius")
    if isinstance(light, SunLight) and not 0 <= light.angle < np.pi:
        raise SceneError(f"{name}: sun angle {light.angle} outside [0, pi)")
    if not np.any(power > 0):
        return [f"{name}: zero power, ignored"]
    return []
