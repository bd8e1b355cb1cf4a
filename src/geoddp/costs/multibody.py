"""Cost terms on the state space of a Pinocchio multibody, with (0)-Hessians.

A multibody state is x = (q, v) with q in the configuration manifold of a ``pin.Model``
(shape (nq,)) and v in R^nv. Its tangent perturbation is zeta = (dq, dv) in R^(2 nv), and the
retraction is::

    retract(x, zeta) = (pin.integrate(model, q, dq), v + dv),

the product of the joints' group exponentials (SE(3) for a free flyer, SO(3) for a spherical
joint, U(1) for an unbounded revolute joint, vector spaces otherwise). Every term supplies, on
N nodes at once (Q (N, nq), V (N, nv), U (N, m) or None for a terminal cost)::

    l    (N,)                 cost value (units of the cost: weight units x residual units^2)
    l_x  (N, 2 nv)            d/ds l(retract(x, s zeta)) = l_x . zeta
    l_xx (N, 2 nv, 2 nv)      the (0)-Hessian: symmetric part of
                              d2/ds1 ds2 l(x exp(s1 z1) exp(s2 z2)) at 0
                              (= second derivative along the curves s -> retract(x, s zeta),
                              polarised; the Lie bracket term is antisymmetric and drops out)
    l_u, l_ux, l_uu           Euclidean in u

and adds them into a :class:`geoddp.costs.CostDerivatives` built with ``nx = 2 nv``.

Residual costs l = 1/2 r^T W r with a residual r(q) and Jacobian J_r = dr/d(dq) have

    l_x  = J_r^T W r
    l_xx = J_r^T W J_r  (Gauss-Newton part)  +  sum_k (W r)_k Hess r_k  (second-order part).

The compiled kernels of ``geoddp._core`` (cpp/costs/costs.cpp, cpp/bindings/bind_cost_sum.cpp) evaluate every term of
this module: the second-order parts are exact (Pinocchio's kinematic Hessians and the exact
derivative of the closed-form right Jacobians, no differences), skipped (hence exactly zero) where
W r = 0, so the exact and the Gauss-Newton Hessians coincide there bit for bit;
``gauss_newton=True`` skips them everywhere. A :class:`MultibodyCostSum` runs all its terms of this
module in one call on all N nodes (node chunks on the core's workers, a pinocchio Data per worker
kept in the sum's workspace); a term of another class (a :class:`MultibodyCostTerm` subclass of the
user's) runs its own ``value`` and ``accumulate`` after them. The Python code these classes ran before
the kernels is the tests' oracle (tests/oracle_costs.py: its second-order parts differenced, ~1e-8
relative), and every kernel is checked against it and against differences of its own gradient.

Time-varying references (tracking). Every reference argument takes either one reference
(``pin.SE3``, an (3, 3) rotation, a (3,) point, ...) or a stack of N of them, one per node
(a list of ``pin.SE3`` or an (N, 4, 4) array, (N, 3, 3), (N, 3), (N, nq), (N, m), ...). A
running cost in geoddp is evaluated on all N = H nodes at once, so node k simply uses
reference k; evaluating a term with a stack of K references on N != K nodes raises
:class:`InputError`. There is therefore no separate tracking class: a tracking term *is*
a term with a per-node reference (see :func:`tracking_costs` for building several at once).

Model apart from data, as in Crocoddyl: a term keeps the (shared, read-only) ``pin.Model`` and
its references; the pinocchio Data live in the compiled workspace of the sum (or of the term, when
a term is evaluated alone), made once, never per call.
"""
from __future__ import annotations

import difflib
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from .. import kernels
from ..lie import product as cfg
from .tso3 import AttitudeChordal, AttitudeGeodesic, CostDerivatives
from ..validate import InputError, choice, closest, finite_array, rotation_matrix, spd_matrix, threads_from_environment

__all__ = [
    "ControlRegularisation",
    "FramePlacement",
    "FrameRotation",
    "FrameRotationChordal",
    "FrameTranslation",
    "MultibodyCostSum",
    "MultibodyCostTerm",
    "StateRegularisation",
    "tracking_costs",
]

BACKENDS = ("auto", "compiled")  # the Python code is the tests' oracle (tests/oracle_costs.py)


# --------------------------------------------------------------------------------------
# validation helpers


def _check_model(model: Any, name: str) -> pin.Model:
    if not isinstance(model, pin.Model):
        raise InputError(name, f"expected a pinocchio.Model, got {type(model).__name__}")
    return model


def _frame_id(model: pin.Model, frame_name: Any, name: str) -> int:
    if not isinstance(frame_name, str):
        raise InputError(name, f"expected a frame name (str), got {type(frame_name).__name__}")
    if not model.existFrame(frame_name):
        names = [f.name for f in model.frames]
        close = difflib.get_close_matches(frame_name, names, n=3) or [g for g in [closest(frame_name, names)] if g]
        hint = f"; did you mean {', '.join(map(repr, close))}?" if close else ""
        raise InputError(name, f"expected the name of a frame of model {model.name!r}, got {frame_name!r}{hint}")
    return int(model.getFrameId(frame_name))


def _stack(x: Any, name: str, shape: tuple[int, ...]) -> np.ndarray:
    """One reference of ``shape`` or a per-node stack (K, *shape), returned as (K, *shape)."""
    A = finite_array(x, name)
    if A.shape == shape:
        return A[None]
    if A.ndim == len(shape) + 1 and A.shape[1:] == shape and A.shape[0] >= 1:
        return A
    inner = ", ".join(str(s) for s in shape)
    raise InputError(name, f"expected shape ({inner}{',' if len(shape) == 1 else ''}) or (N, {inner}), got shape {A.shape}")


def _rotation_stack(R: Any, name: str) -> np.ndarray:
    """One rotation (3, 3) or a stack (N, 3, 3) as (K, 3, 3), each checked a rotation (``name[k]``)."""
    stack = _stack(R, name, (3, 3))
    for k, Rk in enumerate(stack):
        rotation_matrix(Rk, name if len(stack) == 1 else f"{name}[{k}]")
    return stack


def _se3_stack(M: Any, name: str) -> np.ndarray:
    """pin.SE3, (4, 4), a sequence of pin.SE3 or (N, 4, 4) -> (K, 4, 4) homogeneous matrices."""
    if isinstance(M, pin.SE3):
        raw: Any = M.homogeneous
    elif isinstance(M, (list, tuple)) and M and all(isinstance(m, pin.SE3) for m in M):
        raw = np.array([m.homogeneous for m in M])
    else:
        raw = M
    H = _stack(raw, name, (4, 4))
    for k, Hk in enumerate(H):
        where = name if H.shape[0] == 1 else f"{name}[{k}]"
        if not np.array_equal(Hk[3], [0.0, 0.0, 0.0, 1.0]):
            raise InputError(where, f"expected a homogeneous transform with last row [0, 0, 0, 1], got {Hk[3]}")
        rotation_matrix(Hk[:3, :3], f"{where} (rotation)")
    return H


def _check_count(ref: np.ndarray, N: int, name: str) -> None:
    """Raise unless a stack of references (K, ...) serves N nodes: K = 1 (broadcast) or K = N.
    (Only the check: the compiled terms broadcast K = 1 themselves, and np.broadcast_to costs
    ~20 us a call, a few % of a first-order solve on the UR5.)"""
    if ref.shape[0] != 1 and ref.shape[0] != N:
        raise InputError(name, f"a per-node reference of {ref.shape[0]} nodes cannot be evaluated on {N} nodes")


def _on_frames(term: Any, model: pin.Model | None, i: int) -> Any:
    """An attitude term of :mod:`geoddp.costs` on a general model: the same cost on the world
    rotation of its ``frame``, through the model's frame kinematics (one rotation term serves the
    TSO(3) backend and every other model)."""
    if not isinstance(term, (AttitudeGeodesic, AttitudeChordal)):
        return term
    if model is None or term.frame is None:
        raise InputError(f"terms[{i}].frame", "expected the name of the frame whose rotation the term "
                         "penalises (and model= on the cost sum), got none")
    if isinstance(term, AttitudeChordal):
        return FrameRotationChordal(model, term.frame, term.R_d, term.S)
    return FrameRotation(model, term.frame, term.R_d, term.W)


# --------------------------------------------------------------------------------------
# base classes


_ASSIGNMENTS = [0]  # attribute assignments on MultibodyCostTerm instances so far


class MultibodyCostTerm:
    """Base class: ``value`` and ``accumulate`` over N nodes of a multibody state. Subclass it
    for a term of your own (a cost sum runs its Python code beside the kernels); the built-in
    terms below run in the compiled kernels.

    Attributes:
        model: the ``pin.Model`` (None for terms that only see the control).
        uses_control: True if the term needs U (cannot be part of a terminal cost).
    """

    uses_control = False
    model: pin.Model | None = None

    def __setattr__(self, name: str, value: Any) -> None:
        # every assignment to any term (construction included) moves the counter that a cost
        # sum's cached compiled specs are stamped with (MultibodyCostSum._specs): a term whose
        # weight or reference is rebound is never evaluated with the old one
        _ASSIGNMENTS[0] += 1
        object.__setattr__(self, name, value)

    def value(self, Q: np.ndarray, V: np.ndarray, U: np.ndarray | None) -> np.ndarray:
        """(N,) cost values at Q (N, nq), V (N, nv), U (N, m) or None."""
        raise NotImplementedError

    def accumulate(self, Q: np.ndarray, V: np.ndarray, U: np.ndarray | None, d: CostDerivatives) -> None:
        """Add this term's value, gradient (N, 2 nv) and (0)-Hessian (N, 2 nv, 2 nv) into ``d``."""
        raise NotImplementedError


class _CompiledTerm(MultibodyCostTerm):
    """A built-in term: ``value`` and ``accumulate`` of the term alone run the compiled kernels,
    the numbers it adds in a :class:`MultibodyCostSum`."""

    def _workspace(self) -> Any:
        # made on first use and kept (its pinocchio Data too); set past __setattr__, since a
        # workspace is not a change of the term
        ws = self.__dict__.get("_kernel_workspace")
        if ws is None:
            ws = kernels.core.CostWorkspace()
            object.__setattr__(self, "_kernel_workspace", ws)
        return ws

    def value(self, Q, V, U):
        N = _check_arrays(self.model, Q, V, U)
        out = np.zeros(N)
        _add(self._workspace(), [_spec(self, N, U)], Q, V, U, out, None, False, 1)
        return out

    def accumulate(self, Q, V, U, d, gauss_newton=False):
        """As the base class's; ``gauss_newton`` as :meth:`MultibodyCostSum.derivatives`'s."""
        N = _check_arrays(self.model, Q, V, U)
        _add(self._workspace(), [_spec(self, N, U)], Q, V, U, d.l, d, gauss_newton, 1)


class _ResidualTerm(_CompiledTerm):
    """1/2 r(q)^T W r(q) for a residual of the configuration only (subclasses: frame terms)."""

    nr: int = 0

    def __init__(self, model: pin.Model, frame_name: str, W: Any, gauss_newton: bool) -> None:
        cls = type(self).__name__
        self.model = _check_model(model, f"{cls}.model")
        self.nv = self.model.nv
        self.W = spd_matrix(W, f"{cls}.W", self.nr, semidefinite=True)
        if not isinstance(gauss_newton, (bool, np.bool_)):
            raise InputError(f"{cls}.gauss_newton", f"expected True or False, got {gauss_newton!r}")
        self.gauss_newton = bool(gauss_newton)
        self.frame_name = frame_name
        self.frame_id = _frame_id(self.model, frame_name, f"{cls}.frame_name")

    def _check_nodes(self, N: int) -> None:
        """Raise if a per-node reference does not match N (subclasses)."""


# --------------------------------------------------------------------------------------
# frame terms


class FramePlacement(_ResidualTerm):
    """1/2 r^T W r with r = log6(M_ref^-1 oMf(q)) (6,), [linear (m); angular (rad)].

    Args:
        model: the multibody.
        frame_name: a frame of ``model``.
        M_ref: target world placement: ``pin.SE3`` or (4, 4), or per node a list of N
            ``pin.SE3`` or an (N, 4, 4) array (tracking).
        W: (6, 6) PSD weight (scalar or length-6 diagonal accepted), [linear; angular] order.
        gauss_newton: use only J^T W J (no second-order part) in l_xx.

    The log6 has a cut locus at a relative rotation angle of pi (the gradient jumps there). Where
    the frame's rotation equals the reference's exactly, r and l_x are exactly 0 in the rotation.
    """

    nr = 6

    def __init__(self, model: pin.Model, frame_name: str, M_ref: Any, W: Any = 1.0,
                 gauss_newton: bool = False) -> None:
        super().__init__(model, frame_name, W, gauss_newton)
        self.M_ref = _se3_stack(M_ref, "FramePlacement.M_ref")  # (K, 4, 4)

    def _check_nodes(self, N):
        _check_count(self.M_ref, N, "FramePlacement.M_ref")


class FrameRotation(_ResidualTerm):
    """1/2 r^T W r with r = log3(R_ref^T R_frame(q)) (3,) in rad.

    Args:
        R_ref: target world orientation (3, 3) or per node (N, 3, 3).
        W: (3, 3) PSD weight (scalar or length-3 diagonal accepted).
    """

    nr = 3

    def __init__(self, model: pin.Model, frame_name: str, R_ref: Any, W: Any = 1.0,
                 gauss_newton: bool = False) -> None:
        super().__init__(model, frame_name, W, gauss_newton)
        self.R_ref = _rotation_stack(R_ref, "FrameRotation.R_ref")  # (K, 3, 3)

    def _check_nodes(self, N):
        _check_count(self.R_ref, N, f"{type(self).__name__}.R_ref")


class FrameRotationChordal(FrameRotation):
    """1/2 ||I - E||^2_W = 1/2 tr[(I - E)^T W (I - E)], E = R_ref^T R_frame(q): the paper's chordal
    attitude cost (eq. costR) on any frame of any model (:class:`geoddp.costs.AttitudeChordal` on
    TSO(3)). Unlike the geodesic form it has no cut locus at pi, but a saddle there.

    As a residual: r = (I - E) stacked column by column (9,) with weight blockdiag(W, W, W) (the
    attribute ``W``; ``S`` is the given (3, 3)), whose Gauss-Newton part ``gauss_newton`` keeps.
    The kernels use the closed forms of eqs. gradF and hessF in the rotation's local coordinates,
    with the frame's kinematic Hessian.

    Args:
        R_ref: target world orientation (3, 3) or per node (N, 3, 3).
        W: (3, 3) PSD weight (scalar or length-3 diagonal accepted), the paper's S_R.
    """

    nr = 9

    def __init__(self, model: pin.Model, frame_name: str, R_ref: Any, W: Any = 1.0,
                 gauss_newton: bool = False) -> None:
        self.S = spd_matrix(W, "FrameRotationChordal.W", 3, semidefinite=True)
        _ResidualTerm.__init__(self, model, frame_name, np.kron(np.eye(3), self.S), gauss_newton)
        self.R_ref = _rotation_stack(R_ref, "FrameRotationChordal.R_ref")  # (K, 3, 3)


class FrameTranslation(_ResidualTerm):
    """1/2 r^T W r with r = p_frame(q) - p_ref (3,) in m, world frame.

    Args:
        p_ref: target world position (3,) or per node (N, 3), m.
        W: (3, 3) PSD weight (scalar or length-3 diagonal accepted).
    """

    nr = 3

    def __init__(self, model: pin.Model, frame_name: str, p_ref: Any, W: Any = 1.0,
                 gauss_newton: bool = False) -> None:
        super().__init__(model, frame_name, W, gauss_newton)
        self.p_ref = _stack(p_ref, "FrameTranslation.p_ref", (3,))  # (K, 3)

    def _check_nodes(self, N):
        _check_count(self.p_ref, N, "FrameTranslation.p_ref")


# --------------------------------------------------------------------------------------
# state and control


class StateRegularisation(_CompiledTerm):
    """1/2 r^T W r with r = (difference(q_ref, q), v - v_ref) (2 nv,), ``pin.difference`` per joint.

    Args:
        model: the multibody.
        q_ref: (nq,) or per node (N, nq) reference configuration (normalised quaternions).
        v_ref: (nv,) or per node (N, nv) reference velocity; default 0.
        W: (2 nv, 2 nv) PSD weight (scalar or length-2nv diagonal accepted), [dq; dv] order.
        gauss_newton: drop the second-order part of ``difference`` (only non-Euclidean joints
            have one: free flyer, spherical, planar, unbounded revolute).

    Euclidean joints (nq_j == nv_j: revolute, prismatic, ...) have difference = q - q_ref, whose
    Hessian is the constant Gauss-Newton one.
    """

    def __init__(self, model: pin.Model, q_ref: Any, v_ref: Any = None, W: Any = 1.0,
                 gauss_newton: bool = False) -> None:
        self.model = _check_model(model, "StateRegularisation.model")
        nq, nv = self.model.nq, self.model.nv
        self.nv = nv
        self.q_ref = _stack(q_ref, "StateRegularisation.q_ref", (nq,))
        for k, qk in enumerate(self.q_ref):
            if not pin.isNormalized(self.model, qk, 1e-9):
                raise InputError("StateRegularisation.q_ref" + ("" if len(self.q_ref) == 1 else f"[{k}]"),
                                 "expected a normalised configuration (unit quaternions / unit complex numbers)")
        self.v_ref = (np.zeros((1, nv)) if v_ref is None
                      else _stack(v_ref, "StateRegularisation.v_ref", (nv,)))
        self.W = spd_matrix(W, "StateRegularisation.W", 2 * nv, semidefinite=True)
        if not isinstance(gauss_newton, (bool, np.bool_)):
            raise InputError("StateRegularisation.gauss_newton", f"expected True or False, got {gauss_newton!r}")
        self.gauss_newton = bool(gauss_newton)
        try:
            cfg.joint_groups(self.model)  # only joints whose groups geoddp knows
        except ValueError as exc:
            raise InputError("StateRegularisation.model", str(exc)) from None

    def _check_nodes(self, N: int) -> None:
        _check_count(self.q_ref, N, "StateRegularisation.q_ref")
        _check_count(self.v_ref, N, "StateRegularisation.v_ref")


class ControlRegularisation(_CompiledTerm):
    """1/2 (u - u_ref)^T W (u - u_ref), u in R^m (units of the inputs, e.g. N m).

    Args:
        u_ref: (m,) or per node (N, m) reference input; fixes m.
        W: (m, m) PSD weight (scalar or length-m diagonal accepted).

    Like :class:`geoddp.costs.ControlQuadratic` but with per-node references and PSD weights
    (the solver's regularisation handles a singular l_uu).
    """

    uses_control = True

    def __init__(self, u_ref: Any, W: Any = 1.0) -> None:
        ref = finite_array(u_ref, "ControlRegularisation.u_ref")
        if ref.ndim not in (1, 2) or ref.shape[-1] < 1:
            raise InputError("ControlRegularisation.u_ref", f"expected shape (m,) or (N, m), got shape {ref.shape}")
        self.u_ref = ref.reshape(-1, ref.shape[-1])  # (K, m)
        self.m = self.u_ref.shape[1]
        self.W = spd_matrix(W, "ControlRegularisation.W", self.m, semidefinite=True)

    def _check(self, U: np.ndarray | None) -> None:
        """Raise unless U (N, m) can be evaluated: given, of m columns, N matching the references."""
        if U is None:
            raise InputError("ControlRegularisation", "a control cost term cannot be evaluated without controls "
                             "(U = None: a terminal cost)")
        if U.ndim != 2 or U.shape[1] != self.m:
            raise InputError("U", f"expected shape (N, {self.m}), got shape {U.shape}")
        _check_count(self.u_ref, U.shape[0], "ControlRegularisation.u_ref")


# --------------------------------------------------------------------------------------
# sums and tracking


class MultibodyCostSum:
    """A sum of multibody terms: the running or terminal cost; nx = 2 nv from the model.

    Args:
        terms: the terms; every term with a model must share nq and nv.
        model: the model fixing nx (default: the first term's).
        terminal: if True, refuse control terms at construction (they need U).
        backend: ``"auto"`` (the default) or ``"compiled"``: the kernels of ``geoddp._core``, the
            only backend (the Python code they replaced is the tests' oracle); anything else is
            refused, naming ``backend``. ``self.backend`` is ``"compiled"``.

    The built-in terms run in one call of the kernels on all N nodes; a term of another class
    (a :class:`MultibodyCostTerm` subclass of the user's) runs its own ``value`` and
    ``accumulate`` after them.
    """

    # A first-order linearisation of a problem takes this sum's Gauss-Newton Hessians
    # (derivatives(..., gauss_newton=True)): see geoddp.problem.Problem.linearise.
    first_order_gauss_newton = True

    def __init__(self, terms: Sequence[MultibodyCostTerm], model: pin.Model | None = None,
                 terminal: bool = False, backend: str = "auto") -> None:
        self.terms = [_on_frames(t, model, i) for i, t in enumerate(terms)]
        for i, t in enumerate(self.terms):
            if not isinstance(t, MultibodyCostTerm):
                raise InputError(f"terms[{i}]", f"expected a MultibodyCostTerm, got {type(t).__name__}")
        if model is None:
            model = next((t.model for t in self.terms if t.model is not None), None)
            if model is None:
                raise InputError("model", "no term has a model: pass model= to fix the state dimension")
        self.model = _check_model(model, "model")
        for i, t in enumerate(self.terms):
            if t.model is not None and (t.model.nq, t.model.nv) != (model.nq, model.nv):
                raise InputError(f"terms[{i}]", f"expected a term on a model with (nq, nv) = "
                                 f"({model.nq}, {model.nv}), got ({t.model.nq}, {t.model.nv})")
        self.terminal = bool(terminal)
        if self.terminal:
            self._refuse_control()
        choice(backend, "backend", BACKENDS)
        self.backend = "compiled"
        # the built-in terms (exact types: a subclass may compute something else) in one call of
        # the kernels, with the sum's own workspace (pinocchio Data per worker, made once); threads
        # as Multibody's (GEODDP_THREADS or the core's default)
        self._workspace = kernels.core.CostWorkspace()
        self._spec_cache: dict = {}
        self._split_key: tuple = ()
        self._kernel_terms: list = []
        self._own_terms: list = []
        self.threads = threads_from_environment()
        self._split()

    @property
    def nx(self) -> int:
        """Tangent state dimension 2 nv."""
        return 2 * self.model.nv

    def _refuse_control(self) -> None:
        for i, t in enumerate(self.terms):
            if t.uses_control:
                raise InputError(f"terms[{i}]", f"a control cost term ({type(t).__name__}) cannot be part of a "
                                 "terminal cost (there is no control at the final node)")

    def _check(self, Q: np.ndarray, V: np.ndarray, U: np.ndarray | None) -> int:
        N = _check_arrays(self.model, Q, V, U)
        if U is None:
            self._refuse_control()
        self._split()
        return N

    def _split(self) -> None:
        """The built-in terms and the others, of ``self.terms`` as it is now: a list, which a
        user may append to or rebind after construction (the split and the specs follow)."""
        key = tuple(map(id, self.terms))
        if key != self._split_key:
            self._kernel_terms = [t for t in self.terms if type(t) in _COMPILED_KINDS]
            self._own_terms = [t for t in self.terms if type(t) not in _COMPILED_KINDS]
            self._spec_cache.clear()
            self._split_key = key

    def _compiled(self, Q: np.ndarray, V: np.ndarray, U: np.ndarray | None, l: np.ndarray,
                  d: CostDerivatives | None, gauss_newton: bool) -> None:
        """Add the built-in terms into l (N,) and, with d, their derivatives, in one call of the
        kernels (each term's checks first, so bad input raises an InputError naming it)."""
        spec = self._specs(Q.shape[0], U)
        # Waking the core's workers costs about as much as a value or the derivatives of state
        # and control terms on a few hundred nodes (tens of us): only frame terms' derivatives
        # (Jacobians and kinematic Hessians, 2-5 us a node) are worth splitting.
        split = d is not None and any(s[0] == 0 for s in spec)
        _add(self._workspace, spec, Q, V, U, l, d, gauss_newton, self.threads if split else 1)

    def _specs(self, N: int, U: np.ndarray | None) -> list:
        """[_spec(t, N, U) for the built-in terms], cached: a solve asks for the same few (N, U
        shape) every call (building and checking them had been ~3 us of a 10-20 us call). The
        key holds the term-assignment counter, so a rebound attribute builds afresh; in-place
        changes to a term's arrays need nothing (the specs hold the arrays themselves)."""
        key = (N, None if U is None else U.shape, _ASSIGNMENTS[0])
        spec = self._spec_cache.get(key)
        if spec is None:
            spec = [_spec(t, N, U) for t in self._kernel_terms]  # the checks raise here, before caching
            if len(self._spec_cache) >= 16:  # MPC windows of many lengths: keep it small
                self._spec_cache.clear()
            self._spec_cache[key] = spec
        return spec

    def value(self, Q: np.ndarray, V: np.ndarray, U: np.ndarray | None) -> np.ndarray:
        """(N,) summed values."""
        out = np.zeros(self._check(Q, V, U))
        if self._kernel_terms:
            self._compiled(Q, V, U, out, None, False)
        for t in self._own_terms:
            v = t.value(Q, V, U)
            if np.shape(v) != out.shape:  # a user's term: name it, rather than numpy's broadcasting error
                raise InputError(f"terms[{self.terms.index(t)}]", f"{type(t).__name__}.value returned shape "
                                 f"{np.shape(v)}, expected ({out.shape[0]},): one value per node")
            out += v
        return out

    def derivatives(self, Q: np.ndarray, V: np.ndarray, U: np.ndarray | None,
                    gauss_newton: bool = False) -> CostDerivatives:
        """Summed :class:`CostDerivatives` (nx = 2 nv; m = 0 and empty l_u when U is None).

        ``gauss_newton=True`` drops the second-order part of every built-in residual term (frame
        terms, state regularisation), as if each had been built with ``gauss_newton=True``: the
        Hessian J_r^T W J_r of a first-order (Gauss-Newton) iteration."""
        N = self._check(Q, V, U)
        d = CostDerivatives.zeros(N, 0 if U is None else U.shape[1], self.nx)
        if self._kernel_terms:
            self._compiled(Q, V, U, d.l, d, gauss_newton)
        for t in self._own_terms:
            if gauss_newton and isinstance(t, _CompiledTerm):  # a subclass of a built-in term
                t.accumulate(Q, V, U, d, gauss_newton=True)
            else:
                t.accumulate(Q, V, U, d)
        return d


def _check_arrays(model: pin.Model | None, Q: np.ndarray, V: np.ndarray, U: np.ndarray | None) -> int:
    """N, once Q is (N, nq) and V (N, nv) (any widths without a model) and U (N, m) or None,
    each a numpy array (a list is refused, naming it: the kernels read arrays in place)."""
    for name, x in (("Q", Q), ("V", V), ("U", U)):
        if not isinstance(x, np.ndarray) and (x is not None or name != "U"):
            raise InputError(name, f"expected a numpy array, got {type(x).__name__}")
    N = Q.shape[0] if Q.ndim == 2 else -1
    nq, nv = (model.nq, model.nv) if model is not None else (Q.shape[-1], V.shape[-1])
    if Q.shape != (N, nq):
        raise InputError("Q", f"expected shape (N, {nq}), got shape {Q.shape}")
    if V.shape != (N, nv):
        raise InputError("V", f"expected shape ({N}, {nv}), got shape {V.shape}")
    if U is not None and (U.ndim != 2 or U.shape[0] != N):
        raise InputError("U", f"expected shape ({N}, m), got shape {U.shape}")
    return N


def _add(workspace: Any, spec: list, Q: np.ndarray, V: np.ndarray, U: np.ndarray | None, l: np.ndarray,
         d: CostDerivatives | None, gauss_newton: bool, threads: int) -> None:
    """geoddp._core.cost_sum: add the terms of ``spec`` into l (N,) and, with d, d's derivatives."""
    N = Q.shape[0]
    Uc = _EMPTY if U is None else np.ascontiguousarray(U, dtype=float)
    if d is None:
        lx = lxx = lu = luu = _EMPTY
    else:
        lx, lxx = _rows(d.lx, N), _rows(d.lxx, N)
        lu, luu = (_EMPTY, _EMPTY) if U is None else (_rows(d.lu, N), _rows(d.luu, N))
    kernels.core.cost_sum(workspace, spec, np.ascontiguousarray(Q, dtype=float), np.ascontiguousarray(V, dtype=float),
                          Uc, d is not None, gauss_newton, threads, l, lx, lxx, lu, luu)


def _rows(A: np.ndarray, N: int) -> np.ndarray:
    """A (N, ...) as a C-contiguous (N, prod(...)) view the kernels can add into in place."""
    if not A.flags.c_contiguous:
        raise ValueError("expected a C-contiguous array")  # CostDerivatives.zeros makes them so
    return A.reshape(N, -1)


def _spec(t: MultibodyCostTerm, N: int, U: np.ndarray | None) -> tuple:
    """A built-in term (or a subclass's inherited one) as geoddp._core.cost_sum takes it, after
    the term's checks for N nodes (bad input raises an InputError naming the parameter)."""
    kind = next(c for c in type(t).__mro__ if c in _COMPILED_KINDS)
    if kind is ControlRegularisation:
        t._check(U)  # U given, its shape, the per-node reference count
        return (2, t.u_ref, t.W)
    t._check_nodes(N)
    if kind is StateRegularisation:
        return (1, t.model, t.q_ref, t.v_ref, t.W, t.gauss_newton)
    code, refs, W = _FRAME_KINDS[kind](t)
    return (0, t.model, t.frame_id, code, refs, W, t.gauss_newton)


# frame term class -> (kernel code, its references as (K, 16 | 9 | 3) rows, its weight)
_FRAME_KINDS: dict[type, Callable[[Any], tuple[int, np.ndarray, np.ndarray]]] = {
    FramePlacement: lambda t: (0, t.M_ref.reshape(t.M_ref.shape[0], 16), t.W),
    FrameRotation: lambda t: (1, t.R_ref.reshape(t.R_ref.shape[0], 9), t.W),
    FrameTranslation: lambda t: (2, t.p_ref, t.W),
    FrameRotationChordal: lambda t: (3, t.R_ref.reshape(t.R_ref.shape[0], 9), t.S),  # W (3, 3) per column
}
# the built-in term classes, which the kernels evaluate
_COMPILED_KINDS = frozenset((*_FRAME_KINDS, StateRegularisation, ControlRegularisation))
_EMPTY = np.empty((0, 0))


def tracking_costs(term_factory: Callable[[Any], MultibodyCostTerm], references: Sequence[Any]) -> MultibodyCostTerm:
    """Build one tracking term from a factory and N per-node references.

    ``term_factory(ref)`` must build a term from one reference *or* from the stacked
    references, e.g. ``lambda p: FrameTranslation(model, "tool", p, W)``. The references are
    stacked (``np.stack``; lists of ``pin.SE3`` are passed as a list) and given to the factory
    once, so the result is a single term whose node k follows ``references[k]`` -- one
    vectorised term rather than N single-node terms, which would not fit the N-node API.
    """
    refs = list(references)
    if not refs:
        raise InputError("references", "expected at least one reference")
    if all(isinstance(r, pin.SE3) for r in refs):
        return term_factory(refs)
    try:
        stacked = np.stack([np.asarray(r, dtype=float) for r in refs])
    except (ValueError, TypeError) as exc:
        raise InputError("references", f"expected references of one common shape ({exc})") from None
    return term_factory(stacked)
