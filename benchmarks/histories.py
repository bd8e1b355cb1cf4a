"""Solve histories of every built-in scene, saved and compared bit for bit.

A refactor that must leave results unchanged is checked with this script: save the histories of
one checkout, save them again with the other, compare.

    python benchmarks/histories.py save before.npz            # every built-in scene x expansion
    python benchmarks/histories.py save after.npz
    python benchmarks/histories.py compare before.npz after.npz

Each (scene, expansion) records the cost, gradient-norm, regularisation and step histories, the
expansion per iteration, the controls, feedforward and feedback gains, the final state and the
status. ``compare`` prints, per case, "bitwise" when every array is equal to the last bit, else
the largest relative difference per array, and exits 1 if any case differs beyond ``--rtol``
(default 0: bitwise).

Scenes: the built-in satellite, hard, multibody and robot scenes (the robots need
example-robot-data); ``--quick`` skips the 3000-step horizon and the 1e-4 s step.

``--old-defaults`` gives each scene the solver defaults of a checkout from before the relative
stopping test and the quasi-static start: ``tol = 1e-8`` where the scene's ``[solver]`` table sets
neither ``tol`` nor ``rtol``, and ``initial_controls = "zero"`` for a multibody scene that sets no
start. Save the newer checkout with it to compare like for like with an older one.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

EXPANSIONS = ("first", "second", "switch")
SLOW = {"long_horizon_H3000", "fine_dt_1e-4"}


def _solve_scene():
    try:
        from geoddp import solve_scene  # the public facade
    except ImportError:
        from geoddp.api import solve_scene  # before the facade existed
    return solve_scene


def scene_files() -> list[Path]:
    import geoddp

    root = Path(geoddp.__file__).parent / "data" / "scenes"
    return sorted(p for p in root.rglob("*.toml") if "sweeps" not in p.parts)


def record(result) -> dict[str, np.ndarray]:
    out = {
        "cost_history": np.asarray(result.cost_history, float),
        "grad_norm_history": np.asarray(result.grad_norm_history, float),
        "reg_history": np.asarray(result.reg_history, float),
        "step_history": np.asarray(result.step_history, float),
        "expansion_history": np.array([1 if e == "second" else 0 for e in result.expansion_history]),
        "controls": np.asarray(result.controls, float),
        "feedforward": np.asarray(result.feedforward, float),
        "feedback": np.asarray(result.feedback, float),
        "v": np.asarray(result.v, float),
        "q": np.asarray(result.q, float),
        "cost": np.array([result.cost]),
        "status": np.array([result.status]),
    }
    return out


def old_defaults(scene: Path) -> dict:
    """The options that give ``scene`` the defaults of a checkout from before the relative
    stopping test (absolute tol 1e-8) and the quasi-static start (zero controls)."""
    import tomllib

    table = tomllib.loads(scene.read_text())
    solver = table.get("solver", {})
    out: dict = {}
    if "tol" not in solver and "rtol" not in solver:
        out["tol"] = 1e-8
    multibody = table.get("model", {}).get("kind", "satellite") != "satellite"
    if multibody and "initial_controls" not in solver and "initial_controls" not in table:
        out["initial_controls"] = "zero"
    return out


def save(path: str, quick: bool, only: list[str] | None, old: bool = False) -> None:
    solve_scene = _solve_scene()
    arrays: dict[str, np.ndarray] = {}
    for f in scene_files():
        if quick and f.stem in SLOW:
            continue
        if only and f.stem not in only:
            continue
        for exp in EXPANSIONS:
            try:
                r = solve_scene(str(f), expansion=exp, verbose=False, **(old_defaults(f) if old else {}))
            except Exception as exc:  # a robot scene without example-robot-data
                print(f"{f.stem:32s} {exp:7s} skipped: {type(exc).__name__}: {exc}", file=sys.stderr)
                continue
            for k, a in record(r).items():
                arrays[f"{f.stem}|{exp}|{k}"] = a
            print(f"{f.stem:32s} {exp:7s} {r.iterations:4d} it  J = {r.cost:.15e}  {r.status[:30]}")
    np.savez(path, **arrays)
    print(f"saved {len(arrays)} arrays to {path}")


def compare(a: str, b: str, rtol: float) -> int:
    A, B = np.load(a), np.load(b)
    cases = sorted({k.rsplit("|", 1)[0] for k in A.files} | {k.rsplit("|", 1)[0] for k in B.files})
    bad = 0
    for case in cases:
        keys = sorted({k for k in A.files if k.startswith(case + "|")} | {k for k in B.files if k.startswith(case + "|")})
        diffs = []
        for k in keys:
            name = k.rsplit("|", 1)[1]
            if k not in A.files or k not in B.files:
                diffs.append(f"{name}: missing in {'before' if k not in A.files else 'after'}")
                continue
            x, y = A[k], B[k]
            if x.dtype.kind in "US":
                if not np.array_equal(x, y):
                    diffs.append(f"{name}: {x} -> {y}")
                continue
            if x.shape != y.shape:
                diffs.append(f"{name}: shape {x.shape} -> {y.shape}")
                continue
            if np.array_equal(x, y, equal_nan=True):
                continue
            scale = np.maximum(np.abs(x), np.abs(y))
            with np.errstate(all="ignore"):
                rel = np.nanmax(np.where(scale > 0, np.abs(x - y) / scale, 0.0))
            diffs.append(f"{name}: {rel:.1e}")
            if rel > rtol:
                bad += 1
        print(f"{case:40s} " + ("bitwise" if not diffs else "; ".join(diffs)))
    print(f"{len(cases)} cases, {bad} arrays beyond rtol = {rtol:g}")
    return 1 if bad else 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("save")
    s.add_argument("path")
    s.add_argument("--quick", action="store_true")
    s.add_argument("--only", nargs="*")
    s.add_argument("--old-defaults", action="store_true",
                   help="absolute tol 1e-8 and zero start where the scene sets neither (see above)")
    c = sub.add_parser("compare")
    c.add_argument("before")
    c.add_argument("after")
    c.add_argument("--rtol", type=float, default=0.0)
    args = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    if args.cmd == "save":
        save(args.path, args.quick, args.only, args.old_defaults)
        return 0
    return compare(args.before, args.after, args.rtol)


if __name__ == "__main__":
    sys.exit(main())
