"""Any Pinocchio multibody model as a DDP model on its state Lie group Q x R^nv.

State x = (q, v): q in R^nq (Pinocchio's configuration coordinates), v in R^nv. Perturbations are
zeta = (dq, dv) in R^(2 nv) with q = integrate(q_bar, dq), v = v_bar + dv (:meth:`Multibody.retract`
and :meth:`Multibody.local` are the one place this is defined), so nx = 2 nv.

Dynamics (Pinocchio is the source of truth)::

    v+ = v + dt aba(q, v, H u)                      (H: nv x m actuation, generalised forces)
    q+ = integrate(q, dt w),  w = v  (explicit Euler, paper eq. disceq)
                              w = v+ (semi-implicit Euler, Crocoddyl's).

or, with integrator "rk4", the fourth-order Runge-Kutta-Munthe-Kaas step (cpp/dynamics/rkmk4.hpp, where the
scheme is written out; second-order terms by central differences of its analytic step Jacobian,
symmetrised), or the forward variational Euler step ("variational", :mod:`geoddp.models.variational`).

Expansion along a trajectory, z = (dq, dv, du), nz = 2 nv + m, in the compiled core
(:mod:`geoddp.models.compiled`, cpp/): the velocity update's first order from
``computeABADerivatives`` and its second order exact from Pinocchio's
``ComputeRNEASecondOrderDerivatives`` (no differences); the reconstruction's first order from
``dIntegrate``'s ARG0 = Ad_exp(-omega), ARG1 = Jr(omega) and its second order exact per joint group
(the formula of :func:`geoddp.models.integrators.expand`, with SE(3)'s Jr and dJr in closed form:
Pinocchio's SE(3) Jr is inaccurate at small angles). rk4: its analytic step Jacobian and, for the
second order, central differences of it. variational: the residual's Jacobian analytic, with the
kinetic-energy Hessian from the same second-order RNEA, and its second order one central
difference of that Jacobian. Array layout: :class:`geoddp.models.integrators.Expansion` with n = 2 nv.

The Python path geoddp ran before its core is the tests' oracle (tests/oracle_multibody.py).
"""
from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..lie import product as cfg
from ..validate import (InputError, choice, finite_array, keywords_checked, nonnegative_int, positive_float, spin_from_environment,
                        threads_from_environment)
from . import compiled
from . import integrators as integ
from . import variational
from .urdf import build_checked_model, check_model, read_urdf_text

ROOTS = ("free_flyer", "spherical", "fixed")
INTEGRATORS = integ.INTEGRATORS + ("rk4", "variational")
SECOND_ORDER_KINDS = ("exact",)
BACKENDS = ("auto", "compiled")


def _root_joint(root: str):
    return {"free_flyer": pin.JointModelFreeFlyer(), "spherical": pin.JointModelSpherical(), "fixed": None}[root]


def root_of(model: pin.Model) -> str:
    """The root kind of a built ``pin.Model``: "free_flyer" or "spherical" when its first joint
    (the one on the universe) is a free flyer or a spherical joint, else "fixed" (the first link is
    welded to the world and every joint is a robot joint)."""
    first = 1  # joint 0 is the universe
    if model.njoints <= first or model.parents[first] != 0:
        return "fixed"
    kind = model.joints[first].shortname()
    return {"JointModelFreeFlyer": "free_flyer", "JointModelSpherical": "spherical"}.get(kind, "fixed")


def _primitive_record(shape) -> dict | None:
    """The JSON record of a coal primitive (what the replay redraws), or None for other shapes."""
    kind = type(shape).__name__
    if kind == "Box":
        return {"shape": "box", "size": (2.0 * np.asarray(shape.halfSide)).tolist()}
    if kind == "Sphere":
        return {"shape": "sphere", "radius": float(shape.radius)}
    if kind in ("Cylinder", "Capsule"):
        return {"shape": kind.lower(), "radius": float(shape.radius), "length": 2.0 * float(shape.halfLength)}
    return None


def geometry_records(model: pin.Model, geometry: pin.GeometryModel) -> list[dict]:
    """Plain (JSON) records of a visual ``pin.GeometryModel`` attached to ``model``: per object its
    name, parent joint and frame *names*, placement in the parent joint frame (4, 4; metres),
    colour (RGBA in [0, 1]), and either the mesh file (absolute path, scale (3,)) or a primitive
    (box size (3,); sphere radius; cylinder / capsule radius and length, metres). Objects that are
    neither (e.g. a height field built in code) are left out: the replay draws none of them.
    :func:`geoddp.viz.model.load_visual_model` rebuilds the geometry model from these."""
    out = []
    for obj in geometry.geometryObjects:
        rec = {"name": obj.name, "joint": model.names[obj.parentJoint],
               "frame": model.frames[obj.parentFrame].name if obj.parentFrame < len(model.frames) else None,
               "placement": obj.placement.homogeneous.tolist(), "color": np.asarray(obj.meshColor, float).tolist(),
               "override_material": bool(obj.overrideMaterial)}
        path = getattr(obj, "meshPath", "") or ""
        if Path(path).suffix.lower() in (".dae", ".stl", ".obj"):
            rec.update(mesh=str(Path(path).resolve()) if Path(path).exists() else path,
                       scale=np.asarray(obj.meshScale, float).tolist())
        else:
            prim = _primitive_record(obj.geometry)
            if prim is None:
                continue
            rec.update(prim)
        out.append(rec)
    return out


def package_dir_tuple(dirs: object) -> tuple[str, ...]:
    """Package folders (``package://`` mesh URIs) as a tuple of str: one path or a list or tuple of
    paths; anything else is an InputError naming package_dirs."""
    if isinstance(dirs, (str, os.PathLike)):
        dirs = (dirs,)
    if not isinstance(dirs, (list, tuple)) or not all(isinstance(d, (str, os.PathLike)) for d in dirs):
        raise InputError("package_dirs", f"expected a path or a list of paths, got {dirs!r}")
    return tuple(str(d) for d in dirs)


@keywords_checked
@dataclass
class Multibody:
    """A Pinocchio model from a URDF with a discrete-time integrator: constants only.

    Attributes:
        urdf: path of the URDF file.
        root: root joint: "free_flyer" (SE(3)), "spherical" (SO(3)) or "fixed" (none).
        actuation: (nv, m) matrix H mapping inputs to generalised forces (N, N m); default
            identity (every degree of freedom actuated). For a free-flyer root the first six
            rows are the body wrench [force; torque] in the root body frame.
        dt: time step, s.
        integrator: "euler" (paper), "semi_implicit" (Crocoddyl), "rk4" (RKMK4 on the Lie group;
            second order by central differences of its analytic step Jacobian) or "variational"
            (the paper's forward variational Euler, implicit; :mod:`geoddp.models.variational`).
        gravity: Pinocchio's default gravity (-9.81 m/s^2 along world z) if True, none if False.
        second_order: "exact" (the only kind for multibody models).
        backend: "auto" (the default) or "compiled": the compiled core, the only backend (the
            Python path is the tests' oracle, tests/oracle_multibody.py). Holds "compiled".
        threads: worker threads of the compiled expansion (per-node derivatives); 0 = the
            environment variable GEODDP_THREADS if set (:func:`geoddp.validate.threads_from_environment`),
            else the core's default: ``geoddp._core.default_threads()`` (min(2, cores in the affinity
            mask)) workers of a persistent pool, at least 16 nodes each, for first- and second-order
            passes alike.
        contract: with the compiled backend, keep the second-order terms of a solve's expansion
            factored and contract them with V_x' inside the backward pass (True, the default:
            :meth:`expansion` with ``contracted=True``) instead of forming Theta, Gamma, Xi;
            both give the same Q-function blocks to round-off (tests/test_core_contracted.py).
    """

    urdf: str | Path | None
    root: str = "free_flyer"
    actuation: np.ndarray | None = None
    dt: float = field(kw_only=True)  # required, by keyword
    integrator: str = "euler"
    gravity: bool = True
    second_order: str = "exact"
    backend: str = "auto"
    threads: int = 0
    contract: bool = True
    package_dirs: tuple[str, ...] = field(default=(), kw_only=True)
    source_model: pin.Model | None = field(default=None, kw_only=True, repr=False)
    visual_model: pin.GeometryModel | None = field(default=None, kw_only=True, repr=False)
    pin_model: pin.Model = field(init=False, repr=False)
    groups: list = field(init=False, repr=False)
    _urdf_record: tuple[str, str] | None = field(init=False, repr=False, default=None)  # (path, text), read at the first description

    def __post_init__(self) -> None:
        self.root = choice(self.root, "root", ROOTS)
        self.dt = positive_float(self.dt, "dt")
        self.integrator = choice(self.integrator, "integrator", INTEGRATORS)
        self.second_order = choice(self.second_order, "second_order", SECOND_ORDER_KINDS)
        choice(self.backend, "backend", BACKENDS)  # "python" is refused, naming backend
        self.backend = "compiled"  # the core runs every integrator
        self.threads = nonnegative_int(self.threads, "threads")
        if self.threads == 0:  # the environment's choice (a sweep's workers), else the core's default
            self.threads = threads_from_environment()
        spin_from_environment()  # the core read GEODDP_SPIN_US when it loaded: refuse a bad value here
        if not isinstance(self.contract, (bool, np.bool_)):
            raise InputError("contract", f"expected True or False, got {self.contract!r}")
        if not isinstance(self.gravity, (bool, np.bool_)):
            raise InputError("gravity", f"expected True or False, got {self.gravity!r}")
        self.package_dirs = package_dir_tuple(self.package_dirs)
        source = "model" if self.source_model is not None else "urdf"
        if self.source_model is not None:
            model = self._from_source()
        else:
            if not isinstance(self.urdf, (str, Path)):
                raise InputError("urdf", f"expected a path to a URDF file, got {type(self.urdf).__name__}")
            self.urdf = Path(self.urdf)
            if not self.urdf.is_file():
                raise InputError("urdf", f"expected an existing URDF file, got {str(self.urdf)!r} (no such file)")
            rj = _root_joint(self.root)
            model = build_checked_model(self.urdf, rj)  # encoding, axes, masses, inertias; urdfdom's stderr captured
        if model.nv == 0:
            raise InputError(source, "expected at least one degree of freedom, got nv = 0 (fixed root, no joints)")
        if not self.gravity:
            model.gravity = pin.Motion.Zero()
        try:
            self.groups = cfg.joint_groups(model)
        except ValueError as exc:
            raise InputError(source, str(exc)) from None
        self.pin_model = model
        if self.actuation is None:
            self.actuation = np.eye(model.nv)
        else:
            Hm = finite_array(self.actuation, "actuation")
            if Hm.ndim != 2 or Hm.shape[0] != model.nv or Hm.shape[1] < 1:
                raise InputError("actuation", f"expected shape ({model.nv}, m) with m >= 1 (nv = {model.nv}), got shape {Hm.shape}")
            zero = np.flatnonzero(np.linalg.norm(Hm, axis=0) == 0.0)
            if zero.size:
                raise InputError("actuation", f"expected every column to be non-zero, got an all-zero column {int(zero[0])}")
            self.actuation = Hm

    @classmethod
    def from_model(cls, model: pin.Model, geometry: pin.GeometryModel | None = None, root: str | None = None, *,
                   dt: float, actuation: np.ndarray | None = None, integrator: str = "euler",
                   gravity: bool | None = None, backend: str = "auto", threads: int = 0, contract: bool = True,
                   urdf: str | Path | None = None, package_dirs: tuple[str, ...] | list[str] | str = ()) -> "Multibody":
        """A model from a ``pin.Model`` built (and possibly edited) in Python.

        The model is copied: later edits of ``model`` do not change this one. Anything Pinocchio
        can build works: a reduced model (``pin.buildReducedModel``), edited inertias, masses or
        placements, joints added in code. Costs name its frames by their names in ``model``.

        Args:
            model: the kinematic tree with its inertias (kg, m, kg m^2) and gravity.
            geometry: its visual ``pin.GeometryModel`` (optional): the replay draws it (meshes by
                file, primitives by size); without one, the replay rebuilds the visuals from
                ``urdf`` when given (links found by name in ``model``), else draws none.
            root: the root joint kind, read from the model (its first joint: free flyer,
                spherical, else "fixed"); when given it must match, since the root is part of a
                built model (build with ``pin.JointModelFreeFlyer()`` for a floating base).
            dt: time step, s. actuation, integrator, backend, threads, contract: as for the constructor.
            gravity: None keeps ``model.gravity``; False sets it to zero; True requires the
                model's gravity to be non-zero (Pinocchio's default, -9.81 m/s^2 along world z,
                when the model has none).
            urdf: the URDF the model was built from (optional): only for the replay's visuals.
            package_dirs: where ``package://`` mesh URIs of ``urdf`` are found (the replay).

        Raises:
            InputError: naming ``model`` (not a ``pin.Model``, no degree of freedom, non-finite
                or non-physical inertias), ``geometry`` (not a ``pin.GeometryModel``, or an
                object on a joint the model does not have), ``root`` (mismatch), or the other
                parameters as for the constructor.
        """
        if not isinstance(model, pin.Model):
            raise InputError("model", f"expected a pinocchio.Model, got {type(model).__name__}")
        if geometry is not None and not isinstance(geometry, pin.GeometryModel):
            raise InputError("geometry", f"expected a pinocchio.GeometryModel or None, got {type(geometry).__name__}")
        detected = root_of(model)
        if root is not None:
            root = choice(root, "root", ROOTS)
            if root != detected:
                raise InputError("root", f"expected the model's own root {detected!r} (its first joint is "
                                 f"{model.joints[1].shortname() if model.njoints > 1 else 'none'}), got {root!r}; the root "
                                 "joint is part of a built pin.Model: build it with pin.JointModelFreeFlyer() (or "
                                 "JointModelSpherical()) for a floating base")
        has_gravity = bool(np.any(model.gravity.vector))
        if gravity is None:
            gravity = has_gravity
        if urdf is not None:
            if not isinstance(urdf, (str, Path)) or not Path(urdf).is_file():
                raise InputError("urdf", f"expected an existing URDF file or None, got {urdf!r}")
        copy = pin.Model(model)
        if gravity and not has_gravity:
            copy.gravity = pin.Motion(np.array([0.0, 0.0, -9.81]), np.zeros(3))
        return cls(None if urdf is None else Path(urdf), root=detected, actuation=actuation, dt=dt,
                   integrator=integrator, gravity=bool(gravity), backend=backend, threads=threads, contract=contract,
                   package_dirs=package_dirs, source_model=copy,
                   visual_model=None if geometry is None else pin.GeometryModel(geometry))

    def _from_source(self) -> pin.Model:
        """Checks of a model handed over in Python (see :meth:`from_model`)."""
        model = self.source_model
        if not isinstance(model, pin.Model):
            raise InputError("model", f"expected a pinocchio.Model, got {type(model).__name__}")
        detected = root_of(model)
        if self.root != detected:
            raise InputError("root", f"expected the model's own root {detected!r}, got {self.root!r}")
        check_model(model, "model")
        geometry = self.visual_model
        if geometry is not None:
            for obj in geometry.geometryObjects:
                if obj.parentJoint >= model.njoints:
                    raise InputError("geometry", f"object {obj.name!r} hangs on joint {obj.parentJoint}, but the model has "
                                     f"{model.njoints} joints: pass the geometry model built (or reduced) with this model")
        return pin.Model(model)

    def description(self) -> dict:
        """What a Result needs to rebuild the model without the solver: kind "multibody", dt,
        integrator, the root joint kind, nq, nv, and the model itself: the URDF (absolute path and
        its text as solved) for a model built from one; for a model handed over as a ``pin.Model``
        (:meth:`from_model`) the model serialised (``pin_model``: Pinocchio's text archive, exact),
        its visual geometry as plain records (``geometry_objects``,
        :func:`geometry_records`) when one was given, and the URDF when one was named.
        ``package_dirs`` when given (where ``package://`` mesh URIs are found)."""
        out = {"kind": "multibody", "dt": self.dt, "integrator": self.integrator, "root": self.root,
               "nq": self.nq, "nv": self.nv}
        if self.urdf is not None:
            if self._urdf_record is None:  # read once, at the first Result (not on every solve)
                urdf = Path(self.urdf).resolve()
                self._urdf_record = (str(urdf), read_urdf_text(urdf))
            out.update(urdf=self._urdf_record[0], urdf_xml=self._urdf_record[1])
        if self.source_model is not None:
            out["pin_model"] = self.pin_model.saveToString()
            if self.visual_model is not None:
                out["geometry_objects"] = geometry_records(self.pin_model, self.visual_model)
        if self.package_dirs:
            out["package_dirs"] = list(self.package_dirs)
        return out

    # ------------------------------------------------------------------ sizes
    @property
    def nq(self) -> int:
        return int(self.pin_model.nq)

    @property
    def nv(self) -> int:
        return int(self.pin_model.nv)

    @property
    def nx(self) -> int:
        """Tangent dimension of the state, 2 nv."""
        return 2 * self.nv

    @property
    def nu(self) -> int:
        """Number of inputs m."""
        return int(self.actuation.shape[1])

    @property
    def contracts_second_order(self) -> bool:
        """True if :meth:`expansion` can return factored second-order terms (``contracted=True``)."""
        return bool(self.contract) and self.integrator in compiled.CONTRACTED_INTEGRATORS

    @property
    def semi_implicit(self) -> bool:
        return self.integrator == "semi_implicit"

    def neutral(self) -> np.ndarray:
        """Pinocchio's neutral configuration (nq,)."""
        return pin.neutral(self.pin_model)

    # ------------------------------------------------------------------ state chart
    def retract(self, q: np.ndarray, v: np.ndarray, zeta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x exp(zeta) = (integrate(q, dq), v + dv); q (nq,), v (nv,), zeta (2 nv,)."""
        nv = self.nv
        return pin.integrate(self.pin_model, q, zeta[:nv]), v + zeta[nv:]

    def local(self, q_bar: np.ndarray, v_bar: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`retract`: zeta = (difference(q_bar, q), v - v_bar), (2 nv,).

        ``pin.difference`` with exact SO(2) entries (:func:`geoddp.lie.product.difference`).
        """
        return np.concatenate([cfg.difference(self.pin_model, self.groups, q_bar, q), v - v_bar])

    # ------------------------------------------------------------------ dynamics
    def step(self, q: np.ndarray, v: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One step: q (nq,), v (nv,) (m/s, rad/s per joint), u (m,) -> (q+, v+): a rollout of
        one control."""
        Q, V = self.rollout(q, v, np.reshape(u, (1, -1)))
        return Q[1], V[1]

    def check_state(self, q: np.ndarray, v: np.ndarray, name: str | tuple[str, str] = "initial"
                    ) -> tuple[np.ndarray, np.ndarray]:
        """Validated float64 copies of a state: q (nq,) finite with unit quaternions / (cos, sin)
        pairs (to 1e-9), v (nv,) finite; errors name ``name.q`` / ``name.v``, or the two names of
        a pair (``("q0", "v0")``)."""
        nq, nv = name if isinstance(name, tuple) else (f"{name}.q", f"{name}.v")
        q = finite_array(q, nq, (self.nq,))
        v = finite_array(v, nv, (self.nv,))
        if not pin.isNormalized(self.pin_model, q, 1e-9):
            raise InputError(nq, "expected unit quaternions and unit (cos, sin) pairs (use pin.normalize), got a non-normalised configuration")
        return q, v

    def check_controls(self, controls: np.ndarray, H: int | None = None) -> np.ndarray:
        """Validate controls (H, m)."""
        return finite_array(controls, "controls", (H, self.nu))

    @contextlib.contextmanager
    def _step_errors(self):
        """The core's variational step failure as the Python path raises it (naming dt)."""
        try:
            yield
        except compiled._core.StepDidNotConverge as exc:
            raise variational.StepDidNotConverge(variational.not_converged_message(self.dt, str(exc))) from None

    def rollout(self, q0: np.ndarray, v0: np.ndarray, controls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Open-loop rollout: q0 (nq,), v0 (nv,), controls (H, m) -> Q (H+1, nq), V (H+1, nv)."""
        q0, v0 = self.check_state(q0, v0)
        U = self.check_controls(controls)
        with self._step_errors():
            return compiled._core.rollout(self.pin_model, self.actuation, self.dt, compiled.INTEGRATORS[self.integrator], q0, v0, U)

    def rollout_closed_loop(
        self, q0: np.ndarray, v0: np.ndarray, Q_bar: np.ndarray, V_bar: np.ndarray, u_bar: np.ndarray,
        k_ff: np.ndarray, K_fb: np.ndarray, gamma: float, Q_out: np.ndarray, V_out: np.ndarray, u_out: np.ndarray,
        lower: np.ndarray | None = None, upper: np.ndarray | None = None, checked: bool = False,
    ) -> bool:
        """Forward pass of Algorithm 1 (eq. dustar) from (q0, v0): u_k = u_bar_k - gamma k_k - K_k
        zeta_k with zeta_k = local(x_bar_k, x_k). Returns False if the state became non-finite or
        (variational integrator) an implicit step did not converge: the line search rejects the
        trial. The open-loop :meth:`rollout` raises StepDidNotConverge instead.

        Shapes: Q_bar, Q_out (H+1, nq); V_bar, V_out (H+1, nv); u_bar, k_ff, u_out (H, m);
        K_fb (H, m, 2 nv). With control limits lower, upper (H, m), u_k is clamped into the box
        after the feedback law. The whole pass runs in C++.
        ``checked=True``: the caller vouches for the arrays (float64, C-contiguous, these shapes:
        a problem's own nominal, gains and fresh outputs, :meth:`geoddp.problem.Problem.rollout_policy`);
        the Python checks are skipped (the core still checks every shape)."""
        H = np.shape(u_out)[0]  # the outputs are the caller's, sized to its horizon
        if not checked:
            nq, nv, m = self.nq, self.nv, self.nu
            ca, co = compiled.check_array, compiled.check_output
            Q_bar, V_bar = ca(Q_bar, "Q_bar", (H + 1, nq)), ca(V_bar, "V_bar", (H + 1, nv))
            u_bar, k_ff = ca(u_bar, "u_bar", (H, m)), ca(k_ff, "k_ff", (H, m))
            K_fb = ca(K_fb, "K_fb", (H, m, 2 * nv))
            Q_out, V_out = co(Q_out, "Q_out", (H + 1, nq)), co(V_out, "V_out", (H + 1, nv))
            u_out = co(u_out, "u_out", (H, m))
            if lower is not None:
                lower, upper = ca(lower, "lower", (H, m)), ca(upper, "upper", (H, m))
        return compiled._core.rollout_closed_loop(  # False on a step that does not converge
            self.pin_model, self.actuation, self.dt, compiled.INTEGRATORS[self.integrator], q0, v0, Q_bar, V_bar,
            u_bar, k_ff, K_fb, float(gamma), Q_out, V_out, u_out, *(() if lower is None else (lower, upper)))

    # ------------------------------------------------------------------ derivatives
    def expansion(self, Q: np.ndarray, V: np.ndarray, controls: np.ndarray, order: int = 1,
                  contracted: bool = False, checked: bool = False) -> integ.Expansion:
        """Phi, B (and Theta, Gamma, Xi for order 2) at the H nodes of a trajectory.

        Q (H+1, nq), V (H+1, nv), controls (H, m), with (Q, V) the rollout of controls (the
        semi-implicit reconstruction takes V[k+1] as the nominal v+). Shapes: Phi (H, nx, nx), B (H, nx, m),
        Theta (H, nx, nx, nx), Gamma (H, nx, nx, m), Xi (H, nx, m, m), nx = 2 nv, with
        zeta+_i = Phi zeta + B du + 1/2 zeta^T Theta_i zeta + zeta^T Gamma_i du + 1/2 du^T Xi_i du.

        ``contracted=True`` (order 2; :attr:`contracts_second_order` says whether a solve uses it)
        returns the second order factored instead: ``terms`` (geoddp._core.SecondOrderTerms,
        ``terms.contract(k, Vx)`` = sum_i Vx_i [[Theta_i, Gamma_i], [Gamma_i^T, Xi_i]] at node k)
        with Theta, Gamma, Xi None; Phi and B are bitwise those of order 1.

        ``checked=True``: the caller vouches for the inputs (finite float64 arrays of these shapes,
        order 1 or 2: a problem's own rollout, :meth:`geoddp.problem.Problem.linearise`), so the
        checks and their copies are skipped (about 50 us a call, 7 % of a UR5 linearisation; the
        core still checks the shapes).
        """
        if checked:
            U, H = controls, controls.shape[0]
        else:
            U = self.check_controls(controls)
            H = U.shape[0]
            Q = finite_array(Q, "Q", (H + 1, self.nq))
            V = finite_array(V, "V", (H + 1, self.nv))
            if order not in (1, 2):
                raise InputError("order", f"expected 1 or 2, got {order!r}")
        if contracted and order == 2:
            Phi, B, terms = compiled._core.expansion_contracted(
                self.pin_model, self.actuation, self.dt, compiled.INTEGRATORS[self.integrator], Q, V, U, self.threads)
            return integ.Expansion(Phi=Phi, B=B, terms=terms)
        Phi, B, Theta, Gamma, Xi = compiled._core.expansion(
            self.pin_model, self.actuation, self.dt, compiled.INTEGRATORS[self.integrator], Q, V, U, order, self.threads)
        return integ.Expansion(Phi=Phi, B=B, Theta=Theta, Gamma=Gamma, Xi=Xi)
