"""Live, time-synchronised replay of a Result in a meshcat browser viewer.

The server is meshcat's own ZMQ/websocket bridge, started as a subprocess bound to
127.0.0.1 (see ``_loopback_server.py``). Everything that talks to it has a timeout: meshcat
0.3.2's ``start_zmq_server_as_subprocess`` blocks on ``readline()`` and its
``ViewerWindow`` blocks on ``recv()`` forever when no server answers, so neither is used
directly for the parts that can hang.
"""
from __future__ import annotations

import atexit
import collections
import os
import queue
import subprocess
import sys
import threading
import time
import webbrowser
from pathlib import Path

import meshcat
import zmq
from meshcat.visualizer import ViewerWindow

from ..solver.result import Result
from ..validate import positive_float
from .scene import MAX_MESH_MB, build_satellite, build_scene, prepare_scene

__all__ = ["ViewerUnavailable", "build_satellite", "replay", "stop_servers"]

_SERVERS: list[subprocess.Popen] = []  # every server this process started and has not stopped


def stop_servers() -> list[int]:
    """Stop (terminate, then kill, and reap) every meshcat server this process started; returns
    their PIDs. The CLI calls it on SIGINT, SIGTERM and SIGHUP; atexit calls it too."""
    pids = []
    while _SERVERS:
        proc = _SERVERS.pop()
        pids.append(proc.pid)
        _stop_process(proc)
    return pids

_SERVER_SCRIPT = Path(__file__).with_name("_loopback_server.py")
# Run the script by path but without its directory (or the cwd) on sys.path: this package's
# html.py would otherwise shadow the standard library's html module inside tornado.
_LAUNCH = (
    "import runpy, sys; sys.path[:] = [p for p in sys.path if p not in ('', '.')]; "
    "runpy.run_path(sys.argv[1], run_name='__main__')"
)
DEFAULT_TIMEOUT_S = 5.0


class ViewerUnavailable(RuntimeError):
    """The meshcat server could not be started or reached (message says why)."""


def _stop_process(proc: subprocess.Popen | None, timeout_s: float = 3.0) -> None:
    """Terminate, then kill if needed, and reap. Safe to call twice."""
    if proc is None or proc.poll() is not None:
        return
    proc.terminate()
    try:
        proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=timeout_s)


def _drain(stream, sink) -> None:
    """Read a pipe line by line until EOF so the server never blocks on a full pipe."""
    for raw in iter(stream.readline, b""):
        sink(raw.decode("utf-8", "replace").rstrip("\n"))
    stream.close()


def _start_server(timeout_s: float) -> tuple[subprocess.Popen, str, str]:
    """Start the loopback meshcat server; return (process, zmq_url, web_url).

    Raises ViewerUnavailable (after killing the process) when it exits early or has not
    printed both URLs within ``timeout_s`` seconds.
    """
    env = dict(os.environ)
    # The server script imports meshcat: make the directory holding it importable even when
    # meshcat was put on sys.path by hand (same precaution as meshcat's own launcher).
    site = str(Path(meshcat.__file__).resolve().parent.parent)
    env["PYTHONPATH"] = os.pathsep.join([site] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    try:
        proc = subprocess.Popen(
            [sys.executable, "-u", "-c", _LAUNCH, str(_SERVER_SCRIPT)],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=env,
            start_new_session=True,  # a Ctrl-C in the caller's terminal must not kill it mid-send
        )
    except OSError as exc:
        raise ViewerUnavailable(f"could not launch the meshcat server process: {exc}") from exc

    lines: queue.Queue[str] = queue.Queue()
    stderr_tail: collections.deque[str] = collections.deque(maxlen=40)
    threading.Thread(target=_drain, args=(proc.stdout, lines.put), daemon=True).start()
    threading.Thread(target=_drain, args=(proc.stderr, stderr_tail.append), daemon=True).start()

    urls: dict[str, str] = {}
    deadline = time.monotonic() + timeout_s
    while not {"zmq_url", "web_url"} <= urls.keys():
        remaining = deadline - time.monotonic()
        if proc.poll() is not None or remaining <= 0:
            # Give the stderr thread a moment to collect the traceback before reporting it.
            time.sleep(0.2)
            _stop_process(proc)
            why = (
                f"exited with code {proc.returncode}"
                if remaining > 0
                else f"printed no URLs within {timeout_s:g} s"
            )
            tail = "\n".join(list(stderr_tail)[-15:]) or "(no stderr)"
            raise ViewerUnavailable(f"the meshcat server {why}. Its stderr:\n{tail}")
        try:
            line = lines.get(timeout=min(remaining, 0.1))
        except queue.Empty:
            continue
        key, sep, value = line.partition("=")
        if sep and key in ("zmq_url", "web_url"):
            urls[key] = value
    _SERVERS.append(proc)
    atexit.register(_stop_process, proc)  # do not leave a server behind at interpreter exit
    return proc, urls["zmq_url"], urls["web_url"]


class TimeoutWindow(ViewerWindow):
    """``ViewerWindow`` whose every ZMQ exchange times out instead of hanging.

    A timed-out or failed exchange raises :class:`ViewerUnavailable`. ``close()`` closes the
    socket and stops the server process if this window started it.
    """

    def __init__(
        self,
        zmq_url: str,
        web_url: str | None = None,
        server_proc: subprocess.Popen | None = None,
        timeout_s: float = DEFAULT_TIMEOUT_S,
    ) -> None:
        # Deliberately not calling ViewerWindow.__init__: it starts servers and recv()s
        # without timeouts.
        self.zmq_url = zmq_url
        self.server_proc = server_proc
        self.timeout_ms = max(1, int(timeout_s * 1000))
        self.zmq_socket = None
        try:
            self.connect_zmq()
        except zmq.ZMQError as exc:
            self.close()
            raise ViewerUnavailable(f"invalid meshcat zmq_url {zmq_url!r}: {exc}") from exc
        if web_url is None:
            web_url = self.request_web_url()
            # meshcat reconnects after asking for the URL: the server's receive callback
            # otherwise misbehaves once a browser connects (see ViewerWindow.__init__).
            self.connect_zmq()
        self.web_url = web_url

    def connect_zmq(self) -> None:
        if self.zmq_socket is not None:
            self.zmq_socket.close(linger=0)
        sock = self.context.socket(zmq.REQ)
        sock.setsockopt(zmq.LINGER, 0)  # closing must never wait for unsent messages
        sock.setsockopt(zmq.RCVTIMEO, self.timeout_ms)
        sock.setsockopt(zmq.SNDTIMEO, self.timeout_ms)
        self.zmq_socket = sock
        sock.connect(self.zmq_url)

    def _exchange(self, what: str, fn):
        try:
            return fn()
        except zmq.ZMQError as exc:
            # A REQ socket that missed its reply is stuck; replace it so the window stays usable
            # if the server comes back.
            try:
                self.connect_zmq()
            except zmq.ZMQError:
                pass
            cause = (
                f"no reply within {self.timeout_ms / 1000:g} s"
                if isinstance(exc, zmq.Again)
                else f"ZMQ error: {exc}"
            )
            raise ViewerUnavailable(f"meshcat server at {self.zmq_url} unreachable during {what}: {cause}") from exc

    def request_web_url(self) -> str:
        return self._exchange("URL request", super().request_web_url)

    def send(self, command) -> None:
        return self._exchange(command.lower().get("type", "send"), lambda: super(TimeoutWindow, self).send(command))

    def get_scene(self) -> str:
        return self._exchange("get_scene", super().get_scene)

    def close(self) -> None:
        """Close the socket and stop the server process if this window owns one."""
        if self.zmq_socket is not None:
            self.zmq_socket.close(linger=0)
            self.zmq_socket = None
        _stop_process(self.server_proc)


def replay(
    result: Result,
    vis: meshcat.Visualizer | None = None,
    open_browser: bool = False,
    zmq_url: str | None = None,
    *,
    scale: float = 1.0,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    geometry: str = "visual",
    trail: str | None = None,
    max_mesh_mb: float | None = MAX_MESH_MB,
    contacts=None,
) -> meshcat.Visualizer:
    """Show ``result`` in a meshcat viewer as an animation synchronised with its time.

    The scene is the result's model rebuilt from its URDF visuals (the multibody model of the
    solve, or for a satellite result the built-in satellite: bus, two solar panels,
    red/green/blue body axes), each object placed by forward kinematics at q_k (root position and
    orientation and every joint), and the target pose as a translucent ghost
    (:func:`geoddp.viz.scene.build_scene`). The animation has one keyframe per time step, played
    at fps = 1/dt, with play/pause/scrub under "Animations" in the viewer's controls.

    Args:
        result: any Result: reads ``multibody``, ``configurations (H+1, nq)`` or
            ``rotations (H+1, 3, 3)``, ``target_rotation (3, 3)`` and ``dt`` (s).
        vis: an existing visualizer to draw into (no server is started).
        open_browser: open the viewer URL in the default web browser.
        zmq_url: reuse the meshcat server listening at this ZMQ URL
            (e.g. ``"tcp://127.0.0.1:6000"``) instead of starting one.
        scale: uniform size factor of the drawing (1.0: the URDF's size in metres).
        timeout_s: bound in seconds on server start-up and on every ZMQ round trip.
        geometry: "visual" or "collision" (draw the URDF's collision geometry instead).
        trail: None, "root" or a frame name: draw the path of the root body or of that frame.
        max_mesh_mb: largest mesh data (MB) to send, None for no limit (see
            :func:`geoddp.viz.scene.check_mesh_size`).
        contacts: a legged trajectory's ground, contact points and force arrows
            (:class:`geoddp.viz.contact_shapes.ContactScene`; :func:`geoddp.viz.legged.replay_legged`
            builds it from the problem).

    Returns:
        The visualizer. When this call started the server, ``vis.close()`` stops it (it is
        also stopped at interpreter exit); ``vis.window.server_proc`` is the process.

    Raises:
        ViewerUnavailable: the server could not be started, or did not answer in time, or
            ``zmq_url`` is invalid. A server started here is stopped before raising.
        ValueError: malformed ``result`` (:class:`geoddp.validate.InputError` naming the field),
            ``scale`` not positive, or both ``vis`` and ``zmq_url`` given.
    """
    options = dict(geometry=geometry, trail=trail, max_mesh_mb=max_mesh_mb)
    prepared = prepare_scene(result, **options)  # before any server exists, so bad data never leaks a process
    scale = positive_float(scale, "scale")
    if vis is not None and zmq_url is not None:
        raise ValueError("give either vis or zmq_url, not both")
    owned = vis is None  # we created the window (and maybe the server): we clean it up
    if vis is None:
        if zmq_url is not None:
            window = TimeoutWindow(zmq_url, timeout_s=timeout_s)
        else:
            proc, url, web_url = _start_server(timeout_s)
            try:
                window = TimeoutWindow(url, web_url=web_url, server_proc=proc, timeout_s=timeout_s)
            except BaseException:
                _stop_process(proc)
                raise
        vis = meshcat.Visualizer(window=window)
    try:
        build_scene(vis, result, scale=scale, play=True, prepared=prepared, contacts=contacts)
    except BaseException as exc:
        if owned:
            vis.window.close()  # stops a server started here; a user's server is left alone
        if isinstance(exc, zmq.ZMQError):
            raise ViewerUnavailable(f"sending the scene to meshcat failed: {exc}") from exc
        raise
    url = vis.url()
    print(f"meshcat viewer: {url}", flush=True)
    if open_browser and url:
        webbrowser.open(url, new=2)
    return vis
