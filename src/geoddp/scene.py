"""Scene files: a TOML description of one attitude-control problem, parsed to plain values.

A scene file fixes the rigid body, the initial and target states, the time grid, the cost
weights and the solver options. :func:`load_scene` reads it into a frozen :class:`SceneSpec`
of validated numpy arrays and builtins; building models and solvers from it is someone
else's job, so this module never imports the solver.

Schema (``?`` = optional, with its default)::

    name? = "satellite_paper"           description? = "..."
    [model]    kind? = "satellite", inertia (3 numbers or 3x3, kg m^2), actuation? = I_3 (3 x m), urdf? (path)
    [initial]  exactly one of quaternion (x,y,z,w) | rotation (3x3);
               angular_velocity? = [0,0,0] (rad/s)
    [target]   exactly one of rotation | quaternion | euler_intrinsic ([[axis, deg], ...]);
               angular_velocity? = [0,0,0]
    [horizon]  tf (s), dt (s), integrator? = "euler" (euler | semi_implicit)
    [cost]     control (S_u), attitude (S_R or W_R), attitude_kind? = "chordal"
               (chordal | geodesic), angular_velocity (S_Omega),
               running_attitude? = 0, running_angular_velocity? = 0
    [solver]?  expansion? = "switch" (first | second | switch), switch_ratio? = 0.1 in (0, 1),
               tol? = 1e-8, grad_tol? = 1e-10, max_iter? = 200,
               second_order? = "exact" (exact | paper), initial_controls? (H x m, default 0)

Every error is an :class:`~geoddp.validate.InputError` naming the key path (``[cost].attitude``)
and the file.

A scene with ``[model] kind = "multibody"`` is a multibody scene on any Pinocchio URDF: its
schema and :class:`~geoddp.multibody_scene.MultibodySceneSpec` live in
:mod:`geoddp.multibody_scene`; :func:`load_scene`, :func:`parse_scene`, :func:`build_problem` and
:func:`solver_options` accept both kinds.
"""
from __future__ import annotations

import dataclasses
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Union

import numpy as np

from . import data
from . import validate as v
from .scene_common import (DEFAULT_EXPANSION, DEFAULT_GRAD_TOL, DEFAULT_MAX_ITER, DEFAULT_SWITCH_RATIO, DEFAULT_TOL,
                           EXPANSIONS, check_urdf as _check_urdf)
from .validate import InputError

if TYPE_CHECKING:
    from .multibody_scene import MultibodySceneSpec

__all__ = ["SceneSpec", "AnySceneSpec", "SCENE_KINDS", "load_scene", "scene_file", "parse_scene", "INTEGRATORS", "ATTITUDE_KINDS", "EXPANSIONS", "SECOND_ORDER"]

INTEGRATORS = ("euler", "semi_implicit")
ATTITUDE_KINDS = ("chordal", "geodesic")
SECOND_ORDER = ("exact", "paper")
AXES = ("x", "y", "z")
SCENE_KINDS = ("multibody", "satellite")  # [model].kind; absent means "satellite"

DEFAULT_INTEGRATOR = "euler"
DEFAULT_ATTITUDE_KIND = "chordal"
DEFAULT_SECOND_ORDER = "exact"

# Allowed keys per table: key -> required?
_TOP_KEYS = {"name": False, "description": False}
_SECTIONS: dict[str, dict[str, bool]] = {
    "model": {"kind": False, "inertia": True, "actuation": False, "urdf": False},
    "initial": {"quaternion": False, "rotation": False, "angular_velocity": False},
    "target": {"rotation": False, "quaternion": False, "euler_intrinsic": False, "angular_velocity": False},
    "horizon": {"tf": True, "dt": True, "integrator": False},
    "cost": {
        "control": True,
        "attitude": True,
        "attitude_kind": False,
        "angular_velocity": True,
        "running_attitude": False,
        "running_angular_velocity": False,
    },
    "solver": {
        "expansion": False,
        "switch_ratio": False,
        "tol": False,
        "grad_tol": False,
        "max_iter": False,
        "second_order": False,
        "initial_controls": False,
    },
}
_REQUIRED_SECTIONS = ("model", "initial", "target", "horizon", "cost")


def _readonly(a: np.ndarray) -> np.ndarray:
    # The spec is frozen; make its arrays immutable too so a caller cannot edit a shared scene.
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class SceneSpec:
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
        integrator: "euler" | "semi_implicit".
        S_u: (m, m) SPD control weight.
        S_R: (3, 3) PSD terminal attitude weight (S_R for chordal, W_R for geodesic).
        attitude_kind: "chordal" | "geodesic".
        S_Omega: (3, 3) PSD terminal angular-velocity weight.
        running_S_R: (3, 3) PSD attitude weight applied at every running step.
        running_S_Omega: (3, 3) PSD angular-velocity weight applied at every running step.
        expansion: "first" | "second" | "switch".
        switch_ratio: sigma in (0, 1) for the switch expansion.
        tol: stopping tolerance on |J_i - J_(i-1)|, >= 0.
        grad_tol: stopping tolerance on the gradient norm, >= 0.
        max_iter: maximum number of iterations, >= 1.
        second_order: "exact" | "paper" second-order terms.
        initial_controls: (H, m) initial control guess, or None for zeros.

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
    expansion: str
    switch_ratio: float
    tol: float
    grad_tol: float
    max_iter: int
    second_order: str
    initial_controls: np.ndarray | None

    def __post_init__(self) -> None:
        # Validate with field names as parameter names; the parser has already checked the
        # same values under their TOML key paths, so these only fire for direct construction
        # and for with_overrides().
        put = lambda k, val: object.__setattr__(self, k, val)  # noqa: E731  (frozen dataclass)
        for k in ("name", "description", "source"):
            if not isinstance(getattr(self, k), str):
                raise InputError(k, f"expected a string, got {getattr(self, k)!r}")
        put("inertia", _readonly(v.inertia_matrix(self.inertia, "inertia")))
        put("actuation", _readonly(v.actuation_matrix(self.actuation, "actuation")))
        m = self.actuation.shape[1]
        if self.urdf is not None:
            put("urdf", _check_urdf(self.urdf, "urdf", Path.cwd()))
        put("R0", _readonly(v.rotation_matrix(self.R0, "R0")))
        put("Omega0", _readonly(v.finite_array(self.Omega0, "Omega0", shape=(3,))))
        put("Rd", _readonly(v.rotation_matrix(self.Rd, "Rd")))
        put("Omegad", _readonly(v.finite_array(self.Omegad, "Omegad", shape=(3,))))
        H = v.time_grid(self.tf, self.dt, tf_name="tf", dt_name="dt")
        put("tf", float(self.tf))
        put("dt", float(self.dt))
        h = v.positive_int(self.horizon, "horizon")
        if h != H:
            raise InputError("horizon", f"expected tf / dt = {H} (it is derived from tf and dt), got {h}")
        put("integrator", v.choice(self.integrator, "integrator", INTEGRATORS))
        put("S_u", _readonly(v.spd_matrix(self.S_u, "S_u", m)))
        put("S_R", _readonly(v.spd_matrix(self.S_R, "S_R", 3, semidefinite=True)))
        put("attitude_kind", v.choice(self.attitude_kind, "attitude_kind", ATTITUDE_KINDS))
        put("S_Omega", _readonly(v.spd_matrix(self.S_Omega, "S_Omega", 3, semidefinite=True)))
        put("running_S_R", _readonly(v.spd_matrix(self.running_S_R, "running_S_R", 3, semidefinite=True)))
        put(
            "running_S_Omega",
            _readonly(v.spd_matrix(self.running_S_Omega, "running_S_Omega", 3, semidefinite=True)),
        )
        put("expansion", v.choice(self.expansion, "expansion", EXPANSIONS))
        put("switch_ratio", v.bounded_float(self.switch_ratio, "switch_ratio", 0.0, 1.0, False, False))
        put("tol", v.nonnegative_float(self.tol, "tol"))
        put("grad_tol", v.nonnegative_float(self.grad_tol, "grad_tol"))
        put("max_iter", v.positive_int(self.max_iter, "max_iter"))
        put("second_order", v.choice(self.second_order, "second_order", SECOND_ORDER))
        if self.initial_controls is not None:
            U = v.finite_array(self.initial_controls, "initial_controls", shape=(H, m))
            put("initial_controls", _readonly(U))

    @property
    def num_inputs(self) -> int:
        """m, the number of control inputs (columns of the actuation matrix)."""
        return int(self.actuation.shape[1])

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


AnySceneSpec = Union[SceneSpec, "MultibodySceneSpec"]
"""What :func:`load_scene` returns: a satellite or a multibody scene."""


# --------------------------------------------------------------------------------------
# parsing


def scene_file(scene: str | Path) -> Path:
    """The scene file that ``scene`` names: a path, or a built-in scene's name.

    An existing file always wins. Otherwise a bare name (no folder, no ``.toml``), such as
    ``"quadrotor"`` or ``"satellite_paper"``, is a built-in scene (:func:`geoddp.data.scene_names`);
    anything else is returned as a path for the reader to report.

    Raises:
        InputError: naming ``scene``: a bare name that is neither a file nor a built-in scene (the
            message suggests the closest built-in name and lists them).
    """
    p = Path(scene)
    text = str(scene)
    if p.is_file() or Path(text).name != text or p.suffix == ".toml" or not text:
        return p
    return data.scene_path(text, "scene")


def load_scene(path: str | Path) -> AnySceneSpec:
    """Read and validate a TOML scene file: a :class:`SceneSpec`, or a
    :class:`~geoddp.multibody_scene.MultibodySceneSpec` if ``[model] kind = "multibody"``.

    Args:
        path: scene file, or the name of a built-in scene (``"satellite_paper"``,
            ``"quadrotor"``; see :func:`scene_file`). Relative paths inside it
            (``[model].urdf``) are resolved against the file's directory; a bare URDF file
            name not found there is the built-in URDF of that name.

    Raises:
        InputError: the file is missing or unreadable, is not valid TOML (the message gives
            the line and column), or any key is unknown, missing or invalid; ``scene`` for a
            name that is neither a file nor a built-in scene.
    """
    p = scene_file(path)
    src = str(p)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise InputError("scene file", f"expected a readable TOML file, got {src!r} ({exc.strerror})") from None
    try:
        text = raw.decode("utf-8")
        data = tomllib.loads(text)
    except UnicodeDecodeError as exc:
        raise InputError("scene file", f"expected UTF-8 text, got invalid bytes at offset {exc.start}", src) from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError("scene file", _toml_error_detail(exc, text), src) from None
    return _dispatch(data, src, base_dir=p.resolve().parent, default_name=p.stem)


def _dispatch(data: Mapping[str, Any], source: str, base_dir: Path, default_name: str) -> AnySceneSpec:
    """Route to the satellite or the multibody parser by ``[model].kind``."""
    model = data.get("model")
    kind = model.get("kind", "satellite") if isinstance(model, Mapping) else "satellite"
    if kind == "multibody":
        from .multibody_scene import parse_multibody_scene

        return parse_multibody_scene(data, source, base_dir=base_dir, default_name=default_name)
    if kind != "satellite":
        raise InputError("[model].kind", f"expected one of {' | '.join(SCENE_KINDS)} (default satellite), "
                         f"got {kind!r}", source)
    return _parse(data, source, base_dir=base_dir, default_name=default_name)


def _toml_error_detail(exc: tomllib.TOMLDecodeError, text: str) -> str:
    """Normalise a tomllib error to "malformed TOML at line L, column C: ...; the line reads ..."."""
    msg = str(exc)
    lines = text.splitlines()
    m = re.search(r"\s*\(at line (\d+), column (\d+)\)$", msg)
    if m:
        line, where = int(m.group(1)), f"line {m.group(1)}, column {m.group(2)}"
        msg = msg[: m.start()]
    else:
        # Python 3.11's tomllib reports unterminated constructs only as "at end of document";
        # point at the last non-blank line, which is where such a construct was left open.
        msg = re.sub(r"\s*\(at end of document\)$", "", msg)
        line = max((i + 1 for i, t in enumerate(lines) if t.strip()), default=1)
        where = f"line {line} (end of file)"
    shown = lines[line - 1].strip() if 0 < line <= len(lines) else ""
    tail = f"; the line reads {shown!r}" if shown else ""
    return f"malformed TOML at {where}: {msg}{tail}"


def parse_scene(data: Mapping[str, Any], source: str = "<dict>") -> AnySceneSpec:
    """Validate an already-parsed scene (the dict a TOML parser would produce).

    Relative ``[model].urdf`` paths are resolved against the directory of ``source`` if it is
    a file path, else against the current directory.
    """
    if not isinstance(data, Mapping):
        raise InputError("scene", f"expected a table (dict), got {type(data).__name__}", source)
    base = Path(source).resolve().parent if source != "<dict>" else Path.cwd()
    default_name = Path(source).stem if source != "<dict>" else "scene"
    return _dispatch(data, source, base_dir=base, default_name=default_name)


class _Reader(v.SourceReader):
    """Walks the scene dict, checking keys and wrapping errors with the file name."""

    def __init__(self, data: Mapping[str, Any], source: str) -> None:
        super().__init__(source)
        self.data = data

    def unknown_key(self, key: str, allowed: list[str], section: str | None) -> InputError:
        path = f"[{section}].{key}" if section else key
        guess = v.closest(key, allowed)
        if guess:
            hint = f"did you mean {guess!r}?"
        else:
            # A key put in the wrong table: point at the table where it belongs.
            homes = [f"[{s}].{key}" for s, keys in _SECTIONS.items() if key in keys and s != section]
            hint = f"did you mean {' or '.join(homes)}?" if homes else ""
        listing = ", ".join(allowed)
        where = f"[{section}]" if section else "the top level"
        detail = f"unknown key in {where}; {hint + ' ' if hint else ''}allowed keys: {listing}"
        return self.err(path, detail)

    def top(self) -> None:
        allowed_top = list(_TOP_KEYS) + [f"[{s}]" for s in _SECTIONS]
        for key, val in self.data.items():
            if key in _SECTIONS:
                if not isinstance(val, Mapping):
                    raise self.err(f"[{key}]", f"expected a table, got {type(val).__name__} {val!r}")
            elif key not in _TOP_KEYS:
                if isinstance(val, Mapping):
                    guess = v.closest(key, list(_SECTIONS))
                    hint = f"did you mean [{guess}]? " if guess else ""
                    raise self.err(
                        f"[{key}]", f"unknown section; {hint}allowed sections: {', '.join(_SECTIONS)}"
                    )
                raise self.unknown_key(key, allowed_top, None)
        for s in _REQUIRED_SECTIONS:
            if s not in self.data:
                raise self.err(f"[{s}]", "missing required section")

    def section(self, name: str) -> dict[str, Any]:
        table = dict(self.data.get(name, {}))
        spec = _SECTIONS[name]
        for key in table:
            if key not in spec:
                raise self.unknown_key(key, list(spec), name)
        for key, required in spec.items():
            if required and key not in table:
                raise self.err(f"[{name}].{key}", "missing required key")
        return table

    def string(self, table: Mapping[str, Any], key: str, path: str, default: str) -> str:
        val = table.get(key, default)
        if not isinstance(val, str):
            raise self.err(path, f"expected a string, got {val!r} ({type(val).__name__})")
        return val

    def attitude(self, table: Mapping[str, Any], section: str, forms: tuple[str, ...]) -> np.ndarray:
        given = [f for f in forms if f in table]
        if len(given) != 1:
            listing = " | ".join(forms)
            got = "none" if not given else " and ".join(given)
            raise self.err(f"[{section}]", f"expected exactly one of {listing}, got {got}")
        form = given[0]
        path = f"[{section}].{form}"
        val = table[form]
        if form == "rotation":
            return self.check(v.rotation_matrix, val, path)
        if form == "quaternion":
            return self.check(v.quaternion_to_rotation, val, path)
        return self.euler(val, path)

    def euler(self, val: Any, path: str) -> np.ndarray:
        example = 'a list of [axis, degrees] pairs such as [["x", 30.0], ["z", 70.0]]'
        if not isinstance(val, list) or not val:
            raise self.err(path, f"expected {example}, got {val!r}")
        R = np.eye(3)
        for i, item in enumerate(val):
            ipath = f"{path}[{i}]"
            if not isinstance(item, list) or len(item) != 2:
                raise self.err(ipath, f"expected an [axis, degrees] pair, got {item!r}")
            axis, deg = item
            if isinstance(axis, str):
                axis = axis.lower()  # "X" and "x" name the same body axis here
            axis = self.check(v.choice, axis, f"{ipath} axis", AXES)
            angle = np.deg2rad(self.check(v.finite_float, deg, f"{ipath} angle (degrees)"))
            # Intrinsic composition: each rotation is about the already-rotated body axis,
            # which is right-multiplication: R = Rot_a1(t1) Rot_a2(t2) ...
            R = R @ _axis_rotation(axis, angle)
        return R


def _axis_rotation(axis: str, angle: float) -> np.ndarray:
    """Elementary rotation (3, 3) by ``angle`` radians about body axis "x" | "y" | "z"."""
    c, s = np.cos(angle), np.sin(angle)
    if axis == "x":
        return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    if axis == "y":
        return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _parse(data: Mapping[str, Any], source: str, base_dir: Path, default_name: str) -> SceneSpec:
    r = _Reader(data, source)
    r.top()
    name = r.string(data, "name", "name", default_name)
    description = r.string(data, "description", "description", "")

    model = r.section("model")
    inertia = r.check(v.inertia_matrix, model["inertia"], "[model].inertia")
    if "actuation" in model:
        act = r.check(v.actuation_matrix, model["actuation"], "[model].actuation")
    else:
        act = np.eye(3)
    m = act.shape[1]
    urdf = None
    if "urdf" in model:
        urdf = r.check(_check_urdf, model["urdf"], "[model].urdf", base_dir)

    zero3 = [0.0, 0.0, 0.0]
    initial = r.section("initial")
    R0 = r.attitude(initial, "initial", ("quaternion", "rotation"))
    p = "[initial].angular_velocity"
    Omega0 = r.check(v.finite_array, initial.get("angular_velocity", zero3), p, shape=(3,))

    target = r.section("target")
    Rd = r.attitude(target, "target", ("rotation", "quaternion", "euler_intrinsic"))
    p = "[target].angular_velocity"
    Omegad = r.check(v.finite_array, target.get("angular_velocity", zero3), p, shape=(3,))

    horizon = r.section("horizon")
    H = r.check(v.time_grid, horizon["tf"], horizon["dt"], tf_name="[horizon].tf", dt_name="[horizon].dt")
    p = "[horizon].integrator"
    integrator = r.check(v.choice, horizon.get("integrator", DEFAULT_INTEGRATOR), p, INTEGRATORS)

    cost = r.section("cost")

    def weight(key: str, n: int, semidefinite: bool, default: Any = None) -> np.ndarray:
        p = f"[cost].{key}"
        return r.check(v.spd_matrix, cost.get(key, default), p, n, semidefinite=semidefinite)

    S_u = weight("control", m, semidefinite=False)
    S_R = weight("attitude", 3, semidefinite=True)
    p = "[cost].attitude_kind"
    attitude_kind = r.check(v.choice, cost.get("attitude_kind", DEFAULT_ATTITUDE_KIND), p, ATTITUDE_KINDS)
    S_Omega = weight("angular_velocity", 3, semidefinite=True)
    running_S_R = weight("running_attitude", 3, semidefinite=True, default=0.0)
    running_S_Omega = weight("running_angular_velocity", 3, semidefinite=True, default=0.0)

    solver = r.section("solver")
    p = "[solver].expansion"
    expansion = r.check(v.choice, solver.get("expansion", DEFAULT_EXPANSION), p, EXPANSIONS)
    p = "[solver].switch_ratio"
    switch_ratio = r.check(
        v.bounded_float, solver.get("switch_ratio", DEFAULT_SWITCH_RATIO), p, 0.0, 1.0, False, False
    )
    p = "[solver].tol"
    tol = r.check(v.nonnegative_float, solver.get("tol", DEFAULT_TOL), p)
    p = "[solver].grad_tol"
    grad_tol = r.check(v.nonnegative_float, solver.get("grad_tol", DEFAULT_GRAD_TOL), p)
    p = "[solver].max_iter"
    max_iter = r.check(v.positive_int, solver.get("max_iter", DEFAULT_MAX_ITER), p)
    p = "[solver].second_order"
    second_order = r.check(v.choice, solver.get("second_order", DEFAULT_SECOND_ORDER), p, SECOND_ORDER)
    U0 = None
    if "initial_controls" in solver:
        p = "[solver].initial_controls"
        U0 = r.check(v.finite_array, solver["initial_controls"], p, shape=(H, m))

    return SceneSpec(
        name=name,
        description=description,
        source=source,
        inertia=inertia,
        actuation=act,
        urdf=urdf,
        R0=R0,
        Omega0=Omega0,
        Rd=Rd,
        Omegad=Omegad,
        tf=float(horizon["tf"]),
        dt=float(horizon["dt"]),
        horizon=H,
        integrator=integrator,
        S_u=S_u,
        S_R=S_R,
        attitude_kind=attitude_kind,
        S_Omega=S_Omega,
        running_S_R=running_S_R,
        running_S_Omega=running_S_Omega,
        expansion=expansion,
        switch_ratio=switch_ratio,
        tol=tol,
        grad_tol=grad_tol,
        max_iter=max_iter,
        second_order=second_order,
        initial_controls=U0,
    )


def build_problem(spec: AnySceneSpec):
    """The validated scene as a :class:`geoddp.problem.Problem` (model, costs, horizon, x0); the
    model's backend is chosen when it is built (TSO(3) closed forms for the satellite)."""
    from .problem import satellite_problem

    if not isinstance(spec, SceneSpec):
        from .multibody_scene import build_multibody_problem

        return build_multibody_problem(spec)

    return satellite_problem(
        inertia=spec.inertia, actuation=spec.actuation, dt=spec.dt, horizon=spec.horizon,
        R0=spec.R0, Omega0=spec.Omega0, R_d=spec.Rd, Omega_d=spec.Omegad,
        S_u=spec.S_u, S_R=spec.S_R, S_Omega=spec.S_Omega, attitude_kind=spec.attitude_kind,
        running_S_R=spec.running_S_R, running_S_Omega=spec.running_S_Omega,
        integrator=spec.integrator, second_order=spec.second_order, urdf=spec.urdf,
    )


def solver_options(spec: AnySceneSpec, **overrides: Any):
    """The scene's ``[solver]`` table as :class:`geoddp.solver.SolverOptions`."""
    from .solver import SolverOptions

    kw = dict(expansion=spec.expansion, switch_ratio=spec.switch_ratio, tol=spec.tol,
              grad_tol=spec.grad_tol, max_iter=spec.max_iter)
    kw.update(overrides)
    return SolverOptions(**kw)
