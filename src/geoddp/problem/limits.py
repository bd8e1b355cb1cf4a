"""Control limits: per-input lower and upper bounds on the controls, constant or per node.

    lower_k <= u_k <= upper_k   (elementwise, k = 0 .. H-1)

Bounds are given as a scalar, an (m,) vector (the same at every node) or an (H, m) array, with
-inf / +inf for an unbounded side. :class:`ControlLimits` holds what the user gave;
:meth:`ControlLimits.resolve` checks it against a problem's (H, m) and returns the (H, m) float64
arrays the solver uses. Every bad value raises :class:`~geoddp.validate.InputError` naming the
parameter (``limits.lower``, ``limits.upper``, ``initial_controls``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..validate import InputError, keywords_checked

__all__ = ["ControlLimits", "as_limits", "check_inside", "active_set", "projected_gradient", "effort_limits"]


def _bound(x: Any, name: str, horizon: int, m: int, infinite: float) -> np.ndarray:
    """A bound broadcast to (H, m) float64; NaN and a wrong length raise InputError naming ``name``."""
    if x is None:
        return np.full((horizon, m), infinite)
    try:
        a = np.array(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(name, f"expected a number, {m} numbers or an ({horizon}, {m}) array, got {x!r} ({exc})") from None
    if a.ndim == 0:
        a = np.full((horizon, m), float(a))
    elif a.shape == (m,):
        a = np.broadcast_to(a, (horizon, m)).copy()
    elif a.shape != (horizon, m):
        raise InputError(name, f"expected a number, {m} numbers (one per input) or an ({horizon}, {m}) array "
                         f"(one row per node), got shape {a.shape}")
    if np.isnan(a).any():
        k, i = np.argwhere(np.isnan(a))[0]
        raise InputError(name, f"NaN at node {k}, input {i} (use -inf or inf for an unbounded side)")
    return np.ascontiguousarray(a)


@keywords_checked
@dataclass
class ControlLimits:
    """Box constraints on the controls, lower <= u_k <= upper.

    Attributes:
        lower: a scalar, (m,) or (H, m) lower bounds in the units of the model's inputs (N m for the
            satellite's torques, N for rotor thrusts, the joint's effort for a multibody); None or
            -inf: unbounded below.
        upper: the same for the upper bounds; None or +inf: unbounded above.
    """

    lower: Any = None
    upper: Any = None

    def resolve(self, horizon: int, m: int, names: tuple[str, str] = ("limits.lower", "limits.upper")
                ) -> tuple[np.ndarray, np.ndarray]:
        """(H, m) float64 lower and upper arrays; InputError naming ``names`` (the lower's, the
        upper's; a scene passes its keys) for NaN, a wrong length, +inf as a lower or -inf as an
        upper bound, or lower > upper anywhere (named by the lower's name)."""
        lo = _bound(self.lower, names[0], horizon, m, -np.inf)
        hi = _bound(self.upper, names[1], horizon, m, np.inf)
        if np.isposinf(lo).any():
            raise InputError(names[0], "+inf is not a lower bound (use -inf for an unbounded side)")
        if np.isneginf(hi).any():
            raise InputError(names[1], "-inf is not an upper bound (use inf for an unbounded side)")
        bad = lo > hi
        if bad.any():
            k, i = np.argwhere(bad)[0]
            raise InputError(names[0], f"expected lower <= upper, got lower = {lo[k, i]} > upper = {hi[k, i]} "
                             f"at node {k}, input {i}")
        return lo, hi


def as_limits(limits: Any) -> ControlLimits | None:
    """None, a :class:`ControlLimits`, a (lower, upper) pair or a dict with keys lower / upper."""
    if limits is None or isinstance(limits, ControlLimits):
        return limits
    if isinstance(limits, dict):
        unknown = set(limits) - {"lower", "upper"}
        if unknown:
            raise InputError("limits", f"expected keys 'lower' and 'upper', got {sorted(unknown)}")
        return ControlLimits(limits.get("lower"), limits.get("upper"))
    if isinstance(limits, (tuple, list)) and len(limits) == 2:
        return ControlLimits(limits[0], limits[1])
    raise InputError("limits", f"expected None, ControlLimits(lower, upper), a (lower, upper) pair or "
                     f"{{'lower': ..., 'upper': ...}}, got {type(limits).__name__}")


def check_inside(U: np.ndarray, lower: np.ndarray, upper: np.ndarray, name: str = "initial_controls") -> None:
    """InputError naming ``name`` if some control of U (H, m) lies outside [lower, upper]."""
    out = (U < lower) | (U > upper)
    if out.any():
        k, i = np.argwhere(out)[0]
        raise InputError(name, f"the control at node {k}, input {i} is {U[k, i]}, outside the limits "
                         f"[{lower[k, i]}, {upper[k, i]}] (start inside the box, e.g. np.clip(U, lower, upper))")


def active_set(U: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """(H, m) int8: -1 where u sits on its lower bound, +1 on its upper bound, 0 inside (an input
    with lower == upper counts as on its lower bound)."""
    a = np.zeros(U.shape, dtype=np.int8)
    a[U >= upper] = 1
    a[U <= lower] = -1
    return a


def projected_gradient(U: np.ndarray, grad: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """dJ/dU (H, m) without the components that push into an active bound (the KKT residual of
    min J(U) over the box): zero where u = lower and dJ/du > 0 or u = upper and dJ/du < 0, and
    where lower = upper; elsewhere the gradient itself (bit for bit, so that inactive limits change
    nothing)."""
    out = grad.copy()
    blocked = ((U <= lower) & (grad > 0.0)) | ((U >= upper) & (grad < 0.0)) | (lower == upper)
    out[blocked] = 0.0
    return out


# Pinocchio's effortLimit for a degree of freedom whose URDF gives no effort (a free flyer's, a
# joint without <limit>): the largest double. Efforts at or above this, and 0 (which URDF files
# write for "unspecified" on continuous joints), are read as unbounded.
_UNBOUNDED_EFFORT = 1e300


def effort_limits(effort: np.ndarray, actuation: np.ndarray, name: str = "[limits].effort_limits"
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Symmetric input bounds -effort <= u_j <= effort from a URDF's joint effort limits.

    Args:
        effort: (nv,) Pinocchio's ``model.effortLimit`` (N m for revolute joints, N for prismatic).
        actuation: (nv, m) the model's tau = H u; every input must drive one joint directly (its
            column a unit vector e_i), the input then takes joint i's effort limit.

    Returns (lower (m,), upper (m,)); an effort of 0 or >= 1e300 (none given) is unbounded.
    Raises InputError naming ``name`` when an input is not a joint motor (a thruster, a coupled
    transmission): its limit must then be given as numbers.
    """
    effort = np.asarray(effort, dtype=float)
    Hm = np.asarray(actuation, dtype=float)
    upper = np.empty(Hm.shape[1])
    for j in range(Hm.shape[1]):
        nz = np.flatnonzero(Hm[:, j])
        if nz.size != 1 or Hm[nz[0], j] != 1.0:
            raise InputError(name, f"input {j} is not a joint motor (its actuation column is not a unit vector: "
                             f"{Hm[:, j].tolist()}); give control_min / control_max instead")
        e = effort[nz[0]]
        upper[j] = np.inf if (not np.isfinite(e) or e <= 0.0 or e >= _UNBOUNDED_EFFORT) else e
    return -upper, upper
