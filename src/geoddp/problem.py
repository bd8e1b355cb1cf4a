"""The optimal control problem (paper eq. optprob): dynamics, costs, horizon, initial state.

    min_U  J = sum_{k<H} Lambda(g_k, u_k) + F(g_H)   s.t.  g_{k+1} = f(g_k, u_k), g_0 given.

The running cost is applied as written, without a dt factor (the paper's convention); to compare
with Crocoddyl, whose integrated action models multiply running costs by dt, divide its weights by dt.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import kernels
from .contract import Linearisation, Trajectory
from .costs import (
    AngularVelocityQuadratic,
    AttitudeChordal,
    AttitudeGeodesic,
    ControlQuadratic,
    CostDerivatives,
    CostSum,
)
from .models.satellite import Satellite
from .validate import InputError, choice, finite_array, positive_int, rotation_matrix

ATTITUDE_KINDS = ("chordal", "geodesic")


@dataclass
class Problem:
    """A satellite attitude problem on TSO(3).

    Attributes:
        model: the :class:`Satellite` (dynamics, dt, integrator).
        R0: (3, 3) initial attitude. Omega0: (3,) initial body rate (rad/s).
        horizon: number of control steps H.
        running: running cost Lambda (applied at k = 0 .. H-1).
        terminal: terminal cost F (applied at k = H).
    """

    model: Satellite
    R0: np.ndarray
    Omega0: np.ndarray
    horizon: int
    running: CostSum
    terminal: CostSum

    def __post_init__(self) -> None:
        self.R0 = rotation_matrix(self.R0, "initial.rotation")
        self.Omega0 = finite_array(self.Omega0, "initial.angular_velocity", (3,))
        self.horizon = positive_int(self.horizon, "horizon")

    @property
    def nu(self) -> int:
        return self.model.nu

    @property
    def nx(self) -> int:
        """Dimension of the tangent state zeta = (eta, dOmega)."""
        return 6

    @property
    def dt(self) -> float:
        """Time step in seconds."""
        return self.model.dt

    # ------------------------------------------------------------ the solver's contract
    # (geoddp.contract.OptimalControlProblem): thin adapters over the array methods below.
    def trajectory(self, controls: np.ndarray) -> Trajectory:
        """(H, m) controls -> Trajectory(q = R (H+1, 3, 3), v = Omega (H+1, 3), u)."""
        R, Om = self.rollout(controls)
        return Trajectory(R, Om, controls)

    def trajectory_cost(self, traj: Trajectory) -> float:
        """Total cost J of a trajectory (paper eq. J)."""
        return self.cost(traj.q, traj.v, traj.u)

    def linearise(self, traj: Trajectory, order: int) -> Linearisation:
        """Dynamics expansion (with the model's backend) and cost derivatives along ``traj``."""
        exp = self.expansion(traj.q, traj.v, traj.u, order)
        run, term = self.cost_derivatives(traj.q, traj.v, traj.u)
        return Linearisation.from_parts(order, exp, run, term)

    def rollout_policy(self, traj: Trajectory, k: np.ndarray, K: np.ndarray, step: float) -> Trajectory | None:
        """:meth:`rollout_closed_loop` around ``traj`` into new arrays; None if non-finite."""
        R, Om, U = np.empty_like(traj.q), np.empty_like(traj.v), np.empty_like(traj.u)
        if not self.rollout_closed_loop(traj.q, traj.v, traj.u, k, K, step, R, Om, U):
            return None
        return Trajectory(R, Om, U)

    def describe(self) -> dict:
        """Model description for the Result: kind "satellite", dt, integrator, inertia (3, 3),
        actuation (3, m), urdf (str or None) and the target R_d (3, 3), Omega_d (3,) of the
        terminal cost (identity and zero without such terms)."""
        R_d, Omega_d = np.eye(3), np.zeros(3)
        for t in self.terminal.terms:
            R_d = getattr(t, "R_d", R_d)
            Omega_d = getattr(t, "Omega_d", Omega_d)
        m = self.model
        return {"kind": "satellite", "dt": m.dt, "integrator": m.integrator, "inertia": m.inertia.copy(),
                "actuation": m.actuation.copy(), "urdf": None if m.urdf is None else str(m.urdf),
                "target_rotation": np.array(R_d, dtype=float),
                "target_angular_velocity": np.array(Omega_d, dtype=float)}

    def check_controls(self, controls: np.ndarray, name: str = "initial_controls") -> np.ndarray:
        """Validated (H, m) float64 copy of a control sequence."""
        return finite_array(controls, name, (self.horizon, self.nu))

    def rollout(self, controls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(H, m) controls -> R (H+1, 3, 3), Omega (H+1, 3)."""
        return self.model.rollout(self.R0, self.Omega0, controls)

    def rollout_closed_loop(
        self, R_bar: np.ndarray, Omega_bar: np.ndarray, u_bar: np.ndarray, k_ff: np.ndarray, K_fb: np.ndarray,
        gamma: float, R_out: np.ndarray, Omega_out: np.ndarray, u_out: np.ndarray,
    ) -> bool:
        """Forward pass of Algorithm 1: u_k = u_bar_k - gamma k_k - K_k zeta_k (eq. dustar), zeta_k =
        (log(R_bar_k^T R_k), Omega_k - Omega_bar_k), from the initial state.

        Nominal R_bar (H+1,3,3), Omega_bar (H+1,3), u_bar (H,m); gains k_ff (H,m), K_fb (H,m,6);
        results into R_out, Omega_out, u_out. Returns False if the state became non-finite.
        """
        m = self.model
        return kernels.satellite_rollout(
            self.R0, self.Omega0, R_bar, Omega_bar, u_bar, k_ff, K_fb, gamma, True,
            m.inertia, m.inertia_inv, m.actuation, m.dt, m.semi_implicit, R_out, Omega_out, u_out,
        )

    def expansion(self, R: np.ndarray, Omega: np.ndarray, controls: np.ndarray, order: int, backend: str | None = None):
        """The model's expansion along a trajectory (see :meth:`Satellite.expansion`); ``backend``
        defaults to the model's."""
        return self.model.expansion(R, Omega, controls, order=order, backend=backend)

    def cost(self, R: np.ndarray, Omega: np.ndarray, controls: np.ndarray) -> float:
        """Total cost J of a trajectory (paper eq. J)."""
        H = self.horizon
        run = self.running.value(R[:H], Omega[:H], controls).sum()
        return float(run + self.terminal.value(R[H:], Omega[H:], None)[0])

    def total_cost(self, controls: np.ndarray) -> float:
        """J(U) by single shooting."""
        R, Om = self.rollout(controls)
        return self.cost(R, Om, controls)

    def cost_derivatives(
        self, R: np.ndarray, Omega: np.ndarray, controls: np.ndarray
    ) -> tuple[CostDerivatives, CostDerivatives]:
        """Running derivatives at k < H and terminal derivatives at k = H (N = 1)."""
        H = self.horizon
        return self.running.derivatives(R[:H], Omega[:H], controls), self.terminal.derivatives(R[H:], Omega[H:], None)


def satellite_problem(
    *,
    inertia,
    dt: float,
    horizon: int,
    R_d,
    actuation=None,
    R0=None,
    Omega0=None,
    Omega_d=None,
    S_u=0.1,
    S_R=1e4,
    S_Omega=1e4,
    attitude_kind: str = "chordal",
    running_S_R=None,
    running_S_Omega=None,
    integrator: str = "euler",
    second_order: str = "exact",
    urdf=None,
    backend: str = "compiled",
) -> Problem:
    """Build the paper's satellite problem (eqs. disceqs, optprobR, costR) from numbers.

    Weights accept a scalar, a vector (diagonal) or a matrix. Units: inertia kg m^2, dt s,
    angles rad, rates rad/s. ``backend`` picks the model's derivative backend
    (:attr:`Satellite.backend`).
    """
    actuation = np.eye(3) if actuation is None else actuation
    model = Satellite(inertia=inertia, actuation=actuation, dt=dt, integrator=integrator,
                      second_order=second_order, urdf=urdf, backend=backend)
    attitude_kind = choice(attitude_kind, "cost.attitude_kind", ATTITUDE_KINDS)
    Attitude = AttitudeChordal if attitude_kind == "chordal" else AttitudeGeodesic
    m = model.nu
    S_u_arr = np.asarray(S_u, dtype=float)
    if S_u_arr.ndim == 0:
        S_u_arr = float(S_u_arr) * np.eye(m)
    if S_u_arr.shape not in ((m,), (m, m)):
        raise InputError("cost.control", f"expected a scalar, {m} numbers or a {m}x{m} matrix, got shape {S_u_arr.shape}")
    running = CostSum([ControlQuadratic(S_u_arr)])
    if running_S_R is not None and np.any(np.asarray(running_S_R) != 0):
        running.terms.append(Attitude(running_S_R, R_d))
    if running_S_Omega is not None and np.any(np.asarray(running_S_Omega) != 0):
        running.terms.append(AngularVelocityQuadratic(running_S_Omega, Omega_d))
    terminal = CostSum([Attitude(S_R, R_d), AngularVelocityQuadratic(S_Omega, Omega_d)])
    return Problem(
        model=model,
        R0=np.eye(3) if R0 is None else R0,
        Omega0=np.zeros(3) if Omega0 is None else Omega0,
        horizon=horizon,
        running=running,
        terminal=terminal,
    )


def paper_problem(integrator: str = "euler", attitude_kind: str = "chordal", **overrides) -> Problem:
    """The paper's Table I: tf = 3 s, dt = 0.01 s, I = diag(10, 11.1, 13), H = I_3,
    R_d = Rot_x(30 deg) Rot_z(70 deg), S_u = 0.1 I, S_R = S_Omega = 1e4 I, zero initial state."""
    import pinocchio as pin

    R_d = pin.exp3(np.array([np.pi / 6, 0, 0])) @ pin.exp3(np.array([0, 0, np.radians(70.0)]))
    kw = dict(inertia=np.diag([10.0, 11.1, 13.0]), dt=0.01, horizon=300, R_d=R_d, S_u=0.1, S_R=1e4,
              S_Omega=1e4, attitude_kind=attitude_kind, integrator=integrator)
    kw.update(overrides)
    return satellite_problem(**kw)
