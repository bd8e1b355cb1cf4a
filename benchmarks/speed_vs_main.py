"""This checkout's solver against another checkout's (main), interleaved in ONE process.

The other checkout's package (its ``src`` directory, with its built ``geoddp/_core*.so`` for the
same pin) is copied to a temporary directory as the package ``geoddp_ref`` (every internal import
of geoddp is relative, and the extension's init symbol depends only on the file name ``_core``),
and its ``benchmarks/robots.py`` as ``robots_ref`` importing ``geoddp_ref``. Both libraries then
build the same cases (``robots.CASES``: ur5, panda, solo12, quadrotor by default) and solve them
from the same initial controls, alternating per solve: [ref, new] x (warm-up + ``--runs``)
for each expansion (first, second, switch). Reported: iterations, J*, ms per solve and per
iteration (``solve_time_s`` / iterations, the final check included), new / ref ratios, and whether
J(U0) agrees. Timings on a shared machine mean little: compare only the ratios of one run.

    python benchmarks/speed_vs_main.py --ref /work/main [--runs 5] [--cases ur5 panda]
"""
from __future__ import annotations

import argparse
import importlib
import os
import re
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import robots  # noqa: E402

EXPANSIONS = ("first", "second", "switch")


def load_package(checkout: Path, workdir: Path):
    """The other checkout's package (``src/geoddp`` with its built ``_core``), copied into
    ``workdir`` and imported as ``geoddp_ref``."""
    src = checkout / "src" / "geoddp"
    if not list(src.glob("_core*.so")):
        raise SystemExit(f"{src} has no built _core extension")
    shutil.copytree(src, workdir / "geoddp_ref", ignore=shutil.ignore_patterns("__pycache__"))
    sys.path.insert(0, str(workdir))
    return importlib.import_module("geoddp_ref")


def public_api(package):
    """The module with ``load_scene`` and ``solve_scene`` of an imported geoddp package: the package
    itself (its facade), or its ``api`` module in a checkout from before the facade."""
    return package if hasattr(package, "solve_scene") else importlib.import_module(package.__name__ + ".api")


def load_reference(checkout: Path, workdir: Path):
    """The other checkout's robots module, importing its geoddp as ``geoddp_ref``."""
    load_package(checkout, workdir)
    text = (checkout / "benchmarks" / "robots.py").read_text()
    text = re.sub(r"\bfrom geoddp(\.|\s)", lambda m: "from geoddp_ref" + m.group(1), text)
    text = re.sub(r"\bimport geoddp\b", "import geoddp_ref", text)
    (workdir / "robots_ref.py").write_text(text)
    ref = importlib.import_module("robots_ref")
    assert ref.Multibody.__module__.startswith("geoddp_ref"), ref.Multibody.__module__
    # the reference must run its compiled core: a checkout from before 2026-11-27 whose _core failed
    # to import fell back to the Python path and would silently time it (as happened while
    # SecondOrderTerms was a global pybind11 type); this one does not import without its core
    compiled = importlib.import_module("geoddp_ref.models.compiled")
    if getattr(compiled, "IMPORT_ERROR", None) is not None:
        raise SystemExit(f"geoddp_ref._core does not import ({compiled.IMPORT_ERROR}): it would run the Python path")
    return ref


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ref", type=Path, default=Path("/work/main"), help="the other checkout (default /work/main)")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--cases", nargs="*", default=["ur5", "panda", "solo12", "quadrotor"], choices=list(robots.CASES))
    ap.add_argument("--tol", type=float, default=None,
                    help="an absolute stopping tol for both (e.g. 1e-8: the default of a checkout from before "
                         "the relative test, so that both stop by the same rule); default: each its own defaults")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        ref = load_reference(args.ref.resolve(), Path(tmp))
        import geoddp
        import geoddp_ref
        from geoddp.solver import SolverOptions, solve
        from geoddp_ref.solver import SolverOptions as RefOptions, solve as ref_solve

        print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; new: {Path(geoddp.__file__).parent}; "
              f"ref: {args.ref} (as geoddp_ref); {robots.machine()}")
        print("\n| case | expansion | iterations ref / new | J* ref | J* new | ms / solve ref | new | "
              "ms / it ref | new | new / ref per solve | new / ref per iteration |")
        print("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
        for name in args.cases:
            new_case, ref_case = robots.CASES[name](), ref.CASES[name]()
            pn, pr = new_case.problem, ref_case.problem
            J0n, J0r = pn.total_cost(new_case.U0), pr.total_cost(ref_case.U0)
            if abs(J0n - J0r) > 1e-12 * abs(J0r):
                print(f"# {name}: J(U0) differs: new {J0n!r} ref {J0r!r}")
            for exp in EXPANSIONS:
                rec = {"ref": [], "new": []}
                for i in range(args.runs + 1):
                    stop = {} if args.tol is None else {"tol": args.tol}
                    r_ref = ref_solve(pr, RefOptions(expansion=exp, verbose=False, **stop), initial_controls=ref_case.U0)
                    r_new = solve(pn, SolverOptions(expansion=exp, verbose=False, **stop), initial_controls=new_case.U0)
                    if i:
                        rec["ref"].append(r_ref)
                        rec["new"].append(r_new)
                t = {k: statistics.median(r.solve_time_s for r in v) for k, v in rec.items()}
                it = {k: v[-1].iterations for k, v in rec.items()}
                J = {k: v[-1].cost for k, v in rec.items()}
                per = {k: t[k] / max(it[k], 1) for k in t}
                print(f"| {name} | {exp} | {it['ref']} / {it['new']} | {J['ref']:.12g} | {J['new']:.12g} | "
                      f"{1e3 * t['ref']:.1f} | {1e3 * t['new']:.1f} | {1e3 * per['ref']:.2f} | {1e3 * per['new']:.2f} | "
                      f"{t['new'] / t['ref']:.2f}x | {per['new'] / per['ref']:.2f}x |", flush=True)
        print(f"# load average at the end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
