"""geoddp solves Crocoddyl's ANYmal trot (geoddp.scene.legged) and the answer is physical.

From the quasi-static start with the first-order expansion (and the switch expansion, to the same
J*): converged (certified by the exact second-order check), the stance feet do not slide (under
0.05 mm per step: semi-implicit Euler with Baumgarte damping, not an exact constraint on
positions), every stance force pushes (f_z > 0) and stays in the friction cone up to the soft
barrier's slack (under 1 % of f_z), the result JSON has Crocoddyl's shapes with zero control rows
at the impulse nodes.
"""
import json

import numpy as np
import pinocchio as pin
import pytest

from geoddp.scene.legged import anymal_trot, load_anymal
from geoddp.solver import SolverOptions, solve


@pytest.fixture(scope="module")
def solved():
    problem = anymal_trot(load_anymal())
    return problem, solve(problem, SolverOptions(expansion="first"))


def test_converges_below_the_start(solved):
    problem, res = solved
    assert res.converged, res.message
    J0 = problem.trajectory_cost(problem.trajectory(problem.quasi_static_controls()))
    assert res.cost < 1e-3 * J0
    assert res.cost == pytest.approx(problem.trajectory_cost(problem.trajectory(res.controls)), rel=1e-12)


def test_stance_feet_hold_and_forces_are_physical(solved):
    problem, res = solved
    m = problem.model
    d = m.createData()
    A = problem.cone[0]
    slide, fz_min, cone_excess = 0.0, np.inf, -np.inf
    for k, node in enumerate(problem.nodes):
        if node.kind != "contact":
            continue
        ev = problem.node(k, res.q[k], res.v[k], res.controls[k])[0]
        for i, f in enumerate(node.feet):
            pin.framesForwardKinematics(m, d, res.q[k])
            a = d.oMf[f].translation.copy()
            pin.framesForwardKinematics(m, d, res.q[k + 1])
            slide = max(slide, np.linalg.norm(d.oMf[f].translation - a))
            f_i = ev.forces[3 * i:3 * i + 3]
            fz_min = min(fz_min, f_i[2])
            cone_excess = max(cone_excess, np.max(A[:4] @ f_i) / f_i[2])
    assert slide < 5e-5, slide
    assert fz_min > 0.0, fz_min
    assert cone_excess < 1e-2, cone_excess


def test_result_json_shapes(solved, tmp_path):
    problem, res = solved
    d = json.loads(res.write_json(tmp_path / "trot.json").read_text())
    H = problem.horizon
    assert np.shape(d["configurations"]) == (H + 1, 19)
    assert np.shape(d["velocities"]) == (H + 1, 18)
    U = np.array(d["controls"])
    assert U.shape == (H, 12)
    assert problem.impulse_rows.sum() == 2 and np.all(U[problem.impulse_rows] == 0.0)
    assert np.all(np.any(U[~problem.impulse_rows] != 0.0, axis=1))


def test_switch_expansion_reaches_the_same_minimum(solved):
    """The switch expansion (its second-order steps on geoddp.problem.legged's exact terms) ends
    at the first expansion's J* to round-off, certified too."""
    problem, first = solved
    res = solve(problem, SolverOptions(expansion="switch"))
    assert res.converged, res.message
    assert "second" in res.expansion_history
    assert res.cost == pytest.approx(first.cost, rel=1e-12)


def recorded_trials(problem):
    """Record (gamma, J of the trial) of every closed-loop rollout and the order of every
    linearisation the solve makes on ``problem``."""
    trials, orders = [], []
    rollout, linearise = problem.rollout_policy, problem.linearise

    def recorded(nominal, k, K, gamma):
        traj = rollout(nominal, k, K, gamma)
        trials.append((gamma, problem.trajectory_cost(traj) if traj is not None else np.inf))
        return traj

    def counted(traj, order):
        orders.append(order)
        return linearise(traj, order)

    problem.rollout_policy, problem.linearise = recorded, counted
    return trials, orders


def test_a_full_step_within_tolerance_ends_the_search():
    """The trot's first-order solve, uncertified (no exact check, so no anticipated one either),
    ends where the model's full-step decrease (1.6e-12) is below the cost tolerance (rtol |J| =
    2.3e-9) and that step does not decrease J: one rollout (gamma = 1), not a search down through
    eight shorter steps each worth less than tol."""
    problem = anymal_trot(load_anymal())
    trials, orders = recorded_trials(problem)
    res = solve(problem, SolverOptions(expansion="first"), certify=False)
    assert res.converged and "predicted decrease of the full step" in res.message, res.message
    gamma, J_last = trials[-1]
    assert gamma == 1.0 and J_last > res.cost  # the last trial: the full step, rejected, and no other
    assert len(trials) == res.iterations + 1 + sum(
        round(np.log(g) / np.log(SolverOptions().step_factor)) for g in res.step_history)
    assert set(orders) == {1}


def test_first_order_checks_where_gauss_newton_predicts_convergence():
    """Certified, the trot's first order stops at the same iterate one Gauss-Newton iteration
    sooner: after a full step that cut the decrease 100x (3.1e-4 -> 4.4e-8), Gauss-Newton predicts
    a next decrease of about 4.4e-8^2 / 3.1e-4 = 6e-12, below ANTICIPATE x the threshold, so the
    exact check runs at that iterate before another Gauss-Newton expansion and certifies it: one
    exact linearisation, no Gauss-Newton one and no rollout at the returned iterate, and the same
    J* as the uncertified solve."""
    from geoddp.solver.policy import ANTICIPATE, CERTIFY_EARLY

    problem = anymal_trot(load_anymal())
    trials, orders = recorded_trials(problem)
    res = solve(problem, SolverOptions(expansion="first"))
    assert res.converged and "Gauss-Newton's next decrease predicted below" in res.message, res.message
    assert orders == [1] * res.iterations + [2]  # the exact one last, once: the check is the final check's
    assert len(trials) == res.iterations + sum(
        round(np.log(g) / np.log(SolverOptions().step_factor)) for g in res.step_history)
    opt = res.extra["optimality"]
    assert opt["hessian_positive_definite"]
    assert 0.0 <= opt["newton_decrease"] <= CERTIFY_EARLY * opt["newton_threshold"]
    reference = solve(anymal_trot(load_anymal()), SolverOptions(expansion="first"), certify=False)
    assert res.cost == reference.cost and res.iterations == reference.iterations
    assert ANTICIPATE < CERTIFY_EARLY