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

from .contract import Linearisation, Trajectory
from .costs import CostDerivatives
from .integrators import Expansion
from .models.multibody import Multibody
from .urdf_checks import read_urdf_text
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
        zeta_k = local(x_bar_k, x_k). Returns False if the state became non-finite."""
        model, data = self.model, self._data
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
        """Phi, B (and Theta, Gamma, Xi for order 2) along a trajectory; ``backend`` is unused:
        multibody derivatives always come from Pinocchio (analytic first order, central
        differences of it for the velocity update's second order)."""
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

    @property
    def dt(self) -> float:
        """Time step in seconds."""
        return self.model.dt

    # ------------------------------------------------------------ the solver's contract
    # (geoddp.contract.OptimalControlProblem): thin adapters over the array methods above.
    def trajectory(self, controls: np.ndarray) -> Trajectory:
        """(H, m) controls -> Trajectory(q = Q (H+1, nq), v = V (H+1, nv), u)."""
        Q, V = self.rollout(controls)
        return Trajectory(Q, V, controls)

    def trajectory_cost(self, traj: Trajectory) -> float:
        """Total cost J of a trajectory."""
        return self.cost(traj.q, traj.v, traj.u)

    def linearise(self, traj: Trajectory, order: int) -> Linearisation:
        """Dynamics expansion and cost derivatives along ``traj``."""
        exp = self.model.expansion(traj.q, traj.v, traj.u, order=order)
        run, term = self.cost_derivatives(traj.q, traj.v, traj.u)
        return Linearisation.from_parts(order, exp, run, term)

    def rollout_policy(self, traj: Trajectory, k: np.ndarray, K: np.ndarray, step: float) -> Trajectory | None:
        """:meth:`rollout_closed_loop` around ``traj`` into new arrays; None if non-finite."""
        Q, V, U = np.empty_like(traj.q), np.empty_like(traj.v), np.empty_like(traj.u)
        if not self.rollout_closed_loop(traj.q, traj.v, traj.u, k, K, step, Q, V, U):
            return None
        return Trajectory(Q, V, U)

    def describe(self) -> dict:
        """Model description for the Result: kind "multibody", dt, integrator, the
        :meth:`model_description` keys (urdf, urdf_xml, root, nq, nv) and the target attitude of
        a terminal frame-placement term (``target_rotation`` (3, 3), identity without one;
        ``target_angular_velocity`` zero)."""
        R_d = np.eye(3)
        for t in getattr(self.terminal, "terms", []):
            if isinstance(t, FramePlacement):
                R_d = t.M_ref[-1, :3, :3].copy()  # (K, 4, 4) references; the last is the final node's
        return {"kind": "multibody", "dt": self.model.dt, "integrator": self.model.integrator,
                **self.model_description(), "target_rotation": R_d, "target_angular_velocity": np.zeros(3)}

    def model_description(self) -> dict:
        """``Result.multibody``: the URDF (absolute path and its text as solved), the root joint
        kind and (nq, nv), enough to rebuild the kinematics and visuals without the solver."""
        m = self.model
        urdf = Path(m.urdf).resolve()
        return {"urdf": str(urdf), "urdf_xml": read_urdf_text(urdf), "root": m.root,
                "nq": m.nq, "nv": m.nv}
