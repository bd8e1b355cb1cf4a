"""The plant: the system a plan is flown on, which may differ from the model it was planned with.

A :class:`Plant` is built once from the plan's model (:class:`geoddp.models.satellite.Satellite`
or :class:`geoddp.models.multibody.Multibody`) with changed parameters:

* ``inertia_scale``: rotational inertias about the centre of mass times s (a scalar; on the
  satellite also a (3,) vector s, I' = D I D with D = diag(sqrt(s)), which scales a diagonal I's
  principal moments by s_i);
* ``mass_scale``: every link's mass and rotational inertia times s (uniform density; on the
  satellite the inertia times s: its attitude dynamics see no mass);
* ``actuator_gain``: the actuation matrix's columns times g (a scalar or (m,)): input i delivers
  g_i times the force the plan assumed;
* ``integrator`` and ``substeps``: the plant steps with dt / substeps under a zero-order hold
  of the plan step's input (a finer, or different, discretisation than the plan's).

External generalised forces (disturbance torques, wrenches, force noise) enter through nv
extra actuation columns (the identity): the plant's input is (u, w) with w (nv,) in the model's
generalised-force coordinates (the satellite: body torque, N m; a free-flyer root: the body
wrench [force (N); torque (N m)] in the root frame, then joint torques). With w = 0 the extra
columns add exact zeros, so an unchanged plant steps bit for bit as the plan's model.

The state stays in the plan's representation (R, Omega) or (q, v) at the interface. The only
case where the plant's own differs is a satellite flown with "rk4" or "variational": the plant is
then the general one-body model (root quaternion q (4,), (x, y, z, w)) and :meth:`Plant.step`
converts.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from ..models.multibody import INTEGRATORS as MULTIBODY_INTEGRATORS
from ..models.multibody import Multibody
from ..models.satellite import Satellite, satellite_model
from ..validate import InputError, choice, finite_array, keywords_checked, positive_float, positive_int

from ..scene.simulation import PLANT_KEYS  # noqa: E402,F401  (their one home; re-exported)


def _scale(x: Any, name: str, n: int | None) -> float | np.ndarray:
    """A positive scalar, or (n,) positive numbers when n is given."""
    a = finite_array(x, name)
    if a.ndim == 0 or (n is not None and a.shape == (n,)):
        if np.any(a <= 0):
            raise InputError(name, f"expected positive factors, got {a.tolist()}")
        return float(a) if a.ndim == 0 else a
    shapes = "a positive number" + (f" or {n} positive numbers" if n is not None else "")
    raise InputError(name, f"expected {shapes}, got shape {a.shape}")


@keywords_checked
@dataclass
class Plant:
    """The plan's model with changed parameters, stepped with its own integrator and substeps.

    Attributes:
        model: the plan's model (not modified).
        inertia_scale, mass_scale: factors (see the module docstring); 1 = unchanged.
        actuator_gain: scalar or (m,) factors on the inputs; 1 = unchanged.
        integrator: the plant's integrator (default: the plan's).
        substeps: plant steps per plan step (>= 1); the plant's dt is model.dt / substeps.
        stepper: the model the plant steps (built once; its actuation is (nv, m + nv)).
    """

    model: Any
    inertia_scale: Any = 1.0
    mass_scale: Any = 1.0
    actuator_gain: Any = 1.0
    integrator: str | None = None
    substeps: int = 1
    stepper: Any = field(init=False, repr=False)
    nv: int = field(init=False)
    _quaternion: bool = field(init=False, repr=False, default=False)

    def __post_init__(self) -> None:
        m = self.model
        if not isinstance(m, (Satellite, Multibody)):
            raise InputError("model", f"expected a Satellite or Multibody model, got {type(m).__name__}")
        satellite = isinstance(m, Satellite)
        self.inertia_scale = _scale(self.inertia_scale, "plant.inertia_scale", 3 if satellite else None)
        self.mass_scale = _scale(self.mass_scale, "plant.mass_scale", None)
        self.actuator_gain = _scale(self.actuator_gain, "plant.actuator_gain", m.nu)
        self.integrator = choice(m.integrator if self.integrator is None else self.integrator, "plant.integrator",
                                 MULTIBODY_INTEGRATORS)
        self.substeps = positive_int(self.substeps, "plant.substeps")
        dt = positive_float(m.dt / self.substeps, "plant.substeps")
        gain = np.broadcast_to(np.asarray(self.actuator_gain, dtype=float), (m.nu,))
        if satellite:
            self.nv = 3
            D = np.diag(np.sqrt(np.broadcast_to(np.asarray(self.inertia_scale, dtype=float), (3,))))
            inertia = self.mass_scale * (D @ m.inertia @ D)
            A = np.hstack([m.actuation * gain, np.eye(3)])
            self.stepper = satellite_model(inertia=inertia, actuation=A, dt=dt, integrator=self.integrator,
                                           urdf=m.urdf)
            self._quaternion = not isinstance(self.stepper, Satellite)
        else:
            self.nv = m.nv
            A = np.hstack([m.actuation * gain, np.eye(m.nv)])
            st = Multibody(m.urdf, root=m.root, actuation=A, dt=dt, integrator=self.integrator,
                           gravity=bool(np.any(m.pin_model.gravity.vector != 0)))
            pm = st.pin_model
            for j in range(1, pm.njoints):
                I = m.pin_model.inertias[j]  # noqa: E741  (the plan model's link inertia)
                s = self.mass_scale
                pm.inertias[j] = pin.Inertia(s * I.mass, I.lever.copy(), s * self.inertia_scale * I.inertia)
            self.stepper = st

    @property
    def dt(self) -> float:
        """The plant's own time step, s (the plan's dt / substeps)."""
        return float(self.stepper.dt)

    @property
    def changed(self) -> dict[str, Any]:
        """The parameters that differ from the plan's model (JSON-ready)."""
        out: dict[str, Any] = {}
        for k in ("inertia_scale", "mass_scale", "actuator_gain"):
            val = getattr(self, k)
            if np.any(np.asarray(val) != 1.0):
                out[k] = np.asarray(val).tolist()
        if self.integrator != self.model.integrator:
            out["integrator"] = self.integrator
        if self.substeps != 1:
            out["substeps"] = self.substeps
        return out

    def step(self, q: np.ndarray, v: np.ndarray, u: np.ndarray, w: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
        """One plan step dt: ``substeps`` plant steps holding u (m,) and the external
        generalised force w (nv,) (None: zero). q, v in the plan's representation; returns the next
        (q, v) in it."""
        ext = np.zeros(self.nv) if w is None else w
        U = np.tile(np.concatenate([u, ext]), (self.substeps, 1))
        if self._quaternion:  # the satellite's R <-> the general one-body model's root quaternion
            Q, V = self.stepper.rollout(pin.Quaternion(q).coeffs(), v, U)
            return pin.Quaternion(Q[-1]).normalized().toRotationMatrix(), V[-1]
        Q, V = self.stepper.rollout(q, v, U)
        return Q[-1], V[-1]


def plant_from(model: Any, changes: dict[str, Any] | None = None) -> Plant:
    """A :class:`Plant` of ``model`` with ``changes`` (keys of :data:`PLANT_KEYS`); InputError
    naming ``plant.<key>`` on an unknown key or a bad value."""
    from ..validate import closest

    changes = dict(changes or {})
    for k in changes:
        if k not in PLANT_KEYS:
            hint = closest(k, PLANT_KEYS)
            raise InputError(f"plant.{k}", "unknown plant parameter" + (f" (did you mean {hint!r}?)" if hint else "")
                             + f"; known: {', '.join(PLANT_KEYS)}")
    return Plant(model, **changes)
