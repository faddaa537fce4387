"""Console entry points (``pip install`` puts them on the PATH beside ``python -m``).

Each one installs the signal handlers before anything heavy is imported, then runs the same
command line as its ``python -m`` twin (:func:`rpud_common.launch.launch`). This module imports
the standard library only.
"""

from __future__ import annotations

from .launch import launch

__all__ = ["geometry", "modal", "harmonic", "impact", "pipeline", "COMMANDS"]


def geometry() -> int:
    """``rpud-geometry``: ``python -m geometry``."""
    return launch("geometry.__main__", prog="rpud-geometry")


def modal() -> int:
    """``rpud-modal``: ``python -m fem.modal``."""
    return launch("fem.modal_cli", prog="rpud-modal")


def harmonic() -> int:
    """``rpud-harmonic``: ``python -m fem.harmonic``."""
    return launch("fem.harmonic_cli", prog="rpud-harmonic")


def impact() -> int:
    """``rpud-impact``: ``python -m impact``."""
    return launch("impact.cli", prog="rpud-impact")


def pipeline() -> int:
    """``rpud-pipeline``: ``python -m results``."""
    return launch("results.__main__", prog="rpud-pipeline")


COMMANDS = {"rpud-geometry": "geometry", "rpud-modal": "modal", "rpud-harmonic": "harmonic",
            "rpud-impact": "impact", "rpud-pipeline": "pipeline"}
"""Console script name -> function here (pyproject's ``[project.scripts]`` lists the same)."""
