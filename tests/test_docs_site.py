"""The built-site checks that ``make docs`` runs (docs/check_site.py) find what they should."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "docs"))

from check_site import broken_links  # noqa: E402


def test_internal_links_to_missing_files_and_anchors_are_found(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "_static").mkdir()
    (tmp_path / "index.html").write_text(
        '<a href="sub/page.html#there">ok</a> <a href="sub/page.html#nowhere">bad anchor</a> '
        '<img src="missing.png"> <a href="https://example.org/x">external</a> <a href="#top" id="top">self</a>')
    (tmp_path / "sub" / "page.html").write_text('<h1 id="there">x</h1><a href="../index.html">up</a>')
    (tmp_path / "_static" / "template.html").write_text("<a href=\"{{ pathto('x') }}\">a theme template</a>")
    assert sorted(broken_links(tmp_path)) == ["index.html: missing.png (no such file)",
                                              "index.html: sub/page.html#nowhere (no such anchor)"]
