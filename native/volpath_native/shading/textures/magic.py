"""Magic Texture node (Cycles src/kernel/svm/magic.h `svm_magic`, `svm_node_tex_magic`)."""
from __future__ import annotations

import math

import numpy as np

from ...jit import stage_kernel

TWO_PI_F = float(np.float32(2.0 * math.pi))


@stage_kernel
def magic_texture(depth, vx, vy, vz, scale, distortion):
    """magic.h `svm_magic`: (fac, r, g, b), fac the average of the colour. The inputs are wrapped
    by fmod(p, 2 pi) in float32 first, as Cycles does against NaN at large coordinates."""
    px = np.float32(np.fmod(float(np.float32(vx)), TWO_PI_F))
    py = np.float32(np.fmod(float(np.float32(vy)), TWO_PI_F))
    pz = np.float32(np.fmod(float(np.float32(vz)), TWO_PI_F))
    x = math.sin(float((px + py + pz) * np.float32(5.0) * np.float32(scale)))
    y = math.cos(float((-px + py - pz) * np.float32(5.0) * np.float32(scale)))
    z = -math.cos(float((-px - py + pz) * np.float32(5.0) * np.float32(scale)))
    dist = float(np.float32(distortion))
    if depth > 0:
        x *= dist
        y *= dist
        z *= dist
        y = -math.cos(x - y + z)
        y *= dist
        if depth > 1:
            x = math.cos(x - y - z)
            x *= dist
            if depth > 2:
                z = math.sin(-x - y - z)
                z *= dist
                if depth > 3:
                    x = -math.cos(-x + y - z)
                    x *= dist
                    if depth > 4:
                        y = -math.sin(-x + y + z)
                        y *= dist
                        if depth > 5:
                            y = -math.cos(-x + y + z)
                            y *= dist
                            if depth > 6:
                                x = math.cos(x + y + z)
                                x *= dist
                                if depth > 7:
                                    z = math.sin(x + y - z)
                                    z *= dist
                                    if depth > 8:
                                        x = -math.cos(-x - y + z)
                                        x *= dist
                                        if depth > 9:
                                            y = -math.sin(x - y + z)
                                            y *= dist
    if dist != 0.0:
        x /= 2.0 * dist
        y /= 2.0 * dist
        z /= 2.0 * dist
    r, g, b = 0.5 - x, 0.5 - y, 0.5 - z
    return (r + g + b) / 3.0, r, g, b
