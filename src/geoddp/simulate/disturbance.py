"""Disturbances of a simulated run: process noise, sensor noise and external forces, seeded.

Every random number of one run is drawn up front, in a fixed order, from one
``numpy.random.Generator`` (:meth:`Disturbances.draw`): a run is a pure function of its seed, and
two policies flown with the same draw meet the same noise (common random numbers, so their
difference is not blurred by different noise). The standard normals are drawn whether or not a
sigma is zero, so turning one noise source on does not change the others' realisation.

Per plan step k = 0 .. N-1 (N simulated steps, dt the plan's step):

* ``velocity_noise`` sigma (rad/s or m/s; a scalar or (nv,)): v_{k+1} += sigma * n_k after the
  plant's step (the authors' ``test_noise.m``: N(0, 0.001^2) on the body angular velocity);
* ``force_noise`` sigma (generalised force: N m, N; scalar or (nv,)): a force sigma * n_k held
  over the step;
* ``sensor_noise`` sigma (scalar or (nx,)): the policy sees retract(x_k, sigma * n_k), the state
  perturbed in its tangent space (rad and rad/s on the satellite; the model's (dq, dv) otherwise);
* ``wrench`` (nv,): a constant external generalised force (satellite: body torque, N m; a
  free-flyer root: body wrench [force; torque] in the root frame) from ``wrench_start`` (s) for
  ``wrench_duration`` (s; None: to the end);
* ``impulses``: ((t_s, (nv,) generalised impulse, N s or N m s), ...): each applied as the force
  impulse / dt over the plan step that contains t.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..validate import InputError, finite_array, keywords_checked, nonnegative_float


@dataclass(frozen=True)
class DisturbanceSample:
    """One realisation over N steps: ``velocity`` (N, nv) added to v after each step, ``force``
    (N, nv) generalised force held over each step (noise + wrench + impulses), ``sensor`` (N, nx)
    tangent perturbation of the measured state, or None when that source is off."""

    velocity: np.ndarray | None
    force: np.ndarray | None
    sensor: np.ndarray | None


def _sigma(x: Any, name: str, n: int) -> np.ndarray:
    a = finite_array(x, name)
    if a.ndim == 0:
        nonnegative_float(float(a), name)
        return np.full(n, float(a))
    if a.shape != (n,) or np.any(a < 0):
        raise InputError(name, f"expected a number >= 0 or {n} numbers >= 0, got {a.tolist()}")
    return a


@keywords_checked
@dataclass(frozen=True)
class Disturbances:
    """What disturbs a run (see the module docstring for units and timing). All off by default."""

    velocity_noise: Any = 0.0
    force_noise: Any = 0.0
    sensor_noise: Any = 0.0
    wrench: Any = None
    wrench_start: float = 0.0
    wrench_duration: float | None = None
    impulses: tuple = ()

    @property
    def random(self) -> bool:
        """True if any noise source is on."""
        return any(np.any(np.asarray(s, dtype=float) != 0) for s in (self.velocity_noise, self.force_noise,
                                                                        self.sensor_noise))

    def check(self, nv: int, nx: int) -> None:
        """Validate against a model with nv velocities and tangent dimension nx (InputError naming
        ``disturbances.<field>``)."""
        self.draw(np.random.default_rng(0), 1, nv, nx, 1.0)

    def draw(self, rng: np.random.Generator, steps: int, nv: int, nx: int, dt: float) -> DisturbanceSample:
        """The realisation over ``steps`` plan steps of length dt (s) from ``rng``."""
        sv = _sigma(self.velocity_noise, "disturbances.velocity_noise", nv)
        sf = _sigma(self.force_noise, "disturbances.force_noise", nv)
        ss = _sigma(self.sensor_noise, "disturbances.sensor_noise", nx)
        # fixed order, always drawn (see the module docstring)
        nvel = rng.standard_normal((steps, nv))
        nfor = rng.standard_normal((steps, nv))
        nsen = rng.standard_normal((steps, nx))
        force = nfor * sf if np.any(sf) else None
        t = np.arange(steps) * dt
        if self.wrench is not None:
            w = finite_array(self.wrench, "disturbances.wrench", (nv,))
            t0 = nonnegative_float(self.wrench_start, "disturbances.wrench_start")
            dur = np.inf if self.wrench_duration is None else nonnegative_float(self.wrench_duration,
                                                                                 "disturbances.wrench_duration")
            on = (t >= t0 - 1e-12 * dt) & (t < t0 + dur - 1e-12 * dt)
            force = (np.zeros((steps, nv)) if force is None else force) + on[:, None] * w
        if not isinstance(self.impulses, (tuple, list)):
            raise InputError("disturbances.impulses", f"expected a list of (time_s, impulse) pairs, got {self.impulses!r}")
        for i, item in enumerate(self.impulses):
            name = f"disturbances.impulses[{i}]"
            if not isinstance(item, (tuple, list)) or len(item) != 2:
                raise InputError(name, f"expected a pair (time_s, impulse of {nv} numbers), got {item!r}")
            ti = nonnegative_float(item[0], f"{name}.time")
            J = finite_array(item[1], f"{name}.impulse", (nv,))
            k = int(np.floor(ti / dt + 1e-9))
            if k >= steps:
                raise InputError(f"{name}.time", f"expected a time before the end of the run ({steps * dt:g} s), got {ti:g}")
            force = np.zeros((steps, nv)) if force is None else force
            force[k] += J / dt
        return DisturbanceSample(velocity=nvel * sv if np.any(sv) else None, force=force,
                                 sensor=nsen * ss if np.any(ss) else None)
