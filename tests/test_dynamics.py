"""Satellite dynamics: rollouts and expansions against Pinocchio and finite differences."""
import numpy as np
import pinocchio as pin
import pytest

from geoddp.lie import TSO3
from geoddp.models.satellite import DEFAULT_URDF, Satellite
from oracle_satellite import OracleSatellite

INERTIA = np.array([[10.0, 0.4, -0.2], [0.4, 11.1, 0.3], [-0.2, 0.3, 13.0]])  # non-diagonal on purpose
ACTUATION = np.array([[1.0, 0.2], [0.0, 1.0], [0.5, -0.3]])  # underactuated, m = 2
INTEGRATORS = ["euler", "semi_implicit"]


def _model(integrator, **kw):
    return OracleSatellite(inertia=INERTIA, actuation=ACTUATION, dt=0.05, integrator=integrator, urdf=DEFAULT_URDF, **kw)


def _trajectory(model, rng, H=5):
    R0 = pin.exp3(rng.normal(size=3))
    Om0 = 1.5 * rng.normal(size=3)
    U = 3.0 * rng.normal(size=(H, model.nu))
    R, Om = model.rollout(R0, Om0, U)
    return R, Om, U


def _one_step_map(model, R, Om, U, k):
    """z = (zeta, du) -> zeta+ in exponential coordinates about the nominal next state."""
    def f(z):
        Rp, Op = TSO3.retract(R[k], Om[k], z[:6])
        Rn, On = model.step(Rp, Op, U[k] + z[6:])
        return TSO3.local(R[k + 1], Om[k + 1], Rn, On)
    return f


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_compiled_rollout_matches_pinocchio_step(integrator, rng):
    model = _model(integrator)
    R, Om, U = _trajectory(model, rng, H=50)
    Rr, Omr = model.rollout_reference(R[0], Om[0], U)
    assert np.abs(R - Rr).max() < 1e-12
    assert np.abs(Om - Omr).max() < 1e-12


def test_velocity_update_is_the_paper_formula(rng):
    model = _model("euler")
    R, Om, u = pin.exp3(rng.normal(size=3)), rng.normal(size=3), rng.normal(size=2)
    _, Om_next = model.step(R, Om, u)
    expected = Om + 0.05 * np.linalg.solve(INERTIA, np.cross(INERTIA @ Om, Om) + ACTUATION @ u)
    assert np.abs(Om_next - expected).max() < 1e-14


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_phi_b_against_finite_differences_and_pinocchio(integrator, rng):
    model = _model(integrator)
    R, Om, U = _trajectory(model, rng)
    ea = model.expansion(R, Om, U, order=1, backend="analytic")
    ep = model.expansion(R, Om, U, order=1, backend="pinocchio")
    assert np.abs(ea.Phi - ep.Phi).max() < 1e-10
    assert np.abs(ea.B - ep.B).max() < 1e-10
    h = 1e-6
    for k in range(U.shape[0]):
        f = _one_step_map(model, R, Om, U, k)
        J = np.array([(f(h * e) - f(-h * e)) / (2 * h) for e in np.eye(6 + model.nu)]).T
        assert np.abs(J[:, :6] - ea.Phi[k]).max() < 1e-8
        assert np.abs(J[:, 6:] - ea.B[k]).max() < 1e-8


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_second_order_terms_analytic_match_pinocchio_finite_differences(integrator, rng):
    model = _model(integrator)
    R, Om, U = _trajectory(model, rng)
    ea = model.expansion(R, Om, U, order=2, backend="analytic")
    ep = model.expansion(R, Om, U, order=2, backend="pinocchio")
    for name in ("Theta", "Gamma", "Xi"):
        assert np.abs(getattr(ea, name) - getattr(ep, name)).max() < 1e-9, name


def _prediction_errors(model, rng, second_order_terms, trials=6):
    """One-step prediction error at perturbation sizes eps, eps/2, eps/4 ... for random nominals."""
    ratios = []
    for _ in range(trials):
        R, Om, U = _trajectory(model, rng, H=3)
        e = model.expansion(R, Om, U, order=2)
        k = 1
        f = _one_step_map(model, R, Om, U, k)
        n, m = 6, model.nu
        G = np.concatenate([e.Phi[k], e.B[k]], axis=1)
        T = np.zeros((n, n + m, n + m))
        T[:, :n, :n] = e.Theta[k]
        T[:, :n, n:] = e.Gamma[k]
        T[:, n:, :n] = np.swapaxes(e.Gamma[k], 1, 2)
        T[:, n:, n:] = e.Xi[k]
        d = rng.normal(size=n + m)
        d /= np.linalg.norm(d)
        errs = []
        for eps in (2e-2, 1e-2, 5e-3, 2.5e-3):
            z = eps * d
            pred = G @ z + (0.5 * np.einsum("iab,a,b->i", T, z, z) if second_order_terms else 0.0)
            errs.append(np.linalg.norm(f(z) - pred))
        ratios.append([errs[i] / errs[i + 1] for i in range(3)])
    return np.array(ratios)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_exact_second_order_error_falls_8x_per_halving(integrator, rng):
    model = _model(integrator)
    r2 = _prediction_errors(model, rng, True)
    r1 = _prediction_errors(model, rng, False)
    assert np.all((r2 > 7.0) & (r2 < 9.0)), r2
    assert np.all((r1 > 3.5) & (r1 < 4.5)), r1


def test_eta_eta_term_is_exactly_zero_and_the_papers_is_not(rng):
    exact = _model("euler")
    paper = _model("euler", second_order="paper")
    R, Om, U = _trajectory(exact, rng)
    te = exact.expansion(R, Om, U, order=2).Theta
    tp = paper.expansion(R, Om, U, order=2).Theta
    assert np.abs(te[:, 0:3, 0:3, 0:3]).max() == 0.0
    assert np.abs(tp[:, 0:3, 0:3, 0:3]).max() > 1e-4
    # with dOmega = du = 0 the eta update is exactly linear: eta+ = Ad_exp(-dt Omega) eta
    f = _one_step_map(exact, R, Om, U, 1)
    eta = np.array([0.2, -0.1, 0.15])
    z = np.concatenate([eta, np.zeros(3 + exact.nu)])
    assert np.abs(f(z)[:3] - exact.expansion(R, Om, U).Phi[1, :3, :3] @ eta).max() < 1e-13


def test_papers_theta_is_only_first_order_accurate(rng):
    """With the paper's Omega_ij the prediction error falls ~4x, not 8x, per halving of eta."""
    model = _model("euler", second_order="paper")
    ratios = []
    for _ in range(4):
        R, Om, U = _trajectory(model, rng, H=3)
        e = model.expansion(R, Om, U, order=2)
        f = _one_step_map(model, R, Om, U, 1)
        d = np.concatenate([rng.normal(size=3), np.zeros(3 + model.nu)])
        errs = []
        for eps in (2e-2, 1e-2, 5e-3):
            z = eps * d
            pred = e.Phi[1] @ z[:6] + 0.5 * np.einsum("iab,a,b->i", e.Theta[1], z[:6], z[:6])
            errs.append(np.linalg.norm(f(z) - pred))
        ratios.append(errs[1] / errs[2])
    assert np.all(np.array(ratios) < 5.0), ratios


def test_paper_expansion_refuses_semi_implicit():
    with pytest.raises(ValueError, match="second_order"):
        Satellite(inertia=INERTIA, actuation=ACTUATION, dt=0.01, integrator="semi_implicit", second_order="paper")


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_compiled_backend_equals_the_numpy_reference(integrator, rng):
    model = _model(integrator)
    R, Om, U = _trajectory(model, rng, H=40)
    for order in (1, 2):
        a = model.expansion(R, Om, U, order=order, backend="analytic")
        c = model.expansion(R, Om, U, order=order, backend="compiled")
        for name in ("Phi", "B") + (("Theta", "Gamma", "Xi") if order == 2 else ()):
            ref = getattr(a, name)
            assert np.abs(getattr(c, name) - ref).max() <= 1e-13 * max(1.0, np.abs(ref).max()), name


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_both_euler_schemes_are_first_order(integrator):
    """Terminal error against a DOP853 solution of the continuous dynamics has slope 1 in dt."""
    from scipy.integrate import solve_ivp

    tf = 1.0
    torque = lambda t: np.array([np.sin(3 * t), 0.5 * np.cos(2 * t), 1.0 - t])  # smooth, m = 3
    Om0 = np.array([0.3, -0.2, 0.5])

    def rhs(t, y):
        R, Om = y[:9].reshape(3, 3), y[9:]
        W = np.array([[0, -Om[2], Om[1]], [Om[2], 0, -Om[0]], [-Om[1], Om[0], 0]])
        return np.concatenate([(R @ W).ravel(), np.linalg.solve(INERTIA, np.cross(INERTIA @ Om, Om) + torque(t))])

    ref = solve_ivp(rhs, (0, tf), np.concatenate([np.eye(3).ravel(), Om0]), method="DOP853", rtol=1e-12, atol=1e-13).y[:, -1]
    errs = []
    dts = [0.02, 0.01, 0.005, 0.0025]
    for dt in dts:
        model = Satellite(inertia=INERTIA, actuation=np.eye(3), dt=dt, integrator=integrator)
        H = int(round(tf / dt))
        U = np.array([torque(k * dt) for k in range(H)])
        R, Om = model.rollout(np.eye(3), Om0, U)
        errs.append(np.linalg.norm(pin.log3(ref[:9].reshape(3, 3).T @ R[-1])) + np.linalg.norm(Om[-1] - ref[9:]))
    slope = np.polyfit(np.log(dts), np.log(errs), 1)[0]
    assert 0.9 < slope < 1.1, (slope, errs)


def test_satellite_model_comes_from_the_urdf_with_the_scene_inertia():
    model = Satellite(inertia=INERTIA, actuation=ACTUATION, dt=0.01)
    assert model.urdf == DEFAULT_URDF
    pm = model.pin_model
    assert pm.nq == 4 and pm.nv == 3 and np.all(pm.gravity.vector == 0.0)
    assert np.allclose(pm.inertias[1].inertia, INERTIA) and np.allclose(pm.inertias[1].lever, 0.0)
    assert pm.inertias[1].mass == 100.0  # from the URDF


def test_compiled_papers_expansion_equals_the_numpy_reference(rng):
    """second_order="paper" runs the compiled exact expansion with the paper's eta rows."""
    model = _model("euler", second_order="paper")
    R, Om, U = _trajectory(model, rng, H=20)
    a = model.expansion(R, Om, U, order=2, backend="analytic")
    c = model.expansion(R, Om, U, order=2, backend="compiled")
    for name in ("Phi", "B", "Theta", "Gamma", "Xi"):
        ref = getattr(a, name)
        assert np.abs(getattr(c, name) - ref).max() <= 1e-13 * max(1.0, np.abs(ref).max()), name
