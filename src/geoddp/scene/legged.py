"""Legged scenes: Crocoddyl's ANYmal gaits and Talos walk as Python builders and the legged scene
files (``[model] kind = "legged"``) that describe them and any other contact schedule.

Built-in problems (Crocoddyl's example quadrupedal_gaits_fwddyn.py):

* :func:`anymal_walk`: step length 0.25 m, height 0.15 m, dt 0.01 s, 25 step knots, 2 support knots.
* :func:`anymal_trot`: 0.15 m, 0.1 m, 0.01 s, 25, 2.
* :func:`anymal_jump`: jump height 0.15 m, length (0, 0.3, 0) m, dt 0.01 s, 10 ground knots, 20
  flying knots.

ANYmal comes from example-robot-data (``pip install example-robot-data``), posture "standing";
the problems are those Crocoddyl's ``SimpleQuadrupedalGaitProblem`` builds from a fresh instance,
node for node (contact nodes with Baumgarte gains (0, 50), impulse nodes at touch-down, the same
costs and weights: :mod:`geoddp.problem.legged`). The same problems are the built-in scene files
``anymal_walk``, ``anymal_trot`` and ``anymal_jump`` (``geoddp run anymal_trot``).

And a biped on flat feet (Crocoddyl's example bipedal_gaits_fwddyn.py, its walking phase):

* :func:`talos_walk`: Talos' legs ("talos_legs", posture "half_sitting"), 6D contacts of the soles
  (Baumgarte gains (0, 30)), step length 0.6 m, height 0.1 m, dt 0.03 s, 15 step knots, 4 support
  knots: Crocoddyl's ``SimpleBipedGaitProblem`` walk, node for node; the built-in scene
  ``talos_walk``.

Schema of a legged scene file (``?`` = optional, with its default; paths as in error messages)::

    name? = file stem                   description? = ""
    [model]      kind = "legged", robot (example-robot-data's name, free-flyer root),
                 feet (contact frame names; a [gait] takes four: LF, RF, LH, RH),
                 posture? = "standing" (a reference configuration of the robot: the start at
                 rest and the state regularisation's posture)
    [contact]    dt (s), baumgarte? = [0.0, 50.0] (Kp 1/s^2, Kd 1/s),
                 kind? = "3d" (point feet) | "6d" (flat feet: 6D contacts, placement tracking,
                 wrench cones; the [costs] default to Crocoddyl's biped's, GaitCosts.biped)
    exactly one of
    [gait]       type = "walk" | "trot": step_length (m), step_height (m), step_knots, support_knots
                 (a walk of two feet [right, left] is Crocoddyl's biped walk: it ends on the
                 left foot's landing impulse)
                 type = "jump": jump_height (m), jump_length (3, m), ground_knots, flying_knots
    [[phases]]   contacts (feet on the ground, [] in flight), knots (contact nodes),
                 step_length? (m, along x: the swing feet step and the CoM follows, as
                 Crocoddyl's footstep; with step_height? = 0), impulse? (a touch-down impulse
                 node after the phase for the swing feet that are down in the next phase, or
                 in the terminal node; default: true when some foot touches down),
                 base_placement? (a table {translation, rotation form?}: this phase's base
                 target, in place of [costs].base_placement's)
    [costs]?     weights of geoddp.problem.legged.GaitCosts: com, friction_cone, mu, foot, state,
                 control, bounds, impulse_foot, impulse_state (Crocoddyl's by default: its
                 quadruped's for point feet, its biped's for flat feet); and two terms Crocoddyl's
                 gaits do not have (off by default):
                 base_placement? = {weight (>= 0), translation (3, m), at most one of
                 rpy_deg (roll, pitch, yaw, degrees) | quaternion (x, y, z, w) | rotation (3x3) |
                 axis + angle_deg (default: the identity)}: the base's target placement, tracked at
                 every contact node and a contact terminal node;
                 force_regularisation? = {weight (>= 0), reference? = "weight_share" | "zero"}:
                 each support foot's force (a flat foot's wrench) toward m |g| / n_support along +z
                 (zero torque), or zero, at every contact node
    [solver]?    expansion, switch_ratio, tol, rtol, grad_tol, grad_rtol, max_iter,
                 initial_controls? = "quasi_static" ("quasi_static" | "zero")

The terminal node has every foot on the ground and the state terms only (Crocoddyl's walk and
trot); a jump's terminal node also tracks the landed CoM; a biped walk's is its last landing.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from .. import validate as v
from ..models.contact import ContactDynamics
from ..models.multibody import geometry_records
from ..problem.legged import FORCE_REFERENCES, BipedGait, ContactProblem, GaitCosts, Node, QuadrupedGait, footstep
from ..solver.options import DEFAULT_EXPANSION, DEFAULT_MAX_ITER, DEFAULT_SWITCH_RATIO, EXPANSIONS
from ..validate import InputError
from .common import CommonSpec, readonly
from .reader import Reader, Schema

FEET = ("LF_FOOT", "RF_FOOT", "LH_FOOT", "RH_FOOT")
GAITS = {"walk": (0.25, 0.15, 0.01, 25, 2), "trot": (0.15, 0.1, 0.01, 25, 2),
         "jump": (0.15, (0.0, 0.3, 0.0), 0.01, 10, 20)}  # jump: height, length (3,), dt, ground, flying knots
GAINS = (0.0, 50.0)  # Crocoddyl's Baumgarte gains (Kp, Kd) in its quadruped gaits
TALOS_FEET = ("right_sole_link", "left_sole_link")
TALOS_WALK = (0.6, 0.1, 0.03, 15, 4)  # step length, height, dt, step knots, support knots
TALOS_GAINS = (0.0, 30.0)  # Crocoddyl's Baumgarte gains in its biped gaits
FOOT_KINDS = ("3d", "6d")  # [contact].kind: point feet, flat feet (world-aligned 6D contacts)

GAIT_TYPES = ("walk", "trot", "jump")
_GAIT_KEYS = {"walk": ("step_length", "step_height", "step_knots", "support_knots"),
              "trot": ("step_length", "step_height", "step_knots", "support_knots"),
              "jump": ("jump_height", "jump_length", "ground_knots", "flying_knots")}
WEIGHT_KEYS = ("com", "friction_cone", "mu", "foot", "state", "control", "bounds", "impulse_foot", "impulse_state")
COST_KEYS = WEIGHT_KEYS + ("base_placement", "force_regularisation")  # the last two: tables
BASE_ROTATIONS = ("rpy_deg", "quaternion", "rotation", "axis")  # "axis" goes with "angle_deg"
BASE_KEYS = ("translation", "rpy_deg", "quaternion", "rotation", "axis", "angle_deg")  # a base target's table
FORCE_KEYS = ("weight", "reference")
INITIAL_CONTROLS = ("quasi_static", "zero")
SOLVER_KEYS = ("expansion", "switch_ratio", "tol", "rtol", "grad_tol", "grad_rtol", "max_iter", "initial_controls",
               "constraint_tol")
CONSTRAINT_KEYS = ("type", "name", "mu", "facets", "min_normal_force", "max_normal_force", "feet")
PHASE_KEYS = ("contacts", "knots", "step_length", "step_height", "impulse", "base_placement")
SCHEMA: Schema = {  # [table] -> key -> required?
    "model": {"kind": True, "robot": True, "feet": True, "posture": False},
    "contact": {"dt": True, "baumgarte": False, "kind": False},
    "gait": {"type": True, **{k: False for keys in _GAIT_KEYS.values() for k in keys}},
    "costs": {k: False for k in COST_KEYS},
    "solver": {k: False for k in SOLVER_KEYS},
}
ARRAYS = ("phases", "constraints")
REQUIRED = ("model", "contact")


# ------------------------------------------------------------------ the robot and the problem
def load_robot(name: str = "anymal", parameter: str = "robot"):
    """example-robot-data's robot ``name`` (a RobotWrapper, its SRDF's postures loaded);
    InputError naming ``parameter`` if the package is missing or has no such robot."""
    from ..models import robots

    try:
        import example_robot_data
    except ImportError:
        raise InputError(parameter, f"legged scenes need example-robot-data: {robots.INSTALL_HINT}") from None
    robots.find(name, parameter)  # the name checked, with did-you-mean
    return example_robot_data.load(name)


def load_anymal():
    """example-robot-data's ANYmal (a RobotWrapper); InputError naming ``example_robot_data`` if
    the package is missing."""
    try:
        import example_robot_data
    except ImportError:
        raise InputError("example_robot_data", "the ANYmal scenes need example-robot-data: pip install example-robot-data") from None
    return example_robot_data.load("anymal")


def contact_problem(robot, nodes: list[Node], terminal: Node, q0: np.ndarray, dt: float,
                    gains: tuple[float, float] = GAINS, costs: GaitCosts | None = None,
                    feet: tuple[str, ...] | None = None, foot_kind: str = "3d") -> ContactProblem:
    """The ContactProblem of a schedule on ``robot`` (a RobotWrapper) from q0 (nq,) at rest, the
    regularisation posture q0; its description carries the model (for the viewer) and, when
    ``feet`` (frame names) are given, the contact schedule (:func:`schedule`). ``foot_kind``: the
    contact kind of ``feet`` ("3d" point feet, "6d" flat feet). A model that is not its URDF's
    (talos_legs: the loader cut Talos to its legs) carries its visual geometry as records instead
    (:func:`geoddp.models.multibody.geometry_records`): the URDF's links beyond it would not load."""
    model = robot.model
    v0 = np.zeros(model.nv)
    urdf = Path(robot.urdf) if getattr(robot, "urdf", None) else None
    desc = {"kind": "multibody", "root": "free_flyer", "nq": model.nq, "nv": model.nv, "dt": dt,
            "integrator": "semi_implicit", "pin_model": model.saveToString()}
    if urdf is not None and urdf.is_file():
        if pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer()).nv == model.nv:
            desc.update(urdf=str(urdf), urdf_xml=urdf.read_text())
        elif getattr(robot, "visual_model", None) is not None:
            desc["geometry_objects"] = geometry_records(model, robot.visual_model)
    if feet is not None:
        desc["contact_schedule"] = schedule(model, feet, nodes, terminal, gains)
    kinds = {f: foot_kind for f in feet} if feet is not None and foot_kind != "3d" else {}
    return ContactProblem(ContactDynamics(model, dt, gains=gains, contact_kinds=kinds), nodes, terminal, q0, v0,
                          (q0.copy(), v0.copy()), costs=costs, description=desc)


def schedule(model: pin.Model, feet: tuple[str, ...], nodes: list[Node], terminal: Node,
             gains: tuple[float, float]) -> dict[str, Any]:
    """The contact schedule as the result JSON holds it (``model.contact_schedule``): ``feet``
    (frame names), ``contact`` (H + 1 rows of 0 / 1 per foot: on the ground at a contact node,
    touching down at an impulse node, on the ground in the terminal node), ``impulse`` (H
    booleans) and ``baumgarte`` (Kp, Kd)."""
    ids = [int(model.getFrameId(f)) for f in feet]
    rows = [[int(i in n.feet) for i in ids] for n in [*nodes, terminal]]
    return {"feet": list(feet), "contact": rows, "impulse": [n.kind == "impulse" for n in nodes],
            "baumgarte": [float(gains[0]), float(gains[1])]}


def anymal_gait(gait: str, robot=None) -> ContactProblem:
    """The ContactProblem of Crocoddyl's ANYmal ``gait`` ("walk", "trot" or "jump") from "standing" at rest."""
    if gait not in GAITS:
        raise InputError("gait", f"expected one of {tuple(GAITS)}, got {gait!r}")
    robot = robot or load_anymal()
    model = robot.model
    q0 = model.referenceConfigurations["standing"].copy()
    builder = QuadrupedGait(model, FEET)
    if gait == "jump":
        height, length, dt, ground, flying = GAITS[gait]
        nodes, terminal = builder.jump(q0, height, length, ground, flying)
    else:
        length, height, dt, knots, support = GAITS[gait]
        nodes, terminal = getattr(builder, gait)(q0, length, height, knots, support)
    return contact_problem(robot, nodes, terminal, q0, dt, GAINS, feet=FEET)


def anymal_walk(robot=None) -> ContactProblem:
    """Crocoddyl's ANYmal walk: 0.25 m steps, 0.15 m high, dt 0.01 s, 25 + 2 knots (H = 108: 4 impulse nodes)."""
    return anymal_gait("walk", robot)


def anymal_trot(robot=None) -> ContactProblem:
    """Crocoddyl's ANYmal trot: 0.15 m steps, 0.1 m high, dt 0.01 s, 25 + 2 knots (H = 56: 2 impulse nodes)."""
    return anymal_gait("trot", robot)


def anymal_jump(robot=None) -> ContactProblem:
    """Crocoddyl's ANYmal jump: 0.3 m sideways (y), CoM apex 0.15 m up, dt 0.01 s, 10 ground knots,
    20 + 20 flying knots, the landing impulse (H = 60: 1 impulse node)."""
    return anymal_gait("jump", robot)


def talos_walk(robot=None) -> ContactProblem:
    """Crocoddyl's biped walk (its example bipedal_gaits_fwddyn.py, ``SimpleBipedGaitProblem``'s
    createWalkingProblem from a fresh instance) on Talos' legs (example-robot-data's "talos_legs"),
    node for node: from "half_sitting" at rest on flat feet (6D contacts of "right_sole_link" and
    "left_sole_link", Baumgarte gains (0, 30)), 4 support knots, the right foot's 0.3 m half step,
    4 support knots, the left foot's 0.6 m step, 0.1 m high, 15 knots each, dt 0.03 s; the left
    foot's landing impulse is the terminal node (H = 39: 1 impulse node). Costs: Crocoddyl's biped's
    (:meth:`geoddp.problem.legged.GaitCosts.biped`). ``robot``: the loaded RobotWrapper, or None."""
    robot = robot or load_robot("talos_legs")
    model = robot.model
    q0 = model.referenceConfigurations["half_sitting"].copy()
    length, height, dt, knots, support = TALOS_WALK
    nodes, terminal = BipedGait(model, TALOS_FEET).walk(q0, length, height, knots, support)
    return contact_problem(robot, nodes, terminal, q0, dt, TALOS_GAINS, GaitCosts.biped(), TALOS_FEET, "6d")


# ------------------------------------------------------------------ schedules of a scene file
@dataclass(frozen=True)
class PhaseSpec:
    """One ``[[phases]]`` table: ``contacts`` (feet on the ground, in ``[model].feet`` order),
    ``knots`` contact nodes, a step of the swing feet (``step_length`` m along x, None: no step;
    ``step_height`` m), the touch-down impulse's feet (``landing``: () for none) and the phase's
    own base target (``base_target``: translation m and quaternion (x, y, z, w), 7 numbers,
    Pinocchio's XYZQUAT; None: the scene's)."""

    contacts: tuple[str, ...]
    knots: int
    step_length: float | None
    step_height: float
    landing: tuple[str, ...]
    base_target: tuple[float, ...] | None = None


def phase_nodes(model: pin.Model, feet: tuple[str, ...], q0: np.ndarray, phases: tuple[PhaseSpec, ...],
                base: pin.SE3 | None = None) -> tuple[list[Node], Node]:
    """The nodes of a ``[[phases]]`` schedule and its terminal node (every foot down, no CoM or
    foot targets).

    ``base``: the scene's base target placement, or None. Each phase's contact nodes carry its own
    ``base_target`` if it has one, else ``base``; the terminal node carries the last phase's.

    A phase with a step is Crocoddyl's footstep (:func:`geoddp.problem.legged.footstep`):
    per knot the swing feet track a stepping arc and the CoM the fraction of the step the swing
    feet carry; the feet's and the CoM's positions carry over to the next phase. Its impulse node
    tracks the landing feet at their last targets. Written as phases, Crocoddyl's walk and trot are
    the same nodes as :meth:`QuadrupedGait.walk` / ``trot``."""
    ids = {f: int(model.getFrameId(f)) for f in feet}
    d = model.createData()
    pin.forwardKinematics(model, d, q0)
    pin.updateFramePlacements(model, d)
    pos = {f: d.oMf[ids[f]].translation.copy() for f in feet}
    com = sum(pos[f] for f in feet) / len(feet)
    com[2] = pin.centerOfMass(model, d, q0)[2]
    nodes: list[Node] = []
    target = base
    for ph in phases:
        target = base if ph.base_target is None else pin.XYZQUATToSE3(np.array(ph.base_target))
        first = len(nodes)
        support = [ids[f] for f in ph.contacts]
        swing_names = [f for f in feet if f not in ph.contacts]
        swing = [ids[f] for f in swing_names]
        tasks: tuple = ()
        if ph.step_length is not None:
            step = footstep(com, [pos[f] for f in swing_names], ph.step_length, ph.step_height,
                            ph.knots, support, swing)
            nodes += step[:-1]
            tasks = step[-1].swing
        else:
            nodes += [Node("contact", tuple(support)) for _ in range(ph.knots)]
        for n in nodes[first:]:  # the phase's contact nodes (its impulse node, appended below, has no base term)
            n.base = target
        if ph.landing:
            land = tuple(ids[f] for f in ph.landing)
            nodes.append(Node("impulse", land, swing=tuple((i, p) for i, p in tasks if i in land)))
    return nodes, Node("contact", tuple(ids[f] for f in feet), base=target)


# ------------------------------------------------------------------ the spec
@dataclass(frozen=True, eq=False)
class LeggedSceneSpec(CommonSpec):
    """A validated legged scene (``[model] kind = "legged"``), as plain values.

    Attributes:
        name, description: free text; source: scene file path or ``"<dict>"``.
        robot: example-robot-data's name; posture: its reference configuration (the start at rest
            and the regularisation posture); feet: contact frame names; nv: the robot's nv.
        dt: time step of the contact nodes, s; baumgarte: (Kp 1/s^2, Kd 1/s).
        foot_kind: "3d" (point feet) or "6d" (flat feet: 6D contacts, Crocoddyl's biped costs).
        gait: the ``[gait]`` table as a dict (``type`` and its four keys; ``jump_length`` a
            tuple), or None; phases: the ``[[phases]]`` as :class:`PhaseSpec`, or () with a gait.
        costs: the ``[costs]`` weights given, as (name, value) pairs (the rest: Crocoddyl's);
            ``base_placement`` and ``force_regularisation`` as their weights, and
            ``force_reference`` (a string) when ``[costs].force_regularisation`` is given.
        base_target: ``[costs].base_placement``'s target, translation m and quaternion (x, y, z,
            w) (7 numbers, Pinocchio's XYZQUAT), or None.
        initial_controls: "quasi_static" (Crocoddyl's quasiStatic per contact node, zero at
            impulse nodes) or "zero".
        expansion, switch_ratio, tol, rtol, grad_tol, grad_rtol, max_iter: the ``[solver]`` table.
    """

    name: str
    description: str
    source: str
    robot: str
    posture: str
    feet: tuple[str, ...]
    nv: int
    dt: float
    baumgarte: tuple[float, float]
    gait: dict | None
    phases: tuple[PhaseSpec, ...]
    costs: tuple[tuple[str, float | str], ...] = ()
    initial_controls: str = "quasi_static"
    foot_kind: str = "3d"
    base_target: tuple[float, ...] | None = None

    kind = "legged"

    def __post_init__(self) -> None:
        self._check_common(("exact",), self.num_inputs)
        object.__setattr__(self, "initial_controls", v.choice(self.initial_controls, "initial_controls",
                                                              INITIAL_CONTROLS))

    @property
    def num_inputs(self) -> int:
        """m = nv - 6: one torque per joint after the free flyer."""
        return int(self.nv) - 6

    @property
    def horizon(self) -> int:
        """H, the number of nodes (contact and impulse)."""
        g = self.gait
        if g is None:
            return sum(p.knots + bool(p.landing) for p in self.phases)
        if g["type"] == "walk" and len(self.feet) == 2:  # the biped's: its last landing is terminal
            return 2 * g["support_knots"] + 2 * (g["step_knots"] + 1) - 1
        if g["type"] == "walk":
            return 2 * g["support_knots"] + 4 * (g["step_knots"] + 1)
        if g["type"] == "trot":
            return 2 * g["support_knots"] + 2 * (g["step_knots"] + 1)
        return 2 * g["ground_knots"] + 2 * g["flying_knots"]  # the landing impulse, the last ground knot terminal

    def build(self, robot=None) -> ContactProblem:
        """The :class:`~geoddp.problem.legged.ContactProblem` (``robot``: the loaded RobotWrapper
        of ``self.robot``, loaded here if None)."""
        robot = robot or load_robot(self.robot, "[model].robot")
        model = robot.model
        q0 = model.referenceConfigurations[self.posture].copy()
        g = self.gait
        base = None if self.base_target is None else pin.XYZQUATToSE3(np.array(self.base_target))
        if g is None:
            nodes, terminal = phase_nodes(model, self.feet, q0, self.phases, base)
        elif len(self.feet) == 2:
            nodes, terminal = BipedGait(model, self.feet, q0).walk(
                q0, g["step_length"], g["step_height"], g["step_knots"], g["support_knots"])
        elif g["type"] == "jump":
            nodes, terminal = QuadrupedGait(model, self.feet, q0).jump(
                q0, g["jump_height"], g["jump_length"], g["ground_knots"], g["flying_knots"])
        else:
            nodes, terminal = getattr(QuadrupedGait(model, self.feet, q0), g["type"])(
                q0, g["step_length"], g["step_height"], g["step_knots"], g["support_knots"])
        if g is not None and base is not None:  # one target for the whole gait
            for n in [*nodes, terminal]:
                if n.kind == "contact":
                    n.base = base
        try:
            costs = (GaitCosts.biped if self.foot_kind == "6d" else GaitCosts)(**dict(self.costs))
        except TypeError as exc:
            raise InputError("costs", f"expected fields of GaitCosts, got {dict(self.costs)} ({exc})") from None
        problem = contact_problem(robot, nodes, terminal, q0, self.dt, self.baumgarte, costs, self.feet, self.foot_kind)
        if not self.constraints:
            return problem
        from ..constraints import ConstrainedProblem, ConstraintOptions

        return ConstrainedProblem(problem, self.constraints, options=ConstraintOptions(constraint_tol=self.constraint_tol))

    def initial_control_sequence(self) -> np.ndarray | None:
        """None for the solver's default start (the quasi-static controls), zeros (H, m) for "zero"."""
        return None if self.initial_controls == "quasi_static" else np.zeros((self.horizon, self.num_inputs))

    def read_initial_controls(self, value: Any, name: str = "initial_controls") -> str:
        """``value`` as this scene's initial controls: "quasi_static" or "zero" (InputError naming ``name``)."""
        return v.choice(value, name, INITIAL_CONTROLS)

    def with_overrides(self, **overrides: Any) -> "LeggedSceneSpec":
        """A copy with solver options (``second_order``: "exact" only) or ``initial_controls``
        replaced, re-validated."""
        allowed = SOLVER_KEYS + ("second_order",)
        for k in overrides:
            if k not in allowed:
                guess = v.closest(k, allowed)
                hint = f"; did you mean {guess!r}?" if guess else ""
                raise InputError(k, f"cannot override this LeggedSceneSpec field{hint} (allowed: {', '.join(allowed)})")
        if "constraint_tol" in overrides:
            if not self.constraints:
                raise InputError("constraint_tol", "applies only to a scene with [[constraints]] tables "
                                 f"({self.name!r} has none)")
            overrides["constraint_tol"] = v.nonnegative_float(overrides["constraint_tol"], "constraint_tol")
        return dataclasses.replace(self, **overrides)


# ------------------------------------------------------------------ parsing
def parse_legged_scene(data: Mapping[str, Any], source: str, base_dir: Path, default_name: str) -> LeggedSceneSpec:
    """Validate a parsed legged scene (``[model] kind = "legged"``) into a spec; InputError naming
    the key path (``[gait].step_knots``, ``phases[2].contacts[0]``) and the file."""
    from ..models import robots

    r = Reader(data, source, SCHEMA, arrays=ARRAYS, required=REQUIRED)
    r.top()
    name = r.string(data.get("name", default_name), "name")
    description = r.string(data.get("description", ""), "description")

    # ---- model: the robot's URDF and SRDF (its frames and postures), not yet its meshes
    mt = r.table("model")
    robot = r.check(robots.find, mt["robot"], "[model].robot")
    if robot.root != "free_flyer":
        raise r.err("[model].robot", f"expected a robot with a free-flyer root (a legged robot), got {robot.name!r} "
                    f"(fixed base)")
    if robot.loader_model:  # its model is the loader's (talos_legs: the legs of Talos' URDF), loaded here
        pm = load_robot(robot.name, "[model].robot").model
    else:
        pm = pin.buildModelFromUrdf(str(robot.urdf), pin.JointModelFreeFlyer())
    postures = r.check(robots.postures, pm, robot.srdf, "[model].robot")
    posture = r.string(mt.get("posture", "standing"), "[model].posture")
    if posture not in postures:
        guess = v.closest(posture, list(postures))
        hint = f"did you mean {guess!r}? " if guess else ""
        raise r.err("[model].posture", f"expected a posture of {robot.name!r}, got {posture!r}; {hint}"
                    f"postures: {', '.join(postures)}")
    feet = _feet(r, mt["feet"], pm)

    # ---- contact dynamics
    ct = r.table("contact")
    dt = r.check(v.positive_float, ct["dt"], "[contact].dt")
    gains = r.check(v.finite_array, ct.get("baumgarte", list(GAINS)), "[contact].baumgarte", (2,))
    if np.any(gains < 0):
        raise r.err("[contact].baumgarte", f"expected gains [Kp, Kd] >= 0, got {gains.tolist()}")
    foot_kind = r.check(v.choice, ct.get("kind", "3d"), "[contact].kind", FOOT_KINDS)

    # ---- schedule: exactly one of [gait] and [[phases]]
    if ("gait" in data) == ("phases" in data):
        got = "both" if "gait" in data else "neither"
        raise r.err("[gait]", f"expected exactly one of [gait] (walk | trot | jump) | [[phases]], got {got}")
    gait, phases = None, ()
    if "gait" in data:
        gait = _gait(r, r.table("gait"), feet)
    else:
        phases = _phases(r, feet)

    # ---- costs, solver
    cost_t = r.table("costs")
    costs: list[tuple[str, float | str]] = []
    base_target = None
    for k, val in cost_t.items():
        if k == "base_placement":
            weight, base_target = _base_placement(r, val, "[costs].base_placement", weighted=True)
            costs.append((k, weight))
        elif k == "force_regularisation":
            costs += _force_regularisation(r, val, "[costs].force_regularisation")
        else:
            costs.append((k, r.check(v.positive_float if k == "mu" else v.nonnegative_float, val, f"[costs].{k}")))
    if base_target is None:
        for ph_path, ph in zip((p for p, _ in r.array("phases")), phases):
            if ph.base_target is not None:
                raise r.err(f"{ph_path}.base_placement", "needs [costs].base_placement (the term's weight and the "
                            "scene's target), e.g. base_placement = { weight = 1e3, translation = [0.0, 0.0, 0.45] }")
    s = r.table("solver")
    get = s.get
    solver = dict(
        expansion=r.check(v.choice, get("expansion", DEFAULT_EXPANSION), "[solver].expansion", EXPANSIONS),
        switch_ratio=r.check(v.bounded_float, get("switch_ratio", DEFAULT_SWITCH_RATIO), "[solver].switch_ratio",
                             0.0, 1.0, False, False),
        max_iter=r.check(v.positive_int, get("max_iter", DEFAULT_MAX_ITER), "[solver].max_iter"),
        initial_controls=r.check(v.choice, get("initial_controls", "quasi_static"), "[solver].initial_controls",
                                 INITIAL_CONTROLS),
        **{key: r.check(v.nonnegative_float, s[key], f"[solver].{key}") if key in s else None
           for key in ("tol", "rtol", "grad_tol", "grad_rtol")})
    if "constraint_tol" in s:
        solver["constraint_tol"] = r.check(v.nonnegative_float, s["constraint_tol"], "[solver].constraint_tol")
    solver["constraints"] = tuple(_force_constraint(r, t, path, feet) for path, t in r.array("constraints"))
    if "constraint_tol" in s and not solver["constraints"]:
        raise r.err("[solver].constraint_tol", "applies only with [[constraints]] tables (this scene has none)")
    return LeggedSceneSpec(name=name, description=description, source=source, robot=robot.name, posture=posture,
                           feet=feet, nv=int(pm.nv), dt=dt, baumgarte=(float(gains[0]), float(gains[1])), gait=gait,
                           phases=phases, costs=tuple(costs), foot_kind=foot_kind, base_target=base_target,
                           **solver)


def _force_constraint(r: Reader, t: Mapping[str, Any], path: str, feet: tuple[str, ...]):
    """One ``[[constraints]]`` table of a legged scene: ``type = "friction_cone"`` (the contact
    forces' hard constraints, :class:`geoddp.constraints.FrictionCone`) with ``mu?`` (0.7),
    ``facets?`` (4), ``min_normal_force?`` (0 N), ``max_normal_force?`` (none), ``feet?`` (all)
    and ``name?``; errors name the key path."""
    from ..constraints import FrictionCone

    r.keys(t, CONSTRAINT_KEYS, path)
    if "type" not in t:
        raise r.err(f"{path}.type", 'missing required key (a legged scene\'s constraints: "friction_cone")')
    r.check(v.choice, t["type"], f"{path}.type", ("friction_cone",))
    kw: dict[str, Any] = {}
    if "mu" in t:
        kw["mu"] = r.check(v.positive_float, t["mu"], f"{path}.mu")
    if "min_normal_force" in t:
        kw["min_normal_force"] = r.check(v.nonnegative_float, t["min_normal_force"], f"{path}.min_normal_force")
    if "max_normal_force" in t:  # a number of newtons, or inf (TOML's inf) for none
        kw["max_normal_force"] = t["max_normal_force"]
    if "facets" in t:
        kw["facets"] = r.check(v.positive_int, t["facets"], f"{path}.facets")
    if "name" in t:
        kw["name"] = r.string(t["name"], f"{path}.name")
    if "feet" in t:
        names = t["feet"]
        if not isinstance(names, list) or not names:
            raise r.err(f"{path}.feet", f"expected a list of the scene's feet ({', '.join(feet)}), got {names!r}")
        for i, name in enumerate(names):
            if name not in feet:
                guess = v.closest(str(name), list(feet))
                hint = f"; did you mean {guess!r}?" if guess else ""
                raise r.err(f"{path}.feet[{i}]", f"expected one of [model].feet ({', '.join(feet)}), got {name!r}{hint}")
        kw["feet"] = tuple(names)
    try:
        return FrictionCone(**kw)
    except InputError as e:
        raise r.err(f"{path}.{e.parameter}", e.detail) from None


def _feet(r: Reader, val: Any, pm: pin.Model) -> tuple[str, ...]:
    path = "[model].feet"
    if not isinstance(val, list) or not val or not all(isinstance(f, str) for f in val):
        raise r.err(path, f"expected a non-empty list of contact frame names, e.g. {list(FEET)}, got {val!r}")
    frames = [str(f.name) for f in pm.frames]
    for i, f in enumerate(val):
        if not pm.existFrame(f):
            guess = v.closest(f, frames)
            hint = f"; did you mean {guess!r}?" if guess else ""
            raise r.err(f"{path}[{i}]", f"expected a frame of the robot, got {f!r}{hint}")
        if val.index(f) != i:
            raise r.err(f"{path}[{i}]", f"expected each foot once, got {f!r} twice")
    return tuple(val)


def _knots(r: Reader, val: Any, path: str) -> int:
    return r.check(v.positive_int, val, path)


def _gait(r: Reader, t: Mapping[str, Any], feet: tuple[str, ...]) -> dict[str, Any]:
    kind = r.check(v.choice, t["type"], "[gait].type", GAIT_TYPES)
    uses = _GAIT_KEYS[kind]
    for key in t:
        if key != "type" and key not in uses:
            raise r.err(f"[gait].{key}", f'not used by type = "{kind}"; keys for {kind}: {", ".join(("type",) + uses)}')
    for key in uses:
        if key not in t:
            raise r.err(f"[gait].{key}", f'missing required key for type = "{kind}"')
    if len(feet) != 4 and not (kind == "walk" and len(feet) == 2):  # a biped walks on (right, left)
        walk = "; a walk also takes two (right, left)" if kind == "walk" else ""
        raise r.err("[model].feet", f"a [gait] of type {kind!r} moves a quadruped: expected four feet (LF, RF, LH, RH)"
                    f"{walk}, got {len(feet)}")
    out: dict[str, Any] = {"type": kind}
    if kind == "jump":
        out["jump_height"] = r.check(v.finite_float, t["jump_height"], "[gait].jump_height")
        out["jump_length"] = tuple(float(x) for x in r.check(v.finite_array, t["jump_length"], "[gait].jump_length", (3,)))
        out["ground_knots"] = _knots(r, t["ground_knots"], "[gait].ground_knots")
        out["flying_knots"] = _knots(r, t["flying_knots"], "[gait].flying_knots")
    else:
        out["step_length"] = r.check(v.finite_float, t["step_length"], "[gait].step_length")
        out["step_height"] = r.check(v.finite_float, t["step_height"], "[gait].step_height")
        out["step_knots"] = _knots(r, t["step_knots"], "[gait].step_knots")
        out["support_knots"] = _knots(r, t["support_knots"], "[gait].support_knots")
    return out


def _phases(r: Reader, feet: tuple[str, ...]) -> tuple[PhaseSpec, ...]:
    items = r.array("phases")
    if not items:
        raise r.err("phases", "expected at least one [[phases]] table")
    read = []
    for path, t in items:
        r.keys(t, PHASE_KEYS, path)
        for key in ("contacts", "knots"):
            if key not in t:
                raise r.err(f"{path}.{key}", "missing required key")
        c = t["contacts"]
        if not isinstance(c, list) or not all(isinstance(f, str) for f in c):
            raise r.err(f"{path}.contacts", f"expected a list of feet of [model].feet (possibly empty), got {c!r}")
        for i, f in enumerate(c):
            if f not in feet:
                guess = v.closest(f, feet)
                hint = f"did you mean {guess!r}? " if guess else ""
                raise r.err(f"{path}.contacts[{i}]", f"expected a foot of [model].feet, got {f!r}; {hint}"
                            f"feet: {', '.join(feet)}")
            if c.index(f) != i:
                raise r.err(f"{path}.contacts[{i}]", f"expected each foot once, got {f!r} twice")
        contacts = tuple(f for f in feet if f in c)  # in [model].feet order
        knots = _knots(r, t["knots"], f"{path}.knots")
        length = None
        if "step_length" in t:
            length = r.check(v.finite_float, t["step_length"], f"{path}.step_length")
            if len(contacts) == len(feet):
                raise r.err(f"{path}.step_length", "a step needs a swing foot: every foot is in contacts")
        elif "step_height" in t:
            raise r.err(f"{path}.step_height", "expected together with step_length (a step's length along x, m)")
        height = r.check(v.finite_float, t.get("step_height", 0.0), f"{path}.step_height")
        impulse = r.boolean(t["impulse"], f"{path}.impulse") if "impulse" in t else None
        base = _base_placement(r, t["base_placement"], f"{path}.base_placement", weighted=False)[1] \
            if "base_placement" in t else None
        read.append((path, contacts, knots, length, height, impulse, base))
    phases = []
    for j, (path, contacts, knots, length, height, impulse, base) in enumerate(read):
        after = read[j + 1][1] if j + 1 < len(read) else feet  # the terminal node: every foot down
        landing = tuple(f for f in feet if f not in contacts and f in after)
        if impulse and not landing:
            raise r.err(f"{path}.impulse", "expected false: no swing foot of this phase is on the ground in the "
                        "next phase (nothing touches down)")
        phases.append(PhaseSpec(contacts, knots, length, height, landing if impulse is not False else (), base))
    return tuple(phases)


def _base_placement(r: Reader, t: Any, path: str, weighted: bool) -> tuple[float | None, tuple[float, ...]]:
    """A base target table at ``path`` (``[costs].base_placement`` with its ``weight`` when
    ``weighted``, a phase's ``base_placement`` without): (the weight or None, the target as
    translation m and quaternion (x, y, z, w), Pinocchio's XYZQUAT). ``translation`` (3,) is
    required; the rotation, at most one of rpy_deg | quaternion | rotation | axis + angle_deg,
    defaults to the identity (the base level, heading along x)."""
    keys = (("weight",) if weighted else ()) + BASE_KEYS
    example = "{ weight = 1e3, translation = [0.0, 0.0, 0.45] }" if weighted else "{ translation = [0.0, 0.0, 0.45] }"
    if not isinstance(t, Mapping):
        raise r.err(path, f"expected a table such as {example} (keys: {', '.join(keys)}), got {t!r}")
    r.keys(t, keys, path)
    weight = None
    if weighted:
        if "weight" not in t:
            raise r.err(f"{path}.weight", "missing required key (the term's weight, >= 0)")
        weight = r.check(v.nonnegative_float, t["weight"], f"{path}.weight")
    if "translation" not in t:
        raise r.err(f"{path}.translation", "missing required key (the base's target position [x, y, z], m)")
    p = r.check(v.finite_array, t["translation"], f"{path}.translation", (3,))
    R = r.rotation(t, path, BASE_ROTATIONS, required=False)
    M = pin.SE3(np.eye(3) if R is None else R, p)
    return weight, tuple(float(x) for x in pin.SE3ToXYZQUAT(M))


def _force_regularisation(r: Reader, t: Any, path: str) -> list[tuple[str, float | str]]:
    """``[costs].force_regularisation`` = {weight, reference?} as GaitCosts fields:
    [("force_regularisation", weight), ("force_reference", "weight_share" | "zero")]."""
    if not isinstance(t, Mapping):
        raise r.err(path, f'expected a table such as {{ weight = 1e-3, reference = "weight_share" }} '
                    f"(keys: {', '.join(FORCE_KEYS)}), got {t!r}")
    r.keys(t, FORCE_KEYS, path)
    if "weight" not in t:
        raise r.err(f"{path}.weight", "missing required key (the term's weight, >= 0, per N^2)")
    weight = r.check(v.nonnegative_float, t["weight"], f"{path}.weight")
    reference = r.check(v.choice, t.get("reference", "weight_share"), f"{path}.reference", FORCE_REFERENCES)
    return [("force_regularisation", weight), ("force_reference", reference)]
