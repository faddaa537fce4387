"""Parallel parameter sweeps: drill-tool kinetic energy against free-mass weight (Fig. 8).

The dynamics are chaotic, so a single 50 ms run gives a noisy mean kinetic energy (~25 tool
impacts). The default sweep therefore runs ``t_end = 1 s`` per case and an ensemble of 4
members per free mass whose launch speeds differ by up to +-5 % of ``v0`` (member k of n uses
``v0 (1 + 0.1 (k/(n-1) - 1/2))``), and reports the ensemble statistics.
"""

from __future__ import annotations

import logging
import math
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

from geometry.common import ParameterError, check_integer, check_positive

from .model import SimulationError, simulate
from .params import ImpactParams

__all__ = ["sweep", "run_cases", "SweepResult", "ensemble_params", "linear_fit"]

log = logging.getLogger(__name__)


def ensemble_params(params: ImpactParams, n: int) -> list[ImpactParams]:
    """``n`` copies of ``params`` whose ``v0`` is spread by +-5 % (n = 1: unchanged)."""
    if n == 1:
        return [params]
    return [params.with_(v0=params.v0 * (1.0 + 0.1 * (k / (n - 1) - 0.5))) for k in range(n)]


def _case(p: ImpactParams) -> dict:
    """One case, reduced to the few numbers a sweep needs (cheap to send between processes)."""
    try:
        r = simulate(p, series=False)
    except SimulationError as exc:
        return {"error": str(exc)}
    ke = r.tool_ke_after
    return {"tool_impacts": r.tool_impacts, "horn_impacts": r.horn_impacts,
            "tool_impact_rate_hz": r.tool_impact_rate_hz,
            "mean_tool_ke_after_impact_j": float(ke.mean()) if ke.size else 0.0,
            "sum_tool_ke_j": float(ke.sum()),
            "horn_work_j": float(r.horn_work[-1]) if len(r.horn_work) else 0.0, "error": None}


def run_cases(cases: list[ImpactParams], workers: int = 2, progress: bool = True,
              desc: str = "impact") -> list[dict]:
    """Run many cases on a process pool with a tqdm progress bar on stderr.

    Parameters
    ----------
    cases : list of ImpactParams
    workers : int
        Worker processes (1 runs in this process).
    progress : bool
        Show the progress bar.

    Returns
    -------
    list of dict
        Per case: ``tool_impacts``, ``horn_impacts``, ``tool_impact_rate_hz``,
        ``mean_tool_ke_after_impact_j`` (J), ``sum_tool_ke_j`` (J), ``horn_work_j`` (work the horn
        did on the free mass over the run, J), ``error`` (None or text).
    """
    from tqdm import tqdm

    check_integer("workers", workers, 1)
    bar = tqdm(total=len(cases), desc=desc, file=sys.stderr, disable=not progress, leave=False)
    out: list[dict] = []
    try:
        if workers == 1:
            for c in cases:
                out.append(_case(c))
                bar.update()
        else:
            chunk = max(1, len(cases) // (workers * 8))
            with ProcessPoolExecutor(max_workers=workers) as ex:
                for res in ex.map(_case, cases, chunksize=chunk):
                    out.append(res)
                    bar.update()
    finally:
        bar.close()
    return out


def linear_fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """Least-squares line y = slope x + intercept; returns (slope, intercept, R^2)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    if x.size < 2:
        return math.nan, math.nan, math.nan
    slope, intercept = np.polyfit(x, y, 1)
    ss_res = float(np.sum((y - (slope * x + intercept)) ** 2))
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - ss_res / ss_tot if ss_tot > 0 else math.nan
    return float(slope), float(intercept), r2


@dataclass
class SweepResult:
    """Ensemble statistics per free mass and the linear fit of mean tool KE against mass.

    ``m_free`` (kg), ``mean_ke`` (J, mean over all tool impacts of all members),
    ``sem_ke`` (J, standard error over members), ``rate_hz`` (mean tool impact rate),
    ``n_ok`` (members that finished), ``slope`` (J/kg), ``intercept`` (J), ``r2``.
    """

    base: ImpactParams
    ensemble: int
    m_free: np.ndarray
    mean_ke: np.ndarray
    sem_ke: np.ndarray
    rate_hz: np.ndarray
    n_ok: np.ndarray
    slope: float
    intercept: float
    r2: float
    errors: list

    def table(self) -> list[dict]:
        return [{"m_free_kg": float(m), "mean_tool_ke_j": float(k), "sem_tool_ke_j": float(s),
                 "tool_impact_rate_hz": float(r), "members_ok": int(n)}
                for m, k, s, r, n in zip(self.m_free, self.mean_ke, self.sem_ke, self.rate_hz, self.n_ok)]

    def csv(self) -> str:
        lines = ["m_free_kg,mean_tool_ke_j,sem_tool_ke_j,tool_impact_rate_hz,members_ok"]
        for row in self.table():
            lines.append(",".join(f"{v:.9g}" if isinstance(v, float) else str(v) for v in row.values()))
        return "\n".join(lines) + "\n"

    def to_json_dict(self) -> dict:
        return {"params": self.base.to_dict(), "ensemble": self.ensemble, "table": self.table(),
                "fit": {"slope_j_per_kg": self.slope, "intercept_j": self.intercept, "r2": self.r2},
                "errors": self.errors}


def sweep(params: ImpactParams | None, m_free_values, *, ensemble: int = 4,
          t_end: float | None = 1.0, workers: int = 2, progress: bool = True,
          A0_values=None) -> SweepResult:
    """Mean drill-tool kinetic energy after impact for several free masses.

    Parameters
    ----------
    params : ImpactParams, optional
        Base case (``m_free`` and ``v0`` are varied).
    m_free_values : sequence of float
        Free masses, kg.
    ensemble : int
        Members per mass (launch speed spread +-5 %).
    t_end : float or None
        Simulated time per member, s (None keeps ``params.t_end``). Default 1 s: the trend
        needs long runs (50 ms runs hold only ~25 tool impacts).
    workers : int
        Processes.
    progress : bool
        tqdm bar on stderr.
    A0_values : sequence of float, optional
        Horn amplitude per free mass, m (e.g. the FE amplitude loaded by that free mass);
        default: ``params.A0`` for all.
    """
    base = params if params is not None else ImpactParams()
    if t_end is not None:
        base = base.with_(t_end=t_end)
    masses = [float(m) for m in m_free_values]
    if not masses:
        raise ParameterError("m_free", m_free_values, "must list at least one mass in kg")
    for m in masses:
        check_positive("m_free", m, "kg")
    check_integer("ensemble", ensemble, 1)
    if A0_values is None:
        amps = [base.A0] * len(masses)
    else:
        amps = [float(a) for a in A0_values]
        if len(amps) != len(masses):
            raise ParameterError("A0_values", A0_values, f"must give one amplitude per mass ({len(masses)})")
    cases = [q for m, a in zip(masses, amps) for q in ensemble_params(base.with_(m_free=m, A0=a), ensemble)]
    res = run_cases(cases, workers=workers, progress=progress, desc="sweep")
    mean_ke, sem_ke, rate, n_ok, errors = [], [], [], [], []
    for i, m in enumerate(masses):
        block = res[i * ensemble:(i + 1) * ensemble]
        ok = [b for b in block if b["error"] is None]
        errors += [{"m_free_kg": m, "error": b["error"]} for b in block if b["error"] is not None]
        n_imp = sum(b["tool_impacts"] for b in ok)
        mean_ke.append(sum(b["sum_tool_ke_j"] for b in ok) / n_imp if n_imp else math.nan)
        member = np.array([b["mean_tool_ke_after_impact_j"] for b in ok])
        sem_ke.append(float(member.std(ddof=1) / math.sqrt(member.size)) if member.size > 1 else math.nan)
        rate.append(float(np.mean([b["tool_impact_rate_hz"] for b in ok])) if ok else math.nan)
        n_ok.append(len(ok))
    mean_ke = np.array(mean_ke)
    good = np.isfinite(mean_ke)
    slope, intercept, r2 = linear_fit(np.array(masses)[good], mean_ke[good])
    for e in errors:
        log.warning("case m_free = %g kg failed: %s", e["m_free_kg"], e["error"])
    return SweepResult(base=base, ensemble=ensemble, m_free=np.array(masses), mean_ke=mean_ke,
                       sem_ke=np.array(sem_ke), rate_hz=np.array(rate), n_ok=np.array(n_ok),
                       slope=slope, intercept=intercept, r2=r2, errors=errors)


def default_workers() -> int:
    return min(2, os.cpu_count() or 1)
