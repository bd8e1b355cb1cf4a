"""Self-contained static HTML replay (no server, no network).

meshcat 0.3.2's ``Visualizer.static_html()`` asks a running ZMQ server for the scene, so it
cannot work offline. Instead we record the meshcat commands in-process with a stand-in
window, msgpack them exactly as the server would forward them to a browser, and write them
together with meshcat's own bundled viewer script (``viewer/dist/main.min.js``, inlined)
into one HTML file. The browser then feeds each command to
``viewer.handle_command_bytearray`` in order, which is what the websocket path does.

Each mesh is embedded once: a byte string of at least CHUNK_MIN_BYTES that several commands carry
(a mesh file drawn by several objects, as a legged robot's four feet, or again for the target ghost
or a plan's ghost) is stored once in a table of chunks, and those commands as their other bytes
around references into it; the page joins them back before handing each command to the viewer,
which receives exactly the bytes it would have received. A page with no repeated mesh has no
table and is the page this module always wrote.
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

# Ids of the non-visual script blocks; the tests and animation_frame_count read them.
COMMANDS_ID = "geoddp-commands"
STATUS_ID = "geoddp-status"
CHUNKS_ID = "geoddp-chunks"
#: Smallest payload (bytes) stored once in the chunk table when several commands carry it.
CHUNK_MIN_BYTES = 1024


class _RecordingWindow:
    """Stand-in for ``meshcat.visualizer.ViewerWindow`` that keeps the commands, and the large
    byte strings (mesh data) each one carries."""

    web_url = None
    server_proc = None

    def __init__(self) -> None:
        self.commands: list[bytes] = []
        self.payloads: list[list[bytes]] = []

    def send(self, command) -> None:
        # Same encoding as ViewerWindow.send's third frame, which the server forwards verbatim.
        lowered = command.lower()
        self.commands.append(umsgpack.packb(lowered))
        self.payloads.append(_large_payloads(lowered))

    def close(self) -> None:
        pass


def _large_payloads(x) -> list[bytes]:
    """The byte strings of at least CHUNK_MIN_BYTES inside a lowered command, as they appear in its
    msgpack bytes (an extension's data, a binary, a text's UTF-8), in document order."""
    if isinstance(x, umsgpack.Ext):
        return [x.data] if len(x.data) >= CHUNK_MIN_BYTES else []
    if isinstance(x, (bytes, bytearray)):
        return [bytes(x)] if len(x) >= CHUNK_MIN_BYTES else []
    if isinstance(x, str):
        return [x.encode("utf-8")] if len(x) >= CHUNK_MIN_BYTES else []
    if isinstance(x, dict):
        return [p for v in x.values() for p in _large_payloads(v)]
    if isinstance(x, (list, tuple)):
        return [p for v in x for p in _large_payloads(v)]
    return []


def chunked(commands: list[bytes], payloads: list[list[bytes]]) -> tuple[list[bytes], list[bytes | list]]:
    """Store each payload several commands carry once: (chunks, entries), an entry being the
    command's bytes when it carries no shared payload, else the list of its pieces in order: bytes
    around int indices into ``chunks``. Joining an entry's pieces gives the command back."""
    count: dict[bytes, int] = {}
    for ps in payloads:
        for p in ps:
            count[p] = count.get(p, 0) + 1
    index: dict[bytes, int] = {}
    chunks: list[bytes] = []
    entries: list[bytes | list] = []
    for cmd, ps in zip(commands, payloads):
        shared = [p for p in ps if count[p] > 1]
        if not shared:
            entries.append(cmd)
            continue
        pieces: list = []
        at = 0
        for p in shared:
            k = cmd.find(p, at)
            if k < 0:  # not where msgpack should have put it: keep the command whole
                pieces = []
                break
            if p not in index:
                index[p] = len(chunks)
                chunks.append(p)
            pieces += [cmd[at:k], index[p]]
            at = k + len(p)
        entries.append(pieces + [cmd[at:]] if pieces else cmd)
    return chunks, entries


def _joined(entry: bytes | list, chunks: list[bytes]) -> bytes:
    """A command's bytes from its entry (see :func:`chunked`)."""
    if isinstance(entry, (bytes, bytearray)):
        return bytes(entry)
    return b"".join(chunks[p] if isinstance(p, int) else p for p in entry)


def record_scene(result: Result, scale: float = 1.0, **options) -> list[bytes]:
    """msgpack-encoded meshcat commands that build the scene and set the animation.

    Args:
        result: any Result (see :func:`geoddp.viz.scene.build_scene`).
        scale: uniform size factor of the drawing.
        options: ``geometry``, ``trail``, ``max_mesh_mb``, ``plan``, ``contacts`` of
            :func:`geoddp.viz.scene.build_scene`.

    Returns:
        One bytes object per command, in the order they must be applied.
    """
    return _record(result, scale, **options).commands


def _record(result: Result, scale: float = 1.0, **options) -> _RecordingWindow:
    window = _RecordingWindow()
    vis = meshcat.Visualizer(window=window)
    build_scene(vis, result, scale=scale, play=True, **options)
    return window


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
{chunks_block}<script>
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
{chunks_loader}  var cmds = JSON.parse(document.getElementById("{commands_id}").textContent);
  for (var i = 0; i < cmds.length; i++) viewer.handle_command_bytearray({decode}(cmds[i]));
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


# With a chunk table: the decoded chunks, and the function joining a command's pieces (a base64
# string: its bytes; a number: a chunk) into the bytes the viewer takes.
_CHUNKS_LOADER = """  var chunks = JSON.parse(document.getElementById("{chunks_id}").textContent).map(bytes);
  function joined(entry) {{
    if (typeof entry === "string") return bytes(entry);
    var parts = entry.map(function (p) {{ return typeof p === "number" ? chunks[p] : bytes(p); }});
    var n = 0, at = 0;
    parts.forEach(function (a) {{ n += a.length; }});
    var out = new Uint8Array(n);
    parts.forEach(function (a) {{ out.set(a, at); at += a.length; }});
    return out;
  }}
"""


def _b64(b: bytes) -> str:
    return base64.b64encode(b).decode("ascii")


def render_html(result: Result, scale: float = 1.0, title: str = "geoddp replay", **options) -> str:
    """The self-contained HTML page as a string (see :func:`export_html`; ``options``:
    ``geometry``, ``trail``, ``max_mesh_mb``)."""
    window = _record(result, scale=scale, **options)
    chunks, entries = chunked(window.commands, window.payloads)
    commands = [_b64(e) if isinstance(e, bytes) else [p if isinstance(p, int) else _b64(p) for p in e] for e in entries]
    return _TEMPLATE.format(
        title=title.replace("<", "&lt;"),
        status_id=STATUS_ID,
        commands_id=COMMANDS_ID,
        commands_json=json.dumps(commands),  # base64, integers and JSON punctuation only: script-safe
        chunks_block=(f'<script type="application/json" id="{CHUNKS_ID}">{json.dumps([_b64(c) for c in chunks])}'
                      "</script>\n") if chunks else "",
        chunks_loader=_CHUNKS_LOADER.format(chunks_id=CHUNKS_ID) if chunks else "",
        decode="joined" if chunks else "bytes",
        viewer_js=_script_safe(_VIEWER_JS.read_text(encoding="utf-8")),
    )


def export_html(result: Result, path: str | Path, scale: float = 1.0, *, geometry: str = "visual",
                trail: str | None = None, max_mesh_mb: float | None = MAX_MESH_MB,
                plan: Result | None = None, contacts=None) -> Path:
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
        contacts: a legged trajectory's ground, contact points and force arrows
            (:class:`geoddp.viz.contact_shapes.ContactScene`; :func:`geoddp.viz.legged.export_legged_html`
            builds it from the problem).

    Returns:
        The path written (nothing is written when an InputError is raised).
    """
    extra = {} if plan is None else {"plan": plan}
    if contacts is not None:
        extra["contacts"] = contacts
    text = render_html(result, scale=scale, geometry=geometry, trail=trail, max_mesh_mb=max_mesh_mb, **extra)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, text)  # temp file + rename: a kill never leaves a partial page
    return path


def _block(html_text: str, block_id: str) -> str | None:
    m = re.search(r'<script type="application/json" id="%s">(.*?)</script>' % re.escape(block_id), html_text,
                  flags=re.DOTALL)
    return None if m is None else m.group(1)


def command_bytes(html_text: str) -> list[bytes]:
    """The msgpack bytes of each meshcat command embedded in a page written by
    :func:`export_html`, as the viewer receives them (shared mesh chunks joined back)."""
    text = _block(html_text, COMMANDS_ID)
    if text is None:
        raise ValueError("no geoddp command block in this HTML (not written by export_html?)")
    chunks = [base64.b64decode(c) for c in json.loads(_block(html_text, CHUNKS_ID) or "[]")]
    entries = [base64.b64decode(e) if isinstance(e, str) else [p if isinstance(p, int) else base64.b64decode(p) for p in e]
               for e in json.loads(text)]
    return [_joined(e, chunks) for e in entries]


def decode_commands(html_text: str) -> list[dict]:
    """The meshcat commands embedded in a page written by :func:`export_html`, decoded."""
    return [umsgpack.unpackb(c) for c in command_bytes(html_text)]


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
