"""Headless Chromium for the page's tests: Debian's ``chromium`` driven by Playwright from pip (no
``playwright install``: nothing is downloaded). Every request other than the page's own is aborted
and recorded, so a test can assert that a page fetched nothing.

WebGL in headless Chromium without a GPU: ANGLE on SwiftShader (software Vulkan), allowed explicitly
(``--enable-unsafe-swiftshader``, since Chromium 137 software WebGL is off unless asked for).
"""

from __future__ import annotations

import io
import shutil

import numpy as np

#: the flags that give headless Chromium a working WebGL 2 on a machine without a GPU
FLAGS = ("--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist")
#: URL schemes a page may use without a request leaving it
LOCAL = ("data:", "blob:", "about:")


def unavailable() -> str | None:
    """Why the browser tests cannot run here (a reason for pytest.skip), or None."""
    if shutil.which("chromium") is None:
        return ("Debian's chromium is not installed: scripts/test.sh installs it as root "
                "(apt-get install --no-install-recommends chromium)")
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "playwright is not installed (pip install playwright: it is in the dev extra)"
    return None


class Browser:
    """One headless Chromium; :meth:`open` loads a page file into a fresh page."""

    def __init__(self):
        from playwright.sync_api import sync_playwright

        self._pw = sync_playwright().start()
        try:
            self._browser = self._pw.chromium.launch(executable_path=shutil.which("chromium"), args=list(FLAGS))
        except BaseException:
            self._pw.stop()
            raise

    def open(self, path, width=1000, height=700, timeout=60.0, wait=True, init=None) -> Page:
        """``path`` in a fresh page (``init``: a script run before the page's own); with ``wait``,
        once ``o3dheat.ready`` or ``o3dheat.error`` is set."""
        return Page(self._browser, path, width, height, timeout if wait else None, init)

    def close(self):
        self._browser.close()
        self._pw.stop()


class Page:
    """A page file opened from disk, every other request aborted; :attr:`requests` lists every URL
    the page asked for (routed or not), :attr:`blocked` those aborted, :attr:`errors` its errors."""

    def __init__(self, browser, path, width, height, timeout, init):
        self.url = path.resolve().as_uri()
        self.requests, self.blocked, self.errors = [], [], []
        self.context = browser.new_context(viewport={"width": width, "height": height})
        self.context.route("**/*", self._route)
        if init:
            self.context.add_init_script(init)
        self.page = self.context.new_page()
        self.page.on("request", lambda r: self.requests.append(r.url))
        self.page.on("pageerror", lambda e: self.errors.append(str(e)))
        self.page.on("console", lambda m: self.errors.append(m.text) if m.type == "error" else None)
        self.page.goto(self.url)
        if timeout:
            self.wait(self.page, timeout)

    @staticmethod
    def wait(frame, timeout=60.0):
        """Until ``o3dheat.ready`` or ``o3dheat.error`` is set in ``frame`` (a page or a frame)."""
        frame.wait_for_function("window.o3dheat && (window.o3dheat.ready || window.o3dheat.error)",
                                timeout=timeout * 1000, polling=50)

    def _route(self, route):
        url = route.request.url
        if url == self.url or url.startswith(LOCAL):
            route.continue_()
        else:
            self.blocked.append(url)
            route.abort()

    def outside(self) -> list[str]:
        """The URLs asked for other than the page itself and data:/blob: URLs."""
        return [u for u in self.requests + self.blocked if u != self.url and not u.startswith(LOCAL)]

    def js(self, expression, arg=None):
        return self.page.evaluate(expression, arg)

    def set_scale(self, i):
        """``o3dheat.setScale(i)`` (synchronous), then two animation frames: the frame is on screen."""
        return self.js("async (i) => { const j = o3dheat.setScale(i); await new Promise((r) => "
                       "requestAnimationFrame(() => requestAnimationFrame(r))); return j; }", i)

    def picture(self) -> np.ndarray:
        """(h, w, 3) uint8: a screenshot of the 3D view, without the colorbar's strip on the right."""
        from PIL import Image

        png = self.page.locator("#o3h-canvas").screenshot()
        img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
        return img[:, : max(img.shape[1] - 130, 1)]

    def close(self):
        self.context.close()


def drawn(img) -> float:
    """The fraction of pixels that are not the white background."""
    return float(np.any(img < 245, axis=2).mean())


def changed(a, b) -> float:
    """The fraction of pixels that differ (by more than a rounding) between two pictures."""
    return float(np.any(np.abs(a.astype(int) - b.astype(int)) > 8, axis=2).mean())
