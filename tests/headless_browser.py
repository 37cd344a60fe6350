"""A headless Chromium driven over the DevTools protocol on a pipe (no extra packages): the
operator page's tests open Meshcat in it and use its controls as a person would."""

from __future__ import annotations

import json
import os
import select
import shutil
import subprocess
import tempfile
import time

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "chrome")


def find_chromium() -> str | None:
    """The path of a Chromium on this machine, or None."""
    for name in CHROMIUM_NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


class HeadlessChromium:
    """Chromium without a window, its DevTools protocol on file descriptors 3 and 4
    (`--remote-debugging-pipe`: JSON messages ending in a NUL byte); one page at `url`."""

    def __init__(self, url: str, timeout_s: float = 20.0):
        path = find_chromium()
        if path is None:
            raise RuntimeError("no Chromium on this machine")
        self._profile = tempfile.TemporaryDirectory()
        to_browser, self._to_browser = os.pipe()
        self._from_browser, from_browser = os.pipe()

        arguments = [
            "--headless=new",
            "--no-sandbox",
            "--remote-debugging-pipe",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--no-first-run",
            "--window-size=1280,900",
            f"--user-data-dir={self._profile.name}",
            url,
        ]
        # the protocol's pipe on the descriptors Chromium reads (3) and writes (4): the shell
        # moves them there and becomes the browser
        self.process = subprocess.Popen(
            ["bash", "-c", f'exec "$0" "$@" 3<&{to_browser} 4>&{from_browser}', path, *arguments],
            pass_fds=(to_browser, from_browser),
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        os.close(to_browser)
        os.close(from_browser)
        self._buffer, self._id, self._timeout = b"", 0, timeout_s
        self._session = None
        page = self._page_target()
        answer = self.call("Target.attachToTarget", targetId=page, flatten=True, session=False)
        self._session = answer["sessionId"]

    def _page_target(self) -> str:
        end = time.monotonic() + self._timeout
        while time.monotonic() < end:
            targets = self.call("Target.getTargets", session=False)["targetInfos"]
            pages = [t["targetId"] for t in targets if t["type"] == "page"]
            if pages:
                return pages[0]
            time.sleep(0.1)
        raise TimeoutError("Chromium opened no page")

    def call(self, method: str, session: bool = True, **params) -> dict:
        """Sends one DevTools command and returns its result (raises on its error)."""
        self._id += 1
        message = {"id": self._id, "method": method, "params": params}
        if session and self._session:
            message["sessionId"] = self._session
        os.write(self._to_browser, json.dumps(message).encode() + b"\0")
        end = time.monotonic() + self._timeout
        while time.monotonic() < end:
            while b"\0" in self._buffer:
                raw, self._buffer = self._buffer.split(b"\0", 1)
                reply = json.loads(raw)
                if reply.get("id") == self._id:
                    if "error" in reply:
                        raise RuntimeError(f"{method}: {reply['error']}")
                    return reply.get("result", {})
            ready, _, _ = select.select([self._from_browser], [], [], 0.1)
            if ready:
                chunk = os.read(self._from_browser, 1 << 20)
                if not chunk:
                    raise RuntimeError("Chromium closed its DevTools pipe")
                self._buffer += chunk
        raise TimeoutError(f"no answer to {method} in {self._timeout} s")

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page (promises awaited)."""
        result = self.call(
            "Runtime.evaluate", expression=expression, awaitPromise=True, returnByValue=True
        )
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression[:60]}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def wait_for(self, expression: str, timeout_s: float = 20.0):
        """Evaluates `expression` until it is truthy (bounded); its value."""
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            try:
                value = self.evaluate(expression)
            except RuntimeError:
                value = None
            if value:
                return value
            time.sleep(0.1)
        raise TimeoutError(f"the page never had {expression!r}")

    def click(self, x: float, y: float, drag_to: tuple[float, float] | None = None) -> None:
        """A left mouse press at (x, y) CSS pixels, moved to `drag_to` if given, released."""
        common = {"button": "left", "clickCount": 1}
        self.call("Input.dispatchMouseEvent", type="mouseMoved", x=x, y=y)
        self.call("Input.dispatchMouseEvent", type="mousePressed", x=x, y=y, **common)
        if drag_to is not None:
            x, y = drag_to
            self.call("Input.dispatchMouseEvent", type="mouseMoved", x=x, y=y, buttons=1)
        self.call("Input.dispatchMouseEvent", type="mouseReleased", x=x, y=y, **common)

    def close(self) -> None:
        """Ends the browser."""
        try:
            self.call("Browser.close", session=False)
        except (RuntimeError, TimeoutError, OSError):
            pass
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(timeout=10)
        for fd in (self._to_browser, self._from_browser):
            os.close(fd)
        self._profile.cleanup()
