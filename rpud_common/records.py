"""TOML files <-> frozen dataclasses, and JSON-friendly values.

``load_toml`` refuses missing, oversized, non-UTF-8, malformed and too deeply nested files with
a :class:`~rpud_common.errors.ParameterError`; ``from_mapping`` builds a (nested) frozen
dataclass, refusing unknown keys and missing required fields by name.
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import tomllib
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ParameterError, check_choice, is_real_number

__all__ = ["MAX_TOML_BYTES", "MAX_TOML_DEPTH", "load_toml", "toml_section", "dump_toml", "from_mapping",
           "to_mapping", "to_jsonable"]


MAX_TOML_BYTES = 1_000_000
"""Largest design/config file read, bytes (real ones are a few kB)."""

MAX_TOML_DEPTH = 8
"""Deepest table/array nesting accepted in a design/config file (real ones use 3)."""


def _depth(obj: Any, level: int = 0) -> int:
    if level > MAX_TOML_DEPTH:
        return level
    if isinstance(obj, Mapping):
        return max([_depth(v, level + 1) for v in obj.values()], default=level + 1)
    if isinstance(obj, list):
        return max([_depth(v, level + 1) for v in obj], default=level + 1)
    return level


def load_toml(path: str | os.PathLike, name: str = "config") -> dict:
    """Read a TOML file as UTF-8; every way it can be unusable is a :class:`ParameterError`.

    Refused: an empty path, a missing, unreadable or non-regular file, more than
    :data:`MAX_TOML_BYTES`, bytes that are not UTF-8, malformed TOML, nesting deeper than
    :data:`MAX_TOML_DEPTH`.

    Parameters
    ----------
    path : path-like
    name : str
        Parameter name used in the messages (e.g. ``"--design"``).
    """
    text_path = os.fspath(path) if isinstance(path, (str, os.PathLike)) else path
    if not isinstance(text_path, str) or not text_path.strip() or "\0" in text_path:
        raise ParameterError(name, path, "must name a TOML file")
    p = Path(text_path)
    try:
        if not p.exists():
            raise ParameterError(name, text_path, "file does not exist")
        if not p.is_file():
            raise ParameterError(name, text_path, "is not a regular file")
        size = p.stat().st_size
        if size > MAX_TOML_BYTES:
            raise ParameterError(name, text_path, f"is {size} bytes; at most {MAX_TOML_BYTES} are read")
        raw = p.read_bytes()
    except OSError as exc:
        raise ParameterError(name, text_path, f"cannot be read ({exc.strerror or exc})") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ParameterError(name, text_path, f"is not UTF-8 text (byte {raw[exc.start]:#04x} at offset "
                                              f"{exc.start})") from None
    if text.startswith("\ufeff"):  # a BOM is legal UTF-8 but not TOML
        text = text[1:]
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(name, text_path, f"is not valid TOML ({exc})") from None
    except RecursionError:
        raise ParameterError(name, text_path, f"nests deeper than {MAX_TOML_DEPTH} levels") from None
    except ValueError:
        # Python refuses to convert integers of more than sys.get_int_max_str_digits() digits
        raise ParameterError(name, text_path, f"holds an integer of more than {sys.get_int_max_str_digits()} digits") from None
    if _depth(data) > MAX_TOML_DEPTH:
        raise ParameterError(name, text_path, f"nests deeper than {MAX_TOML_DEPTH} levels")
    return data


def toml_section(data: Mapping[str, Any], table: str, source: str = "config") -> Mapping[str, Any]:
    """The parameters of a file that may hold them at top level or in one ``[table]``.

    Both at once is ambiguous (which one wins?), so a top-level key next to the table is a
    :class:`ParameterError` naming that key, as is a ``table`` key that is not a table.
    """
    if table not in data:
        return data
    stray = sorted(k for k in data if k != table)
    if stray:
        raise ParameterError(stray[0], data[stray[0]], f"top-level key next to the [{table}] table in "
                                                       f"{source}: move it into [{table}] or drop the table")
    if not isinstance(data[table], Mapping):
        raise ParameterError(table, data[table], f"must be a table ([{table}]) in {source}")
    return data[table]


def dump_toml(data: Mapping[str, Any]) -> str:
    """Serialise a mapping (tuples and numpy scalars allowed) to TOML text."""
    import tomli_w

    return tomli_w.dumps(to_jsonable(data, drop_none=True))


def _resolve_hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _convert(value: Any, hint: Any, where: str) -> Any:
    """Coerce a TOML value to the annotated field type (nested dataclasses, tuples)."""
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        non_none = [a for a in args if a is not type(None)]
        last_error: Exception | None = None
        for arg in non_none:
            try:
                return _convert(value, arg, where)
            except ParameterError as exc:
                last_error = exc
        raise last_error if last_error else ParameterError(where, value, f"must be {hint}")
    if dataclasses.is_dataclass(hint):
        if isinstance(value, hint):
            return value
        if not isinstance(value, Mapping):
            raise ParameterError(where, value, f"must be a table of {hint.__name__} fields")
        return from_mapping(hint, value, where)
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ParameterError(where, value, "must be a list")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(v, args[0], f"{where}[{i}]") for i, v in enumerate(value))
        if args and len(args) != len(value):
            raise ParameterError(where, value, f"must be a list of {len(args)} values")
        return tuple(_convert(v, a, f"{where}[{i}]") for i, (v, a) in enumerate(zip(value, args or [Any] * len(value))))
    if origin is typing.Literal:
        check_choice(where, value, args)
        return value
    if hint is float:
        if not is_real_number(value):
            raise ParameterError(where, value, "must be a number")
        try:
            number = float(value)
        except OverflowError:  # an integer beyond the float range
            raise ParameterError(where, value, "must be a finite number") from None
        # TOML spells nan and inf; no file field means either, even one its kind does not use
        if not math.isfinite(number):
            raise ParameterError(where, value, "must be a finite number")
        return number
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            if isinstance(value, float) and value.is_integer():
                return int(value)
            raise ParameterError(where, value, "must be an integer")
        return int(value)
    if hint is bool:
        if not isinstance(value, bool):
            raise ParameterError(where, value, "must be true or false")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise ParameterError(where, value, "must be a string")
        return value
    return value


def from_mapping(cls: type, data: Mapping[str, Any], where: str = "") -> Any:
    """Build the (frozen) dataclass ``cls`` from a mapping, recursing into nested dataclasses.

    Unknown keys are an error (a misspelt option must not be silently ignored); missing keys
    take the dataclass defaults. Validation in ``__post_init__`` runs as usual.

    Parameters
    ----------
    cls : type
        A dataclass.
    data : mapping
        Field name -> value (a TOML table); nested dataclasses as nested tables.
    where : str
        Dotted path of ``data`` in its file, for the error message.

    Returns
    -------
    cls
        The instance, its values converted to the field types.

    Raises
    ------
    ParameterError
        An unknown or missing key, or a value of the wrong type, named by its dotted path.

    Examples
    --------
    >>> from dataclasses import dataclass
    >>> @dataclass(frozen=True)
    ... class Rod:
    ...     length: float = 0.04
    ...     material: str = "PZT-4"
    >>> from_mapping(Rod, {"length": 0.05})
    Rod(length=0.05, material='PZT-4')
    >>> to_mapping(Rod())
    {'length': 0.04, 'material': 'PZT-4'}
    >>> from_mapping(Rod, {"lenght": 0.05}, where="rod")
    Traceback (most recent call last):
    rpud_common.errors.ParameterError: rod.lenght = 0.05: unknown key; allowed: length, material
    """
    if not isinstance(data, Mapping):
        raise ParameterError(where or cls.__name__, data, f"must be a table of {cls.__name__} fields")
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    hints = _resolve_hints(cls)
    # unknown keys first: a misspelt required key is reported as the typo, with the right names
    unknown = sorted(set(data) - set(fields), key=str)
    if unknown:
        name = f"{where}.{unknown[0]}" if where else unknown[0]
        raise ParameterError(name, data[unknown[0]], f"unknown key; allowed: {', '.join(fields)}")
    missing = [k for k, f in fields.items() if k not in data and f.default is dataclasses.MISSING
               and f.default_factory is dataclasses.MISSING]
    if missing:
        name = f"{where}.{missing[0]}" if where else missing[0]
        raise ParameterError(name, None, "required field is missing")
    kwargs = {}
    for key, value in data.items():
        name = f"{where}.{key}" if where else key
        kwargs[key] = _convert(value, hints[key], name)
    return cls(**kwargs)


def to_mapping(obj: Any) -> dict:
    """A dataclass as a plain dict of TOML/JSON-friendly values (tuples become lists)."""
    return to_jsonable(dataclasses.asdict(obj))


def to_jsonable(obj: Any, drop_none: bool = False) -> Any:
    """Convert numpy arrays/scalars, tuples, Paths and dataclasses to JSON-friendly values."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        obj = dataclasses.asdict(obj)
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v, drop_none) for k, v in obj.items()
                if not (drop_none and v is None)}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v, drop_none) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist(), drop_none)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, complex):
        return {"re": obj.real, "im": obj.imag}
    if isinstance(obj, Path):
        return str(obj)
    return obj
