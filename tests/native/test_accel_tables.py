"""The Accelerator's per-triangle tables and build quality (issue 13: a big mesh loads fast): the
compiled normal/area pass gives numpy's numbers bit for bit, degenerate triangles are dropped,
one smooth mesh's corner normals are shared rather than copied, and Embree's LOW build quality
(picked for renders with few camera samples per triangle) gives the same hits as MEDIUM."""
from __future__ import annotations

import numpy as np

from volpath_native.accel import LOW_QUALITY_SAMPLES_PER_TRIANGLE, Accelerator, build_quality
from volpath_native.embree import library as lib
from volpath_native.scene import Mesh
from volpath_native.triangle_geometry import corner_bounds, normals_and_doubled_areas


def _numpy_normals(vertices, triangles):
    """The tables as the Accelerator computed them before (numpy cross and einsum)."""
    p0 = vertices[triangles[:, 0]].astype(np.float64)
    cross = np.cross(vertices[triangles[:, 1]] - p0, vertices[triangles[:, 2]] - p0)
    length = np.sqrt(np.einsum("ij,ij->i", cross, cross))
    return cross / np.maximum(length, 1e-30)[:, None], length


def _sphere_mesh(rng, n=3000, name="sphere", smooth=True):
    vertices = rng.normal(size=(n, 3))
    vertices /= np.linalg.norm(vertices, axis=1)[:, None]
    triangles = rng.integers(0, n, size=(2 * n, 3))
    triangles[:7, 2] = triangles[:7, 1]  # degenerate
    normals = vertices[triangles].astype(np.float32) if smooth else None
    return Mesh(name, vertices.astype(np.float32), triangles, np.zeros(len(triangles), int), corner_normals=normals)


def test_normals_and_areas_are_numpys_bit_for_bit():
    rng = np.random.default_rng(3)
    for scale in (1e-3, 1.0, 1e4):
        vertices = (rng.normal(size=(500, 3)) * scale).astype(np.float32)
        triangles = rng.integers(0, 500, size=(2000, 3)).astype(np.int32)
        triangles[:5, 2] = triangles[:5, 0]
        normals, lengths = normals_and_doubled_areas(vertices, triangles)
        expected_normals, expected_lengths = _numpy_normals(vertices, triangles)
        assert np.array_equal(lengths, expected_lengths)
        assert np.array_equal(normals.view(np.int64), expected_normals.view(np.int64))
        lo, hi = corner_bounds(vertices, triangles[:100])
        used = vertices[np.unique(triangles[:100])]
        assert np.array_equal(lo, used.min(axis=0)) and np.array_equal(hi, used.max(axis=0))


def test_accelerator_tables():
    rng = np.random.default_rng(4)
    mesh = _sphere_mesh(rng)
    keep = _numpy_normals(mesh.vertices, mesh.triangles)[1] > 1e-20
    assert mesh.validate(1) == [f"mesh 'sphere': {int((~keep).sum())} degenerate triangles ignored"]
    accel = Accelerator([mesh])
    assert accel.triangle_count == int(keep.sum())
    expected_normals, lengths = _numpy_normals(mesh.vertices, mesh.triangles[keep])
    assert np.array_equal(accel.normals, expected_normals)
    assert np.array_equal(accel.areas, 0.5 * lengths)
    assert np.array_equal(accel.corner_normals, mesh.corner_normals[keep])
    # one smooth mesh, nothing dropped: its own corner normals, not a copy
    whole = Mesh("whole", mesh.vertices, mesh.triangles[keep], np.zeros(int(keep.sum()), int),
                 corner_normals=mesh.corner_normals[keep])
    assert Accelerator([whole]).corner_normals is whole.corner_normals
    # two meshes, one flat: the flat one's corners hold its geometric normal
    flat = _sphere_mesh(np.random.default_rng(5), n=500, name="flat", smooth=False)
    both = Accelerator([whole, flat])
    n_whole = whole.triangles.shape[0]
    assert np.array_equal(both.corner_normals[:n_whole], whole.corner_normals)
    assert np.array_equal(both.corner_normals[n_whole:], np.repeat(both.normals[n_whole:, None, :], 3, 1)
                          .astype(np.float32))


def test_build_quality_follows_the_camera_samples_per_triangle():
    assert build_quality(1000, None) == lib.BUILD_QUALITY_MEDIUM  # Cycles' quality by default
    assert build_quality(1000, LOW_QUALITY_SAMPLES_PER_TRIANGLE * 1000) == lib.BUILD_QUALITY_MEDIUM
    assert build_quality(1000, LOW_QUALITY_SAMPLES_PER_TRIANGLE * 1000 - 1) == lib.BUILD_QUALITY_LOW


def test_low_and_medium_quality_give_the_same_hits():
    rng = np.random.default_rng(6)
    mesh = _sphere_mesh(rng, n=4000)
    many, few = Accelerator([mesh], camera_samples=10 ** 9), Accelerator([mesh], camera_samples=1)
    assert (many.build_quality, few.build_quality) == (lib.BUILD_QUALITY_MEDIUM, lib.BUILD_QUALITY_LOW)
    n = 20000
    origins = (rng.normal(size=(n, 3)) * 0.5).astype(np.float32)
    directions = rng.normal(size=(n, 3))
    directions = (directions / np.linalg.norm(directions, axis=1)[:, None]).astype(np.float32)
    hits = [accel.intersect_raw(origins, directions, np.full(n, 1e30, np.float32)) for accel in (many, few)]
    assert (hits[0].prim >= 0).mean() > 0.5
    assert np.array_equal(hits[0].prim, hits[1].prim)
    hit = hits[0].prim >= 0
    for field in ("t", "u", "v"):
        assert np.array_equal(getattr(hits[0], field)[hit], getattr(hits[1], field)[hit])
