"""Generated-input fuzzing of the CLI and the Python API (issue 13, item 7).

Each case mutates one or a few values of a built-in scene file (seeded: case i of seed s is the
same everywhere), or calls the API with generated options, and runs it in a worker process.
Every case must end in one of two ways:

* solved: exit code 0 or 1, the result JSON parses with a strict parser (no NaN or inf);
* refused: exit code 2 and exactly one line on stderr (geoddp's message).

Anything else is counted: tracebacks / internal errors (exit 3 or an escaped exception), hangs
(no answer within --timeout seconds: the worker is killed and restarted; "slow" instead when the
generated horizon exceeds 20,000 steps, a solve that may honestly take longer), stray stderr lines
(anything on stderr, file descriptor 2 included, besides geoddp's one line), NaN outputs.

    python benchmarks/fuzz.py --cases 10000 --seed 0 [--timeout 60] [--max-iter 50]

tests/test_fuzz.py runs a few hundred cases of the same generator in CI.
"""
from __future__ import annotations

import argparse
import io
import json
import os
import random
import re
import select
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
    except (tomllib.TOMLDecodeError, KeyError, TypeError, ValueError, ZeroDivisionError, OverflowError):
        return 0.0


# ----------------------------------------------------------------------------- worker side
def _strict_json_ok(path: Path) -> bool:
    def refuse(c):
        raise ValueError(c)

    try:
        json.loads(path.read_text(), parse_constant=refuse)
        return True
    except ValueError:
        return False


def run_case(case: dict, folder: Path) -> dict:
    """Run one case in this process; returns {"rc", "stderr", "json_ok", "escaped"}."""
    from geoddp.models.urdf import captured_stderr

    out, err = io.StringIO(), io.StringIO()
    escaped = None
    json_path = folder / "out.json"
    if json_path.exists():
        json_path.unlink()
    with captured_stderr() as fd2:
        try:
            with redirect_stdout(out), redirect_stderr(err):
                if case["kind"] == "scene":
                    scene = folder / "scene.toml"
                    scene.write_text(case["text"], encoding="utf-8", errors="surrogateescape")
                    from geoddp.cli import main

                    rc = main(["run", str(scene), "--quiet", "--json", str(json_path)])
                else:
                    rc = _api_case(case, json_path)
        except BaseException as exc:  # noqa: BLE001 - anything escaping is what we count
            rc, escaped = -1, f"{type(exc).__name__}: {exc}"
    stderr_lines = [ln for ln in err.getvalue().splitlines() if ln.strip()] + fd2
    json_ok = json_path.exists() and _strict_json_ok(json_path)
    return {"rc": rc, "stderr": stderr_lines, "json_ok": json_ok, "json_exists": json_path.exists(), "escaped": escaped}


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


def fuzz(cases: int, seed: int = 0, timeout: float = 60.0, max_iter: int = 50, verbose: bool = False,
         examples: dict | None = None) -> Counter:
    scenes = _base_scenes()
    runner = Runner(timeout)
    counts: Counter = Counter()
    try:
        for i in range(cases):
            case = make_case(seed, i, scenes, max_iter)
            res = runner.run(case)
            c = "slow" if res is None and case.get("long") else classify(res)
            counts[c] += 1
            if c not in ("solved", "refused"):
                if examples is not None:
                    examples.setdefault(c, []).append((i, case, res))
                if verbose:
                    print(f"case {i}: {c}: {res}", flush=True)
    finally:
        runner.close()
    return counts


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases", type=int, default=10000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--timeout", type=float, default=60.0)
    p.add_argument("--max-iter", type=int, default=50)
    p.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.worker:
        worker()
        return
    t0 = time.time()
    counts = fuzz(args.cases, args.seed, args.timeout, args.max_iter, verbose=True)
    print(json.dumps({"cases": args.cases, "seed": args.seed, "seconds": round(time.time() - t0, 1), **counts}))


if __name__ == "__main__":
    main()
