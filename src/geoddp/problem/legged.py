"""Legged robots on flat ground: a contact schedule over the nodes, Crocoddyl's gait costs, and the
problem the solver solves (:class:`ContactProblem`, the solver's contract of
:mod:`geoddp.problem.contract`).

A schedule is a list of nodes, each either a **contact node** (which feet are on the ground; the
others swing) or an **impulse node** (the feet that touch down; a node with no controls), plus a
terminal node. Costs per node are those of Crocoddyl's gait examples, weights included, and costed
as Crocoddyl costs them: running costs of contact nodes times dt, impulse and terminal nodes' costs
as they are. A foot's contact kind (:class:`geoddp.models.contact.ContactDynamics`) picks its
terms, as Crocoddyl's two examples do: a point foot ("3d", ``SimpleQuadrupedalGaitProblem``,
quadrupedal_gaits_fwddyn.py) has its position tracked and its force in a friction cone; a flat
foot ("6d", ``SimpleBipedGaitProblem``, bipedal_gaits_fwddyn.py) has its placement tracked and its
wrench in a wrench cone (:func:`geoddp.models.contact.wrench_cone`).

Contact node (weights: :class:`GaitCosts`, the quadruped's; :meth:`GaitCosts.biped` the biped's):
CoM tracking 1e6 (when the node has a CoM target); per support foot a cone quadratic barrier 10
(mu = 0.7, 4 facets; the friction cone of the force, f_z >= 0; for a flat foot the wrench cone of a
0.1 x 0.05 m sole: also the centre of pressure inside the sole and the yaw torque bounded); per
swing foot a tracking term 1e6 (point foot: its position; flat foot: log6(M_ref^-1 oMf), M_ref the
target position with the identity rotation); state regularisation 10 toward the default posture
(weights (0, 0, 0, 500, 500, 500, 0.01 per joint, 10 x 6, 1 per joint velocity (10 for the biped)),
squared); control regularisation 0.1; a state-bounds quadratic barrier 1e3 (joint position and
velocity limits; none for the biped). Impulse node: tracking 1e7 (biped 1e8) of the feet that
land, state regularisation 10 (weights 1 x 6, 10 per joint (biped 0.1), 10 x nv). Terminal node:
the terms of its node that depend on the state alone (state regularisation and bounds, CoM and foot
tracking), undivided by dt (Crocoddyl's terminal ``calc(x)``); it may be an impulse node (the
biped's walk ends on its last landing).

Two terms beyond Crocoddyl's gaits, weight 0 by default (so the gaits above are unchanged bit for
bit): a **base placement target** (:attr:`GaitCosts.base_placement`; Crocoddyl's
``ResidualModelFramePlacement`` on the free flyer's frame), log6(M_ref^-1 oMb) (6,) toward the
node's :attr:`Node.base`, at contact nodes and a contact terminal node that have one; and
**contact-force regularisation** (:attr:`GaitCosts.force_regularisation`; Crocoddyl's
``ResidualModelContactForce`` / ``ResidualModelContactWrench``), per support foot of a contact
node the world force minus a reference (3,) N, or a flat foot's wrench (force, torque) minus
(reference, 0) (6,): the quasi-static share of the weight m |g| / n_support along the ground's
normal (+z), or zero (:attr:`GaitCosts.force_reference`). Impulse nodes carry neither (their
forces are impulses, N s). A problem with either weight nonzero runs the Python node models
(:attr:`ContactProblem.compiled`): the compiled kernel has neither term.

Controls are (H, nu) at every node; at impulse nodes they act on nothing and stay zero (a unit
quadratic on them keeps the node's control Hessian invertible and costs exactly 0 there), so a
Result has ``controls`` (H, nu) with zero rows at impulse nodes.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from .. import kernels
from ..lie import NONCOMMUTATIVE
from ..lie import product as cfg
from ..models import integrators as integ
from ..models import contact_compiled
from ..models.contact import ContactDynamics, NodeEval, friction_cone, wrench_cone
from ..validate import InputError, finite_array, nonnegative_int, threads_from_environment
from .contract import Linearisation, Trajectory

KINDS = ("contact", "impulse")
BACKENDS = ("compiled", "python")
FORCE_REFERENCES = ("weight_share", "zero")  # GaitCosts.force_reference
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
        base: the base's target placement in the world (``pin.SE3``: translation m, rotation), or
            None; costed by :attr:`GaitCosts.base_placement` at a contact node (and a contact
            terminal node), not at an impulse node.
    """

    kind: str
    feet: tuple[int, ...]
    com: np.ndarray | None = None
    swing: tuple[tuple[int, np.ndarray], ...] = ()
    base: pin.SE3 | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InputError("kind", f"expected one of {KINDS}, got {self.kind!r}")
        self.feet = tuple(int(f) for f in self.feet)
        if self.base is not None and not isinstance(self.base, pin.SE3):
            raise InputError("base", "expected a pinocchio.SE3 target placement or None, got "
                             f"{type(self.base).__name__}")


@dataclass
class GaitCosts:
    """Weights of Crocoddyl's gait costs (see the module docstring): its quadruped's by default,
    its biped's from :meth:`biped`.

    ``friction_cone`` weighs each support foot's cone barrier (a point foot's friction cone, a flat
    foot's wrench cone over a ``sole`` of (length, width) m). ``state_weights`` and
    ``impulse_state_weights``: the state regularisation's weights, squared, per (base position,
    base orientation, joint, base velocity, joint velocity) entry (each entry of the tangent
    state (dq, dv) gets its group's).

    Beyond Crocoddyl's gaits (0 = off, the default): ``base_placement`` weighs the base placement
    term 0.5 |log6(M_ref^-1 oMb)|^2 toward each contact node's :attr:`Node.base` (translation in m,
    rotation in rad); ``force_regularisation`` weighs 0.5 |f - f_ref|^2 (N^2) per support foot of a
    contact node, f its world force (3,) or a flat foot's wrench (6,), f_ref per
    ``force_reference``: "weight_share" (m |g| / n_support along +z, zero torque) or "zero". Both
    are running costs, times dt like the others."""

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
    sole: tuple[float, float] = (0.1, 0.05)
    state_weights: tuple[float, float, float, float, float] = (0.0, 500.0, 0.01, 10.0, 1.0)
    impulse_state_weights: tuple[float, float, float, float, float] = (1.0, 1.0, 10.0, 10.0, 10.0)
    base_placement: float = 0.0
    force_regularisation: float = 0.0
    force_reference: str = "weight_share"

    def __post_init__(self) -> None:
        if self.force_reference not in FORCE_REFERENCES:
            raise InputError("force_reference", f"expected one of {FORCE_REFERENCES}, got {self.force_reference!r}")
        for name in ("base_placement", "force_regularisation"):
            w = getattr(self, name)
            if not (isinstance(w, (int, float, np.floating, np.integer)) and np.isfinite(w) and w >= 0):
                raise InputError(name, f"expected a finite weight >= 0, got {w!r}")

    @classmethod
    def biped(cls, **overrides: float) -> "GaitCosts":
        """Crocoddyl's ``SimpleBipedGaitProblem`` weights: no state bounds, landing feet 1e8, joint
        velocities 10, impulse joints 0.1 (``overrides``: fields to change)."""
        return cls(**{"bounds": 0.0, "impulse_foot": 1e8, "state_weights": (0.0, 500.0, 0.01, 10.0, 10.0),
                      "impulse_state_weights": (1.0, 1.0, 0.1, 10.0, 10.0), **overrides})


def state_weight_vector(weights: tuple[float, ...], nv: int) -> np.ndarray:
    """(2 nv,) the squared per-entry weights of a free-flyer robot's tangent state (dq, dv) from the
    five group weights of :class:`GaitCosts` (base position, base orientation, joint, base
    velocity, joint velocity)."""
    wp, wo, wj, wb, wv = (float(w) for w in weights)
    nj = nv - 6
    return np.array([wp] * 3 + [wo] * 3 + [wj] * nj + [wb] * 6 + [wv] * nj) ** 2


def _placement(target: np.ndarray | pin.SE3) -> pin.SE3:
    """A tracking target as a placement: a position (3,), m (a flat foot's target, the identity
    rotation) or a ``pin.SE3`` as it is."""
    if isinstance(target, pin.SE3):
        return target
    return pin.SE3(np.eye(3), np.asarray(target, dtype=float))


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
            node models (the reference; the tests' oracle). With "compiled" the exact second-order
            expansion (``linearise(traj, 2)``: the KKT system differentiated twice, the
            semi-implicit Euler step's chart terms, the costs' curvature) runs in the kernel too,
            node-parallel, unless ``compiled_second_order`` is set False (then it is Python's, from
            the Python node models). The two agree to round-off (1e-10 relative); the stopping
            tests of ``second`` and ``switch`` sit at round-off-sensitive borders, so an iteration
            count can differ by one between them at the same J* to 1e-12.
            The attributes may be changed after construction. A problem with flat feet (6D
            contacts), with the terms of force constraints, or with a nonzero
            ``costs.base_placement`` or ``costs.force_regularisation`` weight (terms the compiled
            kernel does not have) runs in Python (:attr:`compiled`).
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
        # augmented Lagrangian terms of hard constraints on the contact forces, per node k
        # (:meth:`with_force_terms`; none in a problem built here)
        self._force_at: dict[int, list] = {}
        nv = m.nv
        self.nx, self.nu, self.horizon, self.dt = 2 * nv, nv - 6, len(self.nodes), dynamics.dt
        self.impulse_rows = np.array([n.kind == "impulse" for n in self.nodes])
        self.w_state = state_weight_vector(self.costs.state_weights, nv)
        self.w_impulse = state_weight_vector(self.costs.impulse_state_weights, nv)
        flat = [f for f in dynamics.contact_kinds if any(f in n.feet for n in [*self.nodes, terminal])]
        self.flat_feet = tuple(f for f in flat if dynamics.kind(f) != "3d")  # the compiled kernel: point feet only
        if any(dynamics.kind(f) == "6d_local" for f in flat):
            raise InputError("dynamics.contact_kinds", "the gait costs take flat feet in world-aligned axes ('6d'), "
                             "not '6d_local'")
        # Crocoddyl's StateMultibody bounds, the residual difference(neutral, q) against q's limits
        # shifted by one (the free flyer has nq = 7, nv = 6) and the velocity limits
        lbq = np.concatenate([np.full(7, -np.inf), m.lowerPositionLimit[7:]])
        ubq = np.concatenate([np.full(7, np.inf), m.upperPositionLimit[7:]])
        self.lb = np.concatenate([lbq[1:nv + 1], -m.velocityLimit])
        self.ub = np.concatenate([ubq[1:nv + 1], m.velocityLimit])
        self.q_neutral = pin.neutral(m)
        # the free flyer's own frame (Pinocchio names it after the root joint): its placement is
        # oMi[1] and its LOCAL Jacobian [I_6 0], so the base placement term is that of any frame
        self.base_frame = int(m.getFrameId(m.names[1], pin.FrameType.JOINT))
        # m |g|, N: the weight the support feet share in the "weight_share" force reference
        self.robot_weight = float(pin.computeTotalMass(m)) * float(np.linalg.norm(m.gravity.linear))
        self.groups = cfg.joint_groups(m)
        self.cone = friction_cone(self.costs.mu, 4)  # a point foot's (A, lb, ub) over its force (3,)
        self.wrench = wrench_cone(self.costs.mu, self.costs.sole, 4)  # a flat foot's over (force, torque) (6,)
        self._index = (np.arange(nv), np.arange(nv, 2 * nv), np.arange(2 * nv, 2 * nv + self.nu))
        if backend not in BACKENDS:
            raise InputError("backend", f"expected one of {BACKENDS}, got {backend!r}")
        self.backend = backend
        self.threads = nonnegative_int(threads, "threads") or threads_from_environment()
        self.compiled_second_order = True  # linearise(order=2) in the kernel when compiled
        self._core = None  # the compiled kernel, built on first use
        self._last_costs = None  # (Q, V, U, node costs) of the last compiled rollout
        self._description = description or {"kind": "multibody", "root": "free_flyer", "nq": m.nq, "nv": nv,
                                            "dt": self.dt, "integrator": "semi_implicit"}

    # ------------------------------------------------------------ one node
    def _state_residual(self, q_ref, q, v, v_ref):
        d = pin.difference(self.model, q_ref, q)
        D = pin.dDifference(self.model, q_ref, q, pin.ArgumentPosition.ARG1)
        return np.concatenate([d, v - v_ref]), D

    def _foot_residual(self, f: int, p: np.ndarray, q: np.ndarray, derivatives: bool):
        """Swing-foot tracking residual of frame ``f`` toward the target position ``p`` (3,), m,
        and its Jacobian in dq (None unless ``derivatives``); the frame placements of dyn.data
        current. A point foot: oMf.translation - p (3,), Jacobian R J_lin; a flat foot (Crocoddyl's
        ``ResidualModelFramePlacement``): log6(M_ref^-1 oMf) (6,), M_ref = (I, p), Jacobian
        Jlog6 J (J the LOCAL frame Jacobian)."""
        m, d = self.model, self.dyn.data
        if self.dyn.kind(f) == "3d":
            r = d.oMf[f].translation - p
            return r, (d.oMf[f].rotation @ pin.computeFrameJacobian(m, d, q, f, pin.LOCAL)[:3] if derivatives else None)
        return self._placement_residual(f, _placement(p), q, derivatives)

    def _placement_residual(self, f: int, target: pin.SE3, q: np.ndarray, derivatives: bool):
        """Crocoddyl's ``ResidualModelFramePlacement`` of frame ``f`` toward ``target``: log6(M_ref^-1
        oMf) (6,) (translation part m, rotation part rad) and its Jacobian Jlog6 J (6, nv) in dq (J
        the LOCAL frame Jacobian; None unless ``derivatives``); the frame placements of dyn.data
        current."""
        m, d = self.model, self.dyn.data
        rMf = target.actInv(d.oMf[f])
        r = pin.log6(rMf).vector
        return r, (pin.Jlog6(rMf) @ pin.computeFrameJacobian(m, d, q, f, pin.LOCAL) if derivatives else None)

    def force_references(self, feet: tuple[int, ...]) -> list[tuple[slice, np.ndarray]]:
        """Per foot of a contact node on ``feet``: (its rows of ``NodeEval.forces``, the reference of
        the force regularisation there): (3,) N for a point foot, (6,) (N, N m) for a flat foot's
        wrench; (0, 0, m |g| / len(feet)) (and zero torque) for ``costs.force_reference`` =
        "weight_share", zeros for "zero"."""
        share = self.robot_weight / len(feet) if feet and self.costs.force_reference == "weight_share" else 0.0
        out = []
        for rows, _ in self._cones(feet):
            ref = np.zeros(rows.stop - rows.start)
            ref[2] = share  # world z, the flat ground's normal
            out.append((rows, ref))
        return out

    def force_rows(self, feet: tuple[int, ...]) -> list[int]:
        """The first row of each foot's force in a contact node's ``NodeEval.forces``: 3 rows per
        point foot, 6 per flat foot (its force, then its torque, world-aligned axes)."""
        return [rows.start for rows, _ in self._cones(feet)]

    def _cones(self, feet: tuple[int, ...]) -> list[tuple[slice, tuple[np.ndarray, np.ndarray, np.ndarray]]]:
        """Per foot of a contact node: (its rows of ``NodeEval.forces``, its cone (A, lb, ub)):
        the friction cone of a point foot's force (3 rows), the wrench cone of a flat foot's
        (force, torque) (6 rows)."""
        out, start = [], 0
        for f in feet:
            cone = self.cone if self.dyn.kind(f) == "3d" else self.wrench
            n = cone[0].shape[1]
            out.append((slice(start, start + n), cone))
            start += n
        return out

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

        pin.forwardKinematics(m, d, q)
        pin.updateFramePlacements(m, d)
        if impulse:
            add_state(c.impulse_state, self.q_ref, self.v_ref, self.w_impulse)
            for f, p in node.swing:
                add(c.impulse_foot, *self._foot_residual(f, p, q, derivatives), Q, qi)
            add(c.impulse_control, u, None, U, ui)
            return val, g, Hs
        add_state(c.state, self.q_ref, self.v_ref, self.w_state)
        if c.bounds:  # Crocoddyl's biped has no bounds term
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
            add(c.foot, *self._foot_residual(f, p, q, derivatives), Q, qi)
        if c.base_placement and node.base is not None:  # a state term: the terminal node keeps it too
            add(c.base_placement, *self._placement_residual(self.base_frame, node.base, q, derivatives), Q, qi)
        if not terminal:
            add(c.control, u, None, U, ui)
            for rows, (A, lb, ub) in self._cones(node.feet):
                ex, mask = _barrier(A @ ev.forces[rows], lb, ub)
                val += 0.5 * c.friction_cone * float(ex @ ex)
                if derivatives and mask.any():  # inside the cone the barrier is flat
                    Jr = A @ ev.Lz[rows]
                    g[:] += c.friction_cone * (Jr.T @ ex)
                    Hs[:] += c.friction_cone * (Jr.T @ (mask[:, None] * Jr))
            if c.force_regularisation:
                w = c.force_regularisation
                for rows, ref in self.force_references(node.feet):
                    r = ev.forces[rows] - ref
                    val += 0.5 * w * float(r @ r)
                    if derivatives:  # the forces depend on the whole z: a dense term
                        Jr = ev.Lz[rows]
                        g[:] += w * (Jr.T @ r)
                        Hs[:] += w * (Jr.T @ Jr)
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
        if k in self._force_at:  # hard constraints on the forces: their augmented Lagrangian terms
            fv, fg, fH = self._force_terms(k, ev, derivatives)
            val += fv
            if derivatives:
                g += fg
                Hs += fH
        return ev, val, g, Hs

    # ------------------------------------------------------------ constraints on the contact forces
    def with_force_terms(self, terms: list) -> "ContactProblem":
        """This problem with the augmented Lagrangian terms of constraints on its contact forces
        added to its node costs (the inner problem of :func:`geoddp.constraints.solve_constrained`
        for a legged problem with :class:`geoddp.constraints.contact_forces.FrictionCone`).

        Args:
            terms: ``(placed, multipliers, penalty)`` per constraint: a
                :class:`~geoddp.constraints.contact_forces.ForcePlaced` (its (node, foot) pairs and
                rows G f - h <= 0), multipliers (N, nc) >= 0 and the penalty mu > 0.

        At node k, per pair, the PHR terms (Nocedal & Wright, eq. 17.65) phi = sum_r (max(0, lambda_r +
        mu c_r)^2 - lambda_r^2) / (2 mu), with c = G f_foot - h in newtons (not scaled by dt: they
        are the constraints' terms, not a running cost); gradient lhat G Lz (lhat = max(0, lambda
        + mu c)), Gauss-Newton Hessian mu (G Lz)^T (G Lz) on the rows with lambda + mu c > 0, and in
        the exact second order the forces' curvature sum_r lhat_r G_r L2 (:meth:`_cost_hessian`).
        The copy shares the dynamics and the schedule; this problem is unchanged."""
        new = copy.copy(self)
        new._force_at = {}
        for placed, lam, mu in terms:
            lam = np.asarray(lam, dtype=float)
            for j, (k, slot) in enumerate(zip(placed.nodes.tolist(), placed.slots.tolist())):
                start = new.force_rows(new.nodes[k].feet)[slot]  # a flat foot's wrench takes 6 rows
                new._force_at.setdefault(k, []).append((placed.bound, lam[j], float(mu), start))
        return new

    def _force_terms(self, k: int, ev, derivatives: bool, L2: np.ndarray | None = None):
        """The force constraints' terms at contact node k: (value, gradient (nz,), Gauss-Newton
        Hessian (nz, nz)), or with ``L2`` (the forces' second derivatives (rows of forces, nz, nz)) the
        exact curvature sum_r lhat_r G_r L2 (nz, nz) alone (value and gradient then None)."""
        nz = self.nx + self.nu
        val, g, H = 0.0, np.zeros(nz), np.zeros((nz, nz))
        for bound, lam, mu, start in self._force_at[k]:
            rows = slice(start, start + 3)  # the foot's force (a flat foot's wrench: its first 3 rows)
            c = bound.G @ ev.forces[rows] - bound.h
            t = lam + mu * c
            lhat = np.maximum(t, 0.0)
            if L2 is not None:
                if lhat.any():
                    H += ((lhat @ bound.G) @ L2[rows].reshape(3, -1)).reshape(nz, nz)
                continue
            val += float(lhat @ lhat - lam @ lam) / (2.0 * mu)
            if derivatives and lhat.any():
                Jr = bound.G @ ev.Lz[rows]
                g += Jr.T @ lhat
                on = Jr[t > 0.0]
                H += mu * (on.T @ on)
        return (None, None, H) if L2 is not None else (val, g, H)

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
        held: dict[tuple[int, ...], np.ndarray] = {}  # per set of feet: a gait has a few, over many nodes
        for k, n in enumerate(self.nodes):
            if n.kind == "contact":
                if n.feet not in held:
                    held[n.feet] = self.dyn.quasi_static(self.q0, n.feet)
                U[k] = held[n.feet]
        return U

    # ------------------------------------------------------------ the compiled backend
    def __getstate__(self) -> dict:
        """Pickled (a sweep's workers, deepcopy) without the compiled kernel: rebuilt on first use."""
        state = dict(self.__dict__)
        state["_core"], state["_last_costs"] = None, None
        return state

    @property
    def compiled(self) -> bool:
        """True when the rollouts, costs and first-order expansion run in the compiled core: with
        backend "compiled", point feet only (the kernel has no 6D contacts), no terms of force
        constraints (the augmented Lagrangian's inner problems, :meth:`with_force_terms`, run in
        Python) and the weights ``costs.base_placement`` and ``costs.force_regularisation`` zero
        (the kernel has neither term: a problem with them runs the Python node models)."""
        c = self.costs
        return (self.backend == "compiled" and not self.flat_feet and not self._force_at
                and not c.base_placement and not c.force_regularisation)

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

    def _placement_curvature(self, f: int, p: np.ndarray | pin.SE3, q: np.ndarray, c: np.ndarray) -> np.ndarray:
        """sum_a c_a d^2 r_a (nv, nv) of a frame's placement residual r(eta) =
        log6(M_ref^-1 oMf(q exp(eta))) (a flat foot's, M_ref = (I, p) for a position p (3,); the
        base's, M_ref its target ``pin.SE3``), exactly: with the frame's displacement
        phi(eta) = J eta + 1/2 a_f(q, eta, 0) to second order (a_f the frame's LOCAL spatial
        acceleration at zero joint acceleration, quadratic in the velocity) and
        r = r0 + K phi - 1/2 K D(K phi, K phi) (K = Jlog6, D the SE(3) chart's second-order tensor),
        the curvature is 1/2 (K^T c) . P - (KJ)^T ((K^T c) . D_sym) (KJ), P the velocity Hessian of
        a_f (column k: its velocity derivative at v = e_k). Leaves dyn.data's placements at q."""
        m, d, nv = self.model, self.dyn.data, self.model.nv
        rMf = _placement(p).actInv(d.oMf[f])
        r0 = pin.log6(rMf).vector
        K = pin.Jlog6(rMf)
        J = pin.computeFrameJacobian(m, d, q, f, pin.LOCAL)
        kc = K.T @ c
        P = np.empty((nv, nv))  # kc . P
        zero = np.zeros(nv)
        for k in range(nv):  # d a_f / d v at v = e_k is P e_k (a_f quadratic in v)
            e = np.zeros(nv)
            e[k] = 1.0
            pin.computeForwardKinematicsDerivatives(m, d, q, e, zero)
            P[:, k] = kc @ pin.getFrameAccelerationDerivatives(m, d, f, pin.LOCAL)[2]
        pin.forwardKinematics(m, d, q)
        pin.updateFramePlacements(m, d)
        D = kernels.core.se3_jr_derivative(np.ascontiguousarray(r0)).reshape(6, 6, 6)
        Ds = 0.5 * (D + D.transpose(0, 2, 1))
        KJ = K @ J
        out = 0.5 * P - KJ.T @ np.einsum("a,abc->bc", kc, Ds) @ KJ
        return 0.5 * (out + out.T)

    def _cost_hessian(self, k: int, q, v, u, ev, L2, gauss_newton: np.ndarray | None = None) -> np.ndarray:
        """Exact Hessian (nz, nz) of node k's cost: the Gauss-Newton part of :meth:`_cost` plus
        each residual's curvature times its weighted residual: the state differences' (SE(3) log's
        second order), the CoM's and the point feet's (generalised gravity derivatives of a model
        whose gravity is minus the residual: the CoM of the robot, a unit point mass at the foot),
        the flat feet's and the base's placements' (:meth:`_placement_curvature`) and the forces'
        (``L2``: their exact second derivatives: the cone barriers' and the force regularisation's
        curvature). ``gauss_newton``: that Gauss-Newton part
        at the same point if already computed (it is added to, not copied), else None."""
        m, c, nv = self.model, self.costs, self.model.nv
        terminal = k == self.horizon
        node = self.terminal_node if terminal else self.nodes[k]
        d = self.dyn.data
        if gauss_newton is None:
            _, _, Hs = self._cost(node, q, v, u, ev, True, terminal=terminal)  # leaves the kinematics in dyn.data
            if k in self._force_at:  # node() adds the force constraints' Gauss-Newton part
                Hs += self._force_terms(k, ev, True)[2]
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
                if self.dyn.kind(f) == "3d":
                    mf, df = self.dyn._foot_model(f)
                    out += weight * self._gravity_curvature(mf, df, q, d.oMf[f].translation - p)
                else:
                    out += self._placement_curvature(f, p, q, weight * self._foot_residual(f, p, q, False)[0])
            return out

        if node.kind == "impulse":
            curv += c.impulse_state * self._difference_curvature(self.q_ref, q, self.w_impulse[:nv] * rq)
            curv += feet(c.impulse_foot)
            Hs[:nv, :nv] += curv
            return Hs
        curv += c.state * self._difference_curvature(self.q_ref, q, self.w_state[:nv] * rq)
        if c.bounds:
            ex, _ = _barrier(np.concatenate([pin.difference(m, self.q_neutral, q), v]), self.lb, self.ub)
            if np.any(ex[:nv]):
                curv += c.bounds * self._difference_curvature(self.q_neutral, q, ex[:nv])
        if node.com is not None:
            r = pin.centerOfMass(m, d, q) - node.com
            curv += c.com * self._gravity_curvature(m0, d0, q, r / pin.computeTotalMass(m))
        curv += feet(c.foot)
        if c.base_placement and node.base is not None:
            rb = self._placement_residual(self.base_frame, node.base, q, False)[0]
            curv += self._placement_curvature(self.base_frame, node.base, q, c.base_placement * rb)
        scale = 1.0 if terminal else self.dt
        Hs[:nv, :nv] += scale * curv
        if not terminal:
            nz = Hs.shape[0]
            for rows, (A, lb, ub) in self._cones(node.feet):
                ex, mask = _barrier(A @ ev.forces[rows], lb, ub)
                if mask.any():  # inside the cone the barrier is flat
                    Hs += (c.friction_cone * self.dt) * ((ex @ A) @ L2[rows].reshape(A.shape[1], -1)).reshape(nz, nz)
            if c.force_regularisation:
                w = c.force_regularisation * self.dt
                for rows, ref in self.force_references(node.feet):
                    r = ev.forces[rows] - ref
                    Hs += w * (r @ L2[rows].reshape(len(r), -1)).reshape(nz, nz)
            if k in self._force_at:
                Hs += self._force_terms(k, ev, True, L2)[2]
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
        if order == 2 and self.compiled and self.compiled_second_order:
            # the dynamics' second order factored (per node the RNEA recursion's terms, the feet's
            # rows on their chains, dy/dz and the KKT inverse's velocity rows): the backward pass
            # contracts it with V_x' node by node instead of reading Theta, Gamma, Xi
            # (Linearisation.tensors() forms them when asked)
            c64 = np.ascontiguousarray
            Phi, B, lx, lu, lxx, lux, luu, gf, Hf, _, terms = self.kernel().linearise_contracted(
                c64(traj.q, dtype=float), c64(traj.v, dtype=float), c64(traj.u, dtype=float), self.threads)
            return Linearisation(order=2, Phi=Phi, B=B, Theta=None, Gamma=None, Xi=None, l_x=lx, l_u=lu, l_xx=lxx,
                                 l_ux=lux, l_uu=luu, lf_x=gf, lf_xx=Hf, gauss_newton=False, second_order=terms)
        Phi, B = np.empty((H, nx, nx)), np.empty((H, nx, nu))
        evs = []
        lx, lu = np.empty((H, nx)), np.empty((H, nu))
        lxx, lux, luu = np.empty((H, nx, nx)), np.empty((H, nu, nx)), np.empty((H, nu, nu))
        hess = []
        nodes = self._first_order_nodes(traj, self.compiled and order == 1)
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


# ------------------------------------------------------------------ Crocoddyl's gaits
def _frame_ids(model: pin.Model, names) -> tuple[int, ...]:
    missing = [f for f in names if not model.existFrame(f)]
    if missing:
        raise InputError("feet", f"frames {missing} are not in the model")
    return tuple(int(model.getFrameId(f)) for f in names)


def _posture(model: pin.Model, q_default: np.ndarray | None, name: str) -> np.ndarray:
    if q_default is not None:
        return q_default
    if name not in model.referenceConfigurations:
        raise InputError("q_default", f"the model has no {name!r} reference configuration; give q_default")
    return model.referenceConfigurations[name].copy()


def _start(model: pin.Model, ids: tuple[int, ...], q0: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """(the feet's positions (3,) at q0, m; the CoM's start: their mean with the CoM's height)."""
    d = model.createData()
    pin.forwardKinematics(model, d, q0)
    pin.updateFramePlacements(model, d)
    pos = [d.oMf[i].translation.copy() for i in ids]
    com = sum(pos) / len(pos)
    com[2] = pin.centerOfMass(model, d, q0)[2]
    return pos, com


def footstep(com0: np.ndarray, feet_pos: list[np.ndarray], length: float, height: float, knots: int,
             support, swing) -> list[Node]:
    """Crocoddyl's ``createFootstepModels``: ``knots`` contact nodes on the ``support`` feet (frame
    ids), the ``swing`` feet (at ``feet_pos`` (3,), m) tracking an arc ``length`` m forward and
    ``height`` m up, the CoM the share of the step the swing feet carry (len(swing) / all feet);
    then the impulse node of their landing. Moves ``com0`` and ``feet_pos`` (in place) to the end
    of the step, as Crocoddyl's builder does for the next one."""
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
        self.ids = _frame_ids(self.model, self.feet)
        self.q_default = _posture(self.model, self.q_default, "standing")

    def walk(self, q0, length: float, height: float, knots: int, support_knots: int) -> tuple[list[Node], Node]:
        """Crocoddyl's createWalkingProblem (first call): RH, RF half steps, then LH, LF steps."""
        lf, rf, lh, rh = self.ids
        (plf, prf, plh, prh), com = _start(self.model, self.ids, q0)
        ds = [Node("contact", (lf, rf, lh, rh)) for _ in range(support_knots)]
        nodes = list(ds)
        nodes += footstep(com, [prh], 0.5 * length, height, knots, [lf, rf, lh], [rh])
        nodes += footstep(com, [prf], 0.5 * length, height, knots, [lf, lh, rh], [rf])
        lh_step = footstep(com, [plh], length, height, knots, [lf, rf, rh], [lh])
        lf_step = footstep(com, [plf], length, height, knots, [rf, lh, rh], [lf])
        nodes += ds + lh_step + lf_step
        return nodes, ds[0]

    def trot(self, q0, length: float, height: float, knots: int, support_knots: int) -> tuple[list[Node], Node]:
        """Crocoddyl's createTrottingProblem (first call): RF+LH half step, then LF+RH step."""
        lf, rf, lh, rh = self.ids
        (plf, prf, plh, prh), com = _start(self.model, self.ids, q0)
        ds = [Node("contact", (lf, rf, lh, rh)) for _ in range(support_knots)]
        nodes = list(ds)
        nodes += footstep(com, [prf, plh], 0.5 * length, height, knots, [lf, rh], [rf, lh])
        nodes += ds + footstep(com, [plf, prh], length, height, knots, [rf, lh], [lf, rh])
        return nodes, ds[0]

    def jump(self, q0, height: float, length, ground_knots: int, flying_knots: int) -> tuple[list[Node], Node]:
        """Crocoddyl's createJumpingProblem: ``ground_knots`` on four feet, ``flying_knots`` rising
        to the CoM apex (half of ``length`` (3,) m plus ``height`` m up), ``flying_knots`` falling,
        the landing impulse with the feet at their start plus ``length``, then ``ground_knots`` on
        four feet (the last one terminal) with the CoM target moved by ``length`` (its z: the
        height change of the feet)."""
        lf, rf, lh, rh = self.ids
        feet = (lf, rf, lh, rh)
        (plf, prf, plh, prh), _ = _start(self.model, self.ids, q0)
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


@dataclass
class BipedGait:
    """The walk of Crocoddyl's ``SimpleBipedGaitProblem`` (crocoddyl.utils.biped), node for node, for
    a fresh instance (its first, half, step): :meth:`walk`. The feet are meant as flat feet ("6d"
    contacts of :class:`geoddp.models.contact.ContactDynamics`, :meth:`GaitCosts.biped`).

    Attributes:
        model: the robot (``pin.Model`` with a free-flyer root and a "half_sitting" reference
            configuration unless ``q_default`` is given); feet: the sole frames' names (right, left).
    """

    model: pin.Model
    feet: tuple[str, str]
    q_default: np.ndarray | None = None
    ids: tuple[int, ...] = field(init=False)

    def __post_init__(self) -> None:
        if len(self.feet) != 2:
            raise InputError("feet", f"expected two feet (right, left), got {len(self.feet)}")
        self.ids = _frame_ids(self.model, self.feet)
        self.q_default = _posture(self.model, self.q_default, "half_sitting")

    def walk(self, q0, length: float, height: float, knots: int, support_knots: int) -> tuple[list[Node], Node]:
        """Crocoddyl's createWalkingProblem (first call): ``support_knots`` on both feet, the right
        foot's half step, ``support_knots`` on both feet, the left foot's full step
        (2 support_knots + 2 knots + 1 nodes); the last node, the left foot's landing impulse, is
        the terminal node (Crocoddyl's walk ends on it)."""
        rf, lf = self.ids
        (prf, plf), com = _start(self.model, self.ids, q0)
        ds = [Node("contact", (rf, lf)) for _ in range(support_knots)]
        r_step = footstep(com, [prf], 0.5 * length, height, knots, [lf], [rf])
        l_step = footstep(com, [plf], length, height, knots, [rf], [lf])
        nodes = ds + r_step + ds + l_step
        return nodes[:-1], nodes[-1]
