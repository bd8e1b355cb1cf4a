"""Legged robots on flat ground: a contact schedule over the nodes, Crocoddyl's gait costs, and the
problem the solver solves (:class:`ContactProblem`, the solver's contract of
:mod:`geoddp.problem.contract`).

A schedule is a list of nodes, each either a **contact node** (which feet are on the ground; the
others swing) or an **impulse node** (the feet that touch down; a node with no controls), plus a
terminal node. Costs per node are Crocoddyl's ``SimpleQuadrupedalGaitProblem``'s (its example
quadrupedal_gaits_fwddyn.py), weights included, and costed as Crocoddyl costs them: running costs
of contact nodes times dt, impulse and terminal nodes' costs as they are.

Contact node (weights): CoM tracking 1e6 (when the node has a CoM target), per support foot a
friction-cone quadratic barrier 10 (mu = 0.7, 4 facets, f_z >= 0), per swing foot a position
tracking 1e6, state regularisation 10 toward the default posture (weights (0, 0, 0, 500, 500,
500, 0.01 per joint, 10 x 6, 1 per joint velocity), squared), control regularisation 0.1, a
state-bounds quadratic barrier 1e3 (joint position and velocity limits). Impulse node: foot
tracking 1e7 of the feet that land, state regularisation 10 (weights 1 x 6, 10 per joint, 10 x nv).
Terminal node: the terms of its node that depend on the state alone (state regularisation and
bounds, CoM and foot tracking), undivided by dt (Crocoddyl's terminal ``calc(x)``).

Controls are (H, nu) at every node; at impulse nodes they act on nothing and stay zero (a unit
quadratic on them keeps the node's control Hessian invertible and costs exactly 0 there), so a
Result has ``controls`` (H, nu) with zero rows at impulse nodes.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from .. import kernels
from ..lie import NONCOMMUTATIVE
from ..lie import product as cfg
from ..models import integrators as integ
from ..models import contact_compiled
from ..models.contact import ContactDynamics, NodeEval, friction_cone
from ..validate import InputError, finite_array, nonnegative_int, threads_from_environment
from .contract import Linearisation, Trajectory

KINDS = ("contact", "impulse")
BACKENDS = ("compiled", "python")
# contact nodes per call of the Euler step's second-order expansion in linearise (one call per
# node costs as much as the rest of it; one call for the whole horizon makes arrays of tens of MB)
_EXPAND_BLOCK = 8


@dataclass
class Node:
    """One node of a contact schedule.

    Attributes:
        kind: "contact" (integrated contact dynamics, dt) or "impulse" (touch-down, no controls).
        feet: frame ids on the ground (contact) or touching down (impulse).
        com: (3,) CoM target, m, or None (contact nodes).
        swing: ((frame id, (3,) target position, m), ...): foot tracking terms.
    """

    kind: str
    feet: tuple[int, ...]
    com: np.ndarray | None = None
    swing: tuple[tuple[int, np.ndarray], ...] = ()

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InputError("kind", f"expected one of {KINDS}, got {self.kind!r}")
        self.feet = tuple(int(f) for f in self.feet)


@dataclass
class GaitCosts:
    """Weights of Crocoddyl's quadruped gait costs (see the module docstring)."""

    com: float = 1e6
    friction_cone: float = 1e1
    mu: float = 0.7
    foot: float = 1e6
    state: float = 1e1
    control: float = 1e-1
    bounds: float = 1e3
    impulse_foot: float = 1e7
    impulse_state: float = 1e1
    impulse_control: float = 1.0  # on the controls of an impulse node: they stay 0, so it costs 0


def _barrier(r: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(r beyond the bounds, 0 inside; the mask of active entries): Crocoddyl's quadratic barrier
    0.5 |excess|^2, its gradient excess and Gauss-Newton Hessian diag(active)."""
    # r - lb < 0 exactly where r < lb, r - ub > 0 exactly where r > ub (the other one adds 0)
    ex = np.minimum(r - lb, 0.0) + np.maximum(r - ub, 0.0)
    return ex, (ex != 0.0).astype(float)


class ContactProblem:
    """min over controls of the schedule's costs under contact and impulse dynamics from (q0, v0).

    Args:
        dynamics: :class:`geoddp.models.contact.ContactDynamics` (the robot, dt, Baumgarte gains).
        nodes: the H running nodes (:class:`Node`); terminal: the terminal node (its state terms).
        q0 (nq,), v0 (nv,): the initial state.
        x_ref: (q_ref (nq,), v_ref (nv,)) the default posture of the state regularisation.
        costs: :class:`GaitCosts`. describe: the model description a Result carries (multibody).
        backend: "compiled" (default): the rollouts, the trajectory cost and the first-order
            expansion run in the compiled core (:mod:`geoddp.models.contact_compiled`, the same
            arithmetic as the Python node models to round-off); "python": everything in the Python
            node models (the reference; the tests' oracle). The exact second order (the KKT system
            differentiated twice, the costs' curvature) is Python's either way, and so, unless
            ``compiled_second_order_inputs`` is set, are the node derivatives it starts from: the
            stopping tests of ``second`` and ``switch`` sit at round-off-sensitive borders (the
            compiled inputs, equal to 1e-12, end the trot's switch solve one iteration later and
            the walk's second one earlier, at the same J* to 1e-14) for a gain of a few percent.
            The attributes may be changed after construction.
        threads: worker threads of the compiled first-order expansion and node costs (node-parallel);
            0 = GEODDP_THREADS if set, else the core's default (min(2, cores)).

    The compiled kernel copies the schedule, targets, weights and (q0, v0) when first used: change
    them on a fresh problem (or set ``backend`` to "python").
    """

    def __init__(self, dynamics: ContactDynamics, nodes: list[Node], terminal: Node, q0: np.ndarray,
                 v0: np.ndarray, x_ref: tuple[np.ndarray, np.ndarray], costs: GaitCosts | None = None,
                 description: dict | None = None, backend: str = "compiled", threads: int = 0) -> None:
        if not nodes:
            raise InputError("nodes", "expected at least one node")
        self.dyn = dynamics
        m = dynamics.model
        self.model = m
        self.nodes, self.terminal_node = list(nodes), terminal
        self.q0 = finite_array(q0, "q0", (m.nq,))
        self.v0 = finite_array(v0, "v0", (m.nv,))
        if not pin.isNormalized(m, self.q0, 1e-9):
            raise InputError("q0", "expected a unit quaternion in the free-flyer configuration")
        self.q_ref = finite_array(x_ref[0], "x_ref.q", (m.nq,))
        self.v_ref = finite_array(x_ref[1], "x_ref.v", (m.nv,))
        self.costs = costs or GaitCosts()
        nv = m.nv
        self.nx, self.nu, self.horizon, self.dt = 2 * nv, nv - 6, len(self.nodes), dynamics.dt
        self.impulse_rows = np.array([n.kind == "impulse" for n in self.nodes])
        nj = nv - 6
        self.w_state = np.array([0.0] * 3 + [500.0] * 3 + [0.01] * nj + [10.0] * 6 + [1.0] * nj) ** 2
        self.w_impulse = np.array([1.0] * 6 + [10.0] * nj + [10.0] * nv) ** 2
        # Crocoddyl's StateMultibody bounds, the residual difference(neutral, q) against q's limits
        # shifted by one (the free flyer has nq = 7, nv = 6) and the velocity limits
        lbq = np.concatenate([np.full(7, -np.inf), m.lowerPositionLimit[7:]])
        ubq = np.concatenate([np.full(7, np.inf), m.upperPositionLimit[7:]])
        self.lb = np.concatenate([lbq[1:nv + 1], -m.velocityLimit])
        self.ub = np.concatenate([ubq[1:nv + 1], m.velocityLimit])
        self.q_neutral = pin.neutral(m)
        self.groups = cfg.joint_groups(m)
        self.cone = friction_cone(self.costs.mu, 4)
        self._index = (np.arange(nv), np.arange(nv, 2 * nv), np.arange(2 * nv, 2 * nv + self.nu))
        if backend not in BACKENDS:
            raise InputError("backend", f"expected one of {BACKENDS}, got {backend!r}")
        self.backend = backend
        self.threads = nonnegative_int(threads, "threads") or threads_from_environment()
        self.compiled_second_order_inputs = False  # linearise(order=2): node derivatives from the kernel
        self._core = None  # the compiled kernel, built on first use
        self._last_costs = None  # (Q, V, U, node costs) of the last compiled rollout
        self._description = description or {"kind": "multibody", "root": "free_flyer", "nq": m.nq, "nv": nv,
                                            "dt": self.dt, "integrator": "semi_implicit"}

    # ------------------------------------------------------------ one node
    def _state_residual(self, q_ref, q, v, v_ref):
        d = pin.difference(self.model, q_ref, q)
        D = pin.dDifference(self.model, q_ref, q, pin.ArgumentPosition.ARG1)
        return np.concatenate([d, v - v_ref]), D

    def _cost(self, node: Node | None, q, v, u, ev, derivatives: bool, terminal: bool = False):
        """Cost of one node (dt-scaled for a contact node), its gradient in z = (dq, dv, du) and
        Gauss-Newton Hessian; ``ev``: the node's dynamics evaluation (forces, their Jacobian)."""
        m, d, c = self.model, self.dyn.data, self.costs
        nv, nu = m.nv, self.nu
        nz = 2 * nv + nu
        impulse = node is not None and node.kind == "impulse"
        val, g, Hs = 0.0, np.zeros(nz), np.zeros((nz, nz))
        Q, V, U = slice(0, nv), slice(nv, 2 * nv), slice(2 * nv, nz)
        qi, vi, ui = self._index  # the diagonal's indices of the q, v and u blocks

        # every term's Jacobian lives in one block of z's columns (q, v or u): the gradient and the
        # Gauss-Newton Hessian are added there, an identity Jacobian (None) on the diagonal
        def deriv(w, ar, a, Jr, cols, diag):  # weight, act * residual, act (or None: ones), Jacobian
            if Jr is None:
                g[cols] += w * ar
                Hs[diag, diag] += w if a is None else w * a
            else:
                g[cols] += w * (Jr.T @ ar)
                Hs[cols, cols] += w * (Jr.T @ Jr if a is None else Jr.T @ (a[:, None] * Jr))

        def add(w, r, Jr, cols, diag, act=None):  # weight, residual, its Jacobian (rows, cols) or None
            nonlocal val
            ar = r if act is None else act * r
            val += 0.5 * w * float(r @ ar)
            if derivatives:
                deriv(w, ar, act, Jr, cols, diag)

        def add_state(w, q_ref, v_ref, act):  # (difference(q_ref, q), v - v_ref) weighted by act
            nonlocal val
            rs, D = self._state_residual(q_ref, q, v, v_ref)
            ar = act * rs
            val += 0.5 * w * float(rs @ ar)
            if derivatives:
                deriv(w, ar[:nv], act[:nv], D, Q, qi)
                deriv(w, ar[nv:], act[nv:], None, V, vi)

        def foot_jacobian(f):
            return d.oMf[f].rotation @ pin.computeFrameJacobian(m, d, q, f, pin.LOCAL)[:3] if derivatives else None

        pin.forwardKinematics(m, d, q)
        pin.updateFramePlacements(m, d)
        if impulse:
            add_state(c.impulse_state, self.q_ref, self.v_ref, self.w_impulse)
            for f, p in node.swing:
                add(c.impulse_foot, d.oMf[f].translation - p, foot_jacobian(f), Q, qi)
            add(c.impulse_control, u, None, U, ui)
            return val, g, Hs
        add_state(c.state, self.q_ref, self.v_ref, self.w_state)
        rb, Db = self._state_residual(self.q_neutral, q, v, np.zeros(nv))
        ex, mask = _barrier(rb, self.lb, self.ub)
        val += 0.5 * c.bounds * float(ex @ ex)
        if derivatives:
            deriv(c.bounds, ex[:nv], mask[:nv], Db, Q, qi)
            deriv(c.bounds, ex[nv:], mask[nv:], None, V, vi)
        # CoM and swing-foot terms depend on x alone: the terminal node keeps them (Crocoddyl's calc(x))
        if node.com is not None:
            com = pin.centerOfMass(m, d, q)
            add(c.com, com - node.com, pin.jacobianCenterOfMass(m, d, q) if derivatives else None, Q, qi)
        for f, p in node.swing:
            add(c.foot, d.oMf[f].translation - p, foot_jacobian(f), Q, qi)
        if not terminal:
            add(c.control, u, None, U, ui)
            A, lb, ub = self.cone
            if node.feet:  # all feet's cone residuals at once: (feet, facets + 1)
                ex, mask = _barrier(ev.forces.reshape(-1, 3) @ A.T, lb, ub)
                for i in range(len(node.feet)):
                    val += 0.5 * c.friction_cone * float(ex[i] @ ex[i])
                    if derivatives and mask[i].any():
                        Jr = A @ ev.Lz[3 * i:3 * i + 3]
                        g[:] += c.friction_cone * (Jr.T @ ex[i])
                        Hs[:] += c.friction_cone * (Jr.T @ (mask[i, :, None] * Jr))
            val = val * self.dt
            g *= self.dt
            Hs *= self.dt
        return val, g, Hs

    def node(self, k: int, q: np.ndarray, v: np.ndarray, u: np.ndarray, derivatives: bool = False):
        """Node k at (q, v, u): (dynamics evaluation, cost, gradient, Gauss-Newton Hessian); k = H
        is the terminal node (no dynamics: None)."""
        if k == self.horizon:
            val, g, Hs = self._cost(self.terminal_node, q, v, np.zeros(self.nu), None, derivatives, terminal=True)
            return None, val, g, Hs
        node = self.nodes[k]
        if node.kind == "impulse":
            ev = self.dyn.impulse(q, v, node.feet, derivatives)
        else:
            ev = self.dyn.contact(q, v, u, node.feet, derivatives)
        val, g, Hs = self._cost(node, q, v, u, ev, derivatives)
        return ev, val, g, Hs

    # ------------------------------------------------------------ controls
    def check_controls(self, controls: np.ndarray, name: str = "initial_controls") -> np.ndarray:
        """Validated (H, nu) copy; the rows of impulse nodes are set to zero (they act on nothing)."""
        U = finite_array(controls, name, (self.horizon, self.nu)).copy()
        U[self.impulse_rows] = 0.0
        return U

    def quasi_static_controls(self) -> np.ndarray:
        """Crocoddyl's ``quasiStatic`` at q0 per contact node (zeros at impulse nodes): the
        example's start."""
        U = np.zeros((self.horizon, self.nu))
        for k, n in enumerate(self.nodes):
            if n.kind == "contact":
                U[k] = self.dyn.quasi_static(self.q0, n.feet)
        return U

    # ------------------------------------------------------------ the compiled backend
    def __getstate__(self) -> dict:
        """Pickled (a sweep's workers, deepcopy) without the compiled kernel: rebuilt on first use."""
        state = dict(self.__dict__)
        state["_core"], state["_last_costs"] = None, None
        return state

    @property
    def compiled(self) -> bool:
        """True when the rollouts, costs and first-order expansion run in the compiled core."""
        return self.backend == "compiled"

    def kernel(self):
        """The compiled twin of this problem (:func:`geoddp.models.contact_compiled.build_kernel`),
        built on first use."""
        if self._core is None:
            self._core = contact_compiled.build_kernel(self)
        return self._core

    def _remember(self, traj: Trajectory, costs: np.ndarray) -> None:
        """Keep the node costs a compiled rollout computed along ``traj`` (copies: compared by value)."""
        self._last_costs = (traj.q.copy(), traj.v.copy(), traj.u.copy(), costs)

    def _remembered(self, traj: Trajectory) -> np.ndarray | None:
        last = self._last_costs
        if last is None:
            return None
        Q, V, U, costs = last
        same = (traj.q.shape == Q.shape and traj.v.shape == V.shape and traj.u.shape == U.shape
                and np.array_equal(traj.q, Q) and np.array_equal(traj.v, V) and np.array_equal(traj.u, U))
        return costs if same else None

    # ------------------------------------------------------------ the solver's contract
    def trajectory(self, controls: np.ndarray) -> Trajectory:
        H = self.horizon
        U = np.array(controls, dtype=float)
        U[self.impulse_rows] = 0.0
        if self.compiled:
            Q, V, costs = self.kernel().rollout(np.ascontiguousarray(U))
            traj = Trajectory(Q, V, U)
            self._remember(traj, costs)
            return traj
        Q, V = np.empty((H + 1, self.model.nq)), np.empty((H + 1, self.model.nv))
        Q[0], V[0] = self.q0, self.v0
        for k in range(H):
            ev, *_ = self.node(k, Q[k], V[k], U[k])
            Q[k + 1], V[k + 1] = ev.q_next, ev.v_next
        return Trajectory(Q, V, U)

    def node_costs(self, traj: Trajectory) -> np.ndarray:
        """(H + 1,) cost of each node along ``traj`` (running nodes dt-scaled, as Crocoddyl's)."""
        if self.compiled:
            costs = self._remembered(traj)
            if costs is None:
                c64 = np.ascontiguousarray
                costs = self.kernel().costs(c64(traj.q, dtype=float), c64(traj.v, dtype=float),
                                            c64(traj.u, dtype=float), self.threads)
            return costs.copy()
        out = np.empty(self.horizon + 1)
        for k in range(self.horizon):
            out[k] = self.node(k, traj.q[k], traj.v[k], traj.u[k])[1]
        out[-1] = self.node(self.horizon, traj.q[-1], traj.v[-1], None)[1]
        return out

    def trajectory_cost(self, traj: Trajectory) -> float:
        if not (np.all(np.isfinite(traj.q)) and np.all(np.isfinite(traj.v))):
            return float("inf")
        return float(self.node_costs(traj).sum())

    def rollout_policy(self, traj: Trajectory, k: np.ndarray, K: np.ndarray, step: float) -> Trajectory | None:
        H, m = self.horizon, self.model
        if self.compiled:
            c64 = np.ascontiguousarray
            out = self.kernel().rollout_closed_loop(c64(traj.q, dtype=float), c64(traj.v, dtype=float),
                                                    c64(traj.u, dtype=float), c64(k, dtype=float),
                                                    c64(K, dtype=float), float(step))
            if out is None:
                return None
            Q, V, U, costs = out
            trial = Trajectory(Q, V, U)
            self._remember(trial, costs)
            return trial
        Q, V, U = np.empty_like(traj.q), np.empty_like(traj.v), np.zeros_like(traj.u)
        Q[0], V[0] = self.q0, self.v0
        for j in range(H):
            if not self.impulse_rows[j]:
                zeta = np.concatenate([pin.difference(m, traj.q[j], Q[j]), V[j] - traj.v[j]])
                U[j] = traj.u[j] - step * k[j] - K[j] @ zeta
            ev, *_ = self.node(j, Q[j], V[j], U[j])
            if not (np.all(np.isfinite(ev.q_next)) and np.all(np.isfinite(ev.v_next))):
                return None
            Q[j + 1], V[j + 1] = ev.q_next, ev.v_next
        return Trajectory(Q, V, U)

    def _node_map(self, k: int, traj: Trajectory, z: np.ndarray):
        """Jacobian G (nx, nz) of zeta+ = difference(x_bar+, f(x_bar (+) zeta, u_bar + du)) and the
        cost gradient (nz,) in z = (zeta, du) at z (the chart of the nominal, so that central
        differences of them are the node map's second derivatives)."""
        m, nv = self.model, self.model.nv
        q = pin.integrate(m, traj.q[k], z[:nv])
        v = traj.v[k] + z[nv:2 * nv]
        u = traj.u[k] + z[2 * nv:] if k < self.horizon else None
        ev, _, g, _ = self.node(k, q, v, u, derivatives=True)
        Rq = pin.dIntegrate(m, traj.q[k], z[:nv], pin.ArgumentPosition.ARG1)
        gz = g.copy()
        gz[:nv] = Rq.T @ g[:nv]
        if ev is None:
            return None, gz
        G = ev.Fz.copy()
        G[:, :nv] = G[:, :nv] @ Rq
        G[:nv] = pin.dDifference(m, traj.q[k + 1], ev.q_next, pin.ArgumentPosition.ARG1) @ G[:nv]
        return G, gz

    def _difference_curvature(self, q_ref: np.ndarray, q: np.ndarray, c: np.ndarray) -> np.ndarray:
        """sum_p c_p d^2 r_p (nv, nv), r(eta) = difference(q_ref, q exp(eta)), exactly: with
        r0 = r(0), K = Jr(r0)^-1 and exp(r0 + rho) = exp(r0) exp(Jr rho + 1/2 D(rho, rho)),
        r(eta) = r0 + K eta - 1/2 K D(K eta, K eta) + O(3) (zero on the commutative joints)."""
        nv = self.model.nv
        r0 = cfg.difference(self.model, self.groups, q_ref, q)
        out = np.zeros((nv, nv))
        for g in self.groups:  # D is zero on the commutative factors and across factors
            if g.kind in NONCOMMUTATIVE:
                s = g.slice
                K = NONCOMMUTATIVE[g.kind].right_jacobian_inv(r0[s])
                if g.kind == "se3":  # the compiled core's exact dJr (the Python one differences Jr)
                    D = kernels.core.se3_jr_derivative(np.ascontiguousarray(r0[s])).reshape(6, 6, 6)
                else:
                    D = cfg.group_second_order_tensors(g.kind, r0[None, s])[0][0]
                Ds = 0.5 * (D + D.transpose(0, 2, 1))
                out[s, s] = -K.T @ np.einsum("a,abc->bc", K.T @ c[s], Ds) @ K
        return out

    def _gravity_curvature(self, model: pin.Model, data: pin.Data, q: np.ndarray, force: np.ndarray) -> np.ndarray:
        """Chart Hessian (nv, nv) of a potential with generalised force J^T ``force``: the model's
        generalised gravity under the gravity -force (per unit mass) is that force, and the
        symmetrised derivative of the trivialised gradient is the chart Hessian."""
        g0 = model.gravity.copy()  # (a reference otherwise)
        model.gravity = pin.Motion(-np.asarray(force, dtype=float), np.zeros(3))
        try:
            dg = pin.computeGeneralizedGravityDerivatives(model, data, q)
        finally:
            model.gravity = g0
        return 0.5 * (dg + dg.T)

    def _cost_hessian(self, k: int, q, v, u, ev, L2, gauss_newton: np.ndarray | None = None) -> np.ndarray:
        """Exact Hessian (nz, nz) of node k's cost: the Gauss-Newton part of :meth:`_cost` plus
        each residual's curvature times its weighted residual: the state differences' (SE(3) log's
        second order), the CoM's and the feet's (generalised gravity derivatives of a model whose
        gravity is minus the residual: the CoM of the robot, a unit point mass at the foot) and the
        forces' (``L2``: their exact second derivatives). ``gauss_newton``: that Gauss-Newton part
        at the same point if already computed (it is added to, not copied), else None."""
        m, c, nv = self.model, self.costs, self.model.nv
        terminal = k == self.horizon
        node = self.terminal_node if terminal else self.nodes[k]
        d = self.dyn.data
        if gauss_newton is None:
            _, _, Hs = self._cost(node, q, v, u, ev, True, terminal=terminal)  # leaves the kinematics in dyn.data
        else:
            Hs = gauss_newton
            pin.forwardKinematics(m, d, q)
            pin.updateFramePlacements(m, d)
        curv = np.zeros((nv, nv))
        rq = pin.difference(m, self.q_ref, q)
        m0, d0 = self.dyn._aux_models()["zero_gravity"]

        def feet(weight):
            out = np.zeros((nv, nv))
            for f, p in node.swing:
                mf, df = self.dyn._foot_model(f)
                out += weight * self._gravity_curvature(mf, df, q, d.oMf[f].translation - p)
            return out

        if node.kind == "impulse":
            curv += c.impulse_state * self._difference_curvature(self.q_ref, q, self.w_impulse[:nv] * rq)
            curv += feet(c.impulse_foot)
            Hs[:nv, :nv] += curv
            return Hs
        curv += c.state * self._difference_curvature(self.q_ref, q, self.w_state[:nv] * rq)
        ex, _ = _barrier(np.concatenate([pin.difference(m, self.q_neutral, q), v]), self.lb, self.ub)
        if np.any(ex[:nv]):
            curv += c.bounds * self._difference_curvature(self.q_neutral, q, ex[:nv])
        if node.com is not None:
            r = pin.centerOfMass(m, d, q) - node.com
            curv += c.com * self._gravity_curvature(m0, d0, q, r / pin.computeTotalMass(m))
        curv += feet(c.foot)
        scale = 1.0 if terminal else self.dt
        Hs[:nv, :nv] += scale * curv
        if not terminal:
            A, lb, ub = self.cone
            nz = Hs.shape[0]
            for i in range(len(node.feet)):
                rows = slice(3 * i, 3 * i + 3)
                ex, mask = _barrier(A @ ev.forces[rows], lb, ub)
                if mask.any():  # inside the cone the barrier is flat
                    Hs += (c.friction_cone * self.dt) * ((ex @ A) @ L2[rows].reshape(3, -1)).reshape(nz, nz)
        return Hs

    def second_order_node(self, k: int, traj: Trajectory, ev=None):
        """(T (nx, nz, nz) second derivatives of zeta+ at node k, cost Hessian (nz, nz)), both
        exact. k = H: (None, terminal Hessian).

        T: the contact node's accelerations and the impulse node's velocity jump from
        :meth:`geoddp.models.contact.ContactDynamics.contact_second` / ``impulse_second`` (the KKT
        system differentiated twice), put through the semi-implicit Euler step's exact chart terms
        (:func:`geoddp.models.integrators.expand`); an impulse node's q+ = q has none. The cost
        Hessian: :meth:`_cost_hessian`. ``ev``: the node's dynamics already evaluated with
        derivatives at (traj.q[k], traj.v[k], traj.u[k]), or None."""
        nx, nu, nv, dt = self.nx, self.nu, self.model.nv, self.dt
        nz = nx + nu
        q, v = traj.q[k], traj.v[k]
        if k == self.horizon:
            return None, self._cost_hessian(k, q, v, np.zeros(nu), None, None)
        node = self.nodes[k]
        u = traj.u[k]
        T = np.zeros((nx, nz, nz))
        if node.kind == "impulse":
            ev = ev if ev is not None else self.dyn.impulse(q, v, node.feet, derivatives=True)
            T[nv:], L2 = self.dyn.impulse_second(q, v, node.feet, ev)
            return T, self._cost_hessian(k, q, v, u, ev, L2)
        ev = ev if ev is not None else self.dyn.contact(q, v, u, node.feet, derivatives=True)
        A2, L2 = self.dyn.contact_second(q, v, u, node.feet, ev)
        e = integ.expand(self.groups, dt, ev.v_next[None], ev.Fz[None, nv:], dt * A2[None], True)
        T[:, :nx, :nx], T[:, :nx, nx:], T[:, nx:, nx:] = e.Theta[0], e.Gamma[0], e.Xi[0]
        T[:, nx:, :nx] = e.Gamma[0].transpose(0, 2, 1)
        return T, self._cost_hessian(k, q, v, u, ev, L2)

    def _first_order_nodes(self, traj: Trajectory, compiled: bool):
        """Every node along ``traj`` with first derivatives: H + 1 (NodeEval or None at the terminal
        node, cost gradient (nz,), Gauss-Newton Hessian (nz, nz)), from the compiled kernel
        (node-parallel) or the Python node models."""
        H = self.horizon
        if not compiled:
            for k in range(H + 1):
                ev, _, g, Hs = self.node(k, traj.q[k], traj.v[k], traj.u[k] if k < H else None, derivatives=True)
                yield ev, g, Hs
            return
        c64 = np.ascontiguousarray
        out = self.kernel().evaluate(c64(traj.q, dtype=float), c64(traj.v, dtype=float), c64(traj.u, dtype=float),
                                     self.threads)
        for k, o in enumerate(out):
            ev = None if k == H else NodeEval(o["q_next"], o["v_next"], o["forces"], Fz=o["Fz"], Lz=o["Lz"],
                                              acc=o["acc"], Az=o["Az"])
            yield ev, o["g"], o["Hs"]

    def linearise(self, traj: Trajectory, order: int) -> Linearisation:
        H, nx, nu, nv = self.horizon, self.nx, self.nu, self.model.nv
        if order == 1 and self.compiled:
            c64 = np.ascontiguousarray
            Phi, B, lx, lu, lxx, lux, luu, gf, Hf, _ = self.kernel().linearise(
                c64(traj.q, dtype=float), c64(traj.v, dtype=float), c64(traj.u, dtype=float), self.threads)
            return Linearisation(order=1, Phi=Phi, B=B, Theta=None, Gamma=None, Xi=None, l_x=lx, l_u=lu, l_xx=lxx,
                                 l_ux=lux, l_uu=luu, lf_x=gf, lf_xx=Hf, gauss_newton=True)
        Phi, B = np.empty((H, nx, nx)), np.empty((H, nx, nu))
        evs = []
        lx, lu = np.empty((H, nx)), np.empty((H, nu))
        lxx, lux, luu = np.empty((H, nx, nx)), np.empty((H, nu, nx)), np.empty((H, nu, nu))
        hess = []
        nodes = self._first_order_nodes(traj, self.compiled and self.compiled_second_order_inputs)
        for k, (ev, g, Hs) in enumerate(nodes):
            if k == H:
                gf, Hf = g, Hs
                break
            evs.append(ev)
            hess.append(Hs)
            Phi[k], B[k] = ev.Fz[:, :nx], ev.Fz[:, nx:]
            lx[k], lu[k] = g[:nx], g[nx:]
            lxx[k], lux[k], luu[k] = Hs[:nx, :nx], Hs[nx:, :nx], Hs[nx:, nx:]
        Theta = Gamma = Xi = None
        if order == 2:
            Theta, Gamma, Xi = np.zeros((H, nx, nx, nx)), np.zeros((H, nx, nx, nu)), np.zeros((H, nx, nu, nu))
            contact = []  # (k, dt a'') of the contact nodes, put through the Euler step in blocks
            for k in range(H):
                node, q, v, u, ev = self.nodes[k], traj.q[k], traj.v[k], traj.u[k], evs[k]
                if node.kind == "impulse":
                    Y2, L2 = self.dyn.impulse_second(q, v, node.feet, ev)
                    Theta[k, nv:], Gamma[k, nv:], Xi[k, nv:] = Y2[:, :nx, :nx], Y2[:, :nx, nx:], Y2[:, nx:, nx:]
                else:
                    A2, L2 = self.dyn.contact_second(q, v, u, node.feet, ev)
                    A2 *= self.dt
                    contact.append((k, A2))
                Hc = self._cost_hessian(k, q, v, u, ev, L2, gauss_newton=hess[k])
                lxx[k], lux[k], luu[k] = Hc[:nx, :nx], Hc[nx:, :nx], Hc[nx:, nx:]
            for b in range(0, len(contact), _EXPAND_BLOCK):
                ks = [k for k, _ in contact[b:b + _EXPAND_BLOCK]]
                e = integ.expand(self.groups, self.dt, np.array([evs[k].v_next for k in ks]),
                                 np.array([evs[k].Fz[nv:] for k in ks]),
                                 np.array([A2 for _, A2 in contact[b:b + _EXPAND_BLOCK]]), True)
                Theta[ks], Gamma[ks], Xi[ks] = e.Theta, e.Gamma, e.Xi
            Hf = self.second_order_node(H, traj)[1]
        return Linearisation(order=order, Phi=Phi, B=B, Theta=Theta, Gamma=Gamma, Xi=Xi, l_x=lx, l_u=lu, l_xx=lxx,
                             l_ux=lux, l_uu=luu, lf_x=gf[:nx], lf_xx=Hf[:nx, :nx], gauss_newton=order == 1)

    def describe(self) -> dict[str, Any]:
        return {**self._description, "target_rotation": np.eye(3), "target_angular_velocity": np.zeros(3)}


# ------------------------------------------------------------------ Crocoddyl's quadruped gaits
@dataclass
class QuadrupedGait:
    """The schedules of Crocoddyl's ``SimpleQuadrupedalGaitProblem`` (crocoddyl.utils.quadruped),
    node for node, for a fresh instance (its first half step): :meth:`walk`, :meth:`trot`.

    Attributes:
        model: the robot (``pin.Model`` with a free-flyer root and a "standing" reference configuration
            unless ``q_default`` is given); feet: the frame names (LF, RF, LH, RH).
    """

    model: pin.Model
    feet: tuple[str, str, str, str]
    q_default: np.ndarray | None = None
    ids: tuple[int, ...] = field(init=False)

    def __post_init__(self) -> None:
        missing = [f for f in self.feet if not self.model.existFrame(f)]
        if missing:
            raise InputError("feet", f"frames {missing} are not in the model")
        self.ids = tuple(int(self.model.getFrameId(f)) for f in self.feet)
        if self.q_default is None:
            if "standing" not in self.model.referenceConfigurations:
                raise InputError("q_default", "the model has no 'standing' reference configuration; give q_default")
            self.q_default = self.model.referenceConfigurations["standing"].copy()

    def _start(self, q0):
        m = self.model
        d = m.createData()
        pin.forwardKinematics(m, d, q0)
        pin.updateFramePlacements(m, d)
        pos = [d.oMf[i].translation.copy() for i in self.ids]
        com = sum(pos) / 4
        com[2] = pin.centerOfMass(m, d, q0)[2]
        return pos, com

    @staticmethod
    def _footstep(com0, feet_pos, length, height, knots, support, swing):
        nodes = []
        pct = len(swing) / (len(support) + len(swing))
        ph = knots / 2
        tasks = ()
        for k in range(knots):
            tasks = []
            for i, p in zip(swing, feet_pos):
                if k < ph:
                    dp = np.array([length * (k + 1) / knots, 0.0, height * k / ph])
                elif k == ph:
                    dp = np.array([length * (k + 1) / knots, 0.0, height])
                else:
                    dp = np.array([length * (k + 1) / knots, 0.0, height * (1 - float(k - ph) / ph)])
                tasks.append((i, p + dp))
            com = np.array([length * (k + 1) / knots, 0.0, 0.0]) * pct + com0
            nodes.append(Node("contact", tuple(support), com=com, swing=tuple(tasks)))
        nodes.append(Node("impulse", tuple(swing), swing=tuple(tasks)))
        com0 += [length * pct, 0.0, 0.0]
        for p in feet_pos:
            p += [length, 0.0, 0.0]
        return nodes

    def walk(self, q0, length: float, height: float, knots: int, support_knots: int) -> tuple[list[Node], Node]:
        """Crocoddyl's createWalkingProblem (first call): RH, RF half steps, then LH, LF steps."""
        lf, rf, lh, rh = self.ids
        (plf, prf, plh, prh), com = self._start(q0)
        ds = [Node("contact", (lf, rf, lh, rh)) for _ in range(support_knots)]
        nodes = list(ds)
        nodes += self._footstep(com, [prh], 0.5 * length, height, knots, [lf, rf, lh], [rh])
        nodes += self._footstep(com, [prf], 0.5 * length, height, knots, [lf, lh, rh], [rf])
        lh_step = self._footstep(com, [plh], length, height, knots, [lf, rf, rh], [lh])
        lf_step = self._footstep(com, [plf], length, height, knots, [rf, lh, rh], [lf])
        nodes += ds + lh_step + lf_step
        return nodes, ds[0]

    def trot(self, q0, length: float, height: float, knots: int, support_knots: int) -> tuple[list[Node], Node]:
        """Crocoddyl's createTrottingProblem (first call): RF+LH half step, then LF+RH step."""
        lf, rf, lh, rh = self.ids
        (plf, prf, plh, prh), com = self._start(q0)
        ds = [Node("contact", (lf, rf, lh, rh)) for _ in range(support_knots)]
        nodes = list(ds)
        nodes += self._footstep(com, [prf, plh], 0.5 * length, height, knots, [lf, rh], [rf, lh])
        nodes += ds + self._footstep(com, [plf, prh], length, height, knots, [rf, lh], [lf, rh])
        return nodes, ds[0]

    def jump(self, q0, height: float, length, ground_knots: int, flying_knots: int) -> tuple[list[Node], Node]:
        """Crocoddyl's createJumpingProblem: ``ground_knots`` on four feet, ``flying_knots`` rising
        to the CoM apex (half of ``length`` (3,) m plus ``height`` m up), ``flying_knots`` falling,
        the landing impulse with the feet at their start plus ``length``, then ``ground_knots`` on
        four feet (the last one terminal) with the CoM target moved by ``length`` (its z: the
        height change of the feet)."""
        lf, rf, lh, rh = self.ids
        feet = (lf, rf, lh, rh)
        (plf, prf, plh, prh), _ = self._start(q0)
        length = np.asarray(length, dtype=float).copy()
        df = length[2] - prf[2]
        for p in (plf, prf, plh, prh):
            p[2] = 0.0
        m = self.model
        d = m.createData()
        com = (prf + prh + plf + plh) / 4
        com[2] = pin.centerOfMass(m, d, q0)[2]
        nodes = [Node("contact", feet) for _ in range(ground_knots)]
        apex = np.array([length[0] / 2.0, length[1] / 2.0, length[2] / 2.0 + height])
        nodes += [Node("contact", (), com=apex * (k + 1) / flying_knots + com) for k in range(flying_knots)]
        nodes += [Node("contact", ()) for _ in range(flying_knots)]
        nodes.append(Node("impulse", feet, swing=tuple((f, p + length) for f, p in zip(feet, (plf, prf, plh, prh)))))
        landed_com = com + np.array([length[0], length[1], df])
        landed = [Node("contact", feet, com=landed_com) for _ in range(ground_knots)]
        return nodes + landed[:-1], landed[-1]
