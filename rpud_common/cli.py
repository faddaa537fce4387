"""Command-line plumbing: one-line usage errors, and ``run_cli``, which turns every failure into
one stderr line and an exit code (2 bad input, 130 SIGINT, 143 SIGTERM, 1 a bug)."""

from __future__ import annotations

import argparse
import atexit
import contextlib
import logging
import os
import signal
import sys
import threading
import typing
from collections.abc import Callable, Mapping
from typing import Any

from .errors import ParameterError
from .launch import (
    Terminated, _quiet_unraisable, clear_pending, forget_interrupt, handle, on_sigint, on_sigterm, pending_signal, raise_pending, settle,
    signals_held,
)

__all__ = ["CliParser", "run_cli", "library_error", "setup_logging", "abandon_native_run", "native_code_running"]


class CliParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose usage errors are one line on stderr and exit code 2.

    Started as a console script (``rpud-impact``), usage and errors name that command rather
    than its ``python -m`` twin given as ``prog``.
    """

    def __init__(self, *args, **kwargs):
        script = os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else ""
        if script.startswith("rpud-") and "prog" in kwargs:
            kwargs["prog"] = script
        super().__init__(*args, **kwargs)

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
        The process ends after this call (an entry point, see :func:`rpud_common.launch.launch`):
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
        saved[signal.SIGINT] = handle(signal.SIGINT, on_sigint)
        sys.unraisablehook = _quiet_unraisable
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
    clear_pending()
    try:
        code = int(main(argv) or 0)
        raise_pending()         # a signal whose exception a library callback swallowed
        return code
    except ParameterError as exc:
        return _fail(prog, f"error: {exc}", 2)
    except Terminated:  # first: it is a KeyboardInterrupt too
        forget_interrupt()
        clear_pending()
        return _fail(prog, "terminated", 143)
    except KeyboardInterrupt:
        forget_interrupt()
        clear_pending()
        return _fail(prog, "interrupted", 130)
    except SystemExit:
        raise
    except BaseException as exc:  # noqa: BLE001 - the last line of defence of a CLI
        sig = pending_signal()
        if sig is not None:
            # native code turned the signal's exception into another one: report the signal
            forget_interrupt()
            clear_pending()
            return _fail(prog, "terminated", 143) if sig == signal.SIGTERM else _fail(prog, "interrupted", 130)
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
    with signals_held():
        sys.stderr.write(_one_line(f"{prog}: {text}") + "\n")
        with contextlib.suppress(Exception):
            sys.stderr.flush()
    return code


def setup_logging(verbose: int = 0) -> None:
    """Configure the root logger for a CLI (libraries only create loggers)."""
    level = logging.WARNING if verbose < 0 else logging.INFO if verbose == 0 else logging.DEBUG
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)
