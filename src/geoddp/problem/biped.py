"""Bipeds on flat feet: Crocoddyl's ``SimpleBipedGaitProblem`` (crocoddyl.utils.biped, its example
bipedal_gaits_fwddyn.py with Talos' legs) node for node, on :class:`geoddp.problem.legged.ContactProblem`.

The feet are 6D contacts (flat feet, :class:`geoddp.models.contact.ContactDynamics` with
``contact_kinds`` "6d": Crocoddyl's ``ContactModel6D`` with ``LOCAL_WORLD_ALIGNED``, Baumgarte gains
(0, 30); impulses ``ImpulseModel6D``). Costs per node, Crocoddyl's weights (:class:`BipedCosts`):

* contact node (times dt): CoM tracking 1e6 (when the node has a CoM target); per support foot a
  wrench-cone quadratic barrier 10 on A f (f the foot's wrench in world-aligned axes; A: Crocoddyl's
  ``WrenchCone`` with mu = 0.7, the inner approximation of four facets, a 0.1 x 0.05 m sole: the
  friction cone, the centre of pressure inside the sole and the yaw torque bounded,
  :func:`wrench_cone`); per swing foot a placement tracking 1e6 (the residual log6(M_ref^-1 oMf),
  M_ref the target position with the identity rotation); state regularisation 10 toward the
  posture (weights (0, 0, 0, 500, 500, 500, 0.01 per joint, 10 per velocity), squared);
  control regularisation 0.1. No state-bounds term (the quadruped's has one).
* impulse node: placement tracking 1e8 of the landing feet, state regularisation 10 with weights
  (1 x 6, 0.1 per joint, 10 per velocity), squared.
* terminal node: Crocoddyl's walk ends on the last footstep's impulse model, costed by its
  ``calc(x)``: the landing foot's placement 1e8 and the impulse state term.

Every cost Hessian is exact (the ``second`` and ``switch`` expansions): the Gauss-Newton part plus
the residuals' curvature: the state differences' and the CoM's as the quadruped's; the placement
residual's from r(eta) = r0 + K phi - 1/2 K D(K phi, K phi) (K = Jlog6, D the SE(3) chart's
second-order tensor) with the frame's displacement phi(eta) = J eta + 1/2 a_f(q, eta, 0) to second
order (a_f the frame's spatial acceleration, its velocity Hessian from Pinocchio's frame acceleration
derivatives); the wrench cones' from the forces' exact second derivatives.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from .. import kernels
from ..models.contact import ContactDynamics
from ..validate import InputError
from .legged import ContactProblem, Node, QuadrupedGait, _barrier

LOCAL = pin.ReferenceFrame.LOCAL


def wrench_cone(mu: float, box: tuple[float, float], facets: int = 4, inner: bool = True
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Crocoddyl's ``WrenchCone`` (flat ground, normal +z) of a rectangular sole ``box`` = (length,
    width) m: (A (facets + 13, 6), lb, ub), lb <= A (f, tau) <= ub meaning the wrench inside: the
    linearised friction cone (``inner``: its inner approximation, mu cos(pi / facets)), f_z >= 0,
    the centre of pressure inside the sole, the yaw torque within its friction bound."""
    if facets % 2 or facets < 2:
        raise InputError("facets", f"expected an even number >= 2, got {facets!r}")
    theta = 2.0 * np.pi / facets
    mu = mu * np.cos(0.5 * theta) if inner else mu
    A = np.zeros((facets + 13, 6))
    lb, ub = np.full(facets + 13, -np.inf), np.zeros(facets + 13)
    mu_n = np.array([0.0, 0.0, -mu])
    for i in range(facets // 2):
        t = np.array([np.cos(theta * i), np.sin(theta * i), 0.0])
        A[2 * i, :3], A[2 * i + 1, :3] = mu_n + t, mu_n - t
    A[facets, 2] = 1.0
    lb[facets], ub[facets] = 0.0, np.inf
    L, W = 0.5 * box[0], 0.5 * box[1]
    n = facets
    A[n + 1] = [0, 0, -W, 1, 0, 0]
    A[n + 2] = [0, 0, -W, -1, 0, 0]
    A[n + 3] = [0, 0, -L, 0, 1, 0]
    A[n + 4] = [0, 0, -L, 0, -1, 0]
    mu_lw = -mu * (L + W)
    for j, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        A[n + 5 + j] = [sx * W, sy * L, mu_lw, -sx * mu, -sy * mu, -1.0]
        A[n + 9 + j] = [sx * W, sy * L, mu_lw, sx * mu, sy * mu, 1.0]
    return A, lb, ub


@dataclass
class BipedCosts:
    """Weights of Crocoddyl's biped gait costs (see the module docstring)."""

    com: float = 1e6
    wrench_cone: float = 1e1
    mu: float = 0.7
    sole: tuple[float, float] = (0.1, 0.05)
    foot: float = 1e6
    state: float = 1e1
    control: float = 1e-1
    impulse_foot: float = 1e8
    impulse_state: float = 1e1
    impulse_control: float = 1.0  # on the controls of an impulse node: they stay 0, so it costs 0


class BipedProblem(ContactProblem):
    """A contact schedule of a biped on 6D feet with Crocoddyl's biped costs (:class:`BipedCosts`);
    the dynamics, rollouts and the solver's contract are :class:`ContactProblem`'s. Every foot of
    the schedule must be a "6d" contact of ``dynamics``."""

    def __init__(self, dynamics: ContactDynamics, nodes: list[Node], terminal: Node, q0: np.ndarray,
                 v0: np.ndarray, x_ref: tuple[np.ndarray, np.ndarray], costs: BipedCosts | None = None,
                 description: dict | None = None) -> None:
        super().__init__(dynamics, nodes, terminal, q0, v0, x_ref, None, description)
        for n in [*nodes, terminal]:
            for f in n.feet:
                if dynamics.kind(f) != "6d":
                    raise InputError("dynamics.contact_kinds", f"expected a 6d contact for frame {f} of a biped")
        self.costs = costs or BipedCosts()
        nj = self.model.nv - 6
        self.w_state = np.array([0.0] * 3 + [500.0] * 3 + [0.01] * nj + [10.0] * self.model.nv) ** 2
        self.w_impulse = np.array([1.0] * 6 + [0.1] * nj + [10.0] * self.model.nv) ** 2
        self.cone = wrench_cone(self.costs.mu, self.costs.sole, 4, True)

    def _placement(self, f: int, p: np.ndarray, q: np.ndarray, derivatives: bool):
        """(log6(M_ref^-1 oMf) (6,), its Jacobian (6, nv) or None), M_ref = (I, p); the frame
        placements of dyn.data current."""
        rMf = pin.SE3(np.eye(3), np.asarray(p, dtype=float)).actInv(self.dyn.data.oMf[f])
        r = pin.log6(rMf).vector
        if not derivatives:
            return r, None
        J = pin.computeFrameJacobian(self.model, self.dyn.data, q, f, LOCAL)
        return r, pin.Jlog6(rMf) @ J

    def _cost(self, node, q, v, u, ev, derivatives: bool, terminal: bool = False):
        m, d, c = self.model, self.dyn.data, self.costs
        nv, nu = m.nv, self.nu
        nz = 2 * nv + nu
        val, g, Hs = 0.0, np.zeros(nz), np.zeros((nz, nz))
        Q, V, U = slice(0, nv), slice(nv, 2 * nv), slice(2 * nv, nz)

        def add(w, r, Jr, cols, act=None):  # 0.5 w r' diag(act) r; Jr None: the identity
            nonlocal val
            ar = r if act is None else act * r
            val += 0.5 * w * float(r @ ar)
            if derivatives:
                if Jr is None:
                    g[cols] += w * ar
                    Hs[cols, cols] += np.diag(w * (np.ones(len(r)) if act is None else act))
                else:
                    g[cols] += w * (Jr.T @ ar)
                    Hs[cols, cols] += w * (Jr.T @ (Jr if act is None else act[:, None] * Jr))

        def add_state(w, weights):
            rs, D = self._state_residual(self.q_ref, q, v, self.v_ref)
            add(w, rs[:nv], D, Q, weights[:nv])
            add(w, rs[nv:], None, V, weights[nv:])

        pin.forwardKinematics(m, d, q)
        pin.updateFramePlacements(m, d)
        if node.kind == "impulse":
            add_state(c.impulse_state, self.w_impulse)
            for f, p in node.swing:
                add(c.impulse_foot, *self._placement(f, p, q, derivatives), Q)
            add(c.impulse_control, u, None, U)
            return val, g, Hs
        add_state(c.state, self.w_state)
        if node.com is not None:
            com = pin.centerOfMass(m, d, q)
            add(c.com, com - node.com, pin.jacobianCenterOfMass(m, d, q) if derivatives else None, Q)
        for f, p in node.swing:
            add(c.foot, *self._placement(f, p, q, derivatives), Q)
        if not terminal:
            add(c.control, u, None, U)
            A, lb, ub = self.cone
            for i in range(len(node.feet)):
                rows = slice(6 * i, 6 * i + 6)
                ex, mask = _barrier(A @ ev.forces[rows], lb, ub)
                val += 0.5 * c.wrench_cone * float(ex @ ex)
                if derivatives and mask.any():
                    Jr = A @ ev.Lz[rows]
                    g[:] += c.wrench_cone * (Jr.T @ ex)
                    Hs[:] += c.wrench_cone * (Jr.T @ (mask[:, None] * Jr))
            val *= self.dt
            g *= self.dt
            Hs *= self.dt
        return val, g, Hs

    def _placement_curvature(self, f: int, p: np.ndarray, q: np.ndarray, c: np.ndarray) -> np.ndarray:
        """sum_a c_a d^2 r_a (nv, nv), r(eta) = log6(M_ref^-1 oMf(q exp(eta))), exactly (module
        docstring): 1/2 (K^T c) . P - (KJ)^T ((K^T c) . Ds) (KJ), P the velocity Hessian of the
        frame's spatial acceleration a_f(q, v, 0) (quadratic in v: column k of its velocity
        derivative at v = e_k)."""
        m, d, nv = self.model, self.dyn.data, self.model.nv
        rMf = pin.SE3(np.eye(3), np.asarray(p, dtype=float)).actInv(d.oMf[f])
        r0 = pin.log6(rMf).vector
        K = pin.Jlog6(rMf)
        J = pin.computeFrameJacobian(m, d, q, f, LOCAL)
        kc = K.T @ c
        P = np.empty((nv, nv))  # kc . P
        zero = np.zeros(nv)
        for k in range(nv):
            e = np.zeros(nv)
            e[k] = 1.0
            pin.computeForwardKinematicsDerivatives(m, d, q, e, zero)
            P[:, k] = kc @ pin.getFrameAccelerationDerivatives(m, d, f, LOCAL)[2]
        pin.forwardKinematics(m, d, q)
        pin.updateFramePlacements(m, d)
        D = kernels.core.se3_jr_derivative(np.ascontiguousarray(r0)).reshape(6, 6, 6)
        Ds = 0.5 * (D + D.transpose(0, 2, 1))
        KJ = K @ J
        out = 0.5 * P - KJ.T @ np.einsum("a,abc->bc", kc, Ds) @ KJ
        return 0.5 * (out + out.T)

    def _cost_hessian(self, k: int, q, v, u, ev, L2, gauss_newton: np.ndarray | None = None) -> np.ndarray:
        m, c, nv = self.model, self.costs, self.model.nv
        terminal = k == self.horizon
        node = self.terminal_node if terminal else self.nodes[k]
        d = self.dyn.data
        if gauss_newton is None:
            _, _, Hs = self._cost(node, q, v, u, ev, True, terminal=terminal)
        else:
            Hs = gauss_newton
        pin.forwardKinematics(m, d, q)
        pin.updateFramePlacements(m, d)
        curv = np.zeros((nv, nv))
        rq = pin.difference(m, self.q_ref, q)
        impulse = node.kind == "impulse"
        w_foot = c.impulse_foot if impulse else c.foot
        for f, p in node.swing:
            r, _ = self._placement(f, p, q, False)
            curv += self._placement_curvature(f, p, q, w_foot * r)
        if impulse:
            curv += c.impulse_state * self._difference_curvature(self.q_ref, q, self.w_impulse[:nv] * rq)
            Hs[:nv, :nv] += curv
            return Hs
        curv += c.state * self._difference_curvature(self.q_ref, q, self.w_state[:nv] * rq)
        if node.com is not None:
            m0, d0 = self.dyn._aux_models()["zero_gravity"]
            r = pin.centerOfMass(m, d, q) - node.com
            curv += c.com * self._gravity_curvature(m0, d0, q, r / pin.computeTotalMass(m))
        scale = 1.0 if terminal else self.dt
        Hs[:nv, :nv] += scale * curv
        if not terminal:
            A, lb, ub = self.cone
            nz = Hs.shape[0]
            for i in range(len(node.feet)):
                rows = slice(6 * i, 6 * i + 6)
                ex, mask = _barrier(A @ ev.forces[rows], lb, ub)
                if mask.any():
                    Hs += (c.wrench_cone * self.dt) * ((ex @ A) @ L2[rows].reshape(6, -1)).reshape(nz, nz)
        return Hs


@dataclass
class BipedGait:
    """The schedules of Crocoddyl's ``SimpleBipedGaitProblem`` for a fresh instance (its first,
    half, step): :meth:`walk`.

    Attributes:
        model: the robot (free-flyer root, a "half_sitting" reference configuration unless
            ``q_default`` is given); right, left: the sole frames' names.
    """

    model: pin.Model
    right: str
    left: str
    q_default: np.ndarray | None = None
    ids: tuple[int, int] = field(init=False)

    def __post_init__(self) -> None:
        missing = [f for f in (self.right, self.left) if not self.model.existFrame(f)]
        if missing:
            raise InputError("feet", f"frames {missing} are not in the model")
        self.ids = (int(self.model.getFrameId(self.right)), int(self.model.getFrameId(self.left)))
        if self.q_default is None:
            if "half_sitting" not in self.model.referenceConfigurations:
                raise InputError("q_default", "the model has no 'half_sitting' reference configuration; give q_default")
            self.q_default = self.model.referenceConfigurations["half_sitting"].copy()

    def walk(self, q0: np.ndarray, length: float, height: float, knots: int, support_knots: int
             ) -> tuple[list[Node], Node]:
        """Crocoddyl's createWalkingProblem (first call): double support, the right foot's half
        step, double support, the left foot's step; the last node (the left foot's landing impulse)
        is the terminal node."""
        m = self.model
        d = m.createData()
        pin.forwardKinematics(m, d, q0)
        pin.updateFramePlacements(m, d)
        rf, lf = self.ids
        prf, plf = d.oMf[rf].translation.copy(), d.oMf[lf].translation.copy()
        com = 0.5 * (prf + plf)
        com[2] = pin.centerOfMass(m, d, q0)[2]
        ds = [Node("contact", (rf, lf)) for _ in range(support_knots)]
        r_step = QuadrupedGait._footstep(com, [prf], 0.5 * length, height, knots, [lf], [rf])
        l_step = QuadrupedGait._footstep(com, [plf], length, height, knots, [rf], [lf])
        nodes = ds + r_step + ds + l_step
        return nodes[:-1], nodes[-1]


# Crocoddyl's example bipedal_gaits_fwddyn.py (its walking phase)
TALOS_WALK = {"step_length": 0.6, "step_height": 0.1, "dt": 0.03, "step_knots": 15, "support_knots": 4}


def talos_walk(robot=None, step_length: float = 0.6, step_height: float = 0.1, dt: float = 0.03,
               step_knots: int = 15, support_knots: int = 4) -> BipedProblem:
    """Crocoddyl's biped walk with Talos' legs (example-robot-data "talos_legs", feet
    "right_sole_link" / "left_sole_link", posture "half_sitting", at rest): by default its
    example's values (step 0.6 m, height 0.1 m, dt 0.03 s, 15 step knots, 4 support knots: 39
    nodes). ``robot``: an example_robot_data robot (loaded if None)."""
    if robot is None:
        import example_robot_data

        robot = example_robot_data.load("talos_legs")
    model = robot.model
    gait = BipedGait(model, "right_sole_link", "left_sole_link")
    q0 = gait.q_default.copy()
    nodes, terminal = gait.walk(q0, step_length, step_height, step_knots, support_knots)
    dyn = ContactDynamics(model, dt, gains=(0.0, 30.0), contact_kinds={f: "6d" for f in gait.ids})
    return BipedProblem(dyn, nodes, terminal, q0, np.zeros(model.nv), (q0, np.zeros(model.nv)))
