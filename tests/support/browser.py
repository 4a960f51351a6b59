"""Screenshots of a web page with headless Chromium (Debian's `chromium` package).

`chromium --screenshot --virtual-time-budget=...` shoots once the page's virtual time
runs out, which for Rerun's web viewer comes before its wasm has drawn anything (the
budget does not wait for the wasm compile and shader setup). So this drives Chromium
over the DevTools protocol on a pipe (`--remote-debugging-pipe`: JSON messages ended by
NUL on fds 3 and 4, no websocket needed) and shoots repeatedly until the picture is
`ready` or the time is up.
"""

from __future__ import annotations

import base64
import fcntl
import io
import json
import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable

import numpy as np
from PIL import Image

CHROMIUM = shutil.which("chromium")
# Headless Chromium has no GPU here: WebGL2 through SwiftShader (software), which Rerun's
# viewer accepts (it falls back from WebGPU to GL).
FLAGS = ["--headless", "--no-sandbox", "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
         "--no-first-run", "--no-default-browser-check", "--disable-extensions", "--mute-audio"]


class _Pipe:
    """One DevTools session over Chromium's debugging pipe."""

    def __init__(self, proc: subprocess.Popen, to_browser: int, from_browser: int):
        self.proc, self.out, self.inp = proc, to_browser, from_browser
        self.buffer, self.next_id = b"", 0

    def call(self, method: str, params: dict | None = None, session: str | None = None, timeout: float = 30.0) -> dict:
        self.next_id += 1
        msg = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self.out, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            while b"\0" not in self.buffer:
                if time.monotonic() > deadline or self.proc.poll() is not None:
                    raise RuntimeError(f"chromium gave no answer to {method}")
                chunk = os.read(self.inp, 1 << 20)
                if not chunk:
                    raise RuntimeError("chromium closed its debugging pipe")
                self.buffer += chunk
            raw, _, self.buffer = self.buffer.partition(b"\0")
            reply = json.loads(raw)
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply["result"]


def _with_pipe_fds(to_child: int, from_child: int) -> Callable[[], None]:
    def setup() -> None:  # in the child: Chromium reads commands on fd 3, answers on fd 4
        # Out of the way first (3 and 4 may be either end); dup2's copies survive exec, the
        # originals (os.pipe: close-on-exec) and these F_DUPFD copies do not.
        high = [fcntl.fcntl(fd, fcntl.F_DUPFD, 10) for fd in (to_child, from_child)]
        os.dup2(high[0], 3)
        os.dup2(high[1], 4)
        for fd in high:
            os.close(fd)
    return setup


def screenshots(url: str, size: tuple[int, int], ready: Callable[[np.ndarray], bool],
                timeout: float = 25.0, every: float = 1.0) -> tuple[np.ndarray, float]:
    """Open `url` in a `size` (w, h) window and take a screenshot every `every` s until
    `ready(rgb)` holds or `timeout` s pass. Returns the last picture (H, W, 3) uint8 and
    the seconds it took."""
    cmd_r, cmd_w = os.pipe()
    res_r, res_w = os.pipe()
    profile = tempfile.mkdtemp(prefix="chromium-")
    proc = subprocess.Popen(
        [CHROMIUM, *FLAGS, "--remote-debugging-pipe", f"--user-data-dir={profile}",
         f"--window-size={size[0]},{size[1]}", "about:blank"],
        close_fds=False, preexec_fn=_with_pipe_fds(cmd_r, res_w),  # close_fds would close 3 and 4
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(cmd_r)
    os.close(res_w)
    start = time.monotonic()
    try:
        cdp = _Pipe(proc, cmd_w, res_r)
        page = next(t for t in cdp.call("Target.getTargets")["targetInfos"] if t["type"] == "page")
        session = cdp.call("Target.attachToTarget", {"targetId": page["targetId"], "flatten": True})["sessionId"]
        cdp.call("Emulation.setDeviceMetricsOverride",
                 {"width": size[0], "height": size[1], "deviceScaleFactor": 1, "mobile": False}, session)
        cdp.call("Page.navigate", {"url": url}, session)
        while True:
            time.sleep(every)
            png = cdp.call("Page.captureScreenshot", {"format": "png"}, session)["data"]
            rgb = np.asarray(Image.open(io.BytesIO(base64.b64decode(png))).convert("RGB"))
            if ready(rgb) or time.monotonic() - start > timeout:
                return rgb, time.monotonic() - start
    finally:
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        os.close(cmd_w)
        os.close(res_r)
        shutil.rmtree(profile, ignore_errors=True)
