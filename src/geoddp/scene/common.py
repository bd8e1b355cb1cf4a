"""The tables every scene kind shares, once: their keys, their fields on the spec and how they are
read: ``[solver]``, ``[limits]`` (control limits) and ``[simulation]`` (closed-loop simulation:
:class:`~geoddp.scene.simulation.SimulationSpec`, flown by :func:`geoddp.simulate.simulate_scene`
and ``geoddp simulate``).

:class:`CommonSpec` is the base of both specs (:class:`~geoddp.scene.satellite.SceneSpec`,
:class:`~geoddp.scene.multibody.MultibodySceneSpec`): its fields are keyword-only with defaults,
so a new shared field never disturbs a kind's own fields. :data:`TABLES` is merged into each
kind's schema, and :func:`read_common` reads every shared table into spec fields.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import validate as v
from ..constraints import Constraint
from ..constraints.problem import DEFAULT_CONSTRAINT_TOL
from ..problem.limits import ControlLimits, check_inside
from .simulation import SimulationSpec
from ..solver.options import DEFAULT_EXPANSION, DEFAULT_MAX_ITER, DEFAULT_SWITCH_RATIO, EXPANSIONS
from .reader import Reader, Schema

DEFAULT_SECOND_ORDER = "exact"

# [table] -> key -> required?  (merged into every kind's schema)
TABLES: Schema = {
    "solver": {"expansion": False, "switch_ratio": False, "tol": False, "rtol": False, "grad_tol": False,
               "grad_rtol": False, "max_iter": False, "second_order": False, "initial_controls": False,
               "constraint_tol": False},
    "simulation": {f.name: False for f in dataclasses.fields(SimulationSpec)},
    "limits": {"control_min": False, "control_max": False, "effort_limits": False},
}
EFFORT_LIMITS = ("urdf",)


def readonly(a: Any) -> np.ndarray:
    """A read-only float64 copy: specs are frozen, arrays included, so a caller cannot edit a shared scene."""
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False, kw_only=True)
class CommonSpec:
    """Fields of the shared tables (keyword-only, with defaults).

    Attributes:
        expansion: "first" | "second" | "switch".
        switch_ratio: sigma in (0, 1) for the switch expansion.
        tol: absolute stopping tolerance on |J_i - J_(i-1)| and the Newton decrement (units of
            J), >= 0, or None (not set: the solver's relative default applies). A scene that sets
            it keeps the absolute meaning it always had (the satellite scenes: the paper's 1e-8).
        rtol: relative stopping tolerance (the same tests against rtol |J|), >= 0, or None.
        grad_tol: absolute stopping tolerance on the gradient norm, >= 0, or None.
        grad_rtol: relative stopping tolerance on the gradient norm (against grad_rtol |J|), or None.
            How the four combine, and their defaults: :class:`geoddp.solver.SolverOptions`.
        max_iter: maximum number of iterations, >= 1.
        second_order: "exact" | "paper" (the paper's: satellite with explicit Euler only).
        simulation: the ``[simulation]`` table as a :class:`~geoddp.scene.simulation.SimulationSpec`
            (a dict of its fields is converted), or None when the scene has none.
        control_min, control_max: ``[limits]``: (m,) per-input lower / upper control bounds
            (-inf / inf: unbounded), or None (no bound on that side).
        effort_limits: ``[limits].effort_limits``: "urdf" (multibody scenes: every input is a
            joint motor bounded by its URDF effort, -effort <= u <= effort; combined with
            control_min / control_max by taking the tighter bound) or None.
        constraints, terminal_constraints: the ``[[constraints]]`` (every node k = 1..H) and
            ``[[terminal_constraints]]`` (k = H) tables as :mod:`geoddp.constraints` objects
            (:mod:`geoddp.scene.constraints`); empty: an unconstrained problem.
        constraint_tol: ``[solver].constraint_tol``, the tolerance the constraints are met to
            (:class:`geoddp.constraints.ConstraintOptions`).
    """

    expansion: str = DEFAULT_EXPANSION
    switch_ratio: float = DEFAULT_SWITCH_RATIO
    tol: float | None = None
    rtol: float | None = None
    grad_tol: float | None = None
    grad_rtol: float | None = None
    max_iter: int = DEFAULT_MAX_ITER
    second_order: str = DEFAULT_SECOND_ORDER
    simulation: SimulationSpec | None = None
    control_min: np.ndarray | None = None
    control_max: np.ndarray | None = None
    effort_limits: str | None = None
    constraints: tuple = ()
    terminal_constraints: tuple = ()
    constraint_tol: float = DEFAULT_CONSTRAINT_TOL

    def _check_common(self, second_order_kinds: tuple[str, ...], nu: int) -> None:
        """Validate the shared fields under their field names (direct construction, with_overrides);
        ``nu``: the spec's number of inputs m (for per-input fields)."""
        put = lambda k, val: object.__setattr__(self, k, val)  # noqa: E731  (frozen dataclass)
        put("expansion", v.choice(self.expansion, "expansion", EXPANSIONS))
        put("switch_ratio", v.bounded_float(self.switch_ratio, "switch_ratio", 0.0, 1.0, False, False))
        for key in ("tol", "rtol", "grad_tol", "grad_rtol"):  # None: not set (the solver's default)
            if getattr(self, key) is not None:
                put(key, v.nonnegative_float(getattr(self, key), key))
        put("max_iter", v.positive_int(self.max_iter, "max_iter"))
        put("second_order", v.choice(self.second_order, "second_order", second_order_kinds))
        if isinstance(self.simulation, Mapping):
            put("simulation", SimulationSpec.from_dict(dict(self.simulation)))
        elif self.simulation is not None and not isinstance(self.simulation, SimulationSpec):
            raise v.InputError("simulation", f"expected a SimulationSpec, a dict of its fields or None, got "
                               f"{type(self.simulation).__name__}")
        lo, hi = control_bounds(self.control_min, self.control_max, nu, ("control_min", "control_max"))
        put("control_min", lo)
        put("control_max", hi)
        if self.effort_limits is not None:
            put("effort_limits", v.choice(self.effort_limits, "effort_limits", EFFORT_LIMITS))
        for name in ("constraints", "terminal_constraints"):
            items = tuple(getattr(self, name))
            for i, c in enumerate(items):
                if not isinstance(c, Constraint):
                    raise v.InputError(f"{name}[{i}]", f"expected a geoddp.constraints constraint, got {type(c).__name__}")
            put(name, items)
        put("constraint_tol", v.nonnegative_float(self.constraint_tol, "constraint_tol"))

    @property
    def has_constraints(self) -> bool:
        """True if the scene has hard constraints (``[[constraints]]``, ``[[terminal_constraints]]``)."""
        return bool(self.constraints or self.terminal_constraints)

    @property
    def has_limits(self) -> bool:
        """True if the scene bounds its controls (``[limits]``)."""
        return self.control_min is not None or self.control_max is not None or self.effort_limits is not None

    def _check_initial_in_limits(self, U: np.ndarray | None, name: str) -> None:
        """InputError naming ``name`` if an initial guess U ((m,) or (H, m)) leaves the numeric limits."""
        initial_in_limits(U, self.control_min, self.control_max, name)


def initial_in_limits(U: np.ndarray | None, lower: np.ndarray | None, upper: np.ndarray | None, name: str) -> None:
    """InputError naming ``name`` if an initial guess U ((m,) or (H, m)) leaves [lower, upper]
    ((m,) each or None). URDF effort limits are checked when the problem is solved."""
    if U is None or (lower is None and upper is None):
        return
    U2 = np.atleast_2d(U)
    lo = np.broadcast_to(-np.inf if lower is None else lower, U2.shape)
    hi = np.broadcast_to(np.inf if upper is None else upper, U2.shape)
    check_inside(U2, lo, hi, name)


def control_bounds(lower: Any, upper: Any, nu: int, names: tuple[str, str]) -> tuple[Any, Any]:
    """Per-input bounds (a number or nu numbers each, or None) as read-only (nu,) arrays or None;
    InputError naming ``names`` for NaN, a wrong length, +inf below, -inf above, lower > upper."""
    if lower is None and upper is None:
        return None, None
    lo, hi = ControlLimits(lower, upper).resolve(1, nu, names)
    return (None if lower is None else readonly(lo[0])), (None if upper is None else readonly(hi[0]))


def read_common(r: Reader, second_order_kinds: tuple[str, ...], nu: int, model: Any = None,
                constraint_model: Any = None, default_frame: str | None = None) -> dict[str, Any]:
    """The shared tables as :class:`CommonSpec` keyword arguments.

    Args:
        r: the scene's reader.
        second_order_kinds: the kind's choices for ``[solver].second_order``.
        nu: the number of inputs m (for per-input values).
        model: the kind's ``pin.Model`` if it has one at parse time (multibody), else None.
        constraint_model: the ``pin.Model`` the constraint tables are checked against when it is
            not ``model`` (the satellite's one body on a spherical root).
        default_frame: the frame a ``pointing_keep_out`` constraint without ``frame`` uses (the
            satellite's body), or None.

    ``[solver].initial_controls`` has forms that depend on the kind ("hover"): each kind reads it.
    ``[limits]``: control_min / control_max (a number or nu numbers, -inf / inf allowed) and, for a
    multibody scene (``model`` given), effort_limits = "urdf".
    ``[[constraints]]``, ``[[terminal_constraints]]`` (:mod:`geoddp.scene.constraints`): checked
    against ``constraint_model`` or ``model``.
    """
    from .constraints import read_constraints

    s = r.table("solver")
    get = s.get
    lim = r.table("limits")
    lo, hi = r.check(control_bounds, lim.get("control_min"), lim.get("control_max"), nu,
                     ("[limits].control_min", "[limits].control_max"))
    effort = lim.get("effort_limits")
    if effort is not None:
        effort = r.check(v.choice, effort, "[limits].effort_limits", EFFORT_LIMITS)
        if model is None:
            raise r.err("[limits].effort_limits", "only multibody scenes read joint efforts from their URDF; "
                        "give control_min / control_max")
    pm = constraint_model if constraint_model is not None else model
    path, terminal = read_constraints(r, pm, default_frame) if pm is not None else ((), ())
    return dict(
        constraints=path, terminal_constraints=terminal,
        constraint_tol=r.check(v.nonnegative_float, get("constraint_tol", DEFAULT_CONSTRAINT_TOL),
                               "[solver].constraint_tol"),
        control_min=lo, control_max=hi, effort_limits=effort,
        simulation=r.check(_simulation, r.table("simulation")) if "simulation" in r.data else None,
        expansion=r.check(v.choice, get("expansion", DEFAULT_EXPANSION), "[solver].expansion", EXPANSIONS),
        switch_ratio=r.check(v.bounded_float, get("switch_ratio", DEFAULT_SWITCH_RATIO), "[solver].switch_ratio",
                             0.0, 1.0, False, False),
        **{key: r.check(v.nonnegative_float, s[key], f"[solver].{key}") if key in s else None
           for key in ("tol", "rtol", "grad_tol", "grad_rtol")},
        max_iter=r.check(v.positive_int, get("max_iter", DEFAULT_MAX_ITER), "[solver].max_iter"),
        second_order=r.check(v.choice, get("second_order", DEFAULT_SECOND_ORDER), "[solver].second_order",
                             second_order_kinds),
    )


def _simulation(table: dict[str, Any]) -> SimulationSpec:
    """The ``[simulation]`` table (keys already checked by the reader), its errors named by key path."""
    try:
        return SimulationSpec.from_dict(table)
    except v.InputError as exc:  # "simulation.plant.substeps" -> "[simulation].plant.substeps"
        raise v.InputError("[simulation]." + exc.parameter.removeprefix("simulation."), exc.detail) from None
