"""Start a command-line entry point with its signal handling in place before the heavy imports.

``python -m geometry`` (and ``fem.modal``, ``fem.harmonic``, ``impact``, ``results``) spends its
first ~0.2-1 s importing numpy, scipy, gmsh... A SIGINT in that window would print a
``KeyboardInterrupt`` traceback and a SIGTERM would kill the process by the signal, so every
entry point calls :func:`launch` first. This module and :mod:`rpud_common.signals` import the
standard library only, so the handlers are installed a few milliseconds after the interpreter
starts; :func:`rpud_common.cli.run_cli` takes over once ``main`` is imported.

Signals that arrive before the interpreter has run any of our code (its own start-up, ~30 ms)
cannot be handled by Python code at all.
"""

from __future__ import annotations

import importlib
import signal
from collections.abc import Callable

from .signals import (
    EXIT_INTERRUPTED, EXIT_TERMINATED, Terminated, clear_pending, forget_interrupt, install_handlers, pending_signal,
    raise_pending, report_line, settle,
)

__all__ = ["launch"]


def launch(target: str | Callable[[], Callable], prog: str, func: str = "main") -> int:
    """Install the signal handlers, import the entry point, run it through ``run_cli``.

    Parameters
    ----------
    target : str or callable
        The module holding the entry point, by name (a module of the caller's own package:
        ``python -m fem.modal`` names ``fem.modal_cli``), or a function without arguments that
        imports the entry point and returns it (a console script in another package imports
        it with an ``import`` statement, so the import graph shows the arrow).
    prog : str
        Program name that starts every stderr line.
    func : str
        Name of the ``main(argv) -> int`` function in the named module.

    Returns
    -------
    int
        The exit code: ``run_cli``'s, or 130 / 143 for a signal during the imports.
    """
    try:
        install_handlers()
        main = getattr(importlib.import_module(target), func) if isinstance(target, str) else target()
        # a signal whose exception the import swallowed (a __del__, C code clearing errors) is
        # still recorded: report it now, run_cli starts with a clean record
        raise_pending()
        from .cli import run_cli       # after the handlers: it imports numpy

        return run_cli(main, prog=prog, final=True)
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
    report_line(prog, word)
    return code
