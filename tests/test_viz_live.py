"""Live meshcat viewer: loopback server, ZMQ round trips, clean shutdown, bounded failures."""
from __future__ import annotations

import base64
import re
import socket
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pytest

from geoddp.viz import ViewerUnavailable, meshcat_replay, replay  # first: silences meshcat's import warning
import meshcat.geometry as g  # noqa: E402
import umsgpack  # noqa: E402

from geoddp.viz.scene import BACKGROUND_RGB, ROBOT, SHAPE
from geoddp.validate import InputError
from viz_fixtures import changed_fraction, chromium_or_skip, screenshot, synthetic_result

LOOPBACK_HEX = "0100007F"  # 127.0.0.1 as /proc/net/tcp writes it


def listening_addresses(port: int) -> set[str]:
    """Hex IPv4 addresses with a LISTEN socket on ``port`` (Linux /proc/net/tcp)."""
    found = set()
    with open("/proc/net/tcp") as f:
        next(f)
        for line in f:
            local, state = line.split()[1], line.split()[3]
            ip, p = local.split(":")
            if state == "0A" and int(p, 16) == port:
                found.add(ip)
    return found


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def live():
    """(visualizer, result) with a fresh server; the server is stopped afterwards regardless."""
    result = synthetic_result(horizon=24, dt=0.05)
    vis = replay(result, timeout_s=10)
    try:
        yield vis, result
    finally:
        vis.close()


def test_server_on_loopback_answers_and_stops(live, capsys):
    vis, result = live
    proc = vis.window.server_proc
    assert proc is not None and proc.poll() is None
    assert re.fullmatch(r"http://127\.0\.0\.1:\d+/static/", vis.url())
    assert re.fullmatch(r"tcp://127\.0\.0\.1:\d+", vis.window.zmq_url)
    capsys.readouterr()
    assert replay(result, vis=vis) is vis  # re-sending into a given visualizer works
    assert vis.url() in capsys.readouterr().out  # and the URL is printed for the user

    # Both sockets listen on loopback only (meshcat's stock server listens on all
    # interfaces for HTTP).
    web_port = int(vis.url().split(":")[2].split("/")[0])
    zmq_port = int(vis.window.zmq_url.rsplit(":", 1)[1])
    if sys.platform.startswith("linux"):
        assert listening_addresses(web_port) == {LOOPBACK_HEX}
        assert listening_addresses(zmq_port) == {LOOPBACK_HEX}

    # HTTP: the viewer page is served.
    with urllib.request.urlopen(vis.url(), timeout=5) as resp:
        assert resp.status == 200 and b"MeshCat" in resp.read()

    # ZMQ round trip: set_object gets its "ok" (send() returns only after the reply).
    t0 = time.monotonic()
    vis["probe"].set_object(g.Sphere(0.05))
    assert time.monotonic() - t0 < 5

    # The server holds the scene we sent: ask it back (get_scene) and decode the animation.
    html = vis.static_html()
    blobs = re.findall(r'base64,([A-Za-z0-9+/=]+)"', html)
    cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]
    paths = {c.get("path") for c in cmds if c["type"] == "set_object"}
    assert "/meshcat/probe" in paths and f"/meshcat/{ROBOT}/bus_0/{SHAPE}" in paths
    (anim,) = [c for c in cmds if c["type"] == "set_animation"]
    # one clip per visual of satellite.urdf (bus, two panels, three axes), each with H+1 keys
    clips = {a["path"]: a["clip"] for a in anim["animations"]}
    assert set(clips) == {f"/meshcat/{ROBOT}/bus_{i}" for i in range(6)}
    for clip in clips.values():
        assert {len(t["keys"]) for t in clip["tracks"]} == {result.horizon + 1}
        assert clip["fps"] == pytest.approx(1 / result.dt)

    vis.close()
    assert proc.wait(timeout=5) is not None and proc.poll() is not None
    assert listening_addresses(web_port) == set() if sys.platform.startswith("linux") else True


def test_live_viewer_renders_in_browser(live, tmp_path):
    chromium_or_skip()
    vis, _ = live
    img = screenshot(vis.url(), tmp_path / "live.png")
    background = np.round(255 * np.asarray(BACKGROUND_RGB)).astype(int)
    assert changed_fraction(img, background) > 0.02


def test_reuses_running_server_via_zmq_url(live):
    vis, result = live
    other = replay(result, zmq_url=vis.window.zmq_url, timeout_s=5)
    try:
        assert other.url() == vis.url()
        assert other.window.server_proc is None  # nothing started
    finally:
        other.close()
    assert vis.window.server_proc.poll() is None  # closing a client leaves the server alone


def test_unreachable_zmq_url_fails_fast():
    result = synthetic_result(horizon=5)
    url = f"tcp://127.0.0.1:{free_port()}"  # nobody listens here
    t0 = time.monotonic()
    with pytest.raises(ViewerUnavailable, match="no reply within"):
        replay(result, zmq_url=url, timeout_s=1.0)
    assert time.monotonic() - t0 < 5


def test_invalid_zmq_url_fails():
    with pytest.raises(ViewerUnavailable, match="invalid meshcat zmq_url"):
        replay(synthetic_result(horizon=5), zmq_url="not-a-url", timeout_s=1.0)


class _RecordingPopen(subprocess.Popen):
    started: list[subprocess.Popen] = []

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        _RecordingPopen.started.append(self)


@pytest.mark.parametrize(
    "script, match",
    [
        ("import sys; print('boom', file=sys.stderr); sys.exit(3)", r"exited with code 3(.|\n)*boom"),
        ("import time; print('starting', flush=True); time.sleep(60)", r"printed no URLs within 1 s"),
    ],
    ids=["server-crashes", "server-hangs"],
)
def test_server_start_failure_is_reported_and_cleaned_up(tmp_path, monkeypatch, script, match):
    fake = tmp_path / "fake_server.py"
    fake.write_text(script)
    monkeypatch.setattr(meshcat_replay, "_SERVER_SCRIPT", fake)
    _RecordingPopen.started = []
    monkeypatch.setattr(meshcat_replay.subprocess, "Popen", _RecordingPopen)
    t0 = time.monotonic()
    with pytest.raises(ViewerUnavailable, match=match):
        replay(synthetic_result(horizon=5), timeout_s=1.0)
    assert time.monotonic() - t0 < 8
    (proc,) = _RecordingPopen.started
    assert proc.poll() is not None  # no orphan server left behind


def test_bad_result_starts_no_server(monkeypatch):
    _RecordingPopen.started = []
    monkeypatch.setattr(meshcat_replay.subprocess, "Popen", _RecordingPopen)
    bad = synthetic_result(horizon=5)
    bad.rotations = bad.rotations[:-1]
    with pytest.raises(InputError, match=r"^result\.rotations: expected shape \(H\+1, 3, 3\) = \(6, 3, 3\)"):
        replay(bad)
    assert _RecordingPopen.started == []
