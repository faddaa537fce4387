"""Start a command-line entry point with its signal handling in place before the heavy imports.

``python -m geometry`` (and ``fem.modal``, ``fem.harmonic``, ``impact``, ``results``) spends its
first ~0.2-1 s importing numpy, scipy, gmsh... A SIGINT in that window would print a
``KeyboardInterrupt`` traceback and a SIGTERM would kill the process by the signal, so every
entry point calls :func:`launch` first. This module imports the standard library only, so the
handlers are installed a few milliseconds after the interpreter starts;
:func:`rpud_common.cli.run_cli` takes over once ``main`` is imported.

Signals that arrive before the interpreter has run any of our code (its own start-up, ~30 ms)
cannot be handled by Python code at all.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import signal
import sys
import threading
from collections.abc import Iterator

__all__ = ["Terminated", "on_sigterm", "handle", "install_handlers", "forget_interrupt", "settle", "launch",
           "EXIT_INTERRUPTED", "EXIT_TERMINATED", "signals_held",
           "on_sigint", "raise_pending", "clear_pending", "pending_signal"]

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


def _quiet_unraisable(unraisable) -> None:
    # the exception of a recorded signal, swallowed by a __del__ or a weakref callback: it is
    # raised again at the next commit point (raise_pending), so no "Exception ignored" report
    if isinstance(unraisable.exc_value, KeyboardInterrupt) and _PENDING:
        return
    sys.__unraisablehook__(unraisable)


def install_handlers() -> None:
    """SIGINT raises ``KeyboardInterrupt``, SIGTERM raises :class:`Terminated` (main thread only);
    their exceptions swallowed in callbacks are not reported (they are pending, see above)."""
    handle(signal.SIGINT, on_sigint)
    handle(signal.SIGTERM, on_sigterm)
    sys.unraisablehook = _quiet_unraisable


def _line(prog: str, word: str) -> None:
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


def launch(module: str, prog: str, func: str = "main") -> int:
    """Install the signal handlers, import ``module``, run ``module.func`` through ``run_cli``.

    Parameters
    ----------
    module : str
        Dotted module holding the entry point (imported here, after the handlers).
    prog : str
        Program name that starts every stderr line.
    func : str
        Name of the ``main(argv) -> int`` function in ``module``.

    Returns
    -------
    int
        The exit code: ``run_cli``'s, or 130 / 143 for a signal during the imports.
    """
    try:
        install_handlers()
        target = getattr(importlib.import_module(module), func)
        # a signal whose exception the import swallowed (a __del__, C code clearing errors) is
        # still recorded: report it now, run_cli starts with a clean record
        raise_pending()
        # by name, like the entry module: rpud_common.cli builds on this module's primitives
        run_cli = importlib.import_module("rpud_common.cli").run_cli

        return run_cli(target, prog=prog, final=True)
    except Terminated:  # first: it is a KeyboardInterrupt too
        forget_interrupt()
        code, word = EXIT_TERMINATED, "terminated"
    except KeyboardInterrupt:
        forget_interrupt()
        code, word = EXIT_INTERRUPTED, "interrupted"
    except BaseException:
        # C code (an extension module being imported) can turn the signal's exception into
        # another one, e.g. ImportError: the signal is what happened, report it
        if pending_signal() is None:
            raise
        forget_interrupt()
        terminated = pending_signal() == signal.SIGTERM
        code, word = (EXIT_TERMINATED, "terminated") if terminated else (EXIT_INTERRUPTED, "interrupted")
    clear_pending()
    settle(code)
    _line(prog, word)
    return code


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
