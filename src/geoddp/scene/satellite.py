"""The satellite schema: a TOML scene of one attitude-control problem on TSO(3) (paper Section
VI), read with the one :class:`~geoddp.scene.reader.Reader` into a frozen :class:`SceneSpec`.

The schema is a translator: :meth:`SceneSpec.general` writes the scene in the general schema
(:class:`~geoddp.scene.multibody.MultibodySceneSpec`: the one-body model of ``satellite.urdf``,
spherical root, no gravity, the scene's inertia; the paper's costs as frame_rotation,
state_regularisation and control terms), and the one builder (:mod:`geoddp.scene.build`) builds
that, choosing the TSO(3) backend by structure.

Schema (``?`` = optional, with its default)::

    name? = file stem                   description? = ""
    [model]    kind? = "satellite", inertia (3 numbers or 3x3, kg m^2), actuation? = I_3 (3 x m), urdf? (path)
    [initial]  exactly one of quaternion (x,y,z,w) | rotation (3x3);
               angular_velocity? = [0,0,0] (rad/s)
    [target]   exactly one of rotation | quaternion | euler_intrinsic ([[axis, deg], ...]);
               angular_velocity? = [0,0,0]
    [horizon]  tf (s), dt (s), integrator? = "euler" (euler | semi_implicit | rk4 | variational)
    [cost]     control (S_u), attitude (S_R or W_R), attitude_kind? = "chordal"
               (chordal | geodesic), angular_velocity (S_Omega),
               running_attitude? = 0, running_angular_velocity? = 0
    [solver]?  expansion? = "switch" (first | second | switch), switch_ratio? = 0.1 in (0, 1),
               tol? (absolute, units of J: the paper's 1e-8) | rtol? (relative to |J|; default
               1e-11 when neither is set), grad_tol? | grad_rtol?, max_iter? = 200,
               second_order? = "exact" (exact | paper), initial_controls? (H x m, default 0),
               constraint_tol? = 1e-8
    [[constraints]]?, [[terminal_constraints]]?  hard constraints (geoddp.scene.constraints);
               a pointing_keep_out's frame is the body unless named
"""
from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from ..data import urdf_path
from .. import validate as v
from ..models.urdf import build_urdf_model
from ..validate import InputError
from .common import TABLES, CommonSpec, initial_in_limits, read_common, readonly
from .constraints import ARRAYS as CONSTRAINT_ARRAYS
from .multibody import CostTermSpec, MultibodySceneSpec
from .reader import Reader, Schema, check_urdf

# euler and semi_implicit run on the TSO(3) closed forms; rk4 and variational on the general
# one-body model (scene.build picks by structure), the chordal cost included
INTEGRATORS = ("euler", "semi_implicit", "rk4", "variational")
ATTITUDE_KINDS = ("chordal", "geodesic")
SECOND_ORDER = ("exact", "paper")
DEFAULT_INTEGRATOR = "euler"
DEFAULT_ATTITUDE_KIND = "chordal"

SCHEMA: Schema = {
    "model": {"kind": False, "inertia": True, "actuation": False, "urdf": False},
    "initial": {"quaternion": False, "rotation": False, "angular_velocity": False},
    "target": {"rotation": False, "quaternion": False, "euler_intrinsic": False, "angular_velocity": False},
    "horizon": {"tf": True, "dt": True, "integrator": False},
    "cost": {"control": True, "attitude": True, "attitude_kind": False, "angular_velocity": True,
             "running_attitude": False, "running_angular_velocity": False},
    **TABLES,
}
REQUIRED = ("model", "initial", "target", "horizon", "cost")


@dataclass(frozen=True, eq=False)
class SceneSpec(CommonSpec):
    """A validated attitude-control problem on TSO(3), as plain values.

    Shapes use m = number of inputs and H = horizon (number of control steps).

    Attributes:
        name: scene name.
        description: free text.
        source: path of the scene file, or ``"<dict>"``.
        inertia: (3, 3) body inertia in kg m^2, SPD, physically realisable.
        actuation: (3, m) input-to-body-torque matrix, no zero column.
        urdf: absolute path of an optional URDF model, or None (must exist; a relative path
            given directly to the constructor resolves against the current directory).
        R0: (3, 3) initial attitude (body to world).
        Omega0: (3,) initial body angular velocity in rad/s.
        Rd: (3, 3) target attitude.
        Omegad: (3,) target body angular velocity in rad/s.
        tf: final time in seconds.
        dt: time step in seconds.
        horizon: H = tf / dt (derived; an integer).
        integrator: "euler" | "semi_implicit" (TSO(3) closed forms) | "rk4" | "variational" (the
            general one-body model).
        S_u: (m, m) SPD control weight.
        S_R: (3, 3) PSD terminal attitude weight (S_R for chordal, W_R for geodesic).
        attitude_kind: "chordal" | "geodesic".
        S_Omega: (3, 3) PSD terminal angular-velocity weight.
        running_S_R: (3, 3) PSD attitude weight applied at every running step.
        running_S_Omega: (3, 3) PSD angular-velocity weight applied at every running step.
        initial_controls: (H, m) initial control guess, or None for zeros.
        expansion, switch_ratio, tol, rtol, grad_tol, grad_rtol, max_iter, second_order: the ``[solver]`` table
            (:class:`~geoddp.scene.common.CommonSpec`).

    Constructing a SceneSpec (directly, via :meth:`with_overrides` or :func:`parse_scene`)
    validates every field; array fields are stored as read-only float64 copies.
    """

    name: str
    description: str
    source: str
    inertia: np.ndarray
    actuation: np.ndarray
    urdf: Path | None
    R0: np.ndarray
    Omega0: np.ndarray
    Rd: np.ndarray
    Omegad: np.ndarray
    tf: float
    dt: float
    horizon: int
    integrator: str
    S_u: np.ndarray
    S_R: np.ndarray
    attitude_kind: str
    S_Omega: np.ndarray
    running_S_R: np.ndarray
    running_S_Omega: np.ndarray
    initial_controls: np.ndarray | None = None

    kind = "satellite"

    def __post_init__(self) -> None:
        # Validate with field names as parameter names; the parser has already checked the
        # same values under their TOML key paths, so these only fire for direct construction
        # and for with_overrides().
        put = lambda k, val: object.__setattr__(self, k, val)  # noqa: E731  (frozen dataclass)
        for k in ("name", "description", "source"):
            if not isinstance(getattr(self, k), str):
                raise InputError(k, f"expected a string, got {getattr(self, k)!r}")
        put("inertia", readonly(v.inertia_matrix(self.inertia, "inertia")))
        put("actuation", readonly(v.actuation_matrix(self.actuation, "actuation")))
        m = self.actuation.shape[1]
        if self.urdf is not None:
            put("urdf", check_urdf(self.urdf, "urdf", Path.cwd()))
        put("R0", readonly(v.rotation_matrix(self.R0, "R0")))
        put("Omega0", readonly(v.finite_array(self.Omega0, "Omega0", shape=(3,))))
        put("Rd", readonly(v.rotation_matrix(self.Rd, "Rd")))
        put("Omegad", readonly(v.finite_array(self.Omegad, "Omegad", shape=(3,))))
        H = v.time_grid(self.tf, self.dt, tf_name="tf", dt_name="dt")
        put("tf", float(self.tf))
        put("dt", float(self.dt))
        h = v.positive_int(self.horizon, "horizon")
        if h != H:
            raise InputError("horizon", f"expected tf / dt = {H} (it is derived from tf and dt), got {h}")
        put("integrator", v.choice(self.integrator, "integrator", INTEGRATORS))
        put("S_u", readonly(v.spd_matrix(self.S_u, "S_u", m)))
        for k in ("S_R", "S_Omega", "running_S_R", "running_S_Omega"):
            put(k, readonly(v.spd_matrix(getattr(self, k), k, 3, semidefinite=True)))
        put("attitude_kind", v.choice(self.attitude_kind, "attitude_kind", ATTITUDE_KINDS))
        self._check_common(SECOND_ORDER, m)
        if self.initial_controls is not None:
            put("initial_controls", readonly(v.finite_array(self.initial_controls, "initial_controls", shape=(H, m))))
        self._check_initial_in_limits(self.initial_controls, "initial_controls")

    @property
    def num_inputs(self) -> int:
        """m, the number of control inputs (columns of the actuation matrix)."""
        return int(self.actuation.shape[1])

    def initial_control_sequence(self) -> np.ndarray | None:
        """(H, m) initial guess for the solver, or None for zeros."""
        return None if self.initial_controls is None else np.array(self.initial_controls)

    def read_initial_controls(self, value: Any, name: str = "initial_controls") -> np.ndarray:
        """``value`` as this scene's initial controls, checked as the ``[solver]`` table's are
        (:func:`read_initial_controls`: an (H, m) array inside the limits); InputError naming ``name``."""
        return read_initial_controls(value, name, self.num_inputs, self.horizon, self.control_min, self.control_max)

    def general(self) -> MultibodySceneSpec:
        """This scene in the general schema, which the one builder reads (the translation):

        - model: ``urdf`` (default the built-in satellite.urdf), root "spherical", no gravity,
          this inertia, actuation matrix (3, m);
        - initial state: q0 = the quaternion (x, y, z, w) of R0, v0 = Omega0;
        - running costs (paper eq. costR): control (S_u), then, where non-zero, frame_rotation of
          the body frame (running_S_R, R_d, this attitude_kind as its distance) and
          state_regularisation (velocity weight running_S_Omega, reference Omega_d);
        - terminal costs: frame_rotation (S_R) and state_regularisation (S_Omega);
        - the shared tables ([solver], [limits], [simulation]) as they are.

        The terms carry this schema's key paths (``[cost].attitude``, ...) for their messages.
        Made once per spec (specs are frozen).
        """
        cached = self.__dict__.get("_general")
        if cached is not None:
            return cached
        urdf = self.urdf if self.urdf is not None else urdf_path("satellite.urdf")
        body = _body_frame(str(urdf))
        m = self.num_inputs

        def rotation(path: str, W: np.ndarray) -> CostTermSpec:
            return CostTermSpec("frame_rotation", "attitude", path, body, self.Rd, W, distance=self.attitude_kind)

        def rate(path: str, W: np.ndarray) -> CostTermSpec:
            Wx = np.zeros((6, 6))
            Wx[3:, 3:] = W  # tangent state (eta, dOmega): only the rate is weighted
            ref = np.concatenate([[0.0, 0.0, 0.0, 1.0], self.Omegad])  # q part unweighted
            return CostTermSpec("state_regularisation", "angular_velocity", path, None, readonly(ref), readonly(Wx))

        running = [CostTermSpec("control", "control", "[cost].control", None, readonly(np.zeros(m)), self.S_u)]
        if np.any(self.running_S_R != 0):
            running.append(rotation("[cost].running_attitude", self.running_S_R))
        if np.any(self.running_S_Omega != 0):
            running.append(rate("[cost].running_angular_velocity", self.running_S_Omega))
        terminal = [rotation("[cost].attitude", self.S_R), rate("[cost].angular_velocity", self.S_Omega)]
        common = {f.name: getattr(self, f.name) for f in dataclasses.fields(CommonSpec)}
        general = MultibodySceneSpec(
            name=self.name, description=self.description, source=self.source, urdf=Path(urdf), root="spherical",
            gravity=False, actuation=self.actuation, q0=pin.Quaternion(self.R0).coeffs().copy(), v0=self.Omega0,
            dt=self.dt, horizon=self.horizon, integrator=self.integrator, running_costs=tuple(running),
            terminal_costs=tuple(terminal), initial_controls=self.initial_controls, inertia=self.inertia, **common)
        object.__setattr__(self, "_general", general)  # frozen dataclass: a cache, not a field
        return general

    def with_overrides(self, **overrides: Any) -> "SceneSpec":
        """A copy with some fields replaced and the result re-validated.

        ``horizon`` is derived: override ``tf`` and/or ``dt`` instead and it is recomputed.
        Errors name the field (e.g. ``expansion: expected one of first | second | switch``).

        Example: ``spec.with_overrides(expansion="second", max_iter=50)``.
        """
        fields = [f.name for f in dataclasses.fields(self)]
        for k in overrides:
            if k not in fields:
                guess = v.closest(k, fields)
                hint = f"; did you mean {guess!r}?" if guess else ""
                raise InputError(k, f"unknown SceneSpec field{hint}")
        if "horizon" in overrides:
            raise InputError("horizon", "is derived from tf / dt; override tf or dt instead")
        if "tf" in overrides or "dt" in overrides:
            tf = overrides.get("tf", self.tf)
            dt = overrides.get("dt", self.dt)
            overrides["horizon"] = v.time_grid(tf, dt, tf_name="tf", dt_name="dt")
        return dataclasses.replace(self, **overrides)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, SceneSpec):
            return NotImplemented
        for f in dataclasses.fields(self):
            a, b = getattr(self, f.name), getattr(other, f.name)
            if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
                if not (isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and np.array_equal(a, b)):
                    return False
            elif a != b:
                return False
        return True

    __hash__ = None  # type: ignore[assignment]  # holds arrays; equality is by value


def read_initial_controls(val: Any, name: str, m: int, H: int, lower: np.ndarray | None,
                          upper: np.ndarray | None) -> np.ndarray:
    """A satellite scene's initial controls (``[solver].initial_controls``, or the keyword of
    :func:`geoddp.solve_scene`): an (H, m) sequence of body torques (N m) inside [lower, upper]
    (the ``[limits]``, (m,) each or None); InputError naming ``name``."""
    U0 = v.finite_array(val, name, shape=(H, m))
    initial_in_limits(U0, lower, upper, name)
    return U0


@functools.lru_cache(maxsize=32)
def _one_body(urdf: str) -> pin.Model:
    """A one-body URDF on a spherical root (cached: read only, by the constraint tables' checks and
    the body frame's name), read and checked as every URDF is (:func:`geoddp.models.urdf.build_urdf_model`)."""
    return build_urdf_model(urdf, pin.JointModelSpherical(), "[model].urdf")


@functools.lru_cache(maxsize=32)
def _body_frame(urdf: str) -> str:
    """The name of the body frame of a one-body URDF on a spherical root (its one link)."""
    pm = _one_body(urdf)
    return next(f.name for f in pm.frames if f.parentJoint == 1 and f.type == pin.FrameType.BODY)


def parse(data: Mapping[str, Any], source: str, base_dir: Path, default_name: str) -> SceneSpec:
    """Validate a parsed satellite scene into a :class:`SceneSpec`; errors name the key path."""
    r = Reader(data, source, SCHEMA, arrays=CONSTRAINT_ARRAYS, required=REQUIRED)
    r.top()
    name = r.string(data.get("name", default_name), "name")
    description = r.string(data.get("description", ""), "description")

    model = r.table("model")
    inertia = r.check(v.inertia_matrix, model["inertia"], "[model].inertia")
    act = r.check(v.actuation_matrix, model["actuation"], "[model].actuation") if "actuation" in model else np.eye(3)
    m = act.shape[1]
    urdf = r.check(check_urdf, model["urdf"], "[model].urdf", base_dir) if "urdf" in model else None
    if urdf is not None:
        r.check(_body_frame, str(urdf))  # read and built now (cached), so a bad file is named with the scene

    zero3 = [0.0, 0.0, 0.0]
    initial = r.table("initial")
    R0 = r.rotation(initial, "[initial]", ("quaternion", "rotation"))
    Omega0 = r.check(v.finite_array, initial.get("angular_velocity", zero3), "[initial].angular_velocity", shape=(3,))
    target = r.table("target")
    Rd = r.rotation(target, "[target]", ("rotation", "quaternion", "euler_intrinsic"))
    Omegad = r.check(v.finite_array, target.get("angular_velocity", zero3), "[target].angular_velocity", shape=(3,))

    horizon = r.table("horizon")
    H = r.check(v.time_grid, horizon["tf"], horizon["dt"], tf_name="[horizon].tf", dt_name="[horizon].dt")
    integrator = r.check(v.choice, horizon.get("integrator", DEFAULT_INTEGRATOR), "[horizon].integrator", INTEGRATORS)

    cost = r.table("cost")

    def weight(key: str, n: int, semidefinite: bool = True, default: Any = None) -> np.ndarray:
        return r.weight(cost.get(key, default), f"[cost].{key}", n, semidefinite=semidefinite)

    S_u = weight("control", m, semidefinite=False)
    S_R = weight("attitude", 3)
    attitude_kind = r.check(v.choice, cost.get("attitude_kind", DEFAULT_ATTITUDE_KIND), "[cost].attitude_kind",
                            ATTITUDE_KINDS)
    S_Omega = weight("angular_velocity", 3)
    running_S_R = weight("running_attitude", 3, default=0.0)
    running_S_Omega = weight("running_angular_velocity", 3, default=0.0)

    # the constraint tables are checked against the body's model (frames, joints): built only for them
    body_urdf = str(urdf if urdf is not None else urdf_path("satellite.urdf"))
    constrained = any(name in data for name in CONSTRAINT_ARRAYS)
    common = read_common(r, SECOND_ORDER, m, constraint_model=_one_body(body_urdf) if constrained else None,
                         default_frame=_body_frame(body_urdf) if constrained else None)
    solver = r.table("solver")
    U0 = None
    if "initial_controls" in solver:
        U0 = r.check(read_initial_controls, solver["initial_controls"], "[solver].initial_controls", m, H,
                     common["control_min"], common["control_max"])

    return SceneSpec(
        name=name, description=description, source=source, inertia=inertia, actuation=act, urdf=urdf,
        R0=R0, Omega0=Omega0, Rd=Rd, Omegad=Omegad, tf=float(horizon["tf"]), dt=float(horizon["dt"]), horizon=H,
        integrator=integrator, S_u=S_u, S_R=S_R, attitude_kind=attitude_kind, S_Omega=S_Omega,
        running_S_R=running_S_R, running_S_Omega=running_S_Omega, initial_controls=U0, **common,
    )
