"""The tables every scene kind shares, once: their keys, their fields on the spec and how they are
read. Today that is ``[solver]``; ``[limits]`` and ``[simulation]`` belong here too.

:class:`CommonSpec` is the base of both specs (:class:`~geoddp.scene.satellite.SceneSpec`,
:class:`~geoddp.scene.multibody.MultibodySceneSpec`): its fields are keyword-only with defaults,
so a new shared field never disturbs a kind's own fields. :data:`TABLES` is merged into each
kind's schema, and :func:`read_common` reads every shared table into spec fields.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import validate as v
from ..solver.options import (DEFAULT_EXPANSION, DEFAULT_GRAD_TOL, DEFAULT_MAX_ITER, DEFAULT_SWITCH_RATIO, DEFAULT_TOL,
                              EXPANSIONS)
from .reader import Reader, Schema

DEFAULT_SECOND_ORDER = "exact"

# [table] -> key -> required?  (merged into every kind's schema)
TABLES: Schema = {
    "solver": {"expansion": False, "switch_ratio": False, "tol": False, "grad_tol": False, "max_iter": False,
               "second_order": False, "initial_controls": False},
}


def readonly(a: Any) -> np.ndarray:
    """A read-only float64 copy: specs are frozen, arrays included, so a caller cannot edit a shared scene."""
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False, kw_only=True)
class CommonSpec:
    """Fields of the shared tables (keyword-only, with defaults).

    Attributes:
        expansion: "first" | "second" | "switch".
        switch_ratio: sigma in (0, 1) for the switch expansion.
        tol: stopping tolerance on |J_i - J_(i-1)|, >= 0.
        grad_tol: stopping tolerance on the gradient norm, >= 0.
        max_iter: maximum number of iterations, >= 1.
        second_order: "exact" | "paper" (the paper's: satellite with explicit Euler only).
    """

    expansion: str = DEFAULT_EXPANSION
    switch_ratio: float = DEFAULT_SWITCH_RATIO
    tol: float = DEFAULT_TOL
    grad_tol: float = DEFAULT_GRAD_TOL
    max_iter: int = DEFAULT_MAX_ITER
    second_order: str = DEFAULT_SECOND_ORDER

    def _check_common(self, second_order_kinds: tuple[str, ...], nu: int) -> None:
        """Validate the shared fields under their field names (direct construction, with_overrides);
        ``nu``: the spec's number of inputs m (for per-input fields)."""
        put = lambda k, val: object.__setattr__(self, k, val)  # noqa: E731  (frozen dataclass)
        put("expansion", v.choice(self.expansion, "expansion", EXPANSIONS))
        put("switch_ratio", v.bounded_float(self.switch_ratio, "switch_ratio", 0.0, 1.0, False, False))
        put("tol", v.nonnegative_float(self.tol, "tol"))
        put("grad_tol", v.nonnegative_float(self.grad_tol, "grad_tol"))
        put("max_iter", v.positive_int(self.max_iter, "max_iter"))
        put("second_order", v.choice(self.second_order, "second_order", second_order_kinds))


def read_common(r: Reader, second_order_kinds: tuple[str, ...], nu: int, model: Any = None) -> dict[str, Any]:
    """The shared tables as :class:`CommonSpec` keyword arguments.

    Args:
        r: the scene's reader.
        second_order_kinds: the kind's choices for ``[solver].second_order``.
        nu: the number of inputs m (for per-input values).
        model: the kind's ``pin.Model`` if it has one at parse time (multibody), else None.

    ``[solver].initial_controls`` has forms that depend on the kind ("hover"): each kind reads it.
    """
    s = r.table("solver")
    get = s.get
    return dict(
        expansion=r.check(v.choice, get("expansion", DEFAULT_EXPANSION), "[solver].expansion", EXPANSIONS),
        switch_ratio=r.check(v.bounded_float, get("switch_ratio", DEFAULT_SWITCH_RATIO), "[solver].switch_ratio",
                             0.0, 1.0, False, False),
        tol=r.check(v.nonnegative_float, get("tol", DEFAULT_TOL), "[solver].tol"),
        grad_tol=r.check(v.nonnegative_float, get("grad_tol", DEFAULT_GRAD_TOL), "[solver].grad_tol"),
        max_iter=r.check(v.positive_int, get("max_iter", DEFAULT_MAX_ITER), "[solver].max_iter"),
        second_order=r.check(v.choice, get("second_order", DEFAULT_SECOND_ORDER), "[solver].second_order",
                             second_order_kinds),
    )
