"""The satellite's oracles (moved from src): the same TSO(3) model with the expansion computed by
the numpy closed forms ("analytic", through the generic :func:`geoddp.models.integrators.expand` on
SO(3)) or per node by Pinocchio ("pinocchio": ``computeABADerivatives`` for the first order,
central differences of those analytic first derivatives for the second order, ``dIntegrate`` for
the reconstruction), and a one-step rollout through ``pin.aba`` + ``pin.integrate``. The library
runs only the compiled backend (:class:`geoddp.models.satellite.Satellite`); tests hold it equal
to these.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from geoddp.models import integrators as integ
from geoddp.lie import SO3_ROOT, hat
from geoddp.models.satellite import Satellite
from geoddp.validate import choice

BACKENDS = ("compiled", "analytic", "pinocchio")


def reconstruction_velocity(Omega: np.ndarray, Omega_next: np.ndarray, integrator: str) -> np.ndarray:
    """The velocity w used in R+ = R exp(dt w): Omega (euler) or Omega+ (semi_implicit). (N, 3)."""
    return Omega if integrator == "euler" else Omega_next


def assemble(dt, w_bar, F1, F2, integrator, second_order="exact") -> integ.Expansion:
    """The satellite's (TSO(3)) expansion: :func:`geoddp.models.integrators.expand` on SO(3), with the
    paper's eta rows for ``second_order="paper"``."""
    exp = integ.expand(SO3_ROOT, dt, w_bar, F1, F2, integrator == "semi_implicit")
    if F2 is not None and second_order == "paper":
        integ.paper_eta_rows(exp, dt, w_bar)
    return exp


@dataclass
class OracleSatellite(Satellite):
    """:class:`Satellite` with a ``backend`` ("compiled", "analytic" or "pinocchio") for
    :meth:`expansion`, and the Pinocchio reference step."""

    backend: str = "analytic"

    def __post_init__(self) -> None:
        super().__post_init__()
        self.backend = choice(self.backend, "backend", BACKENDS)

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

    def rollout_reference(self, R0: np.ndarray, Omega0: np.ndarray, controls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Same as :meth:`rollout` through :meth:`step` (Pinocchio), for tests."""
        H = controls.shape[0]
        R = np.empty((H + 1, 3, 3))
        Om = np.empty((H + 1, 3))
        R[0], Om[0] = R0, Omega0
        for k in range(H):
            R[k + 1], Om[k + 1] = self.step(R[k], Om[k], controls[k])
        return R, Om

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
        See :mod:`geoddp.models.integrators`.
        """
        H = controls.shape[0]
        backend = self.backend if backend is None else choice(backend, "backend", BACKENDS)
        if backend == "compiled":
            return Satellite.expansion(self, R, Omega, controls, order)
        F1, F2 = self.velocity_derivatives(R[:H], Omega[:H], controls, order, backend)
        w = reconstruction_velocity(Omega[:H], Omega[1 : H + 1], self.integrator)
        if backend == "pinocchio":
            return self._expansion_pinocchio(R, Omega, controls, F1, F2, w)
        return assemble(self.dt, w, F1, F2, self.integrator, self.second_order)

    def _expansion_pinocchio(self, R, Omega, controls, F1, F2, w):
        """Reconstruction blocks from pin.dIntegrate: d/dq = Ad_exp(-dt w), d/dv = Jexp3(dt w)."""
        exp = assemble(self.dt, w, F1, F2, self.integrator, self.second_order)
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


def oracle_model(model: Satellite, backend: str) -> OracleSatellite:
    """The same satellite (inertia, actuation, dt, integrator, second order, URDF) as an oracle."""
    return OracleSatellite(inertia=model.inertia, actuation=model.actuation, dt=model.dt, integrator=model.integrator,
                           second_order=model.second_order, urdf=model.urdf, backend=backend)


def with_backend(problem, backend: str):
    """A shallow copy of a satellite problem whose model computes expansions with ``backend``."""
    p = copy.copy(problem)
    p.model = oracle_model(problem.model, backend)
    return p
