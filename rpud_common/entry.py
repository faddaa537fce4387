"""Console entry points (``pip install`` puts them on the PATH beside ``python -m``).

Each one installs the signal handlers before anything heavy is imported, then runs the same
command line as its ``python -m`` twin (:func:`rpud_common.launch.launch`). The console scripts
are commands, the top layer: each imports its command module with an ``import`` statement, run
only once the handlers are in place, so importing this module loads the standard library only.
"""

from __future__ import annotations

from .launch import launch

__all__ = ["geometry", "modal", "harmonic", "impact", "pipeline", "COMMANDS"]


def _geometry_main():
    from geometry.__main__ import main
    return main


def _modal_main():
    from fem.modal_cli import main
    return main


def _harmonic_main():
    from fem.harmonic_cli import main
    return main


def _impact_main():
    from impact.__main__ import main
    return main


def _pipeline_main():
    from results.__main__ import main
    return main


def geometry() -> int:
    """``rpud-geometry``: ``python -m geometry``."""
    return launch(_geometry_main, prog="rpud-geometry")


def modal() -> int:
    """``rpud-modal``: ``python -m fem.modal``."""
    return launch(_modal_main, prog="rpud-modal")


def harmonic() -> int:
    """``rpud-harmonic``: ``python -m fem.harmonic``."""
    return launch(_harmonic_main, prog="rpud-harmonic")


def impact() -> int:
    """``rpud-impact``: ``python -m impact``."""
    return launch(_impact_main, prog="rpud-impact")


def pipeline() -> int:
    """``rpud-pipeline``: ``python -m results``."""
    return launch(_pipeline_main, prog="rpud-pipeline")


COMMANDS = {"rpud-geometry": "geometry", "rpud-modal": "modal", "rpud-harmonic": "harmonic",
            "rpud-impact": "impact", "rpud-pipeline": "pipeline"}
"""Console script name -> function here (pyproject's ``[project.scripts]`` lists the same)."""
