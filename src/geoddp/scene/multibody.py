"""The multibody schema, the general one: a TOML scene of an optimal control problem on any
Pinocchio URDF, read with the one :class:`~geoddp.scene.reader.Reader` into a frozen
:class:`MultibodySceneSpec` (built by :func:`geoddp.scene.build.build_problem`).

Selected by ``[model] kind = "multibody"`` (without ``kind`` a scene is a satellite scene). The
parser checks every key against the model it names (frame and joint names, nq, nv, m).

Schema (``?`` = optional, with its default; paths as they appear in error messages)::

    name? = file stem                   description? = ""
    [model]      kind = "multibody", and exactly one of
                   robot (a robot of example-robot-data by name: "ur5", "solo12", ...; the
                     optional extra geoddp[robots]) | urdf (path, relative to the scene file),
                 package_dirs? (path | list of paths, relative to the scene file: where the
                   URDF's package:// mesh URIs are found, before ROS_PACKAGE_PATH; a robot's
                   own directory is added), srdf? (path: named postures; a robot's own SRDF),
                 root? = the robot's root (free flyer or fixed), else "free_flyer"
                   (free_flyer | spherical | fixed), gravity? = true,
                 inertia? (3 numbers or 3x3, kg m^2: replaces the inertia of a one-body model on a
                   spherical root, the satellite; its mass is kept)
    [actuation]? type? = "identity" (identity | matrix | thrusters | quadrotor | joints)
                 matrix (nv x m)                     for type = "matrix"
                 positions, directions (k x 3)       for type = "thrusters" (free-flyer root)
                 arm_length, torque_coefficient      for type = "quadrotor" (free-flyer root)
                 joints (list of joint names)        for type = "joints"; with thrusters or
                                                     quadrotor: joint motors after the root's
    [initial]?   q: (nq) | a posture name ("neutral" or a group_state of the SRDF:
                 "standing", "half_sitting", ...) | {posture? = "neutral", joints? = {joint
                 name = value (rad | m; the joint's nq coordinates for a multi-coordinate joint)}}
                 | a root pose: translation? (3, free flyer), and one of
                 quaternion (x,y,z,w) | rotation (3x3) | axis (3) + angle_deg; default neutral
                 v? = 0 (nv)
    [horizon]    dt (s), exactly one of steps (H) | tf (s, a multiple of dt),
                 integrator? = "euler" (models.multibody.INTEGRATORS)
    [[running_costs]], [[terminal_costs]]   (at least one term in all), each a table with
                 type (frame_placement | frame_rotation | frame_translation |
                       state_regularisation | control), name? (a label)
      frame_placement     frame, weight (scalar | 6 | 6x6, [linear; angular]),
                          translation + one rotation form, or at_configuration (nq)
      frame_rotation      frame, weight (3 | 3x3), one rotation form or at_configuration,
                          distance? = "geodesic" (geodesic | chordal)
      frame_translation   frame, weight (3), translation or at_configuration
      (frame terms)       gauss_newton? = false
      state_regularisation  q_reference? = "neutral" ("neutral" | "initial" | nq),
                          v_reference? = 0 (nv), and weight (scalar | 2nv | 2nv x 2nv)
                          or q_weight? / v_weight? (scalar | nv, default 0), gauss_newton? = false
      control             weight (scalar | m | m x m), reference? = 0 (m | "quasi_static" |
                          "gravity_compensation" | "hover"); running only
    [solver]?    as for satellite scenes (expansion, switch_ratio, tol | rtol, grad_tol | grad_rtol, max_iter,
                 second_order? = "exact"; "paper" too on a spherical root without gravity);
                 initial_controls? = "quasi_static" (the default) | "gravity_compensation" (the same)
                 | "hover" | "zero" | (m) | (H x m); constraint_tol? = 1e-8
    [[constraints]]?, [[terminal_constraints]]?  hard constraints (geoddp.scene.constraints)

Weights are positive semidefinite (PSD). Running costs are summed over the H nodes without a dt
factor (Crocoddyl multiplies running costs by dt: divide its weights by dt to compare).
"quasi_static" (alias "gravity_compensation") is the input u = argmin |H u - g(q0)| (least
squares), g Pinocchio's generalised gravity at the initial configuration at rest: the input that
holds the start posture where the actuation can (zero without gravity); as initial controls it is
clipped into the limits, and it is the default start. "hover" is the same input where it balances
gravity exactly (inside the limits, for initial controls), and refused where it does not.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from .. import validate as v
from ..validate import InputError
from .common import TABLES, CommonSpec, initial_in_limits, read_common, readonly
from .constraints import ARRAYS as CONSTRAINT_ARRAYS
from .frames import POSE_KEYS, ROTATION_FORMS, placement_reference, read_configuration, read_frame
from .reader import Reader, Schema, check_urdf

COST_TYPES = ("frame_placement", "frame_rotation", "frame_translation", "state_regularisation", "control")
DISTANCES = ("geodesic", "chordal")  # of a frame_rotation term
ACTUATION_TYPES = ("identity", "matrix", "thrusters", "quadrotor", "joints")
DEFAULT_INTEGRATOR = "euler"
# inputs holding the start posture against gravity (least squares; "hover": only where exact)
HOLDING = ("quasi_static", "gravity_compensation", "hover")
INITIAL_CONTROLS = HOLDING + ("zero",)  # [solver].initial_controls by name; default "quasi_static"

ARRAYS = ("running_costs", "terminal_costs") + CONSTRAINT_ARRAYS
SCHEMA: Schema = {  # [table] -> key -> required?
    "model": {"kind": True, "urdf": False, "robot": False, "package_dirs": False, "srdf": False, "root": False,
              "gravity": False, "inertia": False},
    "actuation": {"type": False, "matrix": False, "positions": False, "directions": False,
                  "arm_length": False, "torque_coefficient": False, "joints": False},
    "initial": {"q": False, "v": False, "translation": False, "quaternion": False, "rotation": False,
                "axis": False, "angle_deg": False},
    "horizon": {"dt": True, "steps": False, "tf": False, "integrator": False},
    **TABLES,
}
REQUIRED = ("model", "horizon")
# keys each actuation type uses (besides "type")
_ACTUATION_KEYS = {
    "identity": (),
    "matrix": ("matrix",),
    "thrusters": ("positions", "directions", "joints"),
    "quadrotor": ("arm_length", "torque_coefficient", "joints"),
    "joints": ("joints",),
}
_ACTUATION_REQUIRED = {"matrix": ("matrix",), "thrusters": ("positions", "directions"),
                       "quadrotor": ("arm_length", "torque_coefficient"), "joints": ("joints",)}
_COST_KEYS = {
    "frame_placement": ("frame", "weight", "at_configuration", "gauss_newton") + POSE_KEYS,
    "frame_rotation": ("frame", "weight", "at_configuration", "gauss_newton", "quaternion", "rotation", "axis",
                       "angle_deg", "distance"),
    "frame_translation": ("frame", "weight", "at_configuration", "gauss_newton", "translation"),
    "state_regularisation": ("q_reference", "v_reference", "weight", "q_weight", "v_weight", "gauss_newton"),
    "control": ("weight", "reference"),
}
_COMMON_COST_KEYS = ("type", "name")


# --------------------------------------------------------------------------------------
# the spec


@dataclass(frozen=True, eq=False)
class CostTermSpec:
    """One validated cost term of a multibody scene.

    Attributes:
        type: one of :data:`COST_TYPES`.
        name: label (the TOML ``name``, else ``"<type>"``).
        path: where it came from, e.g. ``"terminal_costs[0]"`` (used in error messages).
        frame: frame name (frame terms), else None.
        reference: the resolved reference: (4, 4) placement (frame_placement), (3, 3) rotation
            (frame_rotation), (3,) position in m (frame_translation), (nq + nv,) = (q_ref, v_ref)
            (state_regularisation), (m,) input (control).
        weight: (nr, nr) PSD weight matrix.
        gauss_newton: drop the second-order part of l_xx (frame and state terms).
        distance: of a frame_rotation term: "geodesic" (1/2 r^T W r, r = log3(R_ref^T R)) or
            "chordal" (1/2 ||I - R_ref^T R||^2_W, paper eq. costR), each on every model.
    """

    type: str
    name: str
    path: str
    frame: str | None
    reference: np.ndarray
    weight: np.ndarray
    gauss_newton: bool = False
    distance: str = "geodesic"

    def build(self, model: pin.Model) -> Any:
        """The :mod:`geoddp.costs.multibody` term on ``model``."""
        from ..costs import multibody as mc

        W, ref = np.array(self.weight), np.array(self.reference)
        if self.type == "frame_placement":
            return mc.FramePlacement(model, self.frame, ref, W=W, gauss_newton=self.gauss_newton)
        if self.type == "frame_rotation" and self.distance == "chordal":
            return mc.FrameRotationChordal(model, self.frame, ref, W=W, gauss_newton=self.gauss_newton)
        if self.type == "frame_rotation":
            return mc.FrameRotation(model, self.frame, ref, W=W, gauss_newton=self.gauss_newton)
        if self.type == "frame_translation":
            return mc.FrameTranslation(model, self.frame, ref, W=W, gauss_newton=self.gauss_newton)
        if self.type == "state_regularisation":
            return mc.StateRegularisation(model, ref[: model.nq], ref[model.nq :], W=W, gauss_newton=self.gauss_newton)
        return mc.ControlRegularisation(ref, W=W)


@dataclass(frozen=True, eq=False)
class MultibodySceneSpec(CommonSpec):
    """A validated multibody optimal control problem, as plain values.

    Attributes:
        name, description: free text; source: scene file path or ``"<dict>"``.
        urdf: absolute path of the URDF (a robot's: example-robot-data's file).
        root: "free_flyer" | "spherical" | "fixed".
        gravity: Pinocchio's default gravity on (True) or off.
        actuation: (nv, m) input-to-generalised-force matrix.
        q0: (nq,) initial configuration; v0: (nv,) initial velocity.
        dt: time step, s; horizon: H, number of control steps.
        integrator: one of :data:`geoddp.models.multibody.INTEGRATORS`.
        running_costs, terminal_costs: tuples of :class:`CostTermSpec`.
        initial_controls: None (the default start: the quasi-static controls of the built
            problem, :meth:`geoddp.problem.Problem.quasi_static_controls`), (m,) constant input
            or (H, m) sequence ("zero" is stored as zeros clipped into the limits).
        package_dirs: absolute directories searched for the URDF's ``package://`` mesh URIs.
        robot: the example-robot-data name of ``[model].robot``, or None.
        inertia: (3, 3) rotational inertia about the centre of mass, kg m^2, replacing the URDF's
            (its mass is kept), for a one-body model on a spherical root (the satellite); or None.
        expansion, switch_ratio, tol, rtol, grad_tol, grad_rtol, max_iter, second_order: the ``[solver]`` table
            (:class:`~geoddp.scene.common.CommonSpec`).

    Shared fields, ``dt``, ``horizon``, ``integrator`` and ``initial_controls`` can be replaced
    with :meth:`with_overrides` (re-validated); the rest is fixed by the scene file.
    """

    name: str
    description: str
    source: str
    urdf: Path
    root: str
    gravity: bool
    actuation: np.ndarray
    q0: np.ndarray
    v0: np.ndarray
    dt: float
    horizon: int
    integrator: str
    running_costs: tuple[CostTermSpec, ...]
    terminal_costs: tuple[CostTermSpec, ...]
    initial_controls: np.ndarray | None = None
    package_dirs: tuple[str, ...] = ()
    robot: str | None = None
    inertia: np.ndarray | None = None

    kind = "multibody"

    def __post_init__(self) -> None:
        from ..models import multibody as mbm

        put = lambda k, val: object.__setattr__(self, k, val)  # noqa: E731  (frozen dataclass)
        put("actuation", readonly(v.finite_array(self.actuation, "actuation", (None, None))))
        put("q0", readonly(v.finite_array(self.q0, "q0", (None,))))
        put("v0", readonly(v.finite_array(self.v0, "v0", (self.actuation.shape[0],))))
        put("dt", v.positive_float(self.dt, "dt"))
        put("horizon", v.positive_int(self.horizon, "horizon"))
        put("integrator", v.choice(self.integrator, "integrator", mbm.INTEGRATORS))
        put("running_costs", tuple(self.running_costs))
        put("terminal_costs", tuple(self.terminal_costs))
        if self.inertia is not None:
            if self.root != "spherical":
                raise InputError("inertia", f'expected None unless root = "spherical" (it replaces the inertia of a '
                                 f"one-body model), got root = {self.root!r}")
            put("inertia", readonly(v.inertia_matrix(self.inertia, "inertia")))
        self._check_common(second_order_kinds(self.root, self.gravity), self.num_inputs)
        if self.initial_controls is not None:
            m = self.num_inputs
            U = v.finite_array(self.initial_controls, "initial_controls")
            if U.shape not in ((m,), (self.horizon, m)):
                raise InputError("initial_controls", f"expected shape ({m},) or ({self.horizon}, {m}), got shape {U.shape}")
            put("initial_controls", readonly(U))
        self._check_initial_in_limits(self.initial_controls, "initial_controls")

    @property
    def num_inputs(self) -> int:
        """m, the number of inputs (columns of the actuation matrix)."""
        return int(self.actuation.shape[1])

    @property
    def tf(self) -> float:
        """Final time H dt, s."""
        return self.horizon * self.dt

    def initial_control_sequence(self) -> np.ndarray | None:
        """(H, m) initial guess for the solver, or None for the solver's default start (the
        quasi-static controls)."""
        if self.initial_controls is None:
            return None
        return np.array(np.broadcast_to(self.initial_controls, (self.horizon, self.num_inputs)))

    def read_initial_controls(self, value: Any, name: str = "initial_controls") -> np.ndarray | None:
        """``value`` as this scene's initial controls, checked as the ``[solver]`` table's are
        (:func:`read_initial_controls`: a name of :data:`INITIAL_CONTROLS`, (m,) or (H, m), inside
        the limits); InputError naming ``name``. None means the default (quasi-static) start."""
        def hover(param: str) -> np.ndarray:  # the reader's model: the URDF as parsed, gravity as set
            from ..models import multibody as mbm

            pm = mbm.Multibody(self.urdf, root=self.root, dt=self.dt, integrator=self.integrator, gravity=self.gravity,
                               package_dirs=self.package_dirs).pin_model
            return holding_input(pm, np.array(self.actuation), np.array(self.q0), param)

        return read_initial_controls(value, name, self.num_inputs, self.horizon, hover, self.control_min,
                                     self.control_max)

    def with_overrides(self, **overrides: Any) -> "MultibodySceneSpec":
        """A copy with shared fields (solver options), ``dt``, ``horizon``, ``integrator`` or
        ``initial_controls`` replaced, re-validated (e.g. ``spec.with_overrides(integrator="euler", horizon=60)``)."""
        allowed = tuple(f.name for f in dataclasses.fields(CommonSpec)) + ("dt", "horizon", "integrator",
                                                                           "initial_controls")
        for k in overrides:
            if k not in allowed:
                guess = v.closest(k, allowed)
                hint = f"; did you mean {guess!r}?" if guess else ""
                raise InputError(k, f"cannot override this MultibodySceneSpec field{hint} (allowed: {', '.join(allowed)})")
        return dataclasses.replace(self, **overrides)


def holding_input(pm: pin.Model, actuation: np.ndarray, q0: np.ndarray, name: str, kind: str = "hover"
                  ) -> np.ndarray:
    """The (m,) input holding configuration q0 (nq,) at rest against gravity, by ``kind``: least
    squares for "quasi_static" and "gravity_compensation"
    (:func:`geoddp.models.actuation.quasi_static_inputs`); for "hover" the input that balances
    gravity exactly (:func:`~geoddp.models.actuation.hover_inputs`), else an InputError naming
    ``name``. ``pm``: the scene's model with its gravity; ``actuation``: (nv, m)."""
    from ..models.actuation import hover_inputs, quasi_static_inputs

    if kind != "hover":
        return quasi_static_inputs(pm, actuation, q0)
    try:
        return hover_inputs(pm, actuation, q0)
    except InputError as e:
        raise InputError(name, f'"hover": {e.detail} (at the initial configuration; "quasi_static" takes the '
                         "least-squares input instead)") from None


def read_initial_controls(val: Any, name: str, m: int, H: int, hover: Callable[[str], np.ndarray],
                          lower: np.ndarray | None, upper: np.ndarray | None) -> np.ndarray | None:
    """A multibody scene's initial controls (``[solver].initial_controls``, or the keyword of
    :func:`geoddp.solve_scene`) as the spec stores them; InputError naming ``name``.

    Args:
        val: a name of :data:`INITIAL_CONTROLS`, an (m,) constant input or an (H, m) sequence (in
            the units of the model's inputs: N m, N).
        name: the parameter named in errors (``"[solver].initial_controls"``, ``"initial_controls"``).
        m, H: the number of inputs and the horizon.
        hover: ``hover(name)``: the input that balances gravity exactly at the initial state
            (:func:`holding_input`), called for "hover" only.
        lower, upper: the scene's ``[limits]`` control_min / control_max, (m,) each or None.

    Returns:
        None for "quasi_static" and "gravity_compensation" (the default start: made by the solver
        from the built problem, clipped into all of its limits, URDF efforts included); the hover
        input (m,); zeros (m,) clipped into [lower, upper] for "zero"; the array as given.
    """
    if isinstance(val, str):
        val = v.choice(val, name, INITIAL_CONTROLS)
        if val == "hover":
            return _inside(hover(name), lower, upper, name)
        if val == "zero":  # zeros projected into the limits (URDF effort limits contain 0)
            return np.clip(np.zeros(m), -np.inf if lower is None else lower, np.inf if upper is None else upper)
        return None
    U0 = v.finite_array(val, name)
    if U0.shape not in ((m,), (H, m)):
        raise InputError(name, f'expected one of {", ".join(map(repr, INITIAL_CONTROLS))}, a constant input of shape '
                         f"({m},) or a sequence of shape ({H}, {m}), got shape {U0.shape}")
    return _inside(U0, lower, upper, name)


def _inside(U0: np.ndarray, lower: np.ndarray | None, upper: np.ndarray | None, name: str) -> np.ndarray:
    initial_in_limits(U0, lower, upper, name)
    return U0


def second_order_kinds(root: str, gravity: bool) -> tuple[str, ...]:
    """The ``second_order`` values a model allows: the paper's expansion of the reconstruction
    (Section IV, eta-eta term included) exists for TSO(3) only, so a spherical root without gravity."""
    from ..models import multibody as mbm

    return ("exact", "paper") if root == "spherical" and not gravity else mbm.SECOND_ORDER_KINDS


# --------------------------------------------------------------------------------------
# parsing


def _joint_names(model: pin.Model) -> list[str]:
    return [str(n) for n in list(model.names)[1:]]


def parse_multibody_scene(data: Mapping[str, Any], source: str, base_dir: Path, default_name: str) -> MultibodySceneSpec:
    """Validate a parsed multibody scene (``[model] kind = "multibody"``) into a spec.

    Args:
        data: the dict a TOML parser produced.
        source: the scene file path (for messages) or ``"<dict>"``.
        base_dir: directory that a relative ``[model].urdf`` is resolved against.
        default_name: scene name when the file has no ``name``.

    Raises:
        InputError: naming the key path, e.g. ``running_costs[1].frame`` or ``[horizon].dt``.
    """
    from ..models import multibody as mbm

    r = Reader(data, source, SCHEMA, arrays=ARRAYS, required=REQUIRED)
    r.top()
    name = r.string(data.get("name", default_name), "name")
    description = r.string(data.get("description", ""), "description")

    # ---- model
    model_t = r.table("model")
    urdf, robot, default_root, package_dirs, srdf = _model_source(r, model_t, base_dir)
    root = r.check(v.choice, model_t.get("root", default_root), "[model].root", mbm.ROOTS)
    gravity = r.boolean(model_t.get("gravity", True), "[model].gravity")
    inertia = None
    if "inertia" in model_t:
        if root != "spherical":
            raise r.err("[model].inertia", f'expected only with root = "spherical" (it replaces the inertia of a '
                        f"one-body model), got root = {root!r}")
        inertia = r.check(v.inertia_matrix, model_t["inertia"], "[model].inertia")
    horizon_t = r.table("horizon")
    dt = r.check(v.positive_float, horizon_t["dt"], "[horizon].dt")
    integrator = r.check(v.choice, horizon_t.get("integrator", DEFAULT_INTEGRATOR), "[horizon].integrator",
                         mbm.INTEGRATORS)
    if ("steps" in horizon_t) == ("tf" in horizon_t):
        got = "both" if "steps" in horizon_t else "neither"
        raise r.err("[horizon]", f"expected exactly one of steps (number of control steps H) | tf (s), got {got}")
    if "steps" in horizon_t:
        H = r.check(v.positive_int, horizon_t["steps"], "[horizon].steps")
    else:
        H = r.check(v.time_grid, horizon_t["tf"], dt, tf_name="[horizon].tf", dt_name="[horizon].dt")
    # The model without actuation first: frame, joint and dimension checks need it.
    try:
        bare = mbm.Multibody(urdf, root=root, dt=dt, integrator=integrator, gravity=gravity, package_dirs=package_dirs)
    except InputError as e:
        raise r.err(f"[model].{e.parameter}", e.detail) from None
    pm = bare.pin_model
    nv = pm.nv
    if inertia is not None and nv != 3:
        raise r.err("[model].inertia", f"expected a one-body model (nv = 3 on the spherical root), got nv = {nv}")

    # ---- actuation
    act_t = r.table("actuation")
    actuation = _actuation(r, act_t, pm, root)
    m = actuation.shape[1]

    # ---- initial state
    init_t = r.table("initial")
    q0 = _initial_q(r, init_t, pm, root, srdf)
    v0 = r.check(v.finite_array, init_t.get("v", np.zeros(nv)), "[initial].v", (nv,))

    def hover(path: str, name: str = "hover") -> np.ndarray:
        """The input holding q0 against gravity (``name``): :func:`holding_input`, errors naming the file."""
        return r.check(holding_input, pm, actuation, q0, path, name)

    # ---- costs
    ctx = _CostContext(r, pm, q0, m, hover)
    running = [_cost_term(t, path, ctx, terminal=False) for path, t in r.array("running_costs")]
    terminal = [_cost_term(t, path, ctx, terminal=True) for path, t in r.array("terminal_costs")]
    if not running and not terminal:
        raise r.err("[[running_costs]]", "expected at least one cost term in [[running_costs]] or [[terminal_costs]]")

    # ---- solver
    common = read_common(r, second_order_kinds(root, gravity), m, pm)
    s = r.table("solver")
    U0 = None
    if "initial_controls" in s:
        U0 = r.check(read_initial_controls, s["initial_controls"], "[solver].initial_controls", m, H, hover,
                     common["control_min"], common["control_max"])
    return MultibodySceneSpec(
        name=name, description=description, source=source, urdf=urdf, root=root, gravity=gravity,
        actuation=actuation, q0=q0, v0=v0, dt=dt, horizon=H, integrator=integrator,
        running_costs=tuple(running), terminal_costs=tuple(terminal), initial_controls=U0,
        package_dirs=package_dirs, robot=robot, inertia=inertia, **common,
    )


def _model_source(r: Reader, t: Mapping[str, Any], base_dir: Path) -> tuple[Path, str | None, str, tuple[str, ...], Path | None]:
    """(URDF path, robot name or None, default root, package_dirs, SRDF or None) of ``[model]``:
    exactly one of ``robot`` (:func:`geoddp.models.robots.find`) and ``urdf``. Every
    ``package://`` mesh URI must name a package found in package_dirs (or ROS_PACKAGE_PATH /
    AMENT_PREFIX_PATH); a missing mesh file inside a found package is not an error here (the
    solve does not need meshes; the replay names it)."""
    from ..models import robots

    if ("robot" in t) == ("urdf" in t):
        got = "both" if "robot" in t else "neither"
        raise r.err("[model]", f"expected exactly one of robot (a robot of example-robot-data by name) | urdf (a path), got {got}")
    dirs: list[str] = []
    if "package_dirs" in t:
        val = t["package_dirs"]
        items = [val] if isinstance(val, str) else val
        if not isinstance(items, list) or not all(isinstance(d, str) and d for d in items):
            raise r.err("[model].package_dirs", f"expected a directory path or a list of them, got {val!r}")
        for i, d in enumerate(items):
            p = (base_dir / Path(d).expanduser()).resolve()
            if not p.is_dir():
                where = "[model].package_dirs" + ("" if isinstance(val, str) else f"[{i}]")
                raise r.err(where, f"expected an existing directory, got {d!r} (resolved to {p})")
            dirs.append(str(p))
    robot, srdf, root = None, None, "free_flyer"
    if "robot" in t:
        spec = r.check(robots.find, t["robot"], "[model].robot")
        robot, urdf, srdf, root = spec.name, spec.urdf, spec.srdf, spec.root
        dirs += [d for d in spec.package_dirs if d not in dirs]
    else:
        urdf = r.check(check_urdf, t["urdf"], "[model].urdf", base_dir)
    if "srdf" in t:
        val = t["srdf"]
        p = (base_dir / Path(val).expanduser()).resolve() if isinstance(val, str) and val else None
        if p is None or not p.is_file():
            raise r.err("[model].srdf", f"expected an existing SRDF file, got {val!r}" + (f" (resolved to {p})" if p else ""))
        srdf = p
    r.check(robots.check_meshes, urdf, dirs, "[model].package_dirs", "[model].urdf")
    return urdf, robot, root, tuple(dirs), srdf


def _joint_columns(r: Reader, val: Any, pm: pin.Model, root: str, path: str) -> np.ndarray:
    """(nv, k) unit columns for the degrees of freedom of the named joints."""
    names = _joint_names(pm)
    movable = [n for n in names if not (root != "fixed" and n == names[0])]
    if not isinstance(val, list) or not val or not all(isinstance(j, str) for j in val):
        raise r.err(path, f"expected a non-empty list of joint names, e.g. {movable[:3]}, got {val!r}")
    cols = []
    for i, j in enumerate(val):
        if j not in movable:
            guess = v.closest(j, movable)
            hint = f"did you mean {guess!r}? " if guess else ""
            extra = " (the root joint: actuate it with thrusters, quadrotor or matrix)" if j in names else ""
            raise r.err(f"{path}[{i}]", f"expected an actuated joint of the model{extra}, got {j!r}; {hint}"
                        f"joints: {', '.join(movable) or 'none'}")
        if val.index(j) != i:
            raise r.err(f"{path}[{i}]", f"expected each joint once, got {j!r} twice")
        jm = pm.joints[pm.getJointId(j)]
        for d in range(jm.nv):
            c = np.zeros(pm.nv)
            c[jm.idx_v + d] = 1.0
            cols.append(c)
    return np.array(cols).T


def _actuation(r: Reader, t: Mapping[str, Any], pm: pin.Model, root: str) -> np.ndarray:
    from ..models.actuation import quadrotor_actuation, thruster_actuation

    kind = r.check(v.choice, t.get("type", "identity"), "[actuation].type", ACTUATION_TYPES)
    uses = _ACTUATION_KEYS[kind]
    for key in t:
        if key != "type" and key not in uses:
            raise r.err(f"[actuation].{key}", f'not used by type = "{kind}"; keys for {kind}: '
                        f"{', '.join(('type',) + uses)}")
    for key in _ACTUATION_REQUIRED.get(kind, ()):
        if key not in t:
            raise r.err(f"[actuation].{key}", f'missing required key for type = "{kind}"')
    nv = pm.nv
    if kind == "identity":
        return np.eye(nv)
    if kind == "matrix":
        A = r.check(v.finite_array, t["matrix"], "[actuation].matrix")
        if A.ndim != 2 or A.shape[0] != nv or A.shape[1] < 1:
            raise r.err("[actuation].matrix", f"expected shape ({nv}, m) with m >= 1 (nv = {nv}), got shape {A.shape}")
        zero = np.flatnonzero(np.linalg.norm(A, axis=0) == 0.0)
        if zero.size:
            raise r.err("[actuation].matrix", f"expected every column to be non-zero, got an all-zero column {int(zero[0])}")
        return A
    if kind == "joints":
        return _joint_columns(r, t["joints"], pm, root, "[actuation].joints")
    if root != "free_flyer":
        raise r.err("[actuation].type", f'"{kind}" maps to the root body wrench and needs root = "free_flyer", '
                    f'got root = "{root}"')
    if kind == "thrusters":
        P = r.check(v.finite_array, t["positions"], "[actuation].positions")
        if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] < 1:
            raise r.err("[actuation].positions", f"expected shape (k, 3) with k >= 1 (one row per thruster, m), got shape {P.shape}")
        D = r.check(v.finite_array, t["directions"], "[actuation].directions")
        if D.shape != P.shape:
            raise r.err("[actuation].directions", f"expected shape {P.shape} (one per position), got shape {D.shape}")
        try:
            wrench = thruster_actuation(P, D)
        except InputError as e:
            raise r.err(f"[actuation].{e.parameter}", e.detail) from None
    else:
        ell = r.check(v.positive_float, t["arm_length"], "[actuation].arm_length")
        c = r.check(v.nonnegative_float, t["torque_coefficient"], "[actuation].torque_coefficient")
        wrench = quadrotor_actuation(ell, c)
    if nv == 6 and "joints" not in t:
        return wrench  # a single free body (kept as built: its memory layout fixes the summation order)
    A = np.zeros((nv, wrench.shape[1]))
    A[:6] = wrench
    if "joints" in t:
        A = np.hstack([A, _joint_columns(r, t["joints"], pm, root, "[actuation].joints")])
    return A


def _initial_q(r: Reader, t: Mapping[str, Any], pm: pin.Model, root: str, srdf: Path | None = None) -> np.ndarray:
    pose = [k for k in POSE_KEYS if k in t]
    if "q" in t:
        if pose:
            raise r.err("[initial]", f"expected q or a root pose ({', '.join(POSE_KEYS)}), got q and {', '.join(pose)}")
        q = t["q"]
        if isinstance(q, (str, Mapping)):
            return _posture(r, q, pm, srdf)
        return read_configuration(r, q, pm, "[initial].q")
    q = pin.neutral(pm)
    R = r.rotation(t, "[initial]", ROTATION_FORMS, required=False)
    if "translation" in t:
        if root != "free_flyer":
            raise r.err("[initial].translation", f'expected only with root = "free_flyer", got root = "{root}"')
        q[:3] = r.check(v.finite_array, t["translation"], "[initial].translation", (3,))
    if R is not None:
        if root == "fixed":
            raise r.err("[initial]", 'a root rotation needs root = "free_flyer" or "spherical", got root = "fixed"')
        i = 3 if root == "free_flyer" else 0
        if "quaternion" in t:
            q[i : i + 4] = t["quaternion"]  # as given (validated unit to 1e-9), like q
        else:
            q[i : i + 4] = pin.Quaternion(R).coeffs()
    return q


def _posture(r: Reader, val: Any, pm: pin.Model, srdf: Path | None) -> np.ndarray:
    """``[initial].q`` as a posture name or ``{posture, joints}`` (:func:`geoddp.models.robots.configuration`)."""
    from ..models import robots

    named = r.check(robots.postures, pm, srdf, "[model].srdf")
    if isinstance(val, str):
        return r.check(robots.configuration, pm, named, val, None, "[initial].q")
    r.keys(val, ["posture", "joints"], "[initial].q", "[initial].q")
    joints = val.get("joints", {})
    if not isinstance(joints, Mapping):
        raise r.err("[initial].q.joints", f"expected a table of joint name = value, got {joints!r}")
    return r.check(robots.configuration, pm, named, val.get("posture", "neutral"), joints, "[initial].q.posture")


@dataclass
class _CostContext:
    r: Reader
    pm: pin.Model
    q0: np.ndarray
    m: int
    hover: Any


def _cost_term(t: Mapping[str, Any], path: str, ctx: _CostContext, terminal: bool) -> CostTermSpec:
    r, pm = ctx.r, ctx.pm
    nv = pm.nv
    if "type" not in t:
        raise r.err(f"{path}.type", f"missing required key (one of {' | '.join(COST_TYPES)})")
    kind = r.check(v.choice, t["type"], f"{path}.type", COST_TYPES)
    allowed = _COMMON_COST_KEYS + _COST_KEYS[kind]
    r.keys(t, allowed, path, context=f' (type = "{kind}")')
    label = r.string(t.get("name", kind), f"{path}.name")
    if kind == "control" and terminal:
        raise r.err(f"{path}.type", 'a "control" term cannot be a terminal cost (there is no control at the final '
                    "node); put it in [[running_costs]]")
    gn = r.boolean(t.get("gauss_newton", False), f"{path}.gauss_newton")

    def need_weight() -> Any:
        if "weight" not in t:
            raise r.err(f"{path}.weight", "missing required key")
        return t["weight"]

    if kind in ("frame_placement", "frame_rotation", "frame_translation"):
        frame, M_at = read_frame(r, t, path, pm)
        refs = [k for k in POSE_KEYS if k in t]
        if M_at is not None and refs:
            raise r.err(f"{path}.at_configuration", f"expected either at_configuration or an explicit reference, "
                        f"got both (with {', '.join(refs)})")
        if kind == "frame_placement":
            W = r.weight(need_weight(), f"{path}.weight", 6)
            ref = placement_reference(r, t, path, M_at)
        elif kind == "frame_rotation":
            W = r.weight(need_weight(), f"{path}.weight", 3)
            ref = M_at.rotation if M_at is not None else r.rotation(t, path, ROTATION_FORMS)
            distance = r.check(v.choice, t.get("distance", "geodesic"), f"{path}.distance", DISTANCES)
            return CostTermSpec(kind, label, path, frame, readonly(ref), readonly(W), gn, distance)
        else:
            W = r.weight(need_weight(), f"{path}.weight", 3)
            if M_at is not None:
                ref = M_at.translation
            elif "translation" in t:
                ref = r.check(v.finite_array, t["translation"], f"{path}.translation", (3,))
            else:
                raise r.err(f"{path}.translation", "missing: a frame_translation reference needs translation (m) "
                            "or at_configuration")
        return CostTermSpec(kind, label, path, frame, readonly(ref), readonly(W), gn)

    if kind == "state_regularisation":
        qr = t.get("q_reference", "neutral")
        if isinstance(qr, str):
            qr = r.check(v.choice, qr, f"{path}.q_reference", ("initial", "neutral"))
            q_ref = pin.neutral(pm) if qr == "neutral" else ctx.q0.copy()
        else:
            q_ref = read_configuration(r, qr, pm, f"{path}.q_reference")
        v_ref = r.check(v.finite_array, t.get("v_reference", np.zeros(nv)), f"{path}.v_reference", (nv,))
        split = [k for k in ("q_weight", "v_weight") if k in t]
        if "weight" in t and split:
            raise r.err(f"{path}.weight", f"expected weight (2 nv = {2 * nv}) or q_weight / v_weight (nv = {nv}), "
                        f"got both weight and {' and '.join(split)}")
        if "weight" in t:
            W = r.weight(t["weight"], f"{path}.weight", 2 * nv)
        elif split:
            Wq = r.weight(t.get("q_weight", 0.0), f"{path}.q_weight", nv)
            Wv = r.weight(t.get("v_weight", 0.0), f"{path}.v_weight", nv)
            W = np.zeros((2 * nv, 2 * nv))
            W[:nv, :nv], W[nv:, nv:] = Wq, Wv
        else:
            raise r.err(f"{path}.weight", f"missing: give weight (2 nv = {2 * nv}) or q_weight and/or v_weight "
                        f"(nv = {nv})")
        ref = np.concatenate([q_ref, v_ref])
        return CostTermSpec(kind, label, path, None, readonly(ref), readonly(W), gn)

    # control
    W = r.weight(need_weight(), f"{path}.weight", ctx.m)
    u = t.get("reference", np.zeros(ctx.m))
    if isinstance(u, str):
        name = r.check(v.choice, u, f"{path}.reference", HOLDING)
        ref = ctx.hover(f"{path}.reference", name)
    else:
        ref = r.check(v.finite_array, u, f"{path}.reference", (ctx.m,))
    return CostTermSpec(kind, label, path, None, readonly(ref), readonly(W), False)
