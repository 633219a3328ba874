"""Headless Chromium driven over the Chrome DevTools protocol on a pipe (stdlib only).

``--remote-debugging-pipe`` makes Chromium read protocol commands from file descriptor 3 and
write answers and events to 4, each JSON message ended by a NUL byte: no websocket, no port,
nothing to install (Playwright talks to Chromium the same way).
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import time
from pathlib import Path

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--no-first-run", "--disable-sync", "--disable-quic",
         "--remote-debugging-pipe")


class Browser:
    """One Chromium with one page. ``console_errors`` collects console errors, uncaught
    exceptions and error log entries of the page."""

    def __init__(self, profile: Path, *, width: int = 1280, height: int = 900,
                 timeout: float = 60.0):
        profile.mkdir(parents=True, exist_ok=True)
        log = open(profile / "chromium.log", "wb")
        to_browser_read, self._to_browser = os.pipe()
        self._from_browser, from_browser_write = os.pipe()

        def pipes():  # in the child: its descriptors 3 and 4 are the protocol's
            reading, writing = os.dup(to_browser_read), os.dup(from_browser_write)
            os.dup2(reading, 3)
            os.dup2(writing, 4)

        self.process = subprocess.Popen(
            [CHROMIUM, *FLAGS, f"--user-data-dir={profile}", f"--window-size={width},{height}",
             "about:blank"], preexec_fn=pipes, close_fds=False,
            stdout=subprocess.DEVNULL, stderr=log)
        os.close(to_browser_read)
        os.close(from_browser_write)
        self.timeout = timeout
        self._buffer = b""
        self._next_id = 0
        self.events: list[dict] = []
        self.console_errors: list[str] = []
        self.session = None
        page = next(t for t in self.send("Target.getTargets")["targetInfos"]
                    if t["type"] == "page")
        self.session = self.send("Target.attachToTarget", targetId=page["targetId"],
                                 flatten=True)["sessionId"]
        for domain in ("Page", "Runtime", "Log"):
            self.send(f"{domain}.enable")
        self.send("Emulation.setDeviceMetricsOverride", width=width, height=height,
                  deviceScaleFactor=1, mobile=False)

    # ------------------------------------------------------------------ protocol
    def _read(self) -> dict:
        deadline = time.monotonic() + self.timeout
        while b"\0" not in self._buffer:
            if time.monotonic() > deadline:
                raise TimeoutError("chromium did not answer")
            chunk = os.read(self._from_browser, 1 << 16)
            if not chunk:
                raise RuntimeError("chromium closed the protocol pipe")
            self._buffer += chunk
        message, self._buffer = self._buffer.split(b"\0", 1)
        data = json.loads(message)
        self._note(data)
        return data

    def _note(self, data: dict) -> None:
        method, params = data.get("method"), data.get("params", {})
        if method == "Runtime.consoleAPICalled" and params.get("type") == "error":
            self.console_errors.append(" ".join(str(a.get("value", a.get("description")))
                                                for a in params.get("args", [])))
        elif method == "Runtime.exceptionThrown":
            details = params.get("exceptionDetails", {})
            self.console_errors.append(details.get("exception", {}).get("description")
                                       or details.get("text", "exception"))
        elif method == "Log.entryAdded" and params.get("entry", {}).get("level") == "error":
            self.console_errors.append(params["entry"].get("text", ""))
        if method:
            self.events.append(data)

    def send(self, method: str, **params) -> dict:
        """Send a command and return its result (RuntimeError for a protocol error)."""
        self._next_id += 1
        message = {"id": self._next_id, "method": method, "params": params}
        if self.session is not None:
            message["sessionId"] = self.session
        os.write(self._to_browser, json.dumps(message).encode() + b"\0")
        while True:
            data = self._read()
            if data.get("id") == self._next_id:
                if "error" in data:
                    raise RuntimeError(f"{method}: {data['error']}")
                return data.get("result", {})

    def wait_for(self, method: str) -> dict:
        """The first event ``method`` seen from now (earlier ones are forgotten)."""
        self.events.clear()
        while True:
            found = next((e for e in self.events if e["method"] == method), None)
            if found:
                return found
            self._read()

    # ------------------------------------------------------------------ page
    def open(self, url: str) -> None:
        """Load ``url`` and wait for its load event."""
        self.events.clear()
        self.send("Page.navigate", url=url)
        while not any(e["method"] == "Page.loadEventFired" for e in self.events):
            self._read()

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page (awaited when a promise)."""
        result = self.send("Runtime.evaluate", expression=expression, returnByValue=True,
                           awaitPromise=True)
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression[:80]}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def rect(self, selector: str) -> dict:
        """Where the element is in the viewport, after scrolling it into view (CSS px)."""
        return self.evaluate(f"(() => {{ const e = document.querySelector({json.dumps(selector)});"
                             "e.scrollIntoView({block: 'center'}); const r = "
                             "e.getBoundingClientRect(); return {x: r.x, y: r.y, "
                             "width: r.width, height: r.height}; })()")

    def screenshot(self, rect: dict, path: Path) -> bytes:
        """PNG of a viewport rectangle (as :meth:`rect` gives it), also written to ``path``."""
        scroll = self.evaluate("[window.scrollX, window.scrollY]")  # the clip is in the page's
        clip = {"x": rect["x"] + scroll[0], "y": rect["y"] + scroll[1],   # coordinates
                "width": rect["width"], "height": rect["height"]}
        png = base64.b64decode(self.send("Page.captureScreenshot", format="png",
                                         clip={**clip, "scale": 1},
                                         captureBeyondViewport=True)["data"])
        path.write_bytes(png)
        return png

    def click(self, x: float, y: float) -> None:
        """A left click at viewport point (x, y) CSS px."""
        for kind in ("mousePressed", "mouseReleased"):
            self.send("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left",
                      clickCount=1)

    def close(self) -> None:
        try:
            self.send("Browser.close")
        except (RuntimeError, OSError, TimeoutError):
            pass
        try:
            self.process.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        for fd in (self._to_browser, self._from_browser):
            os.close(fd)
