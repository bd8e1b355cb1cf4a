"""The rigid satellite on TSO(3) (paper Section VI), with Pinocchio as the source of truth.

Model (constant): a Pinocchio model with one spherical joint (gravity off) whose body carries the
inertia I, an actuation matrix H (3 x m) mapping inputs to body torques, the time step and the
integrator. Dynamics: Omega+ = Omega + dt I^-1((I Omega) x Omega + H u) (= Omega + dt aba), with
R+ = R exp(dt Omega) (explicit Euler, paper eq. disceqs) or R+ = R exp(dt Omega+) (semi-implicit).

Derivatives along a trajectory come from one of three backends that tests hold equal:
* ``"compiled"``: the closed forms in one numba loop (:func:`geoddp.kernels.satellite_linearise`),
  the default and the fast path;
* ``"analytic"``: the same closed forms vectorised in numpy through the generic TSO(3) assembly of
  :mod:`geoddp.integrators` (the readable reference);
* ``"pinocchio"``: per node, ``computeABADerivatives`` for the first order and central finite
  differences of those analytic first derivatives for the second order (the pip wheel has no
  second-order ABA derivatives), ``dIntegrate`` for the reconstruction.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from .. import integrators as integ
from ..lie import hat
from .. import data, kernels
from ..validate import actuation_matrix, choice, inertia_matrix, positive_float

DEFAULT_URDF = data.urdf_path("satellite.urdf")
BACKENDS = ("compiled", "analytic", "pinocchio")


def _build_pinocchio_model(inertia: np.ndarray, urdf: Path | None) -> pin.Model:
    if urdf is not None:
        model = pin.buildModelFromUrdf(str(urdf), pin.JointModelSpherical())
        if model.nv != 3:
            raise ValueError(f"urdf: expected a single rigid body (nv = 3 with a spherical root), got nv = {model.nv}")
        mass = model.inertias[1].mass
    else:
        model = pin.Model()
        jid = model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "root_joint")
        model.appendBodyToJoint(jid, pin.Inertia.Zero(), pin.SE3.Identity())
        mass = 1.0
    # The scene's inertia about the centre of mass, which sits at the joint origin.
    model.inertias[1] = pin.Inertia(mass, np.zeros(3), inertia)
    model.gravity = pin.Motion.Zero()
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
        backend: derivative backend used by :meth:`expansion` unless a call names another:
            "compiled" (numba, default), "analytic" (numpy reference) or "pinocchio" (per-node
            Pinocchio calls, the source of truth). A model choice, made when the model is built.
    """

    inertia: np.ndarray
    actuation: np.ndarray
    dt: float
    integrator: str = "euler"
    second_order: str = "exact"
    urdf: Path | None = None
    backend: str = "compiled"
    pin_model: pin.Model = field(init=False, repr=False)
    inertia_inv: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.inertia = inertia_matrix(self.inertia, "inertia")
        self.actuation = actuation_matrix(self.actuation, "actuation")
        self.dt = positive_float(self.dt, "dt")
        self.integrator = choice(self.integrator, "integrator", integ.INTEGRATORS)
        self.second_order = choice(self.second_order, "second_order", integ.SECOND_ORDER_KINDS)
        self.backend = choice(self.backend, "backend", BACKENDS)
        if self.second_order == "paper" and self.integrator != "euler":
            raise ValueError("second_order: 'paper' is derived for integrator 'euler' only")
        if self.urdf is None:
            self.urdf = DEFAULT_URDF
        if self.urdf is not None:
            self.urdf = Path(self.urdf)
            if not self.urdf.is_file():
                raise FileNotFoundError(f"urdf: no such file {self.urdf}")
        self.pin_model = _build_pinocchio_model(self.inertia, self.urdf)
        self.inertia_inv = np.linalg.inv(self.inertia)

    @property
    def nu(self) -> int:
        """Number of inputs m."""
        return int(self.actuation.shape[1])

    @property
    def semi_implicit(self) -> bool:
        return self.integrator == "semi_implicit"

    # ------------------------------------------------------------------ dynamics
    def step(self, R: np.ndarray, Omega: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One step through Pinocchio (aba + integrate): the reference implementation.

        R (3, 3), Omega (3,) rad/s, u (m,) -> (R+, Omega+).
        """
        model, data = self.pin_model, self.pin_model.createData()
        q = pin.Quaternion(R).coeffs()  # (x, y, z, w)
        a = pin.aba(model, data, q, Omega, self.actuation @ u)
        Omega_next = Omega + self.dt * a
        w = Omega_next if self.semi_implicit else Omega
        q_next = pin.integrate(model, q, self.dt * w)
        return pin.Quaternion(q_next).normalized().toRotationMatrix(), Omega_next

    def rollout(self, R0: np.ndarray, Omega0: np.ndarray, controls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Compiled open-loop rollout: R0 (3,3), Omega0 (3,), controls (H, m) ->
        R (H+1, 3, 3), Omega (H+1, 3)."""
        U = np.ascontiguousarray(controls, dtype=float)
        H = U.shape[0]
        R = np.empty((H + 1, 3, 3))
        Om = np.empty((H + 1, 3))
        dummy = np.empty((H, self.nu))
        kernels.satellite_rollout(
            np.ascontiguousarray(R0, dtype=float), np.ascontiguousarray(Omega0, dtype=float),
            R, Om, U, dummy, np.empty((H, self.nu, 6)), 0.0, False,
            self.inertia, self.inertia_inv, self.actuation, self.dt, self.semi_implicit, R, Om, dummy,
        )
        return R, Om

    def rollout_reference(self, R0: np.ndarray, Omega0: np.ndarray, controls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Same as :meth:`rollout` through :meth:`step` (Pinocchio), for tests."""
        H = controls.shape[0]
        R = np.empty((H + 1, 3, 3))
        Om = np.empty((H + 1, 3))
        R[0], Om[0] = R0, Omega0
        for k in range(H):
            R[k + 1], Om[k + 1] = self.step(R[k], Om[k], controls[k])
        return R, Om

    # ------------------------------------------------------------------ derivatives
    def velocity_derivatives(
        self, R: np.ndarray, Omega: np.ndarray, controls: np.ndarray, order: int, backend: str = "analytic"
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Derivatives of Omega+ = f(R, Omega, u) w.r.t. z = (eta, dOmega, du) at N nodes.

        R (N, 3, 3), Omega (N, 3), controls (N, m) -> F1 (N, 3, 6+m), F2 (N, 3, 6+m, 6+m) or None.
        """
        backend = choice(backend, "backend", BACKENDS)
        if backend == "analytic":
            return self._velocity_derivatives_analytic(Omega, controls.shape[0], order)
        return self._velocity_derivatives_pinocchio(R, Omega, controls, order)

    def _velocity_derivatives_analytic(self, Omega: np.ndarray, N: int, order: int):
        dt, I, Iinv = self.dt, self.inertia, self.inertia_inv
        m = self.nu
        nz = 6 + m
        F1 = np.zeros((N, 3, nz))
        # d/dOmega of (I Omega) x Omega = hat(I Omega) - hat(Omega) I   (paper, Section VI)
        L = Omega @ I.T
        F1[:, :, 3:6] = np.eye(3) + dt * (Iinv @ (hat(L) - hat(Omega) @ I))
        F1[:, :, 6:] = dt * (Iinv @ self.actuation)
        if order < 2:
            return F1, None
        # d2/dOmega_j dOmega_l = dt I^-1 ((I e_j) x e_l + (I e_l) x e_j): constant along the horizon.
        C = np.cross(I.T[:, None, :], np.eye(3)[None, :, :])  # C[j, l] = (I e_j) x e_l
        T = dt * np.einsum("ik,jlk->ijl", Iinv, C + np.swapaxes(C, 0, 1))
        F2 = np.zeros((N, 3, nz, nz))
        F2[:, :, 3:6, 3:6] = T
        return F1, F2

    def _velocity_derivatives_pinocchio(self, R, Omega, controls, order):
        model = self.pin_model
        data = model.createData()
        dt, Hm = self.dt, self.actuation
        N, m = controls.shape
        nz = 6 + m

        def jac(q, v, tau):
            pin.computeABADerivatives(model, data, q, v, tau)
            J = np.empty((3, nz))
            J[:, 0:3] = dt * data.ddq_dq
            J[:, 3:6] = np.eye(3) + dt * data.ddq_dv
            Minv = np.triu(data.Minv) + np.triu(data.Minv, 1).T  # Pinocchio fills the upper part
            J[:, 6:] = dt * Minv @ Hm
            return J

        F1 = np.empty((N, 3, nz))
        F2 = np.empty((N, 3, nz, nz)) if order >= 2 else None
        # Central differences of an analytic Jacobian: error ~ h^2 f''' + eps/h; h = 1e-5 balances
        # them (the satellite's f is quadratic, so only round-off ~1e-11 remains; tested).
        h = 1e-5
        for k in range(N):
            q = pin.Quaternion(R[k]).coeffs().copy()
            v = Omega[k]
            tau = Hm @ controls[k]
            F1[k] = jac(q, v, tau)
            if F2 is None:
                continue
            D = np.empty((3, nz, nz))
            for j in range(nz):
                e = np.zeros(nz)
                e[j] = h
                args = []
                for s in (1.0, -1.0):
                    qs = pin.integrate(model, q, s * e[0:3])
                    args.append(jac(qs, v + s * e[3:6], tau + s * Hm @ e[6:]))
                D[:, :, j] = (args[0] - args[1]) / (2.0 * h)
            F2[k] = 0.5 * (D + np.swapaxes(D, 1, 2))  # (0)-connection Hessian is the symmetric part
        return F1, F2

    def expansion(
        self, R: np.ndarray, Omega: np.ndarray, controls: np.ndarray, order: int = 1, backend: str | None = None
    ) -> integ.Expansion:
        """Phi, B (and Theta, Gamma, Xi for order 2) at the H nodes of a trajectory.

        R (H+1, 3, 3), Omega (H+1, 3), controls (H, m); ``backend`` defaults to the model's.
        See :mod:`geoddp.integrators`.
        """
        H = controls.shape[0]
        backend = self.backend if backend is None else choice(backend, "backend", BACKENDS)
        if backend == "compiled" and self.second_order == "exact":
            return self._expansion_compiled(Omega, H, order)
        if backend == "compiled":
            backend = "analytic"  # the paper's Theta exists only as the numpy reference
        F1, F2 = self.velocity_derivatives(R[:H], Omega[:H], controls, order, backend)
        w = integ.reconstruction_velocity(Omega[:H], Omega[1 : H + 1], self.integrator)
        if backend == "pinocchio":
            return self._expansion_pinocchio(R, Omega, controls, F1, F2, w)
        return integ.assemble(self.dt, w, F1, F2, self.integrator, self.second_order)

    def _expansion_compiled(self, Omega: np.ndarray, H: int, order: int) -> integ.Expansion:
        m = self.nu
        e = integ.Expansion(Phi=np.empty((H, 6, 6)), B=np.empty((H, 6, m)))
        if order >= 2:
            e.Theta, e.Gamma, e.Xi = np.empty((H, 6, 6, 6)), np.empty((H, 6, 6, m)), np.empty((H, 6, m, m))
            th, ga, xi = e.Theta, e.Gamma, e.Xi
        else:
            th, ga, xi = np.empty((0, 6, 6, 6)), np.empty((0, 6, 6, m)), np.empty((0, 6, m, m))
        kernels.satellite_linearise(np.ascontiguousarray(Omega, dtype=float), self.dt, self.inertia, self.inertia_inv,
                                    self.actuation, self.semi_implicit, order >= 2, e.Phi, e.B, th, ga, xi)
        return e

    def _expansion_pinocchio(self, R, Omega, controls, F1, F2, w):
        """Reconstruction blocks from pin.dIntegrate: d/dq = Ad_exp(-dt w), d/dv = Jexp3(dt w)."""
        exp = integ.assemble(self.dt, w, F1, F2, self.integrator, self.second_order)
        model = self.pin_model
        H = controls.shape[0]
        W1 = F1 if self.semi_implicit else np.concatenate(
            [np.zeros((H, 3, 3)), np.broadcast_to(np.eye(3), (H, 3, 3)), np.zeros((H, 3, self.nu))], axis=2
        )
        for k in range(H):
            q = pin.Quaternion(R[k]).coeffs().copy()
            Jq = pin.dIntegrate(model, q, self.dt * w[k], pin.ARG0)
            Jv = pin.dIntegrate(model, q, self.dt * w[k], pin.ARG1)
            G = self.dt * Jv @ W1[k]
            G[:, 0:3] += Jq
            exp.Phi[k, 0:3] = G[:, 0:6]
            exp.B[k, 0:3] = G[:, 6:]
        return exp
