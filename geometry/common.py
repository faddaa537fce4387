"""Plumbing shared by every rpud package: input errors, TOML <-> frozen dataclasses,
atomic file output and command-line error handling.

This module imports nothing heavy (no gmsh, no pyvista), so ``impact`` and ``fem`` may use
it freely while ``geometry`` stays the upstream end of the data flow.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import logging
import math
import os
import sys
import tempfile
import tomllib
import types
import typing
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "ParameterError",
    "check_positive",
    "check_nonnegative",
    "check_range",
    "check_choice",
    "load_toml",
    "dump_toml",
    "from_mapping",
    "to_mapping",
    "atomic_output",
    "atomic_write_text",
    "write_json",
    "save_figure",
    "pyplot",
    "to_jsonable",
    "CliParser",
    "run_cli",
]


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
        super().__init__(f"{name} = {value!r}: {allowed}")


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


def check_positive(name: str, value: Any, unit: str = "") -> None:
    """Raise :class:`ParameterError` unless ``value`` is a finite number > 0."""
    if not (_is_number(value) and math.isfinite(value) and value > 0):
        raise ParameterError(name, value, f"must be a finite number > 0{' ' + unit if unit else ''}")


def check_nonnegative(name: str, value: Any, unit: str = "") -> None:
    """Raise :class:`ParameterError` unless ``value`` is a finite number >= 0."""
    if not (_is_number(value) and math.isfinite(value) and value >= 0):
        raise ParameterError(name, value, f"must be a finite number >= 0{' ' + unit if unit else ''}")


def check_integer(name: str, value: Any, minimum: int) -> None:
    """Raise :class:`ParameterError` unless ``value`` is an ``int`` >= ``minimum``."""
    if not (isinstance(value, int) and value >= minimum):
        raise ParameterError(name, value, f"must be an integer >= {minimum}")


def check_range(name: str, value: Any, lo: float, hi: float, unit: str = "",
                lo_open: bool = False, hi_open: bool = False) -> None:
    """Raise :class:`ParameterError` unless ``lo <= value <= hi`` (bounds optionally open)."""
    ok = _is_number(value) and math.isfinite(value)
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


# --------------------------------------------------------------------------- TOML


def load_toml(path: str | os.PathLike) -> dict:
    """Read a TOML file; a missing or malformed file is a :class:`ParameterError`."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ParameterError("config", str(path), "file does not exist") from None
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError("config", str(path), f"is not valid TOML ({exc})") from None


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
        if not _is_number(value):
            raise ParameterError(where, value, "must be a number")
        return float(value)
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
    """
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    hints = _resolve_hints(cls)
    unknown = sorted(set(data) - set(fields))
    if unknown:
        name = f"{where}.{unknown[0]}" if where else unknown[0]
        raise ParameterError(name, data[unknown[0]], f"unknown key; allowed: {', '.join(fields)}")
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


# --------------------------------------------------------------------------- atomic output


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` only on success.

    The temporary name keeps the suffix, so writers that pick a format from the extension
    (gmsh, meshio, matplotlib, pyvista) behave as for the final name. On any exception the
    temporary file is removed and ``path`` is left untouched: never half a result file.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".part{path.suffix}", dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.replace(tmp_path, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp_path.unlink()
        raise


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` through a temporary file and an atomic rename."""
    with atomic_output(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def pyplot():
    """matplotlib's pyplot on the non-interactive Agg backend (imported on first use)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path: str | os.PathLike) -> Path:
    """Lay out, save (atomically, format from the suffix) and close a matplotlib figure."""
    import matplotlib.pyplot as plt

    path = Path(path)
    fig.tight_layout()
    with atomic_output(path) as tmp:
        fig.savefig(tmp)
    plt.close(fig)
    return path


def write_json(path: str | os.PathLike, data: Any) -> Path:
    """Write ``data`` (numpy values allowed) as indented JSON, atomically."""
    return atomic_write_text(path, json.dumps(to_jsonable(data), indent=2, allow_nan=False) + "\n")


# --------------------------------------------------------------------------- command line


class CliParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose usage errors are one line on stderr and exit code 2."""

    def error(self, message: str) -> typing.NoReturn:  # noqa: D401 - argparse API
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise SystemExit(2)


def run_cli(main: Callable[[list[str] | None], int | None], argv: list[str] | None = None,
            prog: str = "rpud") -> int:
    """Run a CLI entry point: bad input becomes one readable line and exit code 2.

    ``ParameterError`` (and ``FileNotFoundError``/``PermissionError`` on the user's paths) are
    reported without a traceback. Other exceptions are bugs and propagate.
    """
    try:
        code = main(argv)
    except ParameterError as exc:
        sys.stderr.write(f"{prog}: error: {exc}\n")
        return 2
    except (FileNotFoundError, PermissionError, IsADirectoryError) as exc:
        sys.stderr.write(f"{prog}: error: {exc.strerror or exc}: {exc.filename}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write(f"{prog}: interrupted\n")
        return 130
    return int(code or 0)


def setup_logging(verbose: int = 0) -> None:
    """Configure the root logger for a CLI (libraries only create loggers)."""
    level = logging.WARNING if verbose < 0 else logging.INFO if verbose == 0 else logging.DEBUG
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)
