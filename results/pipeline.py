"""The end-to-end run: design -> mesh -> resonance matching -> harmonic response -> A0 -> impacts.

Stages (each timed, each reported on the terminal through ``progress``):

1. **mesh** the design (Gmsh, second-order tetrahedra);
2. **match** horn and coupler to the target frequency (:func:`fem.matching.match`);
3. **harmonic**: modal-superposition admittance sweep over the resonance/anti-resonance band,
   the tip amplitude per volt at the working frequency (datasheet losses: the unloaded
   transducer; and the assembled-transducer quality factor ``q_mech``), ring-up at the drive;
4. **A0**: the horn-tip amplitude at the drive voltage, coupled with the impacts it drives. The
   free mass loads the tip: a horn impact exchanges momentum ``J`` at horn velocity ``u'``, and
   the mean power ``P = sum J u' / t`` it draws is that of a viscous damper
   ``c = 2 P / (w A0)^2`` on the tip. The harmonic working point is solved again with that
   damper (a rank-one term on the modal coordinates) and the loop ``A0 -> impacts -> c -> A0``
   is iterated to a fixed point (geometric-mean relaxation; the impact model is chaotic, so
   each power estimate is the mean of 4 runs of 0.5 s, and the loop stops at 3 %);
5. **impacts**: drill-tool kinetic energy versus free-mass weight with that (per-mass) A0 and
   the working frequency, next to the article's assumed 15 um;
6. **renders** of the working mode and its neighbours, VTU with every mode.

Assumption stated loudly: with datasheet losses (PZT-8 Qm 1000, Ti-6Al-4V Q 10 000) the
matched transducer at 225 V and exact resonance would reach ~0.5 mm at the tip and draw
kilowatts: an unloaded resonator. A bolted, mounted Langevin transducer loses far more in its
joints, bolt and mount; ``q_mech`` (default 100) is that assembled-transducer quality factor,
applied to every part. The datasheet result is reported as well.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from geometry.common import ParameterError, check_integer, check_positive, check_range, write_json

log = logging.getLogger(__name__)

__all__ = ["PipelineSettings", "run_pipeline", "coupled_amplitudes"]

ARTICLE_A0 = 15e-6
"""The article's assumed horn-tip amplitude (Table 1), m."""


@dataclass(frozen=True)
class PipelineSettings:
    """Settings of the end-to-end run (SI units).

    Attributes
    ----------
    voltage : drive amplitude on the hot electrodes, V (the article's 225 V)
    q_mech : quality factor of the assembled transducer applied to every part (None: datasheet)
    mesh_size : mesh size override, m (None: the design's elements-per-wavelength rule)
    match : run the resonance matching (else analyse the design as it is)
    couple_impacts : iterate A0 with the impact load on the horn tip
    m_free_values : free masses of the sweep, kg (0 is reported as zero energy: no free mass)
    reference_m_free : free mass for the headline A0 and the impact histories, kg (Table 1: 8 g)
    impact_t_end : simulated time per impact run, s
    ensemble : impact runs per free mass (launch speeds spread +-5 %); 8 x 1 s keeps the standard
        error of the mean tool energy near 10 %
    band : half-width of the admittance band around [f_r, f_a], relative
    n_points : frequencies in the admittance sweep
    workers : processes for the impact sweep
    render : write mode-shape PNGs and the VTU
    """

    voltage: float = 225.0
    q_mech: float | None = 100.0
    mesh_size: float | None = None
    match: bool = True
    couple_impacts: bool = True
    m_free_values: tuple[float, ...] = (0.0, 0.001, 0.002, 0.003, 0.004, 0.005, 0.006, 0.007, 0.008)
    reference_m_free: float = 0.008
    impact_t_end: float = 1.0
    ensemble: int = 8
    band: float = 0.03
    n_points: int = 200
    workers: int = 2
    render: bool = True

    def __post_init__(self):
        check_positive("voltage", self.voltage, "V")
        if self.q_mech is not None:
            check_positive("q_mech", self.q_mech)
        if self.mesh_size is not None:
            check_positive("mesh_size", self.mesh_size, "m")
        if not self.m_free_values or any((not np.isfinite(m)) or m < 0 for m in self.m_free_values):
            raise ParameterError("m_free_values", self.m_free_values, "must be masses >= 0 kg")
        check_positive("reference_m_free", self.reference_m_free, "kg")
        check_positive("impact_t_end", self.impact_t_end, "s")
        check_integer("ensemble", self.ensemble, 1)
        check_range("band", self.band, 0.0, 0.5, lo_open=True)
        check_integer("n_points", self.n_points, 3)


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


def coupled_amplitudes(point_fn: Callable[[float], float], base, masses, *, omega: float, ensemble: int = 4,
                       workers: int = 2, rtol: float = 0.03, max_iter: int = 8) -> dict:
    """Iterate ``A0 -> impact power -> tip damper -> A0`` to a fixed point for every free mass.

    The masses advance in lockstep so that each iteration is one batch of impact runs on the
    process pool (``ensemble`` runs per unconverged mass). The impact power is a noisy estimate
    (chaotic dynamics), so the loop stops at ``rtol`` = 3 %; a mass still wandering after
    ``max_iter`` iterations gets the mean of its last three iterates (``converged`` False,
    ``note`` says so).

    Parameters
    ----------
    point_fn : callable(c) -> tip amplitude (m) of the harmonic working point with a tip damper
        ``c`` (N s/m)
    base : impact.params.ImpactParams (A0 and m_free are replaced)
    masses : free masses, kg
    omega : drive angular frequency, rad/s

    Returns
    -------
    dict mass -> CoupledAmplitude
    """
    from impact.sweep import ensemble_params, run_cases

    a_free = point_fn(0.0)
    state = {m: CoupledAmplitude(m_free=m, A0=a_free, A0_unloaded=a_free, tip_damping=0.0,
                                 impact_power_w=0.0, converged=False) for m in masses}
    for _ in range(max_iter):
        active = [m for m in masses if not state[m].converged and not state[m].note]
        if not active:
            break
        cases = [q for m in active for q in ensemble_params(base.with_(m_free=m, A0=state[m].A0), ensemble)]
        runs = run_cases(cases, workers=workers, progress=False, desc="A0")
        for i, m in enumerate(active):
            st = state[m]
            ok = [r for r in runs[i * ensemble:(i + 1) * ensemble] if r["error"] is None]
            if not ok:
                st.note = f"every impact run failed at A0 = {st.A0:.3g} m (the tool pinches the free mass)"
                log.warning("m_free %g kg: %s", m, st.note)
                continue
            st.impact_power_w = float(np.mean([r["horn_work_j"] for r in ok])) / base.t_end
            st.tip_damping = 2.0 * st.impact_power_w / (omega * st.A0) ** 2
            a_new = point_fn(st.tip_damping)
            st.history.append({"A0_m": st.A0, "impact_power_w": st.impact_power_w,
                               "tip_damping_ns_per_m": st.tip_damping, "A0_next_m": a_new})
            if abs(a_new / st.A0 - 1.0) < rtol:
                st.A0, st.converged = a_new, True
            else:
                st.A0 = float(np.sqrt(st.A0 * a_new))     # geometric relaxation: the loop overshoots
    for st in state.values():
        if not st.converged and not st.note and st.history:
            st.A0 = float(np.mean([h["A0_next_m"] for h in st.history[-3:]]))
            st.note = f"not within {rtol:.0%} after {max_iter} iterations: mean of the last three iterates"
    return state


# --------------------------------------------------------------------------- pipeline



def run_pipeline(design, settings: PipelineSettings, out_dir, *, progress: Callable[[str], None] | None = None) -> dict:
    """Run every stage and write the results into ``out_dir``; returns the summary dict.

    Files: ``summary.json``, ``report.md``, ``figures/*.png``, ``renders/*.png``, ``modes.vtu``.
    """
    import geometry
    from geometry.report import mesh_part_volumes
    from fem.harmonic import LossModel, harmonic_sweep, modal_basis, working_point
    from fem.matching import MatchSettings, match, working_mode
    from fem.modal import modal_analysis
    from fem.transient import ring_up
    from impact.model import simulate
    from impact.params import ImpactParams
    from impact.sweep import sweep

    from . import figures
    from .report import write_report

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
    mesh = geometry.build_mesh(design, mesh_size=settings.mesh_size)
    timings["mesh_s"] = time.perf_counter() - t0
    say(f"      {mesh.n_cells} tetrahedra, {mesh.n_points} nodes ({timings['mesh_s']:.1f} s)")

    # 2. match
    t0 = stage("resonance matching" if settings.match else "modal analysis", 2)
    target = float(design.target_frequency)
    if settings.match:
        def show(rec):
            say(f"      {rec['stage']:5s} {rec['parameter']} = {rec['value_m'] * 1e3:8.4f} mm -> {rec['f_hz']:10.2f} Hz")

        m = match(design, MatchSettings(target_hz=target, mesh_size=settings.mesh_size), mesh=mesh, progress=show)
        design, mesh, system, modal, w = m.design, m.mesh, m.system, m.modal, m.working_index
        match_json = m.to_json()
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
    loss = LossModel(q_mech=settings.q_mech)
    basis = modal_basis(system, f_w, loss=loss, modes=modal)
    lo = f_w * (1 - settings.band)
    hi = (f_a if np.isfinite(f_a) else f_w) * (1 + settings.band)
    freqs = np.linspace(lo, hi, settings.n_points)
    sweep_h = harmonic_sweep(system, freqs, settings.voltage, loss=loss, basis=basis, surfaces=surfaces)
    wp = working_point(system, f_w, settings.voltage, loss=loss, surfaces=surfaces, basis=basis)
    basis_ds = modal_basis(system, f_w, loss=LossModel(), modes=modal)
    wp_ds = working_point(system, f_w, settings.voltage, loss=LossModel(), surfaces=surfaces, basis=basis_ds)
    eta_w = float(basis.eta[w])
    tau = 2.0 / (eta_w * 2 * np.pi * f_w)            # amplitude time constant of the working mode
    ring = ring_up(system, f_w, settings.voltage, min(6 * tau, 0.05), loss=loss, basis=basis,
                   surfaces=surfaces[:1])
    timings["harmonic_s"] = time.perf_counter() - t0
    say(f"      tip {wp.tip_per_volt_m * 1e9:.1f} nm/V (q_mech {settings.q_mech}), "
        f"{wp_ds.tip_per_volt_m * 1e9:.1f} nm/V with datasheet losses; ring-up tau {tau * 1e3:.2f} ms")

    # 4. A0 with the impact load
    t0 = stage("A0 coupled with the impacts", 4)
    horn_mass = mesh_part_volumes(mesh)[1].get("horn", ImpactParams().m_horn)
    base = ImpactParams(A0=wp.tip_amplitude_m, freq=f_w, m_horn=horn_mass, t_end=min(settings.impact_t_end, 0.5))
    omega = 2 * np.pi * f_w

    def point(c):
        return working_point(system, f_w, settings.voltage, loss=loss, surfaces=surfaces[:1], basis=basis,
                             tip_damping=c).tip_amplitude_m

    masses = [m for m in settings.m_free_values if m > 0]
    all_masses = sorted(set(masses) | {settings.reference_m_free})
    if settings.couple_impacts:
        coupled = coupled_amplitudes(point, base, all_masses, omega=omega, ensemble=min(settings.ensemble, 4),
                                     workers=settings.workers)
    else:
        coupled = {m: CoupledAmplitude(m, wp.tip_amplitude_m, wp.tip_amplitude_m, 0.0, 0.0) for m in all_masses}
    for m_free, c in coupled.items():
        say(f"      m_free {m_free * 1e3:4.1f} g: A0 = {c.A0 * 1e6:6.2f} um (unloaded {c.A0_unloaded * 1e6:.2f} um, "
            f"impact load {c.tip_damping:.2f} N s/m, {len(c.history)} iterations)")
    ref = coupled[settings.reference_m_free]
    timings["a0_s"] = time.perf_counter() - t0

    # 5. impacts
    t0 = stage("impact sweep", 5)
    base = base.with_(t_end=settings.impact_t_end, A0=ref.A0, m_free=settings.reference_m_free)
    hist_ref = simulate(base.with_(t_end=0.05))
    sw_fe = sweep(base, masses, ensemble=settings.ensemble, workers=settings.workers, progress=True,
                  t_end=settings.impact_t_end, A0_values=[coupled[m].A0 for m in masses])
    sw_article = sweep(base.with_(A0=ARTICLE_A0, freq=20e3), masses, ensemble=settings.ensemble,
                       workers=settings.workers, progress=True, t_end=settings.impact_t_end)
    timings["impacts_s"] = time.perf_counter() - t0
    say(f"      tool KE at {masses[-1] * 1e3:g} g: {sw_fe.mean_ke[-1] * 1e3:.2f} mJ (FE A0) vs "
        f"{sw_article.mean_ke[-1] * 1e3:.2f} mJ (article 15 um)")

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
    figs = {
        "admittance": figures.admittance(sweep_h, f_w, f_a, out / "figures" / "admittance.png"),
        "tip_response": figures.tip_response(sweep_h, f_w, out / "figures" / "tip_response.png"),
        "ring_up": figures.ring_up(ring, wp.tip_amplitude_m, out / "figures" / "ring_up.png"),
        "impact_history": figures.impact_history(hist_ref, out / "figures" / "impact_history_50ms.png"),
        "kinetic_energy": figures.kinetic_energy(sw_fe, sw_article, coupled, settings.m_free_values,
                                                 out / "figures" / "kinetic_energy_vs_free_mass.png"),
        "a0_coupling": figures.a0_coupling(coupled, out / "figures" / "a0_vs_free_mass.png"),
    }
    ke_table = [{"m_free_kg": 0.0, "A0_m": None, "mean_tool_ke_j": 0.0, "mean_tool_ke_article_j": 0.0,
                 "note": "no free mass: no impacts"}] if 0.0 in settings.m_free_values else []
    for i, m_ in enumerate(masses):
        ke_table.append({"m_free_kg": m_, "A0_m": coupled[m_].A0,
                         "mean_tool_ke_j": float(sw_fe.mean_ke[i]), "sem_tool_ke_j": float(sw_fe.sem_ke[i]),
                         "tool_impact_rate_hz": float(sw_fe.rate_hz[i]),
                         "mean_tool_ke_article_j": float(sw_article.mean_ke[i])})
    timings["figures_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_all
    summary = {
        "design": design.to_mapping(),
        "settings": {k: getattr(settings, k) for k in settings.__dataclass_fields__},
        "mesh": {"tetrahedra": mesh.n_cells, "nodes": mesh.n_points, "order": mesh.order, "ndof": system.ndof},
        "matching": match_json,
        "working_mode": {"index": w, "f_r_hz": f_w, "f_a_hz": f_a, "k_eff": float(modal.k_eff[w]),
                         "label": modal.labels[w], "modal_loss_factor": eta_w},
        "harmonic": {
            "voltage_v": settings.voltage, "q_mech": settings.q_mech,
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
        "impacts": {"params": base.to_dict(), "fit_fe": {"slope_j_per_kg": sw_fe.slope, "r2": sw_fe.r2},
                    "fit_article": {"slope_j_per_kg": sw_article.slope, "r2": sw_article.r2},
                    "reference_run_50ms": hist_ref.summary()},
        "kinetic_energy_table": ke_table,
        "files": {"figures": {k: str(Path(v).relative_to(out)) for k, v in figs.items()},
                  "renders": [str(Path(p).relative_to(out)) for p in renders],
                  "vtu": str(Path(vtu).relative_to(out)) if vtu else None},
        "timings": timings,
    }
    write_json(out / "summary.json", summary)
    write_report(summary, out / "report.md")
    say(f"done in {timings['total_s']:.1f} s: {out / 'report.md'}")
    return summary
