"""Generated-input fuzzing of the CLI and the Python API (and, at the byte level, the
robustness of bad files).

Two generators, both seeded (case i of seed s is the same everywhere), each case run in a worker
process:

* values (``--mode values``): one or a few values of a built-in scene file mutated (rescaled
  numbers, wrong types, special values), or the API called with generated options;
* bytes (``--mode bytes``): the bytes of a file mutated: a scene file, a URDF a scene names (the
  built-in models, a satellite's, example-robot-data's UR5 with its meshes), an SRDF a scene
  names, a sweep file. Mutations: bit flips, truncation, random bytes inserted, spans deleted or
  duplicated, lines swapped, NUL and control bytes, encoding changes (Latin-1, cp1252, UTF-16,
  UTF-32, with or without a byte-order mark or a declaration, true or false), nesting bombs
  (arrays, inline tables, XML elements), entity bombs, huge integers, byte-order marks.

``--mode all`` (the default) draws each case from one or the other (half each). Every case must
end in one of two ways:

* solved: exit code 0 or 1, the result JSON parses with a strict parser (no NaN or inf) and has
  no null where a number belongs (a NaN written as null); a sweep case writes its table instead;
* refused: exit code 2 and exactly one line on stderr (geoddp's message).

Anything else is counted: tracebacks / internal errors (exit 3 or an escaped exception), hangs
(no answer within --timeout seconds: the worker is killed and restarted; "slow" instead when the
generated horizon exceeds 20,000 steps, a solve that may honestly take longer), stray stderr lines
(anything on stderr, file descriptor 2 included, besides geoddp's one line), NaN outputs.

    python benchmarks/fuzz.py --cases 10000 --seed 0 [--mode all] [--timeout 60] [--max-iter 50]
                              [--log benchmarks/results/fuzz.log]

tests/test_fuzz.py runs a few hundred cases of each generator in CI.
"""
from __future__ import annotations

import argparse
import base64
import codecs
import io
import json
import os
import random
import re
import select
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

VALUES = ["0", "-1", "1", "0.5", "2", "1e308", "-1e308", "1e-308", "nan", "inf", "-inf", "\"abc\"", "[]",
          "[1.0, 2.0]", "true", "1e12", "1000000000", "-0.0", "3", "[[1.0]]", "\"first\"", "\"hover\"", "1e-12",
          "\"\"", "\"\\u0000x\"", "[0.0, 0.0, 0.0]", "[nan, 0.0, 1.0]", "1e6", "0.1", "10"]
LINE = re.compile(r"^(\s*)([A-Za-z_][A-Za-z0-9_]*)(\s*=\s*)(.+?)\s*(#.*)?$")


def _base_scenes() -> dict[str, str]:
    from geoddp.data import scene_names, scene_path

    return {n: Path(scene_path(n)).read_text() for n in scene_names() if n not in ("long_horizon_H3000", "fine_dt_1e-4")}


def _scaled(rng: random.Random, x: float) -> str:
    k = rng.choice([-300, -12, -6, -3, -1, 1, 3, 6, 12, 300])
    y = x * 10.0 ** k if x else 10.0 ** rng.choice([-6, -1, 1, 3])
    return repr(-y if rng.random() < 0.15 else y)


def _mutate_value(rng: random.Random, value: str) -> str:
    """A new TOML value for ``value``: mostly a rescaled number (so the scene still parses and is
    solved at an extreme), sometimes a wrong type or a special value."""
    r = rng.random()
    try:
        x = float(value)
    except ValueError:
        x = None
    if x is not None and r < 0.6:
        return _scaled(rng, x)
    nums = list(re.finditer(r"-?\d+\.?\d*(?:[eE][-+]?\d+)?", value))
    if value.startswith("[") and nums and r < 0.6:
        m = rng.choice(nums)
        return value[:m.start()] + _scaled(rng, float(m.group())) + value[m.end():]
    return rng.choice(VALUES)


def make_case(seed: int, i: int, scenes: dict[str, str], max_iter: int) -> dict:
    """Case ``i`` of ``seed``: {"kind": "scene", "text": ...} or {"kind": "api", "options": ...}."""
    rng = random.Random(seed * 1_000_003 + i)
    if rng.random() < 0.15:
        keys = ["tol", "grad_tol", "reg_increase", "reg_min", "reg_max", "step_factor", "min_step", "switch_ratio",
                "switch_after", "expansion", "max_iter", "verbose", "stream", "record_controls", "tool"]
        import tomllib

        opts = {k: tomllib.loads(f"x = {v}")["x"]
                for k, v in ((rng.choice(keys), rng.choice(VALUES)) for _ in range(rng.randint(1, 3)))}
        return {"kind": "api", "scene": rng.choice(["satellite_paper", "quadrotor", "tumbling_2rads"]), "options": opts}
    name = rng.choice(sorted(scenes))
    lines = scenes[name].splitlines()
    editable = [k for k, ln in enumerate(lines) if LINE.match(ln) and not ln.lstrip().startswith("#")]
    for _ in range(rng.choice([1, 1, 1, 2, 3])):
        k = rng.choice(editable)
        m = LINE.match(lines[k])
        if m is None:  # blanked by an earlier mutation of this case
            continue
        if rng.random() < 0.1:
            lines[k] = ""  # a missing key
        else:
            lines[k] = f"{m.group(1)}{m.group(2)}{m.group(3)}{_mutate_value(rng, m.group(4))}"
    text = "\n".join(lines) + "\n"
    # bound the work of a case (the fuzzer looks for crashes, not for long solves)
    text = re.sub(r"(?m)^max_iter\s*=.*$", f"max_iter = {max_iter}", text)
    if "[solver]" not in text:
        text += f"\n[solver]\nmax_iter = {max_iter}\n"
    elif "max_iter" not in text:
        text = text.replace("[solver]", f"[solver]\nmax_iter = {max_iter}", 1)
    return {"kind": "scene", "name": name, "text": text, "long": _horizon(text) > LONG_HORIZON}


LONG_HORIZON = 20000  # steps: a solve this long may honestly outlast the per-case time limit


def _horizon(text: str) -> float:
    """H of a generated scene (0 if it does not parse): a timeout on a long horizon is counted as
    "slow", not as a hang."""
    import tomllib

    try:
        h = tomllib.loads(text).get("horizon", {})
        return float(h["steps"]) if "steps" in h else float(h["tf"]) / float(h["dt"])
    except Exception:  # noqa: BLE001 - any file the reader refuses (malformed, nested too deep, ...) has no horizon
        return 0.0


# ----------------------------------------------------------------------------- byte-level cases
BYTES_SALT = 7_919  # a byte case's random stream differs from the value case of the same index
NEST = [10, 33, 100, 400, 1000, 5000, 100000]  # nesting depths tried (32 is geoddp's limit)
ENCODINGS = ["latin-1", "cp1252", "utf-16", "utf-16-le", "utf-16-be", "utf-32", "utf-8-sig", "utf-7"]
NON_ASCII = ["\u00e9", "\u00fc\u00df", "\u65e5\u672c", "\U0001f680", "\u00a0", "\ufffd", "\u0130"]


def _urdf_hosts(max_iter: int) -> dict[str, tuple[str, bytes]]:
    """(scene text naming "m.urdf", URDF bytes) per host: the built-in multibody scenes with their
    models (horizon cut to 20 steps), the paper's satellite with its URDF, and the UR5 of
    example-robot-data (meshes found through package_dirs) when installed."""
    from geoddp.data import scene_path, urdf_path

    hosts = {}
    for scene, urdf in (("quadrotor", "quadrotor.urdf"), ("space_manipulator", "space_manipulator.urdf"),
                        ("spacecraft_docking", "spacecraft.urdf")):
        text = Path(scene_path(scene)).read_text()
        text = re.sub(r'(?m)^urdf = .*$', 'urdf = "m.urdf"', text)
        text = re.sub(r"(?m)^steps = .*$", "steps = 20", text)
        hosts[scene] = (_bounded(text, max_iter), Path(urdf_path(urdf)).read_bytes())
    sat = Path(scene_path("satellite_paper")).read_text().replace("[model]\n", '[model]\nurdf = "m.urdf"\n', 1)
    hosts["satellite_paper"] = (_bounded(sat, max_iter), Path(urdf_path("satellite.urdf")).read_bytes())
    try:
        from geoddp.models.robots import find

        ur5 = find("ur5")
    except Exception:  # noqa: BLE001 - example-robot-data not installed: no UR5 host
        return hosts
    text = Path(scene_path("ur5_reach")).read_text()
    text = text.replace('robot = "ur5"', f'urdf = "m.urdf"\npackage_dirs = {json.dumps(list(ur5.package_dirs))}', 1)
    hosts["ur5_reach"] = (_bounded(text, max_iter), Path(ur5.urdf).read_bytes())
    return hosts


def _bounded(text: str, max_iter: int) -> str:
    text = re.sub(r"(?m)^max_iter\s*=.*$", f"max_iter = {max_iter}", text)
    if "[solver]" not in text:
        text += f"\n[solver]\nmax_iter = {max_iter}\n"
    elif "max_iter" not in text:
        text = text.replace("[solver]", f"[solver]\nmax_iter = {max_iter}", 1)
    return text


SRDF_SCENE_EDIT = ('urdf = "m.urdf"', 'urdf = "m.urdf"\nsrdf = "m.srdf"')
SRDF = (b'<?xml version="1.0"?>\n<robot name="quadrotor">\n  <group name="all"/>\n'
        b'  <group_state name="up" group="all">\n    <joint name="root_joint" value="0 0 1 0 0 0 1"/>\n'
        b'  </group_state>\n  <group_state name="tilted" group="all">\n'
        b'    <joint name="root_joint" value="0 0 1.5 0 0 0.3826834 0.9238795"/>\n  </group_state>\n</robot>\n')
SWEEP = b"""[sweep]
scene = "satellite_paper"
seed = 3
samples = 2

[scene]
horizon.tf = 0.3
horizon.dt = 0.05
solver.max_iter = 20

[grid]
cost.control = [0.1, 1.0]

[[random]]
key = "target.quaternion"
distribution = "haar"
"""


def _nest(rng: random.Random, xml: bool) -> str:
    n = rng.choice(NEST)
    if xml:
        return "<a>" * n + "</a>" * n
    if rng.random() < 0.5:
        return "zz = " + "[" * n + "]" * n + "\n"
    return "zz = " + "{a = " * n + "1" + "}" * n + "\n"


def _entity_bomb(rng: random.Random) -> str:
    depth = rng.choice([2, 5, 10])
    ents = "".join(f'<!ENTITY e{i} "{("&e" + str(i - 1) + ";") * 10 if i else "lol"}">' for i in range(depth))
    return f"<!DOCTYPE robot [{ents}]>\n"


def _huge_number(rng: random.Random, xml: bool) -> str:
    k = rng.random()
    if k < 0.3:
        return "9" * rng.choice([20, 4400, 5000])
    if k < 0.5 and not xml:
        return "0x" + "f" * rng.choice([17, 3000])
    return rng.choice(["1e999", "-1e999", "nan", "inf", "1e-400", "0x1p3", "1_000", "+-1", "1e308"])


def _reencode(rng: random.Random, data: bytes, xml: bool) -> bytes:
    """The text (UTF-8, as far as it decodes) with a non-ASCII character added, written in another
    encoding; for XML the declaration names it, names another, or is left as it was."""
    text = data.decode("utf-8", "replace")
    pos = rng.randrange(len(text) + 1)
    text = text[:pos] + rng.choice(NON_ASCII) + text[pos:]
    enc = rng.choice(ENCODINGS)
    if xml and rng.random() < 0.7:
        named = enc if rng.random() < 0.6 else rng.choice(ENCODINGS + ["ISO-8859-1", "ascii", "klingon", "rot13"])
        decl = f'<?xml version="1.0" encoding="{named}"?>'
        text = re.sub(r"^\s*<\?xml[^>]*\?>", decl, text, count=1) if text.lstrip().startswith("<?xml") \
            else decl + "\n" + text
    return text.encode(enc, "replace")


def mutate_bytes(rng: random.Random, data: bytes, xml: bool) -> tuple[bytes, list[str]]:
    """``data`` with one to three byte-level mutations; their names, for the log."""
    ops = []
    for _ in range(rng.choice([1, 1, 1, 2, 3])):
        op = rng.choice(["flip", "flip", "truncate", "insert", "delete", "duplicate", "swap_lines", "control",
                         "encoding", "nest", "huge_number", "bom"] + (["entity"] if xml else []))
        ops.append(op)
        n = len(data)
        at = rng.randrange(n + 1)
        if op == "flip" and n:
            b = bytearray(data)
            for _ in range(rng.choice([1, 1, 2, 4, 8])):
                i = rng.randrange(n)
                b[i] ^= 1 << rng.randrange(8)
            data = bytes(b)
        elif op == "truncate":
            data = data[:rng.randrange(n)] if n else data
        elif op == "insert":
            data = data[:at] + bytes(rng.randrange(256) for _ in range(rng.choice([1, 2, 4, 16]))) + data[at:]
        elif op == "delete":
            data = data[:at] + data[at + rng.choice([1, 3, 16, 64]):]
        elif op == "duplicate" and n:
            a = rng.randrange(n)
            data = data[:at] + data[a:a + rng.choice([8, 40, 200])] + data[at:]
        elif op == "swap_lines":
            lines = data.split(b"\n")
            if len(lines) > 1:
                i, j = rng.sample(range(len(lines)), 2)
                lines[i], lines[j] = lines[j], lines[i]
                data = b"\n".join(lines)
        elif op == "control":
            junk = rng.choice([b"\0", b"\x01", b"\x1b[2J", b"\x7f", b"\r", b"\x0c", b"\xff\xfe"])
            data = data[:at] + junk + data[at:]
        elif op == "encoding":
            data = _reencode(rng, data, xml)
        elif op == "nest":
            if xml:  # inside the root element, where a parser descends
                m = re.search(rb"<robot[^>]*>", data)
                cut = m.end() if m else at
                data = data[:cut] + _nest(rng, True).encode() + data[cut:]
            else:  # at a line start: a key of its own, or a value
                starts = [0] + [m.end() for m in re.finditer(rb"\n", data)]
                cut = rng.choice(starts)
                data = data[:cut] + _nest(rng, False).encode() + data[cut:]
        elif op == "huge_number":
            nums = list(re.finditer(rb"-?\d+\.?\d*(?:[eE][-+]?\d+)?", data))
            if nums:
                m = rng.choice(nums)
                data = data[:m.start()] + _huge_number(rng, xml).encode() + data[m.end():]
        elif op == "bom":
            data = rng.choice([codecs.BOM_UTF8, codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE, codecs.BOM_UTF32_LE]) + data
        elif op == "entity":
            m = re.search(rb"<robot", data)
            cut = m.start() if m else 0
            data = data[:cut] + _entity_bomb(rng).encode() + data[cut:]
            if rng.random() < 0.7:  # and use it
                data = re.sub(rb'name="([^"]*)"', lambda mm: b'name="&e1;' + mm.group(1) + b'"', data, count=1)
    return data, ops


def make_bytes_case(seed: int, i: int, scenes: dict[str, str], hosts: dict[str, tuple[str, bytes]],
                    max_iter: int) -> dict:
    """Byte case ``i`` of ``seed``: files (name -> base64 bytes) and the CLI arguments."""
    rng = random.Random(seed * 1_000_003 + i + BYTES_SALT)
    target = rng.choices(["scene", "urdf", "srdf", "sweep"], weights=[4, 4, 1, 1])[0]
    if target == "scene":
        name = rng.choice(sorted(scenes))
        base = _bounded(scenes[name], max_iter).encode()
        data, ops = mutate_bytes(rng, base, xml=False)
        files, argv = {"scene.toml": data}, ["run", "scene.toml"]
    elif target == "urdf":
        name = rng.choice(sorted(hosts))
        scene, urdf = hosts[name]
        data, ops = mutate_bytes(rng, urdf, xml=True)
        files, argv = {"scene.toml": scene.encode(), "m.urdf": data}, ["run", "scene.toml"]
    elif target == "srdf":
        name = "quadrotor"
        scene, urdf = hosts[name]
        scene = scene.replace(*SRDF_SCENE_EDIT).replace("translation = [0.0, 0.0, 1.0]", 'q = "up"', 1)
        data, ops = mutate_bytes(rng, SRDF, xml=True)
        files, argv = {"scene.toml": scene.encode(), "m.urdf": urdf, "m.srdf": data}, ["run", "scene.toml"]
    else:
        name = "sweep"
        data, ops = mutate_bytes(rng, SWEEP, xml=False)
        files, argv = {"sweep.toml": data}, ["sweep", "sweep.toml", "--serial", "--limit", "4"]
    text = files.get("scene.toml", b"").decode("utf-8", "replace")
    return {"kind": "bytes", "target": target, "name": name, "ops": ops, "argv": argv,
            "files": {k: base64.b64encode(v).decode("ascii") for k, v in files.items()},
            "long": _horizon(text) > LONG_HORIZON}


# ----------------------------------------------------------------------------- worker side
def _strict_json_ok(path: Path) -> bool:
    def refuse(c):
        raise ValueError(c)

    try:
        json.loads(path.read_text(), parse_constant=refuse)
        return True
    except ValueError:
        return False


# What a result returns as its solution: a NaN there (written as null by strict_json) is a NaN
# output. The gradient norm is not among them: a solve stopped by a non-finite linearisation
# (status "non-finite") reports the gradient it could not form as null, beside the last finite
# iterate, and says so; those are counted apart.
SOLUTION_KEYS = ("cost", "cost_history", "controls", "quaternions", "angular_velocities", "rotations",
                 "configurations", "velocities", "feedforward", "feedback", "times", "attitude_error_deg",
                 "angular_velocity_error")


def _nulls(x, keys: tuple[str, ...] = SOLUTION_KEYS) -> int:
    """Numbers written as null (strict_json's NaN and inf) under ``keys`` of a result dict."""
    if not isinstance(x, dict):
        return 1
    stack, n = [x[k] for k in keys if k in x], 0
    n += sum(x[k] is None for k in keys if k in x and k in ("cost", "attitude_error_deg", "angular_velocity_error"))
    while stack:
        node = stack.pop()
        if isinstance(node, list):
            n += sum(v is None for v in node)
            stack.extend(v for v in node if isinstance(v, (list, dict)))
        elif isinstance(node, dict):
            stack.extend(v for v in node.values() if isinstance(v, (list, dict)))
    return n


def _bytes_case(case: dict, folder: Path, json_path: Path) -> int:
    from geoddp.cli import main

    work = folder / "case"
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir()
    for name, data in case["files"].items():
        (work / name).write_bytes(base64.b64decode(data))
    argv = [str(work / a) if a in case["files"] else a for a in case["argv"]]
    if argv[0] == "sweep":
        return main(argv + ["--out", str(work / "out"), "--quiet"])
    return main(argv + ["--quiet", "--json", str(json_path)])


def run_case(case: dict, folder: Path) -> dict:
    """Run one case in this process; returns {"rc", "stderr", "json_ok", "escaped", ...}."""
    from geoddp.models.urdf import captured_stderr

    out, err = io.StringIO(), io.StringIO()
    escaped = None
    json_path = folder / "out.json"
    if json_path.exists():
        json_path.unlink()
    with captured_stderr() as fd2:
        try:
            with redirect_stdout(out), redirect_stderr(err):
                if case["kind"] == "bytes":
                    rc = _bytes_case(case, folder, json_path)
                elif case["kind"] == "scene":
                    scene = folder / "scene.toml"
                    scene.write_text(case["text"], encoding="utf-8", errors="surrogateescape")
                    from geoddp.cli import main

                    rc = main(["run", str(scene), "--quiet", "--json", str(json_path)])
                else:
                    rc = _api_case(case, json_path)
        except BaseException as exc:  # noqa: BLE001 - anything escaping is what we count
            rc, escaped = -1, f"{type(exc).__name__}: {exc}"
    stderr_lines = [ln for ln in err.getvalue().splitlines() if ln.strip()] + fd2
    sweep = case["kind"] == "bytes" and case["argv"][0] == "sweep"
    json_ok = sweep or (json_path.exists() and _strict_json_ok(json_path))
    result = json.loads(json_path.read_text()) if json_ok and not sweep else None
    nulls = _nulls(result) if result is not None else 0
    if nulls:
        json_ok = False  # a NaN in the returned solution, written as null
    null_gradient = bool(result) and result.get("grad_norm", 0) is None
    return {"rc": rc, "stderr": stderr_lines, "json_ok": json_ok, "json_exists": json_path.exists() and not sweep,
            "escaped": escaped, "nulls": nulls, "null_gradient": null_gradient,
            "status": (result or {}).get("status")}


def _api_case(case: dict, json_path: Path) -> int:
    from geoddp import solve_scene
    from geoddp.validate import InputError

    try:
        r = solve_scene(case["scene"], **{"verbose": False, "max_iter": 30, **case["options"]})
    except InputError as exc:
        print(f"geoddp: error: {exc}", file=sys.stderr)
        return 2
    r.write_json(json_path)
    return 0 if r.converged else 1


def worker() -> None:
    folder = Path(tempfile.mkdtemp(prefix="geoddp-fuzz-"))
    import numpy  # noqa: F401  (import cost outside the per-case clock)
    import geoddp.cli  # noqa: F401
    sys.__stdout__.write("ready\n")
    sys.__stdout__.flush()
    for line in sys.stdin:
        res = run_case(json.loads(line), folder)
        sys.__stdout__.write(json.dumps(res) + "\n")
        sys.__stdout__.flush()


# ----------------------------------------------------------------------------- driver side
class Runner:
    """A worker process fed one case at a time, killed and restarted after a hang."""

    def __init__(self, timeout: float) -> None:
        self.timeout, self.proc = timeout, None

    def _start(self) -> None:
        self.proc = subprocess.Popen([sys.executable, __file__, "--worker"], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=os.environ.copy())
        assert self.proc.stdout.readline().strip() == "ready", self.proc.stderr.read()

    def run(self, case: dict) -> dict | None:
        if self.proc is None or self.proc.poll() is not None:
            self._start()
        self.proc.stdin.write(json.dumps(case) + "\n")
        self.proc.stdin.flush()
        ready, _, _ = select.select([self.proc.stdout], [], [], self.timeout)
        if not ready:
            self.close()
            return None
        line = self.proc.stdout.readline()
        if not line:  # the worker died (a crash in native code)
            self.close()
            return {"rc": -9, "stderr": ["worker died"], "json_ok": False, "json_exists": False, "escaped": "crash"}
        return json.loads(line)

    def close(self) -> None:
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait()
            self.proc = None


def classify(res: dict | None) -> str:
    if res is None:
        return "hang"
    if res["escaped"] or res["rc"] in (3, -1, -9):
        return "traceback"
    if res["rc"] in (0, 1):
        if not res["json_ok"]:
            return "nan_output"
        return "stray_stderr" if res["stderr"] else "solved"
    if res["rc"] == 2:
        if res["json_exists"] and not res["json_ok"]:
            return "nan_output"
        return "refused" if len(res["stderr"]) == 1 else "stray_stderr"
    return "traceback"


MODES = ("values", "bytes", "all")


def pick_case(mode: str, seed: int, i: int, scenes: dict[str, str], hosts: dict, max_iter: int) -> dict:
    """Case ``i`` of ``seed`` for ``mode``: a value case, a byte case, or (all) one of the two."""
    if mode == "values" or (mode == "all" and random.Random(seed * 1_000_003 + i + 2 * BYTES_SALT).random() < 0.5):
        return make_case(seed, i, scenes, max_iter)
    return make_bytes_case(seed, i, scenes, hosts, max_iter)


def new_stats() -> dict:
    """Counters beside the classes: exit codes, classes per target, mutations, tracebacks, NaNs."""
    return {"exit_codes": Counter(), "by_target": Counter(), "ops": Counter(), "tracebacks": 0, "nan_outputs": 0,
            "nulls": 0, "null_gradient": Counter()}


def fuzz(cases: int, seed: int = 0, timeout: float = 60.0, max_iter: int = 50, verbose: bool = False,
         examples: dict | None = None, mode: str = "values", stats: dict | None = None) -> Counter:
    """Run ``cases`` generated cases of ``mode`` (values, bytes, all); the count of each class.
    ``examples`` collects (index, case, outcome) of every case neither solved nor refused;
    ``stats`` (:func:`new_stats`) the exit codes, classes per target, mutations, tracebacks and
    NaN outputs."""
    if mode not in MODES:
        raise ValueError(f"mode: expected one of {MODES}, got {mode!r}")
    scenes = _base_scenes()
    hosts = _urdf_hosts(max_iter) if mode != "values" else {}
    runner = Runner(timeout)
    counts: Counter = Counter()
    try:
        for i in range(cases):
            case = pick_case(mode, seed, i, scenes, hosts, max_iter)
            res = runner.run(case)
            c = "slow" if res is None and case.get("long") else classify(res)
            counts[c] += 1
            if stats is not None:
                stats["exit_codes"]["timeout" if res is None else str(res["rc"])] += 1
                stats["by_target"][f"{case.get('target', case['kind'])}: {c}"] += 1
                stats["ops"].update(case.get("ops", []))
                said = (res or {}).get("stderr", [])
                stats["tracebacks"] += c == "traceback" or any("Traceback" in ln for ln in said)
                stats["nan_outputs"] += c == "nan_output"
                stats["nulls"] += (res or {}).get("nulls", 0)
                if (res or {}).get("null_gradient"):
                    stats["null_gradient"][str(res.get("status"))] += 1
            if c not in ("solved", "refused"):
                if examples is not None:
                    examples.setdefault(c, []).append((i, case, res))
                if verbose:
                    shown = {k: v for k, v in case.items() if k not in ("files", "text")}
                    print(f"case {i}: {c}: {shown} -> {res}", flush=True)
    finally:
        runner.close()
    return counts


def report(args: argparse.Namespace, counts: Counter, stats: dict, examples: dict, seconds: float) -> str:
    """The fuzz log: the command, the commit, the counts and the first cases of each failure class."""
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=Path(__file__).parent, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        commit = "?"
    lines = [f"# python benchmarks/fuzz.py --cases {args.cases} --seed {args.seed} --mode {args.mode} "
             f"--timeout {args.timeout:g} --max-iter {args.max_iter}",
             f"# {time.strftime('%Y-%m-%d %H:%M')} commit {commit}, {seconds:.0f} s",
             "",
             f"cases: {sum(counts.values())}",
             "classes: " + ", ".join(f"{k} {v}" for k, v in counts.most_common()),
             "exit codes: " + ", ".join(f"{k}: {v}" for k, v in sorted(stats["exit_codes"].items())),
             f"tracebacks (exit 3, an escaped exception or a Traceback line): {stats['tracebacks']}",
             f"NaN outputs (a result JSON with NaN or inf, or null in J*, its history or the returned "
             f"trajectory, controls or gains): {stats['nan_outputs']} ({stats['nulls']} nulls)",
             "gradient norm null (a solve stopped on a non-finite linearisation; the last finite iterate returned), "
             "by status: " + (", ".join(f"{k} {v}" for k, v in stats["null_gradient"].items()) or "none"),
             "",
             "per target:"]
    lines += [f"  {k}: {v}" for k, v in sorted(stats["by_target"].items())]
    lines += ["", "byte mutations applied: " + ", ".join(f"{k} {v}" for k, v in stats["ops"].most_common())]
    for c, items in sorted(examples.items()):
        lines += ["", f"{c}: {len(items)} case(s); the first ones:"]
        for i, case, res in items[:5]:
            shown = {k: v for k, v in case.items() if k not in ("files", "text")}
            lines.append(f"  case {i}: {json.dumps(shown)[:400]} -> {json.dumps(res)[:600]}")
    summary = {"cases": sum(counts.values()), "seed": args.seed, "mode": args.mode, "seconds": round(seconds, 1),
               **counts, "tracebacks": stats["tracebacks"], "nan_outputs": stats["nan_outputs"],
               "exit_codes": dict(stats["exit_codes"])}
    return "\n".join(lines + ["", json.dumps(summary)]) + "\n"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases", type=int, default=10000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--mode", choices=MODES, default="all", help="value mutations, byte mutations, or both")
    p.add_argument("--timeout", type=float, default=60.0)
    p.add_argument("--max-iter", type=int, default=50)
    p.add_argument("--log", type=Path, help="write the counts and the first failing cases here")
    p.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.worker:
        worker()
        return
    t0 = time.time()
    stats, examples = new_stats(), {}
    counts = fuzz(args.cases, args.seed, args.timeout, args.max_iter, verbose=True, examples=examples, mode=args.mode,
                  stats=stats)
    text = report(args, counts, stats, examples, time.time() - t0)
    print(text)
    if args.log is not None:
        args.log.parent.mkdir(parents=True, exist_ok=True)
        tmp = args.log.with_name(args.log.name + ".tmp")
        tmp.write_text(text)
        tmp.replace(args.log)


if __name__ == "__main__":
    main()
