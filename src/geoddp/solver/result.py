"""The solved trajectory as plain data.

A :class:`Result` is what the solver hands downstream: the viewer, the figures and the JSON
writer read it and never call back into the solver. Everything is numpy arrays or builtins.

:class:`Result` holds what every problem has: the state trajectory (q, v) as the problem's
:class:`~geoddp.problem.contract.Trajectory` holds it, the controls and gains, the histories, the
status, and the problem's model description
(:meth:`~geoddp.problem.contract.OptimalControlProblem.describe`), and the views of the root
body's attitude (rotations, quaternions, angular velocities, the target and the attitude error).
Its kind is chosen once, from the description's ``kind``, when the solver builds it
(:func:`result_class`) or :meth:`Result.from_dict` reads it:

* :class:`SatelliteResult`: the state on TSO(3), q the rotations and v the body rates, which the
  views are;
* :class:`MultibodyResult`: Pinocchio configurations and velocities (``configurations``,
  ``velocities``), the viewer's description of the model (``multibody``), and the views derived
  from the root joint.

The JSON keeps every field it has had (files written before the generic Result still load) and
adds ``model``.
"""
from __future__ import annotations

import copy
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ..validate import InputError

# Keys of the model description that make up ``Result.multibody`` (what the viewer rebuilds from).
# optional: the viewer's mesh search path, frame-target triads, and for a model handed over as a
# pin.Model (Multibody.from_model) the serialised model and its visual geometry records
_MULTIBODY_KEYS = ("urdf", "urdf_xml", "root", "nq", "nv", "package_dirs", "frame_targets", "pin_model",
                   "geometry_objects")


def as_result(x: Any, name: str = "result") -> "Result":
    """``x`` if it is a :class:`Result`, else an InputError naming ``name`` (what the viewers and
    figure functions take)."""
    if not isinstance(x, Result):
        raise InputError(name, f"expected a geoddp Result (from solve or Result.read_json), got {type(x).__name__}")
    return x


def rotations_to_quaternions(rotations: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) -> unit quaternions (N, 4) in (x, y, z, w) order.

    The sign is chosen so that consecutive quaternions have a non-negative dot product
    (continuous along a trajectory), starting with w >= 0.
    """
    R = np.asarray(rotations, dtype=float)
    n = R.shape[0]
    q = np.empty((n, 4))
    # Shepperd's method, vectorised: pick the largest of (w, x, y, z) as pivot for stability.
    tr = np.trace(R, axis1=1, axis2=2)
    diag = np.stack([R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    cand = np.concatenate([tr[:, None], diag], axis=1)
    piv = np.argmax(cand, axis=1)
    for i in range(n):
        r = R[i]
        p = piv[i]
        if p == 0:
            s = 2.0 * np.sqrt(max(1.0 + tr[i], 0.0))
            q[i] = [(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, 0.25 * s]
        elif p == 1:
            s = 2.0 * np.sqrt(max(1.0 + r[0, 0] - r[1, 1] - r[2, 2], 0.0))
            q[i] = [0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s, (r[2, 1] - r[1, 2]) / s]
        elif p == 2:
            s = 2.0 * np.sqrt(max(1.0 + r[1, 1] - r[0, 0] - r[2, 2], 0.0))
            q[i] = [(r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s, (r[0, 2] - r[2, 0]) / s]
        else:
            s = 2.0 * np.sqrt(max(1.0 + r[2, 2] - r[0, 0] - r[1, 1], 0.0))
            q[i] = [(r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s, (r[1, 0] - r[0, 1]) / s]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    if n and q[0, 3] < 0.0:
        q[0] = -q[0]
    for i in range(1, n):
        if np.dot(q[i], q[i - 1]) < 0.0:
            q[i] = -q[i]
    return q


def _root_rotations_and_rates(q: np.ndarray, v: np.ndarray, root: str) -> tuple[np.ndarray, np.ndarray]:
    """Root body attitude (N, 3, 3) and body rate (N, 3) of Pinocchio states q (N, nq), v (N, nv)."""
    import pinocchio as pin

    N = q.shape[0]
    if root == "free_flyer":
        quat, rate = q[:, 3:7], v[:, 3:6]
    elif root == "spherical":
        quat, rate = q[:, 0:4], v[:, 0:3]
    else:
        quat, rate = np.tile([0.0, 0.0, 0.0, 1.0], (N, 1)), np.zeros((N, 3))
    R = np.array([pin.Quaternion(c[3], c[0], c[1], c[2]).normalized().toRotationMatrix() for c in quat])
    return R, np.array(rate)


class _WriteThrough(dict):
    """The ``Result.multibody`` dict: a view of some keys of the model description that writes
    changes back to it (code that edits ``result.multibody[...]`` in place keeps working)."""

    def __init__(self, model: dict[str, Any], keys: tuple[str, ...]) -> None:
        super().__init__({k: model[k] for k in keys if k in model})
        self._model = model

    def __setitem__(self, key: str, value: Any) -> None:
        super().__setitem__(key, value)
        self._model[key] = value

    def __delitem__(self, key: str) -> None:
        super().__delitem__(key)
        self._model.pop(key, None)

    def pop(self, key: str, *default: Any) -> Any:
        self._model.pop(key, None)
        return super().pop(key, *default)

    def update(self, *args: Any, **kw: Any) -> None:
        super().update(*args, **kw)
        self._model.update(*args, **kw)


def _nan_for_none(x: Any) -> Any:
    """Inverse of the strict JSON writer (geoddp.output_files): null -> NaN, at any list depth."""
    if x is None:
        return float("nan")
    if isinstance(x, list):
        return [_nan_for_none(v) for v in x]
    return x


def _jsonable(x: Any) -> Any:
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, dict):
        return {k: _jsonable(val) for k, val in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(val) for val in x]
    return x


def _limits_from_json(lim: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """(lower, upper) from the JSON's "limits" (null or NaN = unbounded side)."""
    if lim is None:
        return None
    lo = np.asarray(_nan_for_none(lim["lower"]), dtype=float)
    hi = np.asarray(_nan_for_none(lim["upper"]), dtype=float)
    return np.where(np.isnan(lo), -np.inf, lo), np.where(np.isnan(hi), np.inf, hi)


@dataclass(init=False)
class Result:
    """Solution of a geometric DDP solve: what every problem has (its kinds add their own views:
    :class:`SatelliteResult`, :class:`MultibodyResult`).

    Shapes use H = horizon (number of control steps), m = number of inputs and nx = the dimension
    of the tangent state (6 on TSO(3), 2 nv for a multibody).

    Attributes:
        times: (H+1,) time stamps in seconds, ``k * dt``.
        q: (H+1, ...) configuration part of the state: rotation matrices (H+1, 3, 3) on TSO(3),
            Pinocchio configurations (H+1, nq) for a multibody.
        v: (H+1, nv) velocities: body angular velocity Omega (rad/s) on TSO(3), generalised
            velocities for a multibody.
        model: the problem's model description (``kind``, ``dt``, ``integrator``,
            ``target_rotation``, ``target_angular_velocity``; a multibody adds ``urdf``,
            ``urdf_xml``, ``root``, ``nq``, ``nv``).
        controls: (H, m) inputs u_k (units of the actuation).
        feedforward: (H, m) the last backward pass's k_k = Q_uu^-1 Q_u.
        feedback: (H, m, nx) the last backward pass's K_k = Q_uu^-1 Q_ux; the control law is
            u = u_k - gamma k_k - K_k zeta with zeta = difference(x_k, x) ((log(R_k^T R),
            Omega - Omega_k) on TSO(3)).
        cost: final total cost J.
        iterations: number of accepted iterations.
        converged: True only when a stopping test on |dJ| or on the gradient passed.
        status: one of the STATUS_* strings of :mod:`geoddp.solver.status`.
        message: human-readable detail on the status.
        cost_history: (iterations+1,) J at the initial guess and after each accepted iteration.
        grad_norm_history: (iterations+1,) ||dJ/dU|| at the same iterates.
        reg_history: (iterations,) Q_uu regularisation lambda used by each iteration.
        step_history: (iterations,) line-search gamma accepted by each iteration (for a saddle
            escape, the step length |alpha| along the negative-curvature direction).
        expansion_history: (iterations,) "first" or "second" per iteration (a saddle escape, which
            uses the exact second-order check, is recorded as "second").
        control_history: (iterations+1, H, m) controls per iterate (only when recorded).
        time_history: (iterations+1,) wall time in seconds from the start of the solve at which
            each iterate of cost_history was reached (0 for the initial guess).
        solve_time_s: wall time of the solve in seconds.
        timings: breakdown in seconds (derivatives, backward, forward, ...).
        expansion: the expansion option used (first | second | switch).
        dt: time step in seconds.
        limits: the control limits (lower, upper), each (H, m) (-inf / inf where unbounded), or
            None for an unconstrained problem.
        active_set: (H, m) int8 with limits: -1 where u_k sits on its lower bound, +1 on its upper
            bound, 0 inside; None without limits. ``optimality`` (in extra) then also holds the
            KKT residual (max |projected gradient|) and the complementarity numbers.
        extra: free-form additions; the solver puts ``"saddle_escapes"`` here (a list of dicts with
            iteration, node, eigenvalue, alpha, cost_before, cost_after) when it escaped a saddle,
            and a constrained solve (:func:`geoddp.constraints.solve_constrained`) its report in
            ``"constraints"`` (feasibility, multipliers and active nodes per constraint, the outer
            iterations), which the JSON keeps.

    Views (properties) of the root body's attitude: ``rotations`` (H+1, 3, 3) body-to-world
    attitudes, ``angular_velocities`` (H+1, 3) body rates (rad/s), ``quaternions`` (H+1, 4),
    ``target_rotation`` (3, 3), ``target_angular_velocity`` (3,), ``attitude_error_deg``,
    ``angular_velocity_error``; and ``integrator``. A result of a kind this module does not know
    (a problem of the user's describing another ``kind``) has no root body it knows of: its
    rotations are the identity and its rates zero, as for a multibody's fixed root.

    The constructor also accepts the pre-generic keywords ``target_rotation``,
    ``target_angular_velocity`` and ``integrator`` and puts them into the description (each kind
    takes its own too: :class:`SatelliteResult`, :class:`MultibodyResult`).
    """

    times: np.ndarray
    q: np.ndarray
    v: np.ndarray
    model: dict[str, Any]
    controls: np.ndarray
    feedforward: np.ndarray
    feedback: np.ndarray
    cost: float
    iterations: int
    converged: bool
    status: str
    message: str
    cost_history: np.ndarray
    grad_norm_history: np.ndarray
    reg_history: np.ndarray
    step_history: np.ndarray
    expansion_history: list[str]
    solve_time_s: float
    timings: dict[str, float]
    expansion: str
    dt: float
    control_history: np.ndarray | None
    time_history: np.ndarray | None
    extra: dict[str, Any]
    limits: tuple[np.ndarray, np.ndarray] | None
    active_set: np.ndarray | None

    #: the description's ``kind`` this class is the result of (None: any other)
    KIND: ClassVar[str | None] = None

    def __init__(
        self,
        *,
        times: np.ndarray,
        controls: np.ndarray,
        feedforward: np.ndarray,
        feedback: np.ndarray,
        cost: float,
        iterations: int,
        converged: bool,
        status: str,
        message: str,
        cost_history: np.ndarray,
        grad_norm_history: np.ndarray,
        reg_history: np.ndarray,
        step_history: np.ndarray,
        expansion_history: list[str],
        solve_time_s: float,
        timings: dict[str, float],
        expansion: str,
        dt: float,
        q: np.ndarray | None = None,
        v: np.ndarray | None = None,
        model: dict[str, Any] | None = None,
        control_history: np.ndarray | None = None,
        time_history: np.ndarray | None = None,
        extra: dict[str, Any] | None = None,
        limits: tuple[np.ndarray, np.ndarray] | None = None,
        active_set: np.ndarray | None = None,
        # pre-generic keywords of the description
        target_rotation: np.ndarray | None = None,
        target_angular_velocity: np.ndarray | None = None,
        integrator: str | None = None,
    ) -> None:
        self.times = times
        self.controls = controls
        self.feedforward = feedforward
        self.feedback = feedback
        self.cost = cost
        self.iterations = iterations
        self.converged = converged
        self.status = status
        self.message = message
        self.cost_history = cost_history
        self.grad_norm_history = grad_norm_history
        self.reg_history = reg_history
        self.step_history = step_history
        self.expansion_history = expansion_history
        self.solve_time_s = solve_time_s
        self.timings = timings
        self.expansion = expansion
        self.dt = dt
        self.control_history = control_history
        self.time_history = time_history
        self.extra = {} if extra is None else extra
        self.limits = limits
        self.active_set = active_set
        model = {} if model is None else dict(model)
        if self.KIND is not None:
            model.setdefault("kind", self.KIND)
        model.setdefault("dt", dt)
        if integrator is not None:
            model["integrator"] = integrator
        if target_rotation is not None:
            model["target_rotation"] = target_rotation
        if target_angular_velocity is not None:
            model["target_angular_velocity"] = target_angular_velocity
        self.q, self.v, self.model = q, v, model
        self._views: dict[str, Any] = {}  # root views assigned after construction

    # ------------------------------------------------------------------ generic
    @property
    def horizon(self) -> int:
        """Number of control steps H."""
        return int(self.controls.shape[0])

    @property
    def integrator(self) -> str:
        """The integrator used (euler | semi_implicit | rk4 | variational)."""
        return str(self.model.get("integrator", ""))

    @integrator.setter
    def integrator(self, value: str) -> None:
        self.model["integrator"] = value

    @property
    def grad_norm(self) -> float:
        """Gradient norm at the final iterate."""
        return float(self.grad_norm_history[-1])

    def with_trajectory(self, times: np.ndarray, q: np.ndarray, v: np.ndarray, controls: np.ndarray,
                        **extra: Any) -> "Result":
        """A result of the same kind with another trajectory: times (N+1,), states q, v and
        controls (N, m) replaced, ``extra`` added, the description copied and the solver's fields
        shared; its views derive from the new states (a simulated run replayed beside its plan)."""
        r = copy.copy(self)
        r.model = dict(self.model)
        r.extra = {**self.extra, **extra}
        r._views = {}
        r.times, r.q, r.v, r.controls = times, q, v, controls
        return r

    # ------------------------------------------------------------------ the root body's attitude
    def _attitude(self) -> tuple[np.ndarray, np.ndarray]:
        """(rotations (H+1, 3, 3), body rates (H+1, 3)) of the root body."""
        N = np.shape(self.times)[0]
        return (self._views.get("rotations", np.tile(np.eye(3), (N, 1, 1))),
                self._views.get("angular_velocities", np.zeros((N, 3))))

    def _set_view(self, name: str, value: np.ndarray) -> None:
        self._views[name] = value

    @property
    def rotations(self) -> np.ndarray:
        """(H+1, 3, 3) body-to-world attitudes R_k (the root body's)."""
        return self._attitude()[0]

    @rotations.setter
    def rotations(self, value: np.ndarray) -> None:
        self._set_view("rotations", value)

    @property
    def angular_velocities(self) -> np.ndarray:
        """(H+1, 3) body-frame angular velocities Omega_k in rad/s (the root body's)."""
        return self._attitude()[1]

    @angular_velocities.setter
    def angular_velocities(self, value: np.ndarray) -> None:
        self._set_view("angular_velocities", value)

    @property
    def target_rotation(self) -> np.ndarray:
        """(3, 3) desired terminal attitude R_d."""
        return np.asarray(self.model.get("target_rotation", np.eye(3)), dtype=float)

    @target_rotation.setter
    def target_rotation(self, value: np.ndarray) -> None:
        self.model["target_rotation"] = value

    @property
    def target_angular_velocity(self) -> np.ndarray:
        """(3,) desired terminal angular velocity Omega_d in rad/s."""
        return np.asarray(self.model.get("target_angular_velocity", np.zeros(3)), dtype=float)

    @target_angular_velocity.setter
    def target_angular_velocity(self, value: np.ndarray) -> None:
        self.model["target_angular_velocity"] = value

    @property
    def quaternions(self) -> np.ndarray:
        """(H+1, 4) attitudes as unit quaternions (x, y, z, w), sign-continuous in time."""
        return rotations_to_quaternions(self.rotations)

    @property
    def attitude_error_deg(self) -> float:
        """Geodesic angle between R_H and R_d in degrees."""
        E = self.target_rotation.T @ self.rotations[-1]
        c = np.clip((np.trace(E) - 1.0) / 2.0, -1.0, 1.0)
        return float(np.degrees(np.arccos(c)))

    @property
    def angular_velocity_error(self) -> float:
        """||Omega_H - Omega_d|| in rad/s."""
        return float(np.linalg.norm(self.angular_velocities[-1] - self.target_angular_velocity))

    # ------------------------------------------------------------------ JSON
    def _state_fields(self) -> dict[str, Any]:
        """The JSON's fields of a multibody state ("configurations", "velocities", "multibody"),
        null here, and "model", the description."""
        return {"configurations": None, "velocities": None, "multibody": None, "model": _jsonable(self.model)}

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary (arrays as nested lists): every field the JSON has ever had, plus
        ``model`` (the description)."""
        R, w = self._attitude()
        return {
            "cost": self.cost,
            "iterations": self.iterations,
            "converged": self.converged,
            "status": self.status,
            "message": self.message,
            "expansion": self.expansion,
            "integrator": self.integrator,
            "dt": self.dt,
            "horizon": self.horizon,
            "cost_history": self.cost_history.tolist(),
            "grad_norm_history": self.grad_norm_history.tolist(),
            "reg_history": self.reg_history.tolist(),
            "step_history": self.step_history.tolist(),
            "expansion_history": list(self.expansion_history),
            "attitude_error_deg": self.attitude_error_deg,
            "angular_velocity_error": self.angular_velocity_error,
            "grad_norm": self.grad_norm,
            "solve_time_s": self.solve_time_s,
            "timings": dict(self.timings),
            "times": self.times.tolist(),
            "controls": self.controls.tolist(),
            "quaternions": rotations_to_quaternions(R).tolist(),
            "angular_velocities": np.asarray(w).tolist(),
            "rotations": np.asarray(R).tolist(),
            "feedforward": self.feedforward.tolist(),
            "feedback": self.feedback.tolist(),
            "target_rotation": self.target_rotation.tolist(),
            "target_angular_velocity": self.target_angular_velocity.tolist(),
            "control_history": None if self.control_history is None else self.control_history.tolist(),
            "time_history": None if self.time_history is None else self.time_history.tolist(),
            **self._state_fields(),
            # the certificate of the final check (solver.loop._Solve.final_check); None if not solved here
            "optimality": _jsonable(self.extra.get("optimality")),
            # hard constraints (geoddp.constraints.solve_constrained): feasibility, multipliers,
            # active nodes, the outer iterations; None for a solve without constraints
            "constraints": _jsonable(self.extra.get("constraints")),
            # control limits: unbounded sides as null (strict JSON has no infinity; a NaN bound is
            # invalid, so null is unambiguous)
            "limits": None if self.limits is None else {
                "lower": np.where(np.isfinite(self.limits[0]), self.limits[0], np.nan).tolist(),
                "upper": np.where(np.isfinite(self.limits[1]), self.limits[1], np.nan).tolist()},
            "active_set": None if self.active_set is None else np.asarray(self.active_set).tolist(),
        }

    def write_json(self, path: str | Path) -> Path:
        """Write :meth:`to_dict` to ``path`` (parents created) atomically, as strict JSON (a
        non-finite number is written as null and read back as NaN). Returns the path."""
        from ..output_files import strict_json, write_atomic

        return write_atomic(path, strict_json(self.to_dict()))

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "Result":
        """Inverse of :meth:`to_dict`, of the kind the dictionary describes (``model.kind``; a file
        written before ``model`` existed is a multibody result if it has configurations, else a
        satellite one); also reads dictionaries written before ``model`` existed.

        Raises:
            InputError: naming ``result``: not a dict, a field missing, or one that does not
                convert (what a file not written by :meth:`write_json` gives).
        """
        if not isinstance(d, dict):
            raise InputError("result", f"expected a dict written by Result.to_dict, got {type(d).__name__}")
        try:
            return _from_dict(d)
        except InputError:
            raise
        except KeyError as exc:
            raise InputError("result", f"expected a dict written by Result.to_dict, the field {exc.args[0]!r} is "
                             "missing") from None
        except (TypeError, ValueError, AttributeError) as exc:
            raise InputError("result", f"expected a dict written by Result.to_dict, a field does not convert ({exc})"
                             ) from None

    @classmethod
    def read_json(cls, path: str | Path) -> "Result":
        """Read a file written by :meth:`write_json` (or by any earlier version).

        Raises:
            InputError: naming the path: unreadable, not JSON, or not a result (:meth:`from_dict`).
        """
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(str(path), f"expected a readable result JSON file ({exc})") from None
        try:
            d = json.loads(text)
        except json.JSONDecodeError as exc:
            raise InputError(str(path), f"expected a result JSON file, got invalid JSON ({exc.msg} at line "
                             f"{exc.lineno}, column {exc.colno})") from None
        try:
            return cls.from_dict(d)
        except InputError as exc:
            raise InputError(str(path), exc.detail) from None


class SatelliteResult(Result):
    """A rigid body on TSO(3) (the satellite's closed forms): q (H+1, 3, 3) the rotations R_k
    and v (H+1, 3) the body rates Omega_k (rad/s), which are the attitude views themselves.

    The constructor also takes the pre-generic keywords ``rotations`` and ``angular_velocities``
    for q and v.
    """

    KIND = "satellite"

    def __init__(self, *, rotations: np.ndarray | None = None, angular_velocities: np.ndarray | None = None,
                 **fields: Any) -> None:
        if fields.get("q") is None:
            fields["q"], fields["v"] = rotations, angular_velocities
        super().__init__(**fields)

    def _attitude(self) -> tuple[np.ndarray, np.ndarray]:
        return self.q, self.v

    def _set_view(self, name: str, value: np.ndarray) -> None:
        # the views are the state
        if name == "rotations":
            self.q = value
        else:
            self.v = value


class MultibodyResult(Result):
    """A Pinocchio multibody: q (H+1, nq) configurations and v (H+1, nv) velocities
    (``configurations`` and ``velocities``), ``multibody`` the viewer's description of the model,
    and the attitude views those of the root joint (free flyer or spherical; identity and zero
    rates for a fixed root).

    The constructor also takes the pre-generic keywords ``configurations``, ``velocities``,
    ``multibody`` (merged into the description) and ``rotations``, ``angular_velocities`` (the
    root views of a result without a description, which has nothing to derive them from).
    """

    KIND = "multibody"

    def __init__(self, *, configurations: np.ndarray | None = None, velocities: np.ndarray | None = None,
                 multibody: dict[str, Any] | None = None, rotations: np.ndarray | None = None,
                 angular_velocities: np.ndarray | None = None, **fields: Any) -> None:
        if fields.get("q") is None:
            fields["q"], fields["v"] = configurations, velocities
        model = fields["model"] = dict(fields.get("model") or {})
        model.setdefault("kind", self.KIND)  # first, as a solve's description has it
        for k, val in (multibody or {}).items():
            model.setdefault(k, val)
        super().__init__(**fields)
        self._root_views = (rotations, angular_velocities)

    @property
    def configurations(self) -> np.ndarray | None:
        """(H+1, nq) Pinocchio configurations (= q)."""
        return self.q

    @configurations.setter
    def configurations(self, value: np.ndarray | None) -> None:
        self._pin_root_views()
        self.q = value

    @property
    def velocities(self) -> np.ndarray | None:
        """(H+1, nv) generalised velocities (= v)."""
        return self.v

    @velocities.setter
    def velocities(self, value: np.ndarray | None) -> None:
        self._pin_root_views()
        self.v = value

    @property
    def multibody(self) -> dict[str, Any] | None:
        """What the viewer needs to rebuild the model without the solver (None without a
        description): ``{"urdf": absolute path (str), "urdf_xml": the URDF text as solved (str),
        "root": "free_flyer" | "spherical" | "fixed", "nq": int, "nv": int}``."""
        if "root" not in self.model:
            return None
        return _WriteThrough(self.model, _MULTIBODY_KEYS)

    @multibody.setter
    def multibody(self, value: dict[str, Any] | None) -> None:
        for k in _MULTIBODY_KEYS:
            self.model.pop(k, None)
        if value is not None:
            self.model.update(value)

    def _attitude(self) -> tuple[np.ndarray, np.ndarray]:
        if "root" in self.model and self.q is not None and self.v is not None:
            R, w = _root_rotations_and_rates(np.asarray(self.q), np.asarray(self.v), self.model["root"])
        else:
            R, w = self._root_views
            N = np.shape(self.times)[0]
            R = np.tile(np.eye(3), (N, 1, 1)) if R is None else R
            w = np.zeros((N, 3)) if w is None else w
        return self._views.get("rotations", R), self._views.get("angular_velocities", w)

    def _pin_root_views(self) -> None:
        # Before the state changes by assignment, keep the root views it had (an assigned state
        # may be partial, as the viewer's input checks exercise).
        if self.q is not None and self.v is not None:
            R, w = self._attitude()
            self._views.setdefault("rotations", R)
            self._views.setdefault("angular_velocities", w)

    def _state_fields(self) -> dict[str, Any]:
        Q, V, mb = self.configurations, self.velocities, self.multibody
        return {
            "configurations": None if Q is None else np.asarray(Q).tolist(),
            "velocities": None if V is None else np.asarray(V).tolist(),
            "multibody": None if mb is None else dict(mb),
            # the description, without what the "multibody" field already holds (the URDF text once)
            "model": _jsonable({k: val for k, val in self.model.items() if mb is None or k not in mb}),
        }


#: The result class of each ``kind`` of model description.
KINDS: dict[str, type[Result]] = {"satellite": SatelliteResult, "multibody": MultibodyResult}


def result_class(model: dict[str, Any]) -> type[Result]:
    """The Result kind of a problem's model description (its ``kind``; :class:`Result` itself for
    a kind of the user's)."""
    return KINDS.get(model.get("kind"), Result)


def _from_dict(d: dict[str, Any]) -> Result:
    a = lambda x, dtype=float: np.asarray(_nan_for_none(x), dtype=dtype)  # noqa: E731  (strict JSON: null = NaN)
    opt = lambda key: None if d.get(key) is None else a(d[key], dtype=float)  # noqa: E731
    model = dict(d["model"]) if d.get("model") is not None else None
    if model is not None and d.get("multibody") is not None:
        model.update(d["multibody"])  # to_dict writes the viewer's keys only once, there
    multibody = (model or {}).get("kind") == "multibody" or d.get("configurations") is not None
    for key in ("target_rotation", "target_angular_velocity"):
        if model is not None and key in model:
            model[key] = a(model[key], dtype=float)
    fields = dict(
        times=a(d["times"], dtype=float),
        model=model,
        controls=a(d["controls"], dtype=float),
        feedforward=a(d["feedforward"], dtype=float),
        feedback=a(d["feedback"], dtype=float),
        cost=float(d["cost"]),
        iterations=int(d["iterations"]),
        converged=bool(d["converged"]),
        status=str(d["status"]),
        message=str(d["message"]),
        cost_history=a(d["cost_history"], dtype=float),
        grad_norm_history=a(d["grad_norm_history"], dtype=float),
        reg_history=a(d["reg_history"], dtype=float),
        step_history=a(d["step_history"], dtype=float),
        expansion_history=list(d["expansion_history"]),
        solve_time_s=float(d["solve_time_s"]),
        timings=dict(d["timings"]),
        expansion=str(d["expansion"]),
        dt=float(d["dt"]),
        control_history=opt("control_history"),
        time_history=opt("time_history"),
        # pre-generic files: the description is rebuilt from these (ignored when model is set)
        target_rotation=None if model is not None else a(d["target_rotation"], dtype=float),
        target_angular_velocity=None if model is not None else a(d["target_angular_velocity"], dtype=float),
        integrator=None if model is not None else str(d["integrator"]),
        extra={key: dict(d[key]) for key in ("optimality", "constraints") if d.get(key) is not None} or None,
        limits=_limits_from_json(d.get("limits")),
        active_set=None if d.get("active_set") is None else np.asarray(d["active_set"], dtype=np.int8),
    )
    if multibody:
        # the root views are kept for a multibody without a description (nothing to derive them from)
        return MultibodyResult(
            q=a(d["configurations"], dtype=float), v=a(d["velocities"], dtype=float),
            rotations=a(d["rotations"], dtype=float), angular_velocities=a(d["angular_velocities"], dtype=float),
            multibody=None if model is not None or d.get("multibody") is None else dict(d["multibody"]), **fields)
    return SatelliteResult(q=a(d["rotations"], dtype=float), v=a(d["angular_velocities"], dtype=float), **fields)
