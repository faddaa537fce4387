"""Wiring of the coupled model: the FE reduced transducer (``fem.reduced``) as the impact model's
modal horn (``impact.horn.ModalHorn``), and the coupled ensemble statistics.

``fem`` and ``impact`` do not know each other; this module (allowed to import both) converts
one into the other.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from fem.losses import ASSEMBLED_Q_MECH
from impact.horn import ModalHorn

log = logging.getLogger(__name__)

__all__ = ["horn_from_reduced", "build_transducer", "FeTransducer", "rounded", "tip_body", "wideband_modes",
           "wideband_horn", "truncated_horn", "static_residual"]


def horn_from_reduced(reduced, voltage: float, start: str = "rest", series_resistance: float = 0.0) -> ModalHorn:
    """The impact model's modal horn from a :class:`fem.reduced.ReducedTransducer`.

    Parameters
    ----------
    reduced : fem.reduced.ReducedTransducer
        Modes kept, losses (viscous at the drive), couplings, tip participations, residual.
    voltage : float
        Drive amplitude, V.
    start : {"rest", "steady"}
        Modal state at t = 0.
    series_resistance : float
        Source resistance in series with the electrodes, ohm (0: voltage drive; :mod:`impact.drive`).

    Returns
    -------
    ModalHorn
        Its drive frequency is ``reduced.freq_hz`` (pass it as ``ImpactParams.freq``).
    """
    return ModalHorn(omega=reduced.omega, zeta=reduced.zeta, modal_mass=reduced.modal_mass, tip=reduced.tip,
                     coupling_re=reduced.coupling_re, coupling_im=reduced.coupling_im, voltage=float(voltage),
                     residual_re=float(reduced.residual_re), residual_im=float(reduced.residual_im),
                     blocked_charge_re=float(reduced.blocked_charge_re),
                     blocked_charge_im=float(reduced.blocked_charge_im), start=start,
                     series_resistance=float(series_resistance))


def round_sig(x: float, digits: int) -> float:
    """``x`` rounded to ``digits`` significant digits (the hand-off to the chaotic stage)."""
    if x == 0 or not np.isfinite(x):
        return float(x)
    return float(f"{x:.{digits - 1}e}")


def rounded(reduced, digits: int = 6):
    """The reduced transducer with every number rounded to ``digits`` significant digits: the
    chaotic impact stage must not see the last-bit scatter of threaded FE solvers (reruns give
    identical numbers; 1e-6 is far below the FE discretisation error)."""
    from fem.reduced import ReducedTransducer

    d = reduced.to_dict()
    for k, v in d.items():
        if k in ("mode_index", "working", "tip_surface", "rule"):
            continue
        d[k] = [round_sig(x, digits) for x in v] if isinstance(v, list) else round_sig(v, digits)
    return ReducedTransducer.from_dict(d)


@dataclass
class FeTransducer:
    """The FE side of a coupled run: the reduced transducer and what it came from.

    Attributes
    ----------
    reduced : fem.reduced.ReducedTransducer
    f_r_hz, f_a_hz : float
        Resonance / anti-resonance of the working mode, Hz.
    freq_hz : float
        Drive frequency, Hz.
    tip_amplitude_m : float
        Unloaded steady tip amplitude at the drive (direct modal-basis working point), m.
    power_w : float
        Unloaded electrical input power at the drive, W.
    info : dict
        Mesh size, modes, timings (JSON-ready).
    """

    reduced: object
    f_r_hz: float
    f_a_hz: float
    freq_hz: float
    tip_amplitude_m: float
    power_w: float
    info: dict = field(default_factory=dict)


def build_transducer(design, *, voltage: float, q_mech: float | None = ASSEMBLED_Q_MECH, freq_hz: float | None = None,
                     n_modes: int | None = None, match: bool = False, mesh_size: float | None = None,
                     progress=None, refine: float = 1.0, grade: bool = False, admittance_fits=None) -> FeTransducer:
    """Mesh, (match,) modal analysis, harmonic basis and the reduced transducer of a design.

    Parameters
    ----------
    design : geometry design
    voltage : float
        Drive amplitude, V.
    q_mech : float or None
        Assembled-transducer quality factor (None: datasheet losses), as the pipeline.
    freq_hz : float, optional
        Drive frequency, Hz; default: the working mode's resonance (6 significant digits). Must lie
        within 10 % of it (the modal basis covers the band around the working mode).
    n_modes : int, optional
        Modes kept (default: the tip-participation rule of :mod:`fem.reduced`).
    match : bool
        Run the resonance matching first (about 35 s) instead of analysing the design as it is.
    mesh_size : float, optional
        Mesh size override, m.
    refine : float
        Mesh refinement factor (geometry.sizing; < 1 refines).
    grade : bool
        Grade the mesh toward the re-entrant edges (off by default).
    admittance_fits : list of fem.bvd.BVDFit, optional
        A measured admittance's fits: the one nearest the working mode sets the losses in place of
        ``q_mech`` (:func:`fem.bvd.measured_losses`).
    """
    import time

    import geometry
    from fem.harmonic import LossModel, modal_basis, working_point
    from fem.matching import MatchSettings, match as run_match, working_mode
    from fem.modal import modal_analysis
    from fem.reduced import reduce_transducer
    from rpud_common import ParameterError

    say = progress or (lambda msg: log.info("%s", msg))
    t0 = time.perf_counter()
    target = float(design.target_frequency)
    mesh = geometry.build_mesh(design, mesh_size=mesh_size, refine=refine, grade=grade)
    if match:
        m = run_match(design, MatchSettings(target_hz=target, mesh_size=mesh_size, refine=refine, grade=grade), mesh=mesh)
        mesh, system, modal, w = m.mesh, m.system, m.modal, m.working_index
    else:
        from fem.assembly import assemble

        system = assemble(mesh)
        modal = modal_analysis(system, target, 12)
        w = working_mode(system, modal.f_r_hz, modal.vectors, target)
    f_r, f_a = float(modal.f_r_hz[w]), float(modal.f_a_hz[w])
    say(f"      working mode {w + 1}: f_r = {f_r:.1f} Hz, f_a = {f_a:.1f} Hz ({time.perf_counter() - t0:.1f} s)")
    f = round_sig(f_r, 6) if freq_hz is None else float(freq_hz)
    if not abs(f / f_r - 1.0) <= 0.1:
        raise ParameterError("freq", f, f"must lie within 10 % of the working resonance {f_r:.1f} Hz")
    loss, losses = LossModel(q_mech=q_mech), None
    if admittance_fits:
        from fem.bvd import measured_losses

        losses, fit = measured_losses(system, modal, w, admittance_fits)
        loss = losses.loss_model()
        say(f"      admittance fit: {fit.text()}")
    basis = modal_basis(system, f_r, loss=loss, modes=modal)
    if n_modes is not None and n_modes > len(basis.lam):
        raise ParameterError("modes", n_modes, f"must be at most {len(basis.lam)} (the modal basis)")
    red = rounded(reduce_transducer(system, basis, f, n_modes=n_modes, working=int(w)))
    wp = working_point(system, f, voltage, loss=loss, surfaces=("horn_tip",), basis=basis)
    say(f"      reduced transducer: {red.rule}; modes at " + ", ".join(f"{x / 2e3 / np.pi:.2f}" for x in red.omega)
        + f" kHz; tip mass {1 / np.sum(red.tip ** 2 / red.modal_mass) * 1e3:.1f} g; unloaded tip "
          f"{wp.tip_amplitude_m * 1e6:.2f} um at {voltage:g} V, {f:.1f} Hz")
    info = {"mesh": {"tetrahedra": mesh.n_cells, "nodes": mesh.n_points, "ndof": system.ndof},
            "matched": bool(match), "working_mode": int(w), "modal_f_r_hz": [float(x) for x in modal.f_r_hz],
            "q_mech": loss.q_mech, "losses": None if losses is None else losses.record(),
            "materials": system.materials_block(), "fe_seconds": time.perf_counter() - t0}
    return FeTransducer(red, f_r, f_a, f, wp.tip_amplitude_m, float(wp.power_w), info)


def coupled_history(fe: FeTransducer, params, voltage: float, t_end: float, intervals: int = 5,
                    series_resistance: float = 0.0, unloaded: dict | None = None) -> dict:
    """Ring-up from rest with the free mass in place: one coupled run of ``t_end`` s.

    ``series_resistance`` (ohm) puts the source behind a resistor; ``unloaded`` (``tip_amplitude_m``,
    ``power_w``) is the steady operation without impacts quoted beside the run (default: the FE
    working point of ``fe``).

    Returns a dict: ``result`` (:class:`impact.coupled.CoupledResult`, with series), ``lines``
    (terminal summary), ``json`` (envelope, energy balance per interval, drive power and current,
    impact counts; JSON-ready).
    """
    from impact.coupled import simulate_coupled

    horn = horn_from_reduced(fe.reduced, voltage, start="rest", series_resistance=series_resistance)
    p = params.with_(t_end=t_end, freq=fe.freq_hz)
    res = simulate_coupled(p, horn, series=True)
    tc, env = res.envelope(4)
    edges = np.linspace(0.0, t_end, intervals + 1)
    rows = res.energy_balance(edges)
    tail = (0.8 * t_end, t_end)
    power, i_rms = res.drive_power(*tail)
    amp_tail = res.mean_amplitude(*tail)
    imp = res.impact
    series = series_resistance > 0
    unloaded = unloaded or {"tip_amplitude_m": fe.tip_amplitude_m, "power_w": fe.power_w}
    lines = [f"      {imp.tool_impacts} tool and {imp.horn_impacts} horn impacts; tip amplitude over the last "
             f"{(tail[1] - tail[0]) * 1e3:.0f} ms {amp_tail * 1e6:.3f} um (unloaded {unloaded['tip_amplitude_m'] * 1e6:.3f} um); "
             f"{'source' if series else 'drive'} {power:.2f} W, {i_rms:.3f} A rms (unloaded {unloaded['power_w']:.2f} W)"
             + (f"; {series_resistance:g} ohm in series" if series else ""),
             "      energy per interval (mJ): " + "  ".join(
                 ["electrical"] + (["source loss"] if series else []) + ["to modes", "damping", "stored", "to free mass",
                                                                         "to tool", "restitution", "riding", "balance"])]
    keys = ("electric_j",) + (("source_loss_j",) if series else ()) + ("drive_j", "damping_j", "stored_change_j",
                                                                       "to_free_mass_j", "to_tool_j")
    for r in rows:
        bal = abs(r["residual_j"]) + abs(r.get("electric_residual_j", 0.0))
        lines.append(f"      {r['t_from_s'] * 1e3:5.1f}-{r['t_to_s'] * 1e3:5.1f} ms: " + "  ".join(
            f"{1e3 * r[k]:.4g}" for k in keys) + f"  {1e3 * (r['restitution_horn_j'] + r['restitution_tool_j']):.4g}"
            f"  {1e3 * r['riding_j']:.3g}  {bal:.1e} J")
    doc = {"t_end_s": t_end, "horn_start": "rest", "modes": fe.reduced.n_modes, "series_resistance_ohm": series_resistance,
           "tool_impacts": imp.tool_impacts, "horn_impacts": imp.horn_impacts,
           "envelope": {"t_s": tc.tolist(), "amplitude_m": env.tolist(), "window_cycles": 4},
           "energy_balance": rows,
           "tail": {"t_from_s": tail[0], "t_to_s": tail[1], "tip_amplitude_m": amp_tail, "drive_power_w": power,
                    "drive_current_rms_a": i_rms},
           "horn_impact_times_s": imp.t[~imp.is_tool].tolist(), "tool_impact_times_s": imp.t[imp.is_tool].tolist()}
    return {"result": res, "lines": lines, "json": doc}


def coupled_stage(system, basis, freq_hz: float, working: int, voltage: float, base, masses, stats_settings,
                  damper_stats: list, damper_amplitudes: dict, unloaded_m: float, unloaded_power_w: float,
                  f_r_hz: float, f_a_hz: float, *, n_modes: int | None = None, history_s: float = 0.05,
                  reference_m_free: float = 0.008, say=None) -> dict:
    """The pipeline's coupled-model stage: the FE transducer in the impact loop, next to the
    kinematic horn (unloaded FE amplitude) and the damper-corrected amplitude.

    Parameters
    ----------
    system, basis : the FE system and the harmonic modal basis of the run
    freq_hz : drive frequency handed to the impacts, Hz
    working : index of the working mode in the basis
    voltage : drive amplitude, V
    base : impact.params.ImpactParams of the run (``m_free`` and ``A0`` replaced per case)
    masses : free masses, kg
    stats_settings : impact.stats.StatsSettings
    damper_stats : EnsembleStats per mass of the kinematic horn at the damper-corrected amplitude
        (device scenario)
    damper_amplitudes : mass -> damper-corrected amplitude, m
    unloaded_m, unloaded_power_w : unloaded harmonic tip amplitude (m) and power (W)
    n_modes : modes kept (default: the tip-participation rule)
    history_s : ring-up history length, s

    Returns
    -------
    dict with ``json`` (summary part), ``stats`` (coupled EnsembleStats per mass), ``kinematic``
    (EnsembleStats per mass, kinematic horn at the unloaded amplitude), ``history``
    (coupled_history output), ``reduced``.
    """
    from fem.reduced import reduce_transducer
    from impact.coupled import coupled_batch
    from impact.stats import ensemble_batch

    say = say or (lambda msg: log.info("%s", msg))
    red = rounded(reduce_transducer(system, basis, freq_hz, n_modes=n_modes, working=int(working)))
    fe = FeTransducer(red, f_r_hz, f_a_hz, freq_hz, unloaded_m, unloaded_power_w, {})
    horn = horn_from_reduced(red, voltage, start="steady")
    cases = [base.with_(m_free=m, freq=freq_hz) for m in masses]
    stats = coupled_batch(cases, horn, "device", stats_settings)
    kin = ensemble_batch([c.with_(A0=round_sig(unloaded_m, 4)) for c in cases], "device", stats_settings)
    hist = coupled_history(fe, base.with_(m_free=reference_m_free, freq=freq_hz, spring_force=5.0), voltage,
                           history_s)
    rows = []
    for m, c, k, d in zip(masses, stats, kin, damper_stats):
        amp = c.estimates["tip_amplitude_m"]
        a_d = damper_amplitudes[m]
        rows.append({
            "m_free_kg": m, "members": c.members, "converged": c.converged, "note": c.note,
            "coupled": {q: c.estimates[q].to_dict() for q in ("tip_amplitude_m", "mean_tool_ke_after_j",
                                                               "tool_impact_rate_hz", "tool_power_w", "horn_power_w",
                                                               "drive_power_w", "damping_power_w", "frac_on_horn")},
            "kinematic_unloaded": {"A0_m": round_sig(unloaded_m, 4),
                                   "mean_tool_ke_after_j": k.estimates["mean_tool_ke_after_j"].to_dict()},
            "damper": {"A0_m": a_d, "mean_tool_ke_after_j": d.estimates["mean_tool_ke_after_j"].to_dict()},
            "amplitude_damper_minus_coupled_m": a_d - amp.mean,
            "amplitude_within_ci": bool(abs(a_d - amp.mean) <= amp.half_width),
        })
    r8 = rows[-1]
    say(f"      coupled model ({red.n_modes} modes: {red.rule}): at {masses[-1] * 1e3:g} g tip "
        f"{r8['coupled']['tip_amplitude_m']['mean'] * 1e6:.2f} um (damper {r8['damper']['A0_m'] * 1e6:.2f} um), tool KE "
        f"{r8['coupled']['mean_tool_ke_after_j']['mean'] * 1e3:.2f} mJ (damper "
        f"{r8['damper']['mean_tool_ke_after_j']['mean'] * 1e3:.2f}, kinematic unloaded "
        f"{r8['kinematic_unloaded']['mean_tool_ke_after_j']['mean'] * 1e3:.2f}), drive "
        f"{r8['coupled']['drive_power_w']['mean']:.1f} W")
    doc = {"reduced_transducer": red.to_dict(), "tip_mass_kg": horn.tip_mass, "scenario": "device",
           "horn_start_for_statistics": "steady", "rows": rows, "history": hist["json"]}
    return {"json": doc, "stats": stats, "kinematic": kin, "history": hist, "reduced": red}


def history_csv(res) -> str:
    """The sampled history of a coupled run as CSV text: time (s), tip displacement (m) and velocity
    (m/s), free mass and tool face positions (m), drive voltage (V) and current (A)."""
    import io

    from impact.coupled_result import states_on as _states_on

    t = res.t_grid
    W = 2 * np.pi * res.freq_hz
    V = res.horn.voltage * np.sin(W * t)
    head = "t_s,tip_m,tip_velocity_m_per_s,free_mass_m,tool_face_m,voltage_v,current_a"
    if res.horn.series_resistance > 0:
        from impact.drive_result import physical

        vp = physical(res, t)[0][:, -1]
        current = (V - vp) / res.horn.series_resistance
        extra = [vp]
        head += ",electrode_voltage_v"
    else:
        _, qd, qdd = _states_on(res, t)
        current = res.horn.drive_current(res.freq_hz, t, qd, qdd)
        extra = []
    cols = np.column_stack([t, res.u, res.tip_velocity, res.impact.w, res.impact.tool_face, V, current] + extra)
    buf = io.StringIO()
    buf.write(head + "\n")
    np.savetxt(buf, cols, delimiter=",", fmt="%.10g")
    return buf.getvalue()


def contact_from_design(design, m_free: float, restitution: float, free_mass_material: str = "steel_45"):
    """Hunt-Crossley horn contact from the design: the horn tip's material (``design.part_material("horn")``)
    against a free mass taken as a sphere of ``free_mass_material`` with the mass ``m_free`` (its
    radius is the contact radius; the tip face is flat).

    Returns
    -------
    impact.contact.HuntCrossley
    """
    from geometry.materials import get_material
    from impact.contact import HuntCrossley, hertz_stiffness

    horn = get_material(design.part_material("horn"), design.library)
    ball = get_material(free_mass_material, design.library)
    radius = (3.0 * m_free / (4.0 * np.pi * ball.density)) ** (1.0 / 3.0)
    k = hertz_stiffness(horn.youngs_modulus, horn.poisson_ratio, ball.youngs_modulus, ball.poisson_ratio, radius)
    return HuntCrossley(k, restitution)


def tip_body(system, cutoff_hz: float, *, tip_surface: str = "horn_tip", modes=None, factor=None, say=None):
    """The transducer seen from its tip by an impact: every mode up to ``cutoff_hz`` plus the
    static residual of the rest (:class:`impact.compliant.ModalBody`).

    The short-circuit modes of the driven free set (hot electrode grounded) from 0 to the cut-off
    (:func:`wideband_modes`), the axial rigid-body translation (``omega = 0``, the whole drill's
    mass), and the tip compliance ``g = sum s_i^2 / lambda_i`` of every mode above the cut-off
    (:func:`static_residual`: solves of ``K - sigma M`` deflated of the modes below it).

    Parameters
    ----------
    system : fem.assembly.PiezoSystem
        The drill (a k = 0 sector system carries the axisymmetric modes only, which are the
        modes an axial impact excites).
    cutoff_hz : float
        Highest mode kept, Hz.
    tip_surface : str
        Facet set whose mean axial displacement is the contact point.
    modes : fem.modal.ModalResult, optional
        A wide-band short-circuit modal analysis of ``system`` reaching 0 and ``cutoff_hz``
        (reused; computed otherwise).
    factor : (callable, float), optional
        ``(F, sigma)``: an existing factorisation ``F`` of ``K - sigma M`` on the short-circuit
        free set (e.g. a working-band basis's, :attr:`fem.harmonic.ModalBasis.factor`), used when
        ``sigma <= lambda_cut / 5`` (rad^2/s^2; at most ~11 solves); otherwise a new one at
        ``sigma0 = -(2 pi 0.01 f_cut)^2``, below every elastic mode.

    Returns
    -------
    (impact.compliant.ModalBody, dict)
        The body (undamped, unit modal masses) and its description: ``modes_hz`` (kept, the rigid
        mode first), ``drill_mass_kg``, ``residual_m_per_n``, ``end_mass_kg``, ``cutoff_hz``.
    """
    from fem.eigen import rigid_basis
    from fem.harmonic import surface_functional
    from fem.solvers import factorize
    from impact.compliant import ModalBody
    from rpud_common import ParameterError, check_range

    check_range("cutoff_hz", cutoff_hz, 1e3, 1e6, "Hz")
    say = say or (lambda msg: log.info("%s", msg))
    modes = modes if modes is not None else wideband_modes(system, cutoff_hz)
    if not _window_covers(modes, (2 * np.pi * cutoff_hz) ** 2):
        raise ParameterError("modes", f"{len(modes.f_r_hz)} modes", f"must reach 0 and the cut-off {cutoff_hz:g} Hz")
    split = system.split(())
    free = split.free
    keep = np.flatnonzero(modes.f_r_hz <= cutoff_hz)
    Phi = modes.vectors[free][:, keep]
    lam = (2 * np.pi * modes.f_r_hz[keep]) ** 2
    R, _ = rigid_basis(system, free, split.M)
    a = np.asarray(surface_functional(system, tip_surface).rows[0][:, free].toarray()).ravel()
    s_rigid = R.T @ a
    axial = int(np.argmax(np.abs(s_rigid)))          # the translation along the axis (a rotation: 0)
    B = np.column_stack([R[:, axial], Phi])
    lam_all = np.concatenate(([0.0], lam))
    s_all = B.T @ a
    sign = np.where(s_all < 0, -1.0, 1.0)             # tip participation >= 0: the same numbers every run
    lam_cut = (2 * np.pi * cutoff_hz) ** 2
    if factor is None or factor[0] is None or not factor[1] <= lam_cut / 5:
        # a shift near the cut-off would need many solves (the series falls as sigma / (lambda - sigma))
        sigma = -(2 * np.pi * 0.01 * cutoff_hz) ** 2
        factor = (factorize((split.K - sigma * split.M).tocsr()), sigma)
    # every rigid motion is deflated with the kept modes (the rotation about the axis has no
    # axial tip displacement, but the series below needs every mode below the cut-off out)
    kept = (np.column_stack([R, Phi]), np.concatenate((np.zeros(R.shape[1]), lam)))
    g = static_residual(factor, split.M, a, kept, lam_cut=lam_cut)
    drill_mass = float(1.0 / s_all[0] ** 2)
    body = ModalBody(np.sqrt(lam_all), np.zeros(lam_all.size), np.ones(lam_all.size), sign * s_all, g)
    info = {"cutoff_hz": float(cutoff_hz), "modes_hz": [float(x) for x in np.sqrt(lam_all) / (2 * np.pi)],
            "participation": [float(x) for x in sign * s_all], "drill_mass_kg": drill_mass,
            "residual_m_per_n": g, "end_mass_kg": body.end_mass, "tip_surface": tip_surface}
    say(f"      tip body to {cutoff_hz / 1e3:.0f} kHz: {lam.size} modes + rigid translation "
        f"(drill {drill_mass * 1e3:.1f} g), residual {g:.3g} m/N, effective tip mass {body.end_mass * 1e3:.2f} g")
    return body, info


def static_residual(factor, M, a, kept, *, lam_cut: float, rtol: float = 1e-13, max_solves: int = 20) -> float:
    """The static compliance ``g = sum s_i^2 / lambda_i`` (m/N) of the modes NOT in ``kept``, for
    the load ``a`` (``s_i = phi_i^T a``), from solves at a shift.

    ``T = (K - sigma M)^-1`` deflated of the kept (M-orthonormal) modes holds the modes left out
    with ``1 / (lambda - sigma)``; ``1 / lambda = sum_k (-sigma)^k / (lambda - sigma)^(k+1)`` gives
    ``g = sum_k (-sigma)^k a^T (T M)^k T a``, two terms per solve (``y_j = (T M)^j T a``:
    ``a^T (T M)^(2j+1) T a = y_j^T M y_j``, ``a^T (T M)^(2j) T a = (M y_(j-1))^T y_j``). The terms
    fall as ``|sigma / (lambda - sigma)|`` of the lowest mode left out (< 1 when ``sigma <
    lambda_cut / 2``): summed until a term is below ``rtol`` of the sum.

    Parameters
    ----------
    factor : (callable, float)
        ``(F, sigma)``: ``F(v) = (K - sigma M)^-1 v`` on the free set of ``M``, ``sigma`` in rad^2/s^2.
    M : sparse matrix
        Mass on that free set.
    a : ndarray
        The load (the tip's mean axial displacement row).
    kept : (ndarray, ndarray)
        The modes not counted (M-orthonormal columns, every mode below ``lam_cut``) and their
        eigenvalues, rad^2/s^2.
    lam_cut : float
        The cut-off's eigenvalue, rad^2/s^2: every mode above it is counted.
    """
    from rpud_common import ParameterError

    F, sigma = factor
    B, lam = kept
    if not sigma < lam_cut / 2:
        raise ParameterError("factor", f"shift {sigma:.4g} rad^2/s^2", f"must lie below lambda_cut / 2 = {lam_cut / 2:.4g}")

    def solve(v):
        return np.asarray(F(v)).ravel() - B @ ((B.T @ v) / (lam - sigma))

    y = solve(a)
    My = M @ y
    g = float(a @ y) - sigma * float(y @ My)
    for j in range(1, max_solves):
        y = solve(My)
        even = sigma ** (2 * j) * float(My @ y)
        My = M @ y
        odd = -sigma ** (2 * j + 1) * float(y @ My)
        g += even + odd
        if abs(odd) <= rtol * abs(g):
            return g
    raise ParameterError("factor", f"shift {sigma:.4g} rad^2/s^2",
                         f"leaves the residual series unconverged after {max_solves} solves")


#: modes asked of :func:`wideband_modes`' first window per Hz of cut-off: the article drill's k = 0
#: spectrum holds one mode per ~3.8 kHz (32 below 122 kHz), so one per 3 kHz covers it in one window;
#: a denser spectrum takes a second window on the same factorisation
FIRST_WINDOW_MODES_PER_HZ = 1.0 / 3e3


def wideband_modes(system, cutoff_hz: float):
    """Every short-circuit mode of ``system`` from 0 to ``cutoff_hz`` (Hz): one shift-invert
    window centred on ``lambda_cut / 2``, widened until it reaches both ends on the same
    factorisation (:class:`fem.modal.ModalResult`, without it; rigid-body modes deflated)."""
    import dataclasses

    from fem.modal import modal_analysis
    from rpud_common import ParameterError, check_range

    check_range("cutoff_hz", cutoff_hz, 1e3, 1e6, "Hz")
    lam_cut = (2 * np.pi * cutoff_hz) ** 2
    n_req, modes = max(16, int(np.ceil(cutoff_hz * FIRST_WINDOW_MODES_PER_HZ))), None
    while modes is None or not _window_covers(modes, lam_cut):
        if n_req > 400:
            raise ParameterError("cutoff_hz", cutoff_hz, "needs more than 400 modes (lower the cut-off)")
        modes = modal_analysis(system, cutoff_hz / np.sqrt(2), n_req, open_circuit=False, sigma=lam_cut / 2,
                               factor=None if modes is None else modes.factor, keep_factor=True)
        # the next window from the density of the one found (+25 %): one more solve, not a doubling series
        reach = float(np.max(np.abs((2 * np.pi * np.asarray(modes.f_r_hz)) ** 2 - modes.sigma)))
        n_req = max(2 * n_req, int(np.ceil(1.25 * n_req * lam_cut / (2.0 * reach))) + 4)
    return dataclasses.replace(modes, factor=None)


def _window_covers(modes, lam_cut: float) -> bool:
    """The shift-invert window of ``modes`` (the eigenvalues nearest its shift) reaches 0 and
    ``lam_cut``: every mode below the cut-off is in it."""
    lam = (2 * np.pi * np.asarray(modes.f_r_hz)) ** 2
    reach = np.max(np.abs(lam - modes.sigma))
    return bool(modes.sigma - reach <= 0.0 and modes.sigma + reach >= lam_cut)


@dataclass(frozen=True)
class _DriveView:
    """The wide band's modes as :func:`fem.reduced.reduce_transducer` reads a basis (modes, losses,
    couplings), with the full response at the drive taken from a working-band basis ``drive`` of
    the same system: the response does not depend on which modes a basis expands it in, and the
    working-band basis is the one the run's working point comes from."""

    free: np.ndarray
    Phi: np.ndarray
    lam: np.ndarray
    eta: np.ndarray
    gamma: np.ndarray
    drive: object

    @property
    def L(self):
        return self.drive.L

    @property
    def loss(self):
        return self.drive.loss

    def solution_free(self, freq_hz: float, voltage: float = 1.0, damper=None) -> np.ndarray:
        return self.drive.solution_free(freq_hz, voltage, damper)


def _drive_view(system, modes, keep, drive) -> _DriveView:
    """:class:`_DriveView` of the modes ``keep`` of ``modes`` (their loss factors and couplings
    as :func:`fem.harmonic.modal_basis` computes them, under ``drive``'s losses)."""
    from fem.harmonic import loss_matrix

    free = drive.free
    Phi = modes.vectors[free][:, keep]
    lam = (2 * np.pi * modes.f_r_hz[keep]) ** 2
    L = drive.L if drive.L is not None else loss_matrix(system, drive.loss)
    eta = np.einsum("ij,ij->j", Phi, L[free][:, free] @ Phi) / lam
    return _DriveView(free, Phi, lam, eta, Phi.T @ drive.b1, drive)


def wideband_horn(system, freq_hz: float, cutoff_hz: float, voltage: float, *, q_mech: float | None = 100.0,
                  modes=None, tip_surface: str = "horn_tip", drive=None, say=None):
    """The driven horn with every k = 0 mode up to ``cutoff_hz`` and the impact residual of the rest.

    The drive side is :func:`fem.reduced.reduce_transducer` on the modes below the cut-off (their
    couplings, losses at the drive, and the drive residual: the full response at the drive minus
    theirs); the impact side adds :func:`tip_body`'s static tip compliance of the modes above the
    cut-off. The axial rigid translation is left out: the housing holds the drill (its recoil
    under the impacts is the drill's mass, ~0.4 kg, against a tip of a few grams).

    Parameters
    ----------
    system, freq_hz, cutoff_hz, voltage
        The k = 0 system, drive frequency (Hz), cut-off (Hz) and drive amplitude (V).
    q_mech : float or None
        Assembled-transducer quality factor, without ``drive``.
    modes : fem.modal.ModalResult, optional
        :func:`wideband_modes` of ``system`` reaching the cut-off (computed otherwise).
    drive : fem.harmonic.ModalBasis, optional
        A working-band basis of ``system`` that kept its factorisation (the run's harmonic basis,
        :func:`fem.harmonic.modal_basis`): its losses (in place of ``q_mech``), its response at
        the drive and its factorisation (the tip residual's solves) are reused. Default: a basis
        of every mode below the cut-off with its own factorisation at the drive.

    Returns
    -------
    (impact.horn.ModalHorn, float, dict)
        The horn (steady start), the tip residual compliance (m/N) and :func:`tip_body`'s info.
    """
    import dataclasses

    from fem.harmonic import LossModel, modal_basis
    from fem.reduced import reduce_transducer

    modes = modes if modes is not None else wideband_modes(system, cutoff_hz)
    keep = np.flatnonzero(modes.f_r_hz <= cutoff_hz)
    if drive is None:
        # the drive residual is expanded about the modal shift: put it at the drive (as a working-band
        # basis has it), away from the first modes left out that sit next to the wide window's shift
        sub = dataclasses.replace(modes, f_r_hz=modes.f_r_hz[keep], vectors=modes.vectors[:, keep],
                                  sigma=(2 * np.pi * freq_hz) ** 2 * (1 - 2e-3))
        drive = modal_basis(system, freq_hz, loss=LossModel(q_mech=q_mech), modes=sub)
    body, info = tip_body(system, cutoff_hz, tip_surface=tip_surface, modes=modes,
                          factor=(drive.factor, drive.sigma), say=say)
    view = _drive_view(system, modes, keep, drive)
    red = rounded(reduce_transducer(system, view, freq_hz, n_modes=len(keep), tip_surface=tip_surface))
    return horn_from_reduced(red, voltage, start="steady"), body.residual, info


def truncated_horn(horn: ModalHorn, residual: float, cutoff_hz: float, freq_hz: float) -> tuple[ModalHorn, float]:
    """The horn of :func:`wideband_horn` with the modes above ``cutoff_hz`` (Hz) moved into its residuals.

    A mode left out responds to an impact quasi-statically: its static tip compliance
    ``s_i^2 / (m_i omega_i^2)`` joins the impact residual; under the drive its steady tip motion at
    ``freq_hz`` joins the drive residual (the steady tip motion at the drive is unchanged). The same
    truncation as a fresh :func:`wideband_horn` at the lower cut-off, without another FE solve.

    Returns
    -------
    (ModalHorn, float)
        The truncated horn and its impact residual, m/N.
    """
    import dataclasses

    from rpud_common import ParameterError

    keep = horn.omega <= 2 * np.pi * cutoff_hz
    if not keep.any():
        raise ParameterError("cutoff_hz", cutoff_hz, f"must keep a mode (lowest {horn.omega.min() / 2 / np.pi:.0f} Hz)")
    drop = ~keep
    g = residual + float(np.sum(horn.tip[drop] ** 2 / (horn.modal_mass[drop] * horn.omega[drop] ** 2)))
    d = complex(horn.tip[drop] @ horn.steady_modal(freq_hz)[drop])       # m, phasor of Re(d e^{jWt})
    v = horn.voltage if horn.voltage > 0 else 1.0                        # no drive: d = 0
    arrays = {k: getattr(horn, k)[keep] for k in ("omega", "zeta", "modal_mass", "tip", "coupling_re", "coupling_im")}
    out = dataclasses.replace(horn, **arrays, residual_im=horn.residual_im + d.real / v,
                              residual_re=horn.residual_re - d.imag / v)
    return out, g
