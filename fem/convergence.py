"""Discretisation error of the working mode: mesh-convergence studies and a two-level estimator.

API
---
``study(evaluate, tol=None, start=1.0, ratio=0.8, levels=3, max_levels=6, max_dofs=None)
-> ConvergenceStudy``
    Evaluates ``evaluate(refine) -> Level`` at ``refine = start, start * ratio, start *
    ratio^2, ...`` (every mesh-size rule scaled together, :mod:`geometry.sizing`; the element
    size h is proportional to ``refine``). Without ``tol`` it runs ``levels`` levels; with
    ``tol`` it goes on until every quantity changed by less than ``tol`` (relative) between the
    last two levels, with at least three levels, at most ``max_levels``, and stops early (not
    converged) when the next level's estimated DOFs exceed ``max_dofs``.
``ConvergenceStudy.order(q)``, ``.richardson(q)``, ``.error(q)``, ``.table()``, ``.to_dict()``
    From the last three levels, with the representative element size ``h = DOFs^(-1/3)`` of
    each mesh (an unstructured mesh does not refine exactly by ``refine``; small meshes much
    less): the model ``q(h) = q_inf + C h^p`` through the three points gives the observed order
    ``p`` (solved from ``(q2 - q1) / (q3 - q2) = (h1^p - h2^p) / (h2^p - h3^p)``; with a constant
    ratio r this is ``ln(|q1 - q2| / |q2 - q3|) / ln r``), the Richardson extrapolation ``q_inf``
    and the error estimate ``|q3 - q_inf|`` of the finest level. If the differences change sign
    or the order falls outside ``ORDER_RANGE`` the asymptotic range is not reached: the order is
    reported as NaN and the error falls back to the last change ``|q3 - q2|`` (conservative).
``two_level_error(fine, coarse, ratio, order=ESTIMATOR_ORDER)``
    The cheap estimator: one extra solve on a coarser mesh (``refine`` x 1.4; ``ratio`` =
    h_coarse / h_fine from the DOFs) and an assumed order, ``|q(h) - q(ratio h)| / (ratio^p - 1)``;
    ``estimator_order(grade)`` is the order to assume for a graded or an ungraded mesh.
``working_mode_level(design, refine, ..., grade=False)``
    The evaluator of the RPUD working mode: mesh at ``refine`` (graded toward the re-entrant
    edges with ``grade``), modal analysis near the target
    (f_r, f_a of the working mode), and with ``harmonic=True`` the direct harmonic response at
    the mesh's own resonance (tip amplitude per volt; teeth ellipse ratio if the design has
    teeth), with the pipeline's Q = 100.

Quantities are named as in the JSON of the other modules: ``f_r_hz``, ``f_a_hz``, ``k_eff``,
``tip_per_volt_m``, ``teeth_ellipse_ratio``, ``teeth_phase_deg``, ``teeth_axial_per_volt_m``. The estimates that the CLIs and the pipeline print
beside these values are :mod:`fem.errors`'.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from rpud_common import ParameterError, check_integer, check_range

from .losses import ASSEMBLED_Q_MECH

__all__ = ["Level", "ConvergenceStudy", "study", "two_level_error", "working_mode_level", "estimator_order",
           "ESTIMATOR_ORDER", "ESTIMATOR_ORDER_UNGRADED", "SECTOR_ORDER", "ESTIMATOR_RATIO", "ORDER_RANGE", "QUANTITIES",
           "ANGLES", "harmonic_quantities", "wrapped_difference"]

log = logging.getLogger(__name__)

QUANTITIES = ("f_r_hz", "f_a_hz", "k_eff", "tip_per_volt_m", "teeth_ellipse_ratio", "teeth_phase_deg",
              "teeth_axial_per_volt_m")
"""Quantities of the working mode followed by a study (those a level computed)."""

ANGLES = ("teeth_phase_deg",)
"""Quantities in degrees defined modulo 360: two levels differ by the wrapped difference."""


def harmonic_quantities(wp) -> dict[str, float]:
    """The estimated quantities of a harmonic working point (:class:`fem.harmonic.WorkingPoint`):
    ``tip_per_volt_m`` (m/V) and, where ``teeth_tops`` is among its surfaces, the teeth's
    ``teeth_ellipse_ratio`` (tangential / axial), ``teeth_phase_deg`` (tangential relative to
    axial, degrees) and ``teeth_axial_per_volt_m`` (axial mean amplitude per volt, m/V)."""
    out = {"tip_per_volt_m": float(wp.tip_per_volt_m)}
    teeth = wp.surfaces.get("teeth_tops")
    if teeth is not None:
        out["teeth_ellipse_ratio"] = float(wp.teeth_ellipse_ratio)
        out["teeth_phase_deg"] = float(wp.teeth_phase_deg)
        out["teeth_axial_per_volt_m"] = float(abs(teeth["axial"]) / wp.voltage)
    return out


def wrapped_difference(q: str, a: float, b: float) -> float:
    """``a - b``, wrapped into [-180, 180) degrees for the angles of :data:`ANGLES`."""
    d = float(a) - float(b)
    return (d + 180.0) % 360.0 - 180.0 if q in ANGLES else d

ORDER_RANGE = (0.5, 8.0)
"""Observed orders outside this range mean the levels are not in the asymptotic range."""

ESTIMATOR_ORDER = 2.0
"""Order in h assumed by :func:`two_level_error` on a smooth case or a graded mesh
(``grade=True``), below the orders observed there, so the estimate errs on the large side: 2.5x the three-level Richardson error on a
smooth free-free cylinder (observed order 4.25, tests/test_mesh_grading.py) and ~1.7x the true
error of the article's drill without slots and teeth, graded (refine 1.25 -> 1: 13.1 Hz change,
40 Hz estimate, 23.5 Hz true error against the axisymmetric reference). Not a bound when a mesh
family is pre-asymptotic: see the README's convergence table."""

ESTIMATOR_ORDER_UNGRADED = 1.0
"""Order in h assumed on an ungraded mesh (the default): the re-entrant edges limit the
eigenvalue error to h^1.1 (2 x 0.5445, a 270-degree corner; the axisymmetric (r, z) study,
tests/axisym_reference.py, observed 1.1 with P2 and P3 alike), so order 2 would understate the
error about twofold. Chosen below that rate so the estimate errs on the large side; not validated
by a 3-D study here (the article drill's ungraded levels are pre-asymptotic below ~160k DOFs)."""


def estimator_order(grade: bool, corners: bool = True) -> float:
    """The order :func:`two_level_error` should assume: :data:`ESTIMATOR_ORDER_UNGRADED` on an
    ungraded mesh of a design with major re-entrant edges (``corners``,
    :func:`geometry.sizing.graded_edges` not empty), else :data:`ESTIMATOR_ORDER`."""
    return ESTIMATOR_ORDER if grade or not corners else ESTIMATOR_ORDER_UNGRADED

SECTOR_ORDER = ESTIMATOR_ORDER
"""Order in h assumed by the two-level estimate on the sector path (:mod:`fem.sector_system`):
the sector's section is graded and its notch edges graded (:data:`geometry.sector.AXIAL_RULE`).
The observed orders on the article drill's sector levels (matched lengths, refine 1.4 / 1 / 0.8
and 1 / 0.8 / 0.64, ``h = DOFs^(-1/3)``) are 2.6 and 3.5 (f_r), 2.6 and 3.6 (f_a), 1.8 and 3.7
(tip amplitude per volt), 2.3 and 3.3 (teeth ellipse ratio): 2 lies below all but the tip's
coarsest triple, so the estimate errs on the large side (the 1.4 / 1 / 0.8 triple's lower orders
come partly from the sector's element layers, 3 at refine 1.4 and 1 and 4 at 0.8: the layers' gain
falls on its last step only; the two-level estimate, both levels at 3 layers, does not see it and
covers it through the order-2 margin on the coupler's part, docs/theory/piezo-elastic.md) (f_r at refine 1: 6.8 Hz stated, 4.0 Hz
from the extrapolation of the finest three; teeth ellipse ratio 0.010 stated, 0.0064 to the
extrapolation plus 0.0019 its own step). The teeth's phase takes :data:`SECTOR_PHASE_ORDER`."""

SECTOR_PHASE_ORDER = 1.0
"""Order in h assumed for the teeth's phase (``teeth_phase_deg``) by the two-level estimate on the
sector path. The phase's level-to-level changes do not fall steadily (article drill's sector,
refine 1.4 / 1 / 0.8 / 0.64: -0.073, -0.093, -0.038 degrees; no order from the first three), and
part of its error, the sector's element layers (-0.12 degrees from 3 to 6 layers at refine 1),
does not change between the estimate's two levels (3 layers at refine 1 and 1.4). Order 1, the
rate of the singular notch edges under uniform refinement (h^1.1) and below every observed one,
states 0.35 degrees at refine 1 against at most 0.19 from the four levels' extrapolation
(tests/test_discretisation_error.py); order 2 would state 0.16 and miss it."""

QUANTITY_ORDERS = {"sector": {"teeth_phase_deg": SECTOR_PHASE_ORDER}}
"""Per path, the quantities whose assumed order differs from the path's (:data:`SECTOR_ORDER`)."""

ESTIMATOR_RATIO = 1.4
"""Refine factor of the extra, coarser solve of the two-level estimator (~1/2.4 of the DOFs on the article's drill)."""


@dataclass(frozen=True)
class Level:
    """One mesh of a study: its refine factor, DOFs, the computed quantities and the time (s)."""

    refine: float
    ndof: int
    values: dict[str, float]
    seconds: float = 0.0
    extra: dict = field(default_factory=dict, compare=False)


@dataclass(frozen=True)
class ConvergenceStudy:
    """Levels of a refinement study (coarse to fine) and what they say about the error."""

    levels: tuple[Level, ...]
    tol: float | None = None
    stopped: str = ""

    @property
    def quantities(self) -> tuple[str, ...]:
        return tuple(q for q in self.levels[0].values if all(np.isfinite(l.values.get(q, np.nan))
                                                              for l in self.levels))

    @property
    def ratio(self) -> float:
        """Ratio of the representative sizes h = DOFs^(-1/3) of the last two levels (> 1)."""
        return (self.levels[-1].ndof / self.levels[-2].ndof) ** (1 / 3)

    def _h3(self) -> tuple[float, float, float]:
        return tuple(float(l.ndof) ** (-1 / 3) for l in self.levels[-3:])  # type: ignore[return-value]

    def _fit(self, q: str) -> tuple[float, float]:
        """(p, C) of q(h) = q_inf + C h^p through the last three levels; (NaN, NaN) if none."""
        from scipy.optimize import brentq

        q1, q2, q3 = self._last3(q)
        h1, h2, h3 = self._h3()
        d1, d2 = q2 - q1, q3 - q2
        if d1 == 0 or d2 == 0 or np.sign(d1) != np.sign(d2) or not h1 > h2 > h3:
            return float("nan"), float("nan")
        target = d1 / d2

        def g(p):
            return (h1 ** p - h2 ** p) / (h2 ** p - h3 ** p) - target
        lo, hi = ORDER_RANGE
        if g(lo) * g(hi) > 0:
            return float("nan"), float("nan")
        p = brentq(g, lo, hi, xtol=1e-10)
        return p, d2 / (h3 ** p - h2 ** p)

    def _last3(self, q: str) -> tuple[float, float, float]:
        if len(self.levels) < 3:
            raise ParameterError("levels", len(self.levels), "needs three levels for an order")
        return tuple(float(l.values[q]) for l in self.levels[-3:])  # type: ignore[return-value]

    def change(self, q: str) -> float:
        """Relative change of ``q`` between the last two levels."""
        a, b = (float(l.values[q]) for l in self.levels[-2:])
        return abs(b - a) / max(abs(b), 1e-300)

    @property
    def converged(self) -> bool:
        """Every quantity changed by less than ``tol`` between the last two levels (3+ levels)."""
        return (self.tol is not None and len(self.levels) >= 3
                and all(self.change(q) < self.tol for q in self.quantities))

    def order(self, q: str) -> float:
        """Observed order in h from the last three levels (NaN outside the asymptotic range)."""
        return self._fit(q)[0]

    def richardson(self, q: str) -> float:
        """Richardson extrapolation of ``q`` to h -> 0 (the finest value if no order)."""
        q3 = self._last3(q)[2]
        p, C = self._fit(q)
        if not np.isfinite(p):
            return q3
        return q3 - C * self._h3()[2] ** p

    def error(self, q: str) -> float:
        """Estimated discretisation error of the finest level's ``q`` (same units)."""
        _q1, q2, q3 = self._last3(q)
        if not np.isfinite(self.order(q)):
            return abs(q3 - q2)
        return abs(self.richardson(q) - q3)

    def to_dict(self) -> dict:
        out = {"ratio": self.ratio if len(self.levels) > 1 else None, "tol": self.tol,
               "converged": self.converged if self.tol is not None else None, "stopped": self.stopped,
               "levels": [{"refine": l.refine, "ndof": l.ndof, "seconds": l.seconds, **l.values}
                          for l in self.levels]}
        if len(self.levels) >= 3:
            out["estimate"] = {q: {"order": _none(self.order(q)), "richardson": self.richardson(q),
                                   "error": self.error(q), "change": self.change(q)} for q in self.quantities}
        return out

    def table(self) -> str:
        """Plain-text table: one row per level, then order / Richardson / error per quantity."""
        qs = self.quantities
        fmt = {"f_r_hz": ("f_r Hz", 1.0, "{:.2f}"), "f_a_hz": ("f_a Hz", 1.0, "{:.2f}"), "k_eff": ("k_eff", 1.0, "{:.5f}"),
               "tip_per_volt_m": ("tip um/V", 1e6, "{:.5f}"), "teeth_ellipse_ratio": ("ellipse", 1.0, "{:.5f}"),
               "teeth_phase_deg": ("phase deg", 1.0, "{:.3f}"), "teeth_axial_per_volt_m": ("teeth um/V", 1e6, "{:.5f}")}
        head = f"{'refine':>7} {'DOFs':>8} " + " ".join(f"{fmt.get(q, (q, 1.0, ''))[0]:>12}" for q in qs) + f" {'time s':>7}"
        lines = [head]
        for l in self.levels:
            lines.append(f"{l.refine:7.3f} {l.ndof:8d} " + " ".join(
                f"{fmt.get(q, (q, 1.0, '{:.6g}'))[2].format(l.values[q] * fmt.get(q, (q, 1.0))[1]):>12}" for q in qs)
                + f" {l.seconds:7.1f}")
        if len(self.levels) >= 3:
            lines.append(f"{'order p':>16} " + " ".join(f"{self.order(q):12.2f}" for q in qs))
            lines.append(f"{'Richardson':>16} " + " ".join(
                f"{fmt.get(q, (q, 1.0, '{:.6g}'))[2].format(self.richardson(q) * fmt.get(q, (q, 1.0))[1]):>12}"
                for q in qs))
            lines.append(f"{'error %':>16} " + " ".join(
                f"{100 * self.error(q) / abs(self.levels[-1].values[q]):12.4f}" for q in qs))
        if self.tol is not None:
            lines.append(f"tolerance {self.tol:g}: {'converged' if self.converged else 'NOT converged'}"
                         + (f" ({self.stopped})" if self.stopped else ""))
        return "\n".join(lines)


def _none(x: float):
    return float(x) if np.isfinite(x) else None


def study(evaluate: Callable[[float], Level], tol: float | None = None, start: float = 1.0, ratio: float = 0.8,
          levels: int = 3, max_levels: int = 6, estimate_dofs: Callable[[float], int] | None = None,
          max_dofs: int | None = None) -> ConvergenceStudy:
    """Run a refinement study (see the module docstring).

    Parameters
    ----------
    evaluate : callable
        ``evaluate(refine) -> Level``.
    tol : float, optional
        Relative change between the last two levels below which every quantity is converged.
    start, ratio : float
        First refine factor and the factor between levels (< 1: each level finer).
    levels, max_levels : int
        Levels without ``tol``; the most levels with it.
    estimate_dofs, max_dofs : optional
        ``estimate_dofs(refine)`` predicts a level's DOFs; a level above ``max_dofs`` is not run.
    """
    check_range("ratio", ratio, 0.3, 0.95)
    check_integer("levels", levels, 3, 12)
    check_integer("max_levels", max_levels, 3, 12)
    if tol is not None:
        check_range("tol", tol, 1e-7, 0.1)
    out: list[Level] = []
    n = levels if tol is None else max_levels
    stopped = ""
    for k in range(n):
        refine = start * ratio ** k
        if estimate_dofs is not None and max_dofs is not None and estimate_dofs(refine) > max_dofs:
            stopped = f"next level refine {refine:.3g} would exceed {max_dofs:,} DOFs"
            break
        t0 = time.perf_counter()
        lev = evaluate(refine)
        if not lev.seconds:
            lev = Level(lev.refine, lev.ndof, lev.values, time.perf_counter() - t0)
        out.append(lev)
        log.info("level refine %.3f: %d DOFs, %s", refine, lev.ndof, lev.values)
        s = ConvergenceStudy(tuple(out), tol)
        if tol is not None and s.converged:
            break
    else:
        if tol is not None:
            stopped = f"{n} levels"
    if len(out) < 3:
        raise ParameterError("max_dofs", max_dofs, f"allows only {len(out)} level(s); a study needs three")
    return ConvergenceStudy(tuple(out), tol, "" if ConvergenceStudy(tuple(out), tol).converged else stopped)


def two_level_error(fine: float, coarse: float, ratio: float = ESTIMATOR_RATIO,
                    order: float = ESTIMATOR_ORDER) -> float:
    """Discretisation error of ``fine`` from one coarser value (``ratio`` = h_coarse / h_fine > 1).

    ``|fine - coarse| / (ratio^order - 1)``: the Richardson error for a known order.
    """
    if not ratio > 1:
        raise ParameterError("ratio", ratio, "must be > 1 (the coarse mesh is coarser)")
    return abs(fine - coarse) / (ratio ** order - 1)


def working_mode_level(design, refine: float, *, mesh_size: float | None = None, order: int = 2,
                       near_hz: float | None = None, n_modes: int = 8, harmonic: bool = True,
                       q_mech: float | None = ASSEMBLED_Q_MECH, grade: bool = False, loss=None,
                       surfaces: tuple[str, ...] | None = None, select: Callable | None = None,
                       harmonic_method: str = "direct", mesher: str = "free", path: str = "whole",
                       extra: Callable | None = None) -> Level:
    """Mesh ``design`` at ``refine`` (graded with ``grade``, by ``mesher``: see
    :func:`geometry.builder.build`) and compute the working mode's
    quantities (one Level): ``f_r_hz``, ``f_a_hz``, ``k_eff``; with ``harmonic`` the direct
    response at the mesh's own f_r (``loss``, default ``LossModel(q_mech=q_mech)``) on
    ``surfaces`` (default ``horn_tip`` and ``teeth_tops`` where present; the first is the tip):
    ``tip_per_volt_m``, ``teeth_ellipse_ratio``; without it the teeth ellipse ratio of the mode
    shape (as the resonance matching reports it). ``select(modal, near_hz) -> index`` picks the
    mode (default :func:`fem.modal.working_mode`, the largest axial share). ``harmonic_method``
    ``"modal"`` solves the harmonic response on these modes + residual (:func:`fem.harmonic.modal_basis`,
    as the pipeline and ``python -m fem.harmonic`` do; 1.7x cheaper, within 2e-6 of direct here).
    ``path``: ``"whole"`` (the whole drill by ``mesher``) or ``"sector"`` (the ``k = 0`` swept sector
    of :func:`fem.sector_system.axial_sector` at ``refine``; ``mesher`` is not used). ``extra(system,
    wp) -> dict``: more outputs of this mesh's working point (at 1 V), kept in :attr:`Level.extra`
    (e.g. the coarse utilisation table of :mod:`fem.stress_converged`); called only with ``harmonic``."""
    import geometry

    from .assembly import assemble
    from .modal import modal_analysis, working_mode

    t0 = time.perf_counter()
    near = float(near_hz if near_hz is not None else getattr(design, "target_frequency", 20e3))
    if path == "sector":
        from .sector_system import axial_sector

        system = axial_sector(design, refine=refine, grade=grade, mesh_size=mesh_size)
        mesh = system.mesh
    else:
        mesh = geometry.build_mesh(design, mesh_size=mesh_size, order=order, refine=refine, grade=grade,
                                   mesher=mesher)
        system = assemble(mesh, order=order)
    res = modal_analysis(system, near, n_modes)
    w = select(res, near) if select is not None else working_mode(system, res.f_r_hz, res.vectors, near)
    values = {"f_r_hz": float(res.f_r_hz[w]), "f_a_hz": float(res.f_a_hz[w]), "k_eff": float(res.k_eff[w])}
    if surfaces is None:
        surfaces = tuple(s for s in ("horn_tip", "teeth_tops") if s in mesh.facet_sets)
    more = {}
    if harmonic:
        from .harmonic import LossModel, working_point

        if surfaces:
            loss = LossModel(q_mech=q_mech) if loss is None else loss
            basis = None
            if harmonic_method == "modal":
                from .harmonic import modal_basis

                basis = modal_basis(system, values["f_r_hz"], loss=loss, modes=res)
            wp = working_point(system, values["f_r_hz"], 1.0, surfaces=surfaces, loss=loss, basis=basis)
            values.update(harmonic_quantities(wp))
            if extra is not None:
                more = dict(extra(system, wp))
    elif "teeth_tops" in mesh.facet_sets:
        from .modeshape import surface_motion

        values["teeth_ellipse_ratio"] = float(surface_motion(system, res.shapes[w], "teeth_tops")["ellipse_ratio"])
    return Level(float(refine), int(system.ndof), values, time.perf_counter() - t0, more)
