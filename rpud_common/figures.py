"""matplotlib figures without global state: no backend switch, no pyplot figure registry.

Figures are plain :class:`matplotlib.figure.Figure` objects (they render in a notebook and save
with any backend-independent canvas), so the library never changes the user's pyplot backend.
"""

from __future__ import annotations

import os
from pathlib import Path

from .files import atomic_output

__all__ = ["subplots", "save_figure"]


def subplots(nrows: int = 1, ncols: int = 1, **kwargs):
    """A new :class:`~matplotlib.figure.Figure` and its Axes, like ``pyplot.subplots``.

    ``figsize`` and ``dpi`` go to the figure, everything else to ``Figure.subplots``. The figure
    is not registered with pyplot: nothing global changes and nothing needs closing.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=kwargs.pop("figsize", None), dpi=kwargs.pop("dpi", None))
    return fig, fig.subplots(nrows, ncols, **kwargs)


def save_figure(fig, path: str | os.PathLike) -> Path:
    """Lay out and save a figure atomically (format from the suffix); returns the path."""
    path = Path(path)
    fig.tight_layout()
    with atomic_output(path) as tmp:
        fig.savefig(tmp)
    return path
