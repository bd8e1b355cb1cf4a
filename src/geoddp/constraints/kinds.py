"""Constraint kinds on the state: what each means, its value, Jacobian and contracted Hessian.

A constraint c(x_k) acts on the state at nodes k = 1..H (a path constraint; x_0 is given) or at
k = H only (a terminal constraint). Equalities ask c = 0, inequalities c <= 0, row by row.

Each kind is a small validated object of plain parameters (what a scene table or a user gives);
:meth:`Constraint.bind` ties it to a problem's model and returns a :class:`Bound` evaluator,
vectorised over N nodes, with

    value(q, v)            c (N, nc)
    derivatives(q, v, w)   c (N, nc), J (N, nc, nx), sum_i w[:, i] Hess c_i (N, nx, nx)

in the tangent coordinates the problem's linearisation uses for l_x: zeta = (dq, dv) through
``pin.integrate`` (right/local); on TSO(3) zeta = (eta, dOmega) with R exp(eta). The Hessian is the
symmetric second derivative along x exp(s zeta) (the (0)-Hessian of the paper's eq. trivdif), so
that it adds into l_xx as a cost's would. Values are in the units stated per kind: they are what
the constraint tolerance (``ConstraintOptions.constraint_tol``) is compared with.

Kinds (the scene ``type`` in brackets):

* :class:`PointingKeepOut` ("pointing_keep_out"): angle(R_f a, d) >= alpha at every node, as
  c = d.(R_f a) - cos(alpha) <= 0 (a, d unit: cosine units).
* :class:`JointLimits` ("joint_limits"): lower <= q_j <= upper for 1-dof revolute and prismatic
  joints (rad, m), lower <= v_j <= upper for any joint's velocity components; two rows a bound.
* :class:`FrameHalfspace` ("frame_halfspace"): n.p_f >= offset, as c = offset/|n| - n.p_f/|n|
  <= 0 (a signed distance, m).
* :class:`FrameSphereKeepOut` ("frame_sphere_keep_out"): |p_f - centre| >= radius, as
  c = (radius^2 - |p_f - centre|^2) / (2 radius) <= 0 (m; smooth everywhere, and equal to
  radius - |p_f - centre| to first order on the sphere).
* :class:`FramePlacementConstraint` ("frame_placement", terminal): log6(M_ref^-1 oMf) = 0, the
  frame_placement cost's residual (6 rows: m, rad).
* :class:`StateConstraint` ("state", terminal): difference(q_ref, q) = 0 and/or v - v_ref = 0.

On the satellite's TSO(3) backend the state is (R, Omega): the pointing constraint runs on closed
forms in R (numpy over the nodes); frame constraints run on Pinocchio's kinematics of the
satellite's one-body model with q the quaternion of R (the spherical root's tangent is the same
eta); the state constraint uses the SO(3) closed forms (log, Jr^-1 and its exact derivative).
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pinocchio as pin

from .. import kernels
from ..lie import SO3, joint_groups
from ..lie import product as cfg
from ..validate import InputError, bounded_float, finite_array, finite_float, positive_float, rotation_matrix
from .kinematics import FrameKinematics, sym

__all__ = ["Constraint", "Bound", "PointingKeepOut", "JointLimits", "FrameHalfspace", "FrameSphereKeepOut",
           "FramePlacementConstraint", "StateConstraint", "KINDS", "TERMINAL_ONLY"]


# ------------------------------------------------------------------ models


def _is_tso3(model: Any) -> bool:
    """True for the satellite's TSO(3) backend (states are rotation matrices, not configurations)."""
    from ..models.satellite import Satellite

    return isinstance(model, Satellite)


def _pin_model(model: Any, name: str) -> pin.Model:
    pm = getattr(model, "pin_model", None)
    if not isinstance(pm, pin.Model):
        raise InputError(name, f"expected a problem on a Pinocchio model (the satellite or a multibody), got a "
                         f"model of type {type(model).__name__}")
    return pm


def _configurations(model: Any, q: np.ndarray) -> np.ndarray:
    """Pinocchio configurations (N, nq) of a problem's states q: on TSO(3) the quaternions (x, y, z,
    w) of the rotations R (N, 3, 3) (the spherical root's q); elsewhere q itself."""
    if not _is_tso3(model):
        return np.ascontiguousarray(q, dtype=float)
    return np.array([pin.Quaternion(R).coeffs() for R in q])


def _frame_id(pm: pin.Model, frame: Any, name: str) -> int:
    from ..validate import closest

    if not isinstance(frame, str):
        raise InputError(name, f"expected a frame name (string), got {frame!r}")
    if not pm.existFrame(frame):
        names = [f.name for f in pm.frames if f.name != "universe"]
        guess = closest(frame, names)
        hint = f"; did you mean {guess!r}?" if guess else ""
        shown = ", ".join(repr(n) for n in names[:8]) + (f", ... ({len(names)} frames)" if len(names) > 8 else "")
        raise InputError(name, f"expected a frame of model {pm.name!r}, got {frame!r}{hint} (frames: {shown})")
    return int(pm.getFrameId(frame))


def _unit(x: Any, name: str) -> np.ndarray:
    a = finite_array(x, name, (3,))
    n = float(np.linalg.norm(a))
    if not n > 1e-12:
        raise InputError(name, f"expected a non-zero 3-vector (it is normalised), got {a.tolist()}")
    return a / n


def _pad(J: np.ndarray, nv: int, at: int = 0) -> np.ndarray:
    """(N, r, nv) blocks as (N, r, 2 nv) tangent-state Jacobians: dq columns (at = 0) or dv (at = nv)."""
    out = np.zeros(J.shape[:-1] + (2 * nv,))
    out[..., at:at + nv] = J
    return out


def _pad_hessian(S: np.ndarray, nv: int) -> np.ndarray:
    """(N, nv, nv) dq-dq blocks as (N, 2 nv, 2 nv)."""
    out = np.zeros((S.shape[0], 2 * nv, 2 * nv))
    out[:, :nv, :nv] = S
    return out


# ------------------------------------------------------------------ interfaces


class Bound:
    """A constraint bound to a model, evaluated on N nodes at once.

    Attributes:
        rows: nc, the number of scalar rows per node.
        equality: True for c = 0, False for c <= 0.
        labels: (nc,) what each row is (e.g. "shoulder_lift_joint upper").
        nx: tangent state dimension.
    """

    rows: int
    equality: bool
    labels: tuple[str, ...]
    nx: int

    def value(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """c (N, nc) at states q (N, ...), v (N, nv)."""
        return self.derivatives(q, v, None)[0]

    def derivatives(self, q: np.ndarray, v: np.ndarray, w: Any
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """c (N, nc), its Jacobian (N, nc, nx) and, for weights w (N, nc), the contracted Hessian
        sum_i w[:, i] Hess c_i (N, nx, nx), symmetric (None when w is None). ``w`` may also be a
        function of c (N, nc) returning the weights: the augmented Lagrangian's multiplier
        estimates depend on c, and a frame's kinematics are then computed once."""
        raise NotImplementedError


class Constraint:
    """Base class of the constraint kinds.

    Attributes:
        type: the scene ``type`` of the kind.
        equality: c = 0 (True) or c <= 0 (False).
        name: a label for the result (default the type).
    """

    type: str = ""
    equality: bool = False
    name: str = ""

    def bind(self, model: Any) -> Bound:
        """This constraint on ``model`` (a problem's model: :class:`geoddp.models.satellite.Satellite`
        or :class:`geoddp.models.multibody.Multibody`); InputError naming the parameter (a frame or
        a joint the model lacks)."""
        raise NotImplementedError

    def describe(self) -> dict[str, Any]:
        """JSON-ready parameters (what the result reports and the figures draw)."""
        raise NotImplementedError

    def __eq__(self, other: object) -> bool:
        # by value, as the scene specs that hold constraints compare (a file read twice is one scene)
        if not isinstance(other, Constraint):
            return NotImplemented
        return type(self) is type(other) and self.describe() == other.describe()

    __hash__ = None  # type: ignore[assignment]  # equal by value, mutable

    def _label(self, name: Any) -> str:
        if name is None:
            return self.type
        if not isinstance(name, str) or not name:
            raise InputError("name", f"expected a non-empty string, got {name!r}")
        return name


# ------------------------------------------------------------------ pointing


class PointingKeepOut(Constraint):
    """Keep a body axis at least ``min_angle_deg`` away from a world direction (an instrument that
    must never point near the Sun): angle(R_f a, d) >= alpha at every node, as

        c = d.(R_f a) - cos(alpha) <= 0   (a, d normalised; cosine units).

    Args:
        body_axis: (3,) the axis a in the frame's (body) coordinates; normalised.
        world_direction: (3,) the direction d in the world; normalised.
        min_angle_deg: alpha in degrees, in (0, 180).
        frame: the frame whose rotation R_f carries a; on the satellite None means the body (any
            frame of its model may be named); a multibody model needs one.
        name: label in the result.

    Derivatives (right/local, theta the frame's local rotation): dc/dtheta = a x b with b = R_f^T d,
    and the (0)-Hessian in theta sym(a b^T) - (a.b) I (from b^T hat(theta)^2 a); on a multibody
    through the frame's Jacobian and kinematic Hessian (:mod:`.kinematics`).
    """

    type = "pointing_keep_out"

    def __init__(self, body_axis: Any, world_direction: Any, min_angle_deg: Any, frame: str | None = None,
                 name: str | None = None) -> None:
        self.body_axis = _unit(body_axis, "body_axis")
        self.world_direction = _unit(world_direction, "world_direction")
        self.min_angle_deg = bounded_float(min_angle_deg, "min_angle_deg", 0.0, 180.0, False, False)
        if frame is not None and not isinstance(frame, str):
            raise InputError("frame", f"expected a frame name (string) or None, got {frame!r}")
        self.frame = frame
        self.name = self._label(name)
        self.cos_min = float(np.cos(np.radians(self.min_angle_deg)))

    def describe(self) -> dict[str, Any]:
        return {"type": self.type, "name": self.name, "body_axis": self.body_axis.tolist(),
                "world_direction": self.world_direction.tolist(), "min_angle_deg": self.min_angle_deg,
                "frame": self.frame}

    def bind(self, model: Any) -> Bound:
        pm = _pin_model(model, "model")
        if _is_tso3(model):
            a = self.body_axis
            if self.frame is not None:
                f = pm.frames[_frame_id(pm, self.frame, "frame")]
                if f.parentJoint != 1:
                    raise InputError("frame", f"expected a frame of the satellite's body, got {self.frame!r} "
                                     "(fixed in the world)")
                a = f.placement.rotation @ a  # the frame's axis in body coordinates
            return _PointingTSO3(a, self.world_direction, self.cos_min)
        if self.frame is None:
            raise InputError("frame", "expected the name of the frame that carries body_axis (a multibody model "
                             "has no default body)")
        return _PointingFrame(model, FrameKinematics(pm, _frame_id(pm, self.frame, "frame")), self.body_axis,
                              self.world_direction, self.cos_min)


class _PointingTSO3(Bound):
    """The pointing constraint on R (N, 3, 3) in closed form."""

    rows, equality, nx = 1, False, 6

    def __init__(self, a: np.ndarray, d: np.ndarray, cos_min: float) -> None:
        self.a, self.d, self.cos_min = a, d, cos_min
        self.labels = ("cos(angle) - cos(min_angle)",)

    def value(self, q, v):
        return (np.einsum("nji,j->ni", q, self.d) @ self.a - self.cos_min)[:, None]  # as derivatives(): b.a

    def derivatives(self, q, v, w):
        a = self.a
        b = np.einsum("nji,j->ni", q, self.d)  # R^T d
        c = (b @ a - self.cos_min)[:, None]
        J = np.zeros((q.shape[0], 1, 6))
        J[:, 0, :3] = np.cross(a, b)
        w = w(c) if callable(w) else w
        if w is None:
            return c, J, None
        Hth = sym(np.einsum("i,nj->nij", a, b)) - (b @ a)[:, None, None] * np.eye(3)
        Hw = np.zeros((q.shape[0], 6, 6))
        Hw[:, :3, :3] = w[:, 0, None, None] * Hth
        return c, J, Hw


class _PointingFrame(Bound):
    rows, equality = 1, False

    def __init__(self, model: Any, kin: FrameKinematics, a: np.ndarray, d: np.ndarray, cos_min: float) -> None:
        self.model, self.kin, self.a, self.d, self.cos_min = model, kin, a, d, cos_min
        self.nx = 2 * kin.nv
        self.labels = ("cos(angle) - cos(min_angle)",)

    def value(self, q, v):  # the forward kinematics alone; the same c as derivatives()
        R, _ = self.kin.placements(_configurations(self.model, q))
        return (R @ self.a @ self.d - self.cos_min)[:, None]

    def derivatives(self, q, v, w):
        Q = _configurations(self.model, q)
        frames = self.kin.jacobians(Q)
        c = (frames[0] @ self.a @ self.d - self.cos_min)[:, None]
        w = w(c) if callable(w) else w
        y, Jy, Hy = self.kin.vector(Q, self.a, None if w is None else w[:, :1] * self.d, frames)
        J = _pad(np.einsum("i,nij->nj", self.d, Jy)[:, None], self.kin.nv)
        return c, J, None if Hy is None else _pad_hessian(Hy, self.kin.nv)


# ------------------------------------------------------------------ obstacles


class _FramePointKind(Constraint):
    """Base of the constraints on a frame's origin p_f (world, m)."""

    def _frame(self, frame: Any) -> str:
        if not isinstance(frame, str) or not frame:
            raise InputError("frame", f"expected a frame name (string), got {frame!r}")
        return frame

    def bind(self, model: Any) -> Bound:
        pm = _pin_model(model, "model")
        return _FramePoint(model, FrameKinematics(pm, _frame_id(pm, self.frame, "frame")), self)

    def point_value(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """c (N,), dc/dp (N, 3), d2c/dp2 (3, 3) (constant for these kinds)."""
        raise NotImplementedError


class FrameHalfspace(_FramePointKind):
    """Keep a frame's origin on one side of a plane: n.p_f >= offset at every node, as the signed
    distance c = (offset - n.p_f) / |n| <= 0 (m).

    Args:
        frame: the frame (a multibody frame, or on the satellite any frame of its body).
        normal: (3,) n, pointing to the allowed side (normalised, offset scaled with it).
        offset: the plane's offset along n, m (the plane is n.p = offset).
        name: label in the result.
    """

    type = "frame_halfspace"

    def __init__(self, frame: str, normal: Any, offset: Any, name: str | None = None) -> None:
        self.frame = self._frame(frame)
        n = finite_array(normal, "normal", (3,))
        norm = float(np.linalg.norm(n))
        if not norm > 1e-12:
            raise InputError("normal", f"expected a non-zero 3-vector, got {n.tolist()}")
        self.normal, self.offset = n / norm, finite_float(offset, "offset") / norm
        self.name = self._label(name)

    def describe(self) -> dict[str, Any]:
        return {"type": self.type, "name": self.name, "frame": self.frame, "normal": self.normal.tolist(),
                "offset": self.offset}

    def point_value(self, p):
        N = p.shape[0]
        return self.offset - p @ self.normal, np.broadcast_to(-self.normal, (N, 3)), np.zeros((3, 3))


class FrameSphereKeepOut(_FramePointKind):
    """Keep a frame's origin outside a sphere: |p_f - centre| >= radius at every node, as

        c = (radius^2 - |p_f - centre|^2) / (2 radius) <= 0   (m),

    smooth everywhere (also at the centre, where radius - |p - centre| is not) and equal to
    radius - |p_f - centre| to first order on the sphere.

    Args:
        frame: the frame; centre: (3,) m, world; radius: > 0, m; name: label in the result.
    """

    type = "frame_sphere_keep_out"

    def __init__(self, frame: str, centre: Any, radius: Any, name: str | None = None) -> None:
        self.frame = self._frame(frame)
        self.centre = finite_array(centre, "centre", (3,))
        self.radius = positive_float(radius, "radius")
        self.name = self._label(name)

    def describe(self) -> dict[str, Any]:
        return {"type": self.type, "name": self.name, "frame": self.frame, "centre": self.centre.tolist(),
                "radius": self.radius}

    def point_value(self, p):
        e = p - self.centre
        r = self.radius
        return (r * r - np.einsum("ni,ni->n", e, e)) / (2.0 * r), -e / r, -np.eye(3) / r


class _FramePoint(Bound):
    rows, equality = 1, False

    def __init__(self, model: Any, kin: FrameKinematics, kind: _FramePointKind) -> None:
        self.model, self.kin, self.kind = model, kin, kind
        self.nx = 2 * kin.nv
        self.labels = (kind.type,)
        self.compiled = None
        if isinstance(kind, FrameSphereKeepOut):
            # c = (radius^2 - |p - centre|^2) / (2 radius) = radius / 2 - l / radius with
            # l = 1/2 |p - centre|^2: the compiled frame translation cost (weight 1) gives l, its
            # gradient and its exact Hessian at all nodes in one call of the kernels (the same
            # tangent coordinates; the Python path below agrees to round-off)
            from ..costs.multibody import FrameTranslation, MultibodyCostSum

            self.compiled = MultibodyCostSum([FrameTranslation(kin.model, kind.frame, kind.centre, 1.0)], kin.model,
                                             terminal=True)

    def _compiled(self, q, v, w):
        r = self.kind.radius
        Q, V = _configurations(self.model, q), np.ascontiguousarray(v, dtype=float)
        if w is False:  # the value alone
            return (0.5 * r - self.compiled.value(Q, V, None) / r)[:, None]
        d = self.compiled.derivatives(Q, V, None, gauss_newton=w is None)  # no kinematic Hessians without w
        c = (0.5 * r - d.l / r)[:, None]
        w = w(c) if callable(w) else w
        J = (-d.lx / r)[:, None]
        return c, J, None if w is None else -(w[:, 0, None, None] / r) * d.lxx

    def value(self, q, v):  # the forward kinematics alone; the same c as derivatives()
        if self.compiled is not None:
            return self._compiled(q, v, False)
        _, p = self.kin.placements(_configurations(self.model, q))
        return self.kind.point_value(p)[0][:, None]

    def derivatives(self, q, v, w):
        if self.compiled is not None:
            return self._compiled(q, v, w)
        Q = _configurations(self.model, q)
        frames = self.kin.jacobians(Q)
        c, dc, d2c = self.kind.point_value(frames[1])  # the point first: the Hessian's weights need dc/dp
        w = w(c[:, None]) if callable(w) else w
        _, Jp, Hp = self.kin.point(Q, None if w is None else w[:, :1] * dc, frames)
        J = _pad(np.einsum("ni,nij->nj", dc, Jp)[:, None], self.kin.nv)
        if w is None:
            return c[:, None], J, None
        Hw = Hp + w[:, 0, None, None] * np.einsum("nai,ab,nbj->nij", Jp, d2c, Jp)
        return c[:, None], J, _pad_hessian(Hw, self.kin.nv)


# ------------------------------------------------------------------ joints


def _pair(x: Any, name: str) -> tuple[float, float]:
    """(lower, upper) from a [lower, upper] pair of numbers (-inf / inf allowed for an open side)."""
    import numbers

    ok = isinstance(x, (list, tuple, np.ndarray)) and len(x) == 2 and all(
        isinstance(t, numbers.Real) and not isinstance(t, (bool, np.bool_)) for t in x)
    if not ok:
        raise InputError(name, f"expected a [lower, upper] pair of numbers, got {x!r}")
    lo, hi = float(x[0]), float(x[1])
    if np.isnan(lo) or np.isnan(hi) or lo == np.inf or hi == -np.inf:
        raise InputError(name, f"expected numbers with lower < inf and upper > -inf, got [{lo}, {hi}]")
    if lo > hi:
        raise InputError(name, f"expected lower <= upper, got [{lo}, {hi}] (contradictory limits)")
    return lo, hi


class JointLimits(Constraint):
    """Joint position and velocity limits at every node (two rows per bounded side):

        q_j - upper <= 0,  lower - q_j <= 0   (rad or m)      for ``joints`` / ``position``
        v_j - upper <= 0,  lower - v_j <= 0   (rad/s or m/s)  for ``velocity``

    Args:
        joints: {joint name: [lower, upper]} position limits of 1-dof revolute and prismatic joints
            (-inf / inf for an open side). A continuous (unbounded revolute) joint's angle has no
            global coordinate, and a spherical or free-flyer joint's configuration is a rotation or
            a pose: they are refused here, naming the joint (keep their frames out of regions
            with frame constraints instead).
        position: "urdf": the URDF's position limits of every 1-dof revolute and prismatic joint
            (those with finite limits; continuous, spherical and free-flyer joints have none and
            are skipped: ``skipped`` lists them); a joint also in ``joints`` takes the tighter bound.
        velocity: {joint name: [lower, upper]} on the joint's velocity components (each of them
            for a multi-dof joint: the body rates of a spherical joint, the twist of a free flyer).
        name: label in the result.
    """

    type = "joint_limits"

    def __init__(self, joints: Mapping[str, Any] | None = None, position: str | None = None,
                 velocity: Mapping[str, Any] | None = None, name: str | None = None) -> None:
        self.joints = self._table(joints, "joints")
        if position is not None and position != "urdf":
            raise InputError("position", f'expected "urdf" (the URDF\'s limits of every joint), got {position!r}')
        self.position = position
        self.velocity = self._table(velocity, "velocity")
        if not self.joints and position is None and not self.velocity:
            raise InputError("joints", 'expected at least one of joints, position = "urdf" or velocity')
        self.name = self._label(name)
        self.skipped: tuple[str, ...] = ()

    @staticmethod
    def _table(t: Any, name: str) -> dict[str, tuple[float, float]]:
        if t is None:
            return {}
        if not isinstance(t, Mapping):
            raise InputError(name, f"expected a table {{joint name = [lower, upper], ...}}, got {t!r}")
        return {str(k): _pair(val, f"{name}.{k}") for k, val in t.items()}

    def describe(self) -> dict[str, Any]:
        return {"type": self.type, "name": self.name, "joints": {k: list(v) for k, v in self.joints.items()},
                "position": self.position, "velocity": {k: list(v) for k, v in self.velocity.items()}}

    def bind(self, model: Any) -> Bound:
        from ..validate import closest

        pm = _pin_model(model, "model")
        groups = {g.name: g for g in joint_groups(pm)}
        names = list(groups)

        def group(j: str, where: str) -> cfg.JointGroup:
            if j not in groups:
                guess = closest(j, names)
                hint = f"; did you mean {guess!r}?" if guess else ""
                raise InputError(where, f"expected a joint of model {pm.name!r}, got {j!r}{hint} (joints: "
                                 f"{', '.join(names)})")
            return groups[j]

        rows: list[tuple[int, float, str]] = []  # (tangent-state index, sign, label); c = sign (x - bound)
        bounds: list[float] = []
        limits: dict[str, tuple[float, float, int]] = {}
        skipped = []
        if self.position == "urdf":
            for g in groups.values():
                lo, hi = float(pm.lowerPositionLimit[g.idx_q]), float(pm.upperPositionLimit[g.idx_q])
                finite = np.isfinite(lo) and np.isfinite(hi) and abs(lo) < 1e300 and abs(hi) < 1e300
                if g.kind != "vector" or g.nv != 1 or not finite:
                    skipped.append(g.name)
                    continue
                limits[g.name] = (lo, hi, g.idx_v)
            if not limits and not self.joints:
                raise InputError("position", f'"urdf": model {pm.name!r} has no 1-dof revolute or prismatic joint '
                                 f"with finite position limits (joints: {', '.join(names)})")
        for j, (lo, hi) in self.joints.items():
            g = group(j, f"joints.{j}")
            if g.kind != "vector" or g.nv != 1:
                what = {"so2": "continuous (its angle has no global coordinate: no position limits)",
                        "so3": "spherical (its configuration is a rotation)",
                        "se3": "a free flyer (its configuration is a pose)"}.get(g.kind, f"{g.nv}-dof")
                raise InputError(f"joints.{j}", f"expected a 1-dof revolute or prismatic joint, got joint {j!r}, "
                                 f"which is {what}; bound its frames with frame constraints instead")
            if j in limits:  # the tighter of the URDF's and the table's
                lo, hi = max(lo, limits[j][0]), min(hi, limits[j][1])
                if lo > hi:
                    raise InputError(f"joints.{j}", f"expected limits that meet the URDF's [{limits[j][0]}, "
                                     f"{limits[j][1]}], got none in common")
            limits[j] = (lo, hi, g.idx_v)
        nv = pm.nv
        for j, (lo, hi, iv) in limits.items():
            if np.isfinite(hi):
                rows.append((iv, 1.0, f"{j} upper"))
                bounds.append(hi)
            if np.isfinite(lo):
                rows.append((iv, -1.0, f"{j} lower"))
                bounds.append(lo)
        for j, (lo, hi) in self.velocity.items():
            g = group(j, f"velocity.{j}")
            for i in range(g.nv):
                suffix = f"[{i}]" if g.nv > 1 else ""
                if np.isfinite(hi):
                    rows.append((nv + g.idx_v + i, 1.0, f"{j}{suffix} velocity upper"))
                    bounds.append(hi)
                if np.isfinite(lo):
                    rows.append((nv + g.idx_v + i, -1.0, f"{j}{suffix} velocity lower"))
                    bounds.append(lo)
        if not rows:
            raise InputError("joints", "expected at least one finite bound")
        self.skipped = tuple(skipped)
        return _JointRows(model, nv, rows, np.array(bounds))


class _JointRows(Bound):
    """Rows c = sign (x_i - bound) on coordinates of the tangent state: linear in zeta (the joints
    are vector-space factors of the group), so the Hessian is exactly 0."""

    equality = False

    def __init__(self, model: Any, nv: int, rows: list[tuple[int, float, str]], bounds: np.ndarray) -> None:
        self.tso3 = _is_tso3(model)
        self.nv, self.nx = nv, 2 * nv
        self.rows = len(rows)
        self.index = np.array([r[0] for r in rows])
        self.sign = np.array([r[1] for r in rows])
        self.bounds = bounds
        self.labels = tuple(r[2] for r in rows)
        self.qidx = np.array([_q_index(model, i) if i < nv else -1 for i in self.index])
        self.J = np.zeros((self.rows, self.nx))
        self.J[np.arange(self.rows), self.index] = self.sign

    def _coordinates(self, q, v):
        N = v.shape[0]
        x = np.empty((N, self.rows))
        pos = self.index < self.nv
        if pos.any():
            x[:, pos] = q[:, self.qidx[pos]]
        x[:, ~pos] = v[:, self.index[~pos] - self.nv]
        return x

    def derivatives(self, q, v, w):
        c = self.sign * (self._coordinates(q, v) - self.bounds)
        J = np.broadcast_to(self.J, (c.shape[0],) + self.J.shape).copy()
        return c, J, None if w is None else np.zeros((c.shape[0], self.nx, self.nx))

    def value(self, q, v):
        return self.sign * (self._coordinates(q, v) - self.bounds)


def _q_index(model: Any, iv: int) -> int:
    """The configuration index of a 1-dof vector joint's tangent index iv."""
    pm = model.pin_model
    for g in joint_groups(pm):
        if g.kind == "vector" and g.idx_v <= iv < g.idx_v + g.nv:
            return g.idx_q + (iv - g.idx_v)
    raise InputError("joints", f"tangent index {iv} is not on a vector joint")  # not reached: checked in bind


# ------------------------------------------------------------------ terminal equalities


class FramePlacementConstraint(Constraint):
    """Reach a frame placement exactly: log6(M_ref^-1 oMf(q)) = 0 (6 rows, [linear (m); angular
    (rad)]), the residual of the frame_placement cost (:class:`geoddp.costs.multibody.FramePlacement`)
    made an equality, satisfied to the constraint tolerance instead of approached by a weight.

    Args:
        frame: the frame.
        placement: (4, 4) homogeneous target placement (or a ``pin.SE3``).
        name: label in the result.

    The log6 has a cut locus at a relative rotation of pi. Derivatives: :meth:`FrameKinematics.log6`.
    """

    type = "frame_placement"
    equality = True

    def __init__(self, frame: str, placement: Any, name: str | None = None) -> None:
        if not isinstance(frame, str) or not frame:
            raise InputError("frame", f"expected a frame name (string), got {frame!r}")
        self.frame = frame
        M = placement.homogeneous if isinstance(placement, pin.SE3) else placement
        M = finite_array(M, "placement", (4, 4))
        if not np.array_equal(M[3], [0.0, 0.0, 0.0, 1.0]):
            raise InputError("placement", f"expected a homogeneous transform with last row [0, 0, 0, 1], got {M[3]}")
        rotation_matrix(M[:3, :3], "placement (rotation)")
        self.placement = M
        self.name = self._label(name)

    def describe(self) -> dict[str, Any]:
        return {"type": self.type, "name": self.name, "frame": self.frame, "placement": self.placement.tolist()}

    def bind(self, model: Any) -> Bound:
        pm = _pin_model(model, "model")
        return _Placement(model, FrameKinematics(pm, _frame_id(pm, self.frame, "frame")), self.placement)


class _Placement(Bound):
    rows, equality = 6, True
    labels = ("x", "y", "z", "rx", "ry", "rz")

    def __init__(self, model: Any, kin: FrameKinematics, M: np.ndarray) -> None:
        self.model, self.kin, self.M = model, kin, M
        self.nx = 2 * kin.nv

    def value(self, q, v):  # the forward kinematics alone; the same r as derivatives()
        return self.kin.log6_value(_configurations(self.model, q), self.M)

    def derivatives(self, q, v, w):
        r, J, H = self.kin.log6(_configurations(self.model, q), self.M, w)
        return r, _pad(J, self.kin.nv), None if H is None else _pad_hessian(H, self.kin.nv)


class StateConstraint(Constraint):
    """Reach a state exactly: difference(q_ref, q) = 0 (nv rows: the log of q_ref^-1 q joint by
    joint, rad or m) and/or v - v_ref = 0 (nv rows).

    Args:
        q: (nq,) target configuration (normalised quaternions; on the satellite the quaternion
            (x, y, z, w) of the target attitude, or a (3, 3) rotation), or None (velocity only).
        v: (nv,) target velocity, or None (configuration only).
        name: label in the result.

    Derivatives: Jr(r_j)^-1 per non-commutative joint (spherical, free flyer), identity elsewhere;
    the Hessian's only part is the log's second-order term, -Ji^T D_g Ji with g = Ji^T w
    (:mod:`.kinematics`), exact near the identity and up to pi.
    """

    type = "state"
    equality = True

    def __init__(self, q: Any = None, v: Any = None, name: str | None = None) -> None:
        if q is None and v is None:
            raise InputError("q", "expected a target configuration q and/or velocity v, got neither")
        self.q = None if q is None else finite_array(q, "q")
        self.v = None if v is None else finite_array(v, "v", (None,))
        self.name = self._label(name)

    def describe(self) -> dict[str, Any]:
        return {"type": self.type, "name": self.name, "q": None if self.q is None else self.q.tolist(),
                "v": None if self.v is None else self.v.tolist()}

    def bind(self, model: Any) -> Bound:
        pm = _pin_model(model, "model")
        nq, nv = (4, 3) if _is_tso3(model) else (pm.nq, pm.nv)
        q_ref = None
        if self.q is not None:
            if _is_tso3(model) and self.q.shape == (3, 3):
                q_ref = rotation_matrix(self.q, "q")
            else:
                if self.q.shape != (nq,):
                    raise InputError("q", f"expected shape ({nq},) (the model's nq), got shape {self.q.shape}")
                if not pin.isNormalized(pm, self.q, 1e-9):
                    raise InputError("q", "expected a configuration with unit quaternions (to 1e-9)")
                q_ref = pin.Quaternion(self.q).toRotationMatrix() if _is_tso3(model) else self.q
        if self.v is not None and self.v.shape != (nv,):
            raise InputError("v", f"expected shape ({nv},) (the model's nv), got shape {self.v.shape}")
        return _State(model, pm, q_ref, self.v)


class _State(Bound):
    equality = True

    def __init__(self, model: Any, pm: pin.Model, q_ref: np.ndarray | None, v_ref: np.ndarray | None) -> None:
        self.tso3 = _is_tso3(model)
        self.pm, self.q_ref, self.v_ref = pm, q_ref, v_ref
        self.nv = 3 if self.tso3 else pm.nv
        self.nx = 2 * self.nv
        self.groups = cfg.SO3_ROOT if self.tso3 else tuple(joint_groups(pm))
        labels = []
        if q_ref is not None:
            labels += [f"q[{i}]" for i in range(self.nv)]
        if v_ref is not None:
            labels += [f"v[{i}]" for i in range(self.nv)]
        self.labels = tuple(labels)
        self.rows = len(labels)

    def _log(self, q: np.ndarray) -> np.ndarray:
        """difference(q_ref, q) (N, nv)."""
        if self.tso3:
            return SO3.log_batch(np.einsum("ji,njk->nik", self.q_ref, q))
        return np.array([cfg.difference(self.pm, list(self.groups), self.q_ref, qk) for qk in q])

    def derivatives(self, q, v, w):
        N, nv = v.shape[0], self.nv
        c = np.zeros((N, self.rows))
        J = np.zeros((N, self.rows, self.nx))
        row = 0
        r = self._log(q) if self.q_ref is not None else None
        if r is not None:
            c[:, :nv] = r
            row = nv
        if self.v_ref is not None:
            c[:, row:row + nv] = v - self.v_ref
            J[:, row:row + nv, nv:] = np.eye(nv)
        w = w(c) if callable(w) else w
        Hw = None if w is None else np.zeros((N, self.nx, self.nx))
        if r is not None:
            J[:, :nv, :nv] = np.eye(nv)
            for g in self.groups:
                G = cfg.NONCOMMUTATIVE.get(g.kind)
                if G is None:
                    continue  # vector and SO(2) factors: the difference is linear in dq
                s = g.slice
                Ji = np.array([G.right_jacobian_inv(x) for x in r[:, s]])
                J[:, s, s] = Ji
                if w is not None:
                    # r(s) = x + Ji dq - 1/2 Ji dJr(x)[Ji dq] (Ji dq): sum_i w_i Hess r_i = -Ji^T D_g Ji
                    D = _jr_derivative(g.kind, r[:, s])
                    gw = np.einsum("npi,np->ni", Ji, w[:, s])
                    Dg = np.einsum("np,npab->nab", gw, D)
                    Hw[:, s, s] = -sym(np.einsum("nai,nab,nbj->nij", Ji, Dg, Ji))
        return c, J, Hw


def _jr_derivative(kind: str, X: np.ndarray) -> np.ndarray:
    """D (N, d, d, d), D[n, p, a, b] = d Jr(x_n)[p, a] / dx_b, exact (SO(3) closed form, SE(3) the
    compiled core's dual numbers)."""
    if kind == "so3":
        return SO3.right_jacobian_derivative_batch(X)
    return np.array([kernels.core.se3_jr_derivative(np.ascontiguousarray(x)).reshape(6, 6, 6) for x in X])


#: scene type -> class
KINDS: dict[str, type[Constraint]] = {c.type: c for c in (PointingKeepOut, JointLimits, FrameHalfspace,
                                                          FrameSphereKeepOut, FramePlacementConstraint,
                                                          StateConstraint)}
#: the equality kinds: a path equality would pin the state at every node, so they are terminal only
TERMINAL_ONLY = ("frame_placement", "state")
