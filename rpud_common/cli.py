"""Command-line plumbing: one-line usage errors, and ``run_cli``, which turns every failure into
one stderr line and an exit code (2 bad input, 130 SIGINT, 143 SIGTERM, 1 a bug)."""

from __future__ import annotations

import argparse
import atexit
import contextlib
import logging
import math
import os
import signal
import sys
import threading
import typing
from collections.abc import Callable, Mapping
from typing import Any

from .errors import ParameterError, is_finite_number
from .signals import (
    Terminated, quiet_unraisable, clear_pending, forget_interrupt, handle, on_sigint, on_sigterm, pending_signal, raise_pending, settle,
    signals_held,
)

__all__ = ["CliParser", "run_cli", "library_error", "setup_logging", "abandon_native_run", "native_code_running",
           "start_native_worker",
           "check_given", "needs", "check_zero_or_range", "quantity", "inputs_lines", "echo_inputs", "warn",
           "mesh_text", "DRILL_RANGES", "check_usual"]


class CliParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose usage errors are one line on stderr and exit code 2.

    Started as a console script (``rpud-impact``), usage and errors name that command rather
    than its ``python -m`` twin given as ``prog``. Every command takes ``--version`` (prints
    ``<prog> <rpud version>``, exit 0), so a result can be matched to the code that made it.
    """

    def __init__(self, *args, **kwargs):
        script = os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else ""
        if script.startswith("rpud-") and "prog" in kwargs:
            kwargs["prog"] = script
        super().__init__(*args, **kwargs)
        from .provenance import version

        self.add_argument("--version", action="version", version=f"%(prog)s {version()}",
                          help="print rpud's version and exit")

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
    _NATIVE_RUNS.append(done)
    _install_exit_hook()


def _install_exit_hook() -> None:
    global _exit_hook_installed
    if not _exit_hook_installed:
        atexit.register(_exit_past_native_runs)
        _exit_hook_installed = True


_WORKERS: list[threading.Event] = []
"""Completion flags of :func:`start_native_worker` threads: while one runs, the process ends like
it does past an abandoned Gmsh run, but a new Gmsh run may start."""


def start_native_worker(work: Callable[[], None], name: str,
                        done: threading.Event | None = None) -> tuple[threading.Thread, threading.Event]:
    """Run ``work()`` in a daemon thread whose native code (Gmsh, PARDISO, numba, BLAS) may outlive
    its caller: a run ended by a signal or an error does not wait for it.

    The thread is recorded before it starts, so a process that ends while it still runs ends
    through ``os._exit`` instead of finalising the interpreter and the C library under it (seen:
    "double free detected" on SIGINT during a worker's ensembles). Signals are blocked in the
    thread: they reach the main thread, which decides how the run ends (delivered inside native
    code, they can corrupt its state).

    Parameters
    ----------
    work : callable
        Runs in the thread; it hands its result or error to the caller itself.
    name : str
        The thread's name.
    done : threading.Event, optional
        The completion flag to use (a caller that must hold it even if a signal lands inside
        this call); a new one by default.

    Returns
    -------
    thread : threading.Thread
        The started thread.
    done : threading.Event
        Set as the very last thing the thread does; wait on it rather than ``join`` (an
        interrupted ``join`` may mark the thread stopped while it still runs).
    """
    done = threading.Event() if done is None else done

    def run():
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        try:
            work()
        finally:
            done.set()

    _WORKERS[:] = [d for d in _WORKERS if not d.is_set()] + [done]
    _install_exit_hook()
    thread = threading.Thread(target=run, name=name, daemon=True)
    thread.start()
    return thread, done


def native_code_running() -> bool:
    """True while an abandoned native (Gmsh) run is still going in this process."""
    return any(not done.is_set() for done in _NATIVE_RUNS)


def _flush_std() -> None:
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()


def _native_threads_running() -> bool:
    """True while an abandoned Gmsh run or a :func:`start_native_worker` thread still runs."""
    return native_code_running() or any(not done.is_set() for done in _WORKERS)


def _exit_past_native_runs() -> None:
    if _native_threads_running():
        with contextlib.suppress(Exception):
            sys.stderr.write("rpud: native code is still running in a worker thread: the process ends without "
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
        The exit code. With ``final``, if native code still runs in another thread (Gmsh
        abandoned by an interrupt or a time limit, a :func:`start_native_worker` thread), the
        process ends here instead, through ``os._exit`` after flushing the streams (see
        :data:`_NATIVE_RUNS`); without it (in-process use, tests) the interpreter exit is guarded
        instead.
    """
    in_main = threading.current_thread() is threading.main_thread()
    saved = {}
    if in_main:
        saved[signal.SIGTERM] = handle(signal.SIGTERM, on_sigterm)
        saved[signal.SIGINT] = handle(signal.SIGINT, on_sigint)
        sys.unraisablehook = quiet_unraisable
    try:
        code = _run_main(main, argv, prog)
    except BaseException as exc:
        # SystemExit (argparse usage/--help), RPUD_DEBUG re-raise, or a signal landing while a
        # handler below was already reporting
        if final and _native_threads_running():
            _exit_now(exc.code if isinstance(exc, SystemExit) and isinstance(exc.code, int) else 1)
        _restore(saved)
        raise
    if final and _native_threads_running():
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


# --------------------------------------------------------------------------- options given


def _option_name(action: argparse.Action) -> str:
    longs = [o for o in action.option_strings if o.startswith("--")]
    return (longs or action.option_strings or [action.dest])[0]


def check_given(parser: argparse.ArgumentParser, ns: argparse.Namespace) -> None:
    """Refuse what argparse lets through: empty text and subnormal numbers.

    An empty (or blank) string is never a design, a surface, a band or a list: it is a slip
    like ``--band=`` that would otherwise read as "not given". A subnormal float (``1e-320``)
    is no time, force or tolerance either: it only arises from a typo.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The parser that produced ``ns`` (its actions name the options).
    ns : argparse.Namespace
        The parsed options.

    Raises
    ------
    ParameterError
        Naming the option, the value and what is allowed.
    """
    for action in parser._actions:      # noqa: SLF001 - argparse keeps no public list of its actions
        if not action.option_strings or not hasattr(ns, action.dest):
            continue
        value = getattr(ns, action.dest)
        if value is None or value is action.default:
            continue
        name = _option_name(action)
        for item in value if isinstance(value, list) else [value]:
            if isinstance(item, str) and not item.strip():
                raise ParameterError(name, item, "must not be empty")
            if isinstance(item, float) and item != 0.0 and abs(item) < sys.float_info.min:
                raise ParameterError(name, item, f"is below {sys.float_info.min:.3g} in magnitude (a typo?): "
                                                 "give 0 or a normal number")


def needs(option: str, value: Any, requirement: str, why: str = "") -> None:
    """Refuse ``option`` given (``value`` not None/False) without the option it depends on.

    Call it where the requirement does not hold; e.g. ``needs("--wob", ns.wob, "--load rock")``
    raises "--wob = 5.0: applies only with --load rock" when ``--wob`` was given.

    Parameters
    ----------
    option : str
        The option given, as typed (``"--wob"``).
    value : object
        Its value (None, False or [] when it was not given: nothing to refuse).
    requirement : str
        What it needs, naming that option (``"--load rock"``).
    why : str
        Optional reason, shown in parentheses.
    """
    if value is None or value is False or value == []:
        return
    raise ParameterError(option, value, f"applies only with {requirement}" + (f" ({why})" if why else ""))


def check_zero_or_range(name: str, value: float, lo: float, hi: float, unit: str = "", zero: str = "") -> None:
    """Accept 0 (meaning ``zero``) or a finite number in ``[lo, hi]``; else a ParameterError.

    For options where 0 switches something off or picks an automatic value (``--ring-up 0``: six
    time constants) while a tiny positive value is a typo, not a request.
    """
    if is_finite_number(value) and (value == 0 or lo <= value <= hi):
        return
    unit_text = f" {unit}" if unit else ""
    raise ParameterError(name, value, f"must be 0{f' ({zero})' if zero else ''} or in [{lo:g}, {hi:g}]{unit_text}")


# --------------------------------------------------------------------------- the inputs a run used

_PREFIXES = ((1e9, "G"), (1e6, "M"), (1e3, "k"), (1.0, ""), (1e-3, "m"), (1e-6, "u"), (1e-9, "n"), (1e-12, "p"))


def quantity(value: float, unit: str = "", digits: int = 4) -> str:
    """``value`` with ``unit``, under the SI prefix that keeps the mantissa in [1, 1000).

    Masses are given in kg and shown in g, mg or kg (``quantity(0.008, "kg")`` is ``"8 g"``);
    ``unit`` "" (a ratio) or one starting with a non-letter is shown without a prefix.

    Parameters
    ----------
    value : float
        In the SI unit ``unit``.
    unit : str
        The unit of ``value`` ("kg", "m", "Hz", "V", "N/m", ...).
    digits : int
        Significant digits (trailing zeros dropped).
    """
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
        return f"{value} {unit}".rstrip()
    if value == 0:
        return f"0 {unit}".rstrip()
    base, x = (unit[1:], value * 1e3) if unit.startswith("kg") else (unit, value)
    if not base or not base[0].isalpha():
        return f"{value:.{digits}g} {unit}".rstrip()
    # a mantissa that rounds up to 1000 at these digits takes the next prefix (1 kV, not 1000 V)
    top = 1 - 0.5 * 10.0 ** (1 - digits)
    factor, prefix = next(((f, p) for f, p in _PREFIXES if abs(x) >= f * top), _PREFIXES[-1])
    return f"{x / factor:.{digits}g} {prefix}{base}"


def inputs_lines(items: Mapping[str, Any], width: int = 110) -> list[str]:
    """The ``inputs: ...`` lines of ``items`` (label -> shown value), wrapped at ``width``.

    Every command echoes its inputs through this, so the lines look the same everywhere: the
    first starts with ``inputs:``, continuation lines are indented under it.
    """
    parts = [f"{label} {value}" if value not in ("", None) else label for label, value in items.items()]
    lines, line = [], "inputs:"
    for part in parts:
        piece = (" " if line.endswith(":") else ", ") + part
        if len(line) + len(piece) > width and not line.endswith(":"):
            lines.append(line + ",")
            line = "       " + part
        else:
            line += piece
    lines.append(line)
    return lines


def mesh_text(mesher: str, refine: float, grade: bool = False, mesh_size: float | None = None,
              order: int | None = None) -> str:
    """The mesh settings as the inputs line shows them (``"free, refine 1, graded, size 4 mm"``)."""
    return (f"{mesher}" + (f", order {order}" if order is not None else "") + f", refine {refine:g}"
            + (", graded" if grade else "") + (f", size {quantity(mesh_size, 'm')}" if mesh_size is not None else ""))


def echo_inputs(items: Mapping[str, Any], quiet: bool = False) -> None:
    """Print the run's inputs (:func:`inputs_lines`) on stdout, before any progress, unless ``quiet``."""
    if not quiet:
        print("\n".join(inputs_lines(items)), flush=True)


def warn(prog: str, text: str) -> None:
    """One ``prog: warning: text`` line on stderr (the run goes on)."""
    sys.stderr.write(_one_line(f"{prog}: warning: {text}") + "\n")
    with contextlib.suppress(Exception):
        sys.stderr.flush()


DRILL_RANGES: dict[str, tuple[float, float, str, str]] = {
    "voltage": (10.0, 1000.0, "V", "the drill's drives run at 10-1000 V amplitude (the article's: 225 V)"),
    "m_free": (1e-3, 20e-3, "kg", "the drill's free masses are 1-20 g"),
    "A0": (1e-6, 100e-6, "m", "the drill's horn-tip amplitudes are 1-100 um"),
    "freq": (10e3, 50e3, "Hz", "the drill vibrates at 10-50 kHz"),
    "m_tool": (5e-3, 2.0, "kg", "the drill's tools weigh 5 g - 2 kg"),
    "wob": (1.0, 200.0, "N", "the drill is pressed with 1-200 N"),
}
"""The drill's usual operating ranges (low, high, SI unit, in words) for :func:`check_usual`:
values outside them are physically possible (they run) but usually a unit slip."""


def check_usual(prog: str, option: str, value: float | None, key: str) -> bool:
    """Warn (one stderr line) when ``value`` lies outside the drill's usual range ``DRILL_RANGES[key]``.

    The warning names the likely slip: the unit factor (1e-3, 1e3, 1e-6, 1e6) that brings the
    value into the range, e.g. "--m-free 8 kg: the drill's free masses are 1-20 g; did you mean
    0.008 (8 g)?". Returns True if it warned.
    """
    if value is None or not isinstance(value, (int, float)) or not math.isfinite(value):
        return False
    lo, hi, unit, words = DRILL_RANGES[key]
    if lo <= value <= hi:
        return False
    guess = ""
    if value != 0:
        for factor in (1e-3, 1e3, 1e-6, 1e6):
            if lo <= value * factor <= hi:
                guess = f"; did you mean {value * factor:.6g} ({quantity(value * factor, unit)})?"
                break
    warn(prog, f"{option} {value:.6g} {unit}: {words}{guess or '; check the value and its unit'}")
    return True


def setup_logging(verbose: int = 0) -> None:
    """Configure the root logger for a CLI (libraries only create loggers)."""
    level = logging.WARNING if verbose < 0 else logging.INFO if verbose == 0 else logging.DEBUG
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)
