"""Drilling under load: the percussive system pressed on rock with a weight on bit (article 5.2).

Model (x along the drill, horn -> rock; SI units)
-------------------------------------------------
* Horn: the kinematic tip ``A0 cos(2 pi f t)`` of the no-load model, carried by the *housing*.
* Housing: the drill body (``m_drill`` minus tool and free mass, default 590 g total, article
  section 2), pressed toward the rock by the weight on bit ``wob``. It transmits the WOB to the
  tool through the tool's support spring k0 (and damper c): at rest the spring is compressed by
  ``wob / k0`` and the rock bears ``wob``. The free mass's restoring spring is internal to the
  drill (it pushes the housing as much as it pulls the free mass back), so it transmits WOB only
  while the free mass rests on the tool. A horn impact is Newton's law (e2) between the free
  mass and the housing that carries the horn, the horn's vibration imposed on top (for 8 g on a
  0.53 kg housing the no-load model's infinite-mass horn to 1.5 %), so momentum is conserved and
  the mean rock force is the WOB plus the free mass's weight.
  ``wob`` is the whole static thrust (the weights of housing and tool included).
* Free mass: the no-load model's point mass (flight under ``g - F_spring / m_free``, Newton
  restitution e2 on the horn and e1 on the tool).
* Tool: a rigid collar (hit by the free mass; support spring k0, damper c) on a slender elastic
  rod (:mod:`impact.rod`, exact wave propagation), whose far end is the bit.
* Rock: the bit-rock law of :mod:`impact.rock` (loading / unloading stiffness, crushing
  threshold; sandstone values there).

Outputs per ensemble member over a window after the start-up: blows (free-mass/tool impacts),
permanent penetration, work done on the rock, horn work on the free mass, mean rock force.
Reported (means with 95 % CIs over seeded members, :mod:`impact.stats` estimators): blow rate,
drilling rate (mm/min), penetration per blow, energy transfer efficiency (work on the rock /
work of the horn), mean peak rock force per blow, mean rock force.

The 5-minute depth: the drilling rate is statistically stationary once the start-up transient
has passed (the housing follows the crater through k0 at ~100 Hz, far faster than the crater
deepens), so the depth after ``drill_time`` = rate x drill_time, with the rate's CI scaled
alike. This assumes the rate does not change with depth (no chip clogging or wear), which the
article's short holes allow.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace

import numpy as np

from rpud_common import ParameterError, check_integer, check_range
from rpud_common.result import Result

from .params import ImpactParams
from .rock import RockLaw
from .rod import ToolRod
from .stats import Estimate, StatsSettings, ensemble_uniforms, mean_ci, ratio_ci

__all__ = ["DrillParams", "DrillSettings", "DrillStats", "DrillSweep", "CompliantHorn", "drilling_statistics",
           "drilling_sweep", "pack", "DRILL_QUANTITIES", "MODEL_STATUS", "COMPLIANT_STATUS", "STATUS_LINE",
           "model_status", "status_line"]

log = logging.getLogger(__name__)

MODEL_STATUS = {
    "model": "kinematic horn, Newton impacts, rigid collar on an elastic tool rod",
    "calibration": "uncalibrated: the rock law (k_load, k_unload, crushing threshold) is assumed from textbook "
                   "sandstone values, not fitted to the article's rock or bit; only the impact contact gap is "
                   "calibrated (to the article's ~520 Hz tool-impact rate)",
    "assumptions": "kinematic horn at A0; rigid collar on an elastic tool rod; Lundberg's bilinear bit-rock law "
                   "with a crushing threshold; every blow meets fresh rock (chips cleared, no re-crushing); "
                   "depth = stationary drilling rate x drilling time (no clogging or wear)",
    "use": "the trend with the free mass is the result to compare with the article's Fig. 14; the depths are "
           "NOT credible as magnitudes",
}
"""The drilling model's assumptions and calibration status, printed, written and drawn beside
every number it gives (the depths rest on an assumed rock law)."""

COMPLIANT_STATUS = {
    "model": "FE transducer (k = 0 modes + static residual) with Hertz contacts at horn tip and tool, rigid tool",
    "calibration": "uncalibrated: the rock law (k_load, k_unload, crushing threshold) is assumed from textbook "
                   "sandstone values, not fitted to the article's rock or bit; the gap, tool stiffness and damping "
                   "and launch speed are inherited from the kinematic horn's fit (not refitted under this model); "
                   "the contact stiffness follows an assumed face radius",
    "assumptions": "the horn's modes ride on the housing (their inertial load from its acceleration left out); "
                   "Hertz contacts with restitution unloading; a rigid tool (no rod waves: the kinematic model's "
                   "elastic rod is the comparison); Lundberg's bilinear bit-rock law with a crushing threshold; every "
                   "blow meets fresh rock; depth = stationary drilling rate x drilling time",
    "use": MODEL_STATUS["use"],
}
"""The compliant drilling model's assumptions and calibration status (:func:`model_status`)."""


def model_status(model: str) -> dict:
    """The status block of ``model`` ("kinematic" or "compliant")."""
    return dict(COMPLIANT_STATUS if model == "compliant" else MODEL_STATUS)


def status_line(model: str = "kinematic") -> str:
    """One line of the status of ``model`` for terminals and figures."""
    st = model_status(model)
    return f"model status ({model}): " + st["calibration"].split(":")[0] + " rock law; " + st["use"]


STATUS_LINE = status_line("kinematic")
"""One line of :data:`MODEL_STATUS` for terminals and figures."""

#: (name, unit, description)
DRILL_QUANTITIES = (
    ("drilling_rate_m_s", "m/s", "drilling rate (permanent penetration per second)"),
    ("blow_rate_hz", "Hz", "free-mass/tool impacts (blows) per second"),
    ("penetration_per_blow_m", "m", "permanent penetration per blow"),
    ("efficiency", "-", "energy transfer efficiency: work on the rock / work of the horn"),
    ("rock_power_w", "W", "work done on the rock per second"),
    ("horn_power_w", "W", "work of the horn on the free mass per second"),
    ("peak_force_per_blow_n", "N", "largest rock force between two blows, mean over blows"),
    ("mean_rock_force_n", "N", "time-mean rock force (momentum: WOB + free-mass weight)"),
    ("contact_fraction", "-", "fraction of the time the bit touches the rock"),
)
DRIVING = ("drilling_rate_m_s", "blow_rate_hz")


def _article_impact() -> ImpactParams:
    # the drilling experiment: 19.95 kHz (article 5.2), the device's 5 N restoring spring
    return ImpactParams(freq=19.95e3, spring_force=5.0)


@dataclass(frozen=True)
class DrillParams:
    """Every input of the drilling-under-load model (SI units).

    Parameters
    ----------
    impact : ImpactParams
        Horn, free mass and tool parameters of the no-load model (A0, freq, m_free, e1, e2,
        m_tool, k0, c, gap, g, v0, spring_force). Default: Table 1 and the calibrated values at
        the drilling experiment's 19.95 kHz, with the device's 5 N restoring spring.
    rod : ToolRod
        The tool's slender part (3 mm x 150 mm steel by default; collar = the rest of m_tool).
    rock : RockLaw
        Bit-rock law (sandstone defaults, :mod:`impact.rock`).
    wob : float
        Weight on bit, N, in [0, 1e4] (article: 7 N).
    m_drill : float
        Mass of the whole drill, kg (article: 0.59); the housing is the rest after tool and
        free mass.
    t_from, t_end : float
        Statistics window [t_from, t_end], s (start-up discarded; default 20-220 ms).
    drill_time : float
        Drilling time the depth is extrapolated to, s (article: 300).
    """

    impact: ImpactParams = field(default_factory=_article_impact)
    rod: ToolRod = field(default_factory=ToolRod)
    rock: RockLaw = field(default_factory=RockLaw)
    wob: float = 7.0
    m_drill: float = 0.59
    t_from: float = 0.02
    t_end: float = 0.22
    drill_time: float = 300.0

    def __post_init__(self):
        check_range("wob", self.wob, 0.0, 1e4, "N")
        check_range("m_drill", self.m_drill, 1e-3, 1e3, "kg")
        check_range("t_from", self.t_from, 0.0, 10.0, "s")
        check_range("t_end", self.t_end, self.t_from, 10.0, "s", lo_open=True)
        check_range("drill_time", self.drill_time, 0.0, 1e6, "s", lo_open=True)
        self.rod.collar_mass(self.impact.m_tool)
        if self.housing_mass(self.impact.m_free) <= 0.0:
            raise ParameterError("m_drill", self.m_drill, "must exceed the tool mass plus the free mass")
        # the WOB pushes the collar back by wob / k0: the free mass must still fit
        room = self.impact.gap - self.wob / self.impact.k0 - 2.0 * self.impact.A0
        if room <= 0.0:
            raise ParameterError("wob", self.wob, f"compresses the support spring k0 by {self.wob / self.impact.k0:g} m, "
                                 f"closing the gap {self.impact.gap:g} m: lower wob or raise k0")

    def with_(self, **changes) -> "DrillParams":
        return replace(self, **changes)

    def housing_mass(self, m_free: float) -> float:
        return self.m_drill - self.impact.m_tool - m_free

    @property
    def window_s(self) -> float:
        return self.t_end - self.t_from

    def to_dict(self) -> dict:
        return {"impact": self.impact.to_dict(), "rod": self.rod.to_dict(), "rock": self.rock.to_dict(),
                "wob_n": self.wob, "m_drill_kg": self.m_drill, "t_from_s": self.t_from, "t_end_s": self.t_end,
                "drill_time_s": self.drill_time}


def pack(p: DrillParams, m_free: float | None = None, v0: float | None = None, *, collar_v0: float = 0.0,
         unilateral: bool = False, rock_on: bool = True, housing_fixed: bool = False,
         cold: bool = False) -> np.ndarray:
    """Parameters as the kernel's float vector (:mod:`impact.drill_kernel` ``D_*``).

    ``m_free`` 0 runs without a free mass (no blows). The keyword options serve the checks: a
    collar moving at ``collar_v0`` (m/s), a unilateral collar (a striker), no rock (a free bit
    end), a fixed housing, a cold start (nothing stressed, the bit touching the rock)."""
    from . import drill_kernel as K

    ip = p.impact
    mf = ip.m_free if m_free is None else m_free
    v = np.zeros(K.N_DPARAMS)
    v[K.D_M_FREE], v[K.D_A0], v[K.D_OM], v[K.D_E1], v[K.D_E2] = mf, ip.A0, ip.omega, ip.e1, ip.e2
    v[K.D_M_COLLAR] = p.rod.collar_mass(ip.m_tool)
    v[K.D_K0], v[K.D_C], v[K.D_GAP], v[K.D_G] = ip.k0, ip.c, ip.gap, ip.g
    v[K.D_V0] = ip.v0 if v0 is None else v0
    v[K.D_SPRING] = ip.spring_force
    v[K.D_Z], v[K.D_DT], v[K.D_CELLS] = p.rod.impedance, p.rod.dt, p.rod.cells
    v[K.D_KL], v[K.D_KU], v[K.D_FTH] = p.rock.k_load, p.rock.k_unload, p.rock.f_threshold
    v[K.D_WOB] = p.wob
    v[K.D_M_HOUSING] = math.inf if housing_fixed else p.housing_mass(mf)
    v[K.D_V_STICK] = ip.v_stick
    v[K.D_UNILATERAL] = 1.0 if unilateral else 0.0
    v[K.D_ROCK_ON] = 1.0 if rock_on else 0.0
    v[K.D_COLLAR_V0] = collar_v0
    st = p.rock.static_state(p.wob) if rock_on else np.zeros(3)
    v[K.D_E0], v[K.D_P0], v[K.D_FMAX0] = st[0], st[1], st[2] if rock_on else p.rock.f_threshold
    v[K.D_COLD] = 1.0 if cold else 0.0
    return v


@dataclass(frozen=True)
class DrillSettings(StatsSettings):
    """Ensemble rule of the drilling statistics: :class:`impact.stats.StatsSettings` with the
    drilling stage's defaults (a 5 % target on the driving quantities, the drilling rate and the
    blow rate; a first round of 16 members, at least 2 for a spread; a cap of 512). The members'
    launch speeds are perturbed as in :mod:`impact.stats`."""

    rel_tol: float = 0.05
    n_start: int = 16
    n_max: int = 512

    def __post_init__(self):
        super().__post_init__()
        check_integer("n_start", self.n_start, 2)


@dataclass(repr=False)
class DrillStats(Result):
    """Drilling statistics of one free mass (means and 95 % CIs over members)."""

    m_free: float
    A0: float
    estimates: dict
    depth_m: Estimate
    members: int
    converged: bool
    note: str
    params: DrillParams
    raw: np.ndarray | None = field(default=None, repr=False)
    model: str = "kinematic"

    def __getitem__(self, name) -> Estimate:
        return self.estimates[name]

    def _headline(self) -> str:
        return (f"{self.m_free * 1e3:g} g, A0 {self.A0 * 1e6:.3g} um, WOB {self.params.wob:g} N: drilling rate "
                f"{self['drilling_rate_m_s'].scaled(6e4)} mm/min, depth after {self.params.drill_time:g} s "
                f"{self.depth_m.scaled(1e3)} mm, blows {self['blow_rate_hz']} Hz; {self.members} members (95 % CI); "
                f"{status_line(self.model)}")

    def _arrays(self) -> dict:
        return {"members": self.raw} if self.raw is not None else {}

    def _record(self) -> dict:
        return {"m_free_kg": self.m_free, "A0_m": self.A0, "model": self.model, "members": self.members, "converged": self.converged,
                "note": self.note, "depth_after_drill_time_m": self.depth_m.to_dict(),
                "drilling_rate_mm_per_min": self["drilling_rate_m_s"].scaled(6e4).to_dict(),
                **{k: v.to_dict() for k, v in self.estimates.items()}}


def _estimates(raw, T, level: float):
    from . import drill_kernel as K

    blows = raw[:, K.S_BLOWS]
    horn = raw[:, K.S_HORN_WORK]
    return {
        "drilling_rate_m_s": mean_ci(raw[:, K.S_PEN] / T, level),
        "blow_rate_hz": mean_ci(blows / T, level),
        "penetration_per_blow_m": ratio_ci(raw[:, K.S_PEN], blows, level),
        "efficiency": ratio_ci(raw[:, K.S_ROCK_WORK], horn, level) if np.all(horn > 0) else
        Estimate(math.nan, math.nan, raw.shape[0], level, "no horn work (no free mass)"),
        "rock_power_w": mean_ci(raw[:, K.S_ROCK_WORK] / T, level),
        "horn_power_w": mean_ci(horn / T, level),
        "peak_force_per_blow_n": ratio_ci(raw[:, K.S_FPEAK_SUM], blows, level),
        "mean_rock_force_n": mean_ci(raw[:, K.S_FDT] / raw[:, K.S_T], level),
        "contact_fraction": mean_ci(raw[:, K.S_T_CONTACT] / raw[:, K.S_T], level),
    }


@dataclass(frozen=True)
class CompliantHorn:
    """The FE horn and the contacts of the compliant drilling model (:mod:`impact.kernel_drill_compliant`).

    Parameters
    ----------
    horn : impact.horn.ModalHorn
        The driven transducer's modes (e.g. :func:`results.coupled.wideband_horn`); its drive
        frequency is ``DrillParams.impact.freq``.
    residual : float
        Static tip compliance of the modes left out, m/N.
    laws : tuple
        ``(horn_law, tool_law)`` (:class:`impact.hertz.HertzLaw`) for every free mass, or one such
        pair per mass of the sweep (the stiffness follows the free mass's face radius).
    rtol : float
        Relative tolerance of the DOP853 steps, in [1e-12, 1e-6]. The window's energy balance
        follows it: ~2e-10 of the drive work at 1e-10, ~1.7e-9 at 1e-9 (the default FE horn, 16
        modes to 70 kHz, 2 and 8 g), for about the same time.
    housing_fixed : bool
        An infinitely heavy housing (the limit the kinematic model's check runs in).
    """

    horn: object
    residual: float
    laws: tuple
    rtol: float = 1e-10
    housing_fixed: bool = False

    def __post_init__(self):
        from .compliant_engine import check_compliant

        for hl, tl in self.pairs(1 if self.single else len(self.laws)):
            check_compliant(self.horn, hl, tl, self.residual, self.rtol)
        check_range("rtol", self.rtol, 1e-12, 1e-6)

    @property
    def single(self) -> bool:
        return len(self.laws) == 2 and not isinstance(self.laws[0], (tuple, list))

    def pairs(self, n: int) -> list:
        """The (horn_law, tool_law) pair of each of n masses."""
        if self.single:
            return [tuple(self.laws)] * n
        if len(self.laws) != n:
            raise ParameterError("laws", f"{len(self.laws)} pairs", f"must be one (horn, tool) pair or one per mass ({n})")
        return [tuple(x) for x in self.laws]

    def tip_amplitude(self, freq: float) -> float:
        """The free-running tip amplitude at the drive, m."""
        return float(abs(self.horn.steady_tip(freq)))


def _members(p: DrillParams, m_free: float, start: int, n: int, st: DrillSettings, A0: float | None):
    pp = p if A0 is None else p.with_(impact=p.impact.with_(A0=A0))
    u = ensemble_uniforms(st, start, n)
    return np.array([pack(pp, m_free, pp.impact.v0 * (1.0 + st.v0_spread * (2.0 * ui - 1.0))) for ui in u])


def _compliant_members(p: DrillParams, m_free: float, start: int, n: int, st: DrillSettings, ch: CompliantHorn,
                       laws) -> np.ndarray:
    """The members' packed rows of the compliant kernel: impact parameters, laws, drilling (one block)."""
    from . import kernel_compliant as KC
    from . import kernel_drill_compliant as KD
    from .kernel import pack as pack_impact

    u = ensemble_uniforms(st, start, n)
    ip = p.impact.with_(m_free=m_free)
    lw = KC.pack_laws(laws[0], laws[1], float(ch.residual), float(ch.rtol))
    dv = KD.pack_drill(p.wob, math.inf if ch.housing_fixed else p.housing_mass(m_free), p.rock)
    rows = [np.concatenate([pack_impact(ip.with_(v0=ip.v0 * (1.0 + st.v0_spread * (2.0 * ui - 1.0)))), lw, dv])
            for ui in u]
    return np.array(rows).reshape(n, -1)


def _run_compliant(block: np.ndarray, ch: CompliantHorn, p: DrillParams) -> np.ndarray:
    from . import kernel_compliant as KC
    from . import kernel_drill_compliant as KD
    from .kernel import N_PARAMS

    tab, xs = ch.horn.pack(p.impact.freq)
    a, b = N_PARAMS, N_PARAMS + KC.LAW_N
    return KD.ensemble_drill(block[:, :a], block[:, a:b], block[:, b:], tab, xs, p.t_from, p.t_end)


def _summary(p, m_free, A0, raw, st, model="kinematic") -> DrillStats:
    from . import drill_kernel as K

    T = p.window_s
    est = _estimates(raw, T, st.level)
    if model == "compliant":
        from . import kernel_drill_compliant as KD

        est["ledger_rel"] = mean_ci(raw[:, KD.K_LEDGER] / raw[:, KD.K_DRIVE], st.level)
        est["drive_power_w"] = mean_ci(raw[:, KD.K_ELEC] / T, st.level)
    rel = [est[q].rel_half_width for q in DRIVING]
    det = bool(np.all(raw[:, K.S_PEN] == raw[0, K.S_PEN]) and np.all(raw[:, K.S_BLOWS] == raw[0, K.S_BLOWS]))
    converged = det or all(math.isfinite(r) and r <= st.rel_tol for r in rel)
    note = ""
    if det:
        note = "every member identical (no free mass, or no blow crushes the rock): deterministic, CI 0"
    elif not converged and raw.shape[0] >= st.n_max:
        note = f"member cap {st.n_max} reached before the {st.rel_tol:.0%} target"
    bad = int(np.sum(raw[:, K.S_STATUS] != 0))
    if bad:
        why = "closed a chattering step plastically" if model == "kinematic" else "ran out of integration steps"
        note += (("; " if note else "") + f"{bad} member(s) {why}")
    rate = est["drilling_rate_m_s"]
    return DrillStats(m_free=m_free, A0=p.impact.A0 if A0 is None else A0, estimates=est,
                      depth_m=rate.scaled(p.drill_time), members=int(raw.shape[0]), converged=converged,
                      note=note, params=p, raw=raw, model=model)


def _check_masses(p: DrillParams, masses, compliant: bool) -> None:
    for m in masses:
        if m != 0.0 or compliant:
            p.impact.with_(m_free=m)               # bounds, before any work
            if p.housing_mass(m) <= 0:
                raise ParameterError("m_free", m, "must leave a positive housing mass")


def drilling_sweep(p: DrillParams, masses, settings: DrillSettings | None = None, A0_values=None,
                   progress=None, horn: CompliantHorn | None = None) -> list[DrillStats]:
    """Converged drilling statistics for every free mass (kg), all masses' members run together,
    one parallel kernel call per round.

    Parameters
    ----------
    p : DrillParams
    masses : free masses, kg (0 = no free mass, kinematic model only)
    settings : DrillSettings
    A0_values : one horn amplitude per mass, m (e.g. the pipeline's loaded amplitudes), else
        ``p.impact.A0`` (kinematic model only: the FE horn's amplitude follows from its drive)
    progress : callable taking one message, optional
    horn : CompliantHorn, optional
        Drill on the compliant model (the FE horn with Hertz contacts and a rigid tool,
        :mod:`impact.kernel_drill_compliant`) instead of the kinematic horn with Newton impacts
        and the elastic tool rod (:mod:`impact.drill_kernel`).
    """
    from . import drill_kernel as K

    st = settings or DrillSettings()
    masses = [float(m) for m in masses]
    _check_masses(p, masses, horn is not None)
    laws = horn.pairs(len(masses)) if horn is not None else None
    if horn is not None and A0_values is not None:
        raise ParameterError("A0_values", "given", "applies to the kinematic horn only (the FE horn has its drive)")
    amps = [None] * len(masses) if A0_values is None else list(A0_values)
    if horn is not None:
        amps = [horn.tip_amplitude(p.impact.freq)] * len(masses)
    model = "kinematic" if horn is None else "compliant"
    raws = [None] * len(masses)
    target = [st.n_start] * len(masses)
    done = [False] * len(masses)
    out: list = [None] * len(masses)
    while not all(done):
        todo = [i for i in range(len(masses)) if not done[i]]
        have = [0 if raws[i] is None else raws[i].shape[0] for i in range(len(masses))]
        if horn is None:
            blocks = [_members(p, masses[i], have[i], target[i] - have[i], st, amps[i]) for i in todo]
            res = K.ensemble(np.vstack(blocks), p.t_from, p.t_end)
        else:
            blocks = [_compliant_members(p, masses[i], have[i], target[i] - have[i], st, horn, laws[i]) for i in todo]
            res = _run_compliant(np.vstack(blocks), horn, p)
        k = 0
        for i, b in zip(todo, blocks):
            new = res[k:k + b.shape[0]]
            raws[i] = new if raws[i] is None else np.vstack([raws[i], new])
            k += b.shape[0]
            out[i] = _summary(p, masses[i], amps[i], raws[i], st, model)
            if out[i].converged or raws[i].shape[0] >= st.n_max:
                done[i] = True
            else:
                target[i] = min(2 * raws[i].shape[0], st.n_max)
        msg = f"drilling ({model}): round of {res.shape[0]} members, {sum(done)}/{len(done)} mass(es) finished"
        log.info("%s", msg)
        if progress is not None:
            progress(msg)
    return out


def drilling_statistics(p: DrillParams | None = None, settings: DrillSettings | None = None,
                        m_free: float | None = None) -> DrillStats:
    """Converged drilling statistics of one free mass (default: ``p.impact.m_free``)."""
    p = p or DrillParams()
    return drilling_sweep(p, [p.impact.m_free if m_free is None else m_free], settings)[0]


@dataclass(repr=False)
class DrillSweep(Result):
    """Predicted drilling against free mass, beside the no-load tool kinetic energy; with the
    compliant model, the kinematic model's sweep as its stated comparison (``comparison``)."""

    rows: list
    no_load: object | None = None
    params: DrillParams | None = None
    comparison: "DrillSweep | None" = None

    @property
    def model(self) -> str:
        return self.rows[0].model if self.rows else "kinematic"

    def _headline(self) -> str:
        return ("; ".join(f"{r.m_free * 1e3:g} g: {r.depth_m.scaled(1e3)} mm" for r in self.rows)
                + f" ({status_line(self.model)})")

    def _record(self) -> dict:
        out = {"params": self.params.to_dict() if self.params else None, "model": self.model,
               "model_status": model_status(self.model), "rows": [r._record() for r in self.rows]}
        if self.no_load is not None:
            out["no_load_device"] = self.no_load.to_dict()
        if self.comparison is not None:
            out["comparison"] = self.comparison._record()
        return out
