"""matplotlib figures without global state: no backend switch, no pyplot figure registry.

Figures are plain :class:`matplotlib.figure.Figure` objects (they render in a notebook and save
with any backend-independent canvas), so the library never changes the user's pyplot backend.
"""

from __future__ import annotations

import os
from pathlib import Path

from .files import atomic_output

__all__ = ["subplots", "save_figure", "axes_or_new"]


def subplots(nrows: int = 1, ncols: int = 1, **kwargs):
    """A new :class:`~matplotlib.figure.Figure` and its Axes, like ``pyplot.subplots``.

    ``figsize`` and ``dpi`` go to the figure, everything else to ``Figure.subplots``. The figure
    is not registered with pyplot: nothing global changes and nothing needs closing.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=kwargs.pop("figsize", None), dpi=kwargs.pop("dpi", None))
    return fig, fig.subplots(nrows, ncols, **kwargs)


def axes_or_new(ax=None, n: int = 1, *, side_by_side: bool = False, **kwargs):
    """The caller's Axes, or new ones on a new figure (``n`` panels stacked vertically, or
    side by side).

    The plot functions of the packages take an optional ``ax`` (one Axes) or ``axes`` (a
    sequence of ``n``); ``None`` makes a figure with :func:`subplots` (``kwargs`` go there).
    Returns one Axes for ``n == 1``, else a tuple of ``n``.
    """
    if ax is None:
        shape = (1, n) if side_by_side else (n, 1)
        _, made = subplots(*shape, **kwargs) if n > 1 else subplots(**kwargs)
        return tuple(made) if n > 1 else made
    if n == 1:
        if not hasattr(ax, "figure") or not hasattr(ax, "plot"):
            raise TypeError(f"ax must be a matplotlib Axes, got {type(ax).__name__}")
        return ax
    axes = tuple(ax)
    if len(axes) != n or not all(hasattr(a, "plot") for a in axes):
        raise TypeError(f"axes must be a sequence of {n} matplotlib Axes")
    return axes


def save_figure(fig, path: str | os.PathLike) -> Path:
    """Lay out and save a figure atomically (format from the suffix); returns the path.

    ``fig`` may also be an Axes or a sequence of Axes (as the plot functions return): their
    figure is saved.
    """
    if not hasattr(fig, "savefig"):
        first = fig if hasattr(fig, "figure") else next(iter(fig))
        fig = first.figure
    path = Path(path)
    fig.tight_layout()
    with atomic_output(path) as tmp:
        fig.savefig(tmp)
    return path
