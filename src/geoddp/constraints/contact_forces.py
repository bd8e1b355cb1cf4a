"""Hard constraints on the contact forces of a legged problem: the friction cone and the normal
force's bounds at every foot in contact, at every contact node.

Unlike the kinds of :mod:`.kinds` (functions of the state at nodes k = 1..H), a contact force
f(q_k, v_k, u_k) is a function of a node's state *and* controls, through the contact dynamics
(:mod:`geoddp.models.contact`): its rows enter the inner problem's node costs at k = 0..H-1 in
z = (dq, dv, du), with the exact first derivatives of the forces (their Jacobian ``Lz``) and, for
the exact second order, their second derivatives (the KKT system differentiated twice, ``L2``).
The legged problem (:class:`geoddp.problem.legged.ContactProblem`) adds these terms to its node
costs itself (:meth:`~geoddp.problem.legged.ContactProblem.with_force_terms`), where it has the
node's dynamics evaluation at hand.

Rows per (contact node, foot in contact), c <= 0 (units: N)::

    t_j . f - mu f_z <= 0              facets: the tangent directions t_j = (cos(2 pi j / facets),
                                       sin(2 pi j / facets), 0) and their opposites, j < facets / 2
    min_normal_force - f_z <= 0
    f_z - max_normal_force <= 0        when max_normal_force is finite

The facets are the linearised cone of Crocoddyl's ``ResidualModelContactFrictionCone`` (flat
ground, normal +z, world frame), an outer approximation.

An impulse node (touch-down) has no controls and its impulses are not constrained here.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..models.contact import friction_cone
from ..validate import InputError
from .kinds import Constraint

__all__ = ["FrictionCone", "ForceBound", "ForcePlaced"]


@dataclass
class ForceBound:
    """The rows of a force constraint per foot: c = G f - h <= 0.

    Attributes:
        G: (nc, 3) row directions on the world force f (N); h: (nc,) bounds (N).
        rows, equality, labels: as :class:`geoddp.constraints.kinds.Bound`'s.
    """

    G: np.ndarray
    h: np.ndarray
    labels: tuple[str, ...]
    equality: bool = False

    @property
    def rows(self) -> int:
        return int(self.G.shape[0])

    def value(self, forces: np.ndarray) -> np.ndarray:
        """c (N, nc) for forces (N, 3)."""
        return forces @ self.G.T - self.h


@dataclass
class ForcePlaced:
    """A force constraint at its (contact node, foot) pairs.

    Attributes:
        bound: the :class:`ForceBound`.
        nodes: (N,) node index k of each pair (a node repeats once per foot in contact).
        feet: (N,) frame id of each pair's foot; slots: (N,) its position in the node's feet.
    """

    bound: ForceBound
    nodes: np.ndarray
    feet: np.ndarray
    slots: np.ndarray


class FrictionCone(Constraint):
    """Keep every contact force inside the linearised friction cone, with its normal component in
    [min_normal_force, max_normal_force] (N), at every contact node of a legged problem.

    Args:
        mu: friction coefficient (> 0).
        facets: number of facets of the linearised cone (even, >= 2; Crocoddyl's examples use 4).
        min_normal_force: the smallest normal force a foot in contact may carry (N, >= 0); a
            positive value keeps feet from nearly lifting while in contact.
        max_normal_force: the largest (N, > min_normal_force; inf for none).
        feet: frame names the constraint applies to; None: every foot.
        name: label in the result.
    """

    type = "friction_cone"
    equality = False
    on_contact_forces = True  # a constraint on the forces of a legged problem, not on its state

    def __init__(self, mu: float = 0.7, facets: int = 4, min_normal_force: float = 0.0,
                 max_normal_force: float = np.inf, feet: list[str] | tuple[str, ...] | None = None,
                 name: str | None = None) -> None:
        if isinstance(mu, bool) or not isinstance(mu, (int, float)) or not np.isfinite(mu) or mu <= 0:
            raise InputError("mu", f"expected a friction coefficient > 0, got {mu!r}")
        if isinstance(facets, bool) or not isinstance(facets, (int, np.integer)) or facets < 2 or facets % 2:
            raise InputError("facets", f"expected an even integer >= 2, got {facets!r}")
        for key, val in (("min_normal_force", min_normal_force), ("max_normal_force", max_normal_force)):
            if isinstance(val, bool) or not isinstance(val, (int, float)) or np.isnan(val):
                raise InputError(key, f"expected a number (N), got {val!r}")
        if not (0.0 <= min_normal_force < np.inf):
            raise InputError("min_normal_force", f"expected a finite force >= 0 (N), got {min_normal_force!r}")
        if not max_normal_force > min_normal_force:
            raise InputError("max_normal_force", f"expected more than min_normal_force = {min_normal_force}, "
                             f"got {max_normal_force!r}")
        if feet is not None:
            if isinstance(feet, str) or not all(isinstance(f, str) and f for f in feet) or not feet:
                raise InputError("feet", f"expected a list of frame names, got {feet!r}")
        self.mu, self.facets = float(mu), int(facets)
        self.min_normal_force, self.max_normal_force = float(min_normal_force), float(max_normal_force)
        self.feet = None if feet is None else tuple(feet)
        self.name = self._label(name)

    def describe(self) -> dict[str, Any]:
        return {"type": self.type, "mu": self.mu, "facets": self.facets, "min_normal_force": self.min_normal_force,
                "max_normal_force": None if np.isinf(self.max_normal_force) else self.max_normal_force,
                "feet": None if self.feet is None else list(self.feet)}

    def bind(self, model: Any) -> Any:
        raise InputError("constraints", f'a "{self.type}" constraint acts on the contact forces of a legged '
                         "problem (geoddp.problem.legged.ContactProblem), not on a model's state")

    def force_bound(self) -> ForceBound:
        """The rows G f - h <= 0 of one foot (see the module docstring)."""
        A, lb, ub = friction_cone(self.mu, self.facets, self.min_normal_force, self.max_normal_force)
        cone = A[:self.facets]
        G, h, labels = [cone], [np.zeros(self.facets)], [f"facet {j}" for j in range(self.facets)]
        G.append(-A[self.facets:]), h.append(-lb[self.facets:]), labels.append("min normal force")
        if np.isfinite(self.max_normal_force):
            G.append(A[self.facets:]), h.append(ub[self.facets:]), labels.append("max normal force")
        return ForceBound(np.vstack(G), np.concatenate(h), tuple(labels))

    def place(self, problem: Any) -> ForcePlaced:
        """This constraint at the (contact node, foot) pairs of a legged ``problem`` (its contact
        nodes k = 0..H-1 and their feet); InputError naming ``feet`` for a frame that is not one of
        its feet, ``constraints`` for a problem that is not legged."""
        nodes = getattr(problem, "nodes", None)
        model = getattr(problem, "model", None)
        if nodes is None or not hasattr(problem, "with_force_terms"):
            raise InputError("constraints", f'a "{self.type}" constraint needs a legged problem '
                             f"(geoddp.problem.legged.ContactProblem), got {type(problem).__name__}")
        every = sorted({f for n in nodes for f in n.feet})
        if self.feet is None:
            chosen = set(every)
        else:
            names = {model.frames[f].name: f for f in every}
            chosen = set()
            for i, name in enumerate(self.feet):
                if name not in names:
                    raise InputError(f"feet[{i}]", f"expected a foot of the problem ({', '.join(sorted(names))}), "
                                     f"got {name!r}")
                chosen.add(names[name])
        ks, feet, slots = [], [], []
        for k, n in enumerate(nodes):
            if n.kind != "contact":
                continue
            for i, f in enumerate(n.feet):
                if f in chosen:
                    ks.append(k), feet.append(f), slots.append(i)
        if not ks:
            raise InputError("feet", "no contact node has one of these feet on the ground")
        return ForcePlaced(self.force_bound(), np.array(ks), np.array(feet), np.array(slots))
