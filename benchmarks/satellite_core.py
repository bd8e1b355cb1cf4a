"""The satellite's TSO(3) kernels: this checkout against another (e.g. the last one on numba),
interleaved in ONE process (one compiled core).

The other checkout's package (its ``src/geoddp`` with its built ``_core``) is copied to a temporary
directory as ``geoddp_ref`` (``speed_vs_main.load_package``). Both build every satellite
scene (``examples/satellite_*.toml``) and the 13 hard cases (``examples/hard``) from the same TOML
file and solve them with the same expansion, alternating per solve: [ref, new] x (warm-up +
``--runs``) for first, second and switch on the satellite scenes (timed: medians of the solve's
wall time), once each on the hard cases (the guard only). Reported per row: iterations, J*, the
largest relative difference of the J, gradient-norm, regularisation and step histories between the
two (the guard: 1e-12; the gradient norm relative to its first value), and for the timed rows ms per solve and new / ref. Timings on a
shared machine mean little: compare the ratios of one run.

    python benchmarks/satellite_core.py --ref /tmp/ref_checkout [--runs 11] [--no-hard]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from speed_vs_main import load_package, public_api  # noqa: E402

EXAMPLES = HERE.parent / "examples"
EXPANSIONS = ("first", "second", "switch")


def histories_differ(a, b) -> tuple[float, float, float, float]:
    """Largest differences of the solver histories: J relative to each J and to J(U0) (a problem
    whose J falls by many orders, extreme_weights' 1e8 to 6e-5, amplifies round-off in its late
    iterates relative to their own size); the gradient norm
    relative to the first one (its last entries are round-off, ~1e-11, where a relative difference
    means nothing); regularisation and step relative to each entry. inf if their lengths differ."""
    def rel(x, y, scale=None):
        x, y = np.asarray(x, float), np.asarray(y, float)
        if x.shape != y.shape:
            return float("inf")
        if not x.size:
            return 0.0
        den = np.maximum(np.abs(y) if scale is None else scale, 1e-300)
        return float(np.max(np.abs(x - y) / den))

    g0, j0 = abs(float(b.grad_norm_history[0])), abs(float(b.cost_history[0]))
    return (rel(a.cost_history, b.cost_history), rel(a.cost_history, b.cost_history, j0),
            rel(a.grad_norm_history, b.grad_norm_history, g0),
            max(rel(a.reg_history, b.reg_history), rel(a.step_history, b.step_history)))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ref", type=Path, required=True, help="the other checkout (its src/geoddp built)")
    ap.add_argument("--runs", type=int, default=11)
    ap.add_argument("--no-hard", action="store_true", help="skip the 13 hard cases' history check")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        ref_api = public_api(load_package(args.ref.resolve(), Path(tmp)))
        import geoddp
        import geoddp as api  # the facade: load_scene, solve_scene
        import geoddp_ref.scene as ref_scene
        import geoddp_ref.solver as ref_solver
        from geoddp import scene, solver

        print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; new: {Path(geoddp.__file__).parent}; "
              f"ref: {args.ref} (as geoddp_ref); python benchmarks/satellite_core.py --runs {args.runs}")
        print("\n| scene | expansion | iterations ref / new | J* ref | J* new | J history | J history / J(U0) | "
              "gradient history | regularisation, step | ms / solve ref | new | new / ref |")
        print("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        scenes = sorted(EXAMPLES.glob("satellite_*.toml"))
        hard = [] if args.no_hard else sorted((EXAMPLES / "hard").glob("*.toml"))
        ratios = []
        for path in scenes + hard:
            timed = path in scenes
            new_spec, ref_spec = api.load_scene(path), ref_api.load_scene(path)
            new_p, ref_p = scene.build_problem(new_spec), ref_scene.build_problem(ref_spec)
            for expansion in EXPANSIONS if timed else ("switch",):
                new_o = scene.solver_options(new_spec, expansion=expansion, verbose=False)
                ref_o = ref_scene.solver_options(ref_spec, expansion=expansion, verbose=False)
                tn, tr = [], []
                for rep in range(1 + (args.runs if timed else 0)):
                    t = time.perf_counter()
                    rr = ref_solver.solve(ref_p, ref_o)
                    t1 = time.perf_counter()
                    rn = solver.solve(new_p, new_o)
                    t2 = time.perf_counter()
                    if rep:
                        tr.append(t1 - t)
                        tn.append(t2 - t1)
                dj, dj0, dg, ds = histories_differ(rn, rr)
                row = (f"| {path.stem} | {expansion} | {rr.iterations} / {rn.iterations} | {rr.cost:.13g} | "
                       f"{rn.cost:.13g} | {dj:.1e} | {dj0:.1e} | {dg:.1e} | {ds:.1e} |")
                if timed:
                    mr, mn = statistics.median(tr), statistics.median(tn)
                    ratios.append(mn / mr)
                    row += f" {mr * 1e3:.2f} | {mn * 1e3:.2f} | {mn / mr:.3f} |"
                else:
                    row += " | | |"
                print(row, flush=True)
        if ratios:
            print(f"\nnew / ref per solve over the {len(ratios)} timed rows: {min(ratios):.3f} to {max(ratios):.3f}, "
                  f"median {statistics.median(ratios):.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
