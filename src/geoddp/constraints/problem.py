"""A problem with hard constraints, and the options of the outer loop that solves it.

:class:`ConstrainedProblem` holds an unconstrained problem (:class:`geoddp.problem.Problem` or
any contract problem with a ``model``), its path constraints (nodes k = 1..H), its terminal
constraints (k = H) and :class:`ConstraintOptions`. It is solved by
:func:`geoddp.constraints.solve_constrained` (its method :meth:`ConstrainedProblem.solve_constrained`
is the same call, the hook ``geoddp.solver.solve`` routes through); handed to the unconstrained
solver directly it refuses to be linearised rather than be solved without its constraints.
"""
from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..problem.contract import Trajectory
from ..validate import InputError, keywords_checked, nonnegative_float, positive_float, positive_int
from .augmented import AugmentedLagrangianProblem, Placed
from .contact_forces import ForcePlaced
from .kinds import TERMINAL_ONLY, Constraint

__all__ = ["ConstraintOptions", "ConstrainedProblem"]

DEFAULT_CONSTRAINT_TOL = 1e-8


@keywords_checked
@dataclass
class ConstraintOptions:
    """Options of the augmented Lagrangian outer loop (defaults in one place, here).

    Attributes:
        constraint_tol: a solve is a KKT point only when every constraint row satisfies
            |c| <= constraint_tol (equalities) or c <= constraint_tol with complementarity
            min(-c, lambda / mu) <= constraint_tol (inequalities), in each constraint's units.
        penalty_initial: mu_0 of every constraint (units of J per squared constraint unit).
        penalty_increase: factor on a constraint's mu when its violation fell by less than
            ``violation_decrease`` over an outer iteration (> 1).
        penalty_max: the largest mu; a constraint still violated at that penalty makes the
            problem report itself infeasible, with the smallest violation reached.
        violation_decrease: the fraction (in (0, 1)) the violation must fall to each outer
            iteration for mu to stay.
        inner_tol_initial: the first inner solve's tolerance on |dJ| (the solver's ``tol``);
            later ones tighten with the violation (proportionally), down to the solver's
            ``tol``, which the final inner solve always uses.
        max_outer_iter: maximum number of outer iterations (inner solves).
    """

    constraint_tol: float = DEFAULT_CONSTRAINT_TOL
    penalty_initial: float = 100.0
    penalty_increase: float = 10.0
    penalty_max: float = 1e12
    violation_decrease: float = 0.25
    inner_tol_initial: float = 1e-4
    max_outer_iter: int = 50

    def __post_init__(self) -> None:
        self.constraint_tol = nonnegative_float(self.constraint_tol, "constraint_tol")
        self.penalty_initial = positive_float(self.penalty_initial, "penalty_initial")
        self.penalty_increase = positive_float(self.penalty_increase, "penalty_increase")
        if not self.penalty_increase > 1.0:
            raise InputError("penalty_increase", f"expected a factor > 1, got {self.penalty_increase}")
        self.penalty_max = positive_float(self.penalty_max, "penalty_max")
        if self.penalty_max < self.penalty_initial:
            raise InputError("penalty_max", f"expected penalty_max >= penalty_initial = {self.penalty_initial}, "
                             f"got {self.penalty_max}")
        self.violation_decrease = positive_float(self.violation_decrease, "violation_decrease")
        if not self.violation_decrease < 1.0:
            raise InputError("violation_decrease", f"expected a number in (0, 1), got {self.violation_decrease}")
        self.inner_tol_initial = nonnegative_float(self.inner_tol_initial, "inner_tol_initial")
        self.max_outer_iter = positive_int(self.max_outer_iter, "max_outer_iter")


class ConstrainedProblem:
    """min J(U) subject to the problem's dynamics, its control limits, path constraints at
    k = 1..H and terminal constraints at k = H.

    Args:
        problem: the unconstrained problem: a :class:`geoddp.problem.Problem` (satellite or
            multibody) or any contract problem with a ``model`` the constraints bind to.
        constraints: path constraints (:mod:`geoddp.constraints.kinds`; inequality kinds).
        terminal_constraints: constraints at the final node (any kind).
        options: :class:`ConstraintOptions` (a dict of its fields is accepted).

    Errors name the constraint: ``constraints[1].frame: expected a frame of model ...``.
    The attribute ``placed`` holds the bound constraints at their nodes, path ones first.
    """

    def __init__(self, problem: Any, constraints: Sequence[Constraint] = (),
                 terminal_constraints: Sequence[Constraint] = (), options: ConstraintOptions | dict | None = None
                 ) -> None:
        for attr in ("nx", "nu", "horizon", "dt", "trajectory", "trajectory_cost", "linearise"):
            if not hasattr(problem, attr):
                raise InputError("problem", f"expected an optimal control problem (geoddp.problem.Problem), got "
                                 f"{type(problem).__name__} (missing {attr})")
        if isinstance(problem, ConstrainedProblem):
            raise InputError("problem", "expected an unconstrained problem, got a ConstrainedProblem (give all its "
                             "constraints at once)")
        model = getattr(problem, "model", None)
        self.problem = problem
        self.options = options if isinstance(options, ConstraintOptions) else ConstraintOptions(**(options or {}))
        H = int(problem.horizon)
        self.constraints = tuple(self._checked(constraints, "constraints"))
        self.terminal_constraints = tuple(self._checked(terminal_constraints, "terminal_constraints"))
        self.placed: list[Placed | ForcePlaced] = []
        self.kinds: list[tuple[str, Constraint]] = []  # ("path" | "terminal", constraint), as placed
        for where, items, nodes in (("constraints", self.constraints, np.arange(1, H + 1)),
                                    ("terminal_constraints", self.terminal_constraints, np.array([H]))):
            for i, c in enumerate(items):
                if getattr(c, "on_contact_forces", False):  # forces at the contact nodes k = 0..H-1
                    if where == "terminal_constraints":
                        raise InputError(f"{where}[{i}]", f'a "{c.type}" constraint acts on the contact forces of '
                                         "the contact nodes; the terminal node has none: put it in constraints")
                    try:
                        self.placed.append(c.place(problem))
                    except InputError as e:
                        raise InputError(f"{where}[{i}].{e.parameter}", e.detail) from None
                    self.kinds.append(("path", c))
                    continue
                if where == "constraints" and c.type in TERMINAL_ONLY:
                    raise InputError(f"{where}[{i}]", f'a "{c.type}" equality pins the state at every node; it is a '
                                     "terminal constraint: put it in terminal_constraints ([[terminal_constraints]])")
                try:
                    bound = c.bind(model)
                except InputError as e:
                    raise InputError(f"{where}[{i}].{e.parameter}", e.detail) from None
                if bound.nx != problem.nx:
                    raise InputError(f"{where}[{i}]", f"expected a constraint on the problem's tangent space "
                                     f"(nx = {problem.nx}), got nx = {bound.nx}")
                self.placed.append(Placed(bound, nodes))
                self.kinds.append(("path" if where == "constraints" else "terminal", c))

    @staticmethod
    def _checked(items: Any, name: str) -> list[Constraint]:
        if isinstance(items, Constraint):
            items = [items]
        if not isinstance(items, (list, tuple)):
            raise InputError(name, f"expected a list of constraints, got {type(items).__name__}")
        for i, c in enumerate(items):
            if not isinstance(c, Constraint):
                raise InputError(f"{name}[{i}]", f"expected a constraint (geoddp.constraints: PointingKeepOut, "
                                 f"JointLimits, ...), got {type(c).__name__}")
        return list(items)

    def with_initial_state(self, q0: np.ndarray, v0: np.ndarray) -> "ConstrainedProblem":
        """The same constrained problem from another initial state: the unconstrained problem's
        :meth:`geoddp.problem.Problem.with_initial_state` (q0: R0 (3, 3) or (nq,); v0: (3,) rad/s
        or (nv,); InputError naming ``q0`` / ``v0``) with these constraints, bound once, and
        options; this one is unchanged."""
        if not callable(getattr(self.problem, "with_initial_state", None)):
            raise InputError("problem", f"its unconstrained problem ({type(self.problem).__name__}) has no "
                             "with_initial_state; build the ConstrainedProblem around a geoddp.problem.Problem")
        new = copy.copy(self)  # the constraints bind to the model, not to the initial state
        new.problem = self.problem.with_initial_state(q0, v0)
        return new

    # ---------------------------------------------------------------- sizes and the shared members
    @property
    def nx(self) -> int:
        return self.problem.nx

    @property
    def nu(self) -> int:
        return self.problem.nu

    @property
    def horizon(self) -> int:
        return self.problem.horizon

    @property
    def dt(self) -> float:
        return self.problem.dt

    def check_controls(self, controls: np.ndarray, name: str = "initial_controls") -> np.ndarray:
        return self.problem.check_controls(controls, name)

    def trajectory(self, controls: np.ndarray) -> Trajectory:
        return self.problem.trajectory(controls)

    def trajectory_cost(self, traj: Trajectory) -> float:
        """The objective J (the constraints add nothing to it)."""
        return self.problem.trajectory_cost(traj)

    def control_bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        bounds = getattr(self.problem, "control_bounds", None)
        return None if bounds is None else bounds()

    def describe(self) -> dict[str, Any]:
        return self.problem.describe()

    def __getattr__(self, name: str) -> Any:
        # the default start (``quasi_static_controls``), exactly when the unconstrained problem has one
        if name == "quasi_static_controls":
            return getattr(self.problem, name)
        raise AttributeError(name)

    def linearise(self, traj: Trajectory, order: int) -> Any:
        """Refused: the unconstrained solver would drop the constraints. Solve with
        :func:`geoddp.constraints.solve_constrained` (or :meth:`solve_constrained`)."""
        raise InputError("problem", "a ConstrainedProblem is solved by its augmented Lagrangian outer loop: "
                         "geoddp.constraints.solve_constrained(problem, options, initial_controls), not by the "
                         "unconstrained solver (it would ignore the constraints)")

    def rollout_policy(self, traj: Trajectory, k: np.ndarray, K: np.ndarray, step: float) -> Any:
        """Refused, as :meth:`linearise`."""
        return self.linearise(traj, 1)

    # ---------------------------------------------------------------- what the outer loop uses
    def values(self, traj: Trajectory) -> list[np.ndarray]:
        """c (N_j, nc_j) of every placed constraint along ``traj`` (a force constraint's from the
        contact forces of its nodes, each node's dynamics evaluated once)."""
        forces: dict[int, np.ndarray] = {}
        out = []
        for p in self.placed:
            if isinstance(p, ForcePlaced):
                for k in p.nodes.tolist():
                    if k not in forces:
                        forces[k] = self.problem.node(k, traj.q[k], traj.v[k], traj.u[k])[0].forces
                starts = [self.problem.force_rows(self.problem.nodes[k].feet)[i]  # a flat foot: 6 rows
                          for k, i in zip(p.nodes.tolist(), p.slots.tolist())]
                f = np.array([forces[k][s:s + 3] for k, s in zip(p.nodes.tolist(), starts)])
                out.append(p.bound.value(f))
            else:
                out.append(p.bound.value(*p.states(traj)))
        return out

    def augmented(self, multipliers: list[np.ndarray], penalties: list[float]) -> AugmentedLagrangianProblem:
        """The inner problem for these multipliers and penalties: the state constraints' terms
        around the problem, the force constraints' inside its node costs
        (:meth:`geoddp.problem.legged.ContactProblem.with_force_terms`)."""
        inner = self.problem
        force = [(p, lam, mu) for p, lam, mu in zip(self.placed, multipliers, penalties) if isinstance(p, ForcePlaced)]
        if force:
            inner = inner.with_force_terms(force)
        state = [(p, lam, mu) for p, lam, mu in zip(self.placed, multipliers, penalties)
                 if not isinstance(p, ForcePlaced)]
        return AugmentedLagrangianProblem(inner, [p for p, _, _ in state], [lam for _, lam, _ in state],
                                          [mu for _, _, mu in state])

    def solve_constrained(self, options: Any = None, initial_controls: np.ndarray | None = None) -> Any:
        """:func:`geoddp.constraints.solve_constrained` of this problem (a Result)."""
        from .outer import solve_constrained

        return solve_constrained(self, options, initial_controls)
