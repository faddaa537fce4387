"""The pipeline's rotary-unit stage: the teeth motion the harmonic response reports, with its
error, turned into the rotor's speed, torque, power and efficiency, each with its error.

:func:`rotor_params_from_design` takes the contact geometry (teeth, their top area, the contact
radius) and the coupler's moduli from the design, so a study that varies the coupler's
dimensions moves the rotor's results with them. :func:`rotor_stage` runs the model at the
reported teeth motion and at the eight corners of its error box (axial amplitude, ellipse ratio,
phase, each at value +- error; :func:`impact.rotor_box.error_box`): the error of every output is
its largest departure over the corners. :func:`teeth_report` reads the motion and its errors
off a working point and its discretisation-error estimate.

The efficiency's electrical input is the teeth's power into the contact plus the rotary side's
own loss without the rotor, which the pipeline does not separate from the percussive side's:
it is bounded by 0 and the whole unloaded electrical power, and the efficiency printed is the
midpoint of the two bounds with half their spread as its model-form error.
"""

from __future__ import annotations

import logging

from impact.rotor import RotorParams, bit_friction_torque
from impact.rotor_box import OUTPUTS, ROUNDOFF, TeethReport, error_box, rotor_text
from rpud_common import ParameterError, check_nonnegative
from rpud_common.formatting import plus_minus

log = logging.getLogger(__name__)

__all__ = ["TeethReport", "rotor_params_from_design", "teeth_report", "rotor_stage", "rotor_text", "study_rotor",
           "report_lines", "OUTPUTS", "BIT", "ROUNDOFF", "STUDY_OUTPUTS"]

BIT = (3e-3, 0.4)
"""The load's bit: diameter (m) of a flat bit and its friction coefficient in rock (assumed)."""


def rotor_params_from_design(design, base: RotorParams = RotorParams(), library=None) -> RotorParams:
    """``base`` with the contact geometry and the coupler's moduli of ``design``
    (:class:`geometry.RPUDDesign`): ``n_teeth``, ``tooth_area`` (the annular sector of a tooth top:
    arc ``tooth_width`` at the outer radius, from the bore to the outer surface), ``radius`` (the
    mean of the bore and outer radii) and ``e_tooth``, ``nu_tooth``."""
    from geometry.materials import get_material

    c = design.coupler
    if not c.n_teeth:
        raise ParameterError("coupler.n_teeth", c.n_teeth, "must be >= 1: the rotor is driven by the teeth")
    ro, ri = c.outer_diameter / 2, design.coupler_bore / 2
    angle = c.tooth_width / ro
    mat = get_material(c.material, library)
    return base.with_(n_teeth=c.n_teeth, tooth_area=0.5 * angle * (ro ** 2 - ri ** 2), radius=0.5 * (ro + ri),
                      e_tooth=float(mat.youngs_modulus), nu_tooth=float(mat.poisson_ratio))


def _efficiency(nominal, electric_power_w: float) -> dict:
    """The efficiency against the electrical input: bounds 0 and the whole unloaded power as the
    rotary side's own loss, the midpoint +- half the spread."""
    hi = nominal.load_power / nominal.load_teeth_power if nominal.load_teeth_power > 0 else 0.0
    den = nominal.load_teeth_power + electric_power_w
    lo = nominal.load_power / den if den > 0 else 0.0
    return {"electric_efficiency": 0.5 * (hi + lo), "electric_efficiency_error": 0.5 * (hi - lo),
            "electric_efficiency_bounds": [lo, hi],
            "electric_efficiency_note": ("mechanical power / (teeth power + the rotary side's own loss); that loss is "
                                         "bounded by 0 and the unloaded electrical power "
                                         f"{electric_power_w:.4g} W: midpoint +- half the spread (model form)")}


def rotor_stage(teeth: TeethReport, params: RotorParams, load_torque: float, electric_power_w: float, *,
                points: int = 41, say=None) -> dict:
    """The rotor's results at the reported teeth motion, with errors from its error box.

    Parameters
    ----------
    teeth : TeethReport
        Teeth motion and its errors.
    params : RotorParams
        Rotor, spring, contact and friction data (:func:`rotor_params_from_design` for the design's).
    load_torque : float
        Resisting torque, N m (the drill tool's friction in rock).
    electric_power_w : float
        The transducer's unloaded electrical power, W: the upper bound of the rotary side's own loss.
    points : int
        Speeds on the torque-speed curve.
    say : callable, optional
        Progress lines.

    Returns
    -------
    dict
        ``"result"``: the nominal :class:`impact.rotor.RotorResult`; ``"json"``: the summary block
        (every output of :data:`OUTPUTS` with ``_error``, the efficiency with its model-form
        error, the inputs, the nominal result's record and its notes).
    """
    check_nonnegative("electric_power_w", electric_power_w, "W")
    nominal, values, spread = error_box(teeth, params, load_torque, points)
    out = {}
    for key, _, _ in OUTPUTS:
        out[key], out[f"{key}_error"] = values[key], spread[key]
    out.update(_efficiency(nominal, electric_power_w))
    out["errors_from"] = "largest departure over the 8 corners of the teeth motion's error box"
    out["teeth"] = {"freq_hz": teeth.freq_hz, "axial_m": teeth.axial_m, "axial_m_error": teeth.axial_error_m,
                    "ellipse_ratio": teeth.ratio, "ellipse_ratio_error": teeth.ratio_error,
                    "phase_deg": teeth.phase_deg, "phase_deg_error": teeth.phase_error_deg}
    out["load_torque_n_m"] = load_torque
    out["nominal"] = nominal.to_dict()
    out["hover"] = nominal.hover
    out["notes"] = list(nominal.notes)
    if say:
        say("      " + rotor_text(values, spread, load_torque, None if nominal.hover is None else nominal.hover["holds"],
                                       nominal.torque_bound))
    return {"result": nominal, "json": out}


def teeth_report(wp, f_w: float, est, scale: float = 1.0) -> tuple[TeethReport, dict]:
    """The teeth motion of the working point ``wp`` (at ``f_w`` Hz, amplitudes times ``scale``)
    with its errors from the discretisation-error estimate ``est``
    (:class:`fem.errors.ErrorEstimate`, or None), and a note for each error it cannot give
    (``axial_error_note``, ``ratio_error_note``, ``phase_error_note``).

    The axial amplitude carries the relative error of ``teeth_axial_per_volt_m``, the ellipse
    ratio and the phase their own estimated errors (:mod:`fem.errors`).
    """
    def error_of(q):
        return est.error(q) if est is not None and q in est.errors else None

    axial = _teeth_axial(wp, scale)
    rel = est.relative("teeth_axial_per_volt_m") if error_of("teeth_axial_per_volt_m") is not None else None
    ratio_err, phase_err = error_of("teeth_ellipse_ratio"), error_of("teeth_phase_deg")
    teeth = TeethReport(freq_hz=f_w, axial_m=axial, axial_error_m=axial * (rel or 0.0), ratio=wp.teeth_ellipse_ratio,
                        ratio_error=ratio_err or 0.0, phase_deg=wp.teeth_phase_deg, phase_error_deg=phase_err or 0.0)
    notes = {f"{name}_error_note": "not estimated (no discretisation-error estimate in this run): the errors exclude it"
             for name, err in (("axial", rel), ("ratio", ratio_err), ("phase", phase_err)) if err is None}
    return teeth, notes


def pipeline_rotor_stage(design, wp, f_w: float, est, wob: float, say=None) -> dict | None:
    """The stage as the pipeline runs it, or None for a design without teeth or without the
    rotor's data (a CAD drawing: its coupler is a solid, not a parametric coupler with a rotor).

    ``wp``: the harmonic working point (``teeth_tops`` among its surfaces), ``f_w`` its frequency
    (Hz), ``est`` the discretisation-error estimate (:func:`results.errors.estimate_stage`, or
    None), ``wob`` the weight on bit (N) whose bit friction is the load. The teeth motion and its
    errors: :func:`teeth_report`.
    """
    coupler = getattr(design, "coupler", None)
    if "teeth_tops" not in getattr(wp, "surfaces", {}) or not getattr(coupler, "n_teeth", 0):
        return None
    teeth, notes = teeth_report(wp, f_w, est)
    out = rotor_stage(teeth, rotor_params_from_design(design), bit_friction_torque(wob, *BIT),
                      float(wp.power_w), say=say)
    j = out["json"]
    j.update(notes)
    j["load_note"] = (f"the bit's friction in rock: flat {BIT[0] * 1e3:g} mm bit, weight on bit {wob:g} N, "
                      f"mu_rock {BIT[1]:g} (assumed)")
    return out


def report_lines(rotor: dict | None) -> list[str]:
    """The report's rotary-unit section from the summary's ``rotor`` block (None: no section).

    The terminal's line (:func:`rotor_text`: no-load speed, stall torque, speed under the load,
    each +- its error), the teeth motion it was driven by with its discretisation errors, the
    power and efficiencies, and the model's own notes (a rotor that does not hover is no
    prediction): the report states what the terminal printed, with the same uncertainties.
    """
    if not rotor:
        return []
    t = rotor["teeth"]
    holds = (rotor.get("hover") or {}).get("holds")
    values = {key: rotor[key] for key, _, _ in OUTPUTS}
    errors = {key: rotor[f"{key}_error"] for key, _, _ in OUTPUTS}
    bound = (rotor.get("nominal") or {}).get("torque_bound_mu_f_r_n_m")
    lines = ["", "## Rotary unit", "",
             rotor_text(values, errors, rotor["load_torque_n_m"], holds, bound) + ".", "",
             f"Driven by the teeth motion at {t['freq_hz'] / 1e3:.3f} kHz: axial "
             f"{plus_minus(t['axial_m'], t['axial_m_error'], 'um', 1e6)}, ellipse ratio "
             f"{plus_minus(t['ellipse_ratio'], t['ellipse_ratio_error'], '')}, phase "
             f"{plus_minus(t['phase_deg'], t['phase_deg_error'], 'deg')} (± discretisation); the rotor's errors are "
             f"the {rotor['errors_from']}. The load: {rotor['load_note']}; under it "
             f"{plus_minus(rotor['load_power_w'], rotor['load_power_w_error'], 'mW', 1e3)} mechanical, "
             f"contact efficiency {plus_minus(rotor['contact_efficiency'], rotor['contact_efficiency_error'], '')}, "
             f"electrical efficiency {plus_minus(rotor['electric_efficiency'], rotor['electric_efficiency_error'], '')} "
             f"({rotor['electric_efficiency_note']}); largest power "
             f"{plus_minus(rotor['max_power_w'], rotor['max_power_w_error'], 'mW', 1e3)}.", ""]
    return lines + [f"- {note}" for note in rotor.get("notes", [])] + ([""] if rotor.get("notes") else [])


def _teeth_axial(wp, scale: float) -> float:
    """The teeth tops' axial amplitude (m) of the working point ``wp`` times ``scale`` (the
    harmonic response is linear in the drive voltage)."""
    if "teeth_tops" not in getattr(wp, "surfaces", {}):
        raise ParameterError("coupler.n_teeth", 0, "must be >= 1: the working point has no teeth tops to drive "
                                                   "the rotor")
    return abs(wp.surfaces["teeth_tops"]["axial"]) * scale


STUDY_OUTPUTS = {"rotor_no_load_rpm": "no_load_speed_rpm", "rotor_stall_torque_n_m": "stall_torque_n_m",
                 "rotor_load_rpm": "load_speed_rpm"}
"""A study's rotor columns (:data:`results.study.OUTPUTS`) and the stage's outputs they are."""


def study_rotor(design, wp, f_w: float, scale: float, rotor_values: dict, wob: float, est=None) -> dict:
    """One design-study point's rotor outputs (``rotor_*`` of :data:`results.study.OUTPUTS`),
    each with its error (``<column>_error``).

    The teeth motion of the working point ``wp`` at ``f_w`` (Hz) scaled by ``scale`` (the drive
    voltage over the working point's: the point's voltage for a study's 1 V working point) with
    its errors from ``est`` (the point's discretisation-error estimate, :func:`teeth_report`),
    the rotor data of ``design`` (:func:`rotor_params_from_design`) with ``rotor_values``
    (RotorParams fields) set, and the bit's friction torque under ``wob`` (N) as the load: the
    nominal results of :func:`rotor_stage` and their departures over the error box. Without an
    estimate the errors exclude the FE's and ``rotor_note`` says so.
    """
    params = rotor_params_from_design(design).with_(**rotor_values)
    teeth, notes = teeth_report(wp, f_w, est, scale)
    nominal, values, spread = error_box(teeth, params, bit_friction_torque(wob, *BIT), 41)
    rec = {}
    for column, key in STUDY_OUTPUTS.items():
        rec[column], rec[f"{column}_error"] = float(values[key]), float(spread[key])
    rec["rotor_hovers"] = float(bool(nominal.hover["holds"]))
    missing = [k.split("_")[0] for k in notes]
    rec["rotor_note"] = (f"no discretisation-error estimate of the teeth's {', '.join(missing)}: the errors exclude it"
                         if missing else "")
    return rec
