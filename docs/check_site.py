"""Checks of the built documentation that Sphinx's warnings do not cover (run by ``make docs``).

1. Internal links: every relative ``href``/``src`` of every built page names a file that exists,
   and a ``#fragment`` into a built page names an element id of that page.
2. The front page as a reader sees it, in a real headless Chromium: it renders (no console
   error, every image loads), its heading is there, and its screenshot is not blank.

Exit code 0 when both pass, 1 with one line per problem otherwise.
"""

from __future__ import annotations

import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

HTML = Path(__file__).resolve().parent / "_build" / "html"
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))   # the shared browser driver


class _Page(HTMLParser):
    def __init__(self):
        super().__init__()
        self.ids: set[str] = set()
        self.links: list[str] = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if a.get("id"):
            self.ids.add(a["id"])
        if tag == "a" and a.get("name"):
            self.ids.add(a["name"])
        for key in ("href", "src"):
            if a.get(key):
                self.links.append(a[key])


def _parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8", errors="replace"))
    return page


def broken_links(root: Path = HTML) -> list[str]:
    """``file: link`` for every internal link of the built site that leads nowhere."""
    # _static/ holds the theme's Jinja templates, not pages
    pages = {p: _parse(p) for p in root.rglob("*.html") if "_static" not in p.relative_to(root).parts}
    problems = []
    for path, page in pages.items():
        for link in page.links:
            parts = urlsplit(link)
            if parts.scheme or link.startswith(("//", "mailto:", "javascript:", "data:")):
                continue
            target = (path.parent / unquote(parts.path)).resolve() if parts.path else path
            if not target.exists():
                problems.append(f"{path.relative_to(root)}: {link} (no such file)")
            elif parts.fragment and target.suffix == ".html" and target in pages \
                    and unquote(parts.fragment) not in pages[target].ids:
                problems.append(f"{path.relative_to(root)}: {link} (no such anchor)")
    return problems


def front_page_problems(root: Path = HTML) -> list[str]:
    """What a reader of ``index.html`` would see go wrong."""
    from browser import BrowserMissing, colours, inspect_page

    try:
        seen = inspect_page(root / "index.html", headline="h1")
    except BrowserMissing as exc:
        return [str(exc)]
    problems = [f"index.html: {e}" for e in seen["errors"]]
    problems += [f"index.html: image {alt!r} did not load" for alt, ok, w in seen["images"] if not (ok and w > 0)]
    if not (seen["headline"] or "").startswith("rpud"):
        problems.append(f"index.html: heading {seen['headline']!r} is not the site's")
    if colours(seen["screenshot"]) < 2:
        problems.append("index.html: the screenshot is blank")
    return problems


def main() -> int:
    if not (HTML / "index.html").exists():
        print(f"check_site: {HTML / 'index.html'} is missing: build the site first (make docs)", file=sys.stderr)
        return 1
    problems = broken_links() + front_page_problems()
    for p in problems:
        print(f"check_site: {p}", file=sys.stderr)
    print(f"check_site: {len(list(HTML.rglob('*.html')))} pages, {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
