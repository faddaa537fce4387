"""Drill-tool kinetic energy against free-mass weight (article Fig. 8), as converged statistics.

Every free mass gets its own ensemble (see :mod:`impact.stats`): seeded members, grown until the
95 % confidence intervals of the driving quantities are within 3 % of their means. All masses
run together, one parallel kernel call per round. The line through the mean tool kinetic
energies is fitted by least squares (``scipy.stats.linregress``); with fewer than two masses it
is absent, with the reason.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from rpud_common import ParameterError, check_positive
from rpud_common.result import Result

from .params import ImpactParams
from .stats import QUANTITIES, EnsembleStats, Estimate, Scenario, StatsSettings, ensemble_batch, get_scenario

__all__ = ["sweep", "SweepResult", "linear_fit", "LineFit"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LineFit:
    """Least-squares line ``y = slope x + intercept``.

    ``slope_ci95`` and ``intercept_ci95`` are the half-widths of the slope's and the intercept's
    95 % intervals from the scatter of the points about the line (Student t, n - 2 degrees of
    freedom); they and ``r2`` are NaN with fewer than three points.
    ``reason`` says why a fit is absent.
    """

    slope: float
    intercept: float
    r2: float
    slope_ci95: float
    n: int
    reason: str = ""
    intercept_ci95: float = math.nan

    def to_dict(self) -> dict:
        def num(v):
            return v if math.isfinite(v) else None

        out = {"slope": num(self.slope), "intercept": num(self.intercept), "r2": num(self.r2),
               "slope_ci95_half_width": num(self.slope_ci95),
               "intercept_ci95_half_width": num(self.intercept_ci95), "points": self.n}
        if self.reason:
            out["reason"] = self.reason
        return out


def linear_fit(x, y) -> LineFit:
    """Least-squares line through the points (``scipy.stats.linregress``)."""
    from scipy.stats import linregress, t

    x, y = np.asarray(x, float), np.asarray(y, float)
    good = np.isfinite(x) & np.isfinite(y)
    x, y = x[good], y[good]
    n = int(x.size)
    if n < 2:
        return LineFit(math.nan, math.nan, math.nan, math.nan, n, f"{n} point(s): a line needs at least two")
    if np.ptp(x) == 0:
        return LineFit(math.nan, math.nan, math.nan, math.nan, n, "all points at the same abscissa")
    res = linregress(x, y)
    if n == 2:   # the line passes through both points: R^2 = 1 says nothing
        return LineFit(float(res.slope), float(res.intercept), math.nan, math.nan, n,
                       "two points: no R^2 and no interval on the slope")
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    r2 = float(res.rvalue ** 2) if ss_tot > 0 else math.nan
    tq = float(t.ppf(0.975, n - 2))
    return LineFit(float(res.slope), float(res.intercept), r2, tq * float(res.stderr), n,
                   intercept_ci95=tq * float(res.intercept_stderr))


@dataclass(repr=False)
class SweepResult(Result):
    """Ensemble statistics per free mass, and the line of mean tool KE against mass.

    Attributes
    ----------
    base : ImpactParams
        Base case (the scenario's spring and time set; ``m_free``/``A0`` vary per row).
    scenario : Scenario
    rows : list of EnsembleStats
        One per free mass, in the order given.
    fit : LineFit
        Mean tool kinetic energy after impact (J) against free mass (kg): slope in J/kg.
    """

    base: ImpactParams
    scenario: Scenario
    settings: StatsSettings
    rows: list
    fit: LineFit

    @property
    def m_free(self) -> np.ndarray:
        return np.array([r.params.m_free for r in self.rows])

    def column(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Means and CI half-widths of one quantity over the rows."""
        est = [r.estimates[name] for r in self.rows]
        return np.array([e.mean for e in est]), np.array([e.half_width for e in est])

    @property
    def mean_ke(self) -> np.ndarray:
        return self.column("mean_tool_ke_after_j")[0]

    @property
    def converged(self) -> bool:
        return all(r.converged for r in self.rows)

    def table(self) -> list[dict]:
        return [r.to_dict() for r in self.rows]

    def csv(self) -> str:
        """One row per free mass: every quantity's mean and 95 % CI half-width (empty if absent)."""
        head = ["m_free_kg", "A0_m", "members", "failed_members", "converged"]
        for q, unit, _ in QUANTITIES:
            head += [q, f"{q}_ci95"]
        lines = [",".join(head)]
        for r in self.rows:
            vals = [f"{r.params.m_free:.9g}", f"{r.params.A0:.9g}", str(r.members), str(r.failed),
                    str(r.converged).lower()]
            for q, _, _ in QUANTITIES:
                e = r.estimates[q]
                vals += [f"{e.mean:.9g}" if math.isfinite(e.mean) else "",
                         f"{e.half_width:.9g}" if math.isfinite(e.half_width) else ""]
            lines.append(",".join(vals))
        return "\n".join(lines) + "\n"

    def _headline(self) -> str:
        m = self.m_free * 1e3
        f = self.fit
        slope = f"{Estimate(f.slope, f.slope_ci95, f.n)} J/kg"
        return (f"{self.scenario.name}, {len(self.rows)} masses {m.min():g}-{m.max():g} g: tool KE slope {slope}, "
                f"{'converged' if self.converged else 'NOT converged'} (95 % CI)")

    def _record(self) -> dict:
        return {"params": self.base.to_dict(), "scenario": self.scenario.to_dict(),
                "statistics": {"rel_tol": self.settings.rel_tol, "n_start": self.settings.n_start,
                               "n_max": self.settings.n_max, "seed": self.settings.seed,
                               "v0_spread": self.settings.v0_spread, "level": self.settings.level},
                "converged": self.converged, "table": self.table(),
                "fit_ke_vs_mass": {"unit": "J/kg", **self.fit.to_dict()}}


def sweep(params: ImpactParams | None, m_free_values, *, scenario: str | Scenario = "article",
          settings: StatsSettings | None = None, A0_values=None, progress=None) -> SweepResult:
    """Converged statistics for several free masses, and the KE-vs-mass line.

    Parameters
    ----------
    params : ImpactParams, optional
        Base case (``m_free`` and ``A0`` vary per row, ``v0`` per member).
    m_free_values : sequence of float
        Free masses, kg.
    scenario : str or Scenario
        ``"article"`` (first 50 ms, no spring) or ``"device"`` (restoring spring, steady).
    settings : StatsSettings, optional
        CI target and member counts (default 3 %, 64 to 4096 members).
    A0_values : sequence of float, optional
        Horn amplitude per free mass, m (e.g. the FE amplitude loaded by that mass).
    progress : callable(str), optional
        Called with one line per round of members.

    Returns
    -------
    SweepResult
        One :class:`~impact.stats.EnsembleStats` per free mass (``rows``) and the line of mean
        tool KE against mass (``fit``: slope J/kg with its 95 % CI).

    Examples
    --------
    >>> from impact import ImpactParams, StatsSettings, sweep
    >>> sweep(ImpactParams(), [0.004, 0.008], settings=StatsSettings(n_start=16, n_max=16))
    SweepResult(article, 2 masses 4-8 g: tool KE slope 3.229 J/kg, NOT converged (95 % CI))
    """
    base = params if params is not None else ImpactParams()
    sc = get_scenario(scenario)
    st = settings or StatsSettings()
    try:
        masses = [float(m) for m in m_free_values]
    except (TypeError, ValueError):
        raise ParameterError("m_free", m_free_values, "must be a list of masses in kg") from None
    if not masses:
        raise ParameterError("m_free", m_free_values, "must list at least one mass in kg")
    for m in masses:
        check_positive("m_free", m, "kg")
    if A0_values is None:
        amps = [base.A0] * len(masses)
    else:
        amps = [float(a) for a in A0_values]
        if len(amps) != len(masses):
            raise ParameterError("A0_values", A0_values, f"must give one amplitude per mass ({len(masses)})")
    cases = [base.with_(m_free=m, A0=a) for m, a in zip(masses, amps)]
    rows: list[EnsembleStats] = ensemble_batch(cases, sc, st, progress)
    ke = np.array([r.estimates["mean_tool_ke_after_j"].mean for r in rows])
    fit = linear_fit(np.array(masses), ke)
    for r in rows:
        if r.note:
            log.warning("m_free = %g kg: %s", r.params.m_free, r.note)
    return SweepResult(base=sc.apply(base), scenario=sc, settings=st, rows=rows, fit=fit)
