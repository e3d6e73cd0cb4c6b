"""Cycles' blackbody colour: the numpy form for the exporter and a scalar kernel for programs.

The fit (linear Rec.709, normalised to luminance ~1, piecewise over temperature) and its tables are
Cycles' (intern/cycles/kernel/tables.h blackbody_table_r/g/b, evaluated as kernel/svm/math_util.h
svm_math_blackbody_color_rec709 does); checked against Cycles 5.0.1 renders at 700..13000 K.
"""
from __future__ import annotations

import numpy as np

from ..jit import stage_kernel

# R, G = a/T + b T + c; B = ((a T + b) T + c) T + d per temperature interval.
_BLACKBODY_BREAKS = np.array([965.0, 1167.0, 1449.0, 1902.0, 3315.0, 6365.0])
_BLACKBODY_R = np.array([
    [1.61919106e+03, -2.05010916e-03, 5.02995757e+00], [2.48845471e+03, -1.11330907e-03, 3.22621544e+00],
    [3.34143193e+03, -4.86551192e-04, 1.76486769e+00], [4.09461742e+03, -1.27446582e-04, 7.25731635e-01],
    [4.67028036e+03, 2.91258199e-05, 1.26703442e-01], [4.59509185e+03, 2.87495649e-05, 1.50345020e-01],
    [3.78717450e+03, 9.35907826e-06, 3.99075871e-01]])
_BLACKBODY_G = np.array([
    [-4.88999748e+02, 6.04330754e-04, -7.55807526e-02], [-7.55994277e+02, 3.16730098e-04, 4.78306139e-01],
    [-1.02363977e+03, 1.20223470e-04, 9.36662319e-01], [-1.26571316e+03, 4.87340896e-06, 1.27054498e+00],
    [-1.42529332e+03, -4.01150431e-05, 1.43972784e+00], [-1.17554822e+03, -2.16378048e-05, 1.30408023e+00],
    [-5.00799571e+02, -4.59832026e-06, 1.09098763e+00]])
_BLACKBODY_B = np.array([
    [5.96945309e-11, -4.85742887e-08, -9.70622247e-05, -4.07936148e-03],
    [2.40430366e-11, 5.55021075e-08, -1.98503712e-04, 2.89312858e-02],
    [-1.40949732e-11, 1.89878968e-07, -3.56632824e-04, 9.10767778e-02],
    [-3.61460868e-11, 2.84822009e-07, -4.93211319e-04, 1.56723440e-01],
    [-1.97075738e-11, 1.75359352e-07, -2.50542825e-04, -2.22783266e-02],
    [-1.61997957e-13, -1.64216008e-08, 3.86216271e-04, -7.38077418e-01],
    [6.72650283e-13, -2.73078809e-08, 4.24098264e-04, -7.52335691e-01]])
_BLACKBODY_HOT = np.array([0.8262954810464208, 0.9945080501520986, 1.566307710274283])   # T >= 12000 K
_BLACKBODY_COLD = np.array([5.413294490189271, -0.20319390035873933, -0.0822535242887164])  # T < 800 K
#: Stefan-Boltzmann constant x 1e-6 / pi, Cycles' scale of the Principled Volume's blackbody.
BLACKBODY_SIGMA = 5.670373e-8 * 1e-6 / np.pi


def blackbody_rec709(temperature) -> np.ndarray:
    """Cycles' blackbody colour (linear Rec.709, Blender 5.0's default scene-linear space) for an
    array of temperatures in kelvin: shape (..., 3). Not clamped: below ~1000 K green and blue are
    slightly negative, as in Cycles (the Principled Volume does not clamp them)."""
    t = np.asarray(temperature, dtype=np.float64)
    i = np.searchsorted(_BLACKBODY_BREAKS, t, side="right")
    safe_t = np.maximum(t, 1.0)
    r, g, b = _BLACKBODY_R[i], _BLACKBODY_G[i], _BLACKBODY_B[i]
    color = np.stack([r[..., 0] / safe_t + r[..., 1] * safe_t + r[..., 2],
                      g[..., 0] / safe_t + g[..., 1] * safe_t + g[..., 2],
                      ((b[..., 0] * safe_t + b[..., 1]) * safe_t + b[..., 2]) * safe_t + b[..., 3]], axis=-1)
    color = np.where((t >= 12000.0)[..., None], _BLACKBODY_HOT, color)
    return np.where((t < 800.0)[..., None], _BLACKBODY_COLD, color)




@stage_kernel
def blackbody_rec709_scalar(t):
    """blackbody_rec709 for one temperature (kelvin): (r, g, b)."""
    if t >= 12000.0:
        return _BLACKBODY_HOT[0], _BLACKBODY_HOT[1], _BLACKBODY_HOT[2]
    if t < 800.0:
        return _BLACKBODY_COLD[0], _BLACKBODY_COLD[1], _BLACKBODY_COLD[2]
    i = 0
    while i < _BLACKBODY_BREAKS.shape[0] and t >= _BLACKBODY_BREAKS[i]:
        i += 1
    r, g, b = _BLACKBODY_R[i], _BLACKBODY_G[i], _BLACKBODY_B[i]
    return (r[0] / t + r[1] * t + r[2], g[0] / t + g[1] * t + g[2],
            ((b[0] * t + b[1]) * t + b[2]) * t + b[3])
