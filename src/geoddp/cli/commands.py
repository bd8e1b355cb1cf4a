"""The subcommands of ``geoddp``: each takes the parsed arguments, calls the API and returns an
exit code (:data:`EXIT_CONVERGED` or :data:`EXIT_NOT_CONVERGED`); bad input raises
:class:`~geoddp.validate.InputError`, which :func:`geoddp.cli.main` maps to exit code 2.
"""
from __future__ import annotations

import sys

from ..validate import InputError

EXIT_CONVERGED, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT, EXIT_INTERNAL = 0, 1, 2, 3

WRITTEN: list[str] = []  # outputs written by this run, for the exit message


def wrote(path) -> None:
    """Note and print an output file this run wrote."""
    WRITTEN.append(str(path))
    print(f"wrote {path}")


def check_output_args(args, inputs) -> None:
    """Refuse, before a solve, output paths that could not be written or that name an input."""
    from ..output_files import check_outputs

    outs = {f"--{k}": getattr(args, k, None) for k in ("json", "html", "plots")}
    check_outputs(outs, inputs=inputs, directories=("--plots",))


def _refuse_legged(spec, command: str) -> None:
    """InputError naming ``scene``: ``geoddp COMMAND`` has no legged form (``geoddp run`` solves it)."""
    if getattr(spec, "kind", None) == "legged":
        raise InputError("scene", f"{spec.name!r} is a legged scene: `geoddp {command}` takes satellite and multibody "
                         f"scenes; solve it with `geoddp run {spec.name}` (--expansion first | second | switch)")


def _multibody(args) -> int:
    """``geoddp multibody NAME``: ``geoddp run NAME`` with an optional integrator override."""
    from ..scene.builtin import scene_spec

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


def _print_constraints(result) -> None:
    """With hard constraints ([[constraints]], [[terminal_constraints]]): per constraint its largest
    violation and active nodes, and the outer and inner iteration counts."""
    report = result.extra.get("constraints")
    if not report:
        return
    for item in report["items"]:
        print(f"constraint {item['name']!r} ({item['type']}, {item['where']}): max violation = "
              f"{item['max_violation']:.3e}  active at {item['active_nodes']} of {len(item['nodes'])} nodes")
    print(f"constraints: max violation = {report['max_violation']:.3e} (tol {report['constraint_tol']:.0e})  "
          f"{report['outer_iterations']} outer, {report['inner_iterations']} inner iterations")


def _summary_row(name: str, r) -> str:
    return (f"| {name:8s} | {r.iterations:5d} | {r.cost:.12f} | {r.grad_norm:9.2e} | "
            f"{r.attitude_error_deg:8.4f} | {r.solve_time_s * 1e3:9.1f} | {r.status} |")


def _run(args) -> int:
    from ..scene import load_scene

    return _solve_and_report(load_scene(args.scene), args)


def _solve_and_report(spec, args) -> int:
    from ..scene import MultibodySceneSpec, terminal_frame_errors
    from ..scene.solve import solve_scene

    multibody = isinstance(spec, MultibodySceneSpec)
    legged = getattr(spec, "kind", None) == "legged"
    check_output_args(args, [getattr(spec, "source", None), getattr(spec, "urdf", None)])
    overrides = {"expansion": args.expansion} if args.expansion else {}
    result = solve_scene(spec, verbose=not args.quiet, **overrides)
    if legged:
        sched = result.model["contact_schedule"]
        print(f"J* = {result.cost:.12f}  iterations = {result.iterations}  ||grad|| = {result.grad_norm:.3e}  "
              f"solve time = {result.solve_time_s:.3f} s")
        print(f"contact schedule: {result.horizon} nodes ({sum(sched['impulse'])} impulse) on feet "
              f"{', '.join(sched['feet'])}, dt = {result.dt} s")
    elif multibody:
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
    _print_constraints(result)
    print(f"status: {result.status} ({result.message})")
    if args.json:
        wrote(result.write_json(args.json))
    _visualise(result, args, spec if multibody else None, spec if legged else None)
    return EXIT_CONVERGED if result.converged else EXIT_NOT_CONVERGED


def _visualise(result, args, multibody_spec=None, legged_spec=None) -> None:
    """--plots, --html and --view of a solved scene; ``multibody_spec``: the multibody scene solved
    (its terminal frame terms are the targets of frame_errors.png), None for a satellite;
    ``legged_spec``: the legged scene solved (its contact problem gives the forces, the contact
    points and the ground of the figures and the replay)."""
    if not (getattr(args, "html", None) or getattr(args, "plots", None) or getattr(args, "view", False)):
        return
    from .. import viz

    if legged_spec is not None:
        _visualise_legged(result, args, legged_spec)
        return
    if getattr(args, "plots", None):
        if multibody_spec is not None:
            paths = list(viz.plot_multibody(result, args.plots, scene=multibody_spec).values())
        else:
            paths = [*viz.plot_trajectory(result, args.plots).values(),
                     *viz.plot_solver_history(result, args.plots).values()]
        for path in paths:
            wrote(path)
    if getattr(args, "html", None):
        wrote(viz.export_html(result, args.html))
    if getattr(args, "view", False):
        try:
            viz.replay(result, open_browser=False)
            input("Replaying in meshcat; press Enter to quit.\n") if sys.stdin.isatty() else None
        except viz.ViewerUnavailable as exc:
            print(f"viewer unavailable: {exc}" + (" (the static HTML was written)" if args.html else
                                                    " (use --html OUT.html for a static replay)"), file=sys.stderr)


def _visualise_legged(result, args, spec) -> None:
    """--plots (joints, controls, contact forces, friction-cone margins, solver history), --html
    and --view of a legged scene, with the ground, contact points and force arrows. The replay
    draws the robot's collision geometry: its visual meshes (ANYmal: 30 MB) would make a page of
    about 16 MB."""
    from .. import viz
    from ..scene import build_problem

    problem = build_problem(spec)
    problem = getattr(problem, "problem", problem)  # a scene with constraints: its contact problem
    if getattr(args, "plots", None):
        for path in viz.legged_figures(result, problem, args.plots):
            wrote(path)
    if getattr(args, "html", None):
        wrote(viz.export_legged_html(result, problem, args.html, geometry="collision"))
    if getattr(args, "view", False):
        try:
            viz.replay_legged(result, problem, open_browser=False, geometry="collision")
            input("Replaying in meshcat; press Enter to quit.\n") if sys.stdin.isatty() else None
        except viz.ViewerUnavailable as exc:
            print(f"viewer unavailable: {exc}" + (" (the static HTML was written)" if args.html else
                                                    " (use --html OUT.html for a static replay)"), file=sys.stderr)


def _compare(args) -> int:
    from ..output_files import strict_json, write_atomic
    from ..scene import build_problem, initial_controls, load_scene
    from ..scene.solve import solve_scene
    from ..solver.options import EXPANSIONS
    from ..solver.reference import lbfgs

    spec0 = load_scene(args.scene)
    _refuse_legged(spec0, "compare")
    check_output_args(args, [getattr(spec0, "source", None), getattr(spec0, "urdf", None)])
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
        wrote(args.json)
    spec = load_scene(args.scene)
    ref = lbfgs(build_problem(spec), initial_controls=initial_controls(spec))
    print(f"| L-BFGS (scipy, exact gradient) | {ref.iterations:5d} | {ref.cost:.12f} | {ref.grad_norm:9.2e} | | "
          f"{ref.time_history[-1] * 1e3:9.1f} | {ref.message} |")
    if args.plots:
        from .. import viz

        figs = viz.plot_convergence(results, args.plots, reference_cost=ref.cost, reference_label="L-BFGS (scipy)",
                                    reference_history=ref.cost_history)
        for path in figs.values():
            wrote(path)
    return EXIT_CONVERGED if all(r.converged for r in results.values()) else EXIT_NOT_CONVERGED


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

    from ..output_files import strict_json, write_atomic
    from ..scene import load_scene
    from ..simulate import SimulationSpec, simulate_scene

    spec = load_scene(args.scene)
    _refuse_legged(spec, "simulate")
    check_output_args(args, [getattr(spec, "source", None), getattr(spec, "urdf", None)])
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
        wrote(args.json)
    if args.plots:
        from ..viz import plot_simulation

        for path in plot_simulation(mc, args.plots).values():
            wrote(path)
    if args.html:
        from ..viz import export_html

        run = mc.runs[mc.policies[-1]][0]
        wrote(export_html(run.to_result(plan), args.html, plan=plan))
    return EXIT_CONVERGED if plan.converged else EXIT_NOT_CONVERGED


def _sweep(args) -> int:
    """``geoddp sweep``: run a sweep (exit 0 when every case is in the table, 1 when --limit left
    some for --resume) or summarise one (--summary)."""
    from ..sweep import SweepInterrupted, read_table, run_sweep
    from ..sweep.summary import plots, summary

    if args.summary is not None:
        if not args.summary.is_dir():
            raise InputError("--summary", f"expected a sweep output folder, got {str(args.summary)!r}")
        df = read_table(args.summary)
        print(summary(df))
        if args.plots is not None:
            for path in plots(df, args.plots):
                wrote(path)
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
        wrote(run.table)
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


COMMANDS = {"run": _run, "compare": _compare, "multibody": _multibody, "simulate": _simulate, "sweep": _sweep}
