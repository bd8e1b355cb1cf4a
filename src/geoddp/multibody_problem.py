"""The optimal control problem for a Pinocchio multibody (paper eq. optprob on G = configuration x
velocities).

It speaks the same protocol as :class:`geoddp.problem.Problem`, so :func:`geoddp.solver.solve`
solves it unchanged: a trajectory is the pair (Q (H+1, nq), V (H+1, nv)); its tangent
perturbation is zeta = (dq, dv) with q = integrate(q_bar, dq) (Pinocchio's right/local
convention), v = v_bar + dv, nx = 2 nv.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from .costs import CostDerivatives
from .integrators import Expansion
from .models import compiled
from .models.multibody import Multibody
from .multibody_costs import FramePlacement, MultibodyCostSum
from .validate import InputError, finite_array, positive_int


@dataclass
class MultibodyProblem:
    """min_U sum_k running(q_k, v_k, u_k) + terminal(q_H, v_H) s.t. the model's dynamics.

    Attributes:
        model: the :class:`Multibody` (URDF, root joint, actuation, dt, integrator).
        q0: (nq,) initial configuration; v0: (nv,) initial velocity.
        horizon: number of control steps H.
        running: running cost (on k = 0 .. H-1); terminal: terminal cost (on k = H).
    """

    model: Multibody
    q0: np.ndarray
    v0: np.ndarray
    horizon: int
    running: MultibodyCostSum
    terminal: MultibodyCostSum
    _data: pin.Data = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.q0, self.v0 = self.model.check_state(self.q0, self.v0, "initial")
        self.horizon = positive_int(self.horizon, "horizon")
        for name, s in (("running", self.running), ("terminal", self.terminal)):
            if s.nx != self.model.nx:
                raise InputError(name, f"expected costs on the model's tangent space (nx = {self.model.nx}), got nx = {s.nx}")
        self._data = self.model.pin_model.createData()

    @property
    def nu(self) -> int:
        return self.model.nu

    @property
    def nx(self) -> int:
        """Dimension of the tangent state zeta = (dq, dv): 2 nv."""
        return self.model.nx

    def check_controls(self, controls: np.ndarray, name: str = "initial_controls") -> np.ndarray:
        """Validated (H, m) float64 copy of a control sequence."""
        return finite_array(controls, name, (self.horizon, self.nu))

    def rollout(self, controls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(H, m) controls -> Q (H+1, nq), V (H+1, nv)."""
        return self.model.rollout(self.q0, self.v0, controls)

    def rollout_closed_loop(
        self, Q_bar: np.ndarray, V_bar: np.ndarray, u_bar: np.ndarray, k_ff: np.ndarray, K_fb: np.ndarray,
        gamma: float, Q_out: np.ndarray, V_out: np.ndarray, u_out: np.ndarray,
    ) -> bool:
        """Forward pass of Algorithm 1 (eq. dustar): u_k = u_bar_k - gamma k_k - K_k zeta_k with
        zeta_k = local(x_bar_k, x_k). Returns False if the state became non-finite.

        Shapes: Q_bar, Q_out (H+1, nq); V_bar, V_out (H+1, nv); u_bar, k_ff, u_out (H, m);
        K_fb (H, m, 2 nv). With the compiled backend the whole pass runs in C++."""
        model, data = self.model, self._data
        if model.backend == "compiled":
            H, nq, nv, m = self.horizon, model.nq, model.nv, model.nu
            ca, co = compiled.check_array, compiled.check_output
            return compiled._core.rollout_closed_loop(
                model.pin_model, model.actuation, model.dt, compiled.INTEGRATORS[model.integrator], self.q0, self.v0,
                ca(Q_bar, "Q_bar", (H + 1, nq)), ca(V_bar, "V_bar", (H + 1, nv)), ca(u_bar, "u_bar", (H, m)),
                ca(k_ff, "k_ff", (H, m)), ca(K_fb, "K_fb", (H, m, 2 * nv)), float(gamma),
                co(Q_out, "Q_out", (H + 1, nq)), co(V_out, "V_out", (H + 1, nv)), co(u_out, "u_out", (H, m)))
        Q_out[0], V_out[0] = self.q0, self.v0
        for k in range(self.horizon):
            zeta = model.local(Q_bar[k], V_bar[k], Q_out[k], V_out[k])
            u = u_bar[k] - gamma * k_ff[k] - K_fb[k] @ zeta
            u_out[k] = u
            q1, v1 = model._step(data, Q_out[k], V_out[k], u)
            if not (np.all(np.isfinite(q1)) and np.all(np.isfinite(v1))):
                return False
            Q_out[k + 1], V_out[k + 1] = q1, v1
        return True

    def expansion(self, Q: np.ndarray, V: np.ndarray, controls: np.ndarray, order: int, backend: str) -> Expansion:
        """Phi, B (and Theta, Gamma, Xi for order 2) along a trajectory; ``backend`` (the
        satellite's derivative option) is unused: the multibody model's own backend, chosen
        when it was built, computes them (:class:`geoddp.models.multibody.Multibody`)."""
        return self.model.expansion(Q, V, controls, order=order)

    def cost(self, Q: np.ndarray, V: np.ndarray, controls: np.ndarray) -> float:
        """Total cost J of a trajectory."""
        H = self.horizon
        return float(self.running.value(Q[:H], V[:H], controls).sum() + self.terminal.value(Q[H:], V[H:], None)[0])

    def total_cost(self, controls: np.ndarray) -> float:
        """J(U) by single shooting."""
        Q, V = self.rollout(controls)
        return self.cost(Q, V, controls)

    def cost_derivatives(self, Q: np.ndarray, V: np.ndarray, controls: np.ndarray) -> tuple[CostDerivatives, CostDerivatives]:
        """Running derivatives at k < H and terminal derivatives at k = H (N = 1)."""
        H = self.horizon
        return self.running.derivatives(Q[:H], V[:H], controls), self.terminal.derivatives(Q[H:], V[H:], None)

    def trajectory_fields(self, Q: np.ndarray, V: np.ndarray) -> dict:
        """Result fields: the root body's attitude and body rate (identity and zero for a fixed
        root), the target attitude of a terminal frame-placement term, the full (Q, V), and the
        model description the viewer rebuilds the model from (:meth:`model_description`)."""
        root = self.model.root
        N = Q.shape[0]
        if root == "free_flyer":
            quat, rate = Q[:, 3:7], V[:, 3:6]
        elif root == "spherical":
            quat, rate = Q[:, 0:4], V[:, 0:3]
        else:
            quat, rate = np.tile([0.0, 0.0, 0.0, 1.0], (N, 1)), np.zeros((N, 3))
        R = np.array([pin.Quaternion(q[3], q[0], q[1], q[2]).normalized().toRotationMatrix() for q in quat])
        R_d = np.eye(3)
        for t in getattr(self.terminal, "terms", []):
            if isinstance(t, FramePlacement):
                R_d = t.M_ref[-1, :3, :3].copy()  # (K, 4, 4) references; the last is the final node's
        return dict(rotations=R, angular_velocities=np.array(rate), target_rotation=R_d,
                    target_angular_velocity=np.zeros(3), configurations=Q, velocities=V,
                    multibody=self.model_description())

    def model_description(self) -> dict:
        """``Result.multibody``: the URDF (absolute path and its text as solved), the root joint
        kind and (nq, nv), enough to rebuild the kinematics and visuals without the solver."""
        m = self.model
        urdf = Path(m.urdf).resolve()
        return {"urdf": str(urdf), "urdf_xml": urdf.read_text(encoding="utf-8"), "root": m.root,
                "nq": m.nq, "nv": m.nv}
