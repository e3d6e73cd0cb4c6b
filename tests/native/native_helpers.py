"""Scene builders and statistics shared by the native renderer tests."""
from __future__ import annotations

import numpy as np

from volpath_native import (Camera, Film, Material, Medium, Mesh, PointLight, RenderSettings, Scene,
                            World)

# |z| beyond this is a failure: two-sided p ~ 6e-5 per check, so a test with a few hundred
# independent pixels still has a family-wise false alarm rate below ~2 %.
Z_LIMIT = 4.0


def box_mesh(name, lo, hi, material=0, inward=False):
    """Closed axis-aligned box, outward normals (CCW seen from outside) unless inward."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = np.array([[lo[0], lo[1], lo[2]], [hi[0], lo[1], lo[2]], [hi[0], hi[1], lo[2]], [lo[0], hi[1], lo[2]],
                  [lo[0], lo[1], hi[2]], [hi[0], lo[1], hi[2]], [hi[0], hi[1], hi[2]], [lo[0], hi[1], hi[2]]])
    f = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                  [2, 3, 7], [2, 7, 6], [1, 2, 6], [1, 6, 5], [0, 4, 7], [0, 7, 3]])
    if inward:
        f = f[:, ::-1]
    return Mesh(name, v, f, np.full(len(f), material))


def icosphere(name, radius=1.0, subdivisions=3, material=0, centre=(0, 0, 0)):
    t = (1 + 5 ** 0.5) / 2
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
         [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
         [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
         [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    v = [np.array(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(subdivisions):
        cache, nf = {}, []

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = v[a] + v[b]
                v.append(m / np.linalg.norm(m))
                cache[key] = len(v) - 1
            return cache[key]
        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = nf
    verts = np.array(v) * radius + np.asarray(centre, float)
    return Mesh(name, verts, np.array(f), np.full(len(f), material))


def camera_at(position, look_dir=(0, 0, -1), up=(0, 1, 0)):
    """camera_to_world for a camera at position looking along look_dir."""
    fwd = np.asarray(look_dir, float)
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, up)
    if np.linalg.norm(right) < 1e-9:
        right = np.cross(fwd, [1.0, 0, 0])
    right /= np.linalg.norm(right)
    true_up = np.cross(right, fwd)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, true_up, -fwd, position
    return m


def tiny_box_film(size):
    """A film whose samples all go through pixel centres (box filter of negligible width)."""
    return Film(size, size, filter="box", filter_width=1e-6)


def z_scores(mean_a, var_a, mean_b, var_b=0.0):
    return (mean_a - mean_b) / np.sqrt(np.maximum(var_a + var_b, 1e-30))


def block_z_scores(a, b, block: int = 2):
    """z-scores of the difference between two renders' means over block x block pixels (RGB),
    with each block's variance of the mean from the renders' per-pixel variances."""
    h, w = a.image.shape[:2]

    def blocks(x, reduce):
        return reduce(x.reshape(h // block, block, w // block, block, 3), axis=(1, 3))
    mean = lambda r: blocks(r.image[..., :3], np.mean)
    var = lambda r: blocks(r.variance, np.sum) / block ** 4
    return z_scores(mean(a), var(a), mean(b), var(b))


def chi2_critical(dof, z=3.719):
    """Upper critical value of chi-square(dof) at the normal quantile z (default p = 1e-4),
    Wilson-Hilferty approximation (accurate to < 1 % for dof >= 5)."""
    h = 2.0 / (9.0 * dof)
    return dof * (1.0 - h + z * np.sqrt(h)) ** 3


def rotated_transform(voxel_size=0.05, offset=(0.3, -0.2, 1.0)):
    """A non-axis-aligned, anisotropically scaled index->world map (exercises every transform path)."""
    angle = 0.4
    rot = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    tilt = np.array([[1, 0, 0], [0, np.cos(0.3), -np.sin(0.3)], [0, np.sin(0.3), np.cos(0.3)]])
    m = np.eye(4)
    m[:3, :3] = rot @ tilt @ np.diag([voxel_size, voxel_size * 1.5, voxel_size * 0.8])
    m[:3, 3] = offset
    return m


def lit_box_in_fog(**settings):
    """A lit box in fog inside a null boundary, the lamp inside the fog: shadow rays step through
    the boundary and are seldom blocked."""
    fog = box_mesh("fog", [-1.5, -1.5, -1.5], [1.5, 1.5, 1.5], material=1)
    return Scene(camera=Camera(camera_at([0, 0, 4])), film=Film(12, 8),
                 meshes=[box_mesh("box", [-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]), fog],
                 materials=[Material("d", base_color=[0.8, 0.4, 0.2]), Material("fog", surface="null", medium=0)],
                 media=[Medium("m", [0.3, 0.4, 0.5], 0.05, g=0.3)],
                 lights=[PointLight("p", [0.5, 1.2, 1.0], power=300.0, radius=0.1)],
                 settings=RenderSettings(samples=1, seed=4, **settings))
