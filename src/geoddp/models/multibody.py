"""Any Pinocchio multibody model as a DDP model on its state Lie group Q x R^nv.

State x = (q, v): q in R^nq (Pinocchio's configuration coordinates), v in R^nv. Perturbations are
zeta = (dq, dv) in R^(2 nv) with q = integrate(q_bar, dq), v = v_bar + dv (:meth:`Multibody.retract`
and :meth:`Multibody.local` are the one place this is defined), so nx = 2 nv.

Dynamics (Pinocchio is the source of truth):
    v+ = v + dt aba(q, v, H u)                      (H: nv x m actuation, generalised forces)
    q+ = integrate(q, dt w),  w = v  (explicit Euler, paper eq. disceq)
                              w = v+ (semi-implicit Euler, Crocoddyl's).
or, with integrator "rk4", the fourth-order Runge-Kutta-Munthe-Kaas step of :mod:`geoddp.rkmk4`
(second-order terms by central differences of its analytic step Jacobian, symmetrised).

Expansion along a trajectory, z = (dq, dv, du), nz = 2 nv + m:
* velocity update: first order from ``computeABADerivatives`` (ddq_dq, ddq_dv, Minv); second
  order from the structure of ABA (:meth:`Multibody.velocity_derivatives`): zero in (u, u) and
  (v, u), exact in (v, v) from RNEA's dtau_dv, and central differences of the analytic first
  derivatives along q (through ``integrate``) for the rest, symmetrised to the (0)-connection
  Hessian (the pip wheel has no second-order ABA derivatives);
* reconstruction: first order from ``dIntegrate``'s ARG0 = Ad_exp(-omega), ARG1 = Jr(omega)
  (:func:`geoddp.lie.product.block_Ad_Jr`: Pinocchio's SE(3) Jr is inaccurate at small angles);
  second order exact per joint group (:mod:`geoddp.lie.product`): the reconstruction formula
  written once for any product group, :func:`geoddp.integrators.expand`.
Array layout: :class:`geoddp.integrators.Expansion` with n = 2 nv.

Backends (chosen when the model is built, ``backend=``): "compiled" runs the rollout and the
whole expansion in the C++ core (:mod:`geoddp.models.compiled`): the same quantities, with the
velocity update's second order exact from Pinocchio's ``ComputeRNEASecondOrderDerivatives`` (no
differences) and SE(3)'s dJr exact (rk4: its analytic step Jacobian and, for the second order,
central differences of it, as below; variational: the residual's Jacobian analytic, with the
kinetic-energy Hessian from the same second-order RNEA, and its second order one central
difference of that Jacobian, where the Python oracle differences a difference); "python" is the
code below, kept as the oracle. "auto" (the default) picks "compiled" (geoddp does not import
without its compiled core, :mod:`geoddp.kernels`); the environment variable
GEODDP_MULTIBODY_BACKEND=python makes "auto" pick "python".
"""
from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..urdf_checks import build_checked_model, check_model

from ..lie import product as cfg
from ..linalg import symmetric_from_upper
from .. import integrators as integ
from .. import rkmk4, variational
from ..urdf_checks import read_urdf_text
from ..validate import (InputError, choice, finite_array, nonnegative_int, positive_float, spin_from_environment,
                        threads_from_environment)
from . import compiled

ROOTS = ("free_flyer", "spherical", "fixed")
INTEGRATORS = integ.INTEGRATORS + ("rk4", "variational")
SECOND_ORDER_KINDS = ("exact",)
BACKENDS = ("auto", "compiled", "python")
# Central-difference step for the second derivatives of the velocity update: the error is
# ~h^2 |f'''| / 6 + eps |f'| / h; h = 1e-5 balances them near 1e-10 relative (tested against a
# Richardson-extrapolated difference).
FD_STEP = 1e-5


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
            (the paper's forward variational Euler, implicit; :mod:`geoddp.variational`).
        gravity: Pinocchio's default gravity (-9.81 m/s^2 along world z) if True, none if False.
        second_order: "exact" (the only kind for multibody models).
        backend: "auto" (default: "compiled", or "python" under GEODDP_MULTIBODY_BACKEND=python),
            "compiled" or "python" (the oracle). Holds the
            resolved choice after construction.
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
    _variational: variational.VariationalEuler | None = field(init=False, repr=False, default=None)
    _data: pin.Data | None = field(init=False, repr=False, default=None)
    _urdf_record: tuple[str, str] | None = field(init=False, repr=False, default=None)  # (path, text), read at the first description

    def __post_init__(self) -> None:
        self.root = choice(self.root, "root", ROOTS)
        self.dt = positive_float(self.dt, "dt")
        self.integrator = choice(self.integrator, "integrator", INTEGRATORS)
        self.second_order = choice(self.second_order, "second_order", SECOND_ORDER_KINDS)
        self.backend = choice(self.backend, "backend", BACKENDS)
        self.threads = nonnegative_int(self.threads, "threads")
        if self.threads == 0:  # the environment's choice (a sweep's workers), else the core's default
            self.threads = threads_from_environment()
        spin_from_environment()  # the core read GEODDP_SPIN_US when it loaded: refuse a bad value here
        if not isinstance(self.contract, (bool, np.bool_)):
            raise InputError("contract", f"expected True or False, got {self.contract!r}")
        if self.backend == "auto":  # the core runs every integrator
            # GEODDP_MULTIBODY_BACKEND=python forces the oracle everywhere (scene files, CLI).
            forced = choice(os.environ.get("GEODDP_MULTIBODY_BACKEND", "auto"), "GEODDP_MULTIBODY_BACKEND", BACKENDS)
            self.backend = "python" if forced == "python" else "compiled"
        if not isinstance(self.gravity, (bool, np.bool_)):
            raise InputError("gravity", f"expected True or False, got {self.gravity!r}")
        if isinstance(self.package_dirs, (str, os.PathLike)):
            self.package_dirs = (self.package_dirs,)
        if not isinstance(self.package_dirs, (list, tuple)) or not all(isinstance(d, (str, os.PathLike)) for d in self.package_dirs):
            raise InputError("package_dirs", f"expected a path or a list of paths, got {self.package_dirs!r}")
        self.package_dirs = tuple(str(d) for d in self.package_dirs)
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
        if self.integrator == "variational":
            self._variational = variational.VariationalEuler(model, self.groups, self.actuation, self.dt)
        self._data = model.createData()

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
        return self.backend == "compiled" and bool(self.contract) and self.integrator in compiled.CONTRACTED_INTEGRATORS

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
    def _step(self, data: pin.Data, q: np.ndarray, v: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        model = self.pin_model
        if self.integrator == "rk4":
            return rkmk4.step(model, data, self.groups, q, v, self.actuation @ u, self.dt)
        if self._variational is not None:
            return self._variational.step(data, None, q, v, self.actuation @ u)
        v_next = v + self.dt * pin.aba(model, data, q, v, self.actuation @ u)
        w = v_next if self.semi_implicit else v
        # No pin.normalize: integrate already renormalises to first order, and normalize moves
        # SO(2) coordinates by ~1e-9 (it erased 1e-9 perturbations in finite-difference checks).
        return pin.integrate(model, q, self.dt * w), v_next

    def step(self, q: np.ndarray, v: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One step: q (nq,), v (nv,) (m/s, rad/s per joint), u (m,) -> (q+, v+)."""
        return self._step(self.pin_model.createData(), q, v, u)

    def check_state(self, q: np.ndarray, v: np.ndarray, name: str = "initial") -> tuple[np.ndarray, np.ndarray]:
        """Validate a state: q (nq,) with unit quaternions / (cos, sin) pairs, v (nv,)."""
        q = finite_array(q, f"{name}.q", (self.nq,))
        v = finite_array(v, f"{name}.v", (self.nv,))
        if not pin.isNormalized(self.pin_model, q, 1e-9):
            raise InputError(f"{name}.q", "expected unit quaternions and unit (cos, sin) pairs (use pin.normalize), got a non-normalised configuration")
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
        H = U.shape[0]
        if self.backend == "compiled":
            with self._step_errors():
                return compiled._core.rollout(self.pin_model, self.actuation, self.dt, compiled.INTEGRATORS[self.integrator], q0, v0, U)
        data = self.pin_model.createData()
        Q = np.empty((H + 1, self.nq))
        V = np.empty((H + 1, self.nv))
        Q[0], V[0] = q0, v0
        for k in range(H):
            Q[k + 1], V[k + 1] = self._step(data, Q[k], V[k], U[k])
        return Q, V

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
        after the feedback law. With the compiled backend the whole pass runs in C++.
        ``checked=True``: the caller vouches for the arrays (float64, C-contiguous, these shapes:
        a problem's own nominal, gains and fresh outputs, :meth:`geoddp.problem.Problem.rollout_policy`);
        the Python checks are skipped (the core still checks every shape)."""
        H = np.shape(u_out)[0]  # the outputs are the caller's, sized to its horizon
        if self.backend == "compiled":
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
        data = self._data
        Q_out[0], V_out[0] = q0, v0
        for k in range(H):
            zeta = self.local(Q_bar[k], V_bar[k], Q_out[k], V_out[k])
            u = u_bar[k] - gamma * k_ff[k] - K_fb[k] @ zeta
            if lower is not None:  # np.minimum/maximum propagate NaN, as the compiled clamp does
                u = np.minimum(np.maximum(u, lower[k]), upper[k])
            u_out[k] = u
            try:
                q1, v1 = self._step(data, Q_out[k], V_out[k], u)
            except variational.StepDidNotConverge:
                return False  # a trial whose implicit step has no solution: rejected like a non-finite one
            if not (np.all(np.isfinite(q1)) and np.all(np.isfinite(v1))):
                return False
            Q_out[k + 1], V_out[k + 1] = q1, v1
        return True

    # ------------------------------------------------------------------ derivatives
    def _invariant_q_dirs(self) -> np.ndarray:
        """Tangent directions of q along which the velocity update does not change at all.

        A world-frame rigid motion of the whole mechanism leaves every local quantity (joint
        configurations, body-frame velocities, torques) unchanged, so ABA's output is invariant
        under it unless an external field breaks the symmetry. Perturbing the root joint,
        integrate(q, dq) = q_root exp(dq_root), is such a motion: a free flyer's translational
        directions always (gravity is uniform), its rotational directions, and a spherical root's,
        only without gravity. Along them, ABA and its derivatives are constant: their second
        derivatives are exactly zero (tested against differences along every direction).
        """
        if self.root == "fixed":
            return np.zeros(0, dtype=int)
        rot = slice(3, 6) if self.root == "free_flyer" else slice(0, 3)
        dirs = [0, 1, 2] if self.root == "free_flyer" else []
        if not np.any(self.pin_model.gravity.vector):
            dirs += list(range(rot.start, rot.stop))
        return np.array(dirs, dtype=int)

    def velocity_derivatives(
        self, Q: np.ndarray, V: np.ndarray, controls: np.ndarray, order: int = 1, fd_step: float = FD_STEP
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Derivatives of v+ = f(q, v, u) w.r.t. z = (dq, dv, du) at N nodes.

        Q (N, nq), V (N, nv), controls (N, m) -> F1 (N, nv, nz), F2 (N, nv, nz, nz) or None,
        nz = 2 nv + m. F2 is the symmetric (0)-Hessian of z -> f(retract(x, zeta), u + du).

        F1 is Pinocchio's analytic ABA derivative. F2 uses the structure of
        f = v + dt a,  a = Minv(q) (tau - b(q, v)),  tau = H u,  b = C(q, v) v + g(q)
        (b: RNEA at zero acceleration) instead of differencing along all nz directions:
        * u-u and v-u blocks: zero. a is affine in tau with slope Minv(q), which does not
          depend on v.
        * v-v block: b is quadratic in v and Minv does not depend on v, so
          d2a/dv_i dv_j = -Minv (d2 b / dv_i dv_j) = -Minv dtau_dv(q, e_j, 0)[:, i], exactly:
          RNEA's dtau_dv is linear in v and independent of the acceleration and of gravity.
          One computeRNEADerivatives per velocity direction.
        * q-q, q-v and q-u blocks: central differences of the analytic first derivatives
          (ddq_dq, ddq_dv, Minv H) along integrate(q, h e_j), 2 computeABADerivatives per
          direction. v and u enter additively, so the q-v and q-u entries are mixed partials
          of a smooth function and differencing along q alone gives them; the q-q block is
          symmetrised to the (0)-connection Hessian (the derivative of the right-trivialised
          Jacobian along integrate(q, h e_j) differs from it by an antisymmetric bracket term).
          Directions of :meth:`_invariant_q_dirs` are skipped (exactly zero there).
        These agree with central differences along every direction of z to ~1e-9 relative (the
        differences' own error; tested).
        """
        model = self.pin_model
        data = model.createData()
        Hm, nv, m, dt = self.actuation, self.nv, self.nu, self.dt
        N = controls.shape[0]
        nz = 2 * nv + m
        Tau = controls @ Hm.T
        # Pinocchio fills only the upper triangle of Minv: raw ABA outputs [ddq_dq | ddq_dv | Minv]
        # are collected per node, and the arithmetic runs on whole stacks afterwards.
        raw = np.empty((N, nv, 3 * nv))
        for k in range(N):
            pin.computeABADerivatives(model, data, Q[k], V[k], Tau[k])
            raw[k, :, :nv] = data.ddq_dq
            raw[k, :, nv : 2 * nv] = data.ddq_dv
            raw[k, :, 2 * nv :] = data.Minv
        Minv = symmetric_from_upper(raw[:, :, 2 * nv :])
        F1 = np.empty((N, nv, nz))
        F1[:, :, :nv] = dt * raw[:, :, :nv]
        F1[:, :, nv : 2 * nv] = np.eye(nv) + dt * raw[:, :, nv : 2 * nv]
        F1[:, :, 2 * nv :] = dt * (Minv @ Hm)
        if order < 2:
            return F1, None

        h = fd_step
        dirs = np.setdiff1d(np.arange(nv), self._invariant_q_dirs())
        nd = dirs.size
        plus = np.empty((N, nd, nv, 3 * nv))
        minus = np.empty((N, nd, nv, 3 * nv))
        dtau_dv = np.empty((N, nv, nv, nv))  # [k, j] = RNEA's dtau_dv at (q_k, e_j, 0)
        steps = h * np.eye(nv)[dirs]
        unit, zero = np.eye(nv), np.zeros(nv)
        for k in range(N):
            q, v, tau = Q[k], V[k], Tau[k]
            for jd in range(nd):
                for out, s in ((plus, steps[jd]), (minus, -steps[jd])):
                    pin.computeABADerivatives(model, data, pin.integrate(model, q, s), v, tau)
                    out[k, jd, :, :nv] = data.ddq_dq
                    out[k, jd, :, nv : 2 * nv] = data.ddq_dv
                    out[k, jd, :, 2 * nv :] = data.Minv
            for j in range(nv):
                pin.computeRNEADerivatives(model, data, q, unit[j], zero)
                dtau_dv[k, j] = data.dtau_dv
        D = (plus - minus) / (2.0 * h)  # [k, jd, p, c]: d raw[k, p, c] / d q_dirs[jd]
        # Gq[k, p, c, j]: derivative of column c of the velocity Jacobian along q_j (zero off dirs)
        Gq = np.zeros((N, nv, nz, nv))
        Gq[:, :, : 2 * nv, dirs] = dt * np.moveaxis(D[..., : 2 * nv], 1, -1)
        Gq[:, :, 2 * nv :, dirs] = dt * np.moveaxis(symmetric_from_upper(D[..., 2 * nv :]) @ Hm, 1, -1)
        F2 = np.zeros((N, nv, nz, nz))
        F2[:, :, :nv, :nv] = 0.5 * (Gq[:, :, :nv] + np.swapaxes(Gq[:, :, :nv], 2, 3))
        F2[:, :, nv:, :nv] = Gq[:, :, nv:]
        F2[:, :, :nv, nv:] = np.swapaxes(Gq[:, :, nv:], 2, 3)
        Fvv = -dt * np.moveaxis(Minv[:, None] @ dtau_dv, 1, -1)  # [k, p, i, j]
        F2[:, :, nv : 2 * nv, nv : 2 * nv] = 0.5 * (Fvv + np.swapaxes(Fvv, 2, 3))
        return F1, F2

    def _expansion_rk4(self, Q: np.ndarray, V: np.ndarray, U: np.ndarray, order: int) -> integ.Expansion:
        """RK4 on the Lie group: Phi, B from the analytic step Jacobian (stages chained); for
        order 2, central differences of that analytic Jacobian along tangent directions of
        z = (dq, dv, du), symmetrised. Expressing the output at the perturbed step's image instead
        of the nominal one changes the Jacobian by 1/2 ad(G a) G b, which is antisymmetric in
        (a, b) and so drops out of the symmetrised (0)-Hessian."""
        model, dt, nv, m = self.pin_model, self.dt, self.nv, self.nu
        n, nz, H = 2 * nv, 2 * nv + m, U.shape[0]
        data = model.createData()
        jac = lambda q, v, u: rkmk4.step_jacobian(model, data, self.groups, q, v, self.actuation @ u, self.actuation, dt)  # noqa: E731
        G = np.stack([jac(Q[k], V[k], U[k]) for k in range(H)])
        if order < 2:
            return integ.Expansion.from_blocks(n, G)
        h = FD_STEP
        G2 = np.empty((H, n, nz, nz))
        for k in range(H):
            D = np.empty((n, nz, nz))
            for j in range(nz):
                z = np.zeros(nz)
                z[j] = h
                (qp, vp), (qm, vm) = self.retract(Q[k], V[k], z[:n]), self.retract(Q[k], V[k], -z[:n])
                D[:, :, j] = (jac(qp, vp, U[k] + z[n:]) - jac(qm, vm, U[k] - z[n:])) / (2.0 * h)
            G2[k] = 0.5 * (D + np.swapaxes(D, 1, 2))
        return integ.Expansion.from_blocks(n, G, G2)

    def expansion(self, Q: np.ndarray, V: np.ndarray, controls: np.ndarray, order: int = 1,
                  contracted: bool = False, checked: bool = False) -> integ.Expansion:
        """Phi, B (and Theta, Gamma, Xi for order 2) at the H nodes of a trajectory.

        Q (H+1, nq), V (H+1, nv), controls (H, m), with (Q, V) the rollout of controls (the
        semi-implicit reconstruction takes V[k+1] as the nominal v+). Shapes: Phi (H, nx, nx), B (H, nx, m),
        Theta (H, nx, nx, nx), Gamma (H, nx, nx, m), Xi (H, nx, m, m), nx = 2 nv, with
        zeta+_i = Phi zeta + B du + 1/2 zeta^T Theta_i zeta + zeta^T Gamma_i du + 1/2 du^T Xi_i du.

        ``contracted=True`` (order 2, compiled backend only: :attr:`contracts_second_order`)
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
            if self.backend != "compiled":
                raise InputError("contracted", "expected False: factored second-order terms need the compiled backend")
            Phi, B, terms = compiled._core.expansion_contracted(
                self.pin_model, self.actuation, self.dt, compiled.INTEGRATORS[self.integrator], Q, V, U, self.threads)
            return integ.Expansion(Phi=Phi, B=B, terms=terms)
        if self.backend == "compiled":
            Phi, B, Theta, Gamma, Xi = compiled._core.expansion(
                self.pin_model, self.actuation, self.dt, compiled.INTEGRATORS[self.integrator], Q, V, U, order, self.threads)
            return integ.Expansion(Phi=Phi, B=B, Theta=Theta, Gamma=Gamma, Xi=Xi)
        nv, m, dt = self.nv, self.nu, self.dt
        n, nz = 2 * nv, 2 * nv + m
        if self.integrator == "rk4":
            return self._expansion_rk4(Q, V, U, order)
        if self._variational is not None:
            # Implicit velocity update, explicit-Euler reconstruction q+ = q exp(dt v).
            F1, F2 = self._variational.velocity_derivatives(Q[:H], V[:H], V[1:], U, order)
        else:
            F1, F2 = self.velocity_derivatives(Q[:H], V[:H], U, order)
        W = V[1 : H + 1] if self.semi_implicit else V[:H]  # reconstruction velocity w_bar
        # the exact second-order reconstruction on the product of the joints' groups
        return integ.expand(self.groups, dt, W, F1, F2, self.semi_implicit)
