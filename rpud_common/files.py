"""Result files that appear whole or not at all, and output paths checked before any work.

``atomic_output``/``atomic_write_text``/``write_json`` write to a temporary sibling and rename;
``atomic_folder`` builds a results folder under a temporary name and swaps it in; files are
created with the user's umask (readable by colleagues with the usual 022).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import tempfile
import typing
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from .errors import ParameterError
from .signals import raise_pending, signals_held
from .provenance import provenance_record
from .records import to_jsonable

__all__ = ["atomic_output", "atomic_write_text", "json_text", "write_json", "NAME_MAX", "PATH_MAX",
           "check_output_paths", "atomic_folder", "null_nonfinite"]


def _umask() -> int:
    """The process umask, read without changing it (Linux), else by the set-and-restore idiom."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _as_created(path: Path, folder: bool = False) -> None:
    # mkstemp/mkdtemp create 0600/0700 whatever the umask: give results the mode a plain
    # open()/mkdir() would have, so colleagues can read a results folder (umask 022: 0644/0755)
    os.chmod(path, (0o777 if folder else 0o666) & ~_umask())


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
        raise_pending()         # a signal swallowed while writing: do not commit
        if tmp_path.exists():
            _as_created(tmp_path)
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


def null_nonfinite(obj: Any) -> Any:
    """``obj`` with every non-finite float (in nested dicts and lists) replaced by None (JSON null)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, Mapping):
        return {k: null_nonfinite(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [null_nonfinite(v) for v in obj]
    return obj


def json_text(data: Any, nonfinite: str = "error", name: str = "json", provenance: bool = True) -> str:
    """``data`` as indented JSON text (numpy values allowed).

    Parameters
    ----------
    nonfinite : {"error", "null"}
        NaN/inf are not JSON: "error" raises :class:`ParameterError` naming the first such
        entry by its dotted path; "null" writes them as ``null`` (for fields where NaN
        documents "not available").
    name : str
        Parameter (option) name used in the error.
    provenance : bool
        A result (a JSON object) gets a last key ``"provenance"``
        (:func:`rpud_common.provenance.provenance_record`: version, commit, command line,
        date), so that every number in a file can be traced to the code and the command that
        made it; one the data already carries is kept. False for records that are not results
        on their own (a study's resume rows, read back field by field).
    """
    obj = to_jsonable(data)
    if provenance and isinstance(obj, dict) and "provenance" not in obj:
        obj = {**obj, "provenance": provenance_record()}
    if nonfinite == "null":
        obj = null_nonfinite(obj)
    else:
        hit = _nonfinite(obj, "")
        if hit:
            raise ParameterError(name, hit[1], f"result entry '{hit[0]}' is not finite, so it cannot be "
                                               "written as JSON; change the inputs that produced it")
    return json.dumps(obj, indent=2, allow_nan=False) + "\n"


def write_json(path: str | os.PathLike, data: Any, nonfinite: str = "error", name: str = "json",
               provenance: bool = True) -> Path:
    """Write ``data`` as indented JSON, atomically; the text is complete before any file exists.

    A NaN/inf is a :class:`ParameterError` raised before anything is created (see
    :func:`json_text` for ``nonfinite``, ``name`` and ``provenance``: a JSON object gets a
    ``"provenance"`` record).
    """
    return atomic_write_text(path, json_text(data, nonfinite, name, provenance))


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


def _writable(folder: Path) -> str | None:
    """Why no file can be created in ``folder`` (None if one can), found by creating one.

    ``os.access`` answers by the permission bits, which do not stop root, while /proc and
    /sys refuse new files to everyone and a read-only mount refuses them whatever the bits:
    only an attempt tells. The probe file is removed at once.
    """
    try:
        fd, probe = tempfile.mkstemp(prefix=".rpud-probe-", dir=folder)
    except OSError as exc:
        return exc.strerror or type(exc).__name__
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(probe)
    return None


def _check_path(opt: str, value: Any, folder: bool) -> Path:
    """One output path: a usable name, an existing writable parent, the right kind of entry."""
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
    why = _writable(parent) if os.access(parent, os.W_OK | os.X_OK) else "permission denied"
    if why:
        raise ParameterError(opt, text, f"parent folder {str(parent)!r} is not writable ({why})")
    if folder:
        if path.exists() and not path.is_dir():
            raise ParameterError(opt, text, "is an existing file; an output folder is expected")
        why = _writable(path) if path.is_dir() else None
        if why:
            raise ParameterError(opt, text, f"is a folder that is not writable ({why})")
    elif path.is_dir():
        raise ParameterError(opt, text, "is a folder; give a file path")
    elif path.exists() and not path.is_file():
        raise ParameterError(opt, text, "exists and is not a regular file (a device, pipe or socket); give a file path")
    return path


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
        longer than :data:`PATH_MAX`; a parent folder that is missing, not a folder or where no
        file can be created (tried: permission bits do not stop root, /proc and read-only
        mounts do); a file output that is an existing folder or not a regular file; a folder
        output that is an existing file or a folder where no file can be created; two outputs
        on one path; an output on an input file.
    """
    folders = set(folders)
    checked: dict[str, Path] = {}
    for key, value in outputs.items():
        if value is None:
            continue
        opt = key if key.startswith("-") else "--" + key.replace("_", "-")
        path = _check_path(opt, value, key in folders)
        text = os.fspath(value)
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
    _as_created(tmp, folder=True)
    try:
        yield tmp
        raise_pending()         # a signal swallowed while building: do not commit
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    with signals_held():
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
