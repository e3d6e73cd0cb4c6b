"""Cycles as the oracle for texture nodes: each variant is a node set on its own unit plane, seen by
an orthographic camera so that every pixel is one shader evaluation; the values travel out through
AOV Output nodes (no closure, no film weighting: the AOV pass holds the value itself at 1 spp).

Coordinates are exact: the material floors its Generated coordinate to the pixel's cell (i, j) in
its B x B block (pixel centres sit half a cell from any boundary, so the Box filter's jitter cannot
change them) and builds the texture input with float32 Math nodes,
    vector = (i sx + ox, j sy + oy, (i + j) sz + oz),  W = (i - j) sw + ow,
which numpy reproduces bit for bit (point_inputs). A third AOV carries (i, j, variant + 1) so the
read-back needs no assumption about the image's orientation.
"""
from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

BLOCK = 16
VALUE_AOVS = ("v0", "v1", "v2")
COLOR_AOVS = ("c0", "c1")
INDEX_AOV = "ij"


@dataclass
class Variant:
    """build(nodes, links, vector_socket, w_socket) -> {aov name: output socket}; value AOVs are
    named 'v*', colour AOVs 'c*'. params["setup"](obj), if given, runs on the variant's plane
    object before the render (e.g. to change its texture space)."""
    name: str
    build: Callable
    scale: tuple = (0.25, 0.25, 0.125, 0.1875)
    offset: tuple = (0.1, 0.2, 0.3, 0.4)
    params: dict = field(default_factory=dict)


def point_inputs(variant: Variant, i: np.ndarray, j: np.ndarray):
    """(x, y, z, w) float32 arrays exactly as the material computes them (one rounding per node)."""
    f = np.float32
    i, j = i.astype(f), j.astype(f)
    sx, sy, sz, sw = (f(v) for v in variant.scale)
    ox, oy, oz, ow = (f(v) for v in variant.offset)

    def add(a, b):
        # Cycles folds "x + 0" to x (MathNode::constant_fold), keeping -0.0 that an addition loses
        return a if b == 0 else (a + b).astype(f)

    x = add((i * sx).astype(f), ox)
    y = add((j * sy).astype(f), oy)
    z = add(((i + j).astype(f) * sz).astype(f), oz)
    w = add(((i - j).astype(f) * sw).astype(f), ow)
    return x.astype(f), y.astype(f), z.astype(f), w.astype(f)


def set_input(node, identifier, value):
    """Set an input's default value by identifier (Blender 5.0 hides unavailable sockets from
    lookups by name)."""
    for socket in node.inputs:
        if socket.identifier == identifier:
            socket.default_value = value
            return
    raise KeyError(f"{node.bl_idname} has no input {identifier}")


def link_input(links, node, identifier, source):
    """Link source to an input by identifier (also to inputs unavailable in the node's mode)."""
    for socket in node.inputs:
        if socket.identifier == identifier:
            links.new(source, socket)
            return
    raise KeyError(f"{node.bl_idname} has no input {identifier}")


def _math(nodes, links, operation, a, b):
    node = nodes.new("ShaderNodeMath")
    node.operation = operation
    for k, value in enumerate((a, b)):
        if isinstance(value, (int, float)):
            node.inputs[k].default_value = float(value)
        else:
            links.new(value, node.inputs[k])
    return node.outputs[0]


def _material(bpy, variant: Variant, index: int):
    mat = bpy.data.materials.new(f"oracle_{index}")
    if not mat.node_tree:
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    emit = nodes.new("ShaderNodeEmission")
    emit.inputs["Color"].default_value = (0, 0, 0, 1)
    links.new(emit.outputs[0], out.inputs["Surface"])
    texco = nodes.new("ShaderNodeTexCoord")
    sep = nodes.new("ShaderNodeSeparateXYZ")
    links.new(texco.outputs["Generated"], sep.inputs[0])
    i = _math(nodes, links, "FLOOR", _math(nodes, links, "MULTIPLY", sep.outputs[0], BLOCK), 0.0)
    j = _math(nodes, links, "FLOOR", _math(nodes, links, "MULTIPLY", sep.outputs[1], BLOCK), 0.0)
    sx, sy, sz, sw = variant.scale
    ox, oy, oz, ow = variant.offset
    x = _math(nodes, links, "ADD", _math(nodes, links, "MULTIPLY", i, sx), ox)
    y = _math(nodes, links, "ADD", _math(nodes, links, "MULTIPLY", j, sy), oy)
    z = _math(nodes, links, "ADD", _math(nodes, links, "MULTIPLY", _math(nodes, links, "ADD", i, j), sz), oz)
    w = _math(nodes, links, "ADD", _math(nodes, links, "MULTIPLY", _math(nodes, links, "SUBTRACT", i, j), sw), ow)
    comb = nodes.new("ShaderNodeCombineXYZ")
    for k, s in enumerate((x, y, z)):
        links.new(s, comb.inputs[k])
    index_vec = nodes.new("ShaderNodeCombineXYZ")
    links.new(i, index_vec.inputs[0])
    links.new(j, index_vec.inputs[1])
    index_vec.inputs[2].default_value = float(index + 1)  # 0: background
    aov = nodes.new("ShaderNodeOutputAOV")
    aov.aov_name = INDEX_AOV
    links.new(index_vec.outputs[0], aov.inputs["Color"])
    for name, socket in variant.build(nodes, links, comb.outputs[0], w).items():
        aov = nodes.new("ShaderNodeOutputAOV")
        aov.aov_name = name
        links.new(socket, aov.inputs["Color" if name.startswith("c") else "Value"])
    return mat


def render_variants(variants: list, value_aovs=VALUE_AOVS, color_aovs=COLOR_AOVS) -> list:
    """Render every variant's plane once with Cycles; returns per variant a dict with 'i', 'j'
    (int arrays), 'pixel_world' ((n, 3) world position of each pixel's centre, from the camera)
    and each AOV it wrote ('v*': (n,), 'c*': (n, 3)), float32 as Cycles stored them. The plane
    objects stay in bpy.data (named oracle_<index>) until the next render."""
    import bpy
    import OpenImageIO as oiio

    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    columns = min(len(variants), 8)
    rows = (len(variants) + columns - 1) // columns
    for index, variant in enumerate(variants):
        mesh = bpy.data.meshes.new(f"oracle_{index}")
        mesh.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [], [(0, 1, 2, 3)])
        obj = bpy.data.objects.new(f"oracle_{index}", mesh)
        obj.location = (index % columns, -(index // columns), 0.0)
        mesh.materials.append(_material(bpy, variant, index))
        scene.collection.objects.link(obj)
        if "setup" in variant.params:
            variant.params["setup"](obj)
    cam_data = bpy.data.cameras.new("oracle_camera")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = float(max(columns, rows))
    cam = bpy.data.objects.new("oracle_camera", cam_data)
    cam.location = (columns / 2.0, 1.0 - rows / 2.0, 5.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.world = None
    render = scene.render
    render.engine = "CYCLES"
    render.resolution_x, render.resolution_y = columns * BLOCK, rows * BLOCK
    render.resolution_percentage = 100
    render.use_compositing = False  # the file holds the render passes, AOVs included
    render.use_sequencer = False
    render.threads_mode = "FIXED"
    render.threads = 2
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = 1
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.pixel_filter_type = "BOX"
    cycles.filter_width = 0.01
    cycles.seed = 0
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    layer = scene.view_layers[0]
    for name in value_aovs:
        aov = layer.aovs.add()
        aov.name, aov.type = name, "VALUE"
    for name in tuple(color_aovs) + (INDEX_AOV,):
        aov = layer.aovs.add()
        aov.name, aov.type = name, "COLOR"
    settings = render.image_settings
    settings.media_type = "MULTI_LAYER_IMAGE"  # Blender 5.0: multilayer EXR is a media type
    settings.color_depth = "32"
    settings.exr_codec = "NONE"
    with tempfile.TemporaryDirectory(prefix="volpath_oracle_") as folder:
        path = Path(folder) / "oracle.exr"
        render.filepath = str(path)
        result = bpy.ops.render.render(write_still=True)
        if "FINISHED" not in result or not path.exists():
            raise RuntimeError(f"Cycles oracle render failed ({result})")
        # Blender 5.0 writes one EXR part (OIIO subimage) per pass
        planes = {}
        subimages = oiio.ImageInput.open(str(path))
        count = 0
        while subimages.seek_subimage(count, 0):
            count += 1
        subimages.close()
        for sub in range(count):
            image = oiio.ImageBuf(str(path), sub, 0)
            names = list(image.spec().channelnames)
            pixels = image.get_pixels(oiio.FLOAT).reshape(render.resolution_y, render.resolution_x, len(names))
            for k, name in enumerate(names):
                planes[name] = pixels[..., k].copy()

    def channel(aov, suffix):
        for name, plane in planes.items():
            if name.endswith(f".{aov}.{suffix}"):
                return plane
        raise KeyError(f"{aov}.{suffix} not in {list(planes)}")

    index_rgb = np.stack([channel(INDEX_AOV, c) for c in "RGB"], axis=-1).reshape(-1, 3)
    values = {name: channel(name, "X").reshape(-1) for name in value_aovs}
    colors = {name: np.stack([channel(name, c) for c in "RGB"], axis=-1).reshape(-1, 3) for name in color_aovs}
    # pixel centres in world space: the camera sees columns x rows unit cells, BLOCK pixels each
    # (ortho_scale spans the larger dimension), image row 0 at the top
    rows_px, cols_px = np.mgrid[0:render.resolution_y, 0:render.resolution_x]
    pixel_world = np.column_stack([(cols_px.reshape(-1) + 0.5) / BLOCK,
                                   1.0 - (rows_px.reshape(-1) + 0.5) / BLOCK,
                                   np.zeros(rows_px.size)])
    results = []
    for index, variant in enumerate(variants):
        mask = index_rgb[:, 2] == index + 1
        entry = {"i": index_rgb[mask, 0].astype(np.int64), "j": index_rgb[mask, 1].astype(np.int64),
                 "pixel_world": pixel_world[mask]}
        entry.update({name: v[mask] for name, v in values.items()})
        entry.update({name: c[mask] for name, c in colors.items()})
        if mask.sum() != BLOCK * BLOCK:
            raise RuntimeError(f"variant {variant.name}: {mask.sum()} pixels, expected {BLOCK * BLOCK}")
        results.append(entry)
    return results
