"""Headless Chromium for the report page's tests, driven over the DevTools protocol on a
pipe (``--remote-debugging-pipe``: the browser reads commands from its file descriptor 3
and writes answers and events to 4, each message one JSON object ended by a NUL byte), so
no Python package beyond the standard library is needed. Every wait waits for its event
(an answer, a file, a page state) with a long timeout, never a fixed time.
"""

from __future__ import annotations

import json
import os
import select
import shutil
import subprocess
import time
from pathlib import Path

import pytest

TIMEOUT = 120.0  # seconds: long, for a loaded machine; a wait ends as soon as its event comes


def chromium() -> str | None:
    """The Chromium binary on this machine, or None."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if shutil.which(name):
            return shutil.which(name)
    return None


needs_chromium = pytest.mark.skipif(
    chromium() is None, reason="headless Chromium not found (Debian: apt-get install "
    "chromium); the page is checked in a browser only where it is installed")


def _high(*fds: int) -> list[int]:
    """The descriptors moved to 10 and above, so that none of them is 3 or 4 (which the
    browser's ends are copied to in the child: a copy onto itself would stay close-on-exec,
    and one onto the other end would close it)."""
    import fcntl

    out = [fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10) for fd in fds]
    for fd in fds:
        os.close(fd)
    return out


class Browser:
    """One headless Chromium with one page (:meth:`open`, :meth:`evaluate`)."""

    def __init__(self, binary: str, profile: Path, *, width: int = 1400, height: int = 900,
                 downloads: Path | None = None):
        to_browser_r, self._to_browser = _high(*os.pipe())
        self._from_browser, from_browser_w = _high(*os.pipe())

        def fds():  # the browser's ends as its descriptors 3 and 4 (inheritable)
            os.dup2(to_browser_r, 3)
            os.dup2(from_browser_w, 4)

        self.proc = subprocess.Popen(
            [binary, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
             "--no-first-run", "--disable-background-networking", "--disable-sync",
             "--disable-component-update", "--remote-debugging-pipe",
             f"--user-data-dir={profile}", f"--window-size={width},{height}", "about:blank"],
            preexec_fn=fds, close_fds=False, stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(to_browser_r)
        os.close(from_browser_w)
        self._buffer = b""
        self._id = 0
        target = self.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        self.session = self.send("Target.attachToTarget",
                                 {"targetId": target, "flatten": True})["sessionId"]
        self.send("Emulation.setDeviceMetricsOverride", {
            "width": width, "height": height, "deviceScaleFactor": 1, "mobile": False},
            session=True)
        if downloads is not None:
            self.send("Browser.setDownloadBehavior",
                      {"behavior": "allow", "downloadPath": str(downloads)})

    def send(self, method: str, params: dict | None = None, *, session: bool = False) -> dict:
        """One protocol command; its result (an error answer raises)."""
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = self.session
        os.write(self._to_browser, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + TIMEOUT
        while True:
            while b"\0" not in self._buffer:
                left = deadline - time.monotonic()
                ready, _, _ = select.select([self._from_browser], [], [], max(left, 0))
                if not ready:
                    raise TimeoutError(f"no answer to {method} in {TIMEOUT} s")
                chunk = os.read(self._from_browser, 1 << 16)
                if not chunk:
                    raise RuntimeError("the browser closed the pipe")
                self._buffer += chunk
            raw, self._buffer = self._buffer.split(b"\0", 1)
            answer = json.loads(raw)
            if answer.get("id") == self._id:
                if "error" in answer:
                    raise RuntimeError(f"{method}: {answer['error']}")
                return answer.get("result", {})

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page."""
        r = self.send("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                           "awaitPromise": True}, session=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expression[:80]}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def wait_for(self, expression: str, what: str):
        """Poll an expression until it is truthy (long timeout); its value."""
        deadline = time.monotonic() + TIMEOUT
        while True:
            value = self.evaluate(expression)
            if value:
                return value
            if time.monotonic() > deadline:
                raise TimeoutError(f"{what}: not within {TIMEOUT} s")
            time.sleep(0.05)

    def open(self, url: str) -> None:
        """Load a page afresh (also when only its #fragment differs from the page shown,
        which a browser would not reload) and wait until it is complete."""
        self.evaluate("window.__mtannoOld = true")
        if self.evaluate("location.href.split('#')[0]") == url.split("#")[0]:
            self.send("Page.navigate", {"url": "about:blank"}, session=True)
            self.wait_for("location.href === 'about:blank' && !window.__mtannoOld",
                          "leaving the page")
        self.send("Page.navigate", {"url": url}, session=True)
        self.wait_for(f"document.readyState === 'complete' && !window.__mtannoOld && "
                      f"location.href.split('#')[0] === {url.split('#')[0]!r}",
                      f"loading {url}")

    def reload(self) -> None:
        """Reload the page and wait until the new one is complete."""
        self.evaluate("window.__mtannoOld = true")
        self.send("Page.reload", {"ignoreCache": True}, session=True)
        self.wait_for("!window.__mtannoOld && document.readyState === 'complete'",
                      "reloading the page")

    _KEYS = {"ArrowDown": 40, "ArrowUp": 38, "ArrowLeft": 37, "ArrowRight": 39, "Enter": 13,
             "Escape": 27, " ": 32}

    def key(self, key: str, *, shift: bool = False) -> None:
        """Press and release one key (a real keyboard event: ``keydown`` handlers see it);
        ``key`` is a character or a name of :attr:`_KEYS`."""
        code = self._KEYS.get(key, ord(key.upper()[0]))
        params = {"key": key, "windowsVirtualKeyCode": code, "modifiers": 8 if shift else 0}
        if len(key) == 1:
            params["text"] = key
        self.send("Input.dispatchKeyEvent", {"type": "keyDown", **params}, session=True)
        self.send("Input.dispatchKeyEvent", {"type": "keyUp", **params}, session=True)

    def screenshot(self) -> bytes:
        """The viewport as PNG bytes."""
        import base64

        shot = self.send("Page.captureScreenshot", {"format": "png"}, session=True)
        return base64.b64decode(shot["data"])

    def close(self) -> None:
        try:
            self.send("Browser.close")
        except (RuntimeError, TimeoutError, OSError):
            pass
        try:
            self.proc.wait(timeout=TIMEOUT)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        os.close(self._to_browser)
        os.close(self._from_browser)


def wait_for_file(path: Path) -> Path:
    """Wait until a download is complete (the file there, no partial download beside it)."""
    deadline = time.monotonic() + TIMEOUT
    while not (path.exists() and not list(path.parent.glob("*.crdownload"))):
        if time.monotonic() > deadline:
            raise TimeoutError(f"{path} did not appear within {TIMEOUT} s")
        time.sleep(0.05)
    return path
