"""The direct Embree binding (volpath_native.embree): the RTCRayHit layout on the loaded library,
the same hits as embreex's EmbreeScene.run (same library, robust scene) on random rays against a
random mesh, occlusion agreeing with closest hits, instances and their transforms, and the
compiled query loops loading from numba's on-disk cache in a fresh process."""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from volpath_native.embree import TriangleScene
from volpath_native.embree import library as lib
from volpath_native.embree.queries import new_rayhit


def random_mesh(rng, n_vertices=4000, n_triangles=6000, size=10.0):
    """Small triangles scattered in a box (a realistic BVH, unlike triangles spanning the box)."""
    centres = rng.random((n_triangles, 3)) * size
    vertices = (centres[:, None, :] + rng.normal(scale=0.3, size=(n_triangles, 3, 3))).reshape(-1, 3)
    return vertices.astype(np.float32), np.arange(3 * n_triangles, dtype=np.int32).reshape(-1, 3)


def random_rays(rng, n, size=10.0):
    origins = (rng.random((n, 3)) * size).astype(np.float32)
    directions = rng.normal(size=(n, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    tfar = np.where(rng.random(n) < 0.5, 1e30, rng.random(n) * size).astype(np.float32)
    return origins, directions.astype(np.float32), tfar


def test_rayhit_layout_matches_the_library():
    """One hit through a raw RTCRayHit: tfar, u, v, primID, geomID and instID land at the word
    offsets library.py declares, and nothing is written past RAYHIT_WORDS."""
    import ctypes
    scene = TriangleScene()
    scene.add_triangles(np.float32([[0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.int32([[0, 1, 2]]), 0)
    scene.commit()
    raw = np.full(lib.RAYHIT_WORDS + 16, 7.0, np.float32)
    start = (-raw.ctypes.data % 64) // 4
    rayhit = raw[start:start + lib.RAYHIT_WORDS]
    words = rayhit.view(np.uint32)
    rayhit[lib.RAY_ORG:lib.RAY_ORG + 3] = [0.25, 0.5, 2.0]
    rayhit[lib.RAY_TNEAR] = 0.0
    rayhit[lib.RAY_DIR:lib.RAY_DIR + 3] = [0, 0, -1]
    rayhit[lib.RAY_TIME] = 0.0
    rayhit[lib.RAY_TFAR] = 100.0
    words[lib.RAY_MASK], words[lib.RAY_ID], words[lib.RAY_FLAGS] = 0xFFFFFFFF, 0, 0
    words[lib.HIT_GEOM] = words[lib.HIT_INST] = lib.INVALID_ID
    lib._lib.rtcIntersect1(ctypes.c_void_p(scene._scene), ctypes.c_void_p(rayhit.ctypes.data), None)
    assert rayhit[lib.RAY_TFAR] == pytest.approx(2.0)
    assert (rayhit[lib.HIT_U], rayhit[lib.HIT_V]) == pytest.approx((0.25, 0.5))
    assert (words[lib.HIT_PRIM], words[lib.HIT_GEOM], words[lib.HIT_INST]) == (0, 0, lib.INVALID_ID)
    assert np.allclose(rayhit[lib.HIT_NG:lib.HIT_NG + 3] / rayhit[lib.HIT_NG + 2], [0, 0, 1])
    after = raw[start + lib.RAYHIT_WORDS:]
    assert np.all(after == 7.0)


def test_same_hits_as_embreex_on_random_rays():
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh
    rng = np.random.default_rng(5)
    vertices, triangles = random_mesh(rng)
    origins, directions, tfar = random_rays(rng, 50000)
    reference = rtcore_scene.EmbreeScene()
    TriangleMesh(reference, vertices, triangles)
    expected = reference.run(origins, directions, dists=tfar.copy(), output=1)
    blocked_expected = reference.run(origins, directions, dists=tfar.copy(), query="OCCLUDED") >= 0
    scene = TriangleScene()
    scene.add_triangles(vertices, triangles, 0)
    scene.commit()
    t, prim, inst, u, v = scene.intersect(origins, directions, tfar)
    hit = prim >= 0
    assert 0.2 < hit.mean() < 0.95  # the rays test both outcomes
    np.testing.assert_array_equal(prim, expected["primID"])
    np.testing.assert_array_equal(t[hit], expected["tfar"][hit])
    np.testing.assert_array_equal(u[hit], expected["u"][hit])
    np.testing.assert_array_equal(v[hit], expected["v"][hit])
    assert np.all(inst == -1)
    blocked = scene.occluded(origins, directions, tfar)
    np.testing.assert_array_equal(blocked, blocked_expected)
    np.testing.assert_array_equal(blocked, hit)
    # planted error: one triangle moved must change some hits
    moved = vertices.copy()
    moved[triangles[prim[hit][0]]] += 0.5
    other = TriangleScene()
    other.add_triangles(moved, triangles, 0)
    other.commit()
    assert np.any(other.intersect(origins, directions, tfar)[1] != prim)


def test_instances_report_prototype_triangle_and_instance():
    rng = np.random.default_rng(2)
    vertices, triangles = random_mesh(rng, n_triangles=500, size=2.0)
    prototype = TriangleScene()
    prototype.add_triangles(vertices, triangles, 0)
    prototype.commit()
    transforms = []
    for k in range(3):
        angle = 0.7 * k
        c, s = np.cos(angle), np.sin(angle)
        transforms.append(np.array([[c * (1 + k), -s, 0, 5.0 * k], [s, c, 0, 1.0], [0, 0, 1 + 0.5 * k, -2.0]]))
    world = TriangleScene()
    world.add_triangles(vertices, triangles, 0)  # an untransformed copy too
    for k, transform in enumerate(transforms):
        world.add_instance(prototype, transform[None], 1000 * (k + 1))
    world.commit()
    flat = TriangleScene()
    flat.add_triangles(vertices, triangles, 0)
    for k, transform in enumerate(transforms):
        placed = (vertices.astype(np.float64) @ transform[:, :3].T + transform[:, 3]).astype(np.float32)
        flat.add_triangles(placed, triangles, 1000 * (k + 1))
    flat.commit()
    origins, directions, tfar = random_rays(rng, 20000, size=12.0)
    origins[:, 2] -= 3.0
    t, prim, inst, u, v = world.intersect(origins, directions, tfar)
    t_flat, prim_flat, _, _, _ = flat.intersect(origins, directions, tfar)
    hit = prim >= 0
    assert hit.mean() > 0.05 and np.all(np.isin(inst[hit], [-1, 0, 1, 2]))
    np.testing.assert_array_equal(prim >= 0, prim_flat >= 0)
    same = prim == prim_flat
    assert same.mean() > 0.999  # ties at shared edges may differ by rounding
    assert np.allclose(t[hit & same], t_flat[hit & same], rtol=1e-4, atol=1e-4)
    np.testing.assert_array_equal(inst[hit] == -1, prim[hit] < 1000)
    np.testing.assert_array_equal(inst[hit] >= 0, prim[hit] >= 1000)
    assert np.all(prim[hit & (inst >= 0)] // 1000 == inst[hit & (inst >= 0)] + 1)
    np.testing.assert_array_equal(world.occluded(origins, directions, tfar), hit)


def test_query_loops_load_from_the_disk_cache_in_a_new_process(tmp_path):
    """numba caches the loops that call Embree by name: a second process loads them (cache hits,
    no misses) under the package's KernelCacheLocator folder."""
    code = (
        "import numpy as np\n"
        "from volpath_native.embree import TriangleScene\n"
        "from volpath_native.embree.queries import intersect_rays, occluded_rays\n"
        "from volpath_native.jit import KERNEL_CACHE_DIR\n"
        "s = TriangleScene(); s.add_triangles(np.float32([[0,0,0],[1,0,0],[0,1,0]]), np.int32([[0,1,2]]), 0)\n"
        "s.commit()\n"
        "o = np.float32([[0.2, 0.2, 1]]); d = np.float32([[0, 0, -1]]); t = np.float32([9])\n"
        "assert s.intersect(o, d, t)[1][0] == 0 and s.occluded(o, d, t)[0]\n"
        "print(sum(intersect_rays.stats.cache_hits.values()) + sum(occluded_rays.stats.cache_hits.values()),\n"
        "      sum(intersect_rays.stats.cache_misses.values()) + sum(occluded_rays.stats.cache_misses.values()),\n"
        "      KERNEL_CACHE_DIR)\n")
    env = dict(os.environ)
    runs = [subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600)
            for _ in range(2)]
    for run in runs:
        assert run.returncode == 0, run.stderr
    hits, misses, folder = runs[1].stdout.split()
    assert (int(hits), int(misses)) == (2, 0)
    assert any(name.startswith("queries.intersect_rays") for name in os.listdir(os.path.join(folder, "embree")))
