"""The tests' oracle of the multibody cost terms: the Python code geoddp ran before its compiled
kernels (cpp/costs/costs.cpp), kept here to check them against.

It evaluates the package's own term objects (:mod:`geoddp.costs.multibody`: their models, frames,
references and weights) in numpy over Pinocchio's Python calls, node by node. Residual terms
l = 1/2 r^T W r have

    l_x  = J_r^T W r
    l_xx = J_r^T W J_r  (Gauss-Newton part)  +  sum_k (W r)_k Hess r_k  (second-order part),

the second-order part as central differences, along each tangent direction e_j, of
q -> J_r(q)^T w with w = W r frozen at the base point, then symmetrised: it is exactly zero where
W r = 0, as in the kernels, and its error scales with |W r| (O(h^2), h = 1e-5: ~1e-8 relative
against the 4-point value stencil of tests/test_multibody_costs.py). The kernels' second-order
parts are exact (Pinocchio's kinematic Hessians, the closed-form derivative of Jr).

:func:`use_cost_oracle` makes every :class:`MultibodyCostSum` evaluate through this module for the
rest of a test (the multibody oracle's ``use_oracle`` calls it); :class:`OracleCostSum` is one sum
on it.
"""
from __future__ import annotations

import weakref

import numpy as np
import pinocchio as pin

from geoddp.costs import CostDerivatives
from geoddp.lie import SE3, SO3
from geoddp.lie import product as cfg
from geoddp.costs.multibody import (
    ControlRegularisation,
    FramePlacement,
    FrameRotation,
    FrameRotationChordal,
    FrameTranslation,
    MultibodyCostSum,
    StateRegularisation,
)

# Central-difference step for the second-order part (rad or m of tangent motion): balances the
# O(h^2) truncation of the analytic gradient's difference against eps/h round-off.
FD_STEP = 1e-5

FRAME_TERMS = (FramePlacement, FrameRotationChordal, FrameRotation, FrameTranslation)
BUILT_IN = (*FRAME_TERMS, StateRegularisation, ControlRegularisation)

# one pinocchio Data per term, made once (model apart from data, as in the package)
_DATA: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _data(term) -> pin.Data:
    data = _DATA.get(term)
    if data is None:
        data = _DATA[term] = term.model.createData()
    return data


def _pick(ref: np.ndarray, N: int) -> np.ndarray:
    """Per-node references (N, ...) from a stack of 1 (broadcast) or N."""
    return np.broadcast_to(ref, (N,) + ref.shape[1:]) if ref.shape[0] == 1 else ref


def curved_dofs(model: pin.Model) -> np.ndarray:
    """Tangent indices of the joints whose configuration space is not a vector space (free
    flyer, spherical, planar, unbounded revolute): the only ones where ``difference`` has a
    second-order part."""
    return np.array([j.idx_v + i for j in model.joints[1:] if j.nq != j.nv for i in range(j.nv)], dtype=int)


# --------------------------------------------------------------------------------------
# frame terms


def _kinematics(term, q: np.ndarray, jac: bool):
    """World placement oMf of the term's frame and, with jac, its LOCAL Jacobian (6, nv).

    The LOCAL Jacobian is the right-trivialised one: oMf(integrate(q, s dq)) =
    oMf(q) exp6(s J dq) + O(s^2), [linear; angular] rows (checked by the tests).
    """
    model, data = term.model, _data(term)
    if jac:
        pin.computeJointJacobians(model, data, q)  # also runs forward kinematics
        oMf = pin.updateFramePlacement(model, data, term.frame_id)
        return oMf, pin.getFrameJacobian(model, data, term.frame_id, pin.LOCAL)
    pin.forwardKinematics(model, data, q)
    return pin.updateFramePlacement(model, data, term.frame_id), None


def _relative_rotation(term, q: np.ndarray, k: int, jac: bool):
    """E = R_ref^T R_frame(q) of node k and, with jac, the frame's LOCAL Jacobian."""
    oMf, J = _kinematics(term, q, jac)
    Rref = term.R_ref[k if len(term.R_ref) > 1 else 0]
    # the exact identity at the reference: r and l_x exactly 0 there (R_ref^T R would leave ~1e-16)
    return (np.eye(3) if np.array_equal(oMf.rotation, Rref) else Rref.T @ oMf.rotation), J


def residual(term, q: np.ndarray, k: int, jac: bool):
    """A frame term's residual r (nr,) at node k and, with jac, J_r = dr/d(dq) (nr, nv)."""
    kind = type(term)
    if kind is FramePlacement:
        oMf, J = _kinematics(term, q, jac)
        kk = k if len(term.M_ref) > 1 else 0
        Mref = term.M_ref[kk]
        if np.array_equal(oMf.rotation, Mref[:3, :3]):
            E = pin.SE3(np.eye(3), Mref[:3, :3].T @ (oMf.translation - Mref[:3, 3]))  # exact 0 at the reference
        else:
            E = pin.SE3(Mref).inverse() * oMf
        r = pin.log6(E).vector
        return r, (SE3.right_jacobian_inv(r) @ J if jac else None)  # pin.Jlog6, exact near the target
    if kind is FrameRotation:
        E, J = _relative_rotation(term, q, k, jac)
        r = pin.log3(E)
        # R(q exp(s dq)) = R exp(s J_ang dq): the angular LOCAL rows
        return r, (SO3.right_jacobian_inv(r) @ J[3:6] if jac else None)
    if kind is FrameRotationChordal:
        # r = (I - E) column by column (9,), weight blockdiag(S, S, S); dr/dtheta_a = -vec(E hat(e_a))
        E, J = _relative_rotation(term, q, k, jac)
        r = (np.eye(3) - E).T.reshape(9)
        if not jac:
            return r, None
        dr = -np.stack([(E @ pin.skew(e)).T.reshape(9) for e in np.eye(3)], axis=1)  # (9, 3)
        return r, dr @ J[3:6]
    if kind is FrameTranslation:
        oMf, J = _kinematics(term, q, jac)
        r = oMf.translation - term.p_ref[k if len(term.p_ref) > 1 else 0]
        # the LOCAL linear rows give the velocity in the frame's axes; rotate to the world
        return r, (oMf.rotation @ J[0:3] if jac else None)
    raise TypeError(f"no oracle for {kind.__name__}")


def _frame_second_order(term, q: np.ndarray, k: int, w: np.ndarray) -> np.ndarray:
    """(nv, nv) sym(sum_k w_k Hess r_k): central differences of J_r(q)^T w, w frozen."""
    nv = term.model.nv
    H = np.empty((nv, nv))
    e = np.zeros(nv)
    for j in range(nv):
        e[j] = FD_STEP
        _, Jp = residual(term, pin.integrate(term.model, q, e), k, True)
        _, Jm = residual(term, pin.integrate(term.model, q, -e), k, True)
        e[j] = 0.0
        H[:, j] = (Jp - Jm).T @ w / (2.0 * FD_STEP)
    return 0.5 * (H + H.T)


def _frame_accumulate(term, Q, d: CostDerivatives, gauss_newton: bool) -> None:
    term._check_nodes(Q.shape[0])
    nv, W = term.model.nv, term.W  # the chordal term's: blockdiag(S, S, S)
    for k, q in enumerate(Q):
        r, J = residual(term, q, k, True)
        w = W @ r
        d.l[k] += 0.5 * r @ w
        d.lx[k, :nv] += J.T @ w
        G = J.T @ W @ J
        d.lxx[k, :nv, :nv] += 0.5 * (G + G.T)  # exactly symmetric (round-off is not)
        # exactly zero at r = 0: skip the 2 nv kinematics passes there
        if not (term.gauss_newton or gauss_newton) and np.any(w):
            d.lxx[k, :nv, :nv] += _frame_second_order(term, q, k, w)


# --------------------------------------------------------------------------------------
# state and control


def state_residual(term: StateRegularisation, Q: np.ndarray, V: np.ndarray) -> np.ndarray:
    """(N, 2 nv) residuals (difference(q_ref, q), v - v_ref)."""
    N, model = Q.shape[0], term.model
    term._check_nodes(N)
    groups = cfg.joint_groups(model)
    qr, vr = _pick(term.q_ref, N), _pick(term.v_ref, N)
    rq = np.array([cfg.difference(model, groups, qr[k], Q[k]) for k in range(N)]).reshape(N, model.nv)
    return np.concatenate([rq, V - vr], axis=1)


def _state_accumulate(term: StateRegularisation, Q, V, d: CostDerivatives, gauss_newton: bool) -> None:
    model = term.model
    N, nv = Q.shape[0], model.nv
    r = state_residual(term, Q, V)
    w = r @ term.W  # (N, 2 nv); W symmetric
    qr = _pick(term.q_ref, N)
    d.l += 0.5 * np.einsum("ni,ni->n", r, w)
    d.lx[:, nv:] += w[:, nv:]
    d.lxx[:, nv:, nv:] += term.W[nv:, nv:]
    if not np.any(term.W[:nv]):
        return  # no weight on dq (a velocity penalty): every term below is exactly zero
    groups, curved = cfg.joint_groups(model), curved_dofs(model)
    for k in range(N):
        # pin.dDifference(ARG1), exact where Pinocchio's SE(3) block is not; identity on Euclidean joints
        J = cfg.difference_jacobian(model, groups, qr[k], Q[k])
        d.lx[k, :nv] += J.T @ w[k, :nv]
        JW = J.T @ term.W[:nv]  # (nv, 2 nv)
        G = JW[:, :nv] @ J
        d.lxx[k, :nv, :nv] += 0.5 * (G + G.T)  # exactly symmetric (round-off is not)
        d.lxx[k, :nv, nv:] += JW[:, nv:]
        d.lxx[k, nv:, :nv] += JW[:, nv:].T
        wq = w[k, :nv]
        if not (term.gauss_newton or gauss_newton) and curved.size and np.any(wq):
            # difference is joint-wise, so its second-order part lives on curved joints only
            H = np.zeros((nv, nv))
            e = np.zeros(nv)
            for j in curved:
                e[j] = FD_STEP
                Jp = cfg.difference_jacobian(model, groups, qr[k], pin.integrate(model, Q[k], e))
                Jm = cfg.difference_jacobian(model, groups, qr[k], pin.integrate(model, Q[k], -e))
                e[j] = 0.0
                H[:, j] = (Jp - Jm).T @ wq / (2.0 * FD_STEP)
            d.lxx[k, :nv, :nv] += 0.5 * (H + H.T)


def _control_error(term: ControlRegularisation, U) -> np.ndarray:
    term._check(U)
    return U - _pick(term.u_ref, U.shape[0])


# --------------------------------------------------------------------------------------
# one term, a sum


def value(term, Q: np.ndarray, V: np.ndarray, U: np.ndarray | None) -> np.ndarray:
    """(N,) values of one term (a built-in one by this module; any other by its own code)."""
    kind = type(term)
    if kind in FRAME_TERMS:
        term._check_nodes(Q.shape[0])
        W = term.W
        r = np.array([residual(term, q, k, False)[0] for k, q in enumerate(Q)]).reshape(Q.shape[0], -1)
        return 0.5 * np.einsum("ni,ij,nj->n", r, W, r)
    if kind is StateRegularisation:
        r = state_residual(term, Q, V)
        return 0.5 * np.einsum("ni,ij,nj->n", r, term.W, r)
    if kind is ControlRegularisation:
        e = _control_error(term, U)
        return 0.5 * np.einsum("ni,ij,nj->n", e, term.W, e)
    return term.value(Q, V, U)


def accumulate(term, Q: np.ndarray, V: np.ndarray, U: np.ndarray | None, d: CostDerivatives,
               gauss_newton: bool = False) -> None:
    """Add one term's value, gradient and (0)-Hessian into ``d`` (gauss_newton: as
    MultibodyCostSum.derivatives's)."""
    kind = type(term)
    if kind in FRAME_TERMS:
        _frame_accumulate(term, Q, d, gauss_newton)
    elif kind is StateRegularisation:
        _state_accumulate(term, Q, V, d, gauss_newton)
    elif kind is ControlRegularisation:
        e = _control_error(term, U)
        We = e @ term.W
        d.l += 0.5 * np.einsum("ni,ni->n", e, We)
        d.lu += We
        d.luu += term.W
    elif gauss_newton and isinstance(term, BUILT_IN):  # a user's subclass of a built-in term, as the package
        term.accumulate(Q, V, U, d, gauss_newton=True)
    else:
        term.accumulate(Q, V, U, d)


def _sum_value(self: MultibodyCostSum, Q, V, U) -> np.ndarray:
    out = np.zeros(self._check(Q, V, U))
    for t in self.terms:
        out += value(t, Q, V, U)
    return out


def _sum_derivatives(self: MultibodyCostSum, Q, V, U, gauss_newton: bool = False) -> CostDerivatives:
    N = self._check(Q, V, U)
    d = CostDerivatives.zeros(N, 0 if U is None else U.shape[1], self.nx)
    for t in self.terms:
        accumulate(t, Q, V, U, d, gauss_newton)
    return d


class OracleCostSum(MultibodyCostSum):
    """A :class:`MultibodyCostSum` (same constructor) evaluated by this module."""

    value = _sum_value
    derivatives = _sum_derivatives


def use_cost_oracle(monkeypatch) -> None:
    """Make every :class:`MultibodyCostSum` evaluate through this module for the rest of the
    test (pytest's ``monkeypatch`` undoes it)."""
    monkeypatch.setattr(MultibodyCostSum, "value", _sum_value)
    monkeypatch.setattr(MultibodyCostSum, "derivatives", _sum_derivatives)
