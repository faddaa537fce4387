"""The losses every command that drives the transducer assumes, and where they come from.

The datasheet losses (PZT-8 Q_m 1000, Ti-6Al-4V Q 10 000, ...) describe the unbolted parts. An
assembled Langevin transducer loses far more in its bolted joints, its bolt and its mount; its
mechanical quality factor is of order 10^2, not 10^3, and it moves the drive's answer (tip
amplitude, power, tool energy) in proportion. Without a measurement of the drill (its admittance
sweep: :mod:`fem.bvd`, ``--admittance FILE``) the drive commands use one assumed quality factor,
:data:`ASSEMBLED_Q_MECH`, applied to every part, with the dielectric losses of the datasheet, and
the pipeline brackets it by :data:`Q_BRACKET` (Q/2 and 2Q).
"""

from __future__ import annotations

from dataclasses import dataclass

from rpud_common import ParameterError, check_range

__all__ = ["ASSEMBLED_Q_MECH", "ASSEMBLED_Q_SOURCE", "Q_BRACKET", "DriveLosses", "default_losses",
           "q_option_losses", "add_loss_options"]

ASSEMBLED_Q_MECH = 100.0
"""Assumed mechanical quality factor of the assembled transducer (every part)."""

ASSEMBLED_Q_SOURCE = (
    "assumed: assembled (bolted, mounted) Langevin transducers have Q_m of order 10^2 against 10^3 for the "
    "ceramic alone (PZT-8 datasheet Q_m 1000); not measured on this drill. The article's 15 um at 225 V "
    "implies ~64 for this model. Q/2 and 2Q bracket the assumption; a measured admittance (--admittance) "
    "replaces it")
"""Where :data:`ASSEMBLED_Q_MECH` comes from, printed beside every number it moves."""

Q_BRACKET = (0.5, 2.0)
"""Factors on Q of the sensitivity runs the pipeline reports beside the default."""


@dataclass(frozen=True)
class DriveLosses:
    """The losses of a driven run and their source.

    Attributes
    ----------
    q_mech : float or None
        Mechanical quality factor applied to every part (None: each material's datasheet value).
    tan_delta : float or None
        Dielectric loss tangent of the ceramics (None: the datasheet value).
    origin : str
        One word for the inputs line: ``assumed``, ``given``, ``datasheet`` or ``measured``.
    source : str
        Where the numbers come from, in full (printed and written with the results).
    q_mech_ci95 : float or None
        95 % CI half-width of ``q_mech`` when it was measured (a BVD fit), else None.
    """

    q_mech: float | None = ASSEMBLED_Q_MECH
    tan_delta: float | None = None
    origin: str = "assumed"
    source: str = ASSEMBLED_Q_SOURCE
    q_mech_ci95: float | None = None

    def __post_init__(self):
        if self.q_mech is not None:
            check_range("q_mech", self.q_mech, 1.0, 1e6)
        if self.tan_delta is not None:
            check_range("tan_delta", self.tan_delta, 0.0, 1.0)
        if not self.source:
            raise ParameterError("losses source", self.source, "must say where the losses come from")

    def loss_model(self):
        """The :class:`fem.harmonic.LossModel` of these losses."""
        from .harmonic import LossModel

        return LossModel(q_mech=self.q_mech, tan_delta=self.tan_delta)

    def scaled(self, factor: float) -> "DriveLosses":
        """The same losses with ``q_mech`` multiplied by ``factor`` (a sensitivity run)."""
        if self.q_mech is None:
            raise ParameterError("q_mech", None, "datasheet losses have no single Q to scale")
        return DriveLosses(self.q_mech * factor, self.tan_delta, f"{factor:g} x {self.origin}",
                           f"{factor:g} x ({self.source})")

    def short(self) -> str:
        """``"Q_mech 100 (assumed), tan delta datasheet"``: the inputs line's item."""
        q = "datasheet" if self.q_mech is None else f"{self.q_mech:.4g}"
        if self.q_mech_ci95 is not None:
            q += f" ± {self.q_mech_ci95:.2g}"
        td = "datasheet" if self.tan_delta is None else f"{self.tan_delta:.3g}"
        return f"Q_mech {q} ({self.origin}), tan delta {td}"

    def text(self) -> str:
        """:meth:`short` and the full source."""
        return f"{self.short()}: {self.source}"

    @classmethod
    def from_record(cls, rec: dict) -> "DriveLosses":
        """The losses of a :meth:`record`."""
        return cls(rec["q_mech"], rec["tan_delta"], rec["origin"], rec["source"], rec["q_mech_ci95_half_width"])

    def record(self) -> dict:
        return {"q_mech": self.q_mech, "q_mech_ci95_half_width": self.q_mech_ci95, "tan_delta": self.tan_delta,
                "origin": self.origin, "source": self.source}


def default_losses() -> DriveLosses:
    """The assembled-transducer losses every drive command assumes without a measurement."""
    return DriveLosses()


def q_option_losses(q_mech: float | None, tan_delta: float | None = None) -> DriveLosses:
    """Losses of a ``--q-mech Q`` option: None -> the default, 0 -> the datasheet values, else Q as given."""
    if q_mech is None:
        return DriveLosses(tan_delta=tan_delta)
    if q_mech == 0:
        return DriveLosses(None, tan_delta, "datasheet", "datasheet values of every material (the unbolted parts)")
    return DriveLosses(float(q_mech), tan_delta, "given", "given on the command line (--q-mech)")


def add_loss_options(parser, *, tan_delta: bool = False, number_type=float) -> None:
    """The loss options every drive command shares: ``--q-mech``, ``--admittance`` and, where the
    command takes it, ``--tan-delta`` (one wording, one default: :data:`ASSEMBLED_Q_MECH`)."""
    parser.add_argument("--q-mech", type=number_type, default=None, metavar="Q",
                        help=f"mechanical quality factor of the assembled transducer, applied to every part "
                             f"(default: the assumed {ASSEMBLED_Q_MECH:g} of fem.losses, its source printed; "
                             f"0: each material's datasheet value)")
    if tan_delta:
        parser.add_argument("--tan-delta", type=number_type, default=None, metavar="T",
                            help="dielectric loss tangent of the ceramics (default: datasheet)")
    parser.add_argument("--admittance", metavar="CSV",
                        help="measured impedance/admittance sweep of the drill (frequency and |Z|, phase or G, B; "
                             "fem.bvd): its Butterworth-Van Dyke fit nearest the working mode sets the losses "
                             "(Q_m, tan delta) instead of --q-mech" + ("/--tan-delta" if tan_delta else ""))
