"""The bolted drill's rotary drive: why the teeth's torsion vanishes with the M12 bolt part, and
the design that restores it (geometry/examples.toml ``[bolted]``).

With the bolt part the working mode is stiffer, so the match lengthens the horn (67.1 -> 78.3 mm).
The stepped horn's thin tip section (``(1 - step_fraction) * horn.length`` long) is then a
torsional quarter-wave resonator near 20 kHz, ``c_T / (4 L_tip)`` with ``c_T = sqrt(G / rho)`` of
the horn's titanium. Hung on the thick section's end it is a tuned dynamic absorber of the torsion
that the coupler's slots produce: at its own frequency it holds the step still in torsion and the
teeth hardly twist. The coupler's own dimensions barely move it (first table: every coupler
lever at the bolted lengths, each as it is); the horn's step position does (second table: each
design matched to the target on the k = 0 sector).

With the absorber moved up (step 0.57) the teeth twist again, but the drill's torsional mode that
drives them lies below the drive, so the teeth's phase is near 0 deg instead of near 180 deg and
the rotor turns slowly. The bolt adds almost no torsional stiffness while the longer match lowers
every torsional mode; the horn's back section, whose polar moment goes as ``d^4`` while its
axial stiffness goes as ``d^2``, lifts that mode above the drive (third table: back diameters
matched with the step at 0.57 and the slotted zone 8 mm from the teeth).

    PYTHONPATH=. python benchmarks/study_bolted_coupler.py

k = 0 sector, refine 1, Q_mech 100 (the pipeline's mesh, matching and losses); ellipse ratio,
phase and tip amplitude of the working point at its f_r; the rotor's no-load speed from the
pipeline's rotor model at the pipeline's drive (225 V amplitude, weight on bit 7 N) without the
discretisation errors of the teeth motion (``python -m results --design NAME`` adds them).
Deterministic (same mesh, same numbers).
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time

from _table import print_table

TORSION_ABSORBER_NOTE = "c_T / (4 L_tip), the horn tip section's torsional quarter wave"

COUPLER_LEVERS = ({}, {"slot_depth": 0.004}, {"slot_depth": 0.006}, {"slot_width": 0.005},
                  {"slot_profile": "rectangular"}, {"slot_length": 0.024}, {"slot_angle_deg": 35.0},
                  {"slot_offset": 0.008}, {"slot_offset": 0.012}, {"tooth_height": 0.006})
"""Coupler changes tried at the bolted drill's matched lengths (each alone)."""

STEP_FRACTIONS = (0.43, 0.5, 0.57, 0.6)
"""Horn step positions matched with the bolt part (the default is 0.5)."""

BACK_DIAMETERS = (0.024, 0.026, 0.028, 0.030, 0.032)
"""Horn back-section diameters (m) matched with the bolt part, the step at 0.57 and the slotted
zone 8 mm from the teeth (the default's is 24 mm; the flange's 45 mm bounds it)."""

DRIVE_V, WOB_N = 225.0, 7.0
"""The pipeline's drive amplitude (V) and weight on bit (N) (results.pipeline.PipelineSettings)."""


def bolted(design=None, horn=None, coupler=None):
    """``design`` (default: the bolted example with the default drill's horn, slots and
    lengths, horn 67.1 mm and coupler 49.9 mm) with the changes given."""
    from geometry.examples import bolted_design

    d = design or bolted_design(horn_length=0.0671, coupler_length=0.0499, step_fraction=0.5, slot_offset=0.004,
                                  horn_back_diameter=0.024)
    return dataclasses.replace(d, horn=dataclasses.replace(d.horn, **(horn or {})),
                               coupler=dataclasses.replace(d.coupler, **(coupler or {})))


def absorber_hz(design) -> float:
    """The horn tip section's torsional quarter-wave frequency, Hz (fixed at the step, free at the tip)."""
    from geometry.materials import get_material

    m = get_material(design.horn.material, design.materials or None)
    c_t = math.sqrt(m.youngs_modulus / (2 * (1 + m.poisson_ratio)) / m.density)
    return c_t / (4 * (1 - design.horn.step_fraction) * design.horn.length)


def evaluate(design, match: bool) -> dict:
    """Working mode and working point of ``design`` (matched or as it is) on the pipeline's path."""
    from fem.losses import default_losses
    from results.stage_fe import MeshOptions, mesh_stage, match_stage
    from results.rotor_stage import study_rotor
    from results.stage_harmonic import harmonic_stage

    t0 = time.process_time()
    m = match_stage(mesh_stage(design, MeshOptions()), match=match)
    wp = harmonic_stage(m, loss=default_losses().loss_model(), voltage=1.0).wp
    torsion = [float(f) for f, label in zip(m.modal.f_r_hz, m.modal.labels) if label.startswith("torsional")]
    rpm = study_rotor(m.design, wp, m.f_r_hz, DRIVE_V, {}, WOB_N)["rotor_no_load_rpm"]
    return {"design": m.design, "f_r": m.f_r_hz, "ratio": wp.teeth_ellipse_ratio, "phase": wp.teeth_phase_deg,
            "tip_nm": wp.tip_per_volt_m * 1e9, "torsion": torsion, "rpm": rpm, "cpu": time.process_time() - t0}


def _row(name: str, r: dict) -> tuple:
    d = r["design"]
    near = ", ".join(f"{f / 1e3:.2f}" for f in r["torsion"])
    return (name, f"{d.horn.length * 1e3:.2f} / {d.coupler.length * 1e3:.2f}", f"{r['f_r']:.1f}",
            f"{absorber_hz(d) / 1e3:.2f}", near, f"{r['ratio']:.4f}", f"{r['phase']:.0f}", f"{r['tip_nm']:.1f}",
            f"{r['rpm']:.1f}", f"{r['cpu']:.0f}")


HEADERS = ("design", "horn / coupler mm", "f_r Hz", "absorber kHz", "torsional modes kHz", "ellipse ratio",
           "phase deg", "tip nm/V", "rotor rpm", "CPU s")


def main() -> int:
    from geometry.examples import bolted_design

    start = bolted()
    unbolted = evaluate(dataclasses.replace(start, stack=dataclasses.replace(start.stack, bolt_diameter=0.0)), False)
    base = evaluate(start, match=True)
    rows = [_row("without the bolt part, as it is", unbolted), _row("M12 bolt part, matched", base)]
    lengths = {"length": base["design"].coupler.length}
    for change in COUPLER_LEVERS[1:]:
        d = bolted(base["design"], coupler={**lengths, **change})
        name = ", ".join(f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}" for k, v in change.items())
        rows.append(_row(f"bolted lengths, {name}", evaluate(d, match=False)))
    print_table(rows, HEADERS)
    rows = []
    for s in STEP_FRACTIONS:
        rows.append(_row(f"M12, horn step_fraction {s:g}, matched", evaluate(bolted(horn={"step_fraction": s}), True)))
    print_table(rows, HEADERS)
    rows = []
    for b in BACK_DIAMETERS:
        d = bolted(bolted_design(), horn={"back_diameter": b})
        rows.append(_row(f"M12, step 0.57, slots 8 mm off, horn back {b * 1e3:g} mm, matched", evaluate(d, True)))
    rows.append(_row("geometry/examples.toml [bolted], as it is", evaluate(bolted_design(), match=False)))
    print_table(rows, HEADERS)
    print(f"absorber: {TORSION_ABSORBER_NOTE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
