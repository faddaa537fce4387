"""Where a result came from: rpud's version, the git commit, the command line and the date.

Written into every JSON result and report so that a number can be traced to the code and the
command that produced it. Standard library only.
"""

from __future__ import annotations

import datetime
import functools
import importlib.metadata
import shlex
import subprocess
import sys
from pathlib import Path

__all__ = ["__version__", "version", "git_commit", "provenance_record"]

_ROOT = Path(__file__).resolve().parent.parent


def version() -> str:
    """rpud's version as installed (pyproject's ``version``); ``"unknown"`` when run uninstalled."""
    try:
        return importlib.metadata.version("rpud")
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


__version__ = version()


@functools.lru_cache(maxsize=1)
def git_commit() -> str | None:
    """The commit of the source tree rpud runs from (``+dirty`` with uncommitted changes), or None
    outside a git checkout or without git."""
    if not (_ROOT / ".git").exists():
        return None
    try:
        head = subprocess.run(["git", "-C", str(_ROOT), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=5, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(_ROOT), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "") if head else None


def provenance_record(argv: list[str] | None = None) -> dict:
    """The record a result carries: ``{"rpud_version", "git_commit", "command", "date_utc", "python"}``.

    Parameters
    ----------
    argv : list of str, optional
        The command line (default: this process's, ``sys.argv`` with a ``python -m`` module's
        path given back as ``python -m <module>`` and a console script by its name), quoted as
        a shell would need it.

    Examples
    --------
    >>> sorted(provenance_record(["python", "-m", "results"]))
    ['command', 'date_utc', 'git_commit', 'python', 'rpud_version']
    """
    argv = _command_line() if argv is None else list(argv)
    return {
        "rpud_version": version(),
        "git_commit": git_commit(),
        "command": shlex.join(argv),
        "date_utc": datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0).isoformat(),
        "python": sys.version.split()[0],
    }


def _command_line() -> list[str]:
    """This process's command line as typed: ``sys.argv[0]`` of ``python -m impact`` is the path
    of ``impact/__main__.py``, which neither names the command nor reruns it."""
    argv = list(sys.argv)
    if not argv:
        return argv
    spec = getattr(sys.modules.get("__main__"), "__spec__", None)
    name = getattr(spec, "name", None)
    if name:
        module = name[: -len(".__main__")] if name.endswith(".__main__") else name
        return ["python", "-m", module, *argv[1:]]
    script = Path(argv[0]).name
    if script.startswith("rpud-"):
        return [script, *argv[1:]]
    return argv
