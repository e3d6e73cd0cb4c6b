"""Surface shader programs: BSDF inputs driven by textures, attributes and node math, evaluated at
each surface hit by the one shader interpreter (shading/interpreter.py), as Cycles' SVM evaluates
a material's nodes at every shading point (kernel/svm/svm.h svm_eval_nodes) before its closures.

A material whose BSDF inputs are linked to varying nodes carries a SurfaceProgram: the program
computes each linked input into a register, and `bindings` name the (node, field) it replaces.
At a hit of that material the path stage (path_kernels._surface, shadow_step):
1. fills the program's inputs -- P, the shading normal N, the direction to the viewer I, the
   active-render UV map (R_UV), the geometric normal and back-face flag (R_NG, R_BACKFACING), and
   the per-corner attributes it reads (named UV maps, colour attributes, tangents), each
   interpolated with the hit's barycentrics as Cycles' primitive_surface_attribute;
2. runs the program with the hit object's frame (Texture Coordinate Object / Generated);
3. copies the material's SurfaceNode rows into a per-thread scratch table and overwrites the
   bound fields for this hit (non-finite values read as 0), and takes the program's normal
   output (Normal Map, Bump) as the closures' normal and its tangent output (Tangent input of
   anisotropic BSDFs) as their tangent;
4. expands the scratch rows into closures exactly as a constant material.

A program with Bump nodes also gets its inputs at two points moved from the hit in the plane of
the geometric normal, P + ex and P + ey (`bump_offsets`: the registers of ex, ey; `shifts`: where
each moved input goes); the program swaps them in to evaluate the height there
(shading/program.py OP_BUMP). Cycles moves by the ray footprint (filter width x dPdx, dPdy,
kernel/svm/attribute.h svm_node_bump_P_dx); VolPath moves by BUMP_OFFSET x max(|P|, 1) along
make_orthonormals(Ng), so its normal is the limit of Cycles' as the footprint shrinks:
normalize(N - Distance (grad h - (grad h . N) / (Ng . N) Ng)) with grad h in the triangle's
plane (README: where a height varies within a tenth of a pixel, Cycles' finite footprint filters it).

A program may also compute the material's emitted radiance (textured Emission / Principled
emission): `emission` names its register. The mesh-light rows of such a material carry a unit
strength (lights.py) and the path stage multiplies in the program's emission at the point hit
or sampled on the light (program_emission), so the light-sampling pdf and MIS weights stay
those of a constant emitter, as in Cycles where the emission shader is evaluated at the
sampled point (kernel/light/triangle.h, integrator/shade_surface.h).

Attributes are addressed by name: "uv:<map>" ("uv:" is the active-render map), "color:<name>",
"tangent:<map>" (4 channels: MikkTSpace tangent and sign). A mesh without an attribute reads 0
(Cycles' ATTR_STD_NOT_FOUND; the exporter warns).
"""
from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass, field

import numpy as np

from .bsdfs.nodes import FLOAT_FIELDS, RGB_FIELDS, SurfaceNode, surface_node_table
from .instance_motion import transform_at1
from .jit import inline_stage_kernel, stage_kernel
from .shading.images import empty_image_table
from .shading.interpreter import run_program
from .shading.program import OPS, R_BACKFACING, R_I, R_N, R_NG, R_UV, ShaderProgram

#: the SurfaceNode fields a program may drive, by binding code
BIND_FIELDS = tuple(FLOAT_FIELDS) + tuple(RGB_FIELDS)
BIND_CODES = {name: i for i, name in enumerate(BIND_FIELDS)}
ACTIVE_UV = "uv:"
# the kernels' _set_float / _set_rgb switch on these positions
assert BIND_FIELDS[:17] == ("weight", "roughness", "metallic", "ior", "alpha", "diffuse_roughness",
                            "specular_ior_level", "transmission", "coat_weight", "coat_roughness", "coat_ior",
                            "sheen_weight", "sheen_roughness", "anisotropic", "anisotropic_rotation",
                            "subsurface_weight", "emission_strength")
assert BIND_FIELDS[17:] == ("color", "specular_tint", "coat_tint", "sheen_tint", "edge_tint", "conductor_n",
                            "conductor_k", "emission_color")


@dataclass
class SurfaceProgram:
    """A material's surface program.

    program: the ShaderProgram (shading/program.py).
    bindings: [(node index in Material.surface_nodes, SurfaceNode field, register)]; RGB fields
        read three registers.
    inputs: [(attribute name, width, register)]: per-corner attributes written before each run.
    normal: register of the closures' normal (3), or -1 (the interpolated normal).
    tangent: register of the anisotropic closures' tangent (3, world space), or -1 (none).
    emission: register of the emitted radiance (3, W/(m^2 sr)), or -1 (the material's constant).
    bump_offsets: first of 6 registers the kernel fills with ex, ey (Bump nodes), or -1.
    shifts: [(input, width, dx register, dy register)]: an input ("P" the position, else an
        attribute name as in `inputs`, "uv:" the active-render map) at P + ex and P + ey.
    shading_normal: register of the shading normal the program sets (3), or -1: the Material
        Output's Displacement bump replaces Cycles' sd->N itself (SetNormalNode, C5
        scene/shader_graph.cpp bump_from_displacement), so closures on it get no bump shadowing
        term (closure/bsdf.h bump_shadowing_term compares with sd->N).
    """

    program: ShaderProgram
    bindings: list = field(default_factory=list)
    inputs: list = field(default_factory=list)
    normal: int = -1
    tangent: int = -1
    emission: int = -1
    bump_offsets: int = -1
    shifts: list = field(default_factory=list)
    shading_normal: int = -1

    def validate(self, nodes: list, where: str) -> None:
        """Raise ValueError for bindings or inputs outside the program or the material."""
        self.program.validate()
        regs = self.program.n_registers
        for node_index, name, register in self.bindings:
            if not 0 <= int(node_index) < len(nodes):
                raise ValueError(f"{where}: binding to node {node_index} of {len(nodes)}")
            if name not in BIND_CODES:
                raise ValueError(f"{where}: binding to unknown field {name!r}")
            width = 3 if name in RGB_FIELDS else 1
            if not 0 <= int(register) <= regs - width:
                raise ValueError(f"{where}: binding register {register} outside the {regs} registers")
        for name, width, register in self.inputs:
            if not (isinstance(name, str) and 1 <= int(width) <= 4 and 0 <= int(register) <= regs - int(width)):
                raise ValueError(f"{where}: bad attribute input {name!r} ({width} at {register})")
        if self.bump_offsets != -1 and not 0 <= int(self.bump_offsets) <= regs - 6:
            raise ValueError(f"{where}: bump offset registers {self.bump_offsets} outside the {regs} registers")
        for name, width, dx, dy in self.shifts:
            if not (isinstance(name, str) and 1 <= int(width) <= 4 and 0 <= int(dx) <= regs - int(width)
                    and 0 <= int(dy) <= regs - int(width)):
                raise ValueError(f"{where}: bad bump input {name!r} ({width} at {dx}, {dy})")
        if self.shifts and self.bump_offsets == -1:
            raise ValueError(f"{where}: bump inputs without bump offsets")
        for what in ("normal", "tangent", "emission", "shading_normal"):
            reg = int(getattr(self, what))
            if reg != -1 and not 0 <= reg <= regs - 3:
                raise ValueError(f"{where}: {what} register {reg} outside the {regs} registers")
        self._check_literals(where)

    def _check_literals(self, where: str) -> None:
        """Literal operands of the surface opcodes (the interpreter trusts them): tile tables
        inside the program's tables, enums in range."""
        code, tables = self.program.code, self.program.tables
        by_code = {spec.code: (name, spec) for name, spec in OPS.items()}
        pc = 0
        while pc < len(code):
            name, spec = by_code[int(code[pc])]
            operands = [int(v) for v in code[pc + 1:pc + 1 + len(spec.operands)]]
            if name == "IMAGE_TEXTURE":
                _, tiles, count, interpolation, extension, projection, _unassociate = operands[:7]
                if count < 0 or (count and not 0 <= tiles <= len(tables) - 2 * count):
                    raise ValueError(f"{where}: image tile table {tiles} + {count} tiles outside the program's tables")
                if not (0 <= interpolation <= 2 and 0 <= extension <= 3 and projection in (0, 2, 3)):
                    raise ValueError(f"{where}: image texture options {interpolation}, {extension}, {projection} "
                                     "out of range")
            elif name == "NORMAL_MAP" and not 0 <= operands[0] <= 4:
                raise ValueError(f"{where}: normal map space {operands[0]} out of range")
            elif name == "TANGENT" and not 0 <= operands[0] <= 3:
                raise ValueError(f"{where}: tangent kind {operands[0]} out of range")
            elif name == "IMAGE_BOX" and not (0 <= operands[1] <= 2 and 0 <= operands[2] <= 3):
                raise ValueError(f"{where}: box image texture options {operands[1]}, {operands[2]} out of range")
            elif name == "SWAP":
                count, x, y = operands
                if not (0 <= count <= 4 and x + count <= self.program.n_registers
                        and y + count <= self.program.n_registers):
                    raise ValueError(f"{where}: SWAP of {count} registers at {x}, {y} outside the program")
            pc += 1 + len(spec.operands)

    def drives(self, nodes: list) -> set:
        """{(node kind, field)} this program drives."""
        return {(nodes[int(i)].kind, name) for i, name, _ in self.bindings}

    def to_record(self):
        header = {"name": self.program.name, "varying": bool(self.program.varying),
                  "bindings": [[int(i), str(n), int(r)] for i, n, r in self.bindings],
                  "inputs": [[str(n), int(w), int(r)] for n, w, r in self.inputs], "normal": int(self.normal),
                  "tangent": int(self.tangent), "emission": int(self.emission),
                  "bump_offsets": int(self.bump_offsets),
                  "shifts": [[str(n), int(w), int(x), int(y)] for n, w, x, y in self.shifts],
                  "shading_normal": int(self.shading_normal)}
        arrays = {"code": self.program.code, "init": self.program.init, "tables": self.program.tables}
        return header, arrays

    @classmethod
    def from_record(cls, header: dict, arrays: dict) -> "SurfaceProgram":
        program = ShaderProgram(str(header.get("name", "surface")), arrays["code"], arrays["init"],
                                arrays["tables"], varying=bool(header.get("varying", True)))
        return cls(program, [(int(i), str(n), int(r)) for i, n, r in header.get("bindings", [])],
                   [(str(n), int(w), int(r)) for n, w, r in header.get("inputs", [])], int(header.get("normal", -1)),
                   int(header.get("tangent", -1)), int(header.get("emission", -1)),
                   int(header.get("bump_offsets", -1)),
                   [(str(n), int(w), int(x), int(y)) for n, w, x, y in header.get("shifts", [])],
                   int(header.get("shading_normal", -1)))


# ---------------------------------------------------------------------------------------------
# Tables for the compiled stages
# ---------------------------------------------------------------------------------------------
SurfaceProgramTables = namedtuple("SurfaceProgramTables", [
    "any",            # bool: some material has a program
    "mat_program",    # (n_materials,) int64 program index or -1
    "code", "init", "tables",  # every program's arrays, concatenated
    "prog",           # (n_programs, 6) int64 code start/end, init start/end, tables start/end
    "prog_normal",    # (n_programs,) int64 normal register or -1
    "prog_tangent",   # (n_programs,) int64 tangent register or -1
    "prog_emission",  # (n_programs,) int64 emission register or -1
    "prog_bind",      # (n_programs, 2) int64 first binding, count
    "bind",           # (n_bindings, 3) int64 node row within the material, field code, register
    "prog_input",     # (n_programs, 2) int64 first input, count
    "input",          # (n_inputs, 3) int64 corner channel (-1: the mesh has none), width, register
    "prog_bump",      # (n_programs,) int64 bump offset registers or -1
    "prog_shading_normal",  # (n_programs,) int64 register of the shading normal the program sets, or -1
    "prog_shift",     # (n_programs, 2) int64 first shift, count
    "shift",          # (n_shifts, 5) int64 channel (-2: position, -1: none), channel width, register
                      # width, dx register, dy register
    "tri_corners",    # (n_tri, 3, 3) float64 world-space corners (only when some program bumps)
    "uv_channel",     # int: corner channel of the active-render UV map (-1: none anywhere)
    "corner",         # (n_tri, 3, channels) float32 per-corner attributes
    "tri_mesh",       # (n_tri,) int32 mesh of each triangle
    "frames",         # (n_meshes, 2, 3, 4) float64 world -> object, object -> generated per mesh
    "frame_steps", "frame_motion", "frame_placed",  # moving objects' frames at a ray's time (accel.frame_motion)
    "no_grid", "no_world_to_index",  # the volume-only interpreter inputs, unused here
    "images",         # shading.images.ImageTable
])

# Per-thread scratch: registers, the program's initial registers with the hit's inputs, and the
# material's node rows with this hit's values.
# frame: a moving object's frame at the hit's shutter time (frame_at_time), read for row -1.
SurfaceScratch = namedtuple("SurfaceScratch", ["regs", "init", "nodes", "frame"])


def surface_program_tables(materials, accel, images_table=None) -> SurfaceProgramTables:
    """Pack the materials' programs, the accelerator's corner attributes and per-mesh frames."""
    programs = [m.surface_program for m in materials if getattr(m, "surface_program", None) is not None]
    names = []
    for p in programs:
        for name in [n for n, _, _ in p.inputs] + [n for n, _, _, _ in p.shifts if n != "P"]:
            if name not in names:
                names.append(name)
    if any(True for _ in programs) and ACTIVE_UV not in names:
        names.append(ACTIVE_UV)
    if programs:
        corner, channels = accel.corner_attributes(names)
    else:  # never read
        corner, channels = np.zeros((1, 3, 1), np.float32), {}
    mat_program = np.full(max(len(materials), 1), -1, np.int64)
    code, init, tables = [], [], []
    prog = np.zeros((max(len(programs), 1), 6), np.int64)
    prog_normal = np.full(max(len(programs), 1), -1, np.int64)
    prog_tangent = np.full(max(len(programs), 1), -1, np.int64)
    prog_emission = np.full(max(len(programs), 1), -1, np.int64)
    prog_bind = np.zeros((max(len(programs), 1), 2), np.int64)
    prog_input = np.zeros((max(len(programs), 1), 2), np.int64)
    prog_bump = np.full(max(len(programs), 1), -1, np.int64)
    prog_shading_normal = np.full(max(len(programs), 1), -1, np.int64)
    prog_shift = np.zeros((max(len(programs), 1), 2), np.int64)
    binds, inputs, shifts = [], [], []
    sizes = [0, 0, 0]
    k = 0
    for m, material in enumerate(materials):
        sp = getattr(material, "surface_program", None)
        if sp is None:
            continue
        mat_program[m] = k
        p = sp.program
        prog[k] = (sizes[0], sizes[0] + len(p.code), sizes[1], sizes[1] + len(p.init), sizes[2],
                   sizes[2] + len(p.tables))
        sizes[0] += len(p.code)
        sizes[1] += len(p.init)
        sizes[2] += len(p.tables)
        code.append(p.code)
        init.append(p.init)
        tables.append(p.tables)
        prog_normal[k] = int(sp.normal)
        prog_tangent[k] = int(sp.tangent)
        prog_emission[k] = int(sp.emission)
        prog_bind[k] = (len(binds), len(sp.bindings))
        binds += [(int(i), BIND_CODES[n], int(r)) for i, n, r in sp.bindings]
        prog_input[k] = (len(inputs), len(sp.inputs))
        inputs += [(channels.get(n, (-1, 0))[0] if channels.get(n, (-1, 0))[1] >= int(w) else -1, int(w), int(r))
                   for n, w, r in sp.inputs]
        prog_bump[k] = int(sp.bump_offsets)
        prog_shading_normal[k] = int(sp.shading_normal)
        prog_shift[k] = (len(shifts), len(sp.shifts))
        for name, width, dx, dy in sp.shifts:
            channel, have = (-2, 3) if name == "P" else channels.get(name, (-1, 0))
            shifts.append((channel, min(int(have), int(width)), int(width), int(dx), int(dy)))
        k += 1
    uv = channels.get(ACTIVE_UV, (-1, 0))[0]
    bumps = any(p.bump_offsets >= 0 for p in programs)
    frame_steps, frame_motion, frame_placed = accel.frame_motion()
    return SurfaceProgramTables(
        any=bool(programs), mat_program=mat_program,
        code=np.concatenate(code).astype(np.int32) if code else np.zeros(1, np.int32),
        init=np.concatenate(init) if init else np.zeros(1), tables=np.concatenate(tables) if tables else np.zeros(1),
        prog=prog, prog_normal=prog_normal, prog_tangent=prog_tangent, prog_emission=prog_emission, prog_bind=prog_bind,
        bind=np.array(binds, np.int64).reshape(-1, 3) if binds else np.zeros((1, 3), np.int64),
        prog_input=prog_input,
        input=np.array(inputs, np.int64).reshape(-1, 3) if inputs else np.zeros((1, 3), np.int64),
        prog_bump=prog_bump, prog_shift=prog_shift, prog_shading_normal=prog_shading_normal,
        shift=np.array(shifts, np.int64).reshape(-1, 5) if shifts else np.zeros((1, 5), np.int64),
        tri_corners=np.ascontiguousarray(accel.corners, np.float64) if bumps and accel.triangle_count
        else np.zeros((1, 3, 3)),
        uv_channel=int(uv), corner=corner, tri_mesh=np.ascontiguousarray(accel.mesh_ids, np.int32)
        if len(accel.mesh_ids) else np.zeros(1, np.int32),
        frames=accel.mesh_frames(), frame_steps=frame_steps, frame_motion=frame_motion, frame_placed=frame_placed,
        no_grid=np.zeros((1, 1, 1, 1), np.float32), no_world_to_index=np.zeros((3, 4)),
        images=images_table if images_table is not None else empty_image_table())


def new_surface_scratch(materials, tables: SurfaceProgramTables) -> SurfaceScratch:
    """Scratch for one thread: room for the largest program and material."""
    n_regs = 1
    nodes = 1
    for m in materials:
        sp = getattr(m, "surface_program", None)
        if sp is not None:
            n_regs = max(n_regs, sp.program.n_registers)
            nodes = max(nodes, len(m.bsdf_nodes()))
    rows = surface_node_table([[SurfaceNode() for _ in range(nodes)]])
    return SurfaceScratch(np.zeros(n_regs), np.zeros(n_regs), rows, np.zeros((2, 3, 4)))


# ---------------------------------------------------------------------------------------------
# Kernels
# ---------------------------------------------------------------------------------------------
@inline_stage_kernel
def _corner(SP, prim, w0, hu, hv, channel):
    c = SP.corner
    return w0 * c[prim, 0, channel] + hu * c[prim, 1, channel] + hv * c[prim, 2, channel]


@stage_kernel
def _copy_row(SN, src, D, dst):
    D.kind[dst] = SN.kind[src]
    D.fresnel[dst] = SN.fresnel[src]
    D.distribution[dst] = SN.distribution[src]
    D.weight[dst] = SN.weight[src]
    D.roughness[dst] = SN.roughness[src]
    D.metallic[dst] = SN.metallic[src]
    D.ior[dst] = SN.ior[src]
    D.alpha[dst] = SN.alpha[src]
    D.diffuse_roughness[dst] = SN.diffuse_roughness[src]
    D.specular_ior_level[dst] = SN.specular_ior_level[src]
    D.transmission[dst] = SN.transmission[src]
    D.coat_weight[dst] = SN.coat_weight[src]
    D.coat_roughness[dst] = SN.coat_roughness[src]
    D.coat_ior[dst] = SN.coat_ior[src]
    D.sheen_weight[dst] = SN.sheen_weight[src]
    D.sheen_roughness[dst] = SN.sheen_roughness[src]
    D.anisotropic[dst] = SN.anisotropic[src]
    D.anisotropic_rotation[dst] = SN.anisotropic_rotation[src]
    D.subsurface_weight[dst] = SN.subsurface_weight[src]
    D.emission_strength[dst] = SN.emission_strength[src]
    for c in range(3):
        D.color[dst, c] = SN.color[src, c]
        D.specular_tint[dst, c] = SN.specular_tint[src, c]
        D.coat_tint[dst, c] = SN.coat_tint[src, c]
        D.sheen_tint[dst, c] = SN.sheen_tint[src, c]
        D.edge_tint[dst, c] = SN.edge_tint[src, c]
        D.conductor_n[dst, c] = SN.conductor_n[src, c]
        D.conductor_k[dst, c] = SN.conductor_k[src, c]
        D.emission_color[dst, c] = SN.emission_color[src, c]


@inline_stage_kernel
def _finite(v):
    return v if (v == v and abs(v) <= 1.7976931348623157e308) else 0.0


@stage_kernel
def _set_float(D, row, code, v):
    """D.<FLOAT_FIELDS[code]>[row] = v (BIND_CODES order)."""
    if code == 0:
        D.weight[row] = v
    elif code == 1:
        D.roughness[row] = v
    elif code == 2:
        D.metallic[row] = v
    elif code == 3:
        D.ior[row] = v
    elif code == 4:
        D.alpha[row] = v
    elif code == 5:
        D.diffuse_roughness[row] = v
    elif code == 6:
        D.specular_ior_level[row] = v
    elif code == 7:
        D.transmission[row] = v
    elif code == 8:
        D.coat_weight[row] = v
    elif code == 9:
        D.coat_roughness[row] = v
    elif code == 10:
        D.coat_ior[row] = v
    elif code == 11:
        D.sheen_weight[row] = v
    elif code == 12:
        D.sheen_roughness[row] = v
    elif code == 13:
        D.anisotropic[row] = v
    elif code == 14:
        D.anisotropic_rotation[row] = v
    elif code == 15:
        D.subsurface_weight[row] = v
    elif code == 16:
        D.emission_strength[row] = v


@stage_kernel
def _set_rgb(D, row, code, r, g, b):
    """D.<RGB_FIELDS[code - len(FLOAT_FIELDS)]>[row] = (r, g, b)."""
    k = code - 17
    A = D.color
    if k == 1:
        A = D.specular_tint
    elif k == 2:
        A = D.coat_tint
    elif k == 3:
        A = D.sheen_tint
    elif k == 4:
        A = D.edge_tint
    elif k == 5:
        A = D.conductor_n
    elif k == 6:
        A = D.conductor_k
    elif k == 7:
        A = D.emission_color
    A[row, 0] = r
    A[row, 1] = g
    A[row, 2] = b


#: Bump sampling offset relative to max(|P|, 1) (surface_programs docstring): small against any
#: height detail, large against float32 texture coordinates' rounding.
BUMP_OFFSET = 1e-5


@stage_kernel
def _bump_inputs(SP, init, k, prim, hu, hv, px, py, pz, ng):
    """Fill program k's bump registers: the offsets ex, ey (orthogonal, in the plane of ng, both of
    length BUMP_OFFSET max(|P|, 1)) and each shifted input at P + ex, P + ey, with the
    triangle's barycentrics moved accordingly (attributes extrapolate linearly past its edges,
    as Cycles' differentials)."""
    size = BUMP_OFFSET * max(abs(px), abs(py), abs(pz), 1.0)
    # make_orthonormals (C5 util/math_float3.h)
    if ng[0] != ng[1] or ng[0] != ng[2]:
        ax, ay, az = ng[2] - ng[1], ng[0] - ng[2], ng[1] - ng[0]
    else:
        ax, ay, az = ng[2] - ng[1], ng[0] + ng[2], -ng[1] - ng[0]
    la = np.sqrt(ax * ax + ay * ay + az * az)
    ax, ay, az = ax / la, ay / la, az / la
    bx, by, bz = ng[1] * az - ng[2] * ay, ng[2] * ax - ng[0] * az, ng[0] * ay - ng[1] * ax
    o = SP.prog_bump[k]
    e = ((ax * size, ay * size, az * size), (bx * size, by * size, bz * size))
    for i in range(2):
        for c in range(3):
            init[o + 3 * i + c] = e[i][c]
    # barycentric change of a move e in the triangle's plane
    c = SP.tri_corners[prim]
    e1 = (c[1, 0] - c[0, 0], c[1, 1] - c[0, 1], c[1, 2] - c[0, 2])
    e2 = (c[2, 0] - c[0, 0], c[2, 1] - c[0, 1], c[2, 2] - c[0, 2])
    nx, ny, nz = e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]
    nn = nx * nx + ny * ny + nz * nz
    s0, n_shift = SP.prog_shift[k, 0], SP.prog_shift[k, 1]
    for i in range(2):
        ex, ey, ez = e[i]
        du = dv = 0.0
        if nn > 0.0:
            du = ((ey * e2[2] - ez * e2[1]) * nx + (ez * e2[0] - ex * e2[2]) * ny + (ex * e2[1] - ey * e2[0]) * nz) / nn
            dv = ((e1[1] * ez - e1[2] * ey) * nx + (e1[2] * ex - e1[0] * ez) * ny + (e1[0] * ey - e1[1] * ex) * nz) / nn
        u, v = hu + du, hv + dv
        w0 = 1.0 - u - v
        for j in range(s0, s0 + n_shift):
            channel, have, width = SP.shift[j, 0], SP.shift[j, 1], SP.shift[j, 2]
            reg = SP.shift[j, 3 + i]
            for ch in range(width):
                if channel == -2:
                    value = (px, py, pz)[ch] + e[i][ch]
                elif channel >= 0 and ch < have:
                    value = _corner(SP, prim, w0, u, v, channel + ch)
                else:
                    value = 0.0
                init[reg + ch] = value


@stage_kernel
def _run_at_hit(SP, SS, k, prim, frame, hu, hv, px, py, pz, ns, ng, wi, backfacing):
    """Run program k at a hit (frame: the hit's row in SP.frames -- its mesh's, SP.tri_mesh[prim],
    or its instance's): fill the inputs (module docstring, step 1), run; SS.regs holds the result."""
    i0, i1, t0, t1 = SP.prog[k, 2], SP.prog[k, 3], SP.prog[k, 4], SP.prog[k, 5]
    init = SS.init
    n_regs = i1 - i0
    for i in range(n_regs):
        init[i] = SP.init[i0 + i]
    w0 = 1.0 - hu - hv
    init[R_N], init[R_N + 1], init[R_N + 2] = ns[0], ns[1], ns[2]
    init[R_I], init[R_I + 1], init[R_I + 2] = wi[0], wi[1], wi[2]
    init[R_NG], init[R_NG + 1], init[R_NG + 2] = ng[0], ng[1], ng[2]
    init[R_BACKFACING] = 1.0 if backfacing else 0.0
    uv = SP.uv_channel
    if uv >= 0:
        init[R_UV] = _corner(SP, prim, w0, hu, hv, uv)
        init[R_UV + 1] = _corner(SP, prim, w0, hu, hv, uv + 1)
    else:
        init[R_UV] = init[R_UV + 1] = 0.0
    init[R_UV + 2] = 0.0
    b0, nb = SP.prog_input[k, 0], SP.prog_input[k, 1]
    for j in range(b0, b0 + nb):
        channel, width, reg = SP.input[j, 0], SP.input[j, 1], SP.input[j, 2]
        for c in range(width):
            init[reg + c] = _corner(SP, prim, w0, hu, hv, channel + c) if channel >= 0 else 0.0
    if SP.prog_bump[k] >= 0:
        _bump_inputs(SP, init, k, prim, hu, hv, px, py, pz, ng)
    run_program(SP.code[SP.prog[k, 0]:SP.prog[k, 1]], init[:n_regs], SP.tables[t0:t1], SS.regs,
                SS.frame if frame < 0 else SP.frames[frame], SP.no_grid, SP.no_world_to_index, px, py, pz, SP.images)


@stage_kernel
def frame_at_time(SP, SS, frame, time):
    """The hit's frame row, or -1 with SS.frame filled when the row's object moves: world ->
    object at shutter time `time` = the row's frame o placed o M(time)^-1, M interpolated as
    Cycles (instance_motion.transform_at1; Cycles object_fetch_transform_motion_test gives the
    shader a moving object's inverse transform at the ray's time), object -> generated unchanged."""
    if frame < 0 or SP.frame_steps[frame] < 2:
        return frame
    m, o = transform_at1(SP.frame_motion, SP.frame_steps[frame], frame, time)
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    c00, c01, c02 = m11 * m22 - m12 * m21, m12 * m20 - m10 * m22, m10 * m21 - m11 * m20
    c10, c11, c12 = m02 * m21 - m01 * m22, m00 * m22 - m02 * m20, m01 * m20 - m00 * m21
    c20, c21, c22 = m01 * m12 - m02 * m11, m02 * m10 - m00 * m12, m00 * m11 - m01 * m10
    det = m00 * c00 + m01 * c01 + m02 * c02
    if abs(det) < 1e-300:
        return frame
    inv = 1.0 / det  # M^-1 = adjugate / det, the adjugate the cofactors transposed
    a = ((c00 * inv, c10 * inv, c20 * inv), (c01 * inv, c11 * inv, c21 * inv), (c02 * inv, c12 * inv, c22 * inv))
    f = SP.frames[frame]
    p = SP.frame_placed[frame]
    for r in range(3):
        # row r of (frame o placed): 3 linear coefficients and an offset
        l0 = f[0, r, 0] * p[0, 0] + f[0, r, 1] * p[1, 0] + f[0, r, 2] * p[2, 0]
        l1 = f[0, r, 0] * p[0, 1] + f[0, r, 1] * p[1, 1] + f[0, r, 2] * p[2, 1]
        l2 = f[0, r, 0] * p[0, 2] + f[0, r, 1] * p[1, 2] + f[0, r, 2] * p[2, 2]
        lo = f[0, r, 0] * p[0, 3] + f[0, r, 1] * p[1, 3] + f[0, r, 2] * p[2, 3] + f[0, r, 3]
        # times M^-1 (x - o)
        for c in range(3):
            SS.frame[0, r, c] = l0 * a[0][c] + l1 * a[1][c] + l2 * a[2][c]
        SS.frame[0, r, 3] = lo - (SS.frame[0, r, 0] * o[0] + SS.frame[0, r, 1] * o[1] + SS.frame[0, r, 2] * o[2])
        for c in range(4):
            SS.frame[1, r, c] = f[1, r, c]
    return -1


@stage_kernel
def shade_surface_program(SP, SS, SN, material, prim, frame, hu, hv, px, py, pz, ns, ng, wi, backfacing):
    """Run material `material`'s program at a hit (triangle prim, its row `frame` in SP.frames --
    its mesh's SP.tri_mesh[prim] or its instance's (accel.mesh_frames) --, barycentrics hu, hv, point p,
    shading normal ns and geometric normal ng on the viewer's side, wi towards the viewer) and
    write the material's nodes with this hit's inputs into SS.nodes (its material 0). Returns the
    closures' normal and tangent ((0, 0, 0): none)."""
    k = SP.mat_program[material]
    _run_at_hit(SP, SS, k, prim, frame, hu, hv, px, py, pz, ns, ng, wi, backfacing)
    regs = SS.regs
    # the material's rows, then this hit's values
    D = SS.nodes
    start, count = SN.node_start[material], SN.node_count[material]
    for j in range(count):
        _copy_row(SN, start + j, D, j)
    D.node_start[0] = 0
    D.node_count[0] = count
    b0, nb = SP.prog_bind[k, 0], SP.prog_bind[k, 1]
    for j in range(b0, b0 + nb):
        row, code, reg = SP.bind[j, 0], SP.bind[j, 1], SP.bind[j, 2]
        if code < 17:
            _set_float(D, row, code, _finite(regs[reg]))
        else:
            _set_rgb(D, row, code, _finite(regs[reg]), _finite(regs[reg + 1]), _finite(regs[reg + 2]))
    tangent = (0.0, 0.0, 0.0)
    r = SP.prog_tangent[k]
    if r >= 0:
        tangent = (_finite(regs[r]), _finite(regs[r + 1]), _finite(regs[r + 2]))
    normal = ns
    r = SP.prog_normal[k]
    if r >= 0:
        x, y, z = regs[r], regs[r + 1], regs[r + 2]
        length = np.sqrt(x * x + y * y + z * z)
        if length > 0.0 and length < np.inf:  # safe_normalize of the Normal input (svm/closure.h)
            normal = (x / length, y / length, z / length)
    return normal, tangent


@stage_kernel
def program_shading_normal(SP, SS, material, ns):
    """The shading normal after material's program ran (shade_surface_program, same scratch): the
    one it sets (SurfaceProgram.shading_normal), else ns."""
    r = SP.prog_shading_normal[SP.mat_program[material]]
    if r < 0:
        return ns
    x, y, z = SS.regs[r], SS.regs[r + 1], SS.regs[r + 2]
    length = np.sqrt(x * x + y * y + z * z)
    if length > 0.0 and length < np.inf:
        return (x / length, y / length, z / length)
    return ns


@stage_kernel
def has_program_emission(SP, material):
    """Whether material's emission comes from its program (program_emission)."""
    return SP.any and SP.mat_program[material] >= 0 and SP.prog_emission[SP.mat_program[material]] >= 0


@stage_kernel
def program_emission(SP, SS, material, prim, frame, hu, hv, px, py, pz, ns, ng, wi, backfacing):
    """The emitted radiance of material `material` at a point of triangle prim (arguments as
    shade_surface_program); negative or non-finite channels read as 0 (Cycles' emission
    closure keeps the weight as given; a negative emitter would break light sampling here)."""
    k = SP.mat_program[material]
    _run_at_hit(SP, SS, k, prim, frame, hu, hv, px, py, pz, ns, ng, wi, backfacing)
    r = SP.prog_emission[k]
    regs = SS.regs
    return (max(_finite(regs[r]), 0.0), max(_finite(regs[r + 1]), 0.0), max(_finite(regs[r + 2]), 0.0))
