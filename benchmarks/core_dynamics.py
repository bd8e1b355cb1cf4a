"""The compiled multibody core against the Python path: time per solve on the built-in scenes and
the expansion's time with one worker thread and with the default.

* per solve: ``geoddp.solve_scene`` on examples/multibody/*.toml (the scenes' own solver
  settings), ``Result.solve_time_s``, on the compiled core and on the tests' Python oracle
  (tests/oracle_multibody.py); interleaved after one warm-up each, medians;
* per expansion: ``Multibody.expansion`` (first and second order) along the scene's initial
  rollout with ``threads=1`` and ``threads=0`` (the core's default), medians.

``--integrator rk4`` (or any integrator) solves the same scenes with that integrator instead of the
scenes' own, ``--horizon H`` with H steps (the Python rk4 oracle takes ~0.2 s per node and
second-order linearisation).

Run: ``python benchmarks/core_dynamics.py [--runs 3] [--integrator rk4 --horizon 40]``. Timings
only; the tests check the numbers.
"""
from __future__ import annotations

import argparse
import contextlib
import statistics
import time
from pathlib import Path

import numpy as np

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "multibody"


def _oracle():
    """Every model built inside is the tests' Python oracle (tests/oracle_multibody.py)."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from oracle_multibody import oracle_models

    return oracle_models()


def _spec(scene: Path, integrator: str | None, horizon: int | None):
    """A fresh spec per call (solve_scene builds a problem once per spec object: the oracle's
    models inside ``_oracle()``, the compiled ones outside)."""
    from geoddp import load_scene

    spec = load_scene(scene)
    overrides = {k: v for k, v in (("integrator", integrator), ("horizon", horizon)) if v is not None}
    return spec.with_overrides(**overrides) if overrides else spec


def solve_times(scene: Path, runs: int, integrator: str | None = None, horizon: int | None = None) -> dict:
    from geoddp import solve_scene

    out = {"python": [], "compiled": []}
    info = {}
    for r in range(runs + 1):  # first round: warm-up
        for backend in ("python", "compiled"):
            with (_oracle() if backend == "python" else contextlib.nullcontext()):
                res = solve_scene(_spec(scene, integrator, horizon), verbose=False)
            if r > 0:
                out[backend].append(res.solve_time_s)
            info[backend] = (res.iterations, res.cost)
    return {b: (statistics.median(t), *info[b]) for b, t in out.items()}


def _problem(scene: Path, integrator: str | None, horizon: int | None):
    from geoddp.scene import build_problem, initial_controls

    spec = _spec(scene, integrator, horizon)
    return build_problem(spec), initial_controls(spec)


def threads_times(scene: Path, runs: int, integrator: str | None = None, horizon: int | None = None) -> dict:
    problem, U0 = _problem(scene, integrator, horizon)
    model = problem.model
    U = U0 if U0 is not None else np.zeros((problem.horizon, problem.nu))
    Q, V = problem.rollout(U)
    out = {}
    for order in (1, 2):
        for threads in (1, 0):
            model.threads = threads
            ts = []
            for _ in range(runs + 1):
                t0 = time.perf_counter()
                model.expansion(Q, V, U, order=order)
                ts.append(time.perf_counter() - t0)
            out[(order, threads)] = statistics.median(ts[1:])
    model.threads = 0
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--integrator", default=None, help="solve every scene with this integrator")
    ap.add_argument("--horizon", type=int, default=None, help="and this many steps")
    args = ap.parse_args()
    from geoddp.models import compiled

    scenes_own = "the scenes'"
    print(f"default threads: {compiled._core.default_threads()}; integrator: {args.integrator or scenes_own}; "
          f"horizon: {args.horizon or scenes_own}")
    print("| scene | python per solve | compiled per solve | speed-up | iterations | J* python | J* compiled |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    scenes = sorted(EXAMPLES.glob("*.toml"))
    for scene in scenes:
        t = solve_times(scene, args.runs, args.integrator, args.horizon)
        (tp, ip, jp), (tc, ic, jc) = t["python"], t["compiled"]
        print(f"| {scene.stem} | {tp:.3f} s | {tc:.3f} s | {tp / tc:.1f}x | {ip} / {ic} | {jp:.12g} | {jc:.12g} |")
    print()
    print("| scene | order 1, 1 thread | order 1, default | order 2, 1 thread | order 2, default |")
    print("|---|---:|---:|---:|---:|")
    for scene in scenes:
        e = threads_times(scene, args.runs, args.integrator, args.horizon)
        print(f"| {scene.stem} | {1e3 * e[1, 1]:.2f} ms | {1e3 * e[1, 0]:.2f} ms | {1e3 * e[2, 1]:.2f} ms | {1e3 * e[2, 0]:.2f} ms |")


if __name__ == "__main__":
    main()
