"""The optimal control problem (paper eq. optprob): a model, running and terminal costs, a
horizon and an initial state, for the satellite and any Pinocchio multibody alike.

    min_U  J = sum_{k<H} Lambda(x_k, u_k) + F(x_H)   s.t.  x_{k+1} = f(x_k, u_k), x_0 given.

The running cost is applied as written, without a dt factor (the paper's convention); to compare
with Crocoddyl, whose integrated action models multiply running costs by dt, divide its weights by dt.

The model is a backend chosen when it was built: :class:`geoddp.models.satellite.Satellite` (the
TSO(3) closed forms; states are rotation matrices R (3, 3) and body rates Omega (3,)) or
:class:`geoddp.models.multibody.Multibody` (any URDF; states are Pinocchio configurations q (nq,)
and velocities v (nv,)). Both answer the same questions (check_state, rollout,
rollout_closed_loop, expansion, description), so this one class serves both.
"""
from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from .contract import Linearisation, Trajectory
from .limits import as_limits, check_inside
from ..costs.tso3 import (
    AngularVelocityQuadratic,
    AttitudeChordal,
    AttitudeGeodesic,
    ControlQuadratic,
    CostDerivatives,
    CostSum,
)
from ..models.multibody import Multibody
from ..models.satellite import Satellite, satellite_model
from ..costs.multibody import (ControlRegularisation, FramePlacement, FrameRotation, FrameTranslation, MultibodyCostSum,
                              StateRegularisation)
from ..validate import InputError, choice, finite_array, keywords_checked, positive_int

ATTITUDE_KINDS = ("chordal", "geodesic")


# What the problem asks of its model (the backends Satellite and Multibody answer all of it)
MODEL_METHODS = ("check_state", "rollout", "rollout_closed_loop", "expansion", "description")
MODEL_SIZES = ("nx", "nu", "dt")
_WRAP = ("from geoddp.models.multibody import Multibody; model = Multibody.from_model({name}, dt=0.01) "
         "(dt in s; actuation: (nv, m), every degree of freedom by default)")


def check_model(model: Any) -> None:
    """InputError naming ``model`` unless it is a model backend (:class:`Satellite`,
    :class:`Multibody`, or an object with their methods and sizes), saying how to make one from
    what was given: a ``pin.Model`` (:meth:`Multibody.from_model`), a RobotWrapper, a URDF path."""
    import os

    import pinocchio as pin

    if isinstance(model, (Satellite, Multibody)):
        return
    want = "expected a geoddp model (geoddp.models.multibody.Multibody or geoddp.models.satellite.Satellite)"
    if isinstance(model, pin.Model):
        raise InputError("model", f"{want}, got a bare pinocchio.Model; wrap it (it is copied): "
                         + _WRAP.format(name="model"))
    if isinstance(getattr(model, "model", None), pin.Model):  # pinocchio.RobotWrapper, example_robot_data.load
        raise InputError("model", f"{want}, got a {type(model).__name__}; wrap its pinocchio.Model and visuals: "
                         + _WRAP.format(name="robot.model, robot.visual_model"))
    if isinstance(model, pin.Data):
        raise InputError("model", f"{want}, got a pinocchio.Data (a model's workspace); wrap the pinocchio.Model: "
                         + _WRAP.format(name="model"))
    if isinstance(model, (str, os.PathLike)):
        raise InputError("model", f"{want}, got the path {str(model)!r}; load the URDF: from geoddp.models.multibody "
                         "import Multibody; model = Multibody(path, root=\"fixed\", dt=0.01) (root: fixed | "
                         "free_flyer | spherical)")
    missing = [a for a in MODEL_METHODS if not callable(getattr(model, a, None))]
    missing += [a for a in MODEL_SIZES if not hasattr(model, a)]
    if missing:
        lacks = f" (it has no {', '.join(missing)})" if len(missing) < len(MODEL_METHODS + MODEL_SIZES) else ""
        raise InputError("model", f"{want}, got {type(model).__name__}{lacks}; from a pinocchio.Model: "
                         + _WRAP.format(name="model"))


@keywords_checked
@dataclass
class Problem:
    """min_U sum_k running(x_k, u_k) + terminal(x_H) s.t. the model's dynamics, x_0 = (q0, v0).

    Attributes:
        model: the model backend (:class:`Satellite` or :class:`Multibody`): dynamics, dt, integrator.
            A bare ``pin.Model`` is an InputError naming ``model`` that says how to wrap it:
            ``Multibody.from_model(model, dt=...)`` (:mod:`geoddp.models.multibody`).
        q0: initial configuration part: R0 (3, 3) on TSO(3), (nq,) for a multibody.
        v0: initial velocity part: Omega0 (3,) rad/s on TSO(3), (nv,) for a multibody.
        horizon: number of control steps H.
        running: running cost (applied at k = 0 .. H-1); terminal: terminal cost (at k = H).
        limits: control limits lower <= u_k <= upper: None (unconstrained), a
            :class:`geoddp.problem.limits.ControlLimits`, a (lower, upper) pair or {"lower", "upper"};
            each bound a scalar, (m,) or (H, m), -inf / inf for an unbounded side. Stored as a
            ControlLimits; :meth:`control_bounds` gives the (H, m) arrays.
    """

    model: Any
    q0: np.ndarray
    v0: np.ndarray
    horizon: int
    running: Any
    terminal: Any
    limits: Any = None

    def __post_init__(self) -> None:
        check_model(self.model)
        self.q0, self.v0 = self.model.check_state(self.q0, self.v0, "initial")
        self.horizon = positive_int(self.horizon, "horizon")
        for name, s in (("running", self.running), ("terminal", self.terminal)):
            nx = getattr(s, "nx", self.model.nx)
            if nx != self.model.nx:
                raise InputError(name, f"expected costs on the model's tangent space (nx = {self.model.nx}), got nx = {nx}")
        # terms a cost sum would only refuse at the first evaluation, named here by their place
        for i, t in enumerate(getattr(self.terminal, "terms", ())):
            if getattr(t, "uses_control", False):
                raise InputError(f"terminal.terms[{i}]", f"a control cost term ({type(t).__name__}) cannot be part of "
                                 "the terminal cost (there is no control at the final node)")
        for i, t in enumerate(getattr(self.running, "terms", ())):
            m = getattr(t, "m", None)
            if getattr(t, "uses_control", False) and isinstance(m, int) and m != self.model.nu:
                raise InputError(f"running.terms[{i}]", f"expected a control term on the model's {self.model.nu} "
                                 f"inputs, got one on {m} ({type(t).__name__})")
        self.limits = as_limits(self.limits)
        self._bounds = None if self.limits is None else self.limits.resolve(self.horizon, self.model.nu)

    def with_initial_state(self, q0: np.ndarray, v0: np.ndarray) -> "Problem":
        """The same problem from another initial state x_0 = (q0, v0): a new Problem sharing this
        one's model, costs, horizon and limits (nothing is rebuilt or re-validated but the state);
        this one is unchanged. What a receding-horizon controller (MPC) calls at every re-solve.

        Args:
            q0: R0 (3, 3), a rotation matrix (body to world), for a satellite (TSO(3)) problem; the
                configuration (nq,) for a multibody (unit quaternions, (x, y, z, w), and unit
                (cos, sin) pairs, to 1e-9: ``pin.normalize``).
            v0: Omega0 (3,), the body rate in rad/s; the velocity (nv,) for a multibody.

        Raises:
            InputError: naming ``q0`` (wrong shape, NaN or inf, not a rotation, a quaternion not
                of unit norm) or ``v0`` (wrong shape, NaN or inf).

        Example: ``solve(problem.with_initial_state(q, v), options, initial_controls=U_warm)``.
        """
        q0, v0 = self.model.check_state(q0, v0, ("q0", "v0"))
        new = copy.copy(self)  # the fields were validated when this problem was made
        new.q0, new.v0 = q0, v0
        return new

    def with_limits(self, limits: Any) -> "Problem":
        """The same problem (model, costs, horizon, initial state shared) with other control limits
        (any form the ``limits`` attribute takes; None removes them)."""
        return dataclasses.replace(self, limits=limits)

    def control_bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(lower, upper), each (H, m) float64 (-inf / inf where unbounded), or None without limits."""
        return self._bounds

    def quasi_static_controls(self) -> np.ndarray:
        """(H, m) controls that hold the initial configuration q0 at rest against gravity where
        the actuation can: the solver's default start (:func:`geoddp.solver.solve` without
        ``initial_controls``; ``initial_controls = "quasi_static"`` in a scene file).

        Every node gets u = argmin_u |H u - g(q0)| (least squares of smallest norm,
        :func:`geoddp.models.actuation.quasi_static_inputs`: g is the generalised gravity at
        (q0, v = 0), H the (nv, m) actuation; Crocoddyl's ``quasiStatic`` computes the same),
        clipped into the control limits if the problem has some. Zero where there is no gravity:
        the satellite, and any model built with ``gravity=False``. Read at each call (an MPC
        moves q0)."""
        H, m = self.horizon, self.nu
        if isinstance(self.model, Multibody):  # g(q0) = 0 without gravity: exact zeros
            from ..models.actuation import quasi_static_inputs

            U = np.tile(quasi_static_inputs(self.model.pin_model, self.model.actuation, self.q0), (H, 1))
        else:
            U = np.zeros((H, m))
        if self._bounds is not None:
            U = np.clip(U, *self._bounds)
        return U

    @property
    def nu(self) -> int:
        """Number of inputs m."""
        return self.model.nu

    @property
    def nx(self) -> int:
        """Dimension of the tangent state zeta: 6 on TSO(3), 2 nv for a multibody."""
        return self.model.nx

    @property
    def dt(self) -> float:
        """Time step in seconds."""
        return self.model.dt

    # satellite names of the initial state
    @property
    def R0(self) -> np.ndarray:
        """(3, 3) initial attitude of a TSO(3) problem (= q0)."""
        return self.q0

    @property
    def Omega0(self) -> np.ndarray:
        """(3,) initial body rate of a TSO(3) problem, rad/s (= v0)."""
        return self.v0

    # ------------------------------------------------------------ the solver's contract
    # (geoddp.problem.contract.OptimalControlProblem): thin adapters over the array methods below.
    def check_controls(self, controls: np.ndarray, name: str = "initial_controls") -> np.ndarray:
        """Validated (H, m) float64 copy of a control sequence (inside the limits, if any)."""
        U = finite_array(controls, name, (self.horizon, self.nu))
        if self._bounds is not None:
            check_inside(U, *self._bounds, name)
        return U

    def trajectory(self, controls: np.ndarray) -> Trajectory:
        """(H, m) controls -> Trajectory(q, v, u), the whole horizon in one call."""
        q, v = self.rollout(controls)
        return Trajectory(q, v, controls)

    def trajectory_cost(self, traj: Trajectory) -> float:
        """Total cost J of a trajectory (paper eq. J)."""
        return self.cost(traj.q, traj.v, traj.u)

    def _trusted(self) -> dict:
        """checked=True for a :class:`Multibody` model: the solver's trajectories and gains are
        this problem's own arrays, which its input checks would only copy again (7 % of a UR5
        linearisation). Other models take no such argument (the satellite's kernels check
        nothing; a user's model keeps the signature of the contract)."""
        return {"checked": True} if isinstance(self.model, Multibody) else {}

    def linearise(self, traj: Trajectory, order: int) -> Linearisation:
        """Dynamics expansion (by the model's backend) and cost derivatives along ``traj``, one
        of this problem's own trajectories (:meth:`trajectory`, :meth:`rollout_policy`): a
        Multibody model takes it without its Python input checks (:meth:`_trusted`)."""
        trusted = self._trusted()
        if order == 2 and getattr(self.model, "contracts_second_order", False):
            # factored second order, contracted with V_x' in the backward pass (compiled multibody)
            exp = self.model.expansion(traj.q, traj.v, traj.u, order=2, contracted=True, **trusted)
        else:
            exp = self.model.expansion(traj.q, traj.v, traj.u, order=order, **trusted)
        # Order 1 is a Gauss-Newton model where the costs offer one (multibody residual terms):
        # the exact Hessian's residual-curvature part, sum_i (W r)_i Hess r_i, is indefinite far
        # from a target and made the first iterations regularise heavily (UR5 pose reach: 32
        # restarts to lambda = 4.4 and 11 iterations; Gauss-Newton: lambda 0 and 6, as FDDP).
        # Order 2 stays exact: the Newton steps and the final check need the true Hessian.
        # (flagged only when every cost offers it: a user's own cost sum keeps its Hessians)
        run, term = self.cost_derivatives(traj.q, traj.v, traj.u, gauss_newton=order == 1)
        gn = order == 1 and all(_offers_gauss_newton(c) for c in (self.running, self.terminal))
        return Linearisation.from_parts(order, exp, run, term, gauss_newton=gn)

    def rollout_policy(self, traj: Trajectory, k: np.ndarray, K: np.ndarray, step: float) -> Trajectory | None:
        """:meth:`rollout_closed_loop` around ``traj`` into new arrays; None if non-finite."""
        # fresh C-contiguous outputs (empty_like would copy a nominal's layout, e.g. a transposed guess)
        q, v, u = np.empty(traj.q.shape), np.empty(traj.v.shape), np.empty(traj.u.shape)
        if not self.rollout_closed_loop(traj.q, traj.v, traj.u, k, K, step, q, v, u, trusted=True):
            return None
        return Trajectory(q, v, u)

    def describe(self) -> dict:
        """Model description for the Result: the model's :meth:`description` (kind, dt,
        integrator, and what rebuilds it: inertia/actuation/urdf on TSO(3); urdf, urdf_xml, root,
        nq, nv for a multibody) and the terminal cost's targets: ``target_rotation`` (3, 3) (an
        attitude term's R_d or a frame placement's or rotation's target; identity without one),
        ``target_angular_velocity`` (3,) (zero without a rate term) and, when the terminal cost has
        frame placement or translation terms, ``frame_targets``: their final references as
        ``{"frame", "placement" (4, 4)}`` or ``{"frame", "position" (3,)}`` (metres), which the
        replay draws as triads."""
        R_d, Omega_d = np.eye(3), np.zeros(3)
        targets = []  # what the replay draws as frame-target triads (geoddp.viz.model.frame_targets)
        for t in getattr(self.terminal, "terms", []):
            if isinstance(t, FramePlacement):
                R_d = t.M_ref[-1, :3, :3].copy()  # (K, 4, 4) references; the last is the final node's
                targets.append({"frame": t.frame_name, "placement": np.asarray(t.M_ref[-1], dtype=float).tolist()})
            elif isinstance(t, FrameRotation):
                R_d = t.R_ref[-1].copy()
            elif isinstance(t, FrameTranslation):
                targets.append({"frame": t.frame_name, "position": np.asarray(t.p_ref[-1], dtype=float).tolist()})
            R_d = getattr(t, "R_d", R_d)
            Omega_d = getattr(t, "Omega_d", Omega_d)
        out = {**self.model.description(), "target_rotation": np.array(R_d, dtype=float),
               "target_angular_velocity": np.array(Omega_d, dtype=float)}
        if targets:
            out["frame_targets"] = targets
        return out

    # ------------------------------------------------------------ arrays over the horizon
    def rollout(self, controls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(H, m) controls -> states q (H+1, ...), v (H+1, nv) from the initial state."""
        return self.model.rollout(self.q0, self.v0, controls)

    def rollout_closed_loop(
        self, q_bar: np.ndarray, v_bar: np.ndarray, u_bar: np.ndarray, k_ff: np.ndarray, K_fb: np.ndarray,
        gamma: float, q_out: np.ndarray, v_out: np.ndarray, u_out: np.ndarray, trusted: bool = False,
    ) -> bool:
        """Forward pass of Algorithm 1: u_k = u_bar_k - gamma k_k - K_k zeta_k (eq. dustar) with
        zeta_k = difference(x_bar_k, x_k), from the initial state; gains k_ff (H, m), K_fb
        (H, m, nx); results into q_out, v_out, u_out. Returns False if the state became non-finite.

        With limits, u_k is clamped into [lower_k, upper_k] after the feedback law (the feasible
        forward pass): every control applied and stored lies in the box.
        ``trusted=True``: the arrays are the solver's own (float64, C-contiguous, these shapes;
        :meth:`rollout_policy`), so a Multibody model skips its Python checks (:meth:`_trusted`)."""
        kw = self._trusted() if trusted else {}
        if self._bounds is None:
            return self.model.rollout_closed_loop(self.q0, self.v0, q_bar, v_bar, u_bar, k_ff, K_fb, gamma,
                                                  q_out, v_out, u_out, **kw)
        return self.model.rollout_closed_loop(self.q0, self.v0, q_bar, v_bar, u_bar, k_ff, K_fb, gamma,
                                              q_out, v_out, u_out, lower=self._bounds[0], upper=self._bounds[1], **kw)

    def expansion(self, q: np.ndarray, v: np.ndarray, controls: np.ndarray, order: int):
        """The model's expansion along a trajectory (Phi, B; Theta, Gamma, Xi at order 2)."""
        return self.model.expansion(q, v, controls, order=order)

    def cost(self, q: np.ndarray, v: np.ndarray, controls: np.ndarray) -> float:
        """Total cost J of a trajectory (paper eq. J)."""
        H = self.horizon
        run = self.running.value(q[:H], v[:H], controls).sum()
        return float(run + self.terminal.value(q[H:], v[H:], None)[0])

    def total_cost(self, controls: np.ndarray) -> float:
        """J(U) by single shooting; controls (H, m) (any other shape is an InputError naming
        ``controls``: the rollout alone would take any number of steps)."""
        controls = finite_array(controls, "controls", (self.horizon, self.nu))
        q, v = self.rollout(controls)
        return self.cost(q, v, controls)

    def cost_derivatives(
        self, q: np.ndarray, v: np.ndarray, controls: np.ndarray, gauss_newton: bool = False
    ) -> tuple[CostDerivatives, CostDerivatives]:
        """Running derivatives at k < H and terminal derivatives at k = H (N = 1); with
        ``gauss_newton``, the Gauss-Newton Hessians of each cost that offers them (its
        ``first_order_gauss_newton`` is True); any other cost gives its own."""
        H = self.horizon

        def of(cost: Any, *nodes: Any) -> CostDerivatives:
            if gauss_newton and _offers_gauss_newton(cost):
                return cost.derivatives(*nodes, gauss_newton=True)
            return cost.derivatives(*nodes)

        return of(self.running, q[:H], v[:H], controls), of(self.terminal, q[H:], v[H:], None)


def _offers_gauss_newton(cost: Any) -> bool:
    """True for a cost sum whose derivatives() takes gauss_newton=True (MultibodyCostSum)."""
    return bool(getattr(cost, "first_order_gauss_newton", False))


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
    limits=None,
) -> Problem:
    """Build the paper's satellite problem (eqs. disceqs, optprobR, costR) from numbers.

    Weights accept a scalar, a vector (diagonal) or a matrix. Units: inertia kg m^2, dt s,
    angles rad, rates rad/s. ``limits``: control limits (see :class:`Problem`), e.g.
    ``(-5.0, 5.0)`` for |u_i| <= 5 N m. The model is the one-body satellite (built-in ``satellite.urdf`` or
    ``urdf``, spherical root, no gravity, this inertia) with the compiled TSO(3) backend.
    """
    actuation = np.eye(3) if actuation is None else actuation
    model = satellite_model(inertia=inertia, actuation=actuation, dt=dt, integrator=integrator,
                            second_order=second_order, urdf=urdf)
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
    R0 = np.eye(3) if R0 is None else R0
    Omega0 = np.zeros(3) if Omega0 is None else Omega0
    if isinstance(model, Satellite):
        return Problem(model, R0, Omega0, horizon, running, terminal, limits)
    return _on_general_model(model, R0, Omega0, horizon, running, terminal, limits)


def _on_general_model(model, R0, Omega0, horizon: int, running: CostSum, terminal: CostSum, limits=None) -> Problem:
    """The satellite's costs on its general one-body model (states (q, v) with q the root
    quaternion): control and rate terms as regularisations, attitude terms on the body frame."""
    import pinocchio as pin

    pm = model.pin_model
    body = next(f.name for f in pm.frames if f.parentJoint == 1 and f.type == pin.FrameType.BODY)

    def convert(t):
        if isinstance(t, ControlQuadratic):
            return ControlRegularisation(t.u_ref, t.S)
        if isinstance(t, AngularVelocityQuadratic):
            W = np.zeros((6, 6))
            W[3:, 3:] = t.S
            return StateRegularisation(pm, pin.neutral(pm), t.Omega_d, W)
        t.frame = body  # attitude terms: on the body frame (MultibodyCostSum converts them)
        return t

    q0 = pin.Quaternion(np.asarray(R0, dtype=float)).coeffs().copy()  # (x, y, z, w)
    return Problem(model, q0, Omega0, horizon, MultibodyCostSum([convert(t) for t in running.terms], model=pm),
                   MultibodyCostSum([convert(t) for t in terminal.terms], model=pm, terminal=True), limits)


def paper_problem(integrator: str = "euler", attitude_kind: str = "chordal", **overrides) -> Problem:
    """The paper's Table I: tf = 3 s, dt = 0.01 s, I = diag(10, 11.1, 13), H = I_3,
    R_d = Rot_x(30 deg) Rot_z(70 deg), S_u = 0.1 I, S_R = S_Omega = 1e4 I, zero initial state."""
    import pinocchio as pin

    R_d = pin.exp3(np.array([np.pi / 6, 0, 0])) @ pin.exp3(np.array([0, 0, np.radians(70.0)]))
    kw = dict(inertia=np.diag([10.0, 11.1, 13.0]), dt=0.01, horizon=300, R_d=R_d, S_u=0.1, S_R=1e4,
              S_Omega=1e4, attitude_kind=attitude_kind, integrator=integrator)
    kw.update(overrides)
    return satellite_problem(**kw)
