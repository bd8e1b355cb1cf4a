"""The argument parser of ``geoddp``: one sub-parser per command (run, multibody, compare,
simulate, sweep)."""
from __future__ import annotations

import argparse
from pathlib import Path


def parser() -> argparse.ArgumentParser:
    """The ``geoddp`` command line."""
    from ..data import scene_names
    from ..models.multibody import INTEGRATORS as MULTIBODY_INTEGRATORS
    from ..scene.builtin import NAMES as MULTIBODY_SCENES
    from ..solver.options import EXPANSIONS

    scene_help = ("scene file (TOML: satellite, or [model] kind = \"multibody\" | \"legged\") or a built-in scene's name: "
                  + ", ".join(scene_names()))

    p = argparse.ArgumentParser(prog="geoddp", description="Differential Dynamic Programming on Lie groups")
    sub = p.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="solve a scene and write its results")
    run.add_argument("scene", help=scene_help)
    run.add_argument("--expansion", choices=list(EXPANSIONS), help="override [solver].expansion")
    run.add_argument("--json", type=Path, help="write the result as JSON here")
    run.add_argument("--html", type=Path, help="write a self-contained animated HTML replay here")
    run.add_argument("--plots", type=Path, help="write PNG figures into this directory (satellite: attitude, "
                     "angular velocity, controls; multibody: joint positions and velocities, controls, frame "
                     "errors; both: solver history)")
    run.add_argument("--view", action="store_true", help="replay in a live meshcat viewer (loopback)")
    run.add_argument("--quiet", action="store_true", help="no iteration table")
    mb = sub.add_parser("multibody", help="alias of `run NAME` for a built-in multibody scene, with --integrator")
    mb.add_argument("scene", choices=MULTIBODY_SCENES, help="built-in multibody scene")
    mb.add_argument("--integrator", choices=list(MULTIBODY_INTEGRATORS),
                    help="override the scene's integrator (the files: semi_implicit); variational: the "
                    "paper's forward variational Euler (implicit)")
    mb.add_argument("--expansion", choices=list(EXPANSIONS), help="override [solver].expansion")
    mb.add_argument("--json", type=Path, help="write the result (with configurations and velocities) as JSON here")
    mb.add_argument("--html", type=Path, help="write a self-contained animated HTML replay of the whole model "
                    "(root position and orientation and every joint)")
    mb.add_argument("--plots", type=Path, help="write PNG figures (joints, controls, frame errors, solver history) "
                    "into this directory")
    mb.add_argument("--view", action="store_true", help="replay the whole model in a live meshcat viewer (loopback)")
    mb.add_argument("--quiet", action="store_true")
    cmp_ = sub.add_parser("compare", help="solve a scene with each expansion and compare convergence")
    cmp_.add_argument("scene", help=scene_help)
    cmp_.add_argument("--json", type=Path, help="write a summary JSON here")
    cmp_.add_argument("--plots", type=Path, help="write convergence figures into this directory")
    cmp_.add_argument("--quiet", action="store_true")
    _simulate_parser(sub, scene_help)
    _sweep_parser(sub)
    return p


def _sweep_parser(sub) -> None:
    """``geoddp sweep SWEEP.toml --out DIR ...`` and ``geoddp sweep --summary DIR [--plots DIR]``."""
    sw = sub.add_parser("sweep", help="solve every case of a sweep file on all cores or a Dask cluster; "
                        "or summarise a sweep's results (--summary DIR)")
    sw.add_argument("sweep_file", nargs="?", type=Path, help="sweep file (TOML; see the README's Sweeps section)")
    sw.add_argument("--out", type=Path, help="output folder: results.parquet, parts/, manifest.json")
    sw.add_argument("--workers", type=int, help="local worker processes (default: every core)")
    sw.add_argument("--scheduler", help="address of a running dask.distributed scheduler (tcp://host:8786)")
    sw.add_argument("--resume", action="store_true", help="solve only the cases whose rows --out lacks")
    sw.add_argument("--serial", action="store_true", help="solve in this process, one case after another (no Dask)")
    sw.add_argument("--csv", action="store_true", help="also write results.csv")
    sw.add_argument("--full", action="store_true", help="also write each case's full result as cases/<hash>.json")
    sw.add_argument("--limit", type=int, help="solve at most this many cases now (the rest with --resume)")
    sw.add_argument("--flush-rows", type=int, default=200, help="write a part file every N finished cases "
                    "(and at least every --flush-seconds)")
    sw.add_argument("--flush-seconds", type=float, default=5.0, help="write a part file at least this often (s); "
                    "finished cases are also written on SIGINT, SIGTERM and SIGHUP")
    sw.add_argument("--dashboard", action="store_true", help="start the local cluster's dashboard on 127.0.0.1")
    sw.add_argument("--quiet", action="store_true", help="no progress bar")
    sw.add_argument("--summary", type=Path, metavar="DIR", help="print the summary of the sweep results in DIR")
    sw.add_argument("--plots", type=Path, help="with --summary: write parameter-vs-outcome figures into this folder")


def _simulate_parser(sub, scene_help: str) -> None:
    from ..simulate import POLICIES

    sim = sub.add_parser("simulate", help="fly the scene's plan on a plant (noise, model error): open loop, with the "
                         "DDP gains or MPC; prints the Monte Carlo table")
    sim.add_argument("scene", help=scene_help)
    sim.add_argument("--samples", type=int, help="Monte Carlo samples N (default 1, or the scene's [simulation])")
    sim.add_argument("--seed", type=int, help="root seed (default 0); the same seed gives the same table")
    sim.add_argument("--noise", type=float, help="sigma of N(0, sigma^2) added to the velocity at every step (rad/s, m/s)")
    sim.add_argument("--sensor-noise", type=float, help="sigma of the noise on the measured state (tangent space)")
    sim.add_argument("--plant", action="append", metavar="KEY=VALUE", default=[],
                     help="plant change: inertia_scale, mass_scale, actuator_gain (numbers, comma-separated "
                     "for one per axis or input), integrator (euler | semi_implicit | rk4 | variational), substeps")
    sim.add_argument("--policy", choices=list(POLICIES), help="closed-loop policy flown beside open loop (default feedback)")
    sim.add_argument("--steps", type=int, help="plan steps to simulate (default H; more only with --policy mpc)")
    sim.add_argument("--mpc-horizon", type=int, help="MPC window H_mpc in steps (default min(100, H))")
    sim.add_argument("--mpc-every", type=int, help="re-solve every this many steps (default 1)")
    sim.add_argument("--mpc-max-iter", type=int, help="iteration cap per re-solve (default 3)")
    sim.add_argument("--workers", type=int, help="processes for the samples (default 1; the same numbers)")
    sim.add_argument("--json", type=Path, help="write the statistics and per-sample measures as JSON here")
    sim.add_argument("--plots", type=Path, help="write the bundle and error-histogram figures into this directory")
    sim.add_argument("--html", type=Path, help="write an HTML replay of the first sample of the closed-loop policy "
                     "beside an animated ghost of the plan")
