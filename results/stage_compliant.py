"""The compliant-contact stage: the drill tool's kinetic energy with its model-form uncertainty.

The headline model is the FE transducer in the impact loop with compliant contacts at the horn
tip and at the tool (:func:`impact.compliant_loop.simulate_compliant`): Hertz loading with the
contact geometry below, the restitution unloading of :class:`impact.hertz.HertzLaw`, and the
transducer's axial (k = 0) modes up to a cut-off plus the static residual of the rest
(:func:`results.coupled.wideband_horn`).

Which modes take part is set by the contact's duration: a mode well above the contact frequency
responds quasi-statically and the residual carries it; a mode near or below it responds
dynamically and must be kept. The cut-off is therefore chosen from the contact time: ``t_c`` is
the shortest Hertz contact of the study (the lightest free mass, both laws, on a rigid flat at the
launch speed; :meth:`impact.hertz.HertzLaw.contact_time`), and the headline keeps every mode up to
``cutoff_factors[-1] / t_c`` (the rod reference of the contact helper: cut-off x contact time >= 2
brings the rebound speed within 0.2 % of the wave solution).

Convergence study (every run): tool KE after impact and tool impact rate at the lightest and the
heaviest free mass against the cut-off (``cutoff_factors / t_c``) and against the contact
stiffness (x0.5, x2 at the headline cut-off). The model-form estimate of a quantity is the sum of
the cut-off term (the change between the two highest cut-offs: the last increment of a
converging sequence) and the stiffness term (half the spread between x0.5 and x2: the contact
stiffness is known to about a factor of two, the face radius and the surface finish being
assumed). Both differences carry the sampling noise of the two ensembles they compare, so each term
is taken with its 95 % sampling half-width added (a difference smaller than its noise is not
evidence of convergence); the table gives each difference and its half-width apart. Because the
estimate carries that noise, the study's cases (the lower cut-offs and the stiffness variants) are
held to a looser CI target (``study_rel_tol``) than the headline's.

Contact geometry (design data of this stage, :class:`results.contact_faces.ContactFaces`): the
free mass's faces, crowned (by default with the radius of a sphere of its own mass and material)
or flat with a rounded rim, strike the flat horn tip (the design's horn material) and the flat
tool face (the tool's material). The restitutions are the impact parameters' ``e2`` (horn) and
``e1`` (tool).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from rpud_common import ParameterError, check_integer, check_range

from .contact_faces import ContactFaces

log = logging.getLogger(__name__)

#: the quantities with a model-form estimate: tool KE after impact, tool impact rate, tool power
QUANTITIES = ("mean_tool_ke_after_j", "tool_impact_rate_hz", "tool_power_w")

__all__ = ["QUANTITIES", "CompliantSettings", "contact_laws", "shortest_contact_time", "compliant_ensembles",
           "compliant_stage", "model_form", "stage_runs", "CompliantWorker"]


@dataclass(frozen=True)
class CompliantSettings:
    """Settings of the compliant stage (SI units).

    Attributes
    ----------
    cutoff_factors : mode cut-offs of the study in units of ``1 / t_c`` (increasing; the last is
        the headline's)
    stiffness_factors : contact-stiffness multipliers of the study (at the headline cut-off)
    members : ensemble members per case to start with (launch speeds as :func:`impact.stats.ensemble_members`)
    rel_tol : members are added until every driving 95 % CI of a headline case is within
        ``rel_tol`` of its mean ...
    study_rel_tol : ... and of a study case (lower cut-off, stiffness variant) within this one
        (its sampling half-width enters the model-form estimate) ...
    max_members : ... or this cap is reached (reported)
    seed : seed of the members' launch speeds
    v0_spread : relative half-range of the launch speeds
    faces : the free mass's contact faces and the materials of the contact
        (:class:`results.contact_faces.ContactFaces`)
    t_from, t_end : the statistics window, s (the device scenario's: 20 ms discarded, 200 ms kept)
    spring_force : restoring spring on the free mass, N (the device scenario's)
    """

    cutoff_factors: tuple[float, ...] = (0.5, 1.0, 2.0)
    stiffness_factors: tuple[float, ...] = (0.5, 2.0)
    members: int = 16
    rel_tol: float = 0.05
    study_rel_tol: float = 0.1
    max_members: int = 64
    seed: int = 20260
    v0_spread: float = 0.05
    faces: ContactFaces = ContactFaces()
    t_from: float = 0.02
    t_end: float = 0.22
    spring_force: float = 5.0

    def __post_init__(self):
        f = self.cutoff_factors
        if len(f) < 2 or any(not (0.1 <= x <= 10.0) for x in f) or any(b <= a for a, b in zip(f, f[1:])):
            raise ParameterError("cutoff_factors", f, "must be >= 2 increasing numbers in [0.1, 10]")
        if len(self.stiffness_factors) != 2 or any(not (0.01 <= x <= 100) for x in self.stiffness_factors):
            raise ParameterError("stiffness_factors", self.stiffness_factors, "must be two numbers in [0.01, 100]")
        check_integer("members", self.members, 2, 100_000)
        check_range("rel_tol", self.rel_tol, 0.0, 1.0, lo_open=True)
        check_range("study_rel_tol", self.study_rel_tol, 0.0, 1.0, lo_open=True)
        check_integer("max_members", self.max_members, self.members, 1_000_000)
        check_integer("seed", self.seed, 0)
        check_range("v0_spread", self.v0_spread, 0.0, 0.5)
        if not isinstance(self.faces, ContactFaces):
            raise ParameterError("faces", self.faces, "must be a results.contact_faces.ContactFaces")
        check_range("t_from", self.t_from, 0.0, 10.0, "s")
        check_range("t_end", self.t_end, self.t_from, 10.0, "s", lo_open=True)
        check_range("spring_force", self.spring_force, 0.0, 1e4, "N")


def contact_laws(design, m_free: float, e_horn: float, e_tool: float, settings: CompliantSettings,
                 stiffness_factor: float = 1.0):
    """The Hertz laws at the horn tip and at the tool face for the free mass ``m_free`` (kg).

    Returns
    -------
    (impact.hertz.HertzLaw, impact.hertz.HertzLaw, dict)
        Horn law, tool law, and their description (stiffnesses in N/m^1.5, face radius in m).
    """
    from geometry.materials import get_material
    from impact.hertz import HertzLaw, effective_modulus, hertz_stiffness

    def mat(name):
        return get_material(name, design.library)

    faces = settings.faces
    ball = mat(faces.free_mass_material)
    geom = faces.geometry(m_free, ball.density)
    k = {}
    for side, other in (("horn", mat(design.part_material("horn"))), ("tool", mat(faces.tool_material))):
        e_star = effective_modulus(other.youngs_modulus, other.poisson_ratio, ball.youngs_modulus, ball.poisson_ratio)
        k[side] = stiffness_factor * hertz_stiffness(e_star, geom)
    info = {"face": "flat" if faces.flat else "crowned", "geometry": geom.description,
            "face_radius_m": geom.radius_2 if not faces.flat else faces.face_radius,
            "edge_radius_m": faces.edge_radius, "face_tilt_deg": faces.face_tilt_deg,
            "radii_m": [geom.radius_1, geom.radius_2],
            "face_radius_from": "given" if faces.face_radius is not None else
            f"a {faces.free_mass_material} sphere of the free mass", "horn_stiffness_n_per_m1_5": k["horn"],
            "tool_stiffness_n_per_m1_5": k["tool"], "stiffness_factor": stiffness_factor,
            "e_horn": e_horn, "e_tool": e_tool}
    return HertzLaw(k["horn"], e_horn), HertzLaw(k["tool"], e_tool), info


def shortest_contact_time(design, masses, base, settings: CompliantSettings) -> float:
    """The shortest Hertz contact of the study, s: each free mass on a rigid flat at the fastest
    launch speed, through either law (the cut-off is chosen from it)."""
    v = base.v0 * (1.0 + settings.v0_spread)
    times = []
    for m in masses:
        horn, tool, _ = contact_laws(design, m, base.e2, base.e1, settings)
        times += [horn.contact_time(m, v), tool.contact_time(m, v)]
    return min(times)


def compliant_ensembles(cases, horn, laws: list, residual: float, settings: CompliantSettings, *,
                        rel_tols=None, engine=None) -> list[dict]:
    """Ensemble statistics of several cases of the compliant model on one horn (95 % CIs).

    Parameters
    ----------
    cases : list of impact.params.ImpactParams
        The cases (their ``v0`` the members' centre; the spring and ``t_end`` are set here).
    horn : impact.horn.ModalHorn
    laws : list of (HertzLaw, HertzLaw)
        Horn and tool laws of each case.
    residual : float
        The horn's static tip compliance of the modes left out, m/N.
    rel_tols : list of float, optional
        Each case's CI target (relative 95 % half-width of every driving quantity); default
        ``settings.rel_tol`` for every case. A study's cases, whose job is a model-form estimate
        that carries the CI of each difference, may take a looser one than the headline's.
    engine : callable, optional
        :func:`impact.compliant_engine.compliant_batch`'s signature (default: that batch).

    Returns
    -------
    list of dict
        Per case :data:`QUANTITIES` as :class:`impact.stats.Estimate`, ``members`` and ``converged``.
    """
    from impact.compliant_engine import compliant_batch
    from impact.stats import Scenario, StatsSettings

    engine = engine or compliant_batch
    sc = Scenario("device", settings.spring_force, settings.t_from, settings.t_end, "the compliant stage's window")
    rel_tols = [settings.rel_tol] * len(cases) if rel_tols is None else list(rel_tols)
    if len(rel_tols) != len(cases):
        raise ParameterError("rel_tols", f"{len(rel_tols)} values", f"must be one per case ({len(cases)})")
    st = [StatsSettings(rel_tol=r, n_start=settings.members, n_max=settings.max_members, seed=settings.seed,
                        v0_spread=settings.v0_spread) for r in rel_tols]
    res = engine(list(cases), horn, horn_law=[lw[0] for lw in laws], tool_law=[lw[1] for lw in laws],
                 horn_residual=residual, scenario=sc, settings=st)
    return [{**{q: r.estimates[q] for q in QUANTITIES}, "members": r.members, "converged": bool(r.converged)}
            for r in res]


def model_form(study: dict, quantity: str) -> dict:
    """The model-form estimate of ``quantity`` from one mass's study (see the module docstring):
    ``cutoff`` = |headline - next-lower cut-off|, ``stiffness`` = half the spread of the two
    stiffness variants, each with its sampling half-width (the two ensembles' CIs added in
    quadrature, halved with the spread); ``total`` = both differences plus both half-widths."""
    levels = study["cutoff"]
    top, below = levels[-1][quantity], levels[-2][quantity]
    lo, hi = (v[quantity] for v in study["stiffness"])

    def diff(a, b, scale):
        return scale * abs(a.mean - b.mean), scale * math.hypot(a.half_width, b.half_width)

    cut, cut_hw = diff(top, below, 1.0)
    stiff, stiff_hw = diff(hi, lo, 0.5)
    return {"cutoff": cut, "cutoff_sampling_half_width": cut_hw, "stiffness": stiff,
            "stiffness_sampling_half_width": stiff_hw, "total": cut + cut_hw + stiff + stiff_hw}


def stage_runs(base, design, masses, horns: dict, settings: CompliantSettings, engine) -> tuple[dict, dict]:
    """Every ensemble of the stage, one batch per horn: the lower cut-offs at the two end masses; at
    the headline cut-off every mass and the ends' stiffness variants. The headline cases hold
    ``settings.rel_tol``, the study's ``settings.study_rel_tol``.

    Parameters
    ----------
    base : impact.params.ImpactParams
    design : the design (materials of the contact)
    masses : free masses, kg (increasing)
    horns : dict
        cut-off (Hz) -> (impact.horn.ModalHorn, residual m/N, info); the largest is the headline's.
    settings : CompliantSettings
    engine : the compliant batch (:func:`impact.compliant_engine.compliant_batch`'s signature)

    Returns
    -------
    (dict, dict)
        ``study``: end mass -> {"cutoff": [...], "stiffness": [...]}; ``headline``: mass -> its estimates.
    """
    ends = sorted({masses[0], masses[-1]})
    study = {m: {"cutoff": [], "stiffness": []} for m in ends}
    top = max(horns)
    for cut, (horn, g, _) in horns.items():
        cases = [(m, 1.0) for m in (masses if cut == top else ends)]
        if cut == top:
            cases += [(m, f) for m in ends for f in settings.stiffness_factors]
        laws = [contact_laws(design, m, base.e2, base.e1, settings, f)[:2] for m, f in cases]
        tols = [settings.rel_tol if cut == top and f == 1.0 else settings.study_rel_tol for _, f in cases]
        res = compliant_ensembles([base.with_(m_free=m) for m, _ in cases], horn, laws, g, settings, rel_tols=tols,
                                  engine=engine)
        for (m, f), r in zip(cases, res):
            if f != 1.0:
                study[m]["stiffness"].append(r | {"stiffness_factor": f})
            elif m in study:
                study[m]["cutoff"].append(r | {"cutoff_hz": cut})
    headline = {m: r for (m, f), r in zip(cases, res) if f == 1.0}
    return study, headline


def _json(est: dict) -> dict:
    return {k: (v.to_dict() if hasattr(v, "to_dict") else v) for k, v in est.items()}


def compliant_stage(system, design, freq_hz: float, voltage: float, base, masses, settings: CompliantSettings, *,
                    q_mech: float | None = 100.0, drive=None, engine=None, say=None) -> dict:
    """The pipeline's compliant stage: the headline tool KE per free mass on the compliant model at
    the headline cut-off, and the convergence study at the lightest and heaviest free mass.

    Parameters
    ----------
    system : the k = 0 FE system of the run (its axial modes are the ones an impact excites)
    design : the design (materials of the contact)
    freq_hz : drive frequency, Hz
    voltage : drive amplitude, V
    base : impact.params.ImpactParams of the run (gap, tool, restitutions, launch speed)
    masses : free masses of the headline table, kg
    settings : CompliantSettings
    q_mech : assembled-transducer quality factor of the modes (without ``drive``)
    drive : the run's working-band fem.harmonic.ModalBasis on ``system`` (its losses, its response at
        the drive and its factorisation are reused: :func:`results.coupled.wideband_horn`)
    engine : the compliant batch (:func:`impact.compliant_engine.compliant_batch`'s signature)

    Returns
    -------
    dict with ``json`` (summary part), ``rows`` (per mass: the estimates and the model-form) and
    ``drill_horn`` (the headline horn, its residual and the settings of its contact laws).
    """
    from .coupled import truncated_horn, wideband_horn, wideband_modes

    say = say or (lambda msg: log.info("%s", msg))
    masses = sorted(masses)
    ends = sorted({masses[0], masses[-1]})
    t_c = shortest_contact_time(design, ends, base, settings)
    cutoffs = [round(f / t_c, -2) for f in settings.cutoff_factors]
    top = wideband_horn(system, freq_hz, cutoffs[-1], voltage, q_mech=q_mech, modes=wideband_modes(system, cutoffs[-1]),
                        drive=drive, say=say)
    horns = {c: truncated_horn(top[0], top[1], c, freq_hz) + (top[2],) for c in cutoffs[:-1]} | {cutoffs[-1]: top}
    study, headline = stage_runs(base, design, masses, horns, settings, engine)
    mf = {m: {q: model_form(study[m], q) for q in QUANTITIES} for m in ends}
    horn, g, info = horns[cutoffs[-1]]
    rel = {q: max(mf[e][q]["total"] / abs(study[e]["cutoff"][-1][q].mean) for e in ends) for q in QUANTITIES}
    rows = []
    for m in masses:
        est = headline[m]
        rows.append({"m_free_kg": m, **_json({k: v for k, v in est.items() if k != "cutoff_hz"}),
                     "model_form": {q: (mf[m][q]["total"] if m in mf else rel[q] * abs(est[q].mean))
                                    for q in QUANTITIES},
                     "model_form_from": "this mass's study" if m in mf else
                     "the larger relative estimate of the lightest and heaviest masses' studies"})
    top = rows[-1]
    say(f"      compliant model (modes to {cutoffs[-1] / 1e3:.0f} kHz, contact {t_c * 1e6:.1f} us): tool KE at "
        f"{masses[-1] * 1e3:g} g {top['mean_tool_ke_after_j']['mean'] * 1e3:.2f} "
        f"± {top['mean_tool_ke_after_j']['ci95_half_width'] * 1e3:.2f} (95 % CI) "
        f"± {top['model_form']['mean_tool_ke_after_j'] * 1e3:.2f} (model form) mJ")
    doc = {
        "contact_time_s": t_c, "cutoffs_hz": cutoffs, "cutoff_factors": list(settings.cutoff_factors),
        "modes_hz": info["modes_hz"], "residual_m_per_n": g, "tip_end_mass_kg": info["end_mass_kg"],
        "settings": {k: getattr(settings, k) for k in settings.__dataclass_fields__} | {"faces": settings.faces.to_dict()},
        "contact": contact_laws(design, masses[-1], base.e2, base.e1, settings)[2],
        "scenario": {"spring_force_n": settings.spring_force, "t_from_s": settings.t_from, "t_end_s": settings.t_end},
        "assumed": [f"the free mass's contact faces ({settings.faces.text()})", "restitutions e1, e2 (article Table 1)",
                    "q_mech of the assembled transducer", "contact stiffness within x0.5-x2 (the study's range)"],
        "calibrated": ["gap, tool stiffness k0 and damping c, launch speed v0: inherited from the fit of the "
                       "article scenario's 520 Hz tool-impact rate on the kinematic horn at 15 um; refitted under "
                       "this model (benchmarks/calibrate_compliant.py) no gap (1.5-2.6 mm), tool f_n (200-600 Hz) "
                       "or launch speed (4-8 m/s) reaches 520 Hz (105-169 Hz at 15 um)"],
        "study": {f"{m * 1e3:g} g": {"cutoff": [_json(x) for x in study[m]["cutoff"]],
                                     "stiffness": [_json(x) for x in study[m]["stiffness"]],
                                     "model_form": mf[m]} for m in ends},
        "rows": rows,
    }
    # the drilling stage drills on the same horn and contacts (results.drilling.drill_horn)
    return {"json": doc, "rows": rows, "drill_horn": (horn, g, settings)}



class CompliantWorker:
    """:func:`compliant_stage` in a worker thread beside the caller's own work (``with`` block):
    :meth:`start`, then :meth:`collect`.

    Its eigen solves (PARDISO) release the interpreter and its ensembles run on numba's threads, so
    on two cores it overlaps the caller's stages. OpenBLAS is held at one thread from its start to
    the end of the ``with`` block (the pipeline's stages beside it run at one thread already), so no
    thread count changes under its dense products: its numbers do not depend on what runs beside
    it. Its progress lines are kept (:attr:`lines`) and shown at :meth:`collect`. A run ended by a
    signal or an error does not wait for it (its answer would be dropped); the process then ends
    without finalisation (:func:`rpud_common.cli.start_native_worker`).
    """

    def __init__(self):
        self.lines: list[str] = []
        self.thread, self.done, self.box, self.limit = None, None, {}, None

    def __enter__(self) -> "CompliantWorker":
        return self

    def start(self, system, design, base, masses, settings: CompliantSettings, voltage: float,
              q_mech: float | None, drive=None) -> None:
        """Start :func:`compliant_stage` (same arguments; ``base.freq`` the drive frequency). The
        ``drive`` basis may be used by the caller meanwhile: its factor's solves are serialised
        (:class:`fem.solvers.Factor`)."""
        import time

        from fem.solvers import blas_threads
        from rpud_common.cli import start_native_worker

        self.limit = blas_threads(1)

        def work():
            try:
                t0 = time.perf_counter()
                out = compliant_stage(system, design, base.freq, voltage, base, masses, settings, q_mech=q_mech,
                                      drive=drive, say=self.lines.append)
                self.box["out"] = (out, time.perf_counter() - t0)
            except BaseException as exc:          # handed to the caller at collect
                self.box["error"] = exc

        self.thread, self.done = start_native_worker(work, "compliant")

    def collect(self, say) -> tuple[dict | None, float | None]:
        """Wait for the stage (an error in it is raised here) and pass its progress lines to ``say``.
        Returns ``(answer, its wall time in s)``, or ``(None, None)`` when it was not started."""
        out = (None, None)
        if self.thread is not None:
            self.done.wait()
            if "error" in self.box:
                raise self.box["error"]
            out = self.box["out"]
        for line in self.lines:
            say(line)
        return out

    def __exit__(self, *exc) -> None:
        # a thread count changed under the worker's running dense products corrupts OpenBLAS
        if self.limit is not None and (self.done is None or self.done.is_set()):
            self.limit.restore_original_limits()
