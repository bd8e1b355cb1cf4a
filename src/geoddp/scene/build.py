"""The one builder: a validated spec to a :class:`geoddp.problem.Problem`, the solver options of
its ``[solver]`` table and its initial controls.

It reads the general schema only (:class:`~geoddp.scene.multibody.MultibodySceneSpec`); a
satellite scene arrives translated (:meth:`~geoddp.scene.satellite.SceneSpec.general`). The
model's backend is chosen here, by structure: where the model is one body on a spherical root
without gravity, integrated by explicit or semi-implicit Euler, and every cost term has a closed
form on TSO(3) (control, frame_rotation of the body, a velocity-only state_regularisation), the
problem runs on the compiled TSO(3) closed forms (:class:`geoddp.models.satellite.Satellite`,
paper Section VI); anything else on :class:`geoddp.models.multibody.Multibody`.
"""
from __future__ import annotations

import functools
from typing import Any, Union

import numpy as np
import pinocchio as pin

from ..models.urdf import build_urdf_model
from ..validate import InputError
from .legged import LeggedSceneSpec
from .multibody import MultibodySceneSpec
from .satellite import SceneSpec

AnySceneSpec = Union[SceneSpec, MultibodySceneSpec, LeggedSceneSpec]
"""What :func:`geoddp.scene.load_scene` returns: a satellite, a multibody or a legged scene."""


def build_problem(spec: AnySceneSpec):
    """The validated scene as a :class:`geoddp.problem.Problem` (model, costs, horizon, x0); the
    model's backend is chosen when it is built (TSO(3) closed forms for the satellite). A fresh
    model each call. The shared tables (:mod:`.common`) act on the problem here, once for every kind:
    a scene with constraints gives a :class:`geoddp.constraints.ConstrainedProblem` around it. A
    legged scene gives a :class:`geoddp.problem.legged.ContactProblem`
    (:meth:`~geoddp.scene.legged.LeggedSceneSpec.build`)."""
    if isinstance(spec, LeggedSceneSpec):
        return spec.build()
    general = spec.general() if isinstance(spec, SceneSpec) else spec
    problem = _on_tso3(general) or _multibody(general)
    if general.has_limits:
        problem = problem.with_limits(control_limits(general, problem.model))
    if general.has_constraints:
        problem = constrained_problem(general, problem)
    return problem


def constrained_problem(spec: AnySceneSpec, problem: Any) -> Any:
    """``problem`` with the scene's ``[[constraints]]`` and ``[[terminal_constraints]]``: a
    :class:`geoddp.constraints.ConstrainedProblem` (its tolerance ``[solver].constraint_tol``);
    errors name the constraint's key path and the file."""
    from ..constraints import ConstrainedProblem, ConstraintOptions

    try:
        return ConstrainedProblem(problem, spec.constraints, spec.terminal_constraints,
                                  ConstraintOptions(constraint_tol=spec.constraint_tol))
    except InputError as e:
        raise e.with_source(spec.source) from None


def control_limits(spec: AnySceneSpec, model: Any = None) -> tuple[np.ndarray, np.ndarray] | None:
    """The scene's ``[limits]`` as (lower, upper), each (m,) (-inf / inf where unbounded), or None.

    ``effort_limits = "urdf"`` reads the joint efforts of ``model`` (the built multibody model:
    :func:`geoddp.problem.limits.effort_limits`) and keeps the tighter of them and control_min /
    control_max; InputError naming ``[limits].control_min`` if that leaves lower > upper."""
    from ..problem.limits import effort_limits

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


def _on_tso3(spec: MultibodySceneSpec):
    """The problem on the TSO(3) backend, or None where its structure does not allow it.

    The same problem either way (the general model with these terms gives the same J* to 6e-16,
    tests/test_scene.py); this one runs the satellite's compiled closed forms, ~10x faster."""
    from ..costs.tso3 import CostSum
    from ..models.satellite import Satellite
    from ..problem import Problem

    if spec.root != "spherical" or spec.gravity or spec.integrator not in ("euler", "semi_implicit"):
        return None
    pm = _one_body_model(str(spec.urdf))
    if pm is None:
        return None
    running = [_tso3_term(c, pm) for c in spec.running_costs]
    terminal = [_tso3_term(c, pm) for c in spec.terminal_costs]
    if any(t is None for t in running + terminal):
        return None
    # about the joint (the fixed point): the URDF's centre-of-mass inertia moved there, or the scene's
    inertia = spec.inertia if spec.inertia is not None else pm.inertias[1].matrix()[3:, 3:]
    model = Satellite(inertia=inertia, actuation=spec.actuation, dt=spec.dt, integrator=spec.integrator,
                      second_order=spec.second_order, urdf=spec.urdf)
    R0 = pin.Quaternion(np.asarray(spec.q0)).toRotationMatrix()  # the rotation q0 denotes
    return Problem(model, R0, np.array(spec.v0), spec.horizon, CostSum(running), CostSum(terminal))


@functools.lru_cache(maxsize=32)
def _one_body_model(urdf: str) -> pin.Model | None:
    """The URDF on a spherical root if it is one rigid body (nv = 3), else None. Cached: read-only."""
    pm = build_urdf_model(urdf, pin.JointModelSpherical(), "[model].urdf")
    return pm if pm.nv == 3 else None


def _tso3_term(c: Any, pm: pin.Model):
    """The closed-form TSO(3) term of a general cost term (:mod:`geoddp.costs`), or None where there
    is none: frame_rotation of a frame rotating with the body (any frame of joint 1 whose placement
    has no rotation), a state_regularisation that weights the velocity only, any control term."""
    from ..costs.tso3 import AngularVelocityQuadratic, AttitudeChordal, AttitudeGeodesic, ControlQuadratic

    if c.gauss_newton:
        return None
    if c.type == "control":
        return ControlQuadratic(c.weight, c.reference)
    if c.type == "frame_rotation":
        f = pm.frames[pm.getFrameId(c.frame)]
        if f.parentJoint != 1 or not np.array_equal(f.placement.rotation, np.eye(3)):
            return None
        return (AttitudeChordal if c.distance == "chordal" else AttitudeGeodesic)(c.weight, c.reference)
    if c.type == "state_regularisation" and not np.any(c.weight[:3]) and not np.any(c.weight[:, :3]):
        return AngularVelocityQuadratic(c.weight[3:, 3:], c.reference[4:])
    return None


def _multibody(spec: MultibodySceneSpec):
    """The multibody model of ``spec.urdf`` (with ``spec.inertia`` on its one body, if given) with
    its cost terms."""
    from ..models.multibody import Multibody
    from ..models.satellite import _one_body
    from ..costs.multibody import MultibodyCostSum
    from ..problem import Problem

    if spec.second_order == "paper":
        raise InputError("second_order", "'paper' (the paper's eta-eta term) exists on the TSO(3) backend only: one "
                         "body on a spherical root, no gravity, integrator euler or semi_implicit, and costs with "
                         "closed forms there; use \"exact\"")
    model = Multibody(spec.urdf, root=spec.root, actuation=np.array(spec.actuation), dt=spec.dt,
                      integrator=spec.integrator, gravity=spec.gravity, second_order=spec.second_order,
                      package_dirs=spec.package_dirs)
    pm = model.pin_model
    if spec.inertia is not None:
        try:
            _one_body(pm, spec.inertia)
        except ValueError as e:
            raise InputError("inertia", f"replaces the inertia of a one-body model; {e}") from None
    running = MultibodyCostSum([c.build(pm) for c in spec.running_costs], model=pm)
    terminal = MultibodyCostSum([c.build(pm) for c in spec.terminal_costs], model=pm, terminal=True)
    return Problem(model, np.array(spec.q0), np.array(spec.v0), spec.horizon, running, terminal)


def solver_options(spec: AnySceneSpec, **overrides: Any):
    """The scene's ``[solver]`` table as :class:`geoddp.solver.SolverOptions`."""
    from ..solver import SolverOptions

    kw = dict(expansion=spec.expansion, switch_ratio=spec.switch_ratio, tol=spec.tol, rtol=spec.rtol,
              grad_tol=spec.grad_tol, grad_rtol=spec.grad_rtol, max_iter=spec.max_iter)
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
        R_ref^T R): :func:`frame_errors` at the one configuration, as floats.
    """
    rows = frame_errors(spec, np.asarray(q, dtype=float)[None])
    return [{k: float(v[0]) if isinstance(v, np.ndarray) else v for k, v in row.items()} for row in rows]


def frame_errors(spec: MultibodySceneSpec, Q: np.ndarray) -> list[dict[str, Any]]:
    """Distances of the frames of the scene's terminal frame terms from their references along a
    configuration sequence Q (N, nq), e.g. a solution's ``configurations``.

    Returns:
        One dict per terminal frame term (frame_placement, frame_translation, frame_rotation), in
        order: ``name``, ``frame``, ``type`` and, as the term constrains them, ``position_error_m``
        (N,) |p_k - p_ref| in metres and ``rotation_error_deg`` (N,) the angle of R_ref^T R_k in
        degrees (:func:`frame_target_errors`).
    """
    from ..models.multibody import Multibody

    pm = Multibody(spec.urdf, root=spec.root, dt=spec.dt, gravity=spec.gravity).pin_model
    targets = [(c.name, c.frame, c.type, c.reference) for c in spec.terminal_costs if c.frame is not None]
    return frame_target_errors(pm, Q, targets)


def frame_target_errors(model: pin.Model, Q: np.ndarray, targets: list[tuple[str, str, str, np.ndarray]]
                        ) -> list[dict[str, Any]]:
    """Distances of frames from target poses along configurations Q (N, nq) of ``model``.

    Args:
        model: the kinematic model (root joint as solved).
        Q: (N, nq) configurations.
        targets: (name, frame, type, reference) per target; type "frame_placement" (reference
            (4, 4) world placement), "frame_translation" ((3,) world position, m) or
            "frame_rotation" ((3, 3) world rotation).

    Returns:
        One dict per target: ``name``, ``frame``, ``type`` and, as the type constrains them,
        ``position_error_m`` (N,) |p_k - p_ref| and ``rotation_error_deg`` (N,) the geodesic
        angle |log3(R_ref^T R_k)| in degrees, with p_k, R_k the frame's world placement oMf(q_k).
    """
    Q = np.asarray(Q, dtype=float)
    data = model.createData()
    out = []
    for name, frame, kind, reference in targets:
        ref = np.asarray(reference)
        p_ref = ref[:3, 3] if kind == "frame_placement" else ref if kind == "frame_translation" else None
        R_ref = ref[:3, :3] if kind == "frame_placement" else ref if kind == "frame_rotation" else None
        row: dict[str, Any] = {"name": name, "frame": frame, "type": kind}
        if p_ref is not None:
            row["position_error_m"] = np.empty(len(Q))
        if R_ref is not None:
            row["rotation_error_deg"] = np.empty(len(Q))
        out.append((model.getFrameId(frame), p_ref, R_ref, row))
    for k, q in enumerate(Q):
        pin.framesForwardKinematics(model, data, q)
        for fid, p_ref, R_ref, row in out:
            M = data.oMf[fid]
            if p_ref is not None:
                row["position_error_m"][k] = np.linalg.norm(M.translation - p_ref)
            if R_ref is not None:
                row["rotation_error_deg"][k] = np.degrees(np.linalg.norm(pin.log3(R_ref.T @ M.rotation)))
    return [row for *_, row in out]


def build_multibody_problem(spec: MultibodySceneSpec):
    """:func:`build_problem` of a multibody spec (the older name)."""
    return build_problem(spec)
