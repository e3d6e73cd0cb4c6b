"""Mantaflow gas domains -> grid media (addon/export/fluid.py): placement, attribute mapping, sources.

- Hand-built domains: a stand-in domain object (the settings the exporter reads, texture space
  S != 1 and L != 0, noise upres x2) with OpenVDB cache files written here, or RNA arrays in
  Blender's x-fastest layout: values, voxel positions and the getters' conversions, both sources.
- The baked domains of tests/addon_volume/data (Blender 3.4): the cache files read by VolPath give
  exactly the arrays Blender's fluid runtime hands over (the bpy wheel's runtime, repaired by
  tests/fluid_runtime.py), adaptive domain included.
- Against Cycles: Cycles 5.0 rendering the off-centre-texture-space domain and rendering a Volume
  object built from VolPath's exported grid and transform must give the same image; the grid
  placed at the intended cell centres (S / N instead of Cycles' 1 / N) must not.
- The bpy wheel as shipped (no repair, a subprocess): the plume renders from the cache files and
  says so; bad input warns and renders nothing, never an exception.
"""
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

import fluid_runtime  # noqa: E402  (tests/)
from addon import export_volume_grids as evg  # noqa: E402
from addon.export import fluid  # noqa: E402
from addon.export.grid_media import grid_medium_from_volume  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
FRAME = 5
BASE = (6, 5, 4)          # hand-built domain resolution
NOISE = 2                 # noise upres
LOCATION = np.array([0.5, -0.25, 1.0])   # texture space (evaluated mesh bounds centre ...)
SIZE = np.array([2.0, 1.5, 0.75])        # ... and half size: S != 1


@pytest.fixture(scope="module")
def openvdb():
    return evg.import_openvdb()


@pytest.fixture()
def free_blend():
    yield
    fluid_runtime.free_blend_data()


def principled_material(name="Fire", color_attribute="color", blackbody=1.0, flame_emission=True):
    material = bpy.data.materials.new(name)
    if material.node_tree is None:
        material.use_nodes = True
    tree = material.node_tree
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    node = tree.nodes.new("ShaderNodeVolumePrincipled")
    node.inputs["Density"].default_value = 5.0
    node.inputs["Color Attribute"].default_value = color_attribute
    node.inputs["Blackbody Intensity"].default_value = blackbody
    tree.links.new(node.outputs["Volume"], output.inputs["Volume"])
    if flame_emission:
        attribute = tree.nodes.new("ShaderNodeAttribute")
        attribute.attribute_name = "flame"
        tree.links.new(attribute.outputs["Fac"], node.inputs["Emission Strength"])
    return material


class RnaArray(np.ndarray):
    """A flat float array with bpy_prop_array's foreach_get."""

    def foreach_get(self, out):
        out[:] = self


def rna(grid, channels=1):
    """A [i, j, k(, c)] array flattened as Blender's fluid arrays are: x fastest."""
    axes = (2, 1, 0, 3) if channels > 1 else (2, 1, 0)
    return np.ascontiguousarray(np.transpose(grid, axes)).ravel().astype(np.float32).view(RnaArray)


def hand_built_domain(cache, material, **overrides):
    settings = SimpleNamespace(
        domain_type="GAS", domain_resolution=BASE, use_noise=True, noise_scale=NOISE,
        cache_directory=str(cache), cache_data_format="OPENVDB", cache_type="ALL", cache_frame_offset=0,
        cache_frame_start=1, cache_frame_end=10, clipping=1e-6, flame_ignition=1.25, flame_max_temp=2.75,
        fluid_group=None)
    vars(settings).update(overrides)
    modifier = SimpleNamespace(type="FLUID", fluid_type="DOMAIN", domain_settings=settings, show_render=True)
    mesh = SimpleNamespace(texspace_location=tuple(LOCATION), texspace_size=tuple(SIZE))
    return SimpleNamespace(name="Hand Domain", type="MESH", modifiers=[modifier], data=mesh,
                           active_material=material, particle_systems=[])


def hand_built_grids(seed=3):
    """Mantaflow's grids of one frame: noise-resolution density/flame/colours, base-resolution heat."""
    rng = np.random.default_rng(seed)
    high = tuple(n * NOISE for n in BASE)
    density = rng.uniform(0.2, 1.0, high).astype(np.float32)
    density[0], density[:, -1] = 0.0, 0.0           # an empty border: the active box is smaller
    density[2, 3, 4] = 5e-7                          # below the domain's clipping: background
    flame = np.where(rng.uniform(size=high) < 0.5, rng.uniform(0.0, 1.0, high), 0.0).astype(np.float32)
    flame[density == 0] = 0.0
    colors = {c: (density * v).astype(np.float32) for c, v in zip("rgb", (0.9, 0.5, 0.1))}
    heat = rng.uniform(-2.0, 2.0, BASE).astype(np.float32)
    return {"density": density, "flame": flame, "heat": heat, **colors}


def write_cache(openvdb, cache, grids, frame=FRAME, resolution_metadata=True):
    (cache / "data").mkdir(parents=True, exist_ok=True)
    (cache / "noise").mkdir(parents=True, exist_ok=True)

    def grid(name, array):
        g = openvdb.FloatGrid()
        g.name = name
        g.copyFromArray(array)
        if resolution_metadata:
            g["file_base_resolution"] = tuple(int(n) for n in array.shape)
        return g

    low = {k: np.zeros(BASE, np.float32) for k in ("density", "flame")}
    openvdb.write(str(cache / "data" / f"fluid_data_{frame:04d}.vdb"),
                  grids=[grid("density", low["density"] + 0.5), grid("flame", low["flame"]),
                         grid("temperature", grids["heat"])]
                  + [grid(f"color_{c}", low["density"]) for c in "rgb"])
    openvdb.write(str(cache / "noise" / f"fluid_noise_{frame:04d}.vdb"),
                  grids=[grid("density_noise", grids["density"]), grid("flame_noise", grids["flame"])]
                  + [grid(f"color_{c}_noise", grids[c]) for c in "rgb"])


def cycles_position(index, resolution):
    """Object-space position of grid value `index` in Cycles 5.0 (cycles-volumes-from-blender.md 1.3)."""
    n = np.asarray(resolution, float)
    return (LOCATION - SIZE) + 2.0 * SIZE * np.asarray(index, float) / n + 1.0 / n


OBJECT_TO_WORLD = np.array([[0.0, -2.0, 0.0, 1.0], [1.5, 0.0, 0.0, -2.0], [0.0, 0.0, 0.5, 3.0], [0, 0, 0, 1.0]])


# ---------------------------------------------------------------------------------------------
# Hand-built domains
# ---------------------------------------------------------------------------------------------
def test_index_to_object_is_cycles_5_placement():
    layout = fluid.DomainLayout(BASE, NOISE, LOCATION, SIZE)
    assert layout.resolution("density") == (12, 10, 8) and layout.resolution("heat") == BASE
    for name in ("density", "heat"):
        n = layout.resolution(name)
        matrix = layout.index_to_object(n)
        for index in ((0, 0, 0), (3, 1, 2), tuple(v - 1 for v in n)):
            np.testing.assert_allclose((matrix @ np.append(index, 1.0))[:3], cycles_position(index, n), atol=1e-12)
    # With S = 1 the value sits at its cell centre; with S != 1 Cycles 5.0 is off by (1 - S) / N.
    unit = fluid.DomainLayout(BASE, 1, (0, 0, 0), (1, 1, 1)).index_to_object(BASE)
    np.testing.assert_allclose(unit[:3, 3], -1.0 + 1.0 / np.array(BASE))


@pytest.mark.parametrize("source", ["cache", "runtime"])
def test_hand_built_domain_grids_placement_and_conversions(openvdb, tmp_path, source, free_blend):
    grids = hand_built_grids()
    cache = tmp_path / "cache"
    write_cache(openvdb, cache, grids)
    material = principled_material()
    obj = hand_built_domain(cache, material)
    settings = obj.modifiers[0].domain_settings
    high = tuple(n * NOISE for n in BASE)
    # The fluid runtime's arrays (rna_fluid.cc getters) for the same frame:
    temperature = np.where(grids["flame"] > 0.01, 1.25 + grids["flame"] * 1.5, 0.0)
    rgba = np.stack([grids[c] * grids["density"] for c in "rgb"] + [grids["density"]], axis=-1)
    settings.density_grid, settings.flame_grid = rna(grids["density"]), rna(grids["flame"])
    settings.temperature_grid, settings.color_grid = rna(temperature), rna(rgba, 4)
    settings.heat_grid = rna(grids["heat"] * 0.5)

    warnings, log = [], []
    exported = fluid.export_domain(obj, OBJECT_TO_WORLD, FRAME, warnings, log.append, sources=(source,))
    assert exported is not None and not warnings, warnings
    assert ("cache files" in log[0]) == (source == "cache") and "Hand Domain" in log[0]
    assert set(exported.grids) == {"density", "color", "flame", "temperature"}  # what the material reads
    density = exported.grids["density"]
    active = np.argwhere(grids["density"] > 1e-6)
    lo, hi = active.min(axis=0), active.max(axis=0)
    assert density.index_origin == tuple(lo) and density.data.shape == tuple(hi - lo + 1)
    for index in ((1, 0, 0), (5, 7, 3), (11, 8, 7), (2, 3, 4)):
        value = density.data[tuple(np.subtract(index, lo))]
        expected = grids["density"][index] if grids["density"][index] > 1e-6 else 0.0  # clipping
        assert value == pytest.approx(expected, abs=1e-7)
        world = density.index_to_world @ np.append(np.subtract(index, lo), 1.0)
        np.testing.assert_allclose(world, OBJECT_TO_WORLD @ np.append(cycles_position(index, high), 1.0), atol=1e-9)
    crop = tuple(slice(a, b + 1) for a, b in zip(lo, hi))
    np.testing.assert_allclose(exported.grids["temperature"].data, temperature[crop], rtol=1e-6)
    np.testing.assert_allclose(exported.grids["flame"].data, grids["flame"][crop], rtol=1e-6)
    # Colour: Cycles divides the premultiplied RGB by alpha (the density) per lookup.
    color = exported.grids["color"].data
    inside = grids["density"][crop] > 1e-6
    np.testing.assert_allclose(color[inside], np.stack([grids[c][crop] for c in "rgb"], -1)[inside], rtol=1e-5)
    for grid in exported.grids.values():
        np.testing.assert_allclose(grid.index_to_world, density.index_to_world)
    assert exported.density_factor == 1.0  # smoke domains are not object-space volumes

    # Heat stays at the base resolution, x 0.5 (rna_FluidModifier_heat_grid_get).
    layout = fluid.DomainLayout.of(obj, settings)
    read = fluid._cache_grids if source == "cache" else fluid._runtime_grids
    heat = read(settings, layout, ["heat"], FRAME, obj)["heat"]
    np.testing.assert_allclose(heat, grids["heat"] * 0.5, rtol=1e-6)

    medium = grid_medium_from_volume(exported, warnings)
    assert medium is not None and medium.emission_grid is not None and medium.scatter_grid is not None, warnings
    point = (density.index_to_world @ np.append(np.subtract((5, 7, 3), lo), 1.0))[:3]
    assert medium.density_at(point[None])[0] == pytest.approx(grids["density"][5, 7, 3], rel=1e-5)


def test_hand_built_domain_non_finite_voxels_are_named_and_zero(openvdb, tmp_path, free_blend):
    grids = hand_built_grids()
    write_cache(openvdb, tmp_path, grids)
    obj = hand_built_domain(tmp_path, principled_material(color_attribute="", blackbody=0.0, flame_emission=False))
    settings = obj.modifiers[0].domain_settings
    density = grids["density"].copy()
    density[4, 4, 4], density[5, 5, 5] = np.nan, np.inf
    settings.density_grid = rna(density)
    warnings = []
    exported = fluid.export_domain(obj, np.eye(4), FRAME, warnings, lambda _: None, sources=("runtime",))
    assert any("Hand Domain" in w and "frame 5" in w and "'density'" in w and "2 non-finite" in w
               for w in warnings), warnings
    grid = exported.grids["density"]
    assert np.all(np.isfinite(grid.data))
    assert grid.data[tuple(np.subtract((4, 4, 4), grid.index_origin))] == 0.0


def test_volume_object_nan_voxels_are_named(openvdb, tmp_path, free_blend):
    """OpenVDB files from elsewhere may hold NaN voxels: named in the warning, 0 as in Cycles."""
    grid = openvdb.FloatGrid()
    grid.name = "density"
    grid.copyFromArray(np.ones((4, 4, 4), np.float32))
    accessor = grid.getAccessor()
    accessor.setValueOn((1, 2, 3), float("nan"))
    del accessor
    path = tmp_path / "nan.vdb"
    openvdb.write(str(path), grids=[grid])
    volume = bpy.data.volumes.new("NanCloud")
    volume.filepath = str(path)
    obj = bpy.data.objects.new("NanCloud", volume)
    bpy.context.scene.collection.objects.link(obj)
    warnings = []
    exported = evg.export_volume_object(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()), warnings)
    assert any("NanCloud" in w and "'density'" in w and "1 non-finite" in w for w in warnings), warnings
    data = exported.grids["density"].data
    assert np.all(np.isfinite(data)) and data[1, 2, 3] == 0.0


def test_hand_built_domain_bad_caches_warn_and_render_nothing(openvdb, tmp_path, free_blend):
    material = principled_material(color_attribute="", blackbody=0.0, flame_emission=False)
    grids = hand_built_grids()

    def export(cache, frame=FRAME, **overrides):
        warnings = []
        result = fluid.export_domain(hand_built_domain(cache, material, **overrides), np.eye(4), frame, warnings,
                                     lambda _: None, sources=("cache",))
        assert result is None and len(warnings) == 1, warnings
        assert "Hand Domain" in warnings[0] and f"frame {frame}" in warnings[0]
        return warnings[0]

    assert "does not exist" in export(tmp_path / "never_baked")
    write_cache(openvdb, tmp_path / "ok", grids)
    assert "no data cache file" in export(tmp_path / "ok", frame=6)
    assert "outside the cache range 1-10" in export(tmp_path / "ok", frame=11)
    assert "cannot be read" in export(tmp_path / "ok", cache_data_format="UNI")
    # A cache baked at another resolution (an adaptive domain's other frame, another bake):
    assert "voxels, the domain" in export(tmp_path / "ok", domain_resolution=(6, 5, 5))
    corrupt = tmp_path / "corrupt"
    write_cache(openvdb, corrupt, grids)
    data = corrupt / "data" / f"fluid_data_{FRAME:04d}.vdb"
    data.write_bytes(data.read_bytes()[:len(data.read_bytes()) // 2])  # the grid list intact, the voxels cut
    assert "cannot be read" in export(corrupt)
    # Cache type All/Modular load frame - offset (fluid.cc): frame 7 with offset 2 reads file 5.
    warnings = []
    ok = fluid.export_domain(hand_built_domain(tmp_path / "ok", material, cache_frame_offset=2), np.eye(4), 7,
                             warnings, lambda _: None, sources=("cache",))
    assert ok is not None and not warnings, warnings


# ---------------------------------------------------------------------------------------------
# Baked domains (Blender 3.4): the cache files give exactly what Blender's fluid runtime gives
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    fluid_runtime.restore_mantaflow_bases()  # the runtime as in a working Blender
    return fluid_runtime.copy_data(tmp_path_factory.mktemp("fluid") / "data")


@pytest.mark.parametrize("name,frame", [("smoke", 29), ("fire", 30), ("adaptive", 12), ("texspace", 10)])
def test_baked_domain_cache_files_equal_the_fluid_runtime(baked, name, frame, monkeypatch, free_blend):
    monkeypatch.chdir(baked)  # Mantaflow writes its noise tile into the working directory
    scene, domain = fluid_runtime.open_domain(baked, name, frame)
    evaluated = domain.evaluated_get(bpy.context.evaluated_depsgraph_get())
    settings = fluid.domain_modifier(evaluated).domain_settings
    matrix = np.array(evaluated.matrix_world)
    by_source = {}
    for source in ("runtime", "cache"):
        warnings = []
        by_source[source] = fluid.export_domain(evaluated, matrix, frame, warnings, lambda _: None, sources=(source,))
        assert by_source[source] is not None and not warnings, warnings
    runtime, cache = by_source["runtime"].grids, by_source["cache"].grids
    assert set(runtime) == set(cache) == ({"density", "temperature"} if name == "fire" else {"density"})
    for key in runtime:
        np.testing.assert_array_equal(runtime[key].data, cache[key].data)
        np.testing.assert_allclose(runtime[key].index_to_world, cache[key].index_to_world)
    # Placement from the *evaluated* mesh's texture space and resolution (an adaptive domain's box):
    location, size = np.array(evaluated.data.texspace_location), np.array(evaluated.data.texspace_size)
    n = np.array(settings.domain_resolution) * (settings.noise_scale if settings.use_noise else 1)
    density = runtime["density"]
    first = np.array(density.index_origin)
    expected = matrix @ np.append((location - size) + 2 * size * first / n + 1.0 / n, 1.0)
    np.testing.assert_allclose(density.index_to_world[:, 3], expected, atol=1e-6)
    if name == "adaptive":  # the frame's box is smaller than the domain's, in z
        assert tuple(settings.domain_resolution) == (16, 16, 17) and size[2] < 0.75 and location[2] < -0.2
    if name == "texspace":
        np.testing.assert_allclose(location, [0.5, 0.0, 1.0], atol=1e-6)
        np.testing.assert_allclose(size, [2.0, 2.0, 3.0], atol=1e-6)
    if name == "fire":
        assert n.tolist() == [32, 32, 48]  # noise upres x2


def test_unbaked_domain_warns_and_draws_no_box(baked, tmp_path, monkeypatch, free_blend):
    """A domain whose cache folder does not exist (never baked), with a working fluid runtime (in
    the wheel as shipped, freeing such a domain makes Mantaflow abort: not testable there)."""
    from addon.export import export_scene
    from volpath_native.grid_medium import GridMedium

    monkeypatch.chdir(tmp_path)
    (tmp_path / "alone").mkdir()
    blend = tmp_path / "alone" / "smoke.blend"
    blend.write_bytes((baked / "smoke.blend").read_bytes())
    scene, _ = fluid_runtime.open_domain(tmp_path / "alone", "smoke", 29)
    native, warnings = export_scene(bpy.context.evaluated_depsgraph_get())
    assert not [m for m in native.media if isinstance(m, GridMedium)]
    assert [m.name for m in native.meshes] == ["Floor"]  # no box of smoke
    assert any("'Smoke Domain' (frame 29)" in w and "does not exist (not baked?)" in w for w in warnings), warnings


def test_domain_placement_matches_cycles_5(baked, monkeypatch, free_blend):
    """Cycles renders the S != 1 domain itself, and a Volume object carrying VolPath's exported
    density grid and index->world transform: the images agree to the noise (RMSE against a second
    seed of the domain); the grid at the intended cell centres (offset S/N, not 1/N) does not."""
    from addon.compare import cycles_engine
    from volpath_native import imageio

    openvdb = evg.import_openvdb()
    monkeypatch.chdir(baked)
    scene, domain = fluid_runtime.open_domain(baked, "texspace", 10)
    evaluated = domain.evaluated_get(bpy.context.evaluated_depsgraph_get())
    warnings = []
    exported = fluid.export_domain(evaluated, np.array(evaluated.matrix_world), 10, warnings, lambda _: None)
    density = exported.grids["density"]
    for obj in scene.objects:  # an absorbing silhouette against a white sky, seen along -y
        obj.hide_render = obj.type == "LIGHT" or obj.name == "Floor"
    background = scene.world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value, background.inputs["Strength"].default_value = (1, 1, 1, 1), 1.0
    camera = scene.camera
    camera.data.type, camera.data.ortho_scale = "ORTHO", 4.5
    camera.location, camera.rotation_euler = (0.0, -10.0, 1.0), (np.pi / 2, 0.0, 0.0)

    layout = fluid.DomainLayout.of(evaluated, fluid.domain_modifier(evaluated).domain_settings)
    n = np.array(layout.resolution("density"), float)
    centred = density.index_to_world.copy()  # the same grid moved to the intended cell centres
    centred[:3, 3] += np.array(evaluated.matrix_world)[:3, :3] @ ((layout.texspace_size - 1.0) / n)
    volumes = {}
    for label, index_to_world in (("volpath", density.index_to_world), ("centred", centred)):
        grid = openvdb.FloatGrid()
        grid.name = "density"
        grid.copyFromArray(density.data, tolerance=1e-6)
        index_to_object = np.linalg.inv(np.array(evaluated.matrix_world)) @ index_to_world
        grid.transform = openvdb.createLinearTransform(index_to_object.T.tolist())
        path = baked / f"placement_{label}.vdb"
        openvdb.write(str(path), grids=[grid])
        data = bpy.data.volumes.new(label)
        data.filepath = str(path)
        data.render.space, data.render.clipping = "WORLD", 1e-6  # as a smoke domain: no density scaling
        data.materials.append(domain.active_material)
        volumes[label] = bpy.data.objects.new(label, data)
        scene.collection.objects.link(volumes[label])
        volumes[label].matrix_world = domain.matrix_world.copy()
        volumes[label].hide_render = True

    def render(visible, seed):
        for obj in [domain] + list(volumes.values()):
            obj.hide_render = obj is not visible
        return cycles_engine.render_once(scene, samples=128, seed=seed).image[..., :3]

    with cycles_engine.matched_settings(scene, cycles_engine.BounceLimits(), (48, 48)):
        reference = render(domain, 1)
        images = {"noise": render(domain, 2), "volpath": render(volumes["volpath"], 2),
                  "centred": render(volumes["centred"], 2)}
    rmse = {k: float(np.sqrt(np.mean((v - reference) ** 2))) for k, v in images.items()}
    print("placement RMSE against Cycles' own render of the domain:", rmse)
    assert reference.min() < 0.3 < 0.95 < reference.max(), "the silhouette must be in view"
    assert rmse["volpath"] < 1.3 * rmse["noise"], rmse
    assert rmse["centred"] > 3.0 * rmse["noise"], rmse


# ---------------------------------------------------------------------------------------------
# The bpy wheel as shipped: its fluid runtime hands over nothing; VolPath reads the cache files
# ---------------------------------------------------------------------------------------------
_SHIPPED_SCRIPT = textwrap.dedent('''
    import json, os, shutil, sys
    import bpy, numpy as np
    import addon
    from addon.export import export_scene
    from volpath_native.grid_medium import GridMedium
    folder, out = sys.argv[1], sys.argv[2]
    addon.register()
    results = {}

    def case(label, frame, edit=None):
        bpy.ops.wm.open_mainfile(filepath=os.path.join(folder, "smoke.blend"))
        scene = bpy.context.scene
        domain = bpy.data.objects["Smoke Domain"]
        if edit:
            edit(scene, domain)
        scene.frame_set(frame)
        try:
            native, warnings = export_scene(bpy.context.evaluated_depsgraph_get())
        except Exception as error:
            results[label] = {"exception": repr(error)}
            return
        results[label] = {"warnings": warnings, "meshes": [m.name for m in native.meshes],
                          "grids": [float(m.density.max()) for m in native.media if isinstance(m, GridMedium)]}

    def settings(domain):
        return [m for m in domain.modifiers if m.type == "FLUID"][0].domain_settings

    # Only files change between cases: editing a domain's settings makes this Mantaflow abort.
    cache = os.path.join(folder, "smoke_cache")
    case("baked", 30)
    case("outside", 31)
    case("motion blur", 28, lambda s, d: setattr(s.render, "use_motion_blur", True))
    os.remove(os.path.join(cache, "data", "fluid_data_0029.vdb"))
    case("missing file", 29)
    with open(os.path.join(cache, "data", "fluid_data_0030.vdb"), "r+b") as f:
        f.truncate(300)
    case("corrupt", 30)

    # F12 at frame 28 (the last intact frame): finite pixels, the plume darker than the sky.
    bpy.ops.wm.open_mainfile(filepath=os.path.join(folder, "smoke.blend"))
    scene = bpy.context.scene
    scene.frame_set(28)
    scene.render.engine = "VOLPATH"
    scene.render.resolution_x = scene.render.resolution_y = 16
    scene.volpath.samples = 4
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = os.path.join(folder, "f12.exr")
    bpy.ops.render.render(write_still=True)
    from volpath_native import imageio
    image = imageio.read_exr(scene.render.filepath)
    results["f12"] = {"finite": bool(np.all(np.isfinite(image))), "min": float(image[..., :3].min()),
                      "max": float(image[..., :3].max())}
    bpy.ops.wm.read_homefile(use_empty=True)
    with open(out, "w") as f:
        json.dump(results, f)
''')


def test_shipped_wheel_reads_the_cache_files_and_survives_bad_input(tmp_path):
    """A fresh bpy process without the Mantaflow repair, as a user of the wheel has it."""
    folder = fluid_runtime.copy_data(tmp_path / "data")
    script = tmp_path / "shipped.py"
    script.write_text(_SHIPPED_SCRIPT)
    out = tmp_path / "results.json"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT / "native"), str(ROOT)]
                                                       + os.environ.get("PYTHONPATH", "").split(os.pathsep)))
    proc = subprocess.run([sys.executable, str(script), str(folder), str(out)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    results = json.loads(out.read_text())
    assert "'Smoke Domain' (frame 30): grids ['density'] from the OpenVDB cache files" in proc.stdout
    baked = results["baked"]
    assert baked["grids"] and baked["grids"][0] > 0.5 and not baked["warnings"], baked
    for label, phrase in (("outside", "outside the cache range 28-30"), ("missing file", "no data cache file"),
                          ("corrupt", "cannot be read")):
        result = results[label]
        assert "exception" not in result, (label, result)
        assert not result["grids"] and "Smoke Domain" not in str(result["meshes"]), (label, result)  # no box
        assert any("Smoke Domain" in w and phrase in w and "frame" in w for w in result["warnings"]), (label, result)
    blur = results["motion blur"]
    assert blur["grids"] and any("Smoke Domain" in w and "motion blur" in w for w in blur["warnings"]), blur
    f12 = results["f12"]
    assert f12["finite"] and f12["min"] < 0.7 * f12["max"], f12


def test_liquid_domains_fluid_particles_and_motion_blur_warn(openvdb, tmp_path, free_blend):
    write_cache(openvdb, tmp_path, hand_built_grids())
    gas = hand_built_domain(tmp_path, principled_material(color_attribute="", blackbody=0.0, flame_emission=False))
    gas.particle_systems = [SimpleNamespace(name="Spray", settings=SimpleNamespace(type="SPRAY"))]
    liquid = hand_built_domain(tmp_path, None)
    liquid.name = "Pool"
    liquid.modifiers[0].domain_settings.domain_type = "LIQUID"
    scene = SimpleNamespace(frame_current=FRAME, render=SimpleNamespace(use_motion_blur=True))
    instances = [SimpleNamespace(object=obj, is_instance=False, show_self=True, matrix_world=np.eye(4))
                 for obj in (gas, liquid)]
    warnings = []
    exported = fluid.export_fluid_domains(SimpleNamespace(scene=scene, object_instances=instances), warnings,
                                          lambda _: None)
    assert [e.object_name for e in exported] == ["Hand Domain"]  # the gas domain still renders
    assert any("'Pool'" in w and "liquid" in w and "not rendered" in w for w in warnings), warnings
    assert any("'Hand Domain'" in w and "'Spray'" in w and "not supported" in w for w in warnings), warnings
    assert any("'Hand Domain'" in w and "motion blur" in w for w in warnings), warnings
