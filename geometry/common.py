"""Plumbing shared by every rpud package: input errors, TOML <-> frozen dataclasses,
atomic file output and command-line error handling.

This module imports nothing heavy (no gmsh, no pyvista), so ``impact`` and ``fem`` may use
it freely while ``geometry`` stays the upstream end of the data flow.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import dataclasses
import json
import logging
import math
import os
import shutil
import signal
import sys
import threading
import tempfile
import tomllib
import types
import typing
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .launch import Terminated, forget_interrupt, handle, on_sigterm, settle

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
    "check_finite",
    "check_integer",
    "check_output_paths",
    "atomic_folder",
    "toml_section",
    "Terminated",
    "MAX_TOML_BYTES",
    "MAX_TOML_DEPTH",
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
        shown = repr(value)
        if len(shown) > 80:  # a whole hostile file or list must not flood the one-line message
            shown = shown[:60] + "..." + shown[-12:]
        super().__init__(f"{name} = {shown}: {allowed}")


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


def check_finite(name: str, value: Any, unit: str = "") -> None:
    """Raise :class:`ParameterError` unless ``value`` is a finite number (any sign)."""
    if not (_is_number(value) and math.isfinite(value)):
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
        if not _is_number(value):
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
    # a short prefix: a 255-byte name must not make its temporary name too long to create
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem[:40]}.", suffix=f".part{path.suffix[:20]}", dir=path.parent)
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


def _nonfinite(obj: Any, where: str) -> tuple[str, float] | None:
    """Dotted path and value of the first NaN/inf in a JSON-friendly structure, or None."""
    if isinstance(obj, float):
        return None if math.isfinite(obj) else (where, obj)
    if isinstance(obj, Mapping):
        for k, v in obj.items():
            hit = _nonfinite(v, f"{where}.{k}" if where else str(k))
            if hit:
                return hit
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            hit = _nonfinite(v, f"{where}[{i}]")
            if hit:
                return hit
    return None


def _null_nonfinite(obj: Any) -> Any:
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, Mapping):
        return {k: _null_nonfinite(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_null_nonfinite(v) for v in obj]
    return obj


def json_text(data: Any, nonfinite: str = "error", name: str = "json") -> str:
    """``data`` as indented JSON text (numpy values allowed).

    Parameters
    ----------
    nonfinite : {"error", "null"}
        NaN/inf are not JSON: "error" raises :class:`ParameterError` naming the first such
        entry by its dotted path; "null" writes them as ``null`` (for fields where NaN
        documents "not available").
    name : str
        Parameter (option) name used in the error.
    """
    obj = to_jsonable(data)
    if nonfinite == "null":
        obj = _null_nonfinite(obj)
    else:
        hit = _nonfinite(obj, "")
        if hit:
            raise ParameterError(name, hit[1], f"result entry '{hit[0]}' is not finite, so it cannot be "
                                               "written as JSON; change the inputs that produced it")
    return json.dumps(obj, indent=2, allow_nan=False) + "\n"


def write_json(path: str | os.PathLike, data: Any, nonfinite: str = "error", name: str = "json") -> Path:
    """Write ``data`` as indented JSON, atomically; the text is complete before any file exists.

    A NaN/inf is a :class:`ParameterError` raised before anything is created (see
    :func:`json_text` for ``nonfinite`` and ``name``).
    """
    return atomic_write_text(path, json_text(data, nonfinite, name))


# --------------------------------------------------------------------------- output paths

NAME_MAX = 255
"""Longest file-name component, bytes (ext4, APFS, NTFS)."""

PATH_MAX = 4000
"""Longest path accepted, bytes (Linux PATH_MAX is 4096)."""


def _same(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.normcase(os.path.abspath(a)) == os.path.normcase(os.path.abspath(b))


def check_output_paths(*, inputs: Mapping[str, Any] | None = None, folders: typing.Iterable[str] = (),
                       **outputs: Any) -> dict[str, Path]:
    """Refuse unusable output paths before any computation starts.

    Parameters
    ----------
    inputs : mapping of str to path, optional
        Files the run reads (e.g. ``{"--design": "d.toml"}``): no output may overwrite one.
    folders : iterable of str
        Names (keys of ``outputs``) that are output folders rather than files.
    **outputs : path or None
        Output option name -> path (``None`` entries are skipped). Keyword names may use
        underscores; the messages show them as ``--option-name``.

    Returns
    -------
    dict of str to Path
        The checked outputs (``None`` skipped).

    Raises
    ------
    ParameterError
        Empty name or NUL byte; a name component longer than :data:`NAME_MAX` bytes or a path
        longer than :data:`PATH_MAX`; a parent folder that is missing, not a folder or not
        writable; a file output that is an existing folder or a folder output that is an
        existing file; two outputs on one path; an output on an input file.
    """
    folders = set(folders)
    checked: dict[str, Path] = {}
    for key, value in outputs.items():
        if value is None:
            continue
        opt = key if key.startswith("-") else "--" + key.replace("_", "-")
        if not isinstance(value, (str, os.PathLike)) or not os.fspath(value).strip() or "\0" in os.fspath(value):
            raise ParameterError(opt, value, "must be a path")
        text = os.fspath(value)
        if len(os.fsencode(text)) > PATH_MAX:
            raise ParameterError(opt, text, f"path longer than {PATH_MAX} bytes")
        path = Path(text)
        for part in path.parts:
            if len(os.fsencode(part)) > NAME_MAX:
                raise ParameterError(opt, text, f"has a name of {len(os.fsencode(part))} bytes; at most "
                                                f"{NAME_MAX} are allowed")
        if path.name in ("", ".", ".."):
            raise ParameterError(opt, text, "must end in a file or folder name")
        parent = path.parent
        if not parent.exists():
            raise ParameterError(opt, text, f"parent folder {str(parent)!r} does not exist")
        if not parent.is_dir():
            raise ParameterError(opt, text, f"parent {str(parent)!r} is not a folder")
        if not os.access(parent, os.W_OK | os.X_OK):
            raise ParameterError(opt, text, f"parent folder {str(parent)!r} is not writable")
        if key in folders:
            if path.exists() and not path.is_dir():
                raise ParameterError(opt, text, "is an existing file; an output folder is expected")
        elif path.is_dir():
            raise ParameterError(opt, text, "is a folder; give a file path")
        for other, other_path in checked.items():
            if _same(path, other_path):
                raise ParameterError(opt, text, f"is also the output of {other}")
        for name, inp in (inputs or {}).items():
            if inp is not None and isinstance(inp, (str, os.PathLike)) and os.fspath(inp) \
                    and _same(path, Path(inp)):
                raise ParameterError(opt, text, f"would overwrite the input {name}")
        checked[opt] = path
    return {k.lstrip("-").replace("-", "_"): v for k, v in checked.items()}


@contextlib.contextmanager
def atomic_folder(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary folder beside ``path``; swap it into place only on success.

    The folder is built under a hidden sibling name; on success an existing ``path`` is moved
    aside, the new folder renamed onto ``path`` and the old one removed (signals are held
    meanwhile, so an interrupt never leaves neither or a half-deleted old folder). On any
    exception, interrupt or termination the temporary folder is removed and ``path`` is left as
    it was, also when the swap itself fails (the old folder is moved back): a results folder is
    whole or absent, never a mix of two runs.
    """
    path = Path(path)
    if not path.parent.is_dir():
        raise ParameterError("out", str(path), f"parent folder {str(path.parent)!r} does not exist")
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name[:40]}.part-", dir=path.parent))
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    with _signals_held():
        _swap_in(tmp, path)


def _swap_in(new: Path, path: Path) -> None:
    """Rename folder ``new`` onto ``path``, replacing what is there; on failure ``path`` is kept."""
    aside = None
    try:
        if path.exists() or path.is_symlink():
            aside = Path(tempfile.mkdtemp(prefix=f".{path.name[:40]}.old-", dir=path.parent))
            os.replace(path, aside / path.name)
        try:
            os.replace(new, path)
        except BaseException:
            if aside is not None:
                os.replace(aside / path.name, path)  # the previous results go back in place
            raise
    except BaseException:
        shutil.rmtree(new, ignore_errors=True)
        # remove the holder only once it is empty again: if putting the old folder back failed
        # too, the holder keeps the user's previous results and the error names the file
        if aside is not None and not (aside / path.name).exists():
            shutil.rmtree(aside, ignore_errors=True)
        raise
    if aside is not None:
        shutil.rmtree(aside, ignore_errors=True)


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """Defer SIGINT/SIGTERM for a few system calls that must happen together."""
    held = {signal.SIGINT, signal.SIGTERM}
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


# --------------------------------------------------------------------------- command line


class CliParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose usage errors are one line on stderr and exit code 2."""

    def error(self, message: str) -> typing.NoReturn:  # noqa: D401 - argparse API
        sys.stderr.write(_one_line(f"{self.prog}: error: {message}") + "\n")
        raise SystemExit(2)


_NATIVE_RUNS: list[threading.Event] = []
"""Completion flags of native (Gmsh) runs that an interrupt or a time limit abandoned.

Native code cannot be stopped from Python, so an abandoned run goes on in its thread. While it
does, the process must end by ``os._exit``: a normal interpreter exit runs the C library's exit
handlers (static destructors of Gmsh/OpenCASCADE, OpenBLAS shutdown) under the running code,
which corrupts the heap (seen: SIGSEGV, "corrupted double-linked list"). ``Thread.is_alive``
cannot tell whether the run goes on: on CPython <= 3.12 a ``join`` interrupted by a signal marks
the thread stopped although it still runs (bpo-45274's fix), so each run sets its own flag as
the very last thing it does."""

_exit_hook_installed = False


def abandon_native_run(done: threading.Event) -> None:
    """Record a native run (its completion flag) that goes on after its caller gave up on it.

    An entry point's :func:`run_cli` (``final=True``) then ends the process by ``os._exit``
    after its one line; any other interpreter exit while the run goes on (a library user, a
    test session) is ended the same way from an ``atexit`` hook, with exit code 1 and one
    stderr line, rather than crash in the C library's exit handlers.
    """
    global _exit_hook_installed
    _NATIVE_RUNS.append(done)
    if not _exit_hook_installed:
        atexit.register(_exit_past_native_runs)
        _exit_hook_installed = True


def native_code_running() -> bool:
    """True while an abandoned native (Gmsh) run is still going in this process."""
    return any(not done.is_set() for done in _NATIVE_RUNS)


def _flush_std() -> None:
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()


def _exit_past_native_runs() -> None:
    if native_code_running():
        with contextlib.suppress(Exception):
            sys.stderr.write("rpud: an abandoned Gmsh run is still going: the process ends without "
                             "finalisation (exit code 1)\n")
        _flush_std()
        os._exit(1)


def _one_line(text: str, limit: int = 600) -> str:
    text = " ".join(str(text).replace("\r", "\n").split("\n"))
    text = "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in text)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def library_error(exc: BaseException) -> str | None:
    """One line naming the cause and what to change for a known library failure, else None."""
    kind = type(exc).__name__
    module = type(exc).__module__ or ""
    text = str(exc) or kind
    if isinstance(exc, MemoryError):
        return "out of memory: use a coarser --mesh-size, fewer --modes or --points"
    if kind in ("ArpackNoConvergence", "ArpackError"):
        return f"eigen solver failed ({text}): change --near, --modes or --mesh-size"
    if kind == "LinAlgError" or "singular" in text.lower() or "factor is exactly singular" in text:
        return f"sparse solver failed ({text}): the model is singular; check --clamp, the materials and --mesh-size"
    if module.startswith("gmsh") or text.startswith("Gmsh") or "gmsh" in module:
        return f"Gmsh failed ({text}): change --mesh-size or the design's small features"
    if kind == "SimulationError":
        return f"simulation failed ({text}): change the parameter it names"
    if isinstance(exc, OSError):
        where = f": {exc.filename}" if exc.filename else ""
        return f"cannot read or write a file ({exc.strerror or text}){where}: check the path"
    if isinstance(exc, RecursionError):
        return "input nested too deeply"
    return None


def run_cli(main: Callable[[list[str] | None], int | None], argv: list[str] | None = None,
            prog: str = "rpud", *, final: bool = False) -> int:
    """Run a CLI entry point: every failure becomes one stderr line and an exit code.

    - bad input (:class:`ParameterError`, unusable paths, known library failures): exit 2;
    - SIGINT: "interrupted", exit 130; SIGTERM: "terminated", exit 143 (both raise inside
      ``main``, so ``atomic_output``/``atomic_folder`` remove their temporaries);
    - any other exception is a bug: one line saying so, exit 1 (``RPUD_DEBUG=1`` re-raises it
      with its traceback).

    Parameters
    ----------
    main : callable
        ``main(argv) -> int | None``.
    argv : list of str, optional
        Arguments (default: ``sys.argv[1:]``, as argparse does).
    prog : str
        Program name that starts the stderr line.
    final : bool
        The process ends after this call (an entry point, see :func:`geometry.launch.launch`):
        once the outcome is decided, a late signal ends the process at once with the same code
        instead of restoring the previous handlers (which would add a second line).

    Returns
    -------
    int
        The exit code. With ``final``, if native code (Gmsh) was abandoned by an interrupt or a
        time limit and still runs, the process ends here instead, through ``os._exit`` after
        flushing the streams (see :data:`_NATIVE_RUNS`); without it (in-process use, tests) the
        interpreter exit is guarded instead (:func:`abandon_native_run`).
    """
    in_main = threading.current_thread() is threading.main_thread()
    saved = {}
    if in_main:
        saved[signal.SIGTERM] = handle(signal.SIGTERM, on_sigterm)
        saved[signal.SIGINT] = handle(signal.SIGINT, signal.default_int_handler)
    try:
        code = _run_main(main, argv, prog)
    except BaseException as exc:
        # SystemExit (argparse usage/--help), RPUD_DEBUG re-raise, or a signal landing while a
        # handler below was already reporting
        if final and native_code_running():
            _exit_now(exc.code if isinstance(exc, SystemExit) and isinstance(exc.code, int) else 1)
        _restore(saved)
        raise
    if final and native_code_running():
        _exit_now(code)
    if in_main and final:
        settle(code)
    else:
        _restore(saved)
    return code


def _restore(saved: Mapping[int, Any]) -> None:
    for sig, handler in saved.items():
        if handler is not None:  # None: installed outside Python, cannot be re-installed from here
            signal.signal(sig, handler)


def _exit_now(code: int) -> typing.NoReturn:
    """End the process without interpreter or C-library finalisation (native code still runs)."""
    if threading.current_thread() is threading.main_thread():
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    _flush_std()
    os._exit(code)


def _run_main(main: Callable[[list[str] | None], int | None], argv: list[str] | None, prog: str) -> int:
    """``main(argv)``'s exit code, every known failure turned into one stderr line (see run_cli)."""
    try:
        return int(main(argv) or 0)
    except ParameterError as exc:
        return _fail(prog, f"error: {exc}", 2)
    except Terminated:  # first: it is a KeyboardInterrupt too
        forget_interrupt()
        return _fail(prog, "terminated", 143)
    except KeyboardInterrupt:
        forget_interrupt()
        return _fail(prog, "interrupted", 130)
    except SystemExit:
        raise
    except BaseException as exc:  # noqa: BLE001 - the last line of defence of a CLI
        line = library_error(exc)
        if line is not None:
            logging.getLogger("rpud.cli").debug("library error", exc_info=True)
            return _fail(prog, f"error: {line}", 2)
        if os.environ.get("RPUD_DEBUG"):
            raise
        return _fail(prog, f"internal error: {type(exc).__name__}: {exc} (a bug: please report it; "
                           "RPUD_DEBUG=1 shows the traceback)", 1)


def _fail(prog: str, text: str, code: int) -> int:
    # a signal arriving while the line is written must not produce a second, traceback line
    with _signals_held():
        sys.stderr.write(_one_line(f"{prog}: {text}") + "\n")
        with contextlib.suppress(Exception):
            sys.stderr.flush()
    return code


def setup_logging(verbose: int = 0) -> None:
    """Configure the root logger for a CLI (libraries only create loggers)."""
    level = logging.WARNING if verbose < 0 else logging.INFO if verbose == 0 else logging.DEBUG
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)
