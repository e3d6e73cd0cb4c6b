"""Multiple importance sampling weights in scalar form for the compiled kernels."""
from __future__ import annotations

from .jit import kernel


@kernel
def power_heuristic(a, b):
    """Veach 1997 power heuristic (beta = 2) for pdfs a (the technique used) and b; Cycles
    kernel/sample/mis.h power_heuristic."""
    a2 = a * a
    s = a2 + b * b
    return a2 / s if s > 0.0 else 0.0


@kernel
def mis_weight(prev_pdf, light_pdf):
    """Weight of emission found by BSDF/phase sampling with pdf prev_pdf against light sampling;
    prev_pdf == 0 marks camera rays and delta scattering (no light-sampling alternative)."""
    return power_heuristic(prev_pdf, light_pdf) if prev_pdf > 0.0 else 1.0
