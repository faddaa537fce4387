"""SIGINT and SIGTERM in a command: exceptions that unwind cleanly, and a record that outlives them.

SIGINT raises ``KeyboardInterrupt`` and SIGTERM :class:`Terminated` in the main thread, so
``finally`` blocks and atomic writers clean up; each signal is also recorded until reported, so
one whose exception a callback swallowed is raised again at the next commit point
(:func:`raise_pending`). :func:`rpud_common.launch.launch` installs these handlers before an
entry point's heavy imports and :func:`rpud_common.cli.run_cli` reports the outcome. This module
imports the standard library only.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator

__all__ = ["Terminated", "on_sigterm", "handle", "install_handlers", "forget_interrupt", "settle",
           "EXIT_INTERRUPTED", "EXIT_TERMINATED", "signals_held", "quiet_unraisable",
           "on_sigint", "raise_pending", "clear_pending", "pending_signal", "report_line"]

EXIT_INTERRUPTED = 130
"""Exit code after SIGINT (128 + 2, the shell's convention)."""

EXIT_TERMINATED = 143
"""Exit code after SIGTERM (128 + 15)."""


class Terminated(KeyboardInterrupt):
    """Raised in the main thread by SIGTERM while a CLI runs (KeyboardInterrupt is SIGINT's).

    Not an ``Exception``, so ``except Exception`` blocks in libraries do not swallow it, while
    ``finally`` blocks and context managers (atomic writers) still clean up. A subclass of
    ``KeyboardInterrupt`` because CPython itself lets only that one through in places: a
    handler that runs inside the compiler's constant folding (``2 ** 63`` checks for signals
    while a module is compiled on import) had any other exception cleared, and the SIGTERM was
    lost (seen: 1 start-up in 8 under load). Catch it before ``KeyboardInterrupt``.
    """


_PENDING: list[int] = []
"""Signals received and not yet reported. Their exception can be swallowed where CPython ignores
exceptions (a ``__del__``, a weakref callback run by the garbage collector: matplotlib has many),
so the record outlives it: :func:`raise_pending` raises it again at the next commit point."""


def on_sigterm(signum, frame):
    """SIGTERM handler: unwind the main thread like an interrupt does."""
    _PENDING.append(signum)
    raise Terminated()


def on_sigint(signum, frame):
    """SIGINT handler: ``KeyboardInterrupt``, recorded like SIGTERM."""
    _PENDING.append(signum)
    raise KeyboardInterrupt()


def raise_pending() -> None:
    """Raise again a SIGINT/SIGTERM whose exception was swallowed (see :data:`_PENDING`).

    Called before a result is committed (the rename of an atomic file or folder) and when a
    command ends, so a signal is never lost to a callback that ignored it.
    """
    if _PENDING:
        raise Terminated() if _PENDING[-1] == signal.SIGTERM else KeyboardInterrupt()


def pending_signal() -> int | None:
    """The last SIGINT/SIGTERM received and not yet reported, or None."""
    return _PENDING[-1] if _PENDING else None


def clear_pending() -> None:
    """The pending signal has been reported."""
    _PENDING.clear()


def handle(sig: int, handler) -> object:
    """Install ``handler`` for ``sig`` unless the process was started with ``sig`` ignored.

    A signal ignored at start-up (``nohup``, a background job of a script) stays ignored, as
    for any Unix program. Returns the previous handler (to restore it).
    """
    previous = signal.getsignal(sig)
    if previous != signal.SIG_IGN:
        signal.signal(sig, handler)
    return previous


def quiet_unraisable(unraisable) -> None:
    """``sys.unraisablehook`` that leaves out the exception of a recorded signal.

    Swallowed by a ``__del__`` or a weakref callback, that exception is raised again at the next
    commit point (:func:`raise_pending`), so it gets no "Exception ignored" report.
    """
    if isinstance(unraisable.exc_value, KeyboardInterrupt) and _PENDING:
        return
    sys.__unraisablehook__(unraisable)


def install_handlers() -> None:
    """SIGINT raises ``KeyboardInterrupt``, SIGTERM raises :class:`Terminated` (main thread only);
    their exceptions swallowed in callbacks are not reported (they are pending, see above)."""
    handle(signal.SIGINT, on_sigint)
    handle(signal.SIGTERM, on_sigterm)
    sys.unraisablehook = quiet_unraisable


def report_line(prog: str, word: str) -> None:
    """Write ``prog: word`` on stderr; a closed stderr is ignored."""
    try:
        sys.stderr.write(f"{prog}: {word}\n")
        sys.stderr.flush()
    except Exception:  # noqa: BLE001 - a closed stderr must not turn an interrupt into a traceback
        pass


def forget_interrupt() -> None:
    """Call after a ``KeyboardInterrupt`` was caught and reported, before the process exits.

    CPython (3.8-3.13) flags an interrupt that escapes an ``exec``/``eval`` of source text as
    "unhandled", even when an outer ``except`` handles it (dataclasses and namedtuples run such
    code while modules are imported), and at exit then kills the process by SIGINT instead of
    returning the exit code. Each ``eval`` of text clears that flag first: this one does so.
    """
    eval("None")


def settle(code: int) -> None:
    """The run's outcome is decided and reported: a later SIGINT/SIGTERM ends the process at once.

    Installed once the one stderr line (if any) is written, so a signal during interpreter
    shutdown neither adds a second line or a traceback nor is ignored (a shutdown that waits on
    a thread can still be stopped); the exit code stays ``code``.
    """
    def late(signum, frame):
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:  # noqa: BLE001 - closed or broken stream: nothing left to save
                pass
        os._exit(code)

    handle(signal.SIGINT, late)
    handle(signal.SIGTERM, late)


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
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
