"""`garment view RUN.rrd`: the recording served in Rerun's web viewer on 127.0.0.1, seen
by headless Chromium; signals stop it cleanly; bad input gets one line and exit 2."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from garment.cli import main
from sim.sinks import Frame, MeshTopology
from viz.rerun_sink import RerunSink
from viz.web_viewer import port_in_use

from tests.support import browser
from tests.support.meshes import MESHES, grid_topology, positions
from tests.support.paths import ROOT

PLATE = MeshTopology("plate", grid_topology("p", 3, 3).faces, np.zeros((0, 2)), np.zeros((0, 2)), kind="body")


@pytest.fixture(scope="module")
def rrd(tmp_path_factory):
    """Two waving cloth pieces over a still plate, 8 frames."""
    path = tmp_path_factory.mktemp("view") / "run.rrd"
    sink = RerunSink(path)
    sink.open([*MESHES, PLATE])
    plate = grid_topology("p", 3, 3).rest * 0.4 - 0.02
    plate = np.column_stack([plate, np.full(len(plate), -0.05)])
    for k in range(8):
        sink.write(Frame(k, k * 0.04, {m.name: positions(m, k) for m in MESHES} | {PLATE.name: plate}))
    sink.close()
    return path


def free_ports(n: int) -> list[int]:
    """n ports nothing listens on now (the OS's picks, released again)."""
    socks = [socket.socket() for _ in range(n)]
    for s in socks:
        s.bind(("127.0.0.1", 0))
    ports = [s.getsockname()[1] for s in socks]
    for s in socks:
        s.close()
    return ports


def _ctrl_c_stops() -> None:
    """In the child: SIGINT as at a terminal. A shell starts background jobs (pytest run
    with `&`) with SIGINT ignored, and Python keeps an ignored SIGINT ignored."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start_view(rrds, web: int, grpc: int) -> tuple[subprocess.Popen, str]:
    """`garment view` in a subprocess; returns it and the URL it printed."""
    env = dict(os.environ, NUMBA_CACHE_DIR=os.environ.get("NUMBA_CACHE_DIR", ".cache/numba"))
    proc = subprocess.Popen([sys.executable, "-m", "garment.cli", "view", *map(str, rrds), "--port", str(web),
                             "--grpc-port", str(grpc)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env, cwd=ROOT, preexec_fn=_ctrl_c_stops)
    url = proc.stdout.readline().strip()  # printed once serving; EOF if it failed
    assert url, proc.communicate(timeout=30)[1]
    return proc, url


def stop(proc: subprocess.Popen, sig: int) -> str:
    proc.send_signal(sig)
    try:
        _, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()  # not left serving after the test
        raise
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "stopped serving" in err
    return err


def listening_on(port: int) -> set[str]:
    """Local addresses of the TCP sockets listening on `port` (Linux: /proc/net/tcp, tcp6)."""
    found = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with open(table) as f:
            for line in f.readlines()[1:]:
                local, state = line.split()[1], line.split()[3]
                address, hex_port = local.rsplit(":", 1)
                if state == "0A" and int(hex_port, 16) == port:  # 0A: LISTEN
                    found.add(socket.inet_ntop(socket.AF_INET, bytes.fromhex(address)[::-1])
                              if len(address) == 8 else "ipv6:" + address)
    return found


def cloth_fraction(rgb: np.ndarray) -> float:
    """Share of pixels in the cloth's blue (viz.rerun_sink.COLORS, shaded)."""
    r, g, b = (rgb[..., i].astype(int) for i in range(3))
    return float(((b - r > 60) & (b - g > 30)).mean())


@pytest.mark.skipif(browser.CHROMIUM is None, reason="needs Debian's chromium (scripts/setup.sh installs it)")
def test_the_browser_shows_the_cloth_and_ctrl_c_stops_it(rrd, tmp_path):
    web, grpc = free_ports(2)
    proc, url = start_view([rrd], web, grpc)
    try:
        assert url == f"http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc}%2Fproxy"
        assert listening_on(web) == listening_on(grpc) == {"127.0.0.1"}  # this machine only
        rgb, seconds = browser.screenshots(url, (1024, 640), lambda im: cloth_fraction(im) > 0.01)
    finally:
        err = stop(proc, signal.SIGINT)
    from PIL import Image

    Image.fromarray(rgb).save(tmp_path / "view.png")
    # Not blank, and the cloth is on the page (the viewer's own UI has almost no blue).
    assert rgb.std() > 10 and len(np.unique(rgb.reshape(-1, 3), axis=0)) > 200
    assert cloth_fraction(rgb) > 0.01, f"no cloth after {seconds:.1f} s; see {tmp_path / 'view.png'}"
    assert "8 frames" in err
    assert not port_in_use(web) and not port_in_use(grpc)  # the server is gone


def test_sigterm_stops_it(rrd, tmp_path):
    """Also two files, as a resumed run's parts are served."""
    part2 = tmp_path / "run.part2.rrd"
    part2.write_bytes(rrd.read_bytes())
    web, grpc = free_ports(2)
    proc, _ = start_view([rrd, part2], web, grpc)
    err = stop(proc, signal.SIGTERM)
    assert f"serving {rrd} (8 frames" in err and f"serving {part2} (8 frames" in err
    deadline = time.monotonic() + 5
    while port_in_use(web) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not port_in_use(web) and not port_in_use(grpc)


def test_bad_input(rrd, tmp_path, capsys):
    def fails(argv, fragment):
        assert main(["view", *argv]) == 2
        err = capsys.readouterr().err
        assert fragment in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err

    fails([str(tmp_path / "missing.rrd")], "no such file")
    (tmp_path / "notes.rrd").write_text("not a recording\n")
    fails([str(tmp_path / "notes.rrd")], "not a readable Rerun recording")
    fails([str(rrd), "--port", "70000"], "--port")
    web, grpc = free_ports(2)
    fails([str(rrd), "--port", str(web), "--grpc-port", str(web)], "two ports")
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", web))
        busy.listen()
        fails([str(rrd), "--port", str(web), "--grpc-port", str(grpc)], f"port {web}")
