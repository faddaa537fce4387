"""A headless Chromium driven over its DevTools pipe, for checks of what a reader sees.

Used by the tests (``report.html``) and by ``docs/check_site.py`` (the documentation's front
page). Standard library only, plus Pillow (a matplotlib dependency) to count a screenshot's
colours. Chromium comes from Debian's ``chromium`` package (CI installs it in ``.ci/run``).
"""

from __future__ import annotations

import base64
import io
import json
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

__all__ = ["BrowserMissing", "chromium", "inspect_page", "colours"]


class BrowserMissing(RuntimeError):
    """No Chromium on this machine."""


def chromium() -> str:
    """Path of the Chromium executable, or :class:`BrowserMissing` naming how to install it."""
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        exe = shutil.which(name)
        if exe:
            return exe
    raise BrowserMissing("Chromium is not installed: this check needs a real headless browser "
                         "(apt-get install -y --no-install-recommends chromium; CI does this in .ci/run)")

def _onto_3_and_4(read_end: int, write_end: int) -> None:
    """In the child before exec: the pipe ends as fd 3 and 4, inheritable (the originals close on exec)."""
    a, b = os.dup(read_end), os.dup(write_end)          # copies first, so neither end is clobbered
    os.dup2(a, 3)
    os.dup2(b, 4)
    os.set_inheritable(3, True)
    os.set_inheritable(4, True)


class _Browser:
    """A headless Chromium driven over the DevTools pipe; one page target."""

    def __init__(self, tmp: Path):
        to_chrome_r, self._w = os.pipe()
        self._r, from_chrome_w = os.pipe()
        self.proc = subprocess.Popen(
            [chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--disable-dev-shm-usage", "--hide-scrollbars", f"--user-data-dir={tmp / 'profile'}",
             "--remote-debugging-pipe", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            close_fds=False, preexec_fn=lambda: _onto_3_and_4(to_chrome_r, from_chrome_w))
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self._buf = b""
        self._id = 0
        self.events: list[dict] = []
        target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        self.session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]

    def _read(self, deadline: float) -> dict:
        while b"\0" not in self._buf:
            if time.monotonic() > deadline:
                raise TimeoutError("Chromium did not answer in time")
            chunk = os.read(self._r, 1 << 20)
            if not chunk:
                raise RuntimeError(f"Chromium closed the DevTools pipe (exit code {self.proc.poll()})")
            self._buf += chunk
        msg, _, self._buf = self._buf.partition(b"\0")
        return json.loads(msg)

    def call(self, method: str, params: dict | None = None, *, session: bool = False, timeout: float = 30.0):
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = self.session
        os.write(self._w, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            m = self._read(deadline)
            if m.get("id") == self._id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m["result"]
            self.events.append(m)

    def wait_for(self, method: str, timeout: float = 30.0) -> dict:
        deadline = time.monotonic() + timeout
        for i, m in enumerate(self.events):
            if m.get("method") == method:
                return self.events.pop(i)
        while True:
            m = self._read(deadline)
            if m.get("method") == method:
                return m
            self.events.append(m)

    def close(self):
        try:
            self.call("Browser.close", timeout=5)
        except Exception:                       # the browser may already be gone; it is killed below
            pass
        for fd in (self._w, self._r):
            os.close(fd)
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def inspect_page(page: Path, headline: str = "#headline") -> dict:
    """Load ``page`` in headless Chromium; return what a reader would see and what went wrong.

    Returns a dict: ``images`` ([alt, complete, naturalWidth] each), ``headline`` (the text of the
    first element matching the CSS selector ``headline``, or None), ``tables``, ``title``,
    ``height``, ``errors`` (console errors, exceptions, failed loads), ``urls`` (every request)
    and ``screenshot`` (PNG bytes of the first screen).
    """
    with tempfile.TemporaryDirectory() as tmp:
        b = _Browser(Path(tmp))
        try:
            for domain in ("Page", "Runtime", "Log", "Network"):
                b.call(f"{domain}.enable", session=True)
            b.call("Emulation.setDeviceMetricsOverride",
                   {"width": 1280, "height": 900, "deviceScaleFactor": 1, "mobile": False}, session=True)
            b.call("Page.navigate", {"url": page.resolve().as_uri()}, session=True)
            b.wait_for("Page.loadEventFired")
            probe = b.call("Runtime.evaluate", {"returnByValue": True, "awaitPromise": True, "expression": """
                (async () => {
                  const imgs = Array.from(document.images);
                  await Promise.all(imgs.map(i => i.decode().catch(() => null)));
                  const h = document.querySelector(%s);
                  return {images: imgs.map(i => [i.alt, i.complete, i.naturalWidth]),
                          headline: h ? h.innerText : null, tables: document.querySelectorAll('table').length,
                          title: document.title, height: document.body.scrollHeight};
                })()""" % json.dumps(headline)}, session=True)["result"]["value"]
            shot = base64.b64decode(b.call("Page.captureScreenshot", {"format": "png"}, session=True)["data"])
            time.sleep(0.2)                     # let late console messages arrive before reading them
            b.call("Runtime.evaluate", {"expression": "0"}, session=True)
        finally:
            b.close()
    errors, urls = [], []
    for m in b.events:
        p, meth = m.get("params", {}), m.get("method")
        if meth == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            errors.append("console: " + " ".join(str(a.get("value", a.get("description"))) for a in p["args"]))
        elif meth == "Runtime.exceptionThrown":
            errors.append("exception: " + p["exceptionDetails"].get("text", ""))
        elif meth == "Log.entryAdded" and p["entry"]["level"] == "error":
            errors.append("log: " + p["entry"]["text"])
        elif meth == "Network.requestWillBeSent":
            urls.append(p["request"]["url"])
        elif meth == "Network.loadingFailed":
            errors.append("network: " + p.get("errorText", ""))
    return {**probe, "errors": errors, "urls": urls, "screenshot": shot}


def colours(png: bytes) -> int:
    """Number of distinct colours of a PNG (1: a blank screen)."""
    from PIL import Image

    im = Image.open(io.BytesIO(png)).convert("RGB")
    return len(im.getcolors(maxcolors=1 << 16) or range(1 << 16))
