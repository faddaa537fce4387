"""The end-to-end run: design -> mesh -> resonance matching -> harmonic response -> A0 -> impacts.

Stages (each timed, each reported on the terminal through ``progress``):

1. **mesh** the design (Gmsh, second-order tetrahedra);
2. **match** horn and coupler to the target frequency (:func:`fem.matching.match`);
3. **harmonic**: modal-superposition admittance sweep over the resonance/anti-resonance band,
   the tip amplitude per volt at the working frequency (datasheet losses: the unloaded
   transducer; and the assembled-transducer quality factor ``q_mech``), ring-up at the drive,
   stress peaks against the material limits (:mod:`results.stress_stage`);
4. **A0**: the horn-tip amplitude at the drive voltage, coupled with the impacts it drives. The
   free mass loads the tip: a horn impact exchanges momentum ``J`` at horn velocity ``u'``, and
   the mean power ``P`` it draws (ensemble mean, device scenario: the drill in steady
   operation) is that of a viscous damper ``c = 2 P / (w A0)^2`` on the tip. The harmonic
   working point is solved again with that damper (a rank-one term on the modal coordinates)
   and the loop ``A0 -> impacts -> c -> A0`` is iterated to a fixed point (geometric-mean
   relaxation; it stops at 3 %, the confidence of the power estimate);
5. **impacts**: converged ensemble statistics (95 % CI within 3 %) of the drill-tool kinetic
   energy, impact rates and power versus free-mass weight, in both scenarios of
   :mod:`impact.stats`: ``device`` (restoring spring, steady operation; the headline, because
   it is how the drill runs) and ``article`` (first 50 ms, no spring: the article's Fig. 8),
   with the FE amplitude, next to the article's assumed 15 um;
6. **renders** of the working mode and its neighbours, VTU with every mode.

Assumption stated loudly: with datasheet losses (PZT-8 Qm 1000, Ti-6Al-4V Q 10 000) the
matched transducer at 225 V and exact resonance would reach ~0.5 mm at the tip and draw
kilowatts: an unloaded resonator. A bolted, mounted Langevin transducer loses far more in its
joints, bolt and mount; ``q_mech`` (default 100) is that assembled-transducer quality factor,
applied to every part. The datasheet result is reported as well.

Reproducibility: the impact stage is chaotic, so what it receives from the FE stages is rounded
at the hand-off (``A0`` and the horn mass to ``handoff_digits`` = 4 significant digits, 0.01 %,
far below the FE discretisation error; the frequency to 6, 0.02 Hz): threaded round-off in the
FE solvers never reaches it. MKL runs in its conditional-reproducibility mode as well
(:mod:`fem.solvers`), and the ensembles are seeded, so the same command gives the same numbers.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from impact.stats import MAX_MEMBERS
from rpud_common import (ParameterError, check_choice, check_integer, check_positive, check_range, provenance_record,
                         save_figure, write_json)
from rpud_common.result import Result

from fem.losses import ASSEMBLED_Q_MECH

from .coupled import round_sig  # noqa: F401  (the hand-off rounding; results.explore imports it from here)

log = logging.getLogger(__name__)

__all__ = ["PipelineSettings", "PipelineResult", "run_pipeline", "coupled_amplitudes"]

ARTICLE_A0 = 15e-6
"""The article's assumed horn-tip amplitude (Table 1), m."""


@dataclass(frozen=True)
class PipelineSettings:
    """Settings of the end-to-end run (SI units).

    Attributes
    ----------
    voltage : drive amplitude on the hot electrodes, V (the article's 225 V)
    voltage_given_as : "amplitude" or "rms": how the user gave the voltage (reported beside it)
    q_mech : quality factor of the assembled transducer applied to every part (None: datasheet;
        default :data:`fem.losses.ASSEMBLED_Q_MECH`, an assumption stated with its source)
    tan_delta : dielectric loss tangent of the ceramics (None: datasheet)
    losses_origin, losses_source : where q_mech and tan_delta come from (empty: derived from q_mech)
    mesh_size : mesh size override, m (None: the design's elements-per-wavelength rule)
    refine : mesh refinement factor scaling every size rule (geometry.sizing; < 1 refines)
    grade : grade the mesh toward the re-entrant edges (off: the 60 s budget is set on the ungraded mesh)
    mesher : "free" (default: the 60 s budget), "revolve" (stack, flange and horn swept: working mode
        ~+0.1 % instead of ~+0.5 %; default design 99.6 s instead of 45 s, the matching 56 s instead
        of 19 s) or "auto" (revolve where it can)
    match : run the resonance matching (else analyse the design as it is)
    couple_impacts : iterate A0 with the impact load on the horn tip
    m_free_values : free masses of the sweep, kg (0 is reported as zero energy: no free mass)
    reference_m_free : free mass for the headline A0 and the impact histories, kg (Table 1: 8 g)
    impact_rel_tol : target 95 % CI half-width of the impact statistics, relative to the mean
    impact_max_members : cap of the members per free mass (reaching it is reported)
    seed : seed of the ensemble members' launch speeds
    handoff_digits : significant digits of A0, frequency (+2) and horn mass handed to the impacts
    band : half-width of the admittance band around [f_r, f_a], relative
    n_points : frequencies in the admittance sweep
    render : write mode-shape PNGs and the VTU
    coupled_model : run the coupled model (FE transducer in the impact loop) beside the kinematic horn
    coupled_modes : modes of the reduced transducer (None: the tip-participation rule of fem.reduced)
    coupled_history_s : length of the coupled ring-up history with the reference free mass, s
    load : None, or "rock": also predict drilling under load (results.drilling)
    wob : weight on bit of the drilling stage, N
    """

    voltage: float = 225.0
    voltage_given_as: str = "amplitude"
    q_mech: float | None = ASSEMBLED_Q_MECH
    tan_delta: float | None = None
    losses_origin: str = ""
    losses_source: str = ""
    mesh_size: float | None = None
    refine: float = 1.0
    grade: bool = False
    mesher: str = "free"
    match: bool = True
    couple_impacts: bool = True
    m_free_values: tuple[float, ...] = (0.0, 0.001, 0.002, 0.003, 0.004, 0.005, 0.006, 0.007, 0.008)
    reference_m_free: float = 0.008
    impact_rel_tol: float = 0.03
    impact_max_members: int = 4096
    seed: int = 20260
    handoff_digits: int = 4
    band: float = 0.03
    n_points: int = 200
    render: bool = True
    coupled_model: bool = True
    coupled_modes: int | None = None
    coupled_history_s: float = 0.05
    load: str | None = None
    wob: float = 7.0

    def __post_init__(self):
        check_positive("voltage", self.voltage, "V")
        if self.q_mech is not None:
            check_positive("q_mech", self.q_mech)
        self.losses()                                   # checks tan_delta and the source
        self.drive()                                    # checks the convention
        if self.mesh_size is not None:
            check_positive("mesh_size", self.mesh_size, "m")
        from geometry.sizing import check_refine

        check_refine(self.refine)
        from geometry.revolve import MESHERS

        check_choice("mesher", self.mesher, MESHERS)
        if (not self.m_free_values or any((not np.isfinite(m)) or m < 0 or m > 10 for m in self.m_free_values)
                or max(self.m_free_values) <= 0):
            raise ParameterError("m_free_values", self.m_free_values,
                                 "must be masses in [0, 10] kg, at least one of them > 0")
        check_range("reference_m_free", self.reference_m_free, 0.0, 10.0, "kg", lo_open=True)
        check_range("impact_rel_tol", self.impact_rel_tol, 0.0, 1.0, lo_open=True)
        check_integer("impact_max_members", self.impact_max_members, 2, MAX_MEMBERS)
        check_integer("seed", self.seed, 0)
        check_integer("handoff_digits", self.handoff_digits, 2, 12)
        check_range("band", self.band, 0.0, 0.5, lo_open=True)
        check_integer("n_points", self.n_points, 3)
        if self.coupled_modes is not None:
            check_integer("coupled_modes", self.coupled_modes, 1, 64)
        check_range("coupled_history_s", self.coupled_history_s, 1e-3, 1.0, "s")
        if self.load not in (None, "rock"):
            raise ParameterError("load", self.load, "must be None or 'rock'")
        check_range("wob", self.wob, 0.0, 1e4, "N")

    def losses(self):
        """The :class:`fem.losses.DriveLosses` of these settings (value, origin and source)."""
        from fem.losses import DriveLosses, q_option_losses

        if self.losses_source:
            return DriveLosses(self.q_mech, self.tan_delta, self.losses_origin or "given", self.losses_source)
        if self.q_mech == ASSEMBLED_Q_MECH:
            return DriveLosses(tan_delta=self.tan_delta)
        return q_option_losses(0.0 if self.q_mech is None else self.q_mech, self.tan_delta)

    def drive(self):
        """The :class:`rpud_common.voltage.DriveVoltage` of these settings."""
        from rpud_common.voltage import DriveVoltage

        return DriveVoltage(self.voltage, self.voltage_given_as)

    def impact_settings(self):
        """The ensemble rule of the impact statistics."""
        from impact.stats import StatsSettings

        return StatsSettings(rel_tol=self.impact_rel_tol, n_start=min(64, self.impact_max_members),
                             n_max=self.impact_max_members, seed=self.seed)


# --------------------------------------------------------------------------- A0 <-> impacts


@dataclass
class CoupledAmplitude:
    """Fixed point of the horn amplitude under the impact load (one free mass)."""

    m_free: float
    A0: float
    A0_unloaded: float
    tip_damping: float
    impact_power_w: float
    history: list = field(default_factory=list)
    converged: bool = True
    note: str = ""


@dataclass(repr=False)
class PipelineResult(Result):
    """What :func:`run_pipeline` wrote, and its summary.

    ``repr`` shows the headline (working mode, A0, the headline sweep's slope and its heaviest
    free mass); :meth:`to_dict` is ``summary.json``; :meth:`save` copies the whole results
    folder (report, figures, renders, VTU) to another place, whole or not at all.
    """

    folder: Path
    summary: dict

    def _headline(self) -> str:
        from impact.stats import Estimate

        def est(d, scale=1.0):     # None (no statistics) shows as n/a
            mean, hw = (float("nan") if v is None else v * scale for v in (d["mean"], d["ci95_half_width"]))
            return Estimate(mean, hw, d.get("members", 0))

        s = self.summary
        wm, a0 = s["working_mode"], s["A0"]
        key = s["impacts"]["headline"]
        last = s["kinetic_energy_table"][-1]
        fit = s["impacts"][key]["fit_ke_vs_mass"]
        slope = "" if fit.get("slope") is None else (
            f", slope {Estimate(fit['slope'], fit.get('slope_ci95_half_width') or float('nan'), 0)} J/kg")
        return (f"{self.folder}: f_r {wm['f_r_hz']:.1f} Hz ({wm['label']}), A0 {a0['used_m'] * 1e6:.3g} um "
                f"at {a0['reference_m_free_kg'] * 1e3:g} g; {key}: tool KE "
                f"{est(last[key]['mean_tool_ke_after_j'], 1e3)} mJ at {last['m_free_kg'] * 1e3:g} g "
                f"(95 % CI){slope}")

    def _record(self) -> dict:
        return self.summary

    def save(self, folder, name=None) -> Path:
        """Copy the results folder to ``folder`` (replaced whole, or left as it was on failure).
        ``name`` is not used (the folder keeps its file names). Returns the new folder."""
        import shutil

        from rpud_common import atomic_folder

        folder = Path(folder)
        with atomic_folder(folder) as tmp:
            shutil.copytree(self.folder, tmp, dirs_exist_ok=True)
        return folder


def coupled_amplitudes(point_fn: Callable[[float], float], base, masses, *, omega: float, scenario="device",
                       settings=None, rtol: float = 0.03, max_iter: int = 8, digits: int = 4) -> dict:
    """Iterate ``A0 -> impact power -> tip damper -> A0`` to a fixed point for every free mass.

    The masses advance in lockstep: each iteration is one ensemble batch (:func:`impact.stats.
    ensemble_batch`) over the masses not yet converged. The power is the ensemble mean of the
    horn's work on the free mass per second in ``scenario``; the loop stops when the amplitude
    moves by less than ``rtol`` (3 %, the confidence of that mean). A mass still wandering after
    ``max_iter`` iterations gets the mean of its last three iterates (``converged`` False,
    ``note`` says so). Every amplitude is rounded to ``digits`` significant digits.

    Parameters
    ----------
    point_fn : callable(c) -> tip amplitude (m) of the harmonic working point with a tip damper
        ``c`` (N s/m)
    base : impact.params.ImpactParams (A0 and m_free are replaced)
    masses : free masses, kg
    omega : drive angular frequency, rad/s
    settings : impact.stats.StatsSettings (the ensemble rule)

    Returns
    -------
    dict mass -> CoupledAmplitude
    """
    from impact.stats import ensemble_batch

    a_free = round_sig(point_fn(0.0), digits)
    state = {m: CoupledAmplitude(m_free=m, A0=a_free, A0_unloaded=a_free, tip_damping=0.0,
                                 impact_power_w=0.0, converged=False) for m in masses}
    for _ in range(max_iter):
        active = [m for m in masses if not state[m].converged and not state[m].note]
        if not active:
            break
        stats = ensemble_batch([base.with_(m_free=m, A0=state[m].A0) for m in active], scenario, settings)
        for m, est in zip(active, stats):
            st = state[m]
            power = est["horn_power_w"]
            if not np.isfinite(power.mean):
                st.note = f"no impact statistics at A0 = {st.A0:.3g} m: {est.note}"
                log.warning("m_free %g kg: %s", m, st.note)
                continue
            st.impact_power_w = power.mean
            st.tip_damping = 2.0 * st.impact_power_w / (omega * st.A0) ** 2
            a_new = round_sig(point_fn(st.tip_damping), digits)
            st.history.append({"A0_m": st.A0, "impact_power_w": st.impact_power_w,
                               "impact_power_ci95_w": power.half_width,
                               "tip_damping_ns_per_m": st.tip_damping, "A0_next_m": a_new, "members": est.members})
            if abs(a_new / st.A0 - 1.0) < rtol:
                st.A0, st.converged = a_new, True
            else:
                st.A0 = round_sig(float(np.sqrt(st.A0 * a_new)), digits)   # geometric relaxation: the loop overshoots
    for st in state.values():
        if not st.converged and not st.note and st.history:
            st.A0 = round_sig(float(np.mean([h["A0_next_m"] for h in st.history[-3:]])), digits)
            st.note = f"not within {rtol:.0%} after {max_iter} iterations: mean of the last three iterates"
    return state


# --------------------------------------------------------------------------- pipeline



def run_pipeline(design, settings: PipelineSettings, out_dir, *,
                 progress: Callable[[str], None] | None = None) -> PipelineResult:
    """Run every stage and write the results into ``out_dir`` (created; the command line builds
    it under a temporary name and swaps it in whole). Returns a :class:`PipelineResult`.

    Files: ``summary.json``, ``report.md``, ``figures/*.png``, ``renders/*.png``, ``modes.vtu``.
    """
    import geometry
    from geometry.report import mesh_part_volumes
    from geometry.revolve import resolve_mesher
    from fem.harmonic import LossModel, harmonic_sweep, modal_basis, working_point
    from fem.matching import MatchSettings, default_tune, match, working_mode
    from fem.modal import modal_analysis
    from fem.transient import ring_up
    from impact.model import simulate
    from impact.params import ImpactParams
    from impact.stats import SCENARIOS
    from impact.sweeps import sweep

    from . import figures
    from .errors import annotate_summary, estimate_stage
    from .report import ke_rows, write_report
    from .stress_stage import stress_stage

    tune = default_tune(design) if settings.match else ()      # refused now, not after meshing
    mesher = resolve_mesher(design, settings.mesher)           # likewise
    out = Path(out_dir)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    say = progress or (lambda msg: log.info("%s", msg))
    timings: dict[str, float] = {}
    t_all = time.perf_counter()

    def stage(name, k, n=7):
        say(f"[{k}/{n}] {name}")
        return time.perf_counter()

    # 1. mesh
    t0 = stage("mesh", 1)
    mesh = geometry.build_mesh(design, mesh_size=settings.mesh_size, refine=settings.refine, grade=settings.grade,
                               mesher=mesher)
    timings["mesh_s"] = time.perf_counter() - t0
    say(f"      {mesh.n_cells} tetrahedra, {mesh.n_points} nodes ({timings['mesh_s']:.1f} s)")

    # 2. match
    t0 = stage("resonance matching" if settings.match else "modal analysis", 2)
    target = float(design.target_frequency)
    if settings.match:
        def show(rec):
            say(f"      {rec['stage']:5s} {rec['parameter']} = {rec['value_m'] * 1e3:8.4f} mm -> {rec['f_hz']:10.2f} Hz")

        m = match(design, MatchSettings(target_hz=target, mesh_size=settings.mesh_size, refine=settings.refine,
                                        grade=settings.grade, mesher=mesher, tune=tune), mesh=mesh, progress=show)
        design, mesh, system, modal, w = m.design, m.mesh, m.system, m.modal, m.working_index
        match_json = m.to_dict()
    else:
        from fem.assembly import assemble

        system = assemble(mesh)
        modal = modal_analysis(system, target, 4)
        w = working_mode(system, modal.f_r_hz, modal.vectors, target)
        match_json = None
    f_w = float(modal.f_r_hz[w])
    f_a = float(modal.f_a_hz[w])
    timings["match_s"] = time.perf_counter() - t0
    say(f"      working mode {w + 1}: f_r = {f_w:.1f} Hz, f_a = {f_a:.1f} Hz, k_eff = {modal.k_eff[w]:.3f}")

    # 3. harmonic
    t0 = stage("harmonic response", 3)
    surfaces = tuple(s for s in ("horn_tip", "teeth_tops") if s in mesh.facet_sets)
    loss = settings.losses().loss_model()
    basis = modal_basis(system, f_w, loss=loss, modes=modal)
    lo = f_w * (1 - settings.band)
    hi = (f_a if np.isfinite(f_a) else f_w) * (1 + settings.band)
    freqs = np.linspace(lo, hi, settings.n_points)
    sweep_h = harmonic_sweep(system, freqs, settings.voltage, loss=loss, basis=basis, surfaces=surfaces)
    wp = working_point(system, f_w, settings.voltage, loss=loss, surfaces=surfaces, basis=basis)
    basis_ds = modal_basis(system, f_w, loss=LossModel(), modes=modal, reuse=basis)
    wp_ds = working_point(system, f_w, settings.voltage, loss=LossModel(), surfaces=surfaces, basis=basis_ds)
    eta_w = float(basis.eta[w])
    tau = 2.0 / (eta_w * 2 * np.pi * f_w)            # amplitude time constant of the working mode
    ring = ring_up(system, f_w, settings.voltage, min(6 * tau, 0.05), loss=loss, basis=basis,
                   surfaces=surfaces[:1])
    stress = stress_stage(system, wp, out, render=settings.render, say=say)    # peaks vs limits; own timing
    timings["harmonic_s"] = time.perf_counter() - t0
    say(f"      tip {wp.tip_per_volt_m * 1e9:.1f} nm/V (q_mech {settings.q_mech}), "
        f"{wp_ds.tip_per_volt_m * 1e9:.1f} nm/V with datasheet losses; ring-up tau {tau * 1e3:.2f} ms")
    t0 = time.perf_counter()          # one solve on a 1.4x coarser mesh: the error of every FE output
    est = estimate_stage(design, settings, system, modal, w, wp, surfaces, target, say)
    timings["discretisation_error_s"] = time.perf_counter() - t0

    # 4. A0 with the impact load
    t0 = stage("A0 coupled with the impacts", 4)
    digits = settings.handoff_digits
    horn_mass = mesh_part_volumes(mesh)[1].get("horn", ImpactParams().m_horn)
    f_imp = round_sig(f_w, digits + 2)
    base = ImpactParams(A0=round_sig(wp.tip_amplitude_m, digits), freq=f_imp, m_horn=round_sig(horn_mass, digits))
    omega = 2 * np.pi * f_w
    stats_settings = settings.impact_settings()

    def point(c):
        return working_point(system, f_w, settings.voltage, loss=loss, surfaces=surfaces[:1], basis=basis,
                             tip_damping=c).tip_amplitude_m

    masses = [m for m in settings.m_free_values if m > 0]
    all_masses = sorted(set(masses) | {settings.reference_m_free})
    if settings.couple_impacts:
        coupled = coupled_amplitudes(point, base, all_masses, omega=omega, scenario="device",
                                     settings=stats_settings, digits=digits)
    else:
        coupled = {m: CoupledAmplitude(m, base.A0, base.A0, 0.0, 0.0) for m in all_masses}
    for m_free, c in coupled.items():
        say(f"      m_free {m_free * 1e3:4.1f} g: A0 = {c.A0 * 1e6:6.2f} um (unloaded {c.A0_unloaded * 1e6:.2f} um, "
            f"impact load {c.tip_damping:.2f} N s/m, {len(c.history)} iterations)")
    ref = coupled[settings.reference_m_free]
    timings["a0_s"] = time.perf_counter() - t0

    # 5. impacts
    t0 = stage("impact statistics", 5)
    base = base.with_(A0=ref.A0, m_free=settings.reference_m_free)
    hist_ref = simulate(SCENARIOS["device"].apply(base).with_(t_end=0.05))
    fe_amps = [coupled[m].A0 for m in masses]
    sweeps = {
        "device_fe": sweep(base, masses, scenario="device", settings=stats_settings, A0_values=fe_amps),
        "article_fe": sweep(base, masses, scenario="article", settings=stats_settings, A0_values=fe_amps),
        "article_15um": sweep(base.with_(A0=ARTICLE_A0, freq=20e3), masses, scenario="article",
                              settings=stats_settings),
    }
    timings["impacts_s"] = time.perf_counter() - t0
    # 5b. the coupled model: the FE transducer in the impact loop, beside the kinematic horn
    t0 = time.perf_counter()
    coupled_model = None
    if settings.coupled_model:
        from .coupled import coupled_stage

        coupled_model = coupled_stage(
            system, basis, f_imp, w, settings.voltage, base, masses, stats_settings, sweeps["device_fe"].rows,
            {m: coupled[m].A0 for m in masses}, wp.tip_amplitude_m, wp.power_w, f_w, f_a,
            n_modes=settings.coupled_modes, history_s=settings.coupled_history_s,
            reference_m_free=settings.reference_m_free, say=say)
    timings["coupled_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    from .operating_point import operating_point_stage

    operating = operating_point_stage(settings, system, modal, basis, f_w, surfaces, base, stats_settings, wp,
                                      ref, sweeps["device_fe"], coupled_amplitudes, say=say)
    timings["operating_point_s"] = time.perf_counter() - t0
    drilling = None
    if settings.load == "rock":                # opt-in: drilling under load
        from .drilling import drilling_stage

        t0 = time.perf_counter()
        drilling = drilling_stage(base, list(settings.m_free_values), {m: coupled[m].A0 for m in masses},
                                  settings.wob, settings.seed, say=say)
        timings["drilling_s"] = time.perf_counter() - t0
    top = {k: sw.rows[-1]["mean_tool_ke_after_j"].scaled(1e3) for k, sw in sweeps.items()}
    say(f"      tool KE after impact at {masses[-1] * 1e3:g} g (mJ, 95 % CI): device {top['device_fe']}, "
        f"article scenario {top['article_fe']} (FE A0), {top['article_15um']} (A0 = 15 um)")

    # 6. renders
    t0 = stage("renders", 6)
    renders, vtu = [], None
    if settings.render:
        from fem.render import around, render_modes, write_modes_vtu

        idx = around(w, modal.n_modes, 2)
        renders = render_modes(mesh, modal.shapes, out / "renders", modes=idx, frequencies=modal.f_r_hz,
                               labels=modal.labels)
        vtu = write_modes_vtu(mesh, modal.shapes, out / "modes.vtu", frequencies=modal.f_r_hz)
    timings["renders_s"] = time.perf_counter() - t0

    # 7. figures, summary, report
    t0 = stage("figures and report", 7)
    fig_dir = out / "figures"
    drawn = {
        "admittance": (figures.admittance(sweep_h, f_w, f_a), "admittance.png"),
        "tip_response": (figures.tip_response(sweep_h, f_w), "tip_response.png"),
        "ring_up": (figures.ring_up(ring, wp.tip_amplitude_m), "ring_up.png"),
        "impact_history": (figures.impact_history(hist_ref), "impact_history_50ms.png"),
        "kinetic_energy": (figures.kinetic_energy(sweeps, 0.0 in settings.m_free_values),
                           "kinetic_energy_vs_free_mass.png"),
        "a0_coupling": (figures.a0_coupling(coupled, est.relative("tip_per_volt_m") if est else None),
                        "a0_vs_free_mass.png"),
    }
    if coupled_model is not None:
        from . import coupled_figures as cf

        drawn["coupled_tip_envelope"] = (cf.tip_envelope(coupled_model["history"]["result"], wp.tip_amplitude_m),
                                         "coupled_tip_envelope.png")
        drawn["ke_three_horn_models"] = (cf.ke_three_models(coupled_model["kinematic"], sweeps["device_fe"].rows,
                                                            coupled_model["stats"]),
                                         "ke_vs_free_mass_three_horn_models.png")
        drawn["coupled_drive_power"] = (cf.drive_power(coupled_model["stats"], wp.power_w),
                                        "drive_power_vs_free_mass.png")
    if drilling is not None:
        from impact.drilling_plots import plot_depth_vs_mass

        drilling["result"].no_load = sweeps["device_fe"]
        drawn["drilling"] = (plot_depth_vs_mass(drilling["result"]), "depth_vs_free_mass.png")
    figs = {key: save_figure(axes, fig_dir / name) for key, (axes, name) in drawn.items()}
    ke_table = ke_rows(sweeps, 0.0 in settings.m_free_values, coupled)
    timings["figures_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_all
    summary = {
        "design": design.to_mapping(),
        "settings": {k: getattr(settings, k) for k in settings.__dataclass_fields__},
        "mesh": {"tetrahedra": mesh.n_cells, "nodes": mesh.n_points, "order": mesh.order, "ndof": system.ndof,
                 "mesher": mesher},
        "materials": system.materials_block(),
        "matching": match_json,
        "working_mode": {"index": w, "f_r_hz": f_w, "f_a_hz": f_a, "k_eff": float(modal.k_eff[w]),
                         "label": modal.labels[w], "modal_loss_factor": eta_w},
        "harmonic": {
            "voltage_v": settings.voltage, "voltage": settings.drive().record(), "q_mech": settings.q_mech,
            "losses": settings.losses().record(),
            "tip_per_volt_m": wp.tip_per_volt_m, "tip_amplitude_m": wp.tip_amplitude_m,
            "tip_per_volt_datasheet_losses_m": wp_ds.tip_per_volt_m,
            "tip_amplitude_datasheet_losses_m": wp_ds.tip_amplitude_m,
            "power_w": wp.power_w, "current_a": float(abs(wp.current_a)),
            "teeth_ellipse_ratio": wp.teeth_ellipse_ratio, "teeth_phase_deg": wp.teeth_phase_deg,
            "admittance_f_r_hz": sweep_h.f_r_hz, "admittance_f_a_hz": sweep_h.f_a_hz,
            "ring_up_tau_s": tau, "ring_up_steady_m": ring.steady_amplitude(surfaces[0]),
            "basis_reuse": "modal superposition on the matched short-circuit modes + residual "
                           "(one real factorisation at the modal shift)",
        },
        "A0": {"per_volt_m": wp.tip_per_volt_m, "used_m": ref.A0, "reference_m_free_kg": ref.m_free,
               "unloaded_m": ref.A0_unloaded, "impact_tip_damping_ns_per_m": ref.tip_damping,
               "impact_power_w": ref.impact_power_w, "converged": ref.converged, "note": ref.note,
               "iterations": ref.history,
               "per_mass": {f"{m * 1e3:g} g": c.A0 for m, c in coupled.items()},
               "article_assumption_m": ARTICLE_A0, "frequency_hz": f_w},
        "impacts": {"params": base.to_dict(), "headline": "device_fe",
                    "headline_why": "the device scenario is the drill as built and run: restoring spring on the "
                                    "free mass, steady operation, A0 from the FE model loaded by the impacts",
                    "handoff": {"A0_digits": digits, "freq_hz": f_imp, "m_horn_kg": base.m_horn},
                    **{k: sw.to_dict() for k, sw in sweeps.items()},
                    "sample_run_50ms": {"note": "one sample trajectory (device scenario, chaotic)",
                                        **hist_ref.summary()}},
        "kinetic_energy_table": ke_table,
        "coupled_model": coupled_model["json"] if coupled_model is not None else None,
        **({"drilling": drilling["json"]} if drilling is not None else {}),
        "stress": stress,
        "operating_point": operating,
        "files": {"figures": {k: str(Path(v).relative_to(out)) for k, v in figs.items()},
                  "renders": [str(Path(p).relative_to(out)) for p in renders],
                  "vtu": str(Path(vtu).relative_to(out)) if vtu else None},
        "timings": timings,
    }
    annotate_summary(summary, est)
    # in the summary itself, not only in the file: the report and PipelineResult.summary show it too
    summary["provenance"] = provenance_record()
    write_json(out / "summary.json", summary)
    write_report(summary, out / "report.md")
    say(f"done in {timings['total_s']:.1f} s")
    return PipelineResult(folder=out, summary=summary)
