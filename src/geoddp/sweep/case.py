"""One case of a sweep, run anywhere (in this process or on a Dask worker): a plain payload in,
a plain row of scalars out.

The payload and the row are plain data (dicts of str, float, int, bool, lists), so a worker needs
only ``pip install geoddp`` and nothing is pickled but data. A case that raises is a row with
``status = "error"`` and the error's type and message, never an exception out of here: only a
dying process loses a case, and Dask's retries give it to another worker.

Case kinds (:attr:`geoddp.sweep.spec.Case.kind`):

* ``solve``: :func:`geoddp.solve_scene` on the case's scene.
* ``simulate``: solve, then fly the plan in closed loop with the case's ``[simulation]`` table
  (:func:`geoddp.simulate.simulate_scene`); its flat statistics become ``sim.*`` columns.
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

# Outcome columns, in table order (parameters and sim.* columns come around them).
OUTCOME_COLUMNS = ("status", "converged", "J", "iterations", "gradient_norm", "solve_time_s", "case_time_s")


def payload(case: Any, full_dir: str | None = None, spec: Any = None) -> dict[str, Any]:
    """The plain data a worker needs to run ``case`` (a :class:`~geoddp.sweep.spec.Case`);
    ``full_dir``: write the case's full Result as JSON there (a folder every worker can write).
    ``spec``: the case's scene spec, already validated in this process (serial runs only: a
    payload sent to a worker stays plain data and the worker reads the scene itself)."""
    p = {"index": case.index, "hash": case.hash, "scene": case.scene, "simulation": case.simulation,
         "source": case.source, "full_dir": full_dir}
    if spec is not None:
        p["spec"] = spec
    return p


def run_case(p: dict[str, Any]) -> dict[str, Any]:
    """Solve (and simulate) one case; the outcome columns of its row (never raises on a bad case).

    Args:
        p: a :func:`payload`.

    Returns:
        ``status`` (the solver's status string, or ``"error"``), ``converged``, ``J`` (J*),
        ``iterations``, ``gradient_norm`` (||dJ/dU|| at the solution), ``solve_time_s`` (the
        solver's wall time), ``case_time_s`` (the whole case, s), terminal errors
        (``attitude_error_deg`` and ``angular_velocity_error`` (rad/s) for a satellite,
        ``terminal.<term>.position_error_m`` / ``.rotation_error_deg`` for a multibody's frame
        terms), ``sim.<statistic>`` for a simulated case, and ``error`` ("" or "Type: message").
    """
    t0 = time.perf_counter()
    row: dict[str, Any] = {"status": "error", "converged": False, "J": math.nan, "iterations": -1,
                           "gradient_norm": math.nan, "solve_time_s": math.nan}
    try:
        from ..scene import parse_scene

        spec = p.get("spec")
        if spec is None:
            spec = parse_scene(p["scene"], p["source"])
        if p["simulation"] is None:
            from ..scene.solve import solve_scene

            result = solve_scene(spec, verbose=False)
            stats: dict[str, float] = {}
        else:
            result, stats = simulate(spec, p["simulation"])
        row.update(status=str(result.status), converged=bool(result.converged), J=float(result.cost),
                   iterations=int(result.iterations), gradient_norm=float(result.grad_norm),
                   solve_time_s=float(result.solve_time_s))
        row.update(terminal_errors(spec, result))
        row.update({f"sim.{k}": float(val) for k, val in stats.items()})
        if p.get("full_dir"):
            result.write_json(Path(p["full_dir"]) / f"{p['hash']}.json")  # atomic
        row["error"] = ""
    except Exception as exc:  # recorded, not fatal: the sweep goes on
        row["error"] = f"{type(exc).__name__}: {' '.join(str(exc).split())}"[:2000]
    row["case_time_s"] = time.perf_counter() - t0
    return row


def simulate(spec: Any, simulation: dict[str, Any]) -> tuple[Any, dict[str, float]]:
    """The "solve then simulate" case: the plan's Result and the closed-loop statistics."""
    from ..simulate import simulate_scene

    mc = simulate_scene(spec, dict(simulation))
    return mc.plan, dict(mc.statistics())


def terminal_errors(spec: Any, result: Any) -> dict[str, float]:
    """Terminal errors of a solution: the satellite's attitude (deg) and rate (rad/s) errors, or a
    multibody's frame-term errors (m, deg); none for a legged scene (its targets are per node)."""
    if getattr(spec, "kind", None) == "legged":
        return {}
    if getattr(spec, "kind", "satellite") == "satellite":
        return {"attitude_error_deg": float(result.attitude_error_deg),
                "angular_velocity_error": float(result.angular_velocity_error)}
    from ..scene import terminal_frame_errors

    out = {}
    for term in terminal_frame_errors(spec, result.q[-1]):
        for k in ("position_error_m", "rotation_error_deg"):
            if k in term:
                out[f"terminal.{term['name']}.{k}"] = float(term[k])
    return out

