"""Wave Texture node (Cycles src/kernel/svm/wave.h `svm_wave`, `svm_node_tex_wave`): bands and
rings, their directions, sine / saw / triangle profiles, phase, and fBM distortion (detail, detail
scale, detail roughness). The wave's argument n is float32 as in Cycles (its saw and triangle
profiles jump where n crosses a multiple of 2 pi)."""
from __future__ import annotations

import math

import numpy as np

from ...jit import stage_kernel
from .noise import fbm

#: Cycles svm/types.h NodeWaveType, NodeWaveBandsDirection, NodeWaveRingsDirection, NodeWaveProfile
WAVE_BANDS, WAVE_RINGS = range(2)
WAVE_TYPES = {"BANDS": WAVE_BANDS, "RINGS": WAVE_RINGS}
BANDS_DIRECTIONS = {"X": 0, "Y": 1, "Z": 2, "DIAGONAL": 3}
RINGS_DIRECTIONS = {"X": 0, "Y": 1, "Z": 2, "SPHERICAL": 3}
WAVE_PROFILE_SIN, WAVE_PROFILE_SAW, WAVE_PROFILE_TRI = range(3)
WAVE_PROFILES = {"SIN": WAVE_PROFILE_SIN, "SAW": WAVE_PROFILE_SAW, "TRI": WAVE_PROFILE_TRI}
PI_2_F = np.float32(math.pi / 2.0)
TWO_PI_F = np.float32(2.0 * math.pi)
#: the fBM loop is bounded like the Noise node's (Cycles leaves a linked Detail unclamped: a huge
#: value would loop for ever, a negative one gives NaN); README lists the difference
MAX_DETAIL = 15.0


@stage_kernel
def wave_texture(wave_type, direction, profile, vx, vy, vz, scale, distortion, detail, detail_scale,
                 detail_roughness, phase):
    """wave.h `svm_wave` at co * scale; `direction` is the bands or rings direction of wave_type."""
    s = np.float32(scale)
    eps = np.float32(0.000001)
    shrink = np.float32(0.999999)
    # "prevent precision issues on unit coordinates"
    x = (np.float32(vx) * s + eps) * shrink
    y = (np.float32(vy) * s + eps) * shrink
    z = (np.float32(vz) * s + eps) * shrink
    twenty = np.float32(20.0)
    if wave_type == WAVE_BANDS:
        if direction == 0:
            n = x * twenty
        elif direction == 1:
            n = y * twenty
        elif direction == 2:
            n = z * twenty
        else:
            n = (x + y + z) * np.float32(10.0)
    else:
        rx, ry, rz = x, y, z
        if direction == 0:
            rx = np.float32(0.0)
        elif direction == 1:
            ry = np.float32(0.0)
        elif direction == 2:
            rz = np.float32(0.0)
        n = np.float32(math.sqrt(float(rx * rx + ry * ry + rz * rz))) * twenty
    n = n + np.float32(phase)
    d = np.float32(distortion)
    if d != np.float32(0.0):
        ds = np.float32(detail_scale)
        octaves = min(max(float(np.float32(detail)), 0.0), MAX_DETAIL)
        value = fbm(3, x * ds, y * ds, z * ds, np.float32(0.0), octaves, float(np.float32(detail_roughness)),
                    np.float32(2.0), True)
        n = n + d * np.float32(value * 2.0 - 1.0)
    if profile == WAVE_PROFILE_SIN:
        return 0.5 + 0.5 * math.sin(float(n - PI_2_F))
    n = n / TWO_PI_F
    if profile == WAVE_PROFILE_SAW:
        return float(n - np.float32(math.floor(n)))
    return abs(float(n - np.float32(math.floor(n + np.float32(0.5))))) * 2.0
