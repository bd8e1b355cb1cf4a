"""Contact forces along a legged trajectory, and how far inside the friction cone they stay.

:func:`contact_forces` re-evaluates each node of a :class:`geoddp.problem.legged.ContactProblem`
along a trajectory (the solved configurations, velocities and controls) with its own node
dynamics (:meth:`geoddp.models.contact.ContactDynamics.contact` and ``impulse``): the contact
forces of the feet on the ground at every contact node (N, world frame, the force the ground
exerts on the foot) and the impulses of the feet that touch down at every impulse node (N s), the
feet's positions and velocities, and the rate of change of the robot's linear momentum that those
forces must balance (Newton's law for the whole robot, gravity included):

* contact node k: ``sum_f f_f = m (a_com - g)``, a_com the CoM acceleration at (q_k, v_k, a_k);
* impulse node k: ``sum_f Lambda_f = m (v_com+ - v_com)``, the jump of the CoM velocity.

Friction-cone margins (flat ground, normal +z, friction coefficient mu; positive inside the cone):

* ``cone_margin = mu f_z - |(f_x, f_y)|``: the exact (circular) cone;
* ``facet_margin = min_i (mu f_z - t_i . f)``, t_i the facets' tangent directions: Crocoddyl's
  linearised cone with ``facets`` facets (:func:`geoddp.models.contact.friction_cone`), an outer
  approximation (``facet_margin >= cone_margin``).

Impulses have margins too (the same cone, in N s).

A flat foot (a "6d" contact) also carries a torque about its frame's origin (world-aligned axes):
``torques``, and the centre of pressure ``cop`` (where on the ground plane through the foot's origin
the force acts, relative to that origin, world-aligned x and y): inside the sole while the torque
keeps to the wrench cone (:func:`geoddp.models.contact.wrench_cone`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from ..models.contact import friction_cone
from ..validate import InputError, finite_array

__all__ = ["ContactForces", "contact_forces"]


@dataclass
class ContactForces:
    """The contact forces along a trajectory of H nodes (see the module docstring).

    Attributes:
        feet: the feet's frame names (the columns, in the order they first appear in the schedule).
        frame_ids: their Pinocchio frame ids.
        dt: time step of the contact nodes, s; times: (H,) t_k = k dt, s.
        impulse: (H,) True at impulse nodes.
        active: (H, nf) foot f carries a force at contact node k or an impulse at impulse node k.
        on_ground: (H + 1, nf) foot f is on the ground at frame k: its node's feet (an impulse node:
            the feet that land and those that stood at the node before; frame H: the terminal node's).
        forces: (H, nf, 3) world-frame forces, N (contact nodes), impulses, N s (impulse nodes); 0
            where not active.
        torques: (H, nf, 3) a flat foot's torque about its frame's origin, world-aligned axes, N m
            (N m s at impulse nodes); 0 for point feet and where not active.
        positions: (H + 1, nf, 3) the feet's world positions, m.
        velocities: (H + 1, nf, 3) the feet's world linear velocities, m/s.
        momentum_change: (H, 3) m (a_com - g), N (contact nodes); m (v_com+ - v_com), N s (impulse
            nodes): what the sum of the forces of node k equals.
        mass: the robot's mass, kg; gravity: (3,) m/s^2.
        mu: friction coefficient; facets: facets of the linearised cone.
    """

    feet: tuple[str, ...]
    frame_ids: tuple[int, ...]
    dt: float
    times: np.ndarray
    impulse: np.ndarray
    active: np.ndarray
    on_ground: np.ndarray
    forces: np.ndarray
    torques: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    momentum_change: np.ndarray
    mass: float
    gravity: np.ndarray
    mu: float
    facets: int

    @property
    def horizon(self) -> int:
        return int(self.impulse.size)

    def _masked(self, x: np.ndarray) -> np.ndarray:
        return np.where(self.active, x, np.nan)

    @property
    def normal(self) -> np.ndarray:
        """(H, nf) f_z (N, or N s at impulse nodes); NaN where the foot is not active."""
        return self._masked(self.forces[..., 2])

    @property
    def tangential(self) -> np.ndarray:
        """(H, nf) |(f_x, f_y)|; NaN where the foot is not active."""
        return self._masked(np.linalg.norm(self.forces[..., :2], axis=-1))

    @property
    def cone_margin(self) -> np.ndarray:
        """(H, nf) mu f_z - |(f_x, f_y)|, positive inside the friction cone; NaN where not active."""
        return self._masked(self.mu * self.forces[..., 2] - np.linalg.norm(self.forces[..., :2], axis=-1))

    @property
    def facet_margin(self) -> np.ndarray:
        """(H, nf) min over the facets of mu f_z - t_i . f (Crocoddyl's linearised cone: rows
        A_i = (t_i, -mu) of :func:`~geoddp.models.contact.friction_cone`, inside when A_i f <= 0);
        NaN where not active."""
        A = friction_cone(self.mu, self.facets)[0][: self.facets]
        return self._masked(np.min(-(self.forces @ A.T), axis=-1))

    @property
    def cop(self) -> np.ndarray:
        """(H, nf, 2) centre of pressure of each foot relative to its frame's origin, m, in the
        world-aligned (x, y): (-tau_y, tau_x) / f_z (the torque about the origin of the force
        acting there); 0 for a point foot, NaN where the foot is not active."""
        fz = self.forces[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            cop = np.stack([-self.torques[..., 1], self.torques[..., 0]], axis=-1) / fz[..., None]
        return np.where(self.active[..., None], cop, np.nan)

    @property
    def total(self) -> np.ndarray:
        """(H, 3) sum of the forces (impulses) over the feet: equals ``momentum_change``."""
        return self.forces.sum(axis=1)

    @property
    def stance_speed(self) -> np.ndarray:
        """(H + 1, nf) speed (m/s) of the feet on the ground (NaN for the others)."""
        return np.where(self.on_ground, np.linalg.norm(self.velocities, axis=-1), np.nan)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able arrays (lists) of every attribute."""
        out: dict[str, Any] = {}
        for k, v in self.__dict__.items():
            out[k] = v.tolist() if isinstance(v, np.ndarray) else (list(v) if isinstance(v, tuple) else v)
        return out


def _feet_order(problem) -> list[int]:
    order: list[int] = []
    for node in [*problem.nodes, problem.terminal_node]:
        for f in node.feet:
            if f not in order:
                order.append(f)
    return order


def contact_forces(problem, configurations, velocities, controls, *, mu: float | None = None,
                   facets: int = 4) -> ContactForces:
    """The contact forces, impulses and friction-cone margins along a trajectory of ``problem``.

    Args:
        problem: a :class:`geoddp.problem.legged.ContactProblem` (its schedule and node dynamics).
        configurations: (H + 1, nq); velocities: (H + 1, nv); controls: (H, nu) (a Result's
            ``configurations``, ``velocities``, ``controls``; the rows of impulse nodes are ignored).
        mu: friction coefficient of the margins; None: the problem's (``problem.costs.mu``, 0.7 in
            Crocoddyl's gaits).
        facets: facets of the linearised cone (even, >= 2).

    Returns:
        :class:`ContactForces`.

    Raises:
        InputError: naming ``configurations``, ``velocities``, ``controls``, ``mu`` or ``facets``.
    """
    m, H = problem.model, problem.horizon
    Q = finite_array(configurations, "configurations", (H + 1, m.nq))
    V = finite_array(velocities, "velocities", (H + 1, m.nv))
    U = finite_array(controls, "controls", (H, problem.nu))
    mu = float(problem.costs.mu if mu is None else mu)
    if not (np.isfinite(mu) and mu > 0):
        raise InputError("mu", f"expected a positive friction coefficient, got {mu!r}")
    friction_cone(mu, facets)  # checks facets
    ids = _feet_order(problem)
    col = {f: i for i, f in enumerate(ids)}
    nf = len(ids)
    d = m.createData()
    mass = float(pin.computeTotalMass(m))
    gravity = m.gravity.linear.copy()
    impulse = np.array([n.kind == "impulse" for n in problem.nodes])
    active = np.zeros((H, nf), dtype=bool)
    on_ground = np.zeros((H + 1, nf), dtype=bool)
    forces = np.zeros((H, nf, 3))
    torques = np.zeros((H, nf, 3))
    momentum = np.zeros((H, 3))
    for k, node in enumerate(problem.nodes):
        cols = [col[f] for f in node.feet]
        active[k, cols] = True
        on_ground[k, cols] = True
        if node.kind == "impulse":
            if k > 0 and problem.nodes[k - 1].kind == "contact":
                on_ground[k, [col[f] for f in problem.nodes[k - 1].feet]] = True
            ev = problem.dyn.impulse(Q[k], V[k], node.feet)
            pin.centerOfMass(m, d, Q[k], V[k])
            vcom = d.vcom[0].copy()
            pin.centerOfMass(m, d, Q[k], ev.v_next)
            momentum[k] = mass * (d.vcom[0] - vcom)
        else:
            ev = problem.dyn.contact(Q[k], V[k], U[k], node.feet)
            pin.centerOfMass(m, d, Q[k], V[k], ev.acc)
            momentum[k] = mass * (d.acom[0] - gravity)
        start = 0
        for c, n in zip(cols, problem.dyn.force_dims(node.feet)):  # (force,) or (force, torque) per foot
            forces[k, c] = ev.forces[start:start + 3]
            torques[k, c] = ev.forces[start + 3:start + n] if n == 6 else 0.0
            start += n
    on_ground[H, [col[f] for f in problem.terminal_node.feet]] = True
    positions = np.empty((H + 1, nf, 3))
    vels = np.empty((H + 1, nf, 3))
    for k in range(H + 1):
        pin.forwardKinematics(m, d, Q[k], V[k])
        pin.updateFramePlacements(m, d)
        for i, f in enumerate(ids):
            positions[k, i] = d.oMf[f].translation
            vels[k, i] = pin.getFrameVelocity(m, d, f, pin.LOCAL_WORLD_ALIGNED).linear
    return ContactForces(feet=tuple(m.frames[f].name for f in ids), frame_ids=tuple(ids), dt=float(problem.dt),
                         times=problem.dt * np.arange(H), impulse=impulse, active=active, on_ground=on_ground,
                         forces=forces, torques=torques, positions=positions, velocities=vels,
                         momentum_change=momentum, mass=mass, gravity=gravity, mu=mu, facets=int(facets))
