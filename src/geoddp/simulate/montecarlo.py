"""Monte Carlo: N seeded runs of each policy, and the distribution of their errors.

Reproducible and independent: sample i draws its noise from
``numpy.random.default_rng(SeedSequence(seed).spawn(N)[i])`` (numpy's PCG64 with spawned,
statistically independent streams): the same seed gives the same numbers on every machine and
sample i does not depend on N or on the order the samples run in. Every policy of sample i meets
the same noise (common random numbers: open loop and closed loop are compared run by run).

The table gives, per measure of :mod:`.errors` and per policy, the mean, standard deviation,
median, 95th percentile and maximum over the samples.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..solver.result import Result
from ..validate import InputError, nonnegative_int, positive_int
from .disturbance import Disturbances
from .errors import Targets
from .plant import Plant, plant_from
from .run import SimulationResult, check_mpc_options, make_policy, run

MEASURES = ("attitude_rad", "position_m", "rate", "state", "tracking_rms", "effort")
STATISTICS = ("mean", "std", "p50", "p95", "max")
UNITS = {"attitude_rad": "rad", "position_m": "m", "rate": "rad/s", "state": "tangent", "tracking_rms": "tangent",
         "effort": "u^2 s"}


def _summary(x: np.ndarray) -> dict[str, float]:
    return {"mean": float(np.mean(x)), "std": float(np.std(x)), "p50": float(np.median(x)),
            "p95": float(np.percentile(x, 95)), "max": float(np.max(x))}


@dataclass
class MonteCarloResult:
    """The runs of a Monte Carlo study and their statistics.

    Attributes:
        policies: the policies flown, in order.  samples: N.  seed: the root seed.
        runs: policy -> its N :class:`SimulationResult` (sample order).
        plant: the plant's changed parameters.  plan_cost: J* of the plan.
        wall_time_s: wall time of all runs.
        plan_times (H+1,) s, plan_target_error (H+1,): the plan's own distance to the target
            (the runs' ``target_measure``), for the figures.  plan: the plan's Result.
    """

    policies: tuple[str, ...]
    samples: int
    seed: int
    runs: dict[str, list[SimulationResult]]
    plant: dict[str, Any] = field(default_factory=dict)
    plan_cost: float = float("nan")
    wall_time_s: float = 0.0
    plan_times: np.ndarray | None = None
    plan_target_error: np.ndarray | None = None
    plan: Result | None = None

    def measures(self, policy: str) -> dict[str, np.ndarray]:
        """measure -> (N,) values of ``policy``'s runs (only the measures the runs have)."""
        runs = self.runs[policy]
        return {m: np.array([r.errors[m] for r in runs]) for m in MEASURES if m in runs[0].errors}

    def statistics(self) -> dict[str, float]:
        """Flat ``"<policy>.<measure>.<statistic>"`` -> value (e.g. ``"feedback.attitude_rad.mean"``),
        plus for MPC ``"mpc.solve_median_s"``, ``"mpc.solve_p95_s"``, ``"mpc.solve_max_s"``,
        ``"mpc.iterations_mean"`` and ``"mpc.real_time_factor"`` over every re-solve of every sample,
        and ``"samples"``, ``"seed"``, ``"plan_cost"``, ``"wall_time_s"``."""
        out: dict[str, float] = {"samples": float(self.samples), "seed": float(self.seed), "plan_cost": self.plan_cost,
                                 "wall_time_s": self.wall_time_s}
        for p in self.policies:
            for m, x in self.measures(p).items():
                for s, val in _summary(x).items():
                    out[f"{p}.{m}.{s}"] = val
            times = [t for r in self.runs[p] for t in r.stats.get("solve_times_s", [])]
            if times:
                t = np.asarray(times)
                its = [i for r in self.runs[p] for i in r.stats["iterations"]]
                sim = sum(len(r.u) * (r.times[1] - r.times[0]) for r in self.runs[p])
                out.update({f"{p}.solve_median_s": float(np.median(t)), f"{p}.solve_p95_s": float(np.percentile(t, 95)),
                            f"{p}.solve_max_s": float(t.max()), f"{p}.iterations_mean": float(np.mean(its)),
                            f"{p}.real_time_factor": float(sim / t.sum())})
        return out

    def table(self) -> str:
        """The distribution table as Markdown: one row per measure and statistic, one column per policy."""
        head = "| measure | statistic | " + " | ".join(self.policies) + " |"
        lines = [head, "|---|---|" + "---|" * len(self.policies)]
        per = {p: self.measures(p) for p in self.policies}
        for m in MEASURES:
            if m not in per[self.policies[0]]:
                continue
            summ = {p: _summary(per[p][m]) for p in self.policies}
            for s in STATISTICS if self.samples > 1 else ("mean",):  # one sample: its value
                cells = " | ".join(f"{summ[p][s]:.3e}" for p in self.policies)
                lines.append(f"| {m} ({UNITS[m]}) | {s if self.samples > 1 else 'value'} | {cells} |")
        st = self.statistics()
        for p in self.policies:
            if f"{p}.solve_median_s" in st:
                lines.append(f"\n{p}: re-solve median {st[f'{p}.solve_median_s'] * 1e3:.3f} ms, p95 "
                             f"{st[f'{p}.solve_p95_s'] * 1e3:.3f} ms, max {st[f'{p}.solve_max_s'] * 1e3:.3f} ms, "
                             f"{st[f'{p}.iterations_mean']:.2f} iterations on average, real-time factor "
                             f"{st[f'{p}.real_time_factor']:.1f}")
        return "\n".join(lines)

    def to_dict(self, trajectories: bool = False) -> dict[str, Any]:
        """JSON-ready: the statistics, per-sample measures and (if ``trajectories``) every run."""
        d: dict[str, Any] = {"policies": list(self.policies), "samples": self.samples, "seed": self.seed,
                             "plant": dict(self.plant), "plan_cost": self.plan_cost, "wall_time_s": self.wall_time_s,
                             "statistics": self.statistics(),
                             "measures": {p: {m: x.tolist() for m, x in self.measures(p).items()} for p in self.policies}}
        if trajectories:
            d["runs"] = {p: [r.to_dict() for r in rs] for p, rs in self.runs.items()}
        return d


_JOB: tuple | None = None  # the forked workers' job (inherited through fork, never pickled)


def _samples(job: tuple, indices: Any) -> dict[str, list[SimulationResult]]:
    pols, plant, targets, result, q0, v0, steps, dist, children = job
    model = plant.model
    out: dict[str, list[SimulationResult]] = {p.name: [] for p in pols}
    for i in indices:
        sample = dist.draw(np.random.default_rng(children[i]), steps, plant.nv, model.nx, model.dt)
        for p in pols:
            out[p.name].append(run(p, plant, targets, result, q0, v0, steps, sample))
    return out


def _worker(indices: list[int]) -> dict[str, list[SimulationResult]]:
    assert _JOB is not None
    return _samples(_JOB, indices)


def _in_processes(job: tuple, N: int, workers: int) -> list[dict[str, list[SimulationResult]]]:
    """Blocks of samples in ``workers`` forked processes, in sample order."""
    import multiprocessing as mp

    global _JOB
    if "fork" not in mp.get_all_start_methods():
        return [_samples(job, range(N))]  # no fork (Windows, macOS default): one process
    blocks = [list(b) for b in np.array_split(np.arange(N), min(workers, N))]
    _JOB = job
    try:
        with mp.get_context("fork").Pool(len(blocks)) as pool:
            return pool.map(_worker, blocks)
    finally:
        _JOB = None


def monte_carlo(result: Result, problem: Any, *, samples: int = 90, seed: int = 0,
                policies: tuple[str, ...] | list[str] = ("open", "feedback"), plant: Plant | dict | None = None,
                disturbances: Disturbances | None = None, initial_state: tuple[np.ndarray, np.ndarray] | None = None,
                steps: int | None = None, workers: int = 1, **mpc_options: Any) -> MonteCarloResult:
    """Fly the plan ``result`` of ``problem`` ``samples`` times with each policy (module docstring).

    Args:
        result, problem: the plan and its problem (see :func:`geoddp.simulate.simulate`).
        samples: N >= 1.  seed: root seed (int >= 0).
        policies: names among "open", "feedback", "mpc" (each once).
        plant, disturbances, initial_state, steps, mpc_options: as for :func:`~geoddp.simulate.simulate`.
        workers: processes (>= 1). With more than one, contiguous blocks of samples run in forked
            processes (POSIX fork: the built plant, policies and problem are inherited, nothing is
            rebuilt); the results are the same numbers as with one (each sample's seed is its own).

    Returns:
        :class:`MonteCarloResult`.
    """
    N = positive_int(samples, "samples")
    seed = nonnegative_int(seed, "seed")
    if isinstance(policies, str) or not policies or len(set(policies)) != len(policies):
        raise InputError("policies", f"expected a list of distinct policy names, got {policies!r}")
    model = problem.model
    plant = plant if isinstance(plant, Plant) else plant_from(model, plant)
    dist = Disturbances() if disturbances is None else disturbances
    if not isinstance(dist, Disturbances):
        raise InputError("disturbances", f"expected a geoddp.simulate.Disturbances, got {type(dist).__name__}")
    check_mpc_options(mpc_options, policies, "monte_carlo", ("samples", "seed", "policies", "plant", "disturbances",
                                                             "initial_state", "steps", "workers"))
    pols = [make_policy(p, result, problem, **mpc_options) for p in policies]
    H = result.horizon
    steps = H if steps is None else positive_int(steps, "steps")
    for p in pols:
        if getattr(p, "horizon", None) is not None and steps > p.horizon:
            raise InputError("steps", f"expected at most the plan's H = {H} steps for the {p.name} policy, got {steps}")
    q0, v0 = (problem.q0, problem.v0) if initial_state is None else model.check_state(*initial_state, "initial_state")
    workers = positive_int(workers, "workers")
    targets = Targets(problem)
    t0 = time.perf_counter()
    runs: dict[str, list[SimulationResult]] = {p.name: [] for p in pols}
    children = np.random.SeedSequence(seed).spawn(N)
    job = (pols, plant, targets, result, q0, v0, steps, dist, children)
    if workers == 1 or N == 1:
        chunks = [_samples(job, range(N))]
    else:
        chunks = _in_processes(job, N, workers)
    for chunk in chunks:
        for name, rs in chunk.items():
            runs[name].extend(rs)
    return MonteCarloResult(policies=tuple(p.name for p in pols), samples=N, seed=seed, runs=runs, plant=plant.changed,
                            plan_cost=float(result.cost), wall_time_s=time.perf_counter() - t0,
                            plan_times=np.asarray(result.times, dtype=float),
                            plan_target_error=targets.series(result.q, result.v, result.q, result.v), plan=result)
