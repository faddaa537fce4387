"""Hooks of the sphinx-gallery configuration in ``docs/conf.py``, named there by their dotted
path so that the configuration stays picklable (Sphinx caches it between builds).

The image scraper shows on each example's page the pictures the example wrote into its
``example_output/`` folder: the off-screen renders (pyvista plotters are closed once their PNG
is written, so sphinx-gallery's pyvista scraper has nothing to collect) and the saved
matplotlib figures. A page therefore shows exactly the files a user gets from running the
example, each once.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path

__all__ = ["reset_argv", "saved_pictures_scraper"]

OUTPUT_FOLDER = "example_output"
"""Where every example writes its files, relative to its working folder."""

_BUILD_START_NS = time.time_ns()
_SEEN: dict[str, int] = {}      # picture path -> modification time (ns) already shown


def reset_argv(gallery_conf, script_vars) -> list[str]:
    """Every example runs with ``--fast`` (coarse meshes, looser interval targets)."""
    return ["--fast"]


def _new_pictures(folder: Path) -> list[Path]:
    """PNG files under ``folder`` written during this build and not shown yet, oldest first."""
    if not folder.is_dir():
        return []
    found = []
    for path in folder.rglob("*.png"):
        try:
            mtime = path.stat().st_mtime_ns
        except FileNotFoundError:       # a temporary file renamed meanwhile
            continue
        if mtime < _BUILD_START_NS or _SEEN.get(str(path)) == mtime:
            continue
        _SEEN[str(path)] = mtime
        found.append((mtime, str(path), path))
    return [p for _m, _s, p in sorted(found)]


def saved_pictures_scraper(block, block_vars, gallery_conf) -> str:
    """sphinx-gallery image scraper: the PNGs a code block wrote (see the module docstring)."""
    from sphinx_gallery.scrapers import figure_rst

    import sys

    if "matplotlib.pyplot" in sys.modules:      # figures left open are shown through their files
        sys.modules["matplotlib.pyplot"].close("all")
    folder = Path(block_vars["src_file"]).parent / OUTPUT_FOLDER
    iterator = block_vars["image_path_iterator"]
    shown = []
    for picture in _new_pictures(folder):
        target = Path(next(iterator))
        shutil.copyfile(picture, target)
        shown.append(str(target))
    return figure_rst(shown, gallery_conf["src_dir"])
