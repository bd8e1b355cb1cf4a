"""The configuration space of a Pinocchio model as a product of joint Lie groups.

Pinocchio's ``integrate(model, q, v)`` acts joint by joint: q_j+ = q_j exp(v_j) on each joint's
group, with v_j the joint's slice ``v[idx_v : idx_v + nv]`` of the tangent vector. The
configuration space is therefore a product group, and every object the exact second-order
reconstruction of :mod:`geoddp.integrators` needs is block-diagonal over joints:

    eta+ = Ad_A eta + Jr(omega) rho + 1/2 dJr(omega)[rho] rho + 1/2 [Ad_A eta, Jr(omega) rho] + O(3)

with omega = dt w_bar, A = exp(-omega), rho = dt delta w (derived for any Lie group in the
module docstring of :mod:`geoddp.integrators`). The joint groups Pinocchio uses are

* ``"vector"``: R^k with addition (revolute and prismatic joints, translation, SphericalZYX,
  which Pinocchio integrates additively), and ``"so2"``: revolute-unbounded joints, (cos, sin)
  coordinates. Both are commutative: Ad = I, Jr = I, dJr = 0 and the bracket vanishes, so the
  reconstruction is exactly linear.
* ``"so3"``: the spherical joint; quaternion coordinates, body-frame tangent (3,), ad = hat,
  Jr, dJr from :class:`geoddp.lie.SO3`.
* ``"se3"``: the free-flyer joint; q = (translation, quaternion), body-frame twists (6,) in
  Pinocchio's [linear; angular] order, q+ = q exp6(v); ad = ``Motion(x).action``,
  Jr from :meth:`geoddp.lie.SE3.right_jacobian`, dJr by central differences of it (see
  :func:`se3_dJr`).

Why our own Jr rather than ``pin.Jexp6`` / ``dIntegrate(ARG1)`` / ``dDifference``: Pinocchio 4.1
loses up to 3e-5 absolute in the SE(3) Jacobians' coupling block for joint rotations between
1e-5 and 1e-2 rad (see :meth:`geoddp.lie.SE3.right_jacobian`), exactly the small per-step
rotations a trajectory produces. The functions here are exact to round-off (tested).

Other joints (planar = SE(2), composite, mimic) are refused with an error naming the joint.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from . import kernels
from .lie import SE3, SO3, hat

_VECTOR_SHORTNAMES = frozenset(
    ["JointModelR" + a for a in "XYZ"]
    + ["JointModelP" + a for a in "XYZ"]
    + [
        "JointModelRevoluteUnaligned",
        "JointModelPrismaticUnaligned",
        "JointModelTranslation",
        "JointModelSphericalZYX",
    ]
)
_SO2_SHORTNAMES = frozenset(["JointModelRUB" + a for a in "XYZ"] + ["JointModelRevoluteUnboundedUnaligned"])
KINDS = ("vector", "so2", "so3", "se3")

# Structure constants C[i, p, q] = [e_p, e_q]_i of each non-commutative joint algebra.
_SO3_C = np.moveaxis(hat(np.eye(3)), 0, 1)  # hat(e_p) e_q = e_p x e_q; C[i, p, q] = hat(e_p)[i, q]
_SE3_C = np.stack([pin.Motion(e).action for e in np.eye(6)], axis=1)  # C[:, p, :] = ad_{e_p}

# Central-difference step for dJr of SE(3): truncation ~ h^2 |Jexp6'''| / 6 ~ 1e-11,
# round-off ~ 1e-16 / h ~ 1e-11 (tested against Richardson extrapolation).
_SE3_DJR_STEP = 1e-5


@dataclass(frozen=True)
class JointGroup:
    """One joint's Lie group: its name, kind (one of :data:`KINDS`), tangent slice and the
    start of its configuration coordinates (idx_q)."""

    name: str
    kind: str
    idx_v: int
    nv: int
    idx_q: int = -1

    @property
    def slice(self) -> slice:
        return slice(self.idx_v, self.idx_v + self.nv)


def symmetric_from_upper(M: np.ndarray) -> np.ndarray:
    """The symmetric matrices (..., n, n) whose upper triangles are those of M: Pinocchio fills
    only the upper triangle of the mass matrix (``crba``) and of ``Minv``."""
    return np.triu(M) + np.swapaxes(np.triu(M, 1), -1, -2)


def joint_groups(model: pin.Model) -> list[JointGroup]:
    """The joint groups of ``model`` in tangent order (the universe joint 0 is skipped).

    Raises:
        ValueError: a joint whose group is not one of :data:`KINDS` (e.g. planar = SE(2)).
    """
    out = []
    for j in range(1, model.njoints):
        jm = model.joints[j]
        short = jm.shortname()
        if short in _VECTOR_SHORTNAMES:
            kind = "vector"
        elif short in _SO2_SHORTNAMES:
            kind = "so2"
        elif short == "JointModelSpherical":
            kind = "so3"
        elif short == "JointModelFreeFlyer":
            kind = "se3"
        else:
            raise ValueError(
                f"joint {model.names[j]!r} of type {short} is not supported "
                f"(supported: revolute, continuous, prismatic, spherical, free-flyer)"
            )
        out.append(JointGroup(model.names[j], kind, jm.idx_v, jm.nv, jm.idx_q))
    return out


def difference(model: pin.Model, groups: list[JointGroup], q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """log(q0^-1 q1) per joint, (nv,): ``pin.difference`` with exact SO(2) entries.

    Why: Pinocchio 4.1's SO(2) log returns 0 whenever the rounded trace of the relative rotation
    exceeds 2, i.e. for some angles below ~1e-8 (measured: up to 5e-9 returned as 0), which
    spoils finite differences. atan2 of the relative (cos, sin) is exact there.
    """
    d = pin.difference(model, q0, q1)
    for g in groups:
        if g.kind == "so2":
            c0, s0 = q0[g.idx_q], q0[g.idx_q + 1]
            c1, s1 = q1[g.idx_q], q1[g.idx_q + 1]
            d[g.idx_v] = np.arctan2(c0 * s1 - s0 * c1, c0 * c1 + s0 * s1)
    return d


def se3_dJr(x: np.ndarray) -> np.ndarray:
    """D (6, 6, 6) with D[i, j, l] = d Jr(x)[i, j] / d x_l for SE(3).

    Central differences of the closed-form :meth:`geoddp.lie.SE3.right_jacobian` (error ~1e-10,
    tested); x (6,) [linear; angular].
    """
    return se3_dJr_batch(np.asarray(x, dtype=float)[None])[0]


def se3_dJr_batch(X: np.ndarray) -> np.ndarray:
    """:func:`se3_dJr` at N points: X (N, 6) -> (N, 6, 6, 6), one flat pass of the closed-form Jr."""
    X = np.asarray(X, dtype=float)
    h = _SE3_DJR_STEP
    steps = h * np.eye(6)
    pts = np.stack([X[:, None, :] + steps, X[:, None, :] - steps], axis=1).reshape(-1, 6)  # [n, sign, l]
    J = np.array([SE3.right_jacobian(x) for x in pts]).reshape(X.shape[0], 2, 6, 6, 6)  # [n, sign, l, i, j]
    return np.moveaxis((J[:, 0] - J[:, 1]) / (2.0 * h), 1, -1)


def block_Ad_Jr(groups: list[JointGroup], nv: int, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ad_{exp(-omega)} and Jr(omega), each (nv, nv) block-diagonal; omega (nv,).

    These are ``pin.dIntegrate(model, q, omega, ARG0 / ARG1)``, with Jr exact to round-off
    where Pinocchio's SE(3) block is not (module docstring; tested against the series).
    """
    A = np.eye(nv)
    J = np.eye(nv)
    for g in groups:
        s, w = g.slice, omega[g.slice]
        if g.kind == "so3":
            A[s, s] = pin.exp3(w).T
            J[s, s] = kernels.so3_right_jacobian(w, False)
        elif g.kind == "se3":
            A[s, s] = pin.exp6(-w).action
            J[s, s] = SE3.right_jacobian(w)
    return A, J


def block_Jr_inv(groups: list[JointGroup], nv: int, omega: np.ndarray) -> np.ndarray:
    """Jr(omega)^-1, (nv, nv) block-diagonal; omega (nv,), rotations below 2 pi per joint."""
    K = np.eye(nv)
    for g in groups:
        s, w = g.slice, omega[g.slice]
        if g.kind == "so3":
            K[s, s] = SO3.right_jacobian_inv(w)
        elif g.kind == "se3":
            K[s, s] = SE3.right_jacobian_inv(w)
    return K


def difference_jacobian(model: pin.Model, groups: list[JointGroup], q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """d difference(q0, q1 exp(d)) / dd at d = 0, (nv, nv): Jr(difference(q0, q1))^-1 per joint.

    ``pin.dDifference(model, q0, q1, ARG1)``, exact near q0 = q1 where Pinocchio's SE(3) block
    is not (module docstring).
    """
    return block_Jr_inv(groups, model.nv, difference(model, groups, q0, q1))


def group_second_order_tensors(kind: str, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One non-commutative joint group's dJr at N points and its structure constants.

    kind: "so3" or "se3"; omega (N, d) -> D (N, d, d, d) with D[n, i, j, l] = d Jr(omega_n)[i, j]
    / d omega_l, and C (d, d, d) with [x, y]_i = C[i, p, q] x_p y_q. Vector and SO(2) joints
    have D = 0 and C = 0 (commutative).
    """
    if kind == "so3":
        return SO3.right_jacobian_derivative_batch(omega), _SO3_C
    if kind == "se3":
        return se3_dJr_batch(omega), _SE3_C
    raise ValueError(f"expected a non-commutative group kind ('so3' or 'se3'), got {kind!r}")


def second_order_tensors(groups: list[JointGroup], nv: int, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The reconstruction's second-order ingredients at omega (nv,), block-diagonal over joints.

    Returns:
        D (nv, nv, nv): D[i, j, l] = d Jr(omega)[i, j] / d omega_l, so that
            exp(omega + rho) = exp(omega) exp(Jr rho + 1/2 D(rho, rho) + O(3)).
        C (nv, nv, nv): structure constants, [x, y]_i = C[i, p, q] x_p y_q (zero across joints).
    """
    D = np.zeros((nv, nv, nv))
    C = np.zeros((nv, nv, nv))
    for g in groups:
        if g.kind in ("so3", "se3"):
            s = g.slice
            Dg, Cg = group_second_order_tensors(g.kind, omega[None, s])
            D[s, s, s] = Dg[0]
            C[s, s, s] = Cg
    return D, C
