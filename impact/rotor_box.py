"""The rotary unit's outputs with the error of the teeth motion that drives them.

The teeth motion comes with an error per input (axial amplitude, ellipse ratio, phase:
:class:`TeethReport`); :func:`error_box` runs :func:`impact.rotor.rotor_performance` at the
reported motion and at the eight corners of its error box, and the error of every output is its
largest departure over the corners (the outputs are monotone in each input over such boxes in
the cases tried; a bound then, not a statistical interval). :func:`rotor_text` prints the
headline with each error to two significant digits (:func:`rpud_common.plus_minus`).
The pipeline's stage (:mod:`results.rotor_stage`) and ``python -m impact rotor`` both use it.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

from rpud_common import check_nonnegative, check_range
from rpud_common.formatting import plus_minus

from .rotor import RotorParams, TeethMotion, rotor_performance

__all__ = ["TeethReport", "OUTPUTS", "ROUNDOFF", "outputs", "error_box", "rotor_text"]

_RPM = 30.0 / math.pi

OUTPUTS = (
    ("no_load_speed_rpm", "rpm", "rotor speed without load"),
    ("stall_torque_n_m", "N m", "mean driving torque at rest"),
    ("load_speed_rpm", "rpm", "rotor speed under the load torque"),
    ("load_power_w", "W", "mechanical power under the load torque"),
    ("max_power_w", "W", "largest mechanical power on the torque-speed curve"),
    ("teeth_power_w", "W", "power the teeth put into the contact under the load torque"),
    ("contact_efficiency", "-", "mechanical power / teeth power under the load torque"),
)
"""(key, unit, meaning) of the stage's outputs, each reported with ``<key>_error``."""

ROUNDOFF = 1e-9
"""Relative departure of a corner's output from the nominal one below which the two are equal:
the model's roots are found to 1e-13 and its integrals are exact to round-off, and its energy
balance closes to 1e-9 (``tests/test_rotor.py``). The stall torque of a contact that slides one
way over the window is ``mu F r`` whatever the teeth motion: its error is 0, not 5e-16."""


@dataclass(frozen=True)
class TeethReport:
    """The teeth motion as the harmonic response reports it, with its errors (SI; degrees).

    Parameters
    ----------
    freq_hz : float
        Drive frequency, Hz.
    axial_m, axial_error_m : float
        Axial amplitude of the teeth tops and its error, m.
    ratio, ratio_error : float
        Ellipse ratio (tangential / axial amplitude) and its error.
    phase_deg, phase_error_deg : float
        Phase of the tangential relative to the axial motion and its error, degrees.
    """

    freq_hz: float
    axial_m: float
    axial_error_m: float
    ratio: float
    ratio_error: float
    phase_deg: float
    phase_error_deg: float

    def __post_init__(self):
        for name in ("axial_error_m", "ratio_error", "phase_error_deg"):
            check_nonnegative(name, getattr(self, name))
        check_range("axial_error_m", self.axial_error_m, 0.0, 0.99 * self.axial_m, "m")
        TeethMotion.from_ellipse(self.freq_hz, self.axial_m, self.ratio, self.phase_deg)   # checks the motion

    @property
    def motion(self) -> TeethMotion:
        """The reported motion (the centre of the box)."""
        return TeethMotion.from_ellipse(self.freq_hz, self.axial_m, self.ratio, self.phase_deg)

    def corners(self):
        """The teeth motions at the corners of the error box (ratio kept >= 0)."""
        for sa, sr, sp in itertools.product((-1, 1), repeat=3):
            yield TeethMotion.from_ellipse(self.freq_hz, self.axial_m + sa * self.axial_error_m,
                                           max(0.0, self.ratio + sr * self.ratio_error),
                                           self.phase_deg + sp * self.phase_error_deg)


def outputs(res) -> dict:
    """The values of :data:`OUTPUTS` of a :class:`impact.rotor.RotorResult`."""
    pmax, _ = res.max_power
    return {"no_load_speed_rpm": res.no_load_speed * _RPM, "stall_torque_n_m": res.stall_torque,
            "load_speed_rpm": res.load_speed * _RPM, "load_power_w": res.load_power, "max_power_w": pmax,
            "teeth_power_w": res.load_teeth_power,
            "contact_efficiency": res.load_power / res.load_teeth_power if res.load_teeth_power > 0 else 0.0}


def error_box(teeth: TeethReport, params: RotorParams, load_torque: float, points: int, nominal=None):
    """The nominal result at ``teeth``, its :func:`outputs` and each output's largest departure
    over the corners of the error box (a departure within :data:`ROUNDOFF` of the values is 0).

    Parameters
    ----------
    teeth : TeethReport
        Teeth motion and its errors.
    params : RotorParams
        Rotor, spring, contact and friction data.
    load_torque : float
        Resisting torque, N m.
    points : int
        Speeds on the torque-speed curve.
    nominal : RotorResult, optional
        The result at the reported motion, if already computed (else computed here, with the
        hovering check).

    Returns
    -------
    tuple
        ``(nominal RotorResult, values dict, errors dict)``, both dicts keyed as :data:`OUTPUTS`.
    """
    if nominal is None:
        nominal = rotor_performance(teeth.motion, params, load_torque, points=points)
    values = outputs(nominal)
    spread = {k: 0.0 for k in values}
    for tm in teeth.corners():
        corner = outputs(rotor_performance(tm, params, load_torque, points=points, check_hover=False))
        for k, v in corner.items():
            d = abs(v - values[k])
            if d > ROUNDOFF * max(abs(v), abs(values[k])):
                spread[k] = max(spread[k], d)
    return nominal, values, spread


def rotor_text(values: dict, errors: dict, load_torque: float, hovers: bool | None,
               torque_bound: float | None = None) -> str:
    """One line: no-load speed, stall torque and the speed under the load, each +- its error.

    A stall torque at the friction bound ``torque_bound`` (mu F r, N m) is printed as that bound:
    the teeth motion's error does not move it (its error is the friction coefficient's)."""
    stall, stall_err = values["stall_torque_n_m"], errors["stall_torque_n_m"]
    if torque_bound is not None and stall_err == 0.0 and abs(stall - torque_bound) <= ROUNDOFF * torque_bound:
        stall_part = f"{stall * 1e3:.3g} mN m (the friction bound mu F r: set by the assumed mu, not by the teeth motion)"
    else:
        stall_part = plus_minus(stall, stall_err, "mN m", 1e3)
    return (f"rotor: no-load {plus_minus(values['no_load_speed_rpm'], errors['no_load_speed_rpm'], 'rpm')}, "
            f"stall {stall_part}, under "
            f"{load_torque * 1e3:.3g} mN m {plus_minus(values['load_speed_rpm'], errors['load_speed_rpm'], 'rpm')}"
            + ("" if hovers is None or hovers else "; the rotor does not hover (it bounces): not a prediction"))
