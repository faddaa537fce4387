"""One design length tuned until a frequency hits its target: the 1-D root finding of
:func:`fem.matching.match`.

Bracketing: from the start value the next trial scales the length by ``(f / f_target)^1.5`` (a
quarter-wave section has ``f ~ 1/L``; only part of the resonator is tuned), then secant steps
with 20 % overshoot follow until the target is bracketed; Brent's method finishes inside that
bracket. The search never leaves the user's bracket (:func:`valid_bounds`: default 0.5x-2x the
start value, shrunk to where the design is valid).

The lattice: every trial length is snapped to 10 nm (8 decimals in m, 1000x finer than the
default ``xtol`` of 10 um). The solvers' round-off, which depends on their thread count and BLAS
build, moves a secant step by ~1e-13 m; the lattice absorbs it, so the tuned design, its mesh and
everything downstream are the same numbers whatever the threads (tests/test_results_pipeline.py).
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from scipy.optimize import brentq

from rpud_common import ParameterError

__all__ = ["GRID_DECIMALS", "snap", "valid_bounds", "find_length"]

GRID_DECIMALS = 8                 # lengths in m to 8 decimals: the 10 nm lattice


def snap(value: float) -> float:
    """``value`` (m) on the 10 nm lattice of trial lengths."""
    return round(float(value), GRID_DECIMALS)


def valid_bounds(design, path: str, factors: tuple[float, float]) -> tuple[float, float]:
    """The user's bracket ``factors`` x the start value of ``path`` (m), shrunk to where the
    design is valid (checked on a few trial values) and onto the lattice, inward."""
    v0 = float(design.get(path))
    lo, hi = v0 * factors[0], v0 * factors[1]

    def valid(v):
        try:
            design.replace({path: v})
            return True
        except ParameterError:
            return False

    for _ in range(40):
        if valid(lo):
            break
        lo = 0.5 * (lo + v0)
    for _ in range(40):
        if valid(hi):
            break
        hi = 0.5 * (hi + v0)
    # inward, so that a trial clipped to a bound snaps onto itself, never outside
    scale = 10.0 ** GRID_DECIMALS
    return snap(math.ceil(lo * scale) / scale), snap(math.floor(hi * scale) / scale)


def find_length(evaluate: Callable[[float], float], v0: float, target: float,
                bounds: tuple[float, float], xtol: float, path: str, label: str) -> float:
    """The length (m, on the lattice) at which ``evaluate`` (Hz; it snaps its argument) meets
    ``target`` (Hz): bracketed from ``v0`` inside ``bounds``, then Brent's method to ``xtol`` (m).

    Raises
    ------
    ParameterError
        If the whole bracket passes without crossing the target (``label`` names the model,
        ``path`` the length in the message).
    """
    lo_b, hi_b = bounds
    g0 = evaluate(v0) - target
    if g0 == 0:
        return snap(v0)
    # a longer section resonates lower; only part of the resonator is tuned, so scale by
    # (f / f_target)^1.5 rather than ^1, then follow secants (20 % overshoot) until bracketed
    step = float(np.clip(((g0 + target) / target) ** 1.5, 0.77, 1.3))
    v_prev, g_prev = v0, g0
    v = float(np.clip(v0 * step, lo_b, hi_b))
    seen = [(v0, g0 + target)]
    while v != v_prev:
        g = evaluate(v) - target
        seen.append((v, g + target))
        if np.sign(g) != np.sign(g_prev):
            a, b = sorted((v_prev, v))
            return snap(brentq(lambda x: evaluate(x) - target, a, b, xtol=xtol,
                               rtol=4 * np.finfo(float).eps, maxiter=60))
        slope = (g - g_prev) / (v - v_prev)
        if slope * (v - v_prev) * g < 0:             # the error shrinks: secant, overshoot by 20 %
            v_next = v - 1.2 * g / slope
        else:                                         # no progress: keep going the same way
            v_next = v + (v - v_prev)
        v_next = float(np.clip(v_next, v - 0.3 * abs(v), v + 0.3 * abs(v)))
        v_prev, g_prev = v, g
        v = float(np.clip(v_next, lo_b, hi_b))
    fs = [f for _, f in seen]
    raise ParameterError("target_hz", target,
                         f"outside the bracket: {label} spans {min(fs):.1f}-{max(fs):.1f} Hz for {path} in "
                         f"[{lo_b * 1e3:.2f}, {hi_b * 1e3:.2f}] mm")
