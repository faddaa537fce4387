"""Sphinx configuration of the rpud documentation (``make docs``; warnings are errors)."""

from __future__ import annotations

import importlib.metadata
import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(DOCS))   # the local extensions in _ext/ and _gallery_hooks

os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")

import pyvista  # noqa: E402 - after the environment above

# the renders close their plotters once the PNG is written: the gallery shows the written files
# (_gallery_hooks.saved_pictures_scraper), so pyvista's own gallery mode stays off
pyvista.OFF_SCREEN = True

project = "rpud"
author = "the rpud developers"
copyright = "the rpud developers (MIT License)"
release = importlib.metadata.version("rpud")
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "sphinx.ext.intersphinx",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
]
# every module of _ext/ is a local extension (CLI reference, schema tables, V&V pages, ...)
extensions += sorted(f"_ext.{p.stem}" for p in (DOCS / "_ext").glob("*.py") if not p.stem.startswith("_"))

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "gallery/*.ipynb", "**.ipynb_checkpoints", "gallery/*.py.md5",
                    "gallery/*.json", "gallery/*.zip"]
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

numpydoc_show_class_members = False
numpydoc_validation_checks: set[str] = set()
autodoc_typehints = "none"
autodoc_member_order = "bysource"

# no network at build time: intersphinx mappings are not fetched
intersphinx_mapping: dict[str, tuple[str, str | None]] = {}

sphinx_gallery_conf = {
    "examples_dirs": [str(ROOT / "results" / "examples")],
    "gallery_dirs": ["gallery"],
    "filename_pattern": r"/ex\d+_",            # every example runs during the build
    "ignore_pattern": r"__init__\.py",
    # by dotted name, not as function objects: the configuration stays picklable for Sphinx's cache
    "image_scrapers": ("_gallery_hooks.saved_pictures_scraper",),
    "reset_argv": "_gallery_hooks.reset_argv",
    "abort_on_example_error": True,
    "download_all_examples": False,
    "remove_config_comments": True,
    "plot_gallery": "True",
    "within_subsection_order": "FileNameSortKey",
    "capture_repr": (),                        # the pages show what the examples print, not stray return values
}

html_theme = "pydata_sphinx_theme"
html_title = f"rpud {release}"
html_static_path = ["_static"]
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 6,         # the six manuals in the top bar; the rest under "More"
    "footer_start": ["copyright"],
}
html_last_updated_fmt = None
# a fixed colour mode: without one the theme logs a console error on a first visit
html_context = {"default_mode": "light"}
