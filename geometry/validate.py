"""Physical bounds of design data and the shape of design files, one place for every entry point.

Every number of a design must be finite and lie in a stated physical range (a 1 um ring or a
2 km horn is a typo, not a drill: it would hang Gmsh or overflow the models); names become file
and mesh-region names, so they are plain identifiers; counts are bounded. The messages state
the range, so a refused value says what would have been accepted.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from typing import Any

from rpud_common import ParameterError, check_integer, check_range

__all__ = ["MIN_FEATURE", "MIN_LAYER", "MAX_LENGTH", "FREQUENCY_BAND", "MAX_COUNT", "check_length", "check_bore",
           "check_count", "check_name", "check_material", "check_frequency", "design_table"]

MIN_FEATURE = 1e-4
"""Smallest length of a design feature, m (0.1 mm: thinner electrodes are not meshed as parts)."""

MIN_LAYER = 1e-5
"""Smallest axial length of a stack segment, m (10 um: bonds, shims and insulators down to
this are meshed as structured layers, see :mod:`geometry.layers`)."""

MAX_LENGTH = 2.0
"""Largest length or diameter of a design feature, m."""

FREQUENCY_BAND = (100.0, 1e6)
"""Accepted target frequencies, Hz."""

MAX_COUNT = 64
"""Largest number of rings, slots, teeth, segments or electrodes of one design."""

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_+\-.]{0,63}")


def check_length(name: str, value: Any, minimum: float = MIN_FEATURE) -> None:
    """A finite length in [``minimum`` (default :data:`MIN_FEATURE`), :data:`MAX_LENGTH`] m."""
    check_range(name, value, minimum, MAX_LENGTH, "m")


def check_bore(name: str, value: Any) -> None:
    """0 (no bore) or a length in [:data:`MIN_FEATURE`, :data:`MAX_LENGTH`] m."""
    check_range(name, value, 0.0, MAX_LENGTH, "m")
    if 0 < value < MIN_FEATURE:
        raise ParameterError(name, value, f"must be 0 (none) or >= {MIN_FEATURE:g} m")


def check_frequency(name: str, value: Any) -> None:
    """A finite frequency inside :data:`FREQUENCY_BAND`, Hz."""
    check_range(name, value, *FREQUENCY_BAND, "Hz")


def check_count(name: str, value: Any, minimum: int = 0, maximum: int = MAX_COUNT, even: bool = False) -> None:
    """An integer in [minimum, maximum] (even if asked)."""
    if even and isinstance(value, int) and not isinstance(value, bool) and value % 2:
        raise ParameterError(name, value, f"must be an even integer in [{minimum}, {maximum}] (ground at both ends)")
    check_integer(name, value, minimum, maximum)


def check_name(name: str, value: Any, dots: bool = True) -> None:
    """A plain identifier (letters, digits, ``_ + - .``; at most 64; no ``..``).

    Names become file names (``results/<name>``, ``<name>-tuned.toml``) and mesh regions, so a
    path separator or ``..`` would write outside the intended folder.
    """
    ok = isinstance(value, str) and _NAME.fullmatch(value) is not None and ".." not in value
    if ok and not dots:
        ok = "." not in value
    if not ok:
        extra = "" if dots else ", no dots"
        raise ParameterError(name, value, "must be 1-64 letters, digits, '_', '+', '-' or '.', starting with a "
                                          f"letter or digit{extra} (it becomes a file name)")


def check_material(name: str, value: Any) -> None:
    """A material name known to the library (``geometry.materials``)."""
    from .materials import get_material

    if not isinstance(value, str):
        raise ParameterError(name, value, "must be a material name (string)")
    try:
        get_material(value)
    except ParameterError as exc:
        raise ParameterError(name, value, exc.allowed) from None


def _is_table(v: Any) -> bool:
    return isinstance(v, Mapping)


def design_table(data: Mapping[str, Any], path: str, select: str | None, known: Iterable[str]):
    """The design mapping of a loaded file: ``(mapping, where)``.

    A file holds one design (a top-level ``kind`` or design field, e.g. ``[horn]``) or a
    collection of designs, one table each, from which ``select`` picks one. An empty file, a
    selection from a single design and a collection without selection are refused.
    """
    if not data:
        raise ParameterError("design", path, "is empty: no design in it (omit the option for the built-in design)")
    known = set(known)
    single = any(k in known for k in data) or not all(_is_table(v) for v in data.values())
    if single:
        if select is not None:
            raise ParameterError("select", select, f"{path} holds a single design; drop the selection")
        return data, ""
    names = [k for k, v in data.items() if _is_table(v)]
    if select is None:
        raise ParameterError("design", path, "holds several designs; select one of: " + ", ".join(names))
    if select not in names:
        raise ParameterError("select", select, "unknown design; known: " + ", ".join(names))
    return data[select], select


def finite_or_none(name: str, value: Any, bound: float = 10.0) -> None:
    """``None`` or a finite number with ``|value| <= bound`` m (segment starts)."""
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or abs(value) > bound:
        raise ParameterError(name, value, f"must be a finite number in [-{bound:g}, {bound:g}] m or absent")
