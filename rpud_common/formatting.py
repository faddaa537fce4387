"""Numbers with their uncertainty as text: one convention for every command and report.

``plus_minus(19996.8, 90, "Hz")`` is ``"19 997 ± 90 Hz"``: the error to two significant digits
(all an estimate means), the value to the error's last digit, the integer part in thousands
groups. Standard library only, so every package (``impact`` included) prints errors the same way.
"""

from __future__ import annotations

import math

__all__ = ["plus_minus", "group_thousands"]


def plus_minus(value: float, error: float | None, unit: str = "", scale: float = 1.0, digits: int = 2) -> str:
    """``'19 997 ± 90 Hz'``: ``value x scale`` to the last digit of the error's ``digits``
    significant digits, thin thousands groups; no error (None/NaN): the value to 6 digits.

    Parameters
    ----------
    value : float
        In SI units (``scale`` turns it into ``unit``).
    error : float or None
        Its uncertainty, same units as ``value``; 0 prints ``± 0``.
    unit : str
        Unit shown after the numbers (after scaling).
    scale : float
        Factor from SI to ``unit`` (1e3 for N m -> mN m).
    digits : int
        Significant digits of the error.
    """
    v = value * scale
    u = f" {unit}" if unit else ""
    if error is None or not math.isfinite(error) or not math.isfinite(v):
        return f"{group_thousands(f'{v:.6g}')}{u}"
    e = abs(error * scale)
    if e == 0:
        return f"{group_thousands(f'{v:.6g}')} ± 0{u}"
    dec = digits - 1 - math.floor(math.log10(e))
    if dec >= 0:
        v_txt, e_txt = f"{v:.{dec}f}", f"{e:.{dec}f}"
    else:                                   # round both to tens, hundreds, ...
        v_txt, e_txt = f"{round(v, dec):.0f}", f"{round(e, dec):.0f}"
    return f"{group_thousands(v_txt)} ± {group_thousands(e_txt)}{u}"


def group_thousands(text: str) -> str:
    """Thousands groups of the integer part with a space (SI style): 19996.8 -> 19 996.8
    (four-digit integers stay whole: 1999.5)."""
    sign = "-" if text.startswith("-") else ""
    body = text.lstrip("-")
    if "e" in body or not body[:1].isdigit():
        return text
    whole, dot, frac = body.partition(".")
    if len(whole) > 4:
        whole = f"{int(whole):,}".replace(",", " ")
    return f"{sign}{whole}{dot}{frac}"
