"""One simulated run of a plan: a policy on a plant under disturbances, and its result.

Per plan step k = 0 .. N-1 (dt the plan's step; N = H by default):

    measured  x~_k = retract(x_k, sensor_k)               (sensor noise; x~_k = x_k without)
    input     u_k  = policy.control(k, x~_k)
    plant     x_{k+1} = plant.step(x_k, u_k, force_k)      (substeps with u_k and force_k held)
              v_{k+1} += velocity_k                        (process noise on the velocity)

With no disturbance and the plan's own model as the plant, the feedback policy sees zeta_k = 0
and applies u_bar_k: the run reproduces the plan to round-off (tested).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..solver.result import Result
from ..validate import InputError, positive_int, unknown_keyword
from .disturbance import Disturbances, DisturbanceSample
from .errors import Targets
from .plant import Plant
from .policy import Feedback, OpenLoop

from ..scene.simulation import POLICIES  # noqa: E402  (their one home; re-exported)


@dataclass
class SimulationResult:
    """A simulated run.

    Attributes:
        policy: "open" | "feedback" | "mpc" (the policy's name).
        times: (N+1,) s.  q: (N+1, ...) states' configuration part (rotation matrices (N+1, 3, 3)
            on the satellite, Pinocchio configurations (N+1, nq) otherwise).  v: (N+1, nv) velocities.
        u: (N, m) the controls actually applied (before the plant's actuator gain).
        errors: the measures of :mod:`geoddp.simulate.errors` (terminal errors, ``tracking_rms``,
            ``effort``, ``state``).
        plant: the plant's parameters that differ from the plan's model.
        stats: what the policy measured (MPC: per-step solve times, iterations, real-time factor).
        wall_time_s: the run's wall time.
        target_error: (N+1,) distance to the target at every step (``target_measure``: see
            :meth:`geoddp.simulate.errors.Targets.series`).
    """

    policy: str
    times: np.ndarray
    q: np.ndarray
    v: np.ndarray
    u: np.ndarray
    errors: dict[str, float]
    plant: dict[str, Any] = field(default_factory=dict)
    stats: dict[str, Any] = field(default_factory=dict)
    wall_time_s: float = 0.0
    target_error: np.ndarray | None = None
    target_measure: str = ""

    def to_result(self, plan: Result) -> Result:
        """The run as a :class:`~geoddp.solver.result.Result` for the viewers: ``plan``'s model
        description and solver fields with this run's times, states and applied controls, and
        ``extra["simulation"]`` = policy, errors and plant changes. ``export_html(run.to_result(plan),
        path, plan=plan)`` replays the run beside a ghost of the plan."""
        return plan.with_trajectory(self.times, self.q, self.v, self.u, simulation={
            "policy": self.policy, "errors": dict(self.errors), "plant": dict(self.plant)})

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary (arrays as lists)."""
        return {"policy": self.policy, "times": self.times.tolist(), "q": np.asarray(self.q).tolist(),
                "v": self.v.tolist(), "u": self.u.tolist(), "errors": dict(self.errors), "plant": dict(self.plant),
                "stats": {k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else v) for k, v in self.stats.items()},
                "wall_time_s": self.wall_time_s,
                "target_measure": self.target_measure,
                "target_error": None if self.target_error is None else self.target_error.tolist()}


# the keywords of :class:`~.mpc.MPC` that simulate and monte_carlo pass on
MPC_OPTIONS = ("horizon", "every", "max_iter", "shrink", "options")


def check_mpc_options(mpc_options: dict[str, Any], policies: Any, caller: str, keywords: tuple[str, ...]) -> None:
    """Refuse, naming it, a keyword of ``caller`` that is neither one of its ``keywords`` nor an
    MPC option, and an MPC option where no policy is "mpc": either would be ignored silently."""
    flies_mpc = any(p == "mpc" for p in ([policies] if isinstance(policies, str) else policies))
    for key in mpc_options:
        if key not in MPC_OPTIONS:
            raise unknown_keyword(key, caller, keywords + MPC_OPTIONS,
                                  f"its keywords: {', '.join(keywords)}; MPC's: {', '.join(MPC_OPTIONS)}")
        if not flies_mpc:
            raise InputError(key, "an option of the MPC policy, but no policy here is 'mpc' (it would be ignored)")


def make_policy(policy: Any, result: Result, problem: Any, **mpc_options: Any) -> Any:
    """A policy object from its name ("open", "feedback", "mpc" with :class:`~.mpc.MPC`'s options)
    or the object itself."""
    if not isinstance(policy, str):
        if not callable(getattr(policy, "control", None)):
            raise InputError("policy", f"expected one of {', '.join(POLICIES)} or a policy object, got {policy!r}")
        return policy
    if policy == "open":
        return OpenLoop(result, problem.model)
    if policy == "feedback":
        return Feedback(result, problem.model)
    if policy == "mpc":
        from .mpc import MPC

        return MPC(problem, plan=result, **mpc_options)
    from ..validate import closest

    hint = closest(policy, POLICIES)
    raise InputError("policy", f"expected one of {', '.join(POLICIES)}, got {policy!r}"
                     + (f" (did you mean {hint!r}?)" if hint else ""))


def run(policy: Any, plant: Plant, targets: Targets, plan: Result, q0: np.ndarray, v0: np.ndarray,
        steps: int, sample: DisturbanceSample | None) -> SimulationResult:
    """The loop of the module docstring (inputs already validated)."""
    model = plant.model
    t0 = time.perf_counter()
    policy.reset()
    nq_shape = np.shape(q0)
    Q = np.empty((steps + 1,) + nq_shape)
    V = np.empty((steps + 1, np.shape(v0)[0]))
    U = np.empty((steps, model.nu))
    Q[0], V[0] = q0, v0
    q, v = Q[0], V[0]
    vel = None if sample is None else sample.velocity
    force = None if sample is None else sample.force
    sensor = None if sample is None else sample.sensor
    for k in range(steps):
        if sensor is not None:
            qm, vm = model.retract(q, v, sensor[k])
        else:
            qm, vm = q, v
        u = policy.control(k, qm, vm)
        U[k] = u
        q, v = plant.step(q, v, u, None if force is None else force[k])
        if vel is not None:
            v = v + vel[k]
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            raise FloatingPointError(f"the simulated state became non-finite at step {k + 1}")
        Q[k + 1], V[k + 1] = q, v
    errors = targets.measures(plan.q, plan.v, Q, V, U, model.dt)
    series = targets.series(Q, V, plan.q, plan.v)
    return SimulationResult(policy=policy.name, times=np.arange(steps + 1) * model.dt, q=Q, v=V, u=U, errors=errors,
                            plant=plant.changed, stats=policy.stats(), wall_time_s=time.perf_counter() - t0,
                            target_error=series, target_measure=targets.series_name)


def simulate(result: Result, problem: Any, policy: Any = "feedback", *, plant: Plant | dict | None = None,
             disturbances: Disturbances | None = None, seed: int | np.random.SeedSequence | None = 0,
             initial_state: tuple[np.ndarray, np.ndarray] | None = None, steps: int | None = None,
             **mpc_options: Any) -> SimulationResult:
    """Fly the plan ``result`` of ``problem`` with ``policy`` on ``plant`` under ``disturbances``.

    Args:
        result: the plan (:func:`geoddp.solver.solve` on ``problem``).
        problem: the plan's problem (its model defines the tangent difference and the targets;
            MPC re-solves it).
        policy: "open", "feedback" (default), "mpc", or a policy object (:mod:`.policy`).
        plant: a :class:`Plant`, a dict of :data:`~.plant.PLANT_KEYS` (e.g.
            ``{"inertia_scale": 1.2, "substeps": 10}``) or None (the plan's model).
        disturbances: :class:`Disturbances` (None: none).
        seed: seed of the run's noise (an int or a ``numpy.random.SeedSequence``).
        initial_state: (q0, v0) in the plan's representation (default: the problem's).
        steps: plan steps to simulate (default H; more than H only with MPC, which keeps
            re-planning towards the same targets).
        mpc_options: options of :class:`~.mpc.MPC` when ``policy="mpc"``.

    Returns:
        :class:`SimulationResult`.
    """
    from .plant import plant_from

    model = problem.model
    plant = plant if isinstance(plant, Plant) else plant_from(model, plant)
    if plant.model is not model:
        raise InputError("plant", "expected a plant built from the problem's model (Plant(problem.model, ...))")
    check_mpc_options(mpc_options, [policy], "simulate", ("plant", "disturbances", "seed", "initial_state", "steps"))
    pol = make_policy(policy, result, problem, **mpc_options)
    H = result.horizon
    steps = H if steps is None else positive_int(steps, "steps")
    if getattr(pol, "horizon", None) is not None and steps > pol.horizon:
        raise InputError("steps", f"expected at most the plan's H = {pol.horizon} steps for the {pol.name} policy "
                         f"(only MPC runs past the plan), got {steps}")
    q0, v0 = (problem.q0, problem.v0) if initial_state is None else model.check_state(*initial_state, "initial_state")
    sample = None
    if disturbances is not None:
        if not isinstance(disturbances, Disturbances):
            raise InputError("disturbances", f"expected a geoddp.simulate.Disturbances, got {type(disturbances).__name__}")
        rng = np.random.default_rng(seed)
        sample = disturbances.draw(rng, steps, plant.nv, model.nx, model.dt)
    return run(pol, plant, Targets(problem), result, q0, v0, steps, sample)
