"""The tests' oracle of the multibody dynamics: the Python path geoddp ran before its compiled
core (cpp/), kept here to check the core against.

:class:`OracleMultibody` is a :class:`geoddp.models.multibody.Multibody` whose rollouts, closed-loop
passes and expansions run in numpy over Pinocchio's Python calls, node by node:

* velocity update: first order from ``computeABADerivatives``; second order zero in (u, u) and
  (v, u), exact in (v, v) from RNEA's dtau_dv, and central differences of the analytic first
  derivatives along q for the rest (:meth:`OracleMultibody.velocity_derivatives`), where the core
  uses Pinocchio's second-order RNEA;
* reconstruction: the exact second-order formula written once for any product group,
  :func:`geoddp.models.integrators.expand`;
* rk4: tests/oracle_rkmk4.py's step Jacobian, its second order central differences of it;
* variational: tests/oracle_variational.py.

:func:`use_oracle` makes every ``Multibody`` built afterwards in the test (scene files, the CLI in
process, robots by name) run this path, and every cost sum the cost oracle (tests/oracle_costs.py).
"""
from __future__ import annotations

import contextlib

import numpy as np
import pinocchio as pin

from geoddp.models import integrators as integ
from oracle_linalg import symmetric_from_upper
from geoddp.models.multibody import Multibody
from geoddp.models.variational import StepDidNotConverge

import oracle_rkmk4 as rkmk4
from oracle_costs import use_cost_oracle
from oracle_variational import VariationalEuler

# Central-difference step for the second derivatives of the velocity update: the error is
# ~h^2 |f'''| / 6 + eps |f'| / h; h = 1e-5 balances them near 1e-10 relative (tested against a
# Richardson-extrapolated difference).
FD_STEP = 1e-5


class OracleMultibody(Multibody):
    """A :class:`Multibody` on the Python path (same constructor; ``backend`` is "python")."""

    def __post_init__(self) -> None:
        super().__post_init__()
        _oracle_setup(self)

    @property
    def contracts_second_order(self) -> bool:
        """The oracle forms Theta, Gamma, Xi: never factored."""
        return False

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
        """One step: q (nq,), v (nv,), u (m,) -> (q+, v+)."""
        return self._step(self.pin_model.createData(), q, v, u)

    def rollout(self, q0: np.ndarray, v0: np.ndarray, controls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Open-loop rollout: q0 (nq,), v0 (nv,), controls (H, m) -> Q (H+1, nq), V (H+1, nv)."""
        q0, v0 = self.check_state(q0, v0)
        U = self.check_controls(controls)
        H = U.shape[0]
        data = self.pin_model.createData()
        Q = np.empty((H + 1, self.nq))
        V = np.empty((H + 1, self.nv))
        Q[0], V[0] = q0, v0
        for k in range(H):
            Q[k + 1], V[k + 1] = self._step(data, Q[k], V[k], U[k])
        return Q, V

    def rollout_closed_loop(self, q0, v0, Q_bar, V_bar, u_bar, k_ff, K_fb, gamma, Q_out, V_out, u_out,
                            lower=None, upper=None, checked=False) -> bool:
        """:meth:`Multibody.rollout_closed_loop` node by node in Python."""
        H = np.shape(u_out)[0]
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
            except StepDidNotConverge:
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
        """:meth:`Multibody.expansion` with Theta, Gamma, Xi formed (``contracted`` is refused)."""
        if contracted and order == 2:
            raise ValueError("contracted: the oracle forms Theta, Gamma, Xi")
        if order not in (1, 2):
            raise ValueError(f"order: expected 1 or 2, got {order!r}")
        U = self.check_controls(controls)
        H = U.shape[0]
        if self.integrator == "rk4":
            return self._expansion_rk4(Q, V, U, order)
        if self._variational is not None:
            # Implicit velocity update, explicit-Euler reconstruction q+ = q exp(dt v).
            F1, F2 = self._variational.velocity_derivatives(Q[:H], V[:H], V[1:], U, order)
        else:
            F1, F2 = self.velocity_derivatives(Q[:H], V[:H], U, order)
        W = V[1 : H + 1] if self.semi_implicit else V[:H]  # reconstruction velocity w_bar
        # the exact second-order reconstruction on the product of the joints' groups
        return integ.expand(self.groups, self.dt, W, F1, F2, self.semi_implicit)


def _oracle_setup(model: Multibody) -> None:
    model.backend = "python"
    model._data = model.pin_model.createData()  # the closed-loop pass's workspace
    model._variational = (VariationalEuler(model.pin_model, model.groups, model.actuation, model.dt)
                          if model.integrator == "variational" else None)


_METHODS = ("contracts_second_order", "_step", "step", "rollout", "rollout_closed_loop", "_invariant_q_dirs",
            "velocity_derivatives", "_expansion_rk4", "expansion")


def use_oracle(monkeypatch) -> None:
    """Make every :class:`Multibody` built from now on in this test an oracle one, and the
    multibody cost sums Python ones (pytest's ``monkeypatch`` undoes both after the test)."""
    use_cost_oracle(monkeypatch)
    original = Multibody.__post_init__

    def post_init(self) -> None:
        original(self)
        _oracle_setup(self)

    monkeypatch.setattr(Multibody, "__post_init__", post_init)
    for name in _METHODS:
        monkeypatch.setattr(Multibody, name, OracleMultibody.__dict__[name], raising=False)


@contextlib.contextmanager
def oracle_models():
    """:func:`use_oracle` for a block, outside a test (the benchmarks: ``with oracle_models(): ...``)."""
    import pytest

    with pytest.MonkeyPatch.context() as mp:
        use_oracle(mp)
        yield
