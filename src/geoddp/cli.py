"""Command line: ``geoddp run SCENE``, ``geoddp compare SCENE`` and ``geoddp simulate SCENE``,
where SCENE is a scene file (satellite or multibody) or a built-in scene's name
(``satellite_paper``, ``quadrotor``, ...);
``geoddp multibody NAME`` is an alias of ``geoddp run NAME`` for the built-in multibody scenes.

Exit codes: 0 converged (a verified local minimum, see the README's status table), 1 stopped
without converging (stalled, max_iter, saddle, non-finite, ...), 2 bad input (one line on stderr,
no traceback; outputs are checked before the solve), 3 an internal error (one line; a bug to
report), 128 + N on signal N (130 SIGINT, 143 SIGTERM, 129 SIGHUP: the solve stops, the line says
which outputs were written; a sweep first writes every case that finished, and the line says how
many cases are on disk and the command that resumes it). Every output file is written atomically
(geoddp.outputs).
"""
from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path

from . import interrupts
from .interrupts import Interrupted
from .validate import InputError

EXIT_CONVERGED, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT, EXIT_INTERNAL = 0, 1, 2, 3

_WRITTEN: list[str] = []  # outputs written by this run, for the exit message


def _on_signal(signum, frame) -> None:
    # recorded first: if the exception lands in a gc callback, Python drops it, and the sweep's
    # loop raises it again from the record (geoddp.interrupts)
    interrupts.record(signum)
    if not interrupts.deferring():  # else: finished work is being written; raised when that ends
        raise Interrupted(signum)


def _wrote(path) -> None:
    _WRITTEN.append(str(path))
    print(f"wrote {path}")


def _check_outputs(args, inputs) -> None:
    from .outputs import check_outputs

    outs = {f"--{k}": getattr(args, k, None) for k in ("json", "html", "plots")}
    check_outputs(outs, inputs=inputs, directories=("--plots",))


def _parser() -> argparse.ArgumentParser:
    from .data import scene_names
    from .models.multibody import INTEGRATORS as MULTIBODY_INTEGRATORS
    from .scene.builtin import NAMES as MULTIBODY_SCENES
    from .solver.options import EXPANSIONS

    scene_help = ("scene file (TOML: satellite, or [model] kind = \"multibody\") or a built-in scene's name: "
                  + ", ".join(scene_names()))

    p = argparse.ArgumentParser(prog="geoddp", description="Differential Dynamic Programming on Lie groups")
    sub = p.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="solve a scene and write its results")
    run.add_argument("scene", help=scene_help)
    run.add_argument("--expansion", choices=list(EXPANSIONS), help="override [solver].expansion")
    run.add_argument("--json", type=Path, help="write the result as JSON here")
    run.add_argument("--html", type=Path, help="write a self-contained animated HTML replay here")
    run.add_argument("--plots", type=Path, help="write PNG figures into this directory")
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
    """``geoddp sweep SWEEP.toml --out DIR ...`` and ``geoddp sweep --summary DIR [--plots DIR]`` (issue 17)."""
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


def _multibody(args) -> int:
    """``geoddp multibody NAME``: ``geoddp run NAME`` with an optional integrator override."""
    from .scene.builtin import scene_spec

    # The built-in scene's file, with its initial controls (hover thrust for the quadrotor).
    return _solve_and_report(scene_spec(args.scene, integrator=args.integrator), args)


def _print_limits(result) -> None:
    """With control limits ([limits]): how many (node, input) pairs sit on a bound, per input, and
    the KKT residual (max |projected gradient|) at the returned controls."""
    if getattr(result, "limits", None) is None:
        return
    act = result.active_set
    per_input = ", ".join(f"u_{j + 1}: {int((act[:, j] != 0).sum())}" for j in range(act.shape[1]))
    kkt = (result.extra.get("optimality") or {}).get("kkt_residual")
    print(f"limits: {int((act != 0).sum())} of {act.size} (node, input) pairs on a bound ({per_input})"
          + (f"  KKT residual = {kkt:.3e}" if kkt is not None else ""))


def _summary_row(name: str, r) -> str:
    return (f"| {name:8s} | {r.iterations:5d} | {r.cost:.12f} | {r.grad_norm:9.2e} | "
            f"{r.attitude_error_deg:8.4f} | {r.solve_time_s * 1e3:9.1f} | {r.status} |")


def _run(args) -> int:
    from .scene import load_scene

    return _solve_and_report(load_scene(args.scene), args)


def _solve_and_report(spec, args) -> int:
    from .api import solve_scene
    from .scene import MultibodySceneSpec, terminal_frame_errors

    multibody = isinstance(spec, MultibodySceneSpec)
    if multibody:
        # Refused before solving, as bad input: the figures plot a single rigid body's attitude.
        # --html and --view replay the whole model (as `geoddp multibody NAME` does).
        if getattr(args, "plots", None):
            raise InputError("--plots", "not supported for multibody scenes (the figures plot a single rigid "
                             "body's attitude); use --json OUT.json, --html OUT.html or --view for a replay")
    _check_outputs(args, [getattr(spec, "source", None), getattr(spec, "urdf", None)])
    overrides = {"expansion": args.expansion} if args.expansion else {}
    result = solve_scene(spec, verbose=not args.quiet, **overrides)
    if multibody:
        print(f"J* = {result.cost:.12f}  iterations = {result.iterations}  ||grad|| = {result.grad_norm:.3e}  "
              f"solve time = {result.solve_time_s:.3f} s")
        for e in terminal_frame_errors(spec, result.configurations[-1]):
            parts = [f"position error = {e['position_error_m']:.3e} m"] if "position_error_m" in e else []
            parts += [f"rotation error = {e['rotation_error_deg']:.4f} deg"] if "rotation_error_deg" in e else []
            print(f"terminal {e['type']} {e['frame']!r}: " + "  ".join(parts))
    else:
        print(f"J* = {result.cost:.12f}  iterations = {result.iterations}  ||grad|| = {result.grad_norm:.3e}  "
              f"attitude error = {result.attitude_error_deg:.4f} deg  |Omega_H - Omega_d| = "
              f"{result.angular_velocity_error:.3e} rad/s  solve time = {result.solve_time_s:.3f} s")
    _print_limits(result)
    print(f"status: {result.status} ({result.message})")
    if args.json:
        _wrote(result.write_json(args.json))
    _visualise(result, args)
    return EXIT_CONVERGED if result.converged else EXIT_NOT_CONVERGED


def _visualise(result, args) -> None:
    if not (getattr(args, "html", None) or getattr(args, "plots", None) or getattr(args, "view", False)):
        return
    from . import viz

    if getattr(args, "plots", None):
        for path in viz.plot_trajectory(result, args.plots).values():
            _wrote(getattr(path, 'path', path))
    if getattr(args, "html", None):
        _wrote(viz.export_html(result, args.html))
    if getattr(args, "view", False):
        try:
            viz.replay(result, open_browser=False)
            input("Replaying in meshcat; press Enter to quit.\n") if sys.stdin.isatty() else None
        except viz.ViewerUnavailable as exc:
            print(f"viewer unavailable: {exc}" + (" (the static HTML was written)" if args.html else
                                                    " (use --html OUT.html for a static replay)"), file=sys.stderr)


def _compare(args) -> int:
    from .api import solve_scene
    from .outputs import strict_json, write_atomic
    from .scene import load_scene
    from .solver.options import EXPANSIONS

    spec0 = load_scene(args.scene)
    _check_outputs(args, [getattr(spec0, "source", None), getattr(spec0, "urdf", None)])
    results = {}
    for exp in EXPANSIONS:
        results[exp] = solve_scene(args.scene, verbose=False, expansion=exp, record_controls=True)
    print("| expansion | iters | J* | ||grad|| | att. err (deg) | time (ms) | status |")
    print("|---|---|---|---|---|---|---|")
    for name, r in results.items():
        print(_summary_row(name, r))
    if args.json:
        write_atomic(args.json, strict_json({k: {"cost": r.cost, "iterations": r.iterations, "grad_norm": r.grad_norm,
                                             "cost_history": r.cost_history.tolist(),
                                             "grad_norm_history": r.grad_norm_history.tolist(),
                                             "solve_time_s": r.solve_time_s, "status": r.status}
                                         for k, r in results.items()}))
        _wrote(args.json)
    from .api import initial_controls
    from .reference import lbfgs
    from .scene import build_problem, load_scene

    spec = load_scene(args.scene)
    ref = lbfgs(build_problem(spec), initial_controls=initial_controls(spec))
    print(f"| L-BFGS (scipy, exact gradient) | {ref.iterations:5d} | {ref.cost:.12f} | {ref.grad_norm:9.2e} | | "
          f"{ref.time_history[-1] * 1e3:9.1f} | {ref.message} |")
    if args.plots:
        from . import viz

        figs = viz.plot_convergence(results, args.plots, reference_cost=ref.cost, reference_label="L-BFGS (scipy)",
                                    reference_history=ref.cost_history)
        for path in figs.values():
            _wrote(getattr(path, 'path', path))
    return EXIT_CONVERGED if all(r.converged for r in results.values()) else EXIT_NOT_CONVERGED


# ---------------------------------------------------------------------- geoddp simulate (issue 16)
def _simulate_parser(sub, scene_help: str) -> None:
    from .simulate import POLICIES

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


def _plant_value(key: str, text: str):
    if key == "integrator":
        return text
    try:
        vals = [float(x) for x in text.split(",")]
    except ValueError:
        raise InputError(f"--plant {key}", f"expected a number or comma-separated numbers, got {text!r}") from None
    if key == "substeps":
        if len(vals) != 1 or not vals[0].is_integer():
            raise InputError("--plant substeps", f"expected a positive integer, got {text!r}")
        return int(vals[0])
    return vals[0] if len(vals) == 1 else vals


def _simulate(args) -> int:
    """``geoddp simulate SCENE ...``: solve the plan, fly it, print the table (exit 0; 1 if the
    plan did not converge; 2 on bad input)."""
    import dataclasses

    import numpy as np

    from .outputs import strict_json, write_atomic
    from .scene import load_scene
    from .simulate import SimulationSpec, simulate_scene

    spec = load_scene(args.scene)
    _check_outputs(args, [getattr(spec, "source", None), getattr(spec, "urdf", None)])
    base = getattr(spec, "simulation", None) or SimulationSpec()  # the scene's [simulation] table, if any
    plant = dict(base.plant)
    for item in args.plant:
        key, sep, val = item.partition("=")
        if not sep or not key:
            raise InputError("--plant", f"expected KEY=VALUE, got {item!r}")
        plant[key.strip()] = _plant_value(key.strip(), val.strip())
    over = {k: val for k, val in (("samples", args.samples), ("seed", args.seed), ("noise", args.noise),
                                  ("sensor_noise", args.sensor_noise), ("policy", args.policy), ("steps", args.steps),
                                  ("mpc_horizon", args.mpc_horizon), ("mpc_every", args.mpc_every),
                                  ("mpc_max_iter", args.mpc_max_iter), ("workers", args.workers)) if val is not None}
    try:
        sim = dataclasses.replace(base, plant=plant, **over)
    except InputError as exc:  # name the command-line option
        name = exc.parameter.removeprefix("simulation.")
        raise InputError(f"--plant {name[6:]}" if name.startswith("plant.") else "--" + name.replace("_", "-"),
                         exc.detail) from None
    mc = simulate_scene(spec, sim)
    plan = mc.plan
    print(f"plan: J* = {plan.cost:.10f}  status: {plan.status}")
    print(f"simulated {sim.samples} sample(s) x {', '.join(mc.policies)}, seed {sim.seed}, noise {sim.noise}, "
          f"plant {mc.plant or 'as planned'}  ({mc.wall_time_s:.2f} s)")
    if sim.samples > 1 and not any(any(float(x) != 0.0 for x in np.ravel(getattr(sim, k))) for k in ("noise", "sensor_noise", "force_noise")):
        # Samples differ only in their noise: say so rather than print N equal runs as a distribution.
        print(f"note: no noise (noise, sensor_noise and force_noise are 0), so the {sim.samples} samples are "
              "identical; add e.g. --noise 0.001 (the authors' test) for a distribution")
    print(mc.table())
    if args.json:
        write_atomic(args.json, strict_json({"scene": spec.name, "simulation": dataclasses.asdict(sim), **mc.to_dict()}))
        _wrote(args.json)
    if args.plots:
        from .viz import plot_simulation

        for path in plot_simulation(mc, args.plots).values():
            _wrote(path)
    if args.html:
        from .viz import export_html

        run = mc.runs[mc.policies[-1]][0]
        _wrote(export_html(run.to_result(plan), args.html, plan=plan))
    return EXIT_CONVERGED if plan.converged else EXIT_NOT_CONVERGED


def _sweep(args) -> int:
    """``geoddp sweep``: run a sweep (exit 0 when every case is in the table, 1 when --limit left
    some for --resume) or summarise one (--summary)."""
    from .sweep import SweepInterrupted, read_table, run_sweep
    from .sweep.summary import plots, summary

    if args.summary is not None:
        if not args.summary.is_dir():
            raise InputError("--summary", f"expected a sweep output folder, got {str(args.summary)!r}")
        df = read_table(args.summary)
        print(summary(df))
        if args.plots is not None:
            for path in plots(df, args.plots):
                _wrote(path)
        return EXIT_CONVERGED
    if args.sweep_file is None or args.out is None:
        raise InputError("sweep", "expected a sweep file and --out DIR (or --summary DIR)")
    if args.plots is not None:
        raise InputError("--plots", "expected together with --summary DIR")
    if args.flush_rows < 1:
        raise InputError("--flush-rows", f"expected a number of rows >= 1, got {args.flush_rows}")
    if not args.flush_seconds > 0:  # also NaN
        raise InputError("--flush-seconds", f"expected a number of seconds > 0, got {args.flush_seconds}")
    try:
        run = run_sweep(args.sweep_file, args.out, workers=args.workers, scheduler=args.scheduler, serial=args.serial,
                        resume=args.resume, csv=args.csv, full=args.full, limit=args.limit,
                        flush_rows=args.flush_rows, flush_seconds=args.flush_seconds,
                        progress=None if args.quiet else sys.stderr, dashboard=args.dashboard)
    except SweepInterrupted as exc:  # the finished cases are on disk: say how many and how to go on
        exc.note += f"; resume with: {_resume_command(args)}"
        raise
    print(f"sweep: {run.total} cases: {run.skipped} already done, {run.solved} solved now ({run.failed} raised), "
          f"{run.wall_time_s:.1f} s")
    if run.table is not None:
        _wrote(run.table)
        return EXIT_CONVERGED
    print(f"sweep: incomplete; rows so far in {args.out / 'parts'}; finish with: {_resume_command(args)}")
    return EXIT_NOT_CONVERGED


def _resume_command(args) -> str:
    """The command that finishes a sweep: the same sweep file, folder and executor, with --resume
    (the cases on disk are skipped by their hashes)."""
    import shlex

    cmd = ["geoddp", "sweep", str(args.sweep_file), "--out", str(args.out), "--resume"]
    if args.serial:
        cmd.append("--serial")
    elif args.scheduler:
        cmd += ["--scheduler", args.scheduler]
    elif args.workers:
        cmd += ["--workers", str(args.workers)]
    cmd += [flag for flag, on in (("--csv", args.csv), ("--full", args.full)) if on]
    return shlex.join(cmd)


MAX_MESSAGE = 2000  # characters of an error line; a message quoting a huge value keeps its two ends


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    if len(text) > MAX_MESSAGE:  # the start names the parameter, the end the file: both kept
        cut = len(text) - MAX_MESSAGE
        text = f"{text[:MAX_MESSAGE // 2]} [... {cut} characters ...] {text[-MAX_MESSAGE // 2:]}"
    return text


def _written() -> str:
    return "wrote " + ", ".join(_WRITTEN) if _WRITTEN else "no output written"


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    _WRITTEN.clear()
    interrupts.clear()
    previous = {}
    for sig in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT):
        if sig == signal.SIGINT and signal.getsignal(sig) is not signal.default_int_handler:
            continue  # SIGINT ignored (a background job) or handled by the caller: leave it so
        try:
            previous[sig] = signal.signal(sig, _on_signal)
        except (ValueError, OSError):  # not the main thread
            pass
    try:
        handler = {"run": _run, "compare": _compare, "multibody": _multibody, "simulate": _simulate,
                   "sweep": _sweep}[args.command]
        import numpy as np

        # Backstop: every numeric path checks finiteness itself (the solver's status, the
        # validators' messages); numpy's warnings would put lines on stderr before geoddp's own.
        with np.errstate(all="ignore"):
            return handler(args)
    except (InputError, OSError) as exc:
        # OSError: a missing, unreadable or unwritable file (the message names it)
        print(f"geoddp: error: {_one_line(exc)}" + (f" ({_written()})" if _WRITTEN else ""), file=sys.stderr)
        return EXIT_BAD_INPUT
    except MemoryError:
        print("geoddp: error: out of memory (the problem is too large for this machine)"
              + (f" ({_written()})" if _WRITTEN else ""), file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt as exc:
        signum = exc.signum if isinstance(exc, Interrupted) else signal.SIGINT
        # a sweep's note: the cases on disk and the command that resumes it
        note = getattr(exc, "note", "") or _written()
        print(f"geoddp: interrupted by {signal.Signals(signum).name}; {note}", file=sys.stderr)
        return 128 + int(signum)
    except Exception as exc:  # a bug: one line, not a traceback (GEODDP_TRACEBACK=1 shows it)
        import os

        got = interrupts.received()
        if got:  # a library turned the interrupt into another exception (a meshcat/zmq call cut short)
            print(f"geoddp: interrupted by {signal.Signals(got[0]).name}; {_written()}", file=sys.stderr)
            return 128 + int(got[0])

        if os.environ.get("GEODDP_TRACEBACK"):
            raise
        print(f"geoddp: internal error: {type(exc).__name__}: {_one_line(exc)}; {_written()}", file=sys.stderr)
        return EXIT_INTERNAL
    finally:
        viewer = sys.modules.get("geoddp.viz.meshcat_replay")
        if viewer is not None:  # --view: no meshcat server outlives the run, whatever ended it
            viewer.stop_servers()
        for sig, h in previous.items():
            signal.signal(sig, h)
        interrupts.clear()  # a record outliving the run would stop a later sweep in this process


if __name__ == "__main__":
    sys.exit(main())
