"""Self-contained static HTML replay (no server, no network).

meshcat 0.3.2's ``Visualizer.static_html()`` asks a running ZMQ server for the scene, so it
cannot work offline. Instead we record the meshcat commands in-process with a stand-in
window, msgpack them exactly as the server would forward them to a browser, and write them
together with meshcat's own bundled viewer script (``viewer/dist/main.min.js``, inlined)
into one HTML file. The browser then feeds each command to
``viewer.handle_command_bytearray`` in order, which is what the websocket path does.
"""
from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import meshcat
import umsgpack

from ..output_files import write_atomic
from ..solver.result import Result
from .scene import MAX_MESH_MB, build_scene

_VIEWER_JS = Path(meshcat.__file__).resolve().parent / "viewer" / "dist" / "main.min.js"

# Ids of the two non-visual script blocks; the tests and animation_frame_count read them.
COMMANDS_ID = "geoddp-commands"
STATUS_ID = "geoddp-status"


class _RecordingWindow:
    """Stand-in for ``meshcat.visualizer.ViewerWindow`` that keeps the commands."""

    web_url = None
    server_proc = None

    def __init__(self) -> None:
        self.commands: list[bytes] = []

    def send(self, command) -> None:
        # Same encoding as ViewerWindow.send's third frame, which the server forwards verbatim.
        self.commands.append(umsgpack.packb(command.lower()))

    def close(self) -> None:
        pass


def record_scene(result: Result, scale: float = 1.0, **options) -> list[bytes]:
    """msgpack-encoded meshcat commands that build the scene and set the animation.

    Args:
        result: any Result (see :func:`geoddp.viz.scene.build_scene`).
        scale: uniform size factor of the drawing.
        options: ``geometry``, ``trail``, ``max_mesh_mb`` of :func:`geoddp.viz.scene.build_scene`.

    Returns:
        One bytes object per command, in the order they must be applied.
    """
    window = _RecordingWindow()
    vis = meshcat.Visualizer(window=window)
    build_scene(vis, result, scale=scale, play=True, **options)
    return window.commands


def _script_safe(text: str) -> str:
    # Inside <script>, "</script" (any case) would end the block early; "<\/" means the same
    # in JS strings and regexes. (meshcat 0.3.2's bundle contains none; this is a guard.)
    return re.sub(r"</(script)", r"<\\/\1", text, flags=re.IGNORECASE)


_TEMPLATE = """<!DOCTYPE html>
<html>
<head>
<meta charset="utf-8">
<title>{title}</title>
<style>
body {{ margin: 0; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<pre id="{status_id}" style="display:none">{{"loaded": false}}</pre>
<script type="application/json" id="{commands_id}">{commands_json}</script>
<script>
{viewer_js}
</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
(function () {{
  function bytes(b64) {{
    var s = atob(b64), a = new Uint8Array(s.length);
    for (var i = 0; i < s.length; i++) a[i] = s.charCodeAt(i);
    return a;
  }}
  // Synchronous and in order (meshcat's own static page uses fetch(), whose callbacks
  // are not guaranteed to run in order).
  var cmds = JSON.parse(document.getElementById("{commands_id}").textContent);
  for (var i = 0; i < cmds.length; i++) viewer.handle_command_bytearray(bytes(cmds[i]));
  // Report what the viewer actually loaded, for headless tests (--dump-dom).
  var frames = viewer.animator.actions.map(function (a) {{
    return a.getClip().tracks.map(function (t) {{ return t.times.length; }});
  }});
  // "#t=SECONDS" in the address: pause there (any instant of the replay, e.g. for screenshots);
  // the Animations panel (play, pause, reset, time scrubber) does the same by hand.
  var seek = /[#&]t=([0-9.eE+-]+)/.exec(location.hash);
  if (seek) {{
    viewer.animator.pause();
    viewer.animator.seek(parseFloat(seek[1]));
    viewer.animator.display_progress(parseFloat(seek[1]));
  }}
  var panel = viewer.animator.folder.__folders["default"];
  var controls = panel ? panel.__controllers.map(function (c) {{ return c.property; }}) : [];
  document.getElementById("{status_id}").textContent = JSON.stringify({{
    loaded: true, commands: cmds.length, frames: frames, duration: viewer.animator.duration,
    controls: controls, seek: seek ? parseFloat(seek[1]) : null
  }});
}})();
</script>
</body>
</html>
"""


def render_html(result: Result, scale: float = 1.0, title: str = "geoddp replay", **options) -> str:
    """The self-contained HTML page as a string (see :func:`export_html`; ``options``:
    ``geometry``, ``trail``, ``max_mesh_mb``)."""
    commands = [base64.b64encode(c).decode("ascii") for c in record_scene(result, scale=scale, **options)]
    return _TEMPLATE.format(
        title=title.replace("<", "&lt;"),
        status_id=STATUS_ID,
        commands_id=COMMANDS_ID,
        commands_json=json.dumps(commands),  # base64 and JSON punctuation only: script-safe
        viewer_js=_script_safe(_VIEWER_JS.read_text(encoding="utf-8")),
    )


def export_html(result: Result, path: str | Path, scale: float = 1.0, *, geometry: str = "visual",
                trail: str | None = None, max_mesh_mb: float | None = MAX_MESH_MB,
                plan: Result | None = None) -> Path:
    """Write a self-contained static HTML replay of ``result`` to ``path``.

    The file embeds meshcat's three.js viewer, the recorded scene commands and every mesh file
    they draw, so it opens from disk with no server and no network. The page shows the result's
    model (the multibody model of the solve, or the built-in satellite: bus, panels, body axes),
    every URDF visual (primitive, or DAE/STL/OBJ mesh with its scale and colour) placed by forward
    kinematics at q_k, the target pose as a translucent ghost, frame targets as triads, an
    optional trail, with the camera framing the whole trajectory, in an animation of H+1
    keyframes at fps = 1/dt (play/pause/reset/time scrubber under "Animations" in the control
    panel; ``page.html#t=1.5`` opens paused at t = 1.5 s). See
    :func:`geoddp.viz.scene.build_scene`.

    Args:
        result: any Result: reads ``multibody`` (URDF, root, ``package_dirs``), ``configurations
            (H+1, nq)`` or ``rotations (H+1, 3, 3)``, ``target_rotation (3, 3)``, ``dt`` (s) and
            ``frame_targets`` (in ``multibody`` or ``extra``).
        path: output file; parent directories are created.
        scale: uniform size factor of the drawing (1.0: the URDF's size in metres).
        geometry: "visual" or "collision" (the URDF's collision geometry: usually much smaller).
        trail: None, "root" or a frame name: draw the path of the root body or of that frame.
        max_mesh_mb: refuse (InputError naming ``max_mesh_mb``, with the sizes and the
            ``geometry="collision"`` alternative) to embed more mesh data than this many MB
            (default 20); None: no limit.
        plan: the plan a simulated run flew (``SimulationResult.to_result(plan)`` as ``result``):
            drawn as an animated translucent ghost beside the run.

    Returns:
        The path written (nothing is written when an InputError is raised).
    """
    extra = {} if plan is None else {"plan": plan}
    text = render_html(result, scale=scale, geometry=geometry, trail=trail, max_mesh_mb=max_mesh_mb, **extra)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, text)  # temp file + rename: a kill never leaves a partial page
    return path


def decode_commands(html_text: str) -> list[dict]:
    """The meshcat commands embedded in a page written by :func:`export_html`, decoded."""
    m = re.search(
        r'<script type="application/json" id="%s">(.*?)</script>' % re.escape(COMMANDS_ID),
        html_text,
        flags=re.DOTALL,
    )
    if m is None:
        raise ValueError("no geoddp command block in this HTML (not written by export_html?)")
    return [umsgpack.unpackb(base64.b64decode(c)) for c in json.loads(m.group(1))]


def animation_frame_count(html_text: str) -> int:
    """Number of animation keyframes in an exported page.

    Reads the ``set_animation`` command embedded by :func:`export_html` and counts the keys of
    its clips' tracks (one clip per visual object of the model), which must all agree.

    Args:
        html_text: contents of the HTML file.

    Returns:
        The keyframe count, H+1 for a trajectory with horizon H.

    Raises:
        ValueError: no animation, no clip, or tracks of unequal length.
    """
    anims = [c for c in decode_commands(html_text) if c.get("type") == "set_animation"]
    if not anims:
        raise ValueError("the page contains no set_animation command")
    # The last set_animation wins in the viewer (Animator.load clears earlier ones).
    entries = anims[-1]["animations"]
    if not entries:
        raise ValueError("the animation has no clip")
    counts = {len(track["keys"]) for e in entries for track in e["clip"]["tracks"]}
    if len(counts) != 1:
        raise ValueError(f"animated tracks disagree on the keyframe count: {sorted(counts)}")
    return counts.pop()
