"""The solved trajectory as plain data.

A :class:`Result` is what the solver hands downstream: the viewer, the figures and the JSON
writer read it and never call back into the solver. Everything is numpy arrays or builtins.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

STATUS_CONVERGED_COST = "converged: |J_i - J_(i-1)| <= tol"
STATUS_CONVERGED_GRAD = "converged: gradient norm <= grad_tol"
STATUS_MAX_ITER = "stopped: max_iter reached"
STATUS_NO_DESCENT = "stopped: line search found no descent step"
STATUS_MAX_REG = "stopped: regularisation exceeded its maximum"
STATUS_SADDLE = "stopped: stationary point that is not a minimum (reduced Hessian indefinite)"


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


@dataclass
class Result:
    """Solution of a geometric DDP solve on TSO(3).

    Shapes use H = horizon (number of control steps) and m = number of inputs.

    Attributes:
        times: (H+1,) time stamps in seconds, ``k * dt``.
        rotations: (H+1, 3, 3) body-to-world attitudes R_k.
        angular_velocities: (H+1, 3) body-frame angular velocities Omega_k in rad/s.
        controls: (H, m) inputs u_k (torque units of the actuation matrix).
        feedforward: (H, m) the last backward pass's k_k = Q_uu^-1 Q_u.
        feedback: (H, m, 6) the last backward pass's K_k = Q_uu^-1 Q_ug; the control law is
            u = u_k - gamma k_k - K_k zeta with zeta = (log(R_k^T R), Omega - Omega_k).
        target_rotation: (3, 3) desired terminal attitude R_d.
        target_angular_velocity: (3,) desired terminal angular velocity Omega_d in rad/s.
        cost: final total cost J.
        iterations: number of accepted iterations.
        converged: True only when a stopping test on |dJ| or on the gradient passed.
        status: one of the STATUS_* strings of this module.
        message: human-readable detail on the status.
        cost_history: (iterations+1,) J at the initial guess and after each accepted iteration.
        grad_norm_history: (iterations+1,) ||dJ/dU|| at the same iterates.
        reg_history: (iterations,) Q_uu regularisation lambda used by each iteration.
        step_history: (iterations,) line-search gamma accepted by each iteration (for a saddle
            escape, the step length |alpha| along the negative-curvature direction).
        expansion_history: (iterations,) "first" or "second" per iteration (a saddle escape, which
            uses the exact second-order check, is recorded as "second").
        control_history: (iterations+1, H, m) controls per iterate (only when recorded).
        configurations: (H+1, nq) Pinocchio configurations of a multibody solve (None on TSO(3));
            then ``rotations``/``angular_velocities`` describe the root body.
        velocities: (H+1, nv) generalised velocities of a multibody solve (None on TSO(3)).
        multibody: what the viewer needs to rebuild a multibody model without the solver (None on
            TSO(3)): ``{"urdf": absolute path (str), "urdf_xml": the URDF text as solved (str),
            "root": "free_flyer" | "spherical" | "fixed", "nq": int, "nv": int}``.
        time_history: (iterations+1,) wall time in seconds from the start of the solve at which
            each iterate of cost_history was reached (0 for the initial guess).
        solve_time_s: wall time of the solve in seconds.
        timings: breakdown in seconds (derivatives, backward, forward, ...).
        expansion: the expansion option used (first | second | switch).
        integrator: the integrator used (euler | semi_implicit).
        dt: time step in seconds.
        extra: free-form additions; the solver puts ``"saddle_escapes"`` here (a list of dicts with
            iteration, node, eigenvalue, alpha, cost_before, cost_after) when it escaped a saddle.
    """

    times: np.ndarray
    rotations: np.ndarray
    angular_velocities: np.ndarray
    controls: np.ndarray
    feedforward: np.ndarray
    feedback: np.ndarray
    target_rotation: np.ndarray
    target_angular_velocity: np.ndarray
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
    integrator: str
    dt: float
    control_history: np.ndarray | None = None
    time_history: np.ndarray | None = None
    configurations: np.ndarray | None = None
    velocities: np.ndarray | None = None
    multibody: dict[str, Any] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def horizon(self) -> int:
        """Number of control steps H."""
        return int(self.controls.shape[0])

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

    @property
    def grad_norm(self) -> float:
        """Gradient norm at the final iterate."""
        return float(self.grad_norm_history[-1])

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary (arrays as nested lists)."""
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
            "quaternions": self.quaternions.tolist(),
            "angular_velocities": self.angular_velocities.tolist(),
            "rotations": self.rotations.tolist(),
            "feedforward": self.feedforward.tolist(),
            "feedback": self.feedback.tolist(),
            "target_rotation": self.target_rotation.tolist(),
            "target_angular_velocity": self.target_angular_velocity.tolist(),
            "control_history": None if self.control_history is None else self.control_history.tolist(),
            "time_history": None if self.time_history is None else self.time_history.tolist(),
            "configurations": None if self.configurations is None else self.configurations.tolist(),
            "velocities": None if self.velocities is None else self.velocities.tolist(),
            "multibody": None if self.multibody is None else dict(self.multibody),
        }

    def write_json(self, path: str | Path) -> Path:
        """Write :meth:`to_dict` to ``path`` (parents created). Returns the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(self.to_dict(), indent=1))
        return path

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "Result":
        """Inverse of :meth:`to_dict`."""
        a = np.asarray
        return cls(
            times=a(d["times"], dtype=float),
            rotations=a(d["rotations"], dtype=float),
            angular_velocities=a(d["angular_velocities"], dtype=float),
            controls=a(d["controls"], dtype=float),
            feedforward=a(d["feedforward"], dtype=float),
            feedback=a(d["feedback"], dtype=float),
            target_rotation=a(d["target_rotation"], dtype=float),
            target_angular_velocity=a(d["target_angular_velocity"], dtype=float),
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
            integrator=str(d["integrator"]),
            dt=float(d["dt"]),
            control_history=None if d.get("control_history") is None else a(d["control_history"], dtype=float),
            time_history=None if d.get("time_history") is None else a(d["time_history"], dtype=float),
            configurations=None if d.get("configurations") is None else a(d["configurations"], dtype=float),
            velocities=None if d.get("velocities") is None else a(d["velocities"], dtype=float),
            multibody=None if d.get("multibody") is None else dict(d["multibody"]),
        )

    @classmethod
    def read_json(cls, path: str | Path) -> "Result":
        """Read a file written by :meth:`write_json`."""
        return cls.from_dict(json.loads(Path(path).read_text()))

