"""Serve a recording in Rerun's web viewer, on this machine only (127.0.0.1).

A child process runs the `rerun` binary that ships inside the rerun-sdk wheel: `rerun
--serve-web --bind 127.0.0.1 --web-viewer-port WEB --port GRPC` hosts the viewer (HTML +
wasm) over HTTP and a gRPC server that buffers log data; the page connects back to that
server. This process then replays the file into the server (`viz.recording.replay`).
(Given the file itself, rerun 0.41's command line keeps two cores busy for as long as it
serves, 99 % each; an idle server without one uses none. The Python API's
`rr.serve_web_viewer` has no bind address, so it would listen on every interface.)
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.parse import quote

if TYPE_CHECKING:
    from .recording import Recording

WEB_PORT = 9090  # rerun's defaults
GRPC_PORT = 9876
HOST = "127.0.0.1"


def rerun_executable() -> Path:
    """The `rerun` binary of the installed rerun-sdk (`RERUN_CLI_PATH` overrides, as in
    rerun's own launcher)."""
    if "RERUN_CLI_PATH" in os.environ:
        return Path(os.environ["RERUN_CLI_PATH"])
    import rerun_cli

    return Path(rerun_cli.__file__).parent / "rerun"


def port_in_use(port: int, host: str = HOST) -> bool:
    """True if something on this machine holds `port` (a bind attempt fails)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as servers bind: TIME_WAIT is free
        try:
            s.bind((host, port))
        except OSError:
            return True
    return False


def _die_with_parent() -> None:
    """In the child before exec: SIGTERM it when this process dies, even by SIGKILL, so
    no server outlives `garment view` (Linux's PR_SET_PDEATHSIG; elsewhere nothing)."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # 1 = PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def _listening(port: int) -> bool:
    try:
        socket.create_connection((HOST, port), timeout=0.2).close()
    except OSError:
        return False
    return True


class WebViewer:
    """A `rerun` child process serving recordings read by `viz.recording.load_recording`
    (see the module docstring; the parts of a resumed run are served together).

    `start()` returns once both ports accept connections and the recording is sent to the
    server; `url` is the page to open;
    `stop()` ends the child (SIGTERM, then SIGKILL after `grace` s). Also a context manager.
    The server buffers the recordings in memory: the limit is 4x the files' size, at least
    1 GiB (rerun drops the oldest data beyond it).
    """

    def __init__(self, recordings: list[Recording], web_port: int = WEB_PORT, grpc_port: int = GRPC_PORT):
        self.recordings = recordings
        self.web_port, self.grpc_port = web_port, grpc_port
        self.process: subprocess.Popen | None = None
        self._log = None

    @property
    def grpc_url(self) -> str:
        return f"rerun+http://{HOST}:{self.grpc_port}/proxy"

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.web_port}/?url={quote(self.grpc_url, safe='')}"

    def command(self) -> list[str]:
        size = sum(Path(r.path).stat().st_size for r in self.recordings)
        limit_gib = max(1, -(-4 * size // 2**30))
        return [str(rerun_executable()), "--serve-web", "--bind", HOST, "--web-viewer-port", str(self.web_port),
                "--port", str(self.grpc_port), "--server-memory-limit", f"{limit_gib}GiB"]

    def start(self, timeout: float = 30.0) -> "WebViewer":
        """Start serving. Raises ConnectionError if a port is taken, RuntimeError if the
        child exits or does not listen within `timeout` s (with its last output line)."""
        if self.web_port == self.grpc_port:
            raise ConnectionError(f"the web viewer and the gRPC server need two ports, both are {self.web_port}")
        for what, port in (("web viewer", self.web_port), ("gRPC", self.grpc_port)):
            if port_in_use(port):
                raise ConnectionError(f"{what} port {port} on {HOST} is in use (choose another)")
        self._log = tempfile.TemporaryFile()  # rerun's chatter, shown only if it fails
        self.process = subprocess.Popen(self.command(), stdin=subprocess.DEVNULL, stdout=self._log,
                                        stderr=subprocess.STDOUT, preexec_fn=_die_with_parent)
        deadline = time.monotonic() + timeout
        while not (_listening(self.web_port) and _listening(self.grpc_port)):
            if self.process.poll() is not None:
                raise RuntimeError(f"rerun exited with status {self.process.returncode}: {self._last_line()}")
            if time.monotonic() > deadline:
                last = self._last_line()
                self.stop()
                raise RuntimeError(f"rerun did not start serving within {timeout:g} s: {last}")
            time.sleep(0.05)
        import rerun as rr  # here: `garment --help` imports this module to build its parser

        from .recording import replay

        for r in self.recordings:
            # Under the file's own ids: the viewer lists the file's recording, not also the replay's.
            replay(r.path, rr.GrpcSink(self.grpc_url), r.application_id, r.recording_id)
        return self

    def _last_line(self) -> str:
        self._log.seek(0)
        lines = [ln for ln in self._log.read().decode(errors="replace").splitlines() if ln.strip()]
        return lines[-1].strip() if lines else "no output"

    def wait(self) -> int:
        """Block until the child exits (it serves until stopped); its exit status."""
        return self.process.wait()

    def stop(self, grace: float = 5.0) -> None:
        """End the child and wait for it. Idempotent."""
        p = self.process
        if p is not None and p.poll() is None:
            p.terminate()
            try:
                p.wait(grace)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        if self._log is not None:
            self._log.close()
            self._log = None

    def __enter__(self) -> "WebViewer":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
