"""Estimated discretisation error of the working mode's outputs, the one convention every CLI,
JSON and report uses.

What is estimated
-----------------
``f_r_hz``, ``f_a_hz``, ``k_eff`` (modal), ``tip_per_volt_m`` (horn-tip axial amplitude per volt
at the mode's own f_r), and the teeth's motion: ``teeth_ellipse_ratio`` (tangential / axial),
``teeth_phase_deg`` (phase of the tangential relative to the axial motion, compared modulo 360)
and ``teeth_axial_per_volt_m``: the quantities of :data:`QUANTITIES`
(:func:`harmonic_quantities` reads the harmonic ones off a working point). The amplitudes derived from the tip amplitude per volt (the tip amplitude at
the drive voltage, the pipeline's A0 with or without the impact load) carry its relative error
(:meth:`ErrorEstimate.scaled`): the FE model enters them only through that factor.

How (the cheap estimator)
-------------------------
One extra solve of the same design on a mesh ``ESTIMATOR_RATIO`` = 1.4 times coarser (every
size rule scaled, :mod:`geometry.sizing`; about 1/2.4 of the DOFs and 1/4 of the time): modal
analysis (f_r, f_a, k_eff) and the harmonic response at the coarse mesh's own f_r on its modes +
residual (:func:`fem.harmonic.modal_basis`, the method of the pipeline's and ``python -m
fem.harmonic``'s fine values; within 2e-6 of a direct solve), and
:func:`fem.convergence.two_level_error`: ``|q(h) - q(r h)| / (r^p - 1)`` with ``r`` the ratio
of the representative element sizes ``h = DOFs^(-1/3)`` and an assumed order ``p``
(:func:`fem.convergence.estimator_order`: 1 on an ungraded mesh of a design with re-entrant
edges, whose 270-degree corners limit the rate to h^1.1; 2 graded or without such edges; both
below the observed rates, so the estimate errs on the large side). Validated against exact
answers in ``tests/test_discretisation_error.py`` for f_r, f_a, k_eff and the tip amplitude
(between 1x and 5x the true error, measured 1.21x-2.4x). The teeth's motion has no exact
reference; on the article drill's ``k = 0`` sector (the default path) its estimate is checked
against the refinement studies of two mesh families in the same test file (finest levels 267k and
282k DOFs, limits 0.17909 and 0.17905): ellipse ratio 0.173 ± 0.010 against at most 0.0084
admitted by the studies (both estimate levels have the same 3 element layers across the sector, so
the layers' part of the error is covered by the order-2 margin, not seen; docs/theory/piezo-elastic.md); the phase, whose level-to-level changes do not fall
steadily, assumes order 1 (:data:`fem.convergence.QUANTITY_ORDERS`): ± 0.35 degrees against at
most 0.19. The pipeline reports the teeth's motion from a sector one level finer
(:mod:`results.stage_teeth`, :func:`teeth_estimate` with the run's mesh the coarse level): on the studies' design 0.1756 ±
0.0066 (3.8 %) against at most 0.0055 admitted by the studies. The same
command gives the same estimate: the meshes are bit-identical (``geometry.builder``) and the
solvers deterministic (MKL's reproducible mode); the coarse values are kept to 2 significant
digits of their difference from the fine ones and the errors to 2 significant digits (an
estimate has no more).

A refinement study (``--converge TOL``, :func:`fem.convergence.study`) gives the observed order
and a Richardson estimate instead; ``benchmarks/study_discretisation_error.py`` compares the two
on the article's drill.

Output convention
-----------------
JSON: every value ``X`` that has an estimate gets ``X_error`` in the same object, same units
(``f_r_hz`` -> ``f_r_hz_error``, ``tip_per_volt_m`` -> ``tip_per_volt_m_error``), and the
record gets one ``discretisation_error`` block (:meth:`ErrorEstimate.to_dict`: method, order,
h ratio, both meshes, the coarse values, the errors). Text: ``f_r 19 997 ± 90 Hz``
(:func:`plus_minus`, the error to 2 significant digits, the value to the error's last digit).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Callable

from rpud_common import ParameterError, check_range
from rpud_common.formatting import plus_minus

from .convergence import QUANTITIES as CONVERGENCE_QUANTITIES
from .convergence import (ESTIMATOR_RATIO, QUANTITY_ORDERS, SECTOR_ORDER, Level, estimator_order, harmonic_quantities,
                          two_level_error, wrapped_difference)
from .losses import ASSEMBLED_Q_MECH

__all__ = ["QUANTITIES", "ErrorEstimate", "estimate", "coarse_level", "estimate_from_levels", "has_reentrant_edges",
           "teeth_estimate", "sector_layers",
           "plus_minus", "annotate", "ESTIMATOR_RATIO", "harmonic_quantities"]

QUANTITIES = CONVERGENCE_QUANTITIES
"""Quantities with an estimated discretisation error (the keys of the JSON of every module;
the teeth's phase and axial amplitude per volt feed the rotary unit's error box)."""

ERROR_DIGITS = 2
"""Significant digits of an error estimate (all it means; also what makes it reproducible)."""

DIFFERENCE_DIGITS = 2
"""Significant digits kept of a coarse value's difference from the fine value (what the error
is computed from: an error estimate means no more than that, and it makes the estimate
reproducible, see the module docstring)."""


def _round_sig(x: float, digits: int) -> float:
    if x == 0 or not math.isfinite(x):
        return float(x)
    return float(f"{x:.{digits - 1}e}")


@dataclass(frozen=True)
class ErrorEstimate:
    """Two-level discretisation-error estimate of the working mode (SI units, absolute errors).

    Attributes
    ----------
    errors : quantity -> estimated error of the fine value (same units as the value)
    values, coarse : quantity -> value on the fine and on the coarse mesh
    ndof, coarse_ndof : DOFs of both meshes
    refine, coarse_refine : their refine factors
    ratio : h_coarse / h_fine from the DOFs, ``(ndof / coarse_ndof)^(1/3)``
    order : assumed order in h
    grade, corners : graded mesh; the design has major re-entrant edges
    seconds : time of the coarse solve, s
    extra : more outputs of the coarse mesh (:attr:`fem.convergence.Level.extra`), e.g. its
        utilisation table under ``"stress"``
    orders : quantity -> its own assumed order where it is not ``order``
    """

    errors: dict
    values: dict
    coarse: dict
    ndof: int
    coarse_ndof: int
    refine: float
    coarse_refine: float
    ratio: float
    order: float
    grade: bool
    corners: bool
    seconds: float = field(default=0.0, compare=False)
    extra: dict = field(default_factory=dict, compare=False)
    orders: dict = field(default_factory=dict)

    def error(self, q: str) -> float:
        """Estimated error of ``q`` (NaN if not estimated)."""
        return float(self.errors.get(q, math.nan))

    def relative(self, q: str) -> float:
        """Estimated error of ``q`` relative to its fine value (NaN if not estimated)."""
        v = self.values.get(q)
        return self.error(q) / abs(v) if v else math.nan

    def scaled(self, q: str, value: float) -> float:
        """Error of a ``value`` proportional to ``q`` (e.g. an amplitude at some voltage and load
        from ``tip_per_volt_m``): ``value`` x the relative error of ``q``."""
        return abs(value) * self.relative(q)

    @property
    def method(self) -> str:
        return (f"two-level: refine {self.refine:g} ({self.ndof} DOFs) and {self.coarse_refine:g} "
                f"({self.coarse_ndof} DOFs), h ratio {self.ratio:.3f}, "
                f"{'graded' if self.grade else 'ungraded'}, "
                f"{'re-entrant edges' if self.corners else 'no re-entrant edges'}, order {self.order:g} assumed"
                + "".join(f" ({q}: order {p:g})" for q, p in sorted(self.orders.items()))
                + ": |q(h) - q(r h)| / (r^p - 1)")

    def to_dict(self) -> dict:
        """The ``discretisation_error`` block of the JSON records (NaN as None)."""
        def clean(d):
            return {k: (float(v) if math.isfinite(v) else None) for k, v in d.items()}

        return {"method": self.method, "order": self.order, "ratio": self.ratio, "refine": self.refine,
                "coarse_refine": self.coarse_refine, "ndof": self.ndof, "coarse_ndof": self.coarse_ndof,
                "grade": self.grade, "reentrant_edges": self.corners, "seconds": self.seconds,
                "errors": clean(self.errors), "coarse": clean(self.coarse)}


def has_reentrant_edges(design, mesh_size: float | None = None, refine: float = 1.0) -> bool:
    """The design has major re-entrant circular edges or a narrowing bore's edge
    (:func:`geometry.sizing.graded_edges` with the swept rule, which lists both whatever the free
    mesh grades): a filleted corner is not one, but the stack's bore edge on the flange face
    (a bonded bimaterial re-entrant edge) stays singular and lowers the order."""
    from geometry.sizing import graded_edges, region_sizes

    try:
        return bool(graded_edges(design, region_sizes(design, mesh_size, refine=refine), refine, revolve=True))
    except (AttributeError, TypeError):          # a design kind without graded edges (a stack)
        return False


def estimate_from_levels(fine: Level, coarse: Level, *, grade: bool, corners: bool,
                         order: float | None = None, orders: dict[str, float] | None = None) -> ErrorEstimate:
    """The two-level estimate from two computed levels (the fine one the reported values);
    ``orders``: quantities whose assumed order is not ``order`` (e.g.
    :data:`fem.convergence.QUANTITY_ORDERS`), named in :attr:`ErrorEstimate.method`."""
    if not coarse.ndof < fine.ndof:
        raise ParameterError("coarse", coarse.ndof, f"must have fewer DOFs than the fine mesh ({fine.ndof})")
    ratio = (fine.ndof / coarse.ndof) ** (1 / 3)
    p = estimator_order(grade, corners) if order is None else float(order)
    # the coarse value enters through its difference from the fine one, kept to DIFFERENCE_DIGITS,
    # and the error to ERROR_DIGITS: an estimate has no more digits
    near = {q: (float(fine.values[q]) + _round_sig(wrapped_difference(q, v, fine.values[q]), DIFFERENCE_DIGITS)
                if q in fine.values and math.isfinite(fine.values[q]) and math.isfinite(v) else float(v))
            for q, v in coarse.values.items()}
    orders = dict(orders or {})
    errors = {q: _round_sig(two_level_error(fine.values[q], near[q], ratio, orders.get(q, p)), ERROR_DIGITS)
              for q in QUANTITIES if q in fine.values and q in near
              and math.isfinite(fine.values[q]) and math.isfinite(near[q])}
    return ErrorEstimate(errors, {q: float(v) for q, v in fine.values.items()}, near, int(fine.ndof), int(coarse.ndof),
                         float(fine.refine), float(coarse.refine), float(ratio), p, bool(grade), bool(corners),
                         coarse.seconds, orders={q: float(v) for q, v in orders.items() if q in errors})


def coarse_level(design, *, refine: float = 1.0, mesh_size: float | None = None, grade: bool = False,
                 order: int = 2, near_hz: float | None = None, harmonic: bool = True, loss=None,
                 q_mech: float | None = ASSEMBLED_Q_MECH, surfaces: tuple[str, ...] | None = None, n_modes: int = 4,
                 select: Callable | None = None, mesher: str = "free", path: str = "whole",
                 extra: Callable | None = None) -> Level:
    """The coarse level of :func:`estimate` (the fine mesh's ``refine`` x :data:`ESTIMATOR_RATIO`),
    its ``seconds`` the whole solve's; the arguments are :func:`estimate`'s."""
    from .convergence import working_mode_level

    check_range("refine", refine * ESTIMATOR_RATIO, 0.2, 5.0)
    t0 = time.perf_counter()
    lev = working_mode_level(design, refine * ESTIMATOR_RATIO, mesh_size=mesh_size, order=order, near_hz=near_hz,
                             n_modes=n_modes, harmonic=harmonic, q_mech=q_mech, grade=grade, loss=loss,
                             surfaces=surfaces, select=select, harmonic_method="modal", mesher=mesher, path=path,
                             extra=extra)
    return dataclasses.replace(lev, seconds=time.perf_counter() - t0)


def estimate(design, values: dict, ndof: int, *, refine: float = 1.0, mesh_size: float | None = None,
             grade: bool = False, order: int = 2, near_hz: float | None = None, harmonic: bool = True,
             loss=None, q_mech: float | None = ASSEMBLED_Q_MECH, surfaces: tuple[str, ...] | None = None, n_modes: int = 4,
             select: Callable | None = None, mesher: str = "free", path: str = "whole",
             extra: Callable | None = None, coarse: "Level | None" = None) -> ErrorEstimate:
    """Estimate the discretisation error of ``values`` (computed on ``design`` meshed at ``refine``
    with ``ndof`` DOFs) from one solve at ``refine`` x :data:`ESTIMATOR_RATIO`.

    Parameters
    ----------
    design : the design the values belong to (the tuned one after matching)
    values : quantity -> fine value (keys of :data:`QUANTITIES`; others are ignored)
    ndof : DOFs of the fine system
    refine, mesh_size, grade, order, mesher : how the fine mesh was built (the coarse one scales
        ``refine``; a swept mesh's section is graded: the order of a graded mesh is assumed)
    near_hz : target frequency of the modal search (default: the design's)
    harmonic : compute the coarse tip amplitude per volt and ellipse ratio from the harmonic
        response (modal basis + residual) at the coarse f_r (``loss``, default ``LossModel(q_mech=q_mech)``, on ``surfaces``);
        else only the modal values and the mode shape's ellipse ratio
    n_modes : modes of the coarse modal solve
    select : ``select(modal, near_hz) -> index`` picks the coarse mode as the fine one was picked
        (default :func:`fem.modal.working_mode`)
    path : ``"whole"`` or ``"sector"`` (:mod:`fem.sector_system`): the path the fine values ran on,
        the coarse solve runs on the same
    extra : ``extra(system, wp) -> dict``, more outputs of the coarse mesh's working point (1 V),
        kept in :attr:`ErrorEstimate.extra` (:func:`fem.convergence.working_mode_level`)
    coarse : the coarse level already computed by :func:`coarse_level` with the same arguments
        (so a caller can solve it beside the fine one); None computes it here
    """
    lev = coarse if coarse is not None else coarse_level(
        design, refine=refine, mesh_size=mesh_size, grade=grade, order=order, near_hz=near_hz, harmonic=harmonic,
        loss=loss, q_mech=q_mech, surfaces=surfaces, n_modes=n_modes, select=select, mesher=mesher, path=path,
        extra=extra)
    fine = Level(float(refine), int(ndof), {q: float(v) for q, v in values.items() if q in QUANTITIES})
    from geometry.revolve import resolve_mesher

    graded = grade or path == "sector" or resolve_mesher(design, mesher) == "revolve"
    est = estimate_from_levels(fine, lev, grade=graded, corners=has_reentrant_edges(design, mesh_size, refine),
                               order=SECTOR_ORDER if path == "sector" else None, orders=QUANTITY_ORDERS.get(path))
    return dataclasses.replace(est, extra=lev.extra)


def sector_layers(design, refine: float) -> int:
    """Element layers across the ``k = 0`` sector of ``design`` at ``refine``
    (:data:`geometry.sector.AXIAL_RULE`'s layer angle scaled by ``refine``, as the sweep lays them)."""
    from geometry.sector import AXIAL_RULE, symmetry_order

    sectors = symmetry_order(design) or 6
    return max(1, math.ceil(360.0 / sectors / AXIAL_RULE[1].scaled(refine).layer_deg - 1e-9))


def teeth_estimate(design, fine: Level, coarse: Level, *, mesh_size: float | None = None) -> ErrorEstimate:
    """Two-level estimate of the teeth motion (``teeth_*`` of :data:`QUANTITIES`) between two
    ``k = 0`` sector meshes of ``design`` (the pipeline's finer teeth mesh and its own,
    :mod:`results.stage_teeth`), at :data:`fem.convergence.SECTOR_ORDER` for every quantity when
    the two meshes have different element layers across the sector (every size refined, as in
    the studies' consistent triples: observed orders 3.3 for the ellipse ratio and 4.8 for the
    phase on refine 1 / 0.8 / 0.64), the phase at :data:`fem.convergence.SECTOR_PHASE_ORDER`
    when the layers are the same (the pair does not see their error then). Validated on the
    default design (refine 1 -> 0.8) against the two mesh families' limit in
    tests/test_discretisation_error.py."""
    same_layers = sector_layers(design, fine.refine) == sector_layers(design, coarse.refine)
    orders = QUANTITY_ORDERS.get("sector", {}) if same_layers else {}
    return estimate_from_levels(fine, coarse, grade=True, corners=has_reentrant_edges(design, mesh_size, fine.refine),
                                order=SECTOR_ORDER, orders=orders)


def annotate(record: dict, est: ErrorEstimate | None, keys: dict[str, str]) -> dict:
    """Add ``X_error`` beside each value ``X`` of ``record`` (in place; returns it).

    ``keys`` maps a key of ``record`` to the quantity whose error it carries: to itself for the
    estimated quantities (``{"f_r_hz": "f_r_hz"}``), or to ``tip_per_volt_m`` for an amplitude
    proportional to it (``{"used_m": "tip_per_volt_m"}``: scaled by the relative error). A value
    whose quantity was not estimated gets ``None``."""
    for key, q in keys.items():
        v = record.get(key)
        if est is None or v is None or q not in est.errors or not isinstance(v, (int, float)) or not math.isfinite(v):
            record[f"{key}_error"] = None
        elif key == q or est.values.get(q) == v:
            record[f"{key}_error"] = est.error(q)
        else:
            record[f"{key}_error"] = est.scaled(q, v)
    return record
