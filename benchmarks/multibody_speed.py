"""Speed of geoddp on the multibody scenes, next to Crocoddyl FDDP when it is importable.

Per scene (semi-implicit Euler, the scenes' defaults, zero controls as the initial guess or
hover thrust for the quadrotor, for both solvers): geoddp ``solve`` with the chosen expansion
and, if crocoddyl imports, Crocoddyl FDDP on the same problem (``multibody_peers``). The runs
are interleaved (geoddp, FDDP, geoddp, FDDP, ...) after one warm-up solve each, so that the
load of a shared machine hits both alike; the table gives medians.

* time per solve: geoddp ``Result.solve_time_s`` (from the initial rollout to the final
  second-order check; the first run excluded), Crocoddyl the wall time of
  ``SolverFDDP.solve`` (``multibody_peers.solve_crocoddyl``);
* time per iteration: time per solve / accepted iterations (geoddp's includes its final check);
* ratio: geoddp / FDDP.

Run: ``python benchmarks/multibody_speed.py [--runs 5] [--expansion switch] [--scenes ...]``.
Crocoddyl 3.2.1 needs pin 4.0.0 (the ``bench`` extra); without it only geoddp is timed.
"""
from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

SCENES = ("spacecraft_docking", "space_manipulator", "quadrotor")


def _crocoddyl_available() -> bool:
    try:
        import crocoddyl  # noqa: F401
    except ImportError:
        return False
    return True


def measure(name: str, runs: int, expansion: str, with_crocoddyl: bool) -> dict:
    """Median times of geoddp (and Crocoddyl FDDP) on one scene; see the module docstring."""
    from geoddp.scene import builtin as scenes
    from geoddp.solver import SolverOptions, solve

    p = getattr(scenes, name)(integrator="semi_implicit")
    guess = scenes.hover_controls(p) if name == "quadrotor" else np.zeros((p.horizon, p.nu))
    opts = SolverOptions(expansion=expansion, verbose=False)
    if with_crocoddyl:
        import multibody_peers as peers
    geo, cro = [], []
    for i in range(runs + 1):  # run 0: warm-up (imports, caches), not recorded
        r = solve(p, opts, initial_controls=guess)
        c = peers.solve_crocoddyl(p, "fddp", initial_controls=guess) if with_crocoddyl else None
        if i:
            geo.append(r)
            if c is not None:
                cro.append(c)
    out = dict(scene=name, H=p.horizon, nv=p.model.nv, m=p.nu, expansion=expansion,
               iterations=geo[-1].iterations, cost=geo[-1].cost,
               solve_s=statistics.median(g.solve_time_s for g in geo))
    out["iter_ms"] = 1e3 * out["solve_s"] / max(out["iterations"], 1)
    if cro:
        out.update(fddp_iterations=cro[-1]["iterations"], fddp_cost=cro[-1]["cost"],
                   fddp_s=statistics.median(c["time_s"] for c in cro))
        out["fddp_iter_ms"] = 1e3 * out["fddp_s"] / max(out["fddp_iterations"], 1)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5, help="recorded runs per solver (after one warm-up)")
    ap.add_argument("--expansion", default="switch", choices=("first", "second", "switch"))
    ap.add_argument("--scenes", nargs="+", default=list(SCENES), choices=SCENES)
    ap.add_argument("--no-crocoddyl", action="store_true", help="time geoddp only")
    args = ap.parse_args(argv)
    with_cro = not args.no_crocoddyl and _crocoddyl_available()
    print(f"geoddp expansion {args.expansion!r}, semi-implicit Euler, median of {args.runs} interleaved runs"
          + ("; Crocoddyl FDDP th_stop 1e-9" if with_cro else "; crocoddyl not importable: geoddp only"))
    head = "| scene | nv / m | H | geoddp iterations | geoddp s / solve | geoddp ms / iteration |"
    rule = "|---|---|---:|---:|---:|---:|"
    if with_cro:
        head += " FDDP iterations | FDDP s / solve | FDDP ms / iteration | ratio per solve | ratio per iteration | rel. diff. J* |"
        rule += "---:|---:|---:|---:|---:|---:|"
    print(head)
    print(rule)
    for name in args.scenes:
        r = measure(name, args.runs, args.expansion, with_cro)
        row = (f"| {name} | {r['nv']} / {r['m']} | {r['H']} | {r['iterations']} | {r['solve_s']:.3f} | "
               f"{r['iter_ms']:.1f} |")
        if "fddp_s" in r:
            rel = abs(r["cost"] - r["fddp_cost"]) / abs(r["fddp_cost"])
            row += (f" {r['fddp_iterations']} | {r['fddp_s']:.3f} | {r['fddp_iter_ms']:.2f} | "
                    f"{r['solve_s'] / r['fddp_s']:.1f}x | {r['iter_ms'] / r['fddp_iter_ms']:.1f}x | {rel:.1e} |")
        print(row, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
