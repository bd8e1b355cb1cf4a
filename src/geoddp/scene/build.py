"""The one builder: a validated spec (either kind) to a :class:`geoddp.problem.Problem`, the
solver options of its ``[solver]`` table and its initial controls.

A satellite spec becomes the one-body model of its URDF (spherical root, no gravity, the scene's
inertia) whose backend is chosen by structure (:func:`geoddp.models.satellite.satellite_model`:
the compiled TSO(3) closed forms for the Euler schemes), with the paper's costs; a multibody spec
becomes a :class:`geoddp.models.multibody.Multibody` with its cost terms.
"""
from __future__ import annotations

from typing import Any, Union

import numpy as np
import pinocchio as pin

from ..validate import InputError
from .multibody import MultibodySceneSpec
from .satellite import SceneSpec

AnySceneSpec = Union[SceneSpec, MultibodySceneSpec]
"""What :func:`geoddp.scene.load_scene` returns: a satellite or a multibody scene."""


def build_problem(spec: AnySceneSpec):
    """The validated scene as a :class:`geoddp.problem.Problem` (model, costs, horizon, x0); the
    model's backend is chosen when it is built (TSO(3) closed forms for the satellite). A fresh
    model each call. The shared tables (:mod:`.common`) act on the problem here, once for every kind."""
    problem = _satellite(spec) if isinstance(spec, SceneSpec) else _multibody(spec)
    if spec.has_limits:
        problem = problem.with_limits(control_limits(spec, problem.model))
    return problem


def control_limits(spec: AnySceneSpec, model: Any = None) -> tuple[np.ndarray, np.ndarray] | None:
    """The scene's ``[limits]`` as (lower, upper), each (m,) (-inf / inf where unbounded), or None.

    ``effort_limits = "urdf"`` reads the joint efforts of ``model`` (the built multibody model:
    :func:`geoddp.limits.effort_limits`) and keeps the tighter of them and control_min /
    control_max; InputError naming ``[limits].control_min`` if that leaves lower > upper."""
    from ..limits import effort_limits

    if not spec.has_limits:
        return None
    m = spec.num_inputs
    lo = np.full(m, -np.inf) if spec.control_min is None else np.array(spec.control_min)
    hi = np.full(m, np.inf) if spec.control_max is None else np.array(spec.control_max)
    if spec.effort_limits == "urdf":
        try:
            e_lo, e_hi = effort_limits(model.pin_model.effortLimit, model.actuation)
        except InputError as e:
            raise e.with_source(spec.source) from None
        lo, hi = np.maximum(lo, e_lo), np.minimum(hi, e_hi)
        if np.any(lo > hi):
            i = int(np.argmax(lo > hi))
            raise InputError("[limits].control_min", f"input {i}: control_min = {lo[i]} is above the URDF effort "
                             f"limit {hi[i]} (effort_limits = \"urdf\" keeps the tighter bound)", spec.source)
    return lo, hi


def _satellite(spec: SceneSpec):
    """The one-body model of ``spec.urdf`` (default satellite.urdf) with the paper's costs."""
    from ..problem import satellite_problem

    return satellite_problem(
        inertia=spec.inertia, actuation=spec.actuation, dt=spec.dt, horizon=spec.horizon,
        R0=spec.R0, Omega0=spec.Omega0, R_d=spec.Rd, Omega_d=spec.Omegad,
        S_u=spec.S_u, S_R=spec.S_R, S_Omega=spec.S_Omega, attitude_kind=spec.attitude_kind,
        running_S_R=spec.running_S_R, running_S_Omega=spec.running_S_Omega,
        integrator=spec.integrator, second_order=spec.second_order, urdf=spec.urdf,
    )


def _multibody(spec: MultibodySceneSpec):
    """The multibody model of ``spec.urdf`` with its cost terms."""
    from ..models.multibody import Multibody
    from ..multibody_costs import MultibodyCostSum
    from ..problem import Problem

    model = Multibody(spec.urdf, root=spec.root, actuation=np.array(spec.actuation), dt=spec.dt,
                      integrator=spec.integrator, gravity=spec.gravity, second_order=spec.second_order,
                      package_dirs=spec.package_dirs)
    pm = model.pin_model
    running = MultibodyCostSum([c.build(pm) for c in spec.running_costs], model=pm)
    terminal = MultibodyCostSum([c.build(pm) for c in spec.terminal_costs], model=pm, terminal=True)
    return Problem(model, np.array(spec.q0), np.array(spec.v0), spec.horizon, running, terminal)


def solver_options(spec: AnySceneSpec, **overrides: Any):
    """The scene's ``[solver]`` table as :class:`geoddp.solver.SolverOptions`."""
    from ..solver import SolverOptions

    kw = dict(expansion=spec.expansion, switch_ratio=spec.switch_ratio, tol=spec.tol,
              grad_tol=spec.grad_tol, max_iter=spec.max_iter)
    kw.update(overrides)
    return SolverOptions(**kw)


def initial_controls(spec: AnySceneSpec) -> np.ndarray | None:
    """The scene's (H, m) initial control guess, or None for zeros."""
    return spec.initial_control_sequence()


def terminal_frame_errors(spec: MultibodySceneSpec, q: np.ndarray) -> list[dict[str, Any]]:
    """Distances of the frames of the terminal frame terms from their references at configuration
    q (nq,), e.g. the solution's last configuration.

    Returns:
        One dict per terminal frame term, in order: ``name``, ``frame``, ``type`` and, as the term
        constrains them, ``position_error_m`` (|p - p_ref|) and ``rotation_error_deg`` (the angle of
        R_ref^T R).
    """
    from ..models.multibody import Multibody

    pm = Multibody(spec.urdf, root=spec.root, dt=spec.dt, gravity=spec.gravity).pin_model
    data = pm.createData()
    pin.framesForwardKinematics(pm, data, np.asarray(q, dtype=float))
    out = []
    for c in spec.terminal_costs:
        if c.frame is None:
            continue
        M = data.oMf[pm.getFrameId(c.frame)]
        row: dict[str, Any] = {"name": c.name, "frame": c.frame, "type": c.type}
        ref = np.asarray(c.reference)
        p_ref = ref[:3, 3] if c.type == "frame_placement" else ref if c.type == "frame_translation" else None
        R_ref = ref[:3, :3] if c.type == "frame_placement" else ref if c.type == "frame_rotation" else None
        if p_ref is not None:
            row["position_error_m"] = float(np.linalg.norm(M.translation - p_ref))
        if R_ref is not None:
            row["rotation_error_deg"] = float(np.degrees(np.linalg.norm(pin.log3(R_ref.T @ M.rotation))))
        out.append(row)
    return out


def build_multibody_problem(spec: MultibodySceneSpec):
    """:func:`build_problem` of a multibody spec (the older name)."""
    return build_problem(spec)
