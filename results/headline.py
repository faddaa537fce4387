"""The run's headline, machine-readable: which model answers the user's question (the drill tool's
kinetic energy per impact against free mass), at which free mass, with which uncertainties, and
the comparison models' answers at the same mass (``summary.json`` ``headline``; the report and
the operating-point table read it).
"""

from __future__ import annotations

import math

__all__ = ["HEADLINE_QUANTITIES", "headline_record"]

#: the quantities of the headline record, with their report scale and unit
HEADLINE_QUANTITIES = (("mean_tool_ke_after_j", 1e3, "mJ"), ("tool_impact_rate_hz", 1.0, "Hz"),
                       ("tool_power_w", 1.0, "W"))


def _row_at(rows, m: float):
    """The row of free mass ``m`` (kg) in ``rows``, or None."""
    return next((r for r in rows if math.isclose(r["m_free_kg"], m)), None)


def headline_record(s: dict, note: str = "") -> dict | None:
    """The summary's ``headline`` block: which model answers, at which free mass, and its tool
    kinetic energy, impact rate and power, each ``{mean, ci95_half_width, members, model_form}``,
    with the comparison models' tool energy at the same mass (JSON-safe).

    The compliant model's row at the reference free mass (its heaviest row when the reference is
    not among its masses) when the run has that stage; else the device scenario's kinematic horn,
    whose ``model_form`` is None and ``model_form_note`` says why (``note``: why the compliant
    stage did not run). None when the summary has neither.
    """
    m_ref = s["A0"]["reference_m_free_kg"]
    doc = s.get("compliant_model")
    kin = [r for r in s.get("kinetic_energy_table", []) if "device_fe" in r]
    if doc and doc.get("rows"):
        top = _row_at(doc["rows"], m_ref) or doc["rows"][-1]
        m = top["m_free_kg"]
        rec = {"model": "compliant_model", "scenario": "device", "m_free_kg": m,
               "why": "the FE transducer's axial modes to a cut-off chosen from the contact time drive the free "
                      "mass through Hertz contacts at the horn and the tool: the tip recoils and the answer "
                      "converges in the modes (the convergence study); the horn models below cannot recoil or "
                      "do not converge in their modes",
               **{q: {**top[q], "model_form": top["model_form"][q]} for q, _, _ in HEADLINE_QUANTITIES},
               "model_form_from": top["model_form_from"]}
    else:
        row = _row_at(kin, m_ref)
        if row is None:
            return None
        m = row["m_free_kg"]
        why = note or "the compliant stage did not run"
        rec = {"model": "impacts.device_fe", "scenario": "device", "m_free_kg": m,
               "why": f"the kinematic horn at the impact-loaded amplitude: {why}",
               **{q: {**row["device_fe"][q], "model_form": None} for q, _, _ in HEADLINE_QUANTITIES},
               "model_form_note": f"not estimated: {why} (its convergence study gives the model-form estimate)"}
    cm = s.get("coupled_model") or {}
    newton = _row_at(cm.get("rows", []), m)
    dev = _row_at(kin, m)
    rec["comparison_tool_ke_j"] = {
        "kinematic_damper_a0": dev["device_fe"]["mean_tool_ke_after_j"] if dev else None,
        "kinematic_unloaded_a0": newton["kinematic_unloaded"]["mean_tool_ke_after_j"] if newton else None,
        "newton_working_band": newton["coupled"]["mean_tool_ke_after_j"] if newton else None}
    return rec
