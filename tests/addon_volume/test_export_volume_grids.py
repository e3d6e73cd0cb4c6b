"""Volume object export: .vdb written with openvdb -> bpy Volume object -> dense grids -> GridMedium."""
import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from addon import export_volume_grids as evg  # noqa: E402
from volpath_native.grid_medium import principled_volume_coefficients  # noqa: E402

VOXEL = 0.1
INDEX_ORIGIN = (5, -3, 2)  # where the written array starts in OpenVDB index space


@pytest.fixture(scope="module")
def openvdb():
    return evg.import_openvdb()


def procedural_density(shape=(12, 10, 8)):
    """Smooth blob with a zero border (zeros stay inactive: the active box is the non-zero part)."""
    x, y, z = np.meshgrid(*[np.linspace(-1, 1, n) for n in shape], indexing="ij")
    density = np.clip(1.0 - (x ** 2 + y ** 2 + z ** 2), 0.0, None) * (1.5 + x)
    density[0], density[-1] = 0.0, 0.0
    return density.astype(np.float32)


def write_vdb(openvdb, path, grids):
    openvdb.write(str(path), grids=grids)
    return path


def float_grid(openvdb, name, array, origin=INDEX_ORIGIN):
    grid = openvdb.FloatGrid()
    grid.name = name
    grid.copyFromArray(array, ijk=origin)
    grid.transform = openvdb.createLinearTransform(voxelSize=VOXEL)
    return grid


def volume_object(path, name="Smoke", location=(1.0, 2.0, 3.0), rotation=(0.3, 0.0, 0.5), scale=(2.0, 1.0, 1.5)):
    volume = bpy.data.volumes.new(name)
    volume.filepath = str(path)
    obj = bpy.data.objects.new(name, volume)
    bpy.context.scene.collection.objects.link(obj)
    obj.location, obj.rotation_euler, obj.scale = location, rotation, scale
    return obj


def principled_material(density=2.0, color=(0.8, 0.6, 0.4, 1.0), color_attribute=""):
    material = bpy.data.materials.new("SmokeMaterial")
    tree = material.node_tree if material.node_tree is not None else None
    if tree is None:
        material.use_nodes = True
        tree = material.node_tree
    for node in list(tree.nodes):
        tree.nodes.remove(node)
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    principled = tree.nodes.new("ShaderNodeVolumePrincipled")
    principled.inputs["Density"].default_value = density
    principled.inputs["Color"].default_value = color
    principled.inputs["Color Attribute"].default_value = color_attribute
    tree.links.new(principled.outputs["Volume"], output.inputs["Volume"])
    return material


@pytest.fixture()
def clean_scene():
    yield
    for obj in list(bpy.data.objects):
        if obj.type == "VOLUME":
            bpy.data.objects.remove(obj)
    for volume in list(bpy.data.volumes):
        bpy.data.volumes.remove(volume)


def evaluated(obj):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    return obj.evaluated_get(depsgraph), depsgraph


def test_density_grid_round_trips_with_transform(openvdb, tmp_path, clean_scene):
    density = procedural_density()
    path = write_vdb(openvdb, tmp_path / "smoke.vdb", [float_grid(openvdb, "density", density)])
    obj = volume_object(path)
    warnings = []
    exported = evg.export_volume_object(evaluated(obj)[0], warnings)
    assert exported is not None, warnings
    grid = exported.grids["density"]

    active = np.argwhere(density != 0)
    lo, hi = active.min(axis=0), active.max(axis=0)
    np.testing.assert_array_equal(grid.data, density[lo[0]:hi[0] + 1, lo[1]:hi[1] + 1, lo[2]:hi[2] + 1])
    assert grid.index_origin == tuple(int(v) for v in np.add(INDEX_ORIGIN, lo))

    matrix_world = np.array(obj.matrix_world)
    some_voxel = np.array([2, 3, 1])
    object_position = VOXEL * (some_voxel + np.add(INDEX_ORIGIN, lo))
    expected_world = matrix_world @ np.append(object_position, 1.0)
    np.testing.assert_allclose(grid.index_to_world @ np.append(some_voxel, 1.0), expected_world, atol=1e-6)
    # Cycles' object_volume_density for object-space volumes.
    expected_factor = 1.0 / np.linalg.norm(matrix_world[:3, :3] @ (np.ones(3) / math.sqrt(3)))
    assert exported.density_factor == pytest.approx(expected_factor)


def test_grid_medium_uses_principled_volume_and_object_density_factor(openvdb, tmp_path, clean_scene):
    density = procedural_density()
    path = write_vdb(openvdb, tmp_path / "smoke.vdb", [float_grid(openvdb, "density", density)])
    obj = volume_object(path)
    obj.data.materials.append(principled_material(density=2.0))
    warnings = []
    exported = evg.export_volume_object(evaluated(obj)[0], warnings)
    medium = evg.grid_medium_from_volume(exported, warnings)
    assert medium is not None and not warnings, warnings
    sigma_s, sigma_a = principled_volume_coefficients((0.8, 0.6, 0.4), 2.0, 0.0, exported.density_factor)
    np.testing.assert_allclose(medium.sigma_s, sigma_s, rtol=1e-6)
    np.testing.assert_allclose(medium.sigma_a, sigma_a, rtol=1e-6)
    grid = exported.grids["density"]
    voxel = np.array([4, 5, 3])
    world = (grid.index_to_world @ np.append(voxel, 1.0))[:3]
    assert medium.density_at(world[None])[0] == pytest.approx(grid.data[tuple(voxel)], rel=1e-5)


def test_color_grid_drives_scattering_colour(openvdb, tmp_path, clean_scene):
    density = procedural_density()
    color = np.zeros(density.shape + (3,), np.float32)
    color[density != 0] = (0.25, 0.5, 1.0)
    color_grid = openvdb.Vec3SGrid()
    color_grid.name = "color"
    color_grid.copyFromArray(color, ijk=INDEX_ORIGIN)
    color_grid.transform = openvdb.createLinearTransform(voxelSize=VOXEL)
    path = write_vdb(openvdb, tmp_path / "smoke.vdb", [float_grid(openvdb, "density", density), color_grid])
    obj = volume_object(path)
    obj.data.materials.append(principled_material(density=1.0, color=(1, 1, 1, 1), color_attribute="color"))
    warnings = []
    exported = evg.export_volume_object(evaluated(obj)[0], warnings)
    medium = evg.grid_medium_from_volume(exported, warnings)
    assert medium is not None and not warnings, warnings
    grid = exported.grids["density"]
    voxel = np.array([4, 5, 3])
    world = (grid.index_to_world @ np.append(voxel, 1.0))[:3][None]
    sigma_s, sigma_t, _ = medium.coefficients(world)
    rho = grid.data[tuple(voxel)] * exported.density_factor
    np.testing.assert_allclose(sigma_s[0], rho * np.array([0.25, 0.5, 1.0]), rtol=1e-5)
    np.testing.assert_allclose(sigma_t[0], rho, rtol=1e-5)  # C + (1 - C) = 1 without absorption


def test_missing_file_warns_and_skips(tmp_path, clean_scene):
    obj = volume_object(tmp_path / "does_not_exist.vdb")
    warnings = []
    assert evg.export_volume_object(evaluated(obj)[0], warnings) is None
    assert warnings and "not found" in warnings[0]


def test_unsupported_and_empty_grids_warn_and_are_skipped(openvdb, tmp_path, clean_scene):
    temperature = openvdb.Int32Grid()
    temperature.name = "temperature"
    temperature.copyFromArray(np.ones((3, 3, 3), np.int32))
    empty = openvdb.FloatGrid()
    empty.name = "flame"
    path = write_vdb(openvdb, tmp_path / "mixed.vdb",
                     [float_grid(openvdb, "density", procedural_density()), temperature, empty])
    obj = volume_object(path)
    warnings = []
    exported = evg.export_volume_object(evaluated(obj)[0], warnings)
    assert set(exported.grids) == {"density"}
    assert any("temperature" in w and "unsupported" in w for w in warnings), warnings
    assert any("flame" in w and "empty" in w for w in warnings), warnings


def test_volume_without_density_grid_is_skipped_by_the_medium_builder(openvdb, tmp_path, clean_scene):
    path = write_vdb(openvdb, tmp_path / "heat.vdb", [float_grid(openvdb, "flame", procedural_density())])
    obj = volume_object(path)
    warnings = []
    exported = evg.export_volume_object(evaluated(obj)[0], warnings)
    assert exported is not None and set(exported.grids) == {"flame"}
    assert evg.grid_medium_from_volume(exported, warnings) is None
    assert any("density" in w for w in warnings)


def test_depsgraph_export_finds_every_volume_object(openvdb, tmp_path, clean_scene):
    path = write_vdb(openvdb, tmp_path / "smoke.vdb", [float_grid(openvdb, "density", procedural_density())])
    volume_object(path, name="A")
    volume_object(path, name="B", location=(-3, 0, 0))
    warnings = []
    exported = evg.export_volume_objects(bpy.context.evaluated_depsgraph_get(), warnings)
    assert sorted(e.object_name for e in exported) == ["A", "B"], warnings
    a, b = sorted(exported, key=lambda e: e.object_name)
    shift = b.grids["density"].index_to_world[:3, 3] - a.grids["density"].index_to_world[:3, 3]
    np.testing.assert_allclose(shift, [-4.0, -2.0, -3.0], atol=1e-6)


# ---------------------------------------------------------------------------------------------
# Against Cycles: an absorbing smoke blob in front of a white background
# ---------------------------------------------------------------------------------------------
def render_isolated_with_cycles(scene, keep, world, camera, size, samples, seeds=(1, 2)):
    """Cycles renders (one per seed) of only the objects in `keep`, with the comparison tool's
    settings matched to VolPath (addon.compare.cycles_engine.matched_settings: CPU, no denoising or
    clamping, volume bounces 0) and one ray through each pixel centre; the scene's settings come back
    afterwards. Returns RGB float64 images, row 0 = top."""
    from addon.compare import cycles_engine

    hidden = [o for o in scene.objects if o not in keep and not o.hide_render]
    saved = (scene.world, scene.camera, scene.cycles.filter_width)
    try:
        for other in hidden:
            other.hide_render = True
        scene.world, scene.camera = world, camera
        scene.cycles.filter_width = 0.01  # one ray through each pixel centre
        with cycles_engine.matched_settings(scene, cycles_engine.BounceLimits(), resolution=(size, size)):
            return [cycles_engine.render_once(scene, samples=samples, seed=seed).image[..., :3].astype(np.float64)
                    for seed in seeds]
    finally:
        for other in hidden:
            other.hide_render = False
        scene.world, scene.camera, scene.cycles.filter_width = saved


def transmittance_and_emission(medium, origins, dirs, steps=1500):
    """Midpoint quadrature of T(L) and of the integral of emission(t) T(t) dt along each ray,
    restricted to the medium's box: (N,3), (N,3)."""
    lo, hi = medium.world_bounds()
    length = float(np.linalg.norm(hi - lo)) * 2.0 + float(np.abs(origins).max())
    dt = length / steps
    tau = np.zeros((len(origins), 3))
    emitted = np.zeros((len(origins), 3))
    for k in range(steps):
        _, sigma_t, emission = medium.coefficients(origins + dirs * ((k + 0.5) * dt))
        # exact within a step for piecewise-constant coefficients: e (1 - exp(-s dt)) / s
        attenuation = np.exp(-sigma_t * dt)
        segment = np.where(sigma_t > 0, (1 - attenuation) / np.maximum(sigma_t, 1e-300), dt)
        emitted += np.exp(-tau) * emission * segment
        tau += sigma_t * dt
    return np.exp(-tau), emitted


def test_absorbing_emitting_volume_matches_cycles(openvdb, tmp_path, clean_scene):
    """A pure absorber (Color black: sigma_a = rho) that also emits (Emission Strength: constant,
    not density-weighted, filling Cycles' volume bounds) on a rotated, non-uniformly scaled Volume
    object, seen by an orthographic camera against a white world: each pixel is
    exp(-tau) + integral of emission x transmittance through the exported GridMedium (deterministic
    quadrature). Linear statistics of the image (mean, first
    moments, a T-weighted sum) are z-tested with variances estimated per pixel from two Cycles
    renders with different seeds: var(sum w m) = sum w^2 (c1 - c2)^2 / 4. This checks the grid
    transform, trilinear interpolation, Principled conversion and object density scale together."""
    x, y, z = np.meshgrid(*[np.linspace(-1, 1, n) for n in (20, 16, 12)], indexing="ij")
    density = np.clip(1 - (x ** 2 + y ** 2 + z ** 2), 0, None) * (1.2 + 0.8 * x)
    density = np.where(density > 0.05, density, 0.0).astype(np.float32)  # clear of Cycles' clipping 1e-3
    path = write_vdb(openvdb, tmp_path / "blob.vdb", [float_grid(openvdb, "density", density)])
    obj = volume_object(path, location=(0.1, -0.2, 0.0), rotation=(0.3, 0.2, 0.5), scale=(2.0, 1.2, 1.5))
    obj.data.render.precision = "FULL"  # the default half floats would add ~1e-3 relative error
    material = principled_material(density=3.0, color=(0.0, 0.0, 0.0, 1.0))
    principled = next(n for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeVolumePrincipled")
    principled.inputs["Emission Strength"].default_value = 0.4
    principled.inputs["Emission Color"].default_value = (1.0, 0.5, 0.25, 1.0)
    obj.data.materials.append(material)
    warnings = []
    exported = evg.export_volume_object(evaluated(obj)[0], warnings)
    medium = evg.grid_medium_from_volume(exported, warnings)
    assert medium is not None and not warnings, warnings

    assert_cycles_image_matches(obj, medium)


def assert_cycles_image_matches(obj, medium, min_absorbed=0.8, min_emitted=0.1):
    """Render `obj` alone with Cycles (orthographic, looking down -Z, white world) and z-test the
    image against the deterministic quadrature of `medium` (see the absorbing/emitting test)."""
    scene = bpy.context.scene
    world = bpy.data.worlds.new("White")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    camera_data = bpy.data.cameras.new("Ortho")
    camera_data.type = "ORTHO"
    camera = bpy.data.objects.new("Ortho", camera_data)
    scene.collection.objects.link(camera)
    lo, hi = medium.world_bounds()
    camera.location = (float(lo[0] + hi[0]) / 2, float(lo[1] + hi[1]) / 2, float(hi[2]) + 2.0)
    camera_data.ortho_scale = float(max(hi[:2] - lo[:2]))
    size = 24
    camera_location = np.array(camera.location)  # unrotated: looks down -Z, +Y up
    try:
        first, second = render_isolated_with_cycles(scene, (obj, camera), world, camera, size, samples=64)
    finally:
        bpy.data.objects.remove(camera)
        bpy.data.worlds.remove(world)

    centres = (np.arange(size) + 0.5) / size - 0.5
    u, v = np.meshgrid(centres * camera_data.ortho_scale, -centres * camera_data.ortho_scale)
    origins = np.stack([u.ravel(), v.ravel(), np.zeros(size * size)], axis=1) + camera_location
    dirs = np.tile([0.0, 0.0, -1.0], (size * size, 1))
    transmittance, emitted = transmittance_and_emission(medium, origins, dirs)
    reference = (transmittance + emitted).reshape(size, size, 3)
    assert transmittance.min() < 1.0 - min_absorbed and emitted.max() > min_emitted  # strong enough to test something

    mean = 0.5 * (first + second)
    variance_of_mean = 0.25 * (first - second) ** 2  # unbiased per-pixel variance of `mean`
    rows, cols = (np.mgrid[0:size, 0:size] / size)[..., None]
    absorbed = 1.0 - transmittance.reshape(size, size, 3)
    for name, weights in (("sum", np.ones((size, size, 1))), ("x moment", cols), ("y moment", rows),
                          ("absorption-weighted", absorbed)):
        difference = np.sum(weights * (mean - reference), axis=(0, 1))
        stderr = np.sqrt(np.sum(weights ** 2 * variance_of_mean, axis=(0, 1)))
        assert np.all(np.abs(difference) < 4.0 * stderr + 1e-9), (name, difference, stderr)
    # Outside the volume bounds Cycles must show the plain background (catches shifted bounds).
    clear = (transmittance.reshape(size, size, 3).min(axis=2) > 0.9999) & (emitted.reshape(size, size, 3).max(axis=2) == 0)
    assert np.all(np.abs(mean[clear] - 1.0) < 1e-3), np.argwhere(clear & np.any(np.abs(mean - 1) >= 1e-3, axis=2))



def test_collection_instances_get_their_own_transform(openvdb, tmp_path, clean_scene):
    path = write_vdb(openvdb, tmp_path / "smoke.vdb", [float_grid(openvdb, "density", procedural_density())])
    collection = bpy.data.collections.new("SmokeSource")
    bpy.context.scene.collection.children.link(collection)
    volume = bpy.data.volumes.new("Inst")
    volume.filepath = str(path)
    source = bpy.data.objects.new("Inst", volume)
    collection.objects.link(source)
    empty = bpy.data.objects.new("Instancer", None)
    empty.instance_type = "COLLECTION"
    empty.instance_collection = collection
    empty.location = (5.0, 0.0, 0.0)
    empty.scale = (2.0, 2.0, 2.0)
    bpy.context.scene.collection.objects.link(empty)
    try:
        warnings = []
        exported = evg.export_volume_objects(bpy.context.evaluated_depsgraph_get(), warnings)
        assert len(exported) == 2, warnings
        original, instance = sorted(exported, key=lambda e: e.object_to_world[0, 3])
        np.testing.assert_allclose(instance.grids["density"].index_to_world,
                                   np.array(empty.matrix_world) @ original.grids["density"].index_to_world, atol=1e-6)
        assert instance.density_factor == pytest.approx(original.density_factor / 2.0)
    finally:
        bpy.data.objects.remove(empty)
        bpy.data.collections.remove(collection)


def henyey_greenstein(cos_theta, g):
    """Phase function of the angle between incoming and outgoing propagation directions."""
    denominator = 1.0 + g * g - 2.0 * g * cos_theta
    return (1.0 - g * g) / (4.0 * math.pi * denominator * np.sqrt(denominator))


def test_single_scattering_of_a_sunlit_volume_matches_cycles(openvdb, tmp_path, clean_scene):
    """End to end through the GridMedium API: camera rays -> sample_free_flight -> next-event
    estimation to a sun through `transmittance` (HG phase), against Cycles with Volume bounces 0
    (one scattering vertex, direct light only) on the same exported Volume object. Linear image
    statistics are z-tested with both estimators' measured variances."""
    x, y, z = np.meshgrid(*[np.linspace(-1, 1, n) for n in (16, 14, 12)], indexing="ij")
    density = np.clip(1 - (x ** 2 + y ** 2 + z ** 2), 0, None) * (1.0 + 0.5 * y)
    density = np.where(density > 0.05, density, 0.0).astype(np.float32)
    path = write_vdb(openvdb, tmp_path / "cloud.vdb", [float_grid(openvdb, "density", density)])
    obj = volume_object(path, location=(0.0, 0.0, 0.0), rotation=(0.2, -0.3, 0.4), scale=(1.5, 1.5, 1.5))
    obj.data.render.precision = "FULL"
    anisotropy = 0.4
    material = principled_material(density=4.0, color=(0.9, 0.7, 0.5, 1.0))
    next(n for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeVolumePrincipled") \
        .inputs["Anisotropy"].default_value = anisotropy
    obj.data.materials.append(material)
    warnings = []
    medium = evg.grid_medium_from_volume(evg.export_volume_object(evaluated(obj)[0], warnings), warnings)
    assert medium is not None and not warnings, warnings

    from mathutils import Vector
    sun_travel = np.array([0.3, -0.5, 0.8])  # from below: the camera looks into forward scattering
    sun_travel /= np.linalg.norm(sun_travel)
    irradiance = 3.0
    sun_data = bpy.data.lights.new("Sun", "SUN")
    sun_data.energy, sun_data.angle = irradiance, 0.0
    sun = bpy.data.objects.new("Sun", sun_data)
    sun.rotation_euler = Vector(sun_travel.tolist()).to_track_quat("-Z", "Y").to_euler()

    scene = bpy.context.scene
    world = bpy.data.worlds.new("Black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    camera_data = bpy.data.cameras.new("Ortho")
    camera_data.type = "ORTHO"
    camera = bpy.data.objects.new("Ortho", camera_data)
    lo, hi = medium.world_bounds()
    camera.location = (float(lo[0] + hi[0]) / 2, float(lo[1] + hi[1]) / 2, float(hi[2]) + 2.0)
    camera_data.ortho_scale = float(max(hi[:2] - lo[:2]))
    camera_location = np.array(camera.location)
    for new in (sun, camera):
        scene.collection.objects.link(new)
    size = 16
    try:
        first, second = render_isolated_with_cycles(scene, (obj, camera, sun), world, camera, size, samples=128)
    finally:
        for gone in (camera, sun):
            bpy.data.objects.remove(gone)
        bpy.data.worlds.remove(world)

    # VolPath's side: the estimator an integrator builds from the API, 512 paths per pixel.
    paths = 512
    centres = (np.arange(size) + 0.5) / size - 0.5
    u, v = np.meshgrid(centres * camera_data.ortho_scale, -centres * camera_data.ortho_scale)
    pixels = np.stack([u.ravel(), v.ravel(), np.zeros(size * size)], axis=1) + camera_location
    origins = np.repeat(pixels, paths, axis=0)
    dirs = np.tile([0.0, 0.0, -1.0], (len(origins), 1))
    rng = np.random.default_rng(21)
    flight = medium.sample_free_flight(origins, dirs, np.inf, rng)
    radiance = np.zeros((len(origins), 3))
    s = np.flatnonzero(flight.scattered)
    points = origins[s] + dirs[s] * flight.t[s, None]
    toward_sun = np.tile(-sun_travel, (len(s), 1))
    shadow = medium.transmittance(points, toward_sun, np.inf, rng)
    phase = henyey_greenstein(-dirs[s] @ sun_travel, anisotropy)  # cos(incoming, outgoing propagation)
    radiance[s] = flight.weight[s] * shadow * (phase * irradiance)[:, None]
    radiance = radiance.reshape(size * size, paths, 3)
    ours = radiance.mean(axis=1).reshape(size, size, 3)
    our_variance = (radiance.var(axis=1, ddof=1) / paths).reshape(size, size, 3)

    theirs = 0.5 * (first + second)
    their_variance = 0.25 * (first - second) ** 2
    assert theirs.mean() > 1e-2  # lit
    rows, cols = (np.mgrid[0:size, 0:size] / size)[..., None]
    for name, weights in (("sum", np.ones((size, size, 1))), ("x moment", cols), ("y moment", rows)):
        difference = np.sum(weights * (ours - theirs), axis=(0, 1))
        stderr = np.sqrt(np.sum(weights ** 2 * (our_variance + their_variance), axis=(0, 1)))
        assert np.all(np.abs(difference) < 4.0 * stderr), (name, difference, stderr, theirs.sum(axis=(0, 1)))


def test_geometry_nodes_mesh_to_volume_is_exported(clean_scene):
    """A mesh object whose modifiers output a volume (Mesh to Volume) shows up as a VOLUME instance
    of the evaluated depsgraph; its evaluated grid is what gets exported."""
    import bmesh
    mesh = bpy.data.meshes.new("Cube")
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=1.0)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new("CubeToVolume", mesh)
    bpy.context.scene.collection.objects.link(obj)
    tree = bpy.data.node_groups.new("ToVolume", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    group_in, group_out = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
    to_volume = tree.nodes.new("GeometryNodeMeshToVolume")
    tree.links.new(group_in.outputs[0], to_volume.inputs["Mesh"])
    tree.links.new(to_volume.outputs[0], group_out.inputs[0])
    obj.modifiers.new("ToVolume", "NODES").node_group = tree
    obj.location = (2.0, 0.0, 0.0)
    try:
        warnings = []
        exported = evg.export_volume_objects(bpy.context.evaluated_depsgraph_get(), warnings)
        assert [e.object_name for e in exported] == ["CubeToVolume"], warnings
        grid = exported[0].grids["density"]
        assert grid.data.max() == pytest.approx(1.0)
        medium = evg.grid_medium_from_volume(exported[0], warnings)
        inside = medium.density_at(np.array([[2.0, 0.0, 0.0], [2.1, 0.1, -0.1]]))
        outside = medium.density_at(np.array([[2.0, 0.0, 0.7], [1.2, 0.0, 0.0]]))
        np.testing.assert_allclose(inside, 1.0, atol=1e-6)
        np.testing.assert_allclose(outside, 0.0, atol=1e-6)
    finally:
        bpy.data.objects.remove(obj)
        bpy.data.meshes.remove(mesh)
        bpy.data.node_groups.remove(tree)


def fire_volume(openvdb, tmp_path, temperature_name="temperature", flame=False):
    """A blob of smoke (absorbing) with a temperature grid (a ramp, ~700..2600 K with Temperature
    1000) and optionally a flame grid, on a rotated, scaled Volume object. The temperature and
    flame grids cover a different (larger) box than the density: they must still align."""
    x, y, z = np.meshgrid(*[np.linspace(-1, 1, n) for n in (16, 14, 12)], indexing="ij")
    density = np.clip(1 - (x ** 2 + y ** 2 + z ** 2), 0, None) * 1.5
    density = np.where(density > 0.05, density, 0.0).astype(np.float32)
    temperature = (0.7 + 0.95 * (x + 1)).astype(np.float32)  # every voxel active: a larger box
    grids = [float_grid(openvdb, "density", density), float_grid(openvdb, temperature_name, temperature)]
    if flame:
        grids.append(float_grid(openvdb, "flame", np.clip(1.0 - np.hypot(y, z), 0.0, None).astype(np.float32) * 3.0))
    path = write_vdb(openvdb, tmp_path / "fire.vdb", grids)
    obj = volume_object(path, location=(0.1, -0.2, 0.0), rotation=(0.3, 0.2, 0.5), scale=(2.0, 1.2, 1.5))
    obj.data.render.precision = "FULL"
    material = principled_material(density=0.8, color=(0.0, 0.0, 0.0, 1.0))
    principled = next(n for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeVolumePrincipled")
    principled.inputs["Blackbody Intensity"].default_value = 1.0
    principled.inputs["Blackbody Tint"].default_value = (1.0, 0.8, 0.9, 1.0)
    principled.inputs["Temperature"].default_value = 1000.0
    principled.inputs["Temperature Attribute"].default_value = temperature_name
    if flame:  # Emission Strength <- Attribute 'flame' (Fac), Emission Color orange
        attribute = material.node_tree.nodes.new("ShaderNodeAttribute")
        attribute.attribute_name = "flame"
        material.node_tree.links.new(attribute.outputs["Fac"], principled.inputs["Emission Strength"])
        principled.inputs["Emission Color"].default_value = (1.0, 0.4, 0.1, 1.0)
    obj.data.materials.append(material)
    return obj


def test_blackbody_temperature_grid_matches_closed_form(openvdb, tmp_path, clean_scene):
    """Per voxel: sigma/pi x T^4 x tint x blackbody(T), T = Temperature x temperature attribute,
    scaled by the object density factor (kernel/svm/closure.h); interpolated trilinearly."""
    from volpath_native.grid_medium import BLACKBODY_SIGMA, blackbody_rec709

    obj = fire_volume(openvdb, tmp_path)
    warnings = []
    exported = evg.export_volume_object(evaluated(obj)[0], warnings)
    medium = evg.grid_medium_from_volume(exported, warnings)
    assert medium is not None and not warnings, warnings
    density, temperature = exported.grids["density"], exported.grids["temperature"]
    assert density.data.shape == temperature.data.shape == (16, 14, 12)  # aligned on the union box
    voxel = (12, 7, 5)
    t = 1000.0 * temperature.data[voxel]
    expected = exported.density_factor * BLACKBODY_SIGMA * t ** 4 * np.array([1.0, 0.8, 0.9]) * blackbody_rec709(t)
    world = (density.index_to_world @ np.append(voxel, 1.0))[:3]
    _, _, emission = medium.coefficients(world[None])
    np.testing.assert_allclose(emission[0], expected, rtol=1e-5)
    assert medium.emission.tolist() == [0.0, 0.0, 0.0]  # the grid carries it all


def test_blackbody_without_temperature_grid_uses_constant_temperature(openvdb, tmp_path, clean_scene):
    from volpath_native.grid_medium import blackbody_emission

    obj = fire_volume(openvdb, tmp_path, temperature_name="heat_not_read")
    obj.active_material.node_tree.nodes["Principled Volume"].inputs["Temperature Attribute"].default_value = "missing"
    warnings = []
    exported = evg.export_volume_object(evaluated(obj)[0], warnings)
    medium = evg.grid_medium_from_volume(exported, warnings)
    assert medium is not None and medium.emission_grid is None
    np.testing.assert_allclose(medium.emission, exported.density_factor * blackbody_emission(1000.0, 1.0, (1.0, 0.8, 0.9)))


@pytest.mark.parametrize("flame", [False, True], ids=["blackbody", "blackbody+flame"])
def test_fire_volume_matches_cycles(openvdb, tmp_path, clean_scene, flame):
    """Blackbody from a temperature grid (and flame emission via an Attribute node) on an
    absorbing blob, rendered by Cycles and z-tested against the exported medium's quadrature."""
    obj = fire_volume(openvdb, tmp_path, flame=flame)
    warnings = []
    exported = evg.export_volume_object(evaluated(obj)[0], warnings)
    medium = evg.grid_medium_from_volume(exported, warnings)
    assert medium is not None and not warnings, warnings
    assert (medium.emission_grid is not None) and medium.emission_grid.max() > 0.05
    assert_cycles_image_matches(obj, medium, min_absorbed=0.5, min_emitted=0.3)


def test_node_detail_over_a_vdb_density_becomes_a_program_medium(openvdb, tmp_path, clean_scene):
    """Density = density attribute x (0.5 + 0.5 x Object X) via Math nodes: compiled into a program
    that reads the grid as an attribute (Cycles evaluates the nodes per lookup)."""
    from volpath_native.program_medium import ProgramMedium

    density = procedural_density()
    path = write_vdb(openvdb, tmp_path / "smoke.vdb", [float_grid(openvdb, "density", density)])
    obj = volume_object(path)
    material = principled_material(density=1.0)
    tree = material.node_tree
    principled = next(n for n in tree.nodes if n.type == "PRINCIPLED_VOLUME")
    coords, separate = tree.nodes.new("ShaderNodeTexCoord"), tree.nodes.new("ShaderNodeSeparateXYZ")
    ramp = tree.nodes.new("ShaderNodeMath")
    ramp.operation = "MULTIPLY_ADD"
    ramp.inputs[1].default_value, ramp.inputs[2].default_value = 0.5, 0.5
    tree.links.new(coords.outputs["Object"], separate.inputs["Vector"])
    tree.links.new(separate.outputs["X"], ramp.inputs[0])
    tree.links.new(ramp.outputs["Value"], principled.inputs["Density"])
    obj.data.materials.append(material)
    warnings = []
    exported = evg.export_volume_object(evaluated(obj)[0], warnings)
    medium = evg.grid_medium_from_volume(exported, warnings)
    assert isinstance(medium, ProgramMedium), (type(medium), warnings)
    assert not warnings, warnings
    grid = exported.grids["density"]
    voxel = np.array([4, 5, 3])
    world = (grid.index_to_world @ np.append(voxel, 1.0))[:3]
    object_x = (np.linalg.inv(np.array(obj.matrix_world)) @ np.append(world, 1.0))[0]
    _, sigma_t, _ = medium.coefficients(world[None])
    expected = exported.density_factor * grid.data[tuple(voxel)] * (0.5 + 0.5 * object_x)
    assert sigma_t[0, 0] == pytest.approx(expected, rel=1e-5)
    # the box is the grid's (padded) box, as for grid media
    lo, hi = medium.world_bounds()
    assert np.all(lo <= world) and np.all(world <= hi)
