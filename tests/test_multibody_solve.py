"""Geometric DDP on the issue-6 multibody scenes: convergence, rates, an independent optimum."""
import numpy as np
import pytest

from geoddp.scene.builtin import hover_controls, quadrotor, space_manipulator, spacecraft_docking
from geoddp.solver.reference import lbfgs
from geoddp.solver import SolverOptions, solve

# Same manoeuvres as the scene defaults, on coarser grids to keep CI short.
SCENES = {
    "spacecraft": lambda integ: spacecraft_docking(integrator=integ, dt=0.125, horizon=80),
    "manipulator": lambda integ: space_manipulator(integrator=integ, dt=0.05, horizon=60),
    "quadrotor": lambda integ: quadrotor(integrator=integ, dt=0.05, horizon=60),
}


def _guess(name, problem):
    return hover_controls(problem) if name == "quadrotor" else None


@pytest.fixture(scope="module")
def solves():
    out = {}
    for name, build in SCENES.items():
        p = build("semi_implicit")
        for exp in ("first", "second", "switch"):
            out[name, exp] = (p, solve(p, SolverOptions(expansion=exp, verbose=False, max_iter=200, tol=0.0,
                                                        grad_tol=1e-9, record_controls=True),
                                       initial_controls=_guess(name, p)))
    return out


@pytest.mark.parametrize("name", list(SCENES))
def test_expansions_agree_and_invariants_hold(solves, name):
    costs = {exp: solves[name, exp][1].cost for exp in ("first", "second", "switch")}
    ref = costs["second"]
    for exp, (p, r) in ((e, solves[name, e]) for e in ("first", "second", "switch")):
        assert r.converged, (name, exp, r.status, r.message)
        assert abs(r.cost - ref) <= 1e-7 * abs(ref), costs
        assert np.all(np.diff(r.cost_history) <= 0.0)
        for a in (r.configurations, r.velocities, r.controls, r.feedback):
            assert np.all(np.isfinite(a))
        assert r.configurations.shape == (p.horizon + 1, p.model.nq)
        RtR = np.einsum("nji,njk->nik", r.rotations, r.rotations)
        assert np.abs(RtR - np.eye(3)).max() < 1e-12


@pytest.mark.parametrize("name", list(SCENES))
@pytest.mark.parametrize("exp", ["second", "switch"])
def test_second_order_converges_superlinearly(solves, name, exp):
    g = solves[name, exp][1].grad_norm_history
    idx = np.where(g > 1e-8)[0]
    tail = g[idx[-3]: idx[-1] + 2]
    q = tail[1:] / tail[:-1]
    assert len(q) >= 2
    assert q[-1] < 1e-2 and q[-1] < q[0], (name, exp, g)


def test_spacecraft_optimum_agrees_with_an_independent_solver(solves):
    p, r = solves["spacecraft", "second"]
    ref = lbfgs(p, max_iter=3000, gtol=1e-7)
    assert abs(ref.cost - r.cost) <= 1e-6 * r.cost, (ref.cost, r.cost, ref.message)
    assert ref.cost >= r.cost - 1e-9 * r.cost  # DDP's optimum is not beaten


def test_spacecraft_docks():
    """The default scene (dt = 0.05, H = 200) ends at the docking pose, nearly at rest."""
    import pinocchio as pin

    p = spacecraft_docking()
    r = solve(p, SolverOptions(verbose=False))
    assert r.converged
    M = pin.XYZQUATToSE3(r.configurations[-1])
    # measured: 1.3 cm, 0.075 deg, 0.65 mm/s from a start 4.3 m away and 50 deg off
    assert np.linalg.norm(M.translation) < 0.02  # m
    assert np.degrees(np.linalg.norm(pin.log3(M.rotation.T @ pin.exp3(np.array([0, 0, np.pi / 2]))))) < 0.2
    assert np.linalg.norm(r.velocities[-1][:3]) < 2e-3  # m/s
    assert np.linalg.norm(r.velocities[-1][3:]) < 1e-3  # rad/s


def test_variational_integrator_solves_the_spacecraft_scene_superlinearly():
    """The paper's forward variational Euler (derivatives by implicit differentiation): first and
    switch agree on J* and switch converges superlinearly (measured ||grad J|| 1.5e-2, 2.0e-4,
    6.5e-8 over its last three iterations)."""
    p = SCENES["spacecraft"]("variational")
    opts = dict(verbose=False, max_iter=200, tol=0.0, grad_tol=1e-9)
    first = solve(p, SolverOptions(expansion="first", **opts))
    switch = solve(p, SolverOptions(expansion="switch", **opts))
    assert first.converged and switch.converged, (first.message, switch.message)
    assert abs(first.cost - switch.cost) <= 1e-9 * switch.cost
    assert switch.iterations < first.iterations
    g = switch.grad_norm_history
    tail = g[-3:]
    assert tail[-1] < 1e-6 and tail[2] / tail[1] < 1e-2 and tail[1] / tail[0] < 1e-1, g
    # and the optimum differs from the semi-implicit one by the integrators' O(dt) difference only
    semi = solve(SCENES["spacecraft"]("semi_implicit"), SolverOptions(**opts))
    assert abs(semi.cost - switch.cost) < 0.05 * semi.cost
