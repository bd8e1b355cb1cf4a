"""The configuration space of a Pinocchio model as a product of joint Lie groups.

Pinocchio's ``integrate(model, q, v)`` acts joint by joint: q_j+ = q_j exp(v_j) on each joint's
group, with v_j the joint's slice ``v[idx_v : idx_v + nv]`` of the tangent vector. The
configuration space is therefore a product group, and every object the exact second-order
reconstruction of :mod:`geoddp.models.integrators` needs is block-diagonal over joints:

    eta+ = Ad_A eta + Jr(omega) rho + 1/2 dJr(omega)[rho] rho + 1/2 [Ad_A eta, Jr(omega) rho] + O(3)

with omega = dt w_bar, A = exp(-omega), rho = dt delta w (derived for any Lie group in the
module docstring of :mod:`geoddp.models.integrators`, which assembles it once, for any product of the
groups here: :func:`geoddp.models.integrators.expand`). A product group is a sequence of
:class:`JointGroup` factors in tangent order (:func:`joint_groups` reads it off a ``pin.Model``);
the functions below are its operations. The joint groups Pinocchio uses are

* ``"vector"``: R^k with addition (revolute and prismatic joints, translation), and ``"so2"``:
  revolute-unbounded joints, (cos, sin) coordinates. Both are commutative: Ad = I, Jr = I,
  dJr = 0 and the bracket vanishes, so the reconstruction is exactly linear.
* ``"so3"``: the spherical joint; quaternion coordinates, body-frame tangent (3,), ad = hat,
  Jr, dJr from :class:`geoddp.lie.SO3`.
* ``"se3"``: the free-flyer joint; q = (translation, quaternion), body-frame twists (6,) in
  Pinocchio's [linear; angular] order, q+ = q exp6(v); ad = ``Motion(x).action``,
  Jr from :meth:`geoddp.lie.SE3.right_jacobian`, dJr by central differences of it
  (:meth:`geoddp.lie.SE3.right_jacobian_derivative_batch`).

The satellite's state space TSO(3) = SO(3) x R^3 is the instance with one spherical factor
(:data:`SO3_ROOT`) and its velocities: :class:`TSO3`.

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

from .se3 import SE3
from .so3 import SO3

_VECTOR_SHORTNAMES = frozenset(
    ["JointModelR" + a for a in "XYZ"]
    + ["JointModelP" + a for a in "XYZ"]
    + [
        "JointModelRevoluteUnaligned",
        "JointModelPrismaticUnaligned",
        "JointModelTranslation",
    ]
)
_SO2_SHORTNAMES = frozenset(["JointModelRUB" + a for a in "XYZ"] + ["JointModelRevoluteUnboundedUnaligned"])
KINDS = ("vector", "so2", "so3", "se3")
#: the non-commutative joint groups; "vector" and "so2" have Ad = Jr = I and dJr = [.,.] = 0
NONCOMMUTATIVE = {"so3": SO3, "se3": SE3}


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


def joint_groups(model: pin.Model) -> list[JointGroup]:
    """The joint groups of ``model`` in tangent order (the universe joint 0 is skipped).

    Raises:
        ValueError: a joint whose group is not one of :data:`KINDS` (e.g. planar = SE(2)), or whose
            motion subspace moves with q (spherical ZYX, universal, helical): Pinocchio's analytic
            RNEA and ABA derivatives do not hold for spherical ZYX (measured against differences,
            tests/test_core_dynamics.py), and every accepted joint's subspace is constant in its
            own frame.
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


def block_Ad_Jr(groups: list[JointGroup], nv: int, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ad_{exp(-omega)} and Jr(omega), each (nv, nv) block-diagonal; omega (nv,).

    These are ``pin.dIntegrate(model, q, omega, ARG0 / ARG1)``, with Jr exact to round-off
    where Pinocchio's SE(3) block is not (module docstring; tested against the series).
    """
    A = np.eye(nv)
    J = np.eye(nv)
    for g in groups:
        G = NONCOMMUTATIVE.get(g.kind)
        if G is not None:
            s, w = g.slice, omega[g.slice]
            A[s, s] = G.Ad_exp_neg(w)
            J[s, s] = G.right_jacobian(w)
    return A, J


def block_Jr_inv(groups: list[JointGroup], nv: int, omega: np.ndarray) -> np.ndarray:
    """Jr(omega)^-1, (nv, nv) block-diagonal; omega (nv,), rotations below 2 pi per joint."""
    K = np.eye(nv)
    for g in groups:
        G = NONCOMMUTATIVE.get(g.kind)
        if G is not None:
            K[g.slice, g.slice] = G.right_jacobian_inv(omega[g.slice])
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
    G = NONCOMMUTATIVE.get(kind)
    if G is not None:
        return G.right_jacobian_derivative_batch(omega), G.structure_constants
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
        if g.kind in NONCOMMUTATIVE:
            s = g.slice
            Dg, Cg = group_second_order_tensors(g.kind, omega[None, s])
            D[s, s, s] = Dg[0]
            C[s, s, s] = Cg
    return D, C


#: SO(3) as a product group: one spherical joint (the satellite's configuration space)
SO3_ROOT: tuple[JointGroup, ...] = (JointGroup("root_joint", "so3", 0, 3, 0),)


class TSO3:
    """The satellite state space G = SO(3) x R^3 with g = (R, Omega) (paper, Section IV).

    The configuration factor is the product group :data:`SO3_ROOT` (R as a rotation matrix rather
    than Pinocchio's quaternion); the velocity factor is R^3 with addition.

    Tangent vectors are the paper's zeta = (eta, delta_xi) stacked as (6,): the first block acts
    on SO(3) by right multiplication, the second on R^3 by addition. This is the one place the
    ordering is defined.
    """

    nx = 6
    ETA = slice(0, 3)
    XI = slice(3, 6)

    @staticmethod
    def retract(R: np.ndarray, Omega: np.ndarray, zeta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """g exp(zeta) = (R exp(eta), Omega + delta_xi)."""
        zeta = np.asarray(zeta, dtype=float)
        return R @ SO3.exp(zeta[TSO3.ETA]), Omega + zeta[TSO3.XI]

    @staticmethod
    def local(R_bar: np.ndarray, Omega_bar: np.ndarray, R: np.ndarray, Omega: np.ndarray) -> np.ndarray:
        """zeta = log(g_bar^-1 g) = (log(R_bar^T R), Omega - Omega_bar), (6,)."""
        return np.concatenate([SO3.log(R_bar.T @ R), Omega - Omega_bar])
