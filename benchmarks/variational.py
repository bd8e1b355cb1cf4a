"""The forward variational Euler integrator on the compiled core, against semi-implicit Euler.

Per built-in multibody scene (its own horizon and weights; stopping tests tightened to tol = 0,
grad_tol = 1e-9 as in the README's variational table): geoddp first, second and switch with the
variational integrator, and second with semi-implicit Euler, all on the compiled core. Runs are
interleaved (one of each in turn) after one warm-up round; the table gives medians of
``Result.solve_time_s``. The ratio is variational second-order time over semi-implicit
second-order time on the same scene (issue 12's target: at most 3x).

``--python`` adds one run of the Python oracle's variational switch solve per scene (its second
order is differences of differences; slow).

Run: ``python benchmarks/variational.py [--runs 3] [--python]``.
"""
from __future__ import annotations

import argparse
import os
import statistics
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "multibody"
SCENES = ("spacecraft_docking", "space_manipulator", "quadrotor")
CASES = (("variational", "first"), ("variational", "second"), ("variational", "switch"), ("semi_implicit", "second"))


def _solve(scene: str, integrator: str, expansion: str):
    from geoddp.api import load_scene, solve_scene

    spec = load_scene(EXAMPLES / f"{scene}.toml").with_overrides(integrator=integrator)
    return solve_scene(spec, verbose=False, expansion=expansion, tol=0.0, grad_tol=1e-9)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--python", action="store_true", help="one run of the Python oracle's switch solve per scene")
    args = ap.parse_args()
    print("| scene | integrator | expansion | iterations | J* | ‖∇J‖ | solve time (s) | variational second / semi-implicit second |")
    print("|---|---|---|---:|---:|---:|---:|---:|")
    for scene in SCENES:
        times = {c: [] for c in CASES}
        last = {}
        for r in range(args.runs + 1):  # round 0: warm-up
            for c in CASES:
                res = _solve(scene, *c)
                if r > 0:
                    times[c].append(res.solve_time_s)
                last[c] = res
        med = {c: statistics.median(t) for c, t in times.items()}
        ratio = med["variational", "second"] / med["semi_implicit", "second"]
        for c in CASES:
            res = last[c]
            extra = f"{ratio:.2f}x" if c == ("variational", "second") else ""
            print(f"| {scene} | {c[0]} | {c[1]} | {res.iterations} | {res.cost:.12f} | {res.grad_norm_history[-1]:.1e} | "
                  f"{med[c]:.3f} | {extra} |", flush=True)
        if args.python:
            os.environ["GEODDP_MULTIBODY_BACKEND"] = "python"
            res = _solve(scene, "variational", "switch")
            os.environ.pop("GEODDP_MULTIBODY_BACKEND")
            print(f"| {scene} | variational (Python oracle) | switch | {res.iterations} | {res.cost:.12f} | "
                  f"{res.grad_norm_history[-1]:.1e} | {res.solve_time_s:.3f} | |", flush=True)


if __name__ == "__main__":
    main()
