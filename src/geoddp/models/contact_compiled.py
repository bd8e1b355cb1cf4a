"""The compiled backend of a legged contact problem: :class:`geoddp._core.ContactKernel` built from a
:class:`geoddp.problem.legged.ContactProblem`.

The kernel (cpp/dynamics/contact.hpp) is the C++ twin of the problem's Python node models: the
node dynamics of :class:`geoddp.models.contact.ContactDynamics` (contact nodes: forward dynamics
with Baumgarte stabilisation, semi-implicit Euler; impulse nodes: the velocity jump), the gait
costs of ``ContactProblem._cost`` (values, gradients in z = (dq, dv, du), Gauss-Newton Hessians)
and the first-order expansion of ``ContactProblem.linearise(traj, 1)``: the same Pinocchio calls
in the same order, the same results to round-off (tests/test_contact_compiled.py). It holds a
copy of every datum it reads (schedule, targets, weights, bounds, friction cone, q0, v0), taken
when it is built, and a reference to the ``pin.Model``.

Arrays in and out are float64, C-contiguous, row-major; shapes: Q (H + 1, nq), V (H + 1, nv),
U (H, nu), node costs (H + 1) (running contact nodes dt-scaled, as the Python costs).
"""
from __future__ import annotations

import numpy as np

from ..kernels import core as _core
from ..validate import InputError

__all__ = ["build_kernel"]


def _node(node) -> tuple:
    """``node`` (:class:`geoddp.problem.legged.Node`) as the kernel reads it: (impulse, feet,
    com (3,) or None, ((frame id, target (3,)), ...))."""
    com = None if node.com is None else np.ascontiguousarray(node.com, dtype=np.float64)
    swing = tuple((int(f), np.ascontiguousarray(p, dtype=np.float64)) for f, p in node.swing)
    return (node.kind == "impulse", [int(f) for f in node.feet], com, swing)


def build_kernel(problem):
    """The compiled twin (``geoddp._core.ContactKernel``) of ``problem``
    (:class:`geoddp.problem.legged.ContactProblem`): its robot, contact model, schedule and costs as
    they are now. InputError ("problem") for a problem with terms the kernel does not have (flat
    feet, a nonzero ``costs.base_placement`` or ``costs.force_regularisation``): those run the
    Python node models (``ContactProblem.compiled`` is False for them)."""
    dyn, c = problem.dyn, problem.costs
    # a kernel without terms the problem has would cost it wrongly without a word: refuse
    missing = [name for name, present in (("flat feet (6D contacts)", bool(problem.flat_feet)),
                                          ("costs.base_placement", bool(c.base_placement)),
                                          ("costs.force_regularisation", bool(c.force_regularisation)))
               if present]
    if missing:
        raise InputError("problem", f"the compiled kernel has point feet and Crocoddyl's gait costs only; this "
                         f"problem has {', '.join(missing)}: run it with backend=\"python\"")
    Kp, Kd = dyn.gains
    weights = np.array([c.com, c.friction_cone, c.foot, c.state, c.control, c.bounds, c.impulse_foot,
                        c.impulse_state, c.impulse_control], dtype=np.float64)
    A, lb, ub = problem.cone

    def arr(x):
        return np.ascontiguousarray(x, dtype=np.float64)

    nodes = [_node(n) for n in problem.nodes] + [_node(problem.terminal_node)]
    return _core.ContactKernel(dyn.model, float(dyn.dt), float(Kp), float(Kd), float(dyn.impulse_damping), nodes,
                               weights, arr(problem.q0), arr(problem.v0), arr(problem.w_state),
                               arr(problem.w_impulse), arr(problem.lb), arr(problem.ub), arr(problem.q_ref),
                               arr(problem.v_ref), arr(problem.q_neutral), arr(A), arr(lb), arr(ub))
