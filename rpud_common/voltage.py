"""The drive-voltage convention of every command that drives the transducer.

A sinusoidal drive ``v(t) = V sin(w t)`` is named by its amplitude ``V`` (peak, the value the
physics uses), its RMS value ``V / sqrt(2)`` or its peak-to-peak value ``2 V``; the three differ
by up to 2x in amplitude and 4x in power. The article's "225 V" does not say which one it is.
The commands read ``--voltage V`` as the amplitude and ``--voltage-rms V`` as the RMS value
(mutually exclusive), carry the amplitude inside, and print the convention that ran next to every
voltage they report (:meth:`DriveVoltage.text`, :meth:`DriveVoltage.record`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .errors import ParameterError, check_range

__all__ = ["DriveVoltage", "add_voltage_options", "drive_voltage", "VOLTAGE_RANGE", "DEFAULT_VOLTAGE"]

VOLTAGE_RANGE = (1e-3, 1e4)
"""Accepted drive voltage, V (amplitude or RMS): 1 mV (below it no drive is meant) to 10 kV."""

DEFAULT_VOLTAGE = 225.0
"""The article's drive voltage, read as an amplitude, V."""

CONVENTIONS = ("amplitude", "rms")


@dataclass(frozen=True)
class DriveVoltage:
    """A drive voltage and the convention it was given in.

    Attributes
    ----------
    amplitude_v : float
        Amplitude (peak) of the sinusoidal drive, V: what the models use.
    convention : str
        ``"amplitude"`` or ``"rms"``: how the user gave it.
    """

    amplitude_v: float
    convention: str = "amplitude"

    def __post_init__(self):
        check_range("voltage", self.amplitude_v, 0.0, math.inf, "V", lo_open=True)
        if self.convention not in CONVENTIONS:
            raise ParameterError("voltage convention", self.convention, "must be 'amplitude' or 'rms'")

    @property
    def rms_v(self) -> float:
        """RMS value of the sinusoidal drive, V."""
        return self.amplitude_v / math.sqrt(2.0)

    @property
    def given_v(self) -> float:
        """The value as the user gave it (amplitude or RMS), V."""
        return self.rms_v if self.convention == "rms" else self.amplitude_v

    def text(self) -> str:
        """``"225 V amplitude (159.1 V rms)"``, or ``"159.1 V rms (225 V amplitude)"`` when given as RMS."""
        from .cli import quantity

        amp, rms = f"{quantity(self.amplitude_v, 'V')} amplitude", f"{quantity(self.rms_v, 'V')} rms"
        return f"{rms} ({amp})" if self.convention == "rms" else f"{amp} ({rms})"

    def record(self) -> dict:
        """The JSON block: amplitude, RMS, peak-to-peak and the convention given."""
        return {"amplitude_v": self.amplitude_v, "rms_v": self.rms_v, "peak_to_peak_v": 2 * self.amplitude_v,
                "given_as": self.convention}


def add_voltage_options(parser, default: float = DEFAULT_VOLTAGE, number_type=float) -> None:
    """``--voltage V`` (amplitude) and ``--voltage-rms V`` (RMS), one or the other."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--voltage", type=number_type, default=default, metavar="V",
                       help=f"drive voltage AMPLITUDE (peak) on the hot electrodes, V (default {default:g}, the "
                            "article's 225 V read as an amplitude)")
    group.add_argument("--voltage-rms", dest="voltage_rms", type=number_type, default=None, metavar="V",
                       help="drive voltage as an RMS value, V (amplitude = sqrt(2) x RMS); instead of --voltage")


def drive_voltage(args, default: float = DEFAULT_VOLTAGE) -> DriveVoltage:
    """The checked :class:`DriveVoltage` of parsed ``--voltage`` / ``--voltage-rms`` options."""
    rms = getattr(args, "voltage_rms", None)
    if rms is not None:
        check_range("--voltage-rms", rms, *VOLTAGE_RANGE, "V")
        return DriveVoltage(float(rms) * math.sqrt(2.0), "rms")
    amp = default if getattr(args, "voltage", None) is None else args.voltage
    check_range("--voltage", amp, *VOLTAGE_RANGE, "V")
    return DriveVoltage(float(amp), "amplitude")
