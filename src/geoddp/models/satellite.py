"""The rigid satellite on TSO(3) (paper Section VI), with Pinocchio as the source of truth.

Model (constant): a Pinocchio model with one spherical joint (gravity off) whose body carries the
inertia I, an actuation matrix H (3 x m) mapping inputs to body torques, the time step and the
integrator. Dynamics: Omega+ = Omega + dt I^-1((I Omega) x Omega + H u) (= Omega + dt aba), with
R+ = R exp(dt Omega) (explicit Euler, paper eq. disceqs) or R+ = R exp(dt Omega+) (semi-implicit).

This is the TSO(3) backend of a one-body model (spherical root, no gravity): the rollout, the
closed-loop pass and the exact first- and second-order expansion run as closed forms in C++
(``cpp/tso3/tso3.cpp``, through :mod:`geoddp.kernels`). Any other structure runs the general path
(:class:`geoddp.models.multibody.Multibody`). The numpy and Pinocchio finite-difference versions
of the same quantities are the tests' oracles (tests/oracle_satellite.py).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from .. import data, kernels
from .urdf import build_urdf_model
from ..validate import actuation_matrix, choice, finite_array, inertia_matrix, positive_float, rotation_matrix
from . import integrators as integ

DEFAULT_URDF = data.urdf_path("satellite.urdf")


def _one_body(model: pin.Model, inertia: np.ndarray) -> pin.Model:
    """``model`` (one rigid body on a spherical root) with the scene's inertia about the centre of
    mass, which sits at the joint origin (the URDF's mass is kept)."""
    if model.nv != 3:
        raise ValueError(f"urdf: expected a single rigid body (nv = 3 with a spherical root), got nv = {model.nv}")
    model.inertias[1] = pin.Inertia(model.inertias[1].mass, np.zeros(3), inertia)
    return model


@dataclass
class Satellite:
    """A rigid satellite: constants only (Crocoddyl's model/data split: no per-call state).

    Attributes:
        inertia: (3, 3) SPD inertia about the centre of mass, kg m^2.
        actuation: (3, m) input-to-body-torque matrix H.
        dt: time step, s.
        integrator: "euler" (paper) or "semi_implicit" (Crocoddyl).
        second_order: "exact" (default) or "paper" expansion of the reconstruction.
        urdf: URDF of one rigid body (its inertia is replaced by ``inertia``). By default the
            built-in ``satellite.urdf`` (package data, :mod:`geoddp.data`).
    """

    inertia: np.ndarray
    actuation: np.ndarray
    dt: float
    integrator: str = "euler"
    second_order: str = "exact"
    urdf: Path | None = None
    pin_model: pin.Model = field(init=False, repr=False)
    inertia_inv: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.inertia = inertia_matrix(self.inertia, "inertia")
        self.actuation = actuation_matrix(self.actuation, "actuation")
        self.dt = positive_float(self.dt, "dt")
        self.integrator = choice(self.integrator, "integrator", integ.INTEGRATORS)
        self.second_order = choice(self.second_order, "second_order", integ.SECOND_ORDER_KINDS)
        if self.second_order == "paper" and self.integrator != "euler":
            raise ValueError("second_order: 'paper' is derived for integrator 'euler' only")
        self.urdf = DEFAULT_URDF if self.urdf is None else Path(self.urdf)
        if not self.urdf.is_file():
            raise FileNotFoundError(f"urdf: no such file {self.urdf}")
        # read and checked as every URDF is (encoding, XML, urdfdom's messages), by name
        self.pin_model = _one_body(build_urdf_model(self.urdf, pin.JointModelSpherical()), self.inertia)
        self.pin_model.gravity = pin.Motion.Zero()
        self.inertia_inv = np.linalg.inv(self.inertia)

    @property
    def nu(self) -> int:
        """Number of inputs m."""
        return int(self.actuation.shape[1])

    @property
    def semi_implicit(self) -> bool:
        return self.integrator == "semi_implicit"

    @property
    def nx(self) -> int:
        """Dimension of the tangent state zeta = (eta, dOmega)."""
        return 6

    def check_state(self, R: np.ndarray, Omega: np.ndarray, name: str | tuple[str, str] = "initial"
                    ) -> tuple[np.ndarray, np.ndarray]:
        """Validated float64 copies of a state: R (3, 3) a rotation (orthonormal to 1e-9, det +1),
        Omega (3,) finite, rad/s; errors name ``name.rotation`` / ``name.angular_velocity``, or
        the two names of a pair (``("q0", "v0")``)."""
        nR, nO = name if isinstance(name, tuple) else (f"{name}.rotation", f"{name}.angular_velocity")
        return rotation_matrix(R, nR), finite_array(Omega, nO, (3,))

    def description(self) -> dict:
        """What a Result needs to rebuild the model: kind "satellite", dt, integrator, inertia
        (3, 3), actuation (3, m), and as a multibody describes itself: urdf (str), root
        ("spherical"), nq (4), nv (3)."""
        return {"kind": "satellite", "dt": self.dt, "integrator": self.integrator, "inertia": self.inertia.copy(),
                "actuation": self.actuation.copy(), "urdf": str(self.urdf),
                "root": "spherical", "nq": 4, "nv": 3}

    # ------------------------------------------------------------------ state chart
    def retract(self, R: np.ndarray, Omega: np.ndarray, zeta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x exp(zeta) = (R exp(eta), Omega + dOmega); R (3, 3), Omega (3,), zeta = (eta, dOmega) (6,)."""
        E = np.empty((3, 3))
        kernels.so3_exp(float(zeta[0]), float(zeta[1]), float(zeta[2]), E)
        return R @ E, Omega + zeta[3:]

    def local(self, R_bar: np.ndarray, Omega_bar: np.ndarray, R: np.ndarray, Omega: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`retract`, the perturbation of the paper's feedback law (eq. dustar):
        zeta = (log(R_bar^T R), Omega - Omega_bar) (6,), the same chart as the closed-loop kernel."""
        out = np.empty(6)
        kernels.so3_log(np.ascontiguousarray(R_bar.T @ R), out[:3])
        out[3:] = Omega - Omega_bar
        return out

    # ------------------------------------------------------------------ dynamics
    def rollout(self, R0: np.ndarray, Omega0: np.ndarray, controls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Open-loop rollout: R0 (3,3), Omega0 (3,), controls (H, m) -> R (H+1, 3, 3), Omega (H+1, 3)."""
        U = np.ascontiguousarray(controls, dtype=float)
        H = U.shape[0]
        R = np.empty((H + 1, 3, 3))
        Om = np.empty((H + 1, 3))
        dummy = np.empty((H, self.nu))
        finite = kernels.satellite_rollout(
            np.ascontiguousarray(R0, dtype=float), np.ascontiguousarray(Omega0, dtype=float),
            R, Om, U, dummy, np.empty((H, self.nu, 6)), 0.0, False,
            self.inertia, self.inertia_inv, self.actuation, self.dt, self.semi_implicit, R, Om, dummy,
        )
        if not finite:
            # The kernel stops at the first non-finite state and leaves the later steps unwritten
            # (uninitialised memory, which a cost could read as finite: a spin of 3e12 rad/s gave
            # J = 15000 and a result with NaN states). NaN throughout: the cost is NaN, and the
            # solver refuses such an initial guess as bad input.
            R.fill(np.nan)
            Om.fill(np.nan)
        return R, Om

    def rollout_closed_loop(
        self, R0: np.ndarray, Omega0: np.ndarray, R_bar: np.ndarray, Omega_bar: np.ndarray, u_bar: np.ndarray,
        k_ff: np.ndarray, K_fb: np.ndarray, gamma: float, R_out: np.ndarray, Omega_out: np.ndarray, u_out: np.ndarray,
        lower: np.ndarray | None = None, upper: np.ndarray | None = None,
    ) -> bool:
        """Forward pass of Algorithm 1 from (R0, Omega0): u_k = u_bar_k - gamma k_k - K_k zeta_k
        (eq. dustar), zeta_k = (log(R_bar_k^T R_k), Omega_k - Omega_bar_k).

        Nominal R_bar (H+1,3,3), Omega_bar (H+1,3), u_bar (H,m); gains k_ff (H,m), K_fb (H,m,6);
        results into R_out, Omega_out, u_out. Returns False if the state became non-finite.
        With control limits lower, upper (H, m), u_k is clamped into the box after the feedback law.
        """
        if lower is not None:
            return kernels.satellite_rollout_box(
                R0, Omega0, R_bar, Omega_bar, u_bar, k_ff, K_fb, gamma, lower, upper,
                self.inertia, self.inertia_inv, self.actuation, self.dt, self.semi_implicit, R_out, Omega_out, u_out,
            )
        return kernels.satellite_rollout(
            R0, Omega0, R_bar, Omega_bar, u_bar, k_ff, K_fb, gamma, True,
            self.inertia, self.inertia_inv, self.actuation, self.dt, self.semi_implicit, R_out, Omega_out, u_out,
        )

    # ------------------------------------------------------------------ derivatives
    def expansion(self, R: np.ndarray, Omega: np.ndarray, controls: np.ndarray, order: int = 1) -> integ.Expansion:
        """Phi, B (and Theta, Gamma, Xi for order 2) at the H nodes of a trajectory, compiled.

        R (H+1, 3, 3) (unused: on TSO(3) the expansion depends on the rates only), Omega
        (H+1, 3), controls (H, m). See :mod:`geoddp.models.integrators`. With ``second_order="paper"``
        the eta rows of the second-order terms are the paper's (eq. etamatrixterms).
        """
        H, m = controls.shape[0], self.nu
        e = integ.Expansion(Phi=np.empty((H, 6, 6)), B=np.empty((H, 6, m)))
        if order >= 2:
            e.Theta, e.Gamma, e.Xi = np.empty((H, 6, 6, 6)), np.empty((H, 6, 6, m)), np.empty((H, 6, m, m))
            th, ga, xi = e.Theta, e.Gamma, e.Xi
        else:
            th, ga, xi = np.empty((0, 6, 6, 6)), np.empty((0, 6, 6, m)), np.empty((0, 6, m, m))
        kernels.satellite_linearise(np.ascontiguousarray(Omega, dtype=float), self.dt, self.inertia, self.inertia_inv,
                                    self.actuation, self.semi_implicit, order >= 2, e.Phi, e.B, th, ga, xi)
        if order >= 2 and self.second_order == "paper":
            integ.paper_eta_rows(e, self.dt, Omega[:H])
        return e


def satellite_model(*, inertia, actuation, dt: float, integrator: str = "euler", second_order: str = "exact",
                    urdf: Path | None = None):
    """The one-body satellite (``urdf`` or the built-in ``satellite.urdf``, spherical root, no
    gravity, this inertia) with its backend chosen by structure: the TSO(3) closed forms
    (:class:`Satellite`) for the Euler schemes, else the general path
    (:class:`geoddp.models.multibody.Multibody`: rk4, variational), which keeps the URDF's mass."""
    from .multibody import Multibody

    if integrator in integ.INTEGRATORS:
        return Satellite(inertia=inertia, actuation=actuation, dt=dt, integrator=integrator,
                         second_order=second_order, urdf=urdf)
    inertia = inertia_matrix(inertia, "inertia")
    second_order = choice(second_order, "second_order", ("exact",))
    mb = Multibody(DEFAULT_URDF if urdf is None else urdf, root="spherical", actuation=actuation_matrix(actuation, "actuation"),
                   dt=dt, integrator=integrator, gravity=False, second_order=second_order)
    _one_body(mb.pin_model, inertia)
    return mb
