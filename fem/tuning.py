"""One design length tuned until a frequency hits its target: the 1-D root finding of
:func:`fem.matching.match`.

Bracketing: from the start value the next trial scales the length by ``(f / f_target)^1.5`` (a
quarter-wave section has ``f ~ 1/L``; only part of the resonator is tuned), then secant steps
with 20 % overshoot follow until the target is bracketed; Brent's method finishes inside that
bracket. A trial whose frequency error, over the secant slope of the last two trials (or of the
bracket), puts the root within ``RESIDUAL_FRACTION`` of ``xtol`` ends the search there: every
evaluation is a full eigen solve, and Brent's method would otherwise spend one more to shrink a
bracket that already holds the root far inside the tolerance (the law is smooth and nearly
linear over the last steps, so the secant estimate of the distance is good to ~10 %, and the
criterion keeps a 10x margin on ``xtol``). The search never leaves the user's bracket (:func:`valid_bounds`: default 0.5x-2x the
start value, shrunk to where the design is valid).

The lattice: every trial length is snapped to 10 nm (8 decimals in m, 1000x finer than the
default ``xtol`` of 10 um). The solvers' round-off, which depends on their thread count and BLAS
build, moves a secant step by ~1e-13 m; the lattice absorbs it unless the step lands within that
distance of a rounding boundary (a chance of ~1e-5 per trial), so the tuned design, its mesh and
everything downstream are the same numbers whatever the threads (tests/test_results_pipeline.py).
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from scipy.optimize import brentq

from rpud_common import ParameterError

__all__ = ["GRID_DECIMALS", "CELL", "RESIDUAL_FRACTION", "snap", "valid_bounds", "find_length"]

GRID_DECIMALS = 8                 # lengths in m to 8 decimals: the 10 nm lattice
CELL = 10.0 ** -GRID_DECIMALS     # m, one cell of the lattice
RESIDUAL_FRACTION = 0.1           # a trial this close to the root (in units of xtol, by the secant) ends the search


def snap(value: float) -> float:
    """``value`` (m) on the 10 nm lattice of trial lengths."""
    return round(float(value), GRID_DECIMALS)


def valid_bounds(design, path: str, factors: tuple[float, float]) -> tuple[float, float]:
    """The bracket of a tuned length, m.

    Parameters
    ----------
    design : DesignBase
        The design; ``design.get(path)`` is the start length, m.
    path : str
        The tuned length's path.
    factors : (float, float)
        The user's bracket as factors of the start length.

    Returns
    -------
    (float, float)
        ``factors`` x the start length, shrunk to where the design is valid (checked on a few
        trial values) and onto the lattice, inward, m.
    """
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


def _trial(v: float, towards: float, bounds: tuple[float, float]) -> float:
    """``towards`` clipped to ``bounds`` and snapped, but at least one lattice cell away from
    ``v`` (a secant step below 10 nm would otherwise stall on ``v``) unless ``v`` is the bound."""
    t = snap(np.clip(towards, *bounds))
    if t == v and towards != v:
        t = snap(np.clip(v + math.copysign(CELL, towards - v), *bounds))
    return t


class _Close(Exception):
    """Raised inside Brent's method by a trial close enough to the root (it carries the length)."""

    def __init__(self, value: float):
        super().__init__(value)
        self.value = value


def _close(g: float, slope: float, xtol: float) -> bool:
    """The secant's distance to the root ``|g / slope|`` is within ``RESIDUAL_FRACTION`` of ``xtol``."""
    return g == 0 or (slope != 0 and np.isfinite(slope) and abs(g) <= RESIDUAL_FRACTION * xtol * abs(slope))


def _brent(evaluate, target: float, a: float, ga: float, b: float, gb: float, xtol: float) -> float:
    """Brent's method on the bracket ``[a, b]`` (errors ``ga``, ``gb``), stopped early at a trial
    the bracket's secant puts within ``RESIDUAL_FRACTION`` of ``xtol`` of the root."""
    slope = (gb - ga) / (b - a)

    def g(x):
        gx = evaluate(x) - target
        if _close(gx, slope, xtol):
            raise _Close(snap(x))
        return gx

    try:
        return snap(brentq(g, a, b, xtol=xtol, rtol=4 * np.finfo(float).eps, maxiter=60))
    except _Close as hit:
        return hit.value


def find_length(evaluate: Callable[[float], float], v0: float, target: float,
                bounds: tuple[float, float], xtol: float, path: str, label: str,
                max_steps: int = 200) -> float:
    """The length at which ``evaluate`` meets ``target``: bracketed from ``v0``, then Brent's method.

    Parameters
    ----------
    evaluate : callable
        Frequency (Hz) of the design with the length (m); called with lattice lengths while
        bracketing, and with Brent's own trial points, which it should :func:`snap`.
    v0 : float
        Start length, m.
    target : float
        Target frequency, Hz.
    bounds : (float, float)
        Bracket of the length, m (:func:`valid_bounds`).
    xtol : float
        Length tolerance of Brent's method, m (>= the 10 nm lattice).
    path, label : str
        The length's name and the model's, for the error message.
    max_steps : int
        Bracketing steps before giving up.

    Returns
    -------
    float
        The tuned length on the lattice, m.

    Raises
    ------
    ParameterError
        If the whole bracket passes without crossing the target.
    """
    lo_b, hi_b = bounds
    v0 = snap(v0)
    g0 = evaluate(v0) - target
    if g0 == 0:
        return v0
    # a longer section resonates lower; only part of the resonator is tuned, so scale by
    # (f / f_target)^1.5 rather than ^1, then follow secants (20 % overshoot) until bracketed
    step = float(np.clip(((g0 + target) / target) ** 1.5, 0.77, 1.3))
    v_prev, g_prev = v0, g0
    v = _trial(v0, v0 * step, bounds)
    seen = [(v0, g0 + target)]
    for _ in range(max_steps):
        if v == v_prev:                               # stopped at the end of the bracket
            break
        g = evaluate(v) - target
        seen.append((v, g + target))
        slope = (g - g_prev) / (v - v_prev)
        if _close(g, slope, xtol):
            return v
        if np.sign(g) != np.sign(g_prev):
            (a, ga), (b, gb) = sorted(((v_prev, g_prev), (v, g)))
            return _brent(evaluate, target, a, ga, b, gb, xtol)
        if slope * (v - v_prev) * g < 0:             # the error shrinks: secant, overshoot by 20 %
            v_next = v - 1.2 * g / slope
        else:                                         # no progress: keep going the same way
            v_next = v + (v - v_prev)
        v_next = float(np.clip(v_next, v - 0.3 * abs(v), v + 0.3 * abs(v)))
        v_prev, g_prev = v, g
        v = _trial(v, v_next, bounds)
    fs = [f for _, f in seen]
    raise ParameterError("target_hz", target,
                         f"outside the bracket: {label} spans {min(fs):.1f}-{max(fs):.1f} Hz for {path} in "
                         f"[{lo_b * 1e3:.2f}, {hi_b * 1e3:.2f}] mm")
