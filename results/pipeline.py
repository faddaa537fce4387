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
6. **renders** of the working mode and its neighbours, VTU with every mode, and the stress
   picture and VTU (drawn in a worker process while stages 3-5 run);
7. **compliant contacts** (the headline, on the k = 0 sector path): the FE transducer's axial
   modes to a cut-off chosen from the contact time drive the free mass through Hertz contacts
   at the horn and the tool; tool kinetic energy, impact rate and power per free mass with a
   95 % CI and a model-form estimate from a convergence study (mode cut-off, contact stiffness)
   run every time (:mod:`results.stage_compliant`). The stages 1-5 models above become its
   comparison rows.

Pieces of stage 3 run side by side on two cores (:mod:`results.stage_beside`): the harmonic
stage and the bolt's unit preload state beside the teeth motion's finer mesh, then the preload
window, the band response and the stress fields (a worker thread) beside the discretisation-error
estimate on the coarser mesh; the teeth motion's finer mesh is solved in a worker thread after
them; ``timings`` therefore holds overlapping intervals (``discretisation_error_s``
lies inside ``harmonic_s``).
Beside stages 4-5 run the operating point's modal bases at Q/2 and 2Q (a worker thread) and the
renders (a worker process); ``operating_point_s`` and ``renders_s`` count what is left after them.
The compliant stage runs in a worker thread from the end of the harmonic solve to the end of
stage 5 (``compliant_s`` its own time, ``compliant_wait_s`` what the run waited for it after
stage 5).

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
from rpud_common import (ParameterError, check_integer, check_positive, check_range, provenance_record,
                         save_figure, write_json)
from rpud_common.result import Result

from fem.losses import ASSEMBLED_Q_MECH

from .contact_faces import ContactFaces
from .stage_impacts import CoupledAmplitude, coupled_amplitudes

log = logging.getLogger(__name__)

__all__ = ["PipelineSettings", "PipelineResult", "run_pipeline", "coupled_amplitudes", "CoupledAmplitude"]

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
    admittance : a measured admittance sweep (CSV, :mod:`fem.bvd`) whose fit sets q_mech and tan_delta
    mesh_size : mesh size override, m (None: the design's elements-per-wavelength rule)
    refine : mesh refinement factor scaling every size rule (geometry.sizing; < 1 refines)
    grade : grade the mesh toward the re-entrant edges (None: the path's own rule, the sector's
        notch grading on the sector path, graded on the whole drill)
    mesher : whole-drill mesher, "auto" (default: swept where it can be), "free" or "revolve"; a
        mesher other than auto asks for the whole drill
    path : "sector" (the k = 0 swept sector: converged within ~0.03 % at refine 1 on the default
        design), "whole" or None (default: the sector where the design can be swept,
        :func:`fem.sector_system.default_path`)
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
    losses_bracket : recompute the headline at Q/2 and 2Q (the losses' model-form range,
        :mod:`results.operating_point`); off, the report says the range was not computed
    compliant_members : ensemble members per case of the compliant-contact model and its convergence
        study to start with (:mod:`results.stage_compliant`, the report's headline; 0: the stage is
        skipped; it runs on the k = 0 sector path)
    compliant_max_members : members per case are added until every driving 95 % CI is within its
        target (below) or this cap is reached (reported)
    compliant_rel_tol : the CI target of the headline cases (the full cut-off, nominal stiffness),
        relative to the mean
    compliant_study_rel_tol : the CI target of the convergence study's cases (lower cut-offs,
        stiffness x0.5 / x2): their differences enter the model-form estimate with their own 95 %
        half-widths, so a looser target widens that estimate instead of hiding noise
    faces : the free mass's contact faces of the compliant model (:class:`results.contact_faces.ContactFaces`)
    load : None, or "rock": also predict drilling under load (results.drilling)
    wob : weight on bit of the drilling stage, N
    """

    voltage: float = 225.0
    voltage_given_as: str = "amplitude"
    q_mech: float | None = ASSEMBLED_Q_MECH
    tan_delta: float | None = None
    losses_origin: str = ""
    losses_source: str = ""
    admittance: str | None = None
    mesh_size: float | None = None
    refine: float = 1.0
    grade: bool | None = None
    mesher: str = "auto"
    path: str | None = None
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
    losses_bracket: bool = True
    compliant_members: int = 16
    compliant_max_members: int = 64
    compliant_rel_tol: float = 0.05
    compliant_study_rel_tol: float = 0.1
    faces: ContactFaces = ContactFaces()
    load: str | None = None
    wob: float = 7.0

    def __post_init__(self):
        check_positive("voltage", self.voltage, "V")
        if self.q_mech is not None:
            check_positive("q_mech", self.q_mech)
        self.losses()                                   # checks tan_delta and the source
        self.drive()                                    # checks the convention
        self.mesh_options()
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
        if self.compliant_members:
            check_integer("compliant_members", self.compliant_members, 2, 100_000)
            check_integer("compliant_max_members", self.compliant_max_members, self.compliant_members, 1_000_000)
        check_range("compliant_rel_tol", self.compliant_rel_tol, 0.0, 1.0, lo_open=True)
        check_range("compliant_study_rel_tol", self.compliant_study_rel_tol, 0.0, 1.0, lo_open=True)
        if not isinstance(self.faces, ContactFaces):
            raise ParameterError("faces", self.faces, "must be a results.contact_faces.ContactFaces")
        if self.load not in (None, "rock"):
            raise ParameterError("load", self.load, "must be None or 'rock'")
        check_range("wob", self.wob, 0.0, 1e4, "N")

    def compliant_settings(self):
        """The :class:`results.stage_compliant.CompliantSettings` of these settings."""
        from .stage_compliant import CompliantSettings

        return CompliantSettings(members=self.compliant_members, max_members=self.compliant_max_members,
                                 rel_tol=self.compliant_rel_tol, study_rel_tol=self.compliant_study_rel_tol,
                                 seed=self.seed, faces=self.faces)

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

    def mesh_options(self):
        """How the design is meshed (:class:`results.stage_fe.MeshOptions`; checks the options)."""
        from .stage_fe import MeshOptions

        return MeshOptions(mesh_size=self.mesh_size, refine=self.refine, grade=self.grade, mesher=self.mesher,
                           path=self.path)

    def impact_settings(self):
        """The ensemble rule of the impact statistics."""
        from .stage_impacts import stats_settings

        return stats_settings(self.impact_rel_tol, self.impact_max_members, self.seed)


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
        wm, a0, head = s["working_mode"], s["A0"], s.get("headline")
        if head and head["model"] == "compliant_model":
            ke, mf = head["mean_tool_ke_after_j"], head["mean_tool_ke_after_j"]["model_form"]
            return (f"{self.folder}: f_r {wm['f_r_hz']:.1f} Hz ({wm['label']}); compliant model: tool KE "
                    f"{est(ke, 1e3)} ± {mf * 1e3:.2g} mJ at {head['m_free_kg'] * 1e3:g} g (95 % CI ± model form)")
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


# --------------------------------------------------------------------------- pipeline


class _Clock:
    """Stage announcements on the terminal (``[k/n] name``) and the ``timings`` record."""

    def __init__(self, say: Callable[[str], None], n: int = 7):
        self.say, self.n, self.k = say, n, 0
        self.timings: dict[str, float] = {}
        self.t_all = time.perf_counter()

    def stage(self, name: str) -> float:
        self.k += 1
        self.say(f"[{self.k}/{self.n}] {name}")
        return time.perf_counter()

    def took(self, key: str, t0: float) -> float:
        self.timings[key] = time.perf_counter() - t0
        return self.timings[key]


@dataclass
class _Run:
    """The stage results of one run, gathered for the figures and ``summary.json``."""

    settings: PipelineSettings
    out: Path
    meshed: object = None
    matched: object = None
    harm: object = None
    resp: object = None
    stress: dict | None = None
    est: object = None
    base: object = None
    amps: dict = field(default_factory=dict)
    hist_ref: object = None
    sweeps: dict = field(default_factory=dict)
    coupled_model: dict | None = None
    compliant: dict | None = None
    compliant_note: str = ""
    operating: dict | None = None
    bolt: object = None
    preload: dict | None = None
    op_fine: dict | None = None
    drilling: dict | None = None
    rotor: dict | None = None
    teeth: object = None
    teeth_note: str = ""
    renders: list = field(default_factory=list)
    vtu: object = None


def run_pipeline(design, settings: PipelineSettings, out_dir, *,
                 progress: Callable[[str], None] | None = None) -> PipelineResult:
    """Run every stage and write the results into ``out_dir`` (created; the command line builds
    it under a temporary name and swaps it in whole). Returns a :class:`PipelineResult`.

    Files: ``summary.json``, ``report.md``, ``figures/*.png``, ``renders/*.png``, ``modes.vtu``.
    """
    from fem.matching import default_tune

    from .stage_fe import mesh_stage

    tune = default_tune(design) if settings.match else ()      # refused now, not after meshing
    options = settings.mesh_options().resolved(design)         # likewise
    run = _Run(settings, Path(out_dir))
    (run.out / "figures").mkdir(parents=True, exist_ok=True)
    say = progress or (lambda msg: log.info("%s", msg))
    clock = _Clock(say)

    t0 = clock.stage("mesh")
    run.meshed = mesh_stage(design, options)
    clock.took("mesh_s", t0)
    mesh = run.meshed.mesh
    say(f"      {mesh.n_cells} tetrahedra, {mesh.n_points} nodes ({clock.timings['mesh_s']:.1f} s)")
    from .renders import Renders
    from .stage_compliant import CompliantWorker

    with Renders(run) as renders, CompliantWorker() as compliant:     # beside the later stages
        teeth = _fe_stages(run, clock, tune, say, renders, compliant)
        renders.modes()
        base, masses = _impact_stages(run, clock, say)
        _rotor_stage(run, clock, say, teeth)      # after the impacts: the teeth job's solve ran beside them
        t0 = time.perf_counter()
        run.compliant, seconds = compliant.collect(say)
        if seconds is not None:
            clock.timings["compliant_s"] = seconds
            clock.took("compliant_wait_s", t0)
        if run.settings.load == "rock":
            _drilling_stage(run, clock, say, base, masses)
        t0 = clock.stage("renders")
        renders.collect()
        clock.took("renders_s", t0)
    t0 = clock.stage("figures and report")
    figs = _figures(run)
    summary = _summary(run, figs)
    clock.took("figures_s", t0)
    clock.took("total_s", clock.t_all)
    summary["timings"] = clock.timings
    from .errors import annotate_summary
    from fem.operating_errors import annotate_operating_point, error_lines
    from .report import write_report

    annotate_summary(summary, run.est, teeth=None if run.teeth is None else run.teeth.est)
    annotate_operating_point(summary, run.op_fine, run.est)
    for line in error_lines(summary):
        say(f"      {line}")
    # in the summary itself, not only in the file: the report and PipelineResult.summary show it too
    summary["provenance"] = provenance_record()
    write_json(run.out / "summary.json", summary)
    write_report(summary, run.out / "report.md")
    say(f"done in {clock.timings['total_s']:.1f} s")
    return PipelineResult(folder=run.out, summary=summary)


def _fe_stages(run: _Run, clock: _Clock, tune, say, renders: "Renders", compliant):
    """Matching, harmonic response, stress and the discretisation error of the FE outputs (the
    stress picture and VTU drawn by ``renders``' worker; the compliant stage started in
    ``compliant``'s as soon as the working frequency is known). Returns the teeth motion's job
    (:func:`results.stage_teeth.start_job`), still solving."""
    from .operating_point import preload_state
    from .stage_beside import harmonic_beside_teeth_mesh, response_beside_estimate
    from .stage_fe import match_stage
    from .stage_teeth import start_job
    from .stress_stage import stress_stage

    st = run.settings
    t0 = clock.stage("resonance matching" if st.match else "modal analysis")

    def show(rec):
        say(f"      {rec['stage']:5s} {rec['parameter']} = {rec['value_m'] * 1e3:8.4f} mm -> {rec['f_hz']:10.2f} Hz")

    m = run.matched = match_stage(run.meshed, match=st.match, tune=tune, progress=show)
    clock.took("match_s", t0)
    say(f"      working mode {m.w + 1}: f_r = {m.f_r_hz:.1f} Hz, f_a = {m.f_a_hz:.1f} Hz, k_eff = {m.k_eff:.3f}")
    t0 = clock.stage("harmonic response")
    if st.admittance:                         # the measured losses replace the assumed ones
        from .operating_point import measured_settings

        st = run.settings = measured_settings(st, m.system, m.modal, m.w, say)
    # the teeth motion's finer mesh (solved beside what follows) beside the harmonic stage
    h, unit, teeth = harmonic_beside_teeth_mesh(m, st, lambda: start_job(m, st))
    run.harm, run.teeth_note = h, teeth.note
    _start_compliant(run, compliant)
    run.bolt = preload_state(m.design, unit)
    preloaded, estimated, state = response_beside_estimate(run, clock, unit)
    teeth.release()                           # after the estimate's and the band's solves: memory
    clock.took("harmonic_s", t0)
    preloaded.replay(say)
    say(f"      tip {h.wp.tip_per_volt_m * 1e9:.1f} nm/V (q_mech {st.q_mech}), "
        f"{run.resp.wp_datasheet.tip_per_volt_m * 1e9:.1f} nm/V with datasheet losses; "
        f"ring-up tau {run.resp.tau * 1e3:.2f} ms")
    estimated.replay(say)
    run.stress = stress_stage(m.system, h.wp, run.out, render=st.render, say=say, coarse=run.est, preload=run.bolt,
                              mesh=m.options.label(m.design), submit=renders.submit, state=state)  # own timing
    return teeth


def _rotor_stage(run: _Run, clock: _Clock, say, teeth) -> None:
    """The rotary unit driven by the teeth (designs with teeth), on the teeth motion of the finer
    mesh when its job ran (waited for here)."""
    from .rotor_stage import pipeline_rotor_stage
    from .stage_teeth import collect_job

    t0 = time.perf_counter()
    run.teeth, wp, est = collect_job(teeth, run.harm.wp, run.matched, run.est, say)
    clock.took("teeth_wait_s", t0)
    t0 = time.perf_counter()
    run.rotor = pipeline_rotor_stage(run.matched.design, wp, run.harm.f_w, est, run.settings.wob, say=say)
    clock.took("rotor_s", t0)


def _impact_stages(run: _Run, clock: _Clock, say) -> tuple:
    """A0 under the impact load, the impact statistics, the coupled model and the operating point;
    returns the impact stage's base parameters and its free masses.

    The operating point's modal bases at Q/2 and 2Q need only the FE system: a worker thread
    builds them while the impact stages run (their solves and products release the interpreter,
    the impact kernels run on the other core), beside the teeth motion's solve (a
    :class:`results.stage_teeth.TeethJob`): the bases solve on the run's own factorisation, so
    they add little memory to the teeth's. OpenBLAS stays on one thread across both, as beside
    the estimate, so the numbers do not depend on which runs when.
    """
    from concurrent.futures import ThreadPoolExecutor

    from fem.solvers import blas_threads

    from .operating_point import bracket_bases, operating_point_stage

    st, h, m = run.settings, run.harm, run.matched
    with blas_threads(1), ThreadPoolExecutor(max_workers=1, thread_name_prefix="bracket") as pool:
        bracket = pool.submit(bracket_bases, st, m.system, m.modal, h.basis, h.f_w)
        base, masses = _loaded_impacts(run, clock, say)
        bases = bracket.result()
    t0 = time.perf_counter()
    run.operating = operating_point_stage(st, m.system, m.modal, h.basis, h.f_w, h.surfaces, base,
                                          st.impact_settings(), h.wp, run.amps[st.reference_m_free],
                                          run.sweeps["device_fe"], coupled_amplitudes, say=say, bases=bases)
    run.operating["preload"] = run.preload
    clock.took("operating_point_s", t0)
    top = {k: sw.rows[-1]["mean_tool_ke_after_j"].scaled(1e3) for k, sw in run.sweeps.items()}
    say(f"      tool KE after impact at {masses[-1] * 1e3:g} g (mJ, 95 % CI): device {top['device_fe']}, "
        f"article scenario {top['article_fe']} (FE A0), {top['article_15um']} (A0 = 15 um)")
    return base, masses


def _compliant_no_load(run: _Run, model: str):
    """The compliant headline's no-load tool KE per free mass for the drilling figure when the
    drilling ran on the compliant model (None otherwise: the kinematic device sweep is drawn)."""
    if run.compliant is None or model == "kinematic":
        return None
    rows = run.compliant["json"]["rows"]
    ke = [r["mean_tool_ke_after_j"] for r in rows]
    return ([r["m_free_kg"] for r in rows], [k["mean"] for k in ke], [k["ci95_half_width"] for k in ke],
            "no-load tool KE after impact, compliant model (device scenario, 95 % CI)")


def _drilling_stage(run: _Run, clock: _Clock, say, base, masses) -> None:
    """(opt-in) drilling under load: on the compliant stage's horn and contacts when it ran, with
    the kinematic model at the loaded amplitudes as its comparison (:mod:`results.drilling`)."""
    from .drilling import drill_horn, drilling_stage

    st = run.settings
    t0 = time.perf_counter()
    run.drilling = drilling_stage(base, list(st.m_free_values), {k: run.amps[k].A0 for k in masses},
                                  st.wob, st.seed, say=say, horn_members=st.compliant_members or 16,
                                  horn=drill_horn(run.compliant, run.matched.design, base, st.m_free_values))
    clock.took("drilling_s", t0)


def _loaded_impacts(run: _Run, clock: _Clock, say):
    """A0 under the impact load, the impact statistics and the coupled model; returns the impact
    parameters handed over (at the reference free mass) and the free masses."""
    from impact.model import simulate
    from impact.stats import SCENARIOS

    from .stage_impacts import amplitude_stage, handoff, impact_stage

    st, h = run.settings, run.harm
    stats_settings = st.impact_settings()
    t0 = clock.stage("A0 coupled with the impacts")
    base = handoff(h, st.handoff_digits)
    masses = [m for m in st.m_free_values if m > 0]
    all_masses = sorted(set(masses) | {st.reference_m_free})
    run.amps = amplitude_stage(h, base, all_masses, voltage=st.voltage, settings=stats_settings,
                               couple=st.couple_impacts, digits=st.handoff_digits)
    for m_free, c in run.amps.items():
        say(f"      m_free {m_free * 1e3:4.1f} g: A0 = {c.A0 * 1e6:6.2f} um (unloaded {c.A0_unloaded * 1e6:.2f} um, "
            f"impact load {c.tip_damping:.2f} N s/m, {len(c.history)} iterations)")
    clock.took("a0_s", t0)
    t0 = clock.stage("impact statistics")
    base = run.base = base.with_(A0=run.amps[st.reference_m_free].A0, m_free=st.reference_m_free)
    run.hist_ref = simulate(SCENARIOS["device"].apply(base).with_(t_end=0.05))
    article = {m: CoupledAmplitude(m, ARTICLE_A0, ARTICLE_A0, 0.0, 0.0) for m in masses}
    run.sweeps = {
        "device_fe": impact_stage(base, masses, run.amps, scenario="device", settings=stats_settings),
        "article_fe": impact_stage(base, masses, run.amps, scenario="article", settings=stats_settings),
        "article_15um": impact_stage(base.with_(A0=ARTICLE_A0, freq=20e3), masses, article, scenario="article",
                                     settings=stats_settings),
    }
    clock.took("impacts_s", t0)
    t0 = time.perf_counter()      # the coupled model: the FE transducer in the impact loop, beside the kinematic horn
    if st.coupled_model:
        from .coupled import coupled_stage

        m = run.matched
        run.coupled_model = coupled_stage(
            m.system, h.basis, base.freq, m.w, st.voltage, base, masses, stats_settings,
            run.sweeps["device_fe"].rows, {k: run.amps[k].A0 for k in masses}, h.wp.tip_amplitude_m, h.wp.power_w,
            m.f_r_hz, m.f_a_hz, n_modes=st.coupled_modes, history_s=st.coupled_history_s,
            reference_m_free=st.reference_m_free, say=say)
    clock.took("coupled_s", t0)
    return base, masses


def _start_compliant(run: _Run, worker) -> None:
    """Start the compliant stage in ``worker`` (:class:`results.stage_compliant.CompliantWorker`),
    or note why it is skipped. It needs only the matched k = 0 system, the drive and the impact
    parameters of the hand-off: its horn is driven from the voltage through the FE modes, so the
    damper-loaded A0 of stage 4 does not enter it."""
    from fem.sector_system import SectorSystem

    from .stage_impacts import handoff

    st, m = run.settings, run.matched
    if not st.compliant_members:
        run.compliant_note = "the compliant stage was not asked for (compliant_members 0)"
    elif not isinstance(m.system, SectorSystem):
        run.compliant_note = ("the compliant stage runs on the k = 0 sector path only (the whole drill's wide-band "
                              "axial modes would cost several times the sector's)")
        worker.lines.append(f"      compliant model skipped: {run.compliant_note}")
    else:
        worker.start(m.system, m.design, handoff(run.harm, st.handoff_digits), [x for x in st.m_free_values if x > 0],
                     st.compliant_settings(), st.voltage, st.q_mech, drive=run.harm.basis)


def _figures(run: _Run) -> dict:
    """Every figure of the report, written into ``figures/``; returns key -> path."""
    from . import figures

    m, h, r, sw = run.matched, run.harm, run.resp, run.sweeps
    with_zero = 0.0 in run.settings.m_free_values
    kinematic_head = None if run.compliant is not None else "device_fe"      # else comparison rows
    drawn = {}
    if run.compliant is not None:            # the headline figure first
        from .coupled_figures import compliant_energy_power

        drawn["compliant_energy_power"] = (compliant_energy_power(run.compliant["json"]),
                                           "compliant_tool_energy_and_power.png")
    drawn |= {
        "admittance": (figures.admittance(r.sweep, m.f_r_hz, m.f_a_hz), "admittance.png"),
        "tip_response": (figures.tip_response(r.sweep, m.f_r_hz), "tip_response.png"),
        "ring_up": (figures.ring_up(r.ring, h.wp.tip_amplitude_m), "ring_up.png"),
        "impact_history": (figures.impact_history(run.hist_ref), "impact_history_50ms.png"),
        "kinetic_energy": (figures.kinetic_energy(sw, with_zero, headline=kinematic_head),
                           "kinetic_energy_vs_free_mass.png"),
        "a0_coupling": (figures.a0_coupling(run.amps, run.est.relative("tip_per_volt_m") if run.est else None),
                        "a0_vs_free_mass.png"),
    }
    if run.coupled_model is not None:
        from . import coupled_figures as cf

        cm = run.coupled_model
        drawn["coupled_tip_envelope"] = (cf.tip_envelope(cm["history"]["result"], h.wp.tip_amplitude_m),
                                         "coupled_tip_envelope.png")
        drawn["ke_three_horn_models"] = (cf.ke_three_models(cm["kinematic"], sw["device_fe"].rows, cm["stats"],
                                                            damper_is_headline=kinematic_head is not None),
                                         "ke_vs_free_mass_three_horn_models.png")
        drawn["coupled_drive_power"] = (cf.drive_power(cm["stats"], h.wp.power_w), "drive_power_vs_free_mass.png")
    if run.drilling is not None:
        from impact.drilling_plots import plot_depth_vs_mass

        res = run.drilling["result"]
        res.no_load = sw["device_fe"]
        drawn["drilling"] = (plot_depth_vs_mass(res, no_load_ke=_compliant_no_load(run, res.model)),
                             "depth_vs_free_mass.png")
    if run.rotor is not None:
        from impact.rotor_plots import plot_contact_phases, plot_torque_speed

        drawn["rotor_torque_speed"] = (plot_torque_speed(run.rotor["result"]), "rotor_torque_speed.png")
        drawn["rotor_contact_phases"] = (plot_contact_phases(run.rotor["result"]), "rotor_contact_phases.png")
    return {key: save_figure(axes, run.out / "figures" / name) for key, (axes, name) in drawn.items()}


def _harmonic_record(run: _Run) -> dict:
    st, h, r = run.settings, run.harm, run.resp
    wp, wp_ds = h.wp, r.wp_datasheet
    return {
        "voltage_v": st.voltage, "voltage": st.drive().record(), "q_mech": st.q_mech,
        "losses": st.losses().record(),
        "tip_per_volt_m": wp.tip_per_volt_m, "tip_amplitude_m": wp.tip_amplitude_m,
        "tip_per_volt_datasheet_losses_m": wp_ds.tip_per_volt_m,
        "tip_amplitude_datasheet_losses_m": wp_ds.tip_amplitude_m,
        "power_w": wp.power_w, "current_a": float(abs(wp.current_a)),
        **_teeth_record(run),
        "admittance_f_r_hz": r.sweep.f_r_hz, "admittance_f_a_hz": r.sweep.f_a_hz,
        "ring_up_tau_s": r.tau, "ring_up_steady_m": r.ring.steady_amplitude(h.surfaces[0]),
        "basis_reuse": "modal superposition on the matched short-circuit modes + residual "
                       "(one real factorisation at the modal shift)",
    }


def _teeth_record(run: _Run) -> dict:
    """The teeth motion's keys of the harmonic record: the finer mesh's values and the
    ``teeth_mesh`` block when it ran, else the run's working point's and why."""
    t = run.teeth
    wp = run.harm.wp if t is None else t.wp
    return {"teeth_ellipse_ratio": wp.teeth_ellipse_ratio, "teeth_phase_deg": wp.teeth_phase_deg,
            "teeth_mesh": t.record() if t is not None else {"note": run.teeth_note}}


def _a0_record(run: _Run) -> dict:
    st, m = run.settings, run.matched
    ref = run.amps[st.reference_m_free]
    return {"per_volt_m": run.harm.wp.tip_per_volt_m, "used_m": ref.A0, "reference_m_free_kg": ref.m_free,
            "unloaded_m": ref.A0_unloaded, "impact_tip_damping_ns_per_m": ref.tip_damping,
            "impact_power_w": ref.impact_power_w, "converged": ref.converged, "note": ref.note,
            "iterations": ref.history,
            "per_mass": {f"{k * 1e3:g} g": c.A0 for k, c in run.amps.items()},
            "article_assumption_m": ARTICLE_A0, "frequency_hz": m.f_r_hz}


def _summary(run: _Run, figs: dict) -> dict:
    """``summary.json`` without the timings, error annotations and provenance (added by the caller)."""
    from .headline import headline_record
    from .report import ke_rows

    st, m, out = run.settings, run.matched, run.out
    doc = {
        "design": m.design.to_mapping(),
        "settings": {k: (v.to_dict() if hasattr(v, "to_dict") else v)   # plain JSON values, in memory too
                     for k, v in ((k, getattr(st, k)) for k in st.__dataclass_fields__)},
        "mesh": {"tetrahedra": m.mesh.n_cells, "nodes": m.mesh.n_points, "order": m.mesh.order,
                 "ndof": m.system.ndof, "mesher": m.options.mesher, "path": m.options.path,
                 "label": m.options.label(m.design)},
        "materials": m.system.materials_block(),
        "matching": m.matching.to_dict() if m.matching is not None else None,
        "working_mode": {"index": m.w, "f_r_hz": m.f_r_hz, "f_a_hz": m.f_a_hz, "k_eff": m.k_eff,
                         "label": m.modal.labels[m.w], "modal_loss_factor": run.harm.eta},
        "harmonic": _harmonic_record(run),
        "A0": _a0_record(run),
        "impacts": {"params": run.base.to_dict(), "headline": "device_fe",
                    "headline_why": "the device scenario is the drill as built and run: restoring spring on the "
                                    "free mass, steady operation, A0 from the FE model loaded by the impacts",
                    "handoff": {"A0_digits": st.handoff_digits, "freq_hz": run.base.freq, "m_horn_kg": run.base.m_horn},
                    **{k: sw.to_dict() for k, sw in run.sweeps.items()},
                    "sample_run_50ms": {"note": "one sample trajectory (device scenario, chaotic)",
                                        **run.hist_ref.summary()}},
        "kinetic_energy_table": ke_rows(run.sweeps, 0.0 in st.m_free_values, run.amps),
        "coupled_model": run.coupled_model["json"] if run.coupled_model is not None else None,
        "compliant_model": run.compliant["json"] if run.compliant is not None else None,
        **({"drilling": run.drilling["json"]} if run.drilling is not None else {}),
        **({"rotor": run.rotor["json"]} if run.rotor is not None else {}),
        "stress": run.stress,
        "operating_point": run.operating,
        "files": {"figures": {k: str(Path(v).relative_to(out)) for k, v in figs.items()},
                  "renders": [str(Path(p).relative_to(out)) for p in run.renders],
                  "vtu": str(Path(run.vtu).relative_to(out)) if run.vtu else None},
        "timings": {},
    }
    return {"headline": headline_record(doc, run.compliant_note), **doc}
