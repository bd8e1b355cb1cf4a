"""The forward variational Euler integrator on the compiled core, against semi-implicit Euler.

Per built-in multibody scene (its own horizon and weights; stopping tests tightened to tol = 0,
grad_tol = 1e-9 as in the benchmarks page's variational table): geoddp first, second and switch with the
variational integrator, and second with semi-implicit Euler, all on the compiled core. Runs are
interleaved (one of each in turn) after one warm-up round; the table gives medians of
``Result.solve_time_s``. The ratio is variational second-order time over semi-implicit
second-order time on the same scene (the target: at most 3x).

``--python`` adds one run of the Python oracle's variational switch solve per scene (its second
order is differences of differences; slow).

``--ref CHECKOUT`` instead times this code against another checkout with its own built core
(``benchmarks/speed_vs_main.py``'s ``geoddp_ref``), side by side in one process: the variational
second order and switch, and semi-implicit second order as the control, alternating per solve.
With ``--robots`` it also times the whole variational expansion of a trajectory (first order, and
the second order in the solver's factored form) on the UR5, Panda and Solo12 of
example-robot-data (gravity off, H = 100, dt = 0.01, controls 0.2 N(0, 1), seeded), one and two
threads, alternating per call between the two cores; medians, microseconds a node.

Run: ``python benchmarks/variational.py [--runs 3] [--python] [--ref /tmp/ref_checkout [--robots]]``.
"""
from __future__ import annotations

import argparse
import statistics
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "multibody"
SCENES = ("spacecraft_docking", "space_manipulator", "quadrotor")
CASES = (("variational", "first"), ("variational", "second"), ("variational", "switch"), ("semi_implicit", "second"))


def _oracle():
    """Every model built inside is the tests' Python oracle (tests/oracle_multibody.py)."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from oracle_multibody import oracle_models

    return oracle_models()


def _solve(scene: str, integrator: str, expansion: str, api=None):
    """One solve of a built-in scene with the benchmarks table's stopping tests, through ``api``
    (geoddp by default; side_by_side passes the reference checkout's)."""
    if api is None:
        import geoddp as api

    spec = api.load_scene(EXAMPLES / f"{scene}.toml").with_overrides(integrator=integrator)
    return api.solve_scene(spec, verbose=False, expansion=expansion, tol=0.0, grad_tol=1e-9)


def side_by_side(ref_checkout: Path, runs: int, robots: bool = False) -> None:
    """This code against ``ref_checkout`` in one process, alternating per solve (new / ref ratios)."""
    import sys
    import tempfile
    import time

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from speed_vs_main import load_reference, public_api

    import geoddp as new_api

    with tempfile.TemporaryDirectory() as tmp:
        load_reference(ref_checkout, Path(tmp))
        import geoddp_ref

        ref_api = public_api(geoddp_ref)

        print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; this checkout against {ref_checkout}, "
              f"medians of {runs} rounds after one warm-up, alternating per solve")
        print("| scene | integrator | expansion | iterations (new, ref) | J* new | J* ref | new (s) | ref (s) | new / ref |")
        print("|---|---|---|---:|---:|---:|---:|---:|---:|")
        for scene in SCENES:
            for integrator, expansion in (("variational", "second"), ("variational", "switch"), ("semi_implicit", "second")):
                times: dict[str, list[float]] = {"new": [], "ref": []}
                last = {}
                for r in range(runs + 1):
                    for side, api in (("new", new_api), ("ref", ref_api)):
                        res = _solve(scene, integrator, expansion, api)
                        if r:
                            times[side].append(res.solve_time_s)
                        last[side] = res
                a, b = statistics.median(times["new"]), statistics.median(times["ref"])
                print(f"| {scene} | {integrator} | {expansion} | {last['new'].iterations}, {last['ref'].iterations} | "
                      f"{last['new'].cost:.12f} | {last['ref'].cost:.12f} | {a:.3f} | {b:.3f} | {a / b:.3f} |", flush=True)
        if robots:
            print()
            robots_side_by_side(runs)


def robots_side_by_side(runs: int) -> None:
    """The variational expansion on example-robot-data's robots, this core against geoddp_ref's
    (already imported by side_by_side), alternating per call."""
    import time

    import example_robot_data
    import numpy as np
    import pinocchio as pin

    import geoddp.models.compiled as new_compiled
    import geoddp_ref.models.compiled as ref_compiled
    from geoddp.models.multibody import Multibody

    print("| robot (nv) | order | threads | new (us a node) | ref (us a node) | new / ref |")
    print("|---|---:|---:|---:|---:|---:|")
    H = 100
    for name in ("ur5", "panda", "solo12"):
        model = example_robot_data.load(name).model
        mb = Multibody.from_model(model, dt=0.01, integrator="variational", gravity=False)
        rng = np.random.default_rng(0)
        q0 = pin.integrate(mb.pin_model, pin.neutral(mb.pin_model), 0.3 * rng.normal(size=mb.nv))
        U = 0.2 * rng.normal(size=(H, mb.nu))
        Q, V = mb.rollout(q0, np.zeros(mb.nv), U)
        for order in (1, 2):
            for threads in (1, 2):
                def call(core):
                    if order == 2:
                        core.expansion_contracted(mb.pin_model, mb.actuation, mb.dt, 3, Q, V, U, threads)
                    else:
                        core.expansion(mb.pin_model, mb.actuation, mb.dt, 3, Q, V, U, 1, threads)

                times: dict[str, list[float]] = {"new": [], "ref": []}
                for r in range(3 * runs + 1):
                    for side, core in (("new", new_compiled._core), ("ref", ref_compiled._core)):
                        t0 = time.perf_counter()
                        call(core)
                        if r:
                            times[side].append((time.perf_counter() - t0) / H * 1e6)
                a, b = statistics.median(times["new"]), statistics.median(times["ref"])
                print(f"| {name} ({mb.nv}) | {order} | {threads} | {a:.1f} | {b:.1f} | {a / b:.3f} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--python", action="store_true", help="one run of the Python oracle's switch solve per scene")
    ap.add_argument("--ref", type=Path, help="another checkout (with its core built) to time against, side by side")
    ap.add_argument("--robots", action="store_true", help="with --ref: also the variational expansion on robots")
    args = ap.parse_args()
    if args.ref is not None:
        side_by_side(args.ref.resolve(), args.runs, args.robots)
        return
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
            with _oracle():
                res = _solve(scene, "variational", "switch")
            print(f"| {scene} | variational (Python oracle) | switch | {res.iterations} | {res.cost:.12f} | "
                  f"{res.grad_norm_history[-1]:.1e} | {res.solve_time_s:.3f} | |", flush=True)


if __name__ == "__main__":
    main()
