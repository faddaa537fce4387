"""Bad input: one exception type that names the parameter, and the checks that raise it.

Every rpud entry point reports a :class:`ParameterError` as one line (which parameter, what
value, what is allowed) and exit code 2. Standard library and numpy only.
"""

from __future__ import annotations

import math
import typing
from typing import Any

import numpy as np

__all__ = ["ParameterError", "is_real_number", "is_finite_number", "check_positive", "check_nonnegative", "check_finite", "check_integer",
           "check_range", "check_choice"]


class ParameterError(ValueError):
    """Bad input: names the parameter, the value given and what is allowed.

    Parameters
    ----------
    name : str
        Parameter name as the user knows it (e.g. ``"m_free"``, ``"horn.length"``).
    value : object
        The value that was given.
    allowed : str
        What would have been accepted, in words (e.g. ``"must be > 0 kg"``).
    """

    def __init__(self, name: str, value: Any, allowed: str):
        self.name = name
        self.value = value
        self.allowed = allowed
        shown = repr(value)
        if len(shown) > 80:  # a whole hostile file or list must not flood the one-line message
            shown = shown[:60] + "..." + shown[-12:]
        super().__init__(f"{name} = {shown}: {allowed}")


def is_real_number(value: Any) -> bool:
    """True for an int or float (numpy's too) that is not a bool; finite or not."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


def is_finite_number(value: Any) -> bool:
    """True for a real number (not a bool) that is finite as a float.

    An integer beyond the float range (a TOML file may hold one) counts as not finite rather
    than raising ``OverflowError`` from :func:`math.isfinite`.
    """
    if not is_real_number(value):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def check_positive(name: str, value: Any, unit: str = "") -> None:
    """Raise :class:`ParameterError` unless ``value`` is a finite number > 0."""
    if not (is_finite_number(value) and value > 0):
        raise ParameterError(name, value, f"must be a finite number > 0{' ' + unit if unit else ''}")


def check_nonnegative(name: str, value: Any, unit: str = "") -> None:
    """Raise :class:`ParameterError` unless ``value`` is a finite number >= 0."""
    if not (is_finite_number(value) and value >= 0):
        raise ParameterError(name, value, f"must be a finite number >= 0{' ' + unit if unit else ''}")


def check_finite(name: str, value: Any, unit: str = "") -> None:
    """Raise :class:`ParameterError` unless ``value`` is a finite number (any sign)."""
    if not is_finite_number(value):
        raise ParameterError(name, value, f"must be a finite number{' ' + unit if unit else ''}")


def check_integer(name: str, value: Any, minimum: int, maximum: int | None = None) -> None:
    """Raise :class:`ParameterError` unless ``value`` is an ``int`` in ``[minimum, maximum]``."""
    ok = isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value >= minimum
    if ok and maximum is not None:
        ok = value <= maximum
    if not ok:
        bound = f"in [{minimum}, {maximum}]" if maximum is not None else f">= {minimum}"
        raise ParameterError(name, value, f"must be an integer {bound}")


def check_range(name: str, value: Any, lo: float, hi: float, unit: str = "",
                lo_open: bool = False, hi_open: bool = False) -> None:
    """Raise :class:`ParameterError` unless ``lo <= value <= hi`` (bounds optionally open).

    Examples
    --------
    >>> check_range("voltage", 225.0, 1e-3, 1e4, "V")
    >>> check_range("voltage", float("nan"), 1e-3, 1e4, "V")
    Traceback (most recent call last):
    rpud_common.errors.ParameterError: voltage = nan: must lie in [0.001, 10000] V
    """
    ok = is_finite_number(value)
    if ok:
        ok = (value > lo if lo_open else value >= lo) and (value < hi if hi_open else value <= hi)
    if not ok:
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        raise ParameterError(name, value, f"must lie in {left}{lo:g}, {hi:g}{right}{' ' + unit if unit else ''}")


def check_choice(name: str, value: Any, choices: typing.Iterable[Any]) -> None:
    """Raise :class:`ParameterError` unless ``value`` is one of ``choices``."""
    choices = list(choices)
    if value not in choices:
        raise ParameterError(name, value, "must be one of " + ", ".join(repr(c) for c in choices))
