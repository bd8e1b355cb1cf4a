"""Constrained solves: the KKT conditions at the solution as numbers (feasibility, complementarity,
stationarity of the Lagrangian checked independently of the outer loop's own claims), each
expansion to the same optimum, infeasible problems reported as infeasible with their smallest
violation, the unconstrained path bit for bit, the Result and its JSON."""
from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

from geoddp.constraints import (STATUS_INFEASIBLE, STATUS_KKT, ConstrainedProblem, ConstraintOptions,
                                FramePlacementConstraint, JointLimits, PointingKeepOut, StateConstraint,
                                solve_constrained)
from geoddp.scene.builtin import space_manipulator
from geoddp.problem import paper_problem
from geoddp import Result
from geoddp.scene import build_problem, load_scene
from geoddp.solver import SolverOptions, cost_gradient, solve
from geoddp.solver.loop import check
from geoddp.validate import InputError

D = np.array([0.849, 0.482, 0.215]) / np.linalg.norm([0.849, 0.482, 0.215])
TOL = 1e-8


def _opts(**kw) -> SolverOptions:
    return SolverOptions(verbose=False, **kw)


def _angles_deg(R: np.ndarray) -> np.ndarray:
    """Angle between the body x axis R_k e_x and D at every node (degrees)."""
    return np.degrees(np.arccos(np.clip(R[:, :, 0] @ D, -1.0, 1.0)))


@pytest.fixture(scope="module")
def keep_out():
    """The built-in keep-out scene, solved with the second-order expansion."""
    cp = build_problem(load_scene("satellite_keep_out"))
    return cp, solve_constrained(cp, _opts(expansion="second"))


def _multipliers(r: Result) -> list[np.ndarray]:
    return [np.array(it["multipliers"], dtype=float) for it in r.extra["constraints"]["items"]]


def test_the_unconstrained_slew_crosses_the_cone(keep_out):
    cp, _ = keep_out
    free = solve(cp.problem, _opts())
    assert free.converged and free.cost == pytest.approx(510.372636558827, rel=1e-12)
    assert _angles_deg(free.q).min() < 0.02  # passes within 0.02 deg of the direction the cone is around


def test_keep_out_solution_is_a_kkt_point(keep_out):
    cp, r = keep_out
    assert r.status == STATUS_KKT and r.converged
    report = r.extra["constraints"]
    (item,) = report["items"]
    c = np.array(item["values"])[:, 0]
    lam = _multipliers(r)[0][:, 0]
    # primal feasibility: the cone holds at every node k = 1..H to the tolerance (cosine units)
    assert item["nodes"] == list(range(1, 301))
    assert c.max() <= TOL and report["max_violation"] == pytest.approx(max(c.max(), 0.0), abs=0)
    assert _angles_deg(r.q)[1:].min() >= 20.0 - 1e-6
    # dual feasibility and complementarity: lambda >= 0, zero off the cone, on it |c| <= tol
    assert lam.min() >= 0.0
    on = lam > 0.0
    assert 1 <= on.sum() <= 5 and np.all(np.abs(c[on]) <= TOL)
    assert np.all(c[~on] < 0.0)
    assert report["complementarity"] == pytest.approx(np.max(np.abs(lam * c)), rel=1e-12)
    assert report["complementarity"] <= TOL * lam.max()
    assert item["active_nodes"] == int(np.sum(on | (c >= -TOL)))
    # stationarity, independently of the outer loop: the gradient of the Lagrangian
    # J + sum_k lambda_k c_k by the adjoint (the inner problem with these multipliers and a
    # vanishing penalty, whose gradient is exactly the Lagrangian's) ...
    lagrangian = cp.augmented(_multipliers(r), [1e-300])
    _, gL = cost_gradient(lagrangian, r.controls)
    _, gJ = cost_gradient(cp.problem, r.controls)
    assert np.linalg.norm(gL) <= 1e-8 * np.linalg.norm(gJ)  # measured 1.8e-9 against 21.6
    assert r.extra["optimality"]["lagrangian_stationarity"] == pytest.approx(np.linalg.norm(gL), rel=1e-6, abs=1e-12)
    # ... and by central differences of L(U) at a few controls around the contact (t = 1.5 s)
    def L(U):
        t = cp.problem.trajectory(U)
        return cp.problem.trajectory_cost(t) + float(np.sum(lam * cp.values(t)[0][:, 0]))

    picks = [(140, 0), (150, 1), (151, 2), (10, 2)]
    for idx in picks:
        e = np.zeros_like(r.controls)
        e[idx] = 1e-5
        fd = (L(r.controls + e) - L(r.controls - e)) / 2e-5
        assert abs(fd - gL[idx]) <= 1e-6  # the differences' round-off: ~1e-7 (J ~ 900, step 1e-5)
    assert max(abs(gJ[idx]) for idx in picks) > 0.5  # while J alone is far from stationary there
    # the inner certificate at the returned iterate
    o = r.extra["optimality"]
    # (at the default stopping rule: rtol |J| = 1e-11 x 908.7)
    assert o["hessian_positive_definite"] and o["newton_decrease"] <= o["newton_threshold"]
    # (the inner problem's J includes the augmented Lagrangian's terms: a few 1e-9 relative above r.cost)
    assert o["newton_threshold"] == pytest.approx(SolverOptions().cost_tolerance(r.cost), rel=1e-8)
    assert o["newton_threshold"] == pytest.approx(9.0875e-9, rel=1e-4)
    assert o["constraint_violation"] == report["max_violation"]


def test_every_expansion_reaches_the_same_constrained_optimum(keep_out):
    cp, second = keep_out
    for exp in ("first", "switch"):
        r = solve_constrained(cp, _opts(expansion=exp))
        assert r.status == STATUS_KKT, (exp, r.message)
        assert r.cost == pytest.approx(second.cost, rel=1e-9)  # 908.74701971..., IPOPT: test_constraints_ipopt
        assert r.extra["constraints"]["max_violation"] <= TOL
        report = r.extra["constraints"]
        assert report["outer_iterations"] == len(report["outer"]) >= 2
        assert report["inner_iterations"] == r.iterations == sum(o["inner_iterations"] for o in report["outer"])


def test_the_result_and_its_json(keep_out, tmp_path):
    cp, r = keep_out
    H = cp.horizon
    n = r.iterations
    assert r.cost == pytest.approx(cp.problem.total_cost(r.controls), rel=1e-14)  # J, without the augmented terms
    assert r.cost_history.shape == (n + 1,) and r.grad_norm_history.shape == (n + 1,)
    assert r.reg_history.shape == r.step_history.shape == (n,) and len(r.expansion_history) == n
    assert np.all(np.diff(r.time_history) >= 0.0)
    assert r.cost_history[-1] == pytest.approx(r.cost, rel=1e-7)  # the merit equals J at a KKT point
    assert r.feedback.shape == (H, 3, 6)
    path = r.write_json(tmp_path / "r.json")
    text = path.read_text()
    assert "NaN" not in text and "Infinity" not in text
    back = Result.read_json(path)
    assert back.extra["constraints"] == json.loads(text)["constraints"]
    (item,) = back.extra["constraints"]["items"]
    np.testing.assert_array_equal(np.array(item["multipliers"]), _multipliers(r)[0])
    assert item["definition"]["world_direction"] == pytest.approx(D.tolist(), abs=1e-16)
    assert back.extra["optimality"]["constraint_violation"] == r.extra["optimality"]["constraint_violation"]


# ------------------------------------------------------------------ multibody


def _arm_target():
    p = space_manipulator(horizon=30, dt=0.1)
    pm = p.model.pin_model
    data = pm.createData()
    pin.framesForwardKinematics(pm, data, np.array([0, 0, 0, 0, 0, 0, 1, 0.6, -0.5, 0.8], dtype=float))
    return p, data.oMf[pm.getFrameId("ee")].copy()


def test_multibody_exact_terminal_pose_with_joint_limits():
    """The space manipulator reaches its end-effector pose exactly (instead of approaching it with a
    weight: the unconstrained solve stops 0.08 away) with the elbow kept below 0.9 rad (the
    unconstrained plan takes it to 1.79): each expansion gives the same KKT point."""
    p, M = _arm_target()
    pm = p.model.pin_model
    i_elbow = pm.joints[pm.getJointId("elbow")].idx_q
    free = solve(p, _opts())
    assert free.q[:, i_elbow].max() > 1.7
    data = pm.createData()
    costs = {}
    for exp in ("second", "switch", "first"):
        cp = ConstrainedProblem(p, [JointLimits(joints={"elbow": [-0.2, 0.9]})], [FramePlacementConstraint("ee", M)])
        r = solve_constrained(cp, _opts(expansion=exp))
        assert r.status == STATUS_KKT, (exp, r.message)
        assert r.q[1:, i_elbow].max() <= 0.9 + TOL
        pin.framesForwardKinematics(pm, data, r.q[-1])
        residual = pin.log6(M.inverse() * data.oMf[pm.getFrameId("ee")]).vector
        assert np.abs(residual).max() <= TOL  # checked with Pinocchio, apart from the constraint's own code
        limits, pose = r.extra["constraints"]["items"]
        assert (limits["where"], pose["where"], pose["equality"]) == ("path", "terminal", True)
        assert np.array(limits["multipliers"]).min() >= 0.0 and limits["active_nodes"] >= 1
        costs[exp] = r.cost
    # 38.82442...: the three agree to 1.7e-7 relative, what violations up to 1e-8 allow with these
    # multipliers (J moves by about lambda . c), not to round-off
    assert max(costs.values()) - min(costs.values()) <= 1e-6 * costs["second"]


# ------------------------------------------------------------------ infeasible problems


def test_a_cone_around_the_initial_boresight_is_infeasible():
    """R_1 = R_0 exp(dt Omega_0) does not depend on the controls (explicit Euler): a cone around
    the initial boresight cannot hold at node 1. The solve says so, with that node's violation as
    the smallest it reached."""
    p = paper_problem(horizon=30)
    d = np.array([1.0, 0.1, 0.0])
    cp = ConstrainedProblem(p, [PointingKeepOut([1.0, 0.0, 0.0], d, 20.0)])
    r = solve_constrained(cp, _opts())
    assert r.status == STATUS_INFEASIBLE and not r.converged
    node1 = 1.0 / np.linalg.norm(d) - np.cos(np.radians(20.0))  # d.(R_1 e_x) / |d| - cos(20 deg), R_1 = I
    report = r.extra["constraints"]
    assert report["smallest_violation"] == pytest.approx(node1, rel=1e-12)
    assert report["max_violation"] == pytest.approx(node1, rel=1e-12)
    assert f"{node1:.3e}" in r.message and "pointing_keep_out" in r.message
    assert np.isfinite(r.cost) and np.all(np.isfinite(r.controls))
    text = json.dumps(r.to_dict(), allow_nan=False)  # strict JSON: raises on NaN or inf
    assert "infeasible" in text
    # the last inner solve is not certified there: the final check alone at its iterate gives the
    # gains and the certificate (Q_uu positive definite: a minimiser of the last merit)
    assert np.all(np.isfinite(r.grad_norm_history)) and np.all(np.isfinite(r.feedback))
    o = r.extra["optimality"]
    assert o["hessian_positive_definite"] and np.isfinite(o["newton_decrease"])
    assert r.extra["optimality"]["lagrangian_stationarity"] == r.grad_norm_history[-1]


def test_an_unreachable_terminal_state_is_infeasible():
    """0.2 s with |u| <= 1 N m cannot turn the satellite by 1.5 rad: the terminal state equality is
    reported infeasible, its violation near 1.5 (the rotation that could not be made)."""
    p = paper_problem(horizon=20, limits=(-1.0, 1.0))
    q = pin.Quaternion(pin.exp3(np.array([0.0, 0.0, 1.5]))).coeffs()
    cp = ConstrainedProblem(p, terminal_constraints=[StateConstraint(q=q, v=np.zeros(3))])
    r = solve_constrained(cp, _opts())
    assert r.status == STATUS_INFEASIBLE and not r.converged
    assert 1.49 < r.extra["constraints"]["smallest_violation"] <= r.extra["constraints"]["max_violation"] < 1.5
    assert np.all(np.abs(r.controls) <= 1.0)  # the box limits held throughout


def test_contradictory_joint_limit_and_terminal_state_are_infeasible():
    p, _ = _arm_target()
    pm = p.model.pin_model
    q_end = pin.neutral(pm)
    q_end[pm.joints[pm.getJointId("elbow")].idx_q] = 0.8
    cp = ConstrainedProblem(p, [JointLimits(joints={"elbow": [-0.1, 0.3]})], [StateConstraint(q=q_end)])
    r = solve_constrained(cp, _opts())
    assert r.status == STATUS_INFEASIBLE and not r.converged
    # the elbow cannot be both <= 0.3 and = 0.8 at the last node: some row stays >= 0.25 away
    assert r.extra["constraints"]["smallest_violation"] >= 0.25 - 1e-6
    json.dumps(r.to_dict(), allow_nan=False)


# ------------------------------------------------------------------ uncertified inner solves


def test_an_uncertified_solve_stops_at_its_test_and_the_check_alone_certifies_it():
    """certify=False (the outer loop's inner solves before the last): the same iterates up to the
    stopping test, no exact pass; check() at the returned controls is the final check of solve()."""
    p = paper_problem(horizon=100)
    opt = _opts(tol=1e-8, expansion="first")
    a = solve(p, opt)
    b = solve(p, opt, certify=False)
    assert a.converged and b.converged and b.extra["optimality"] == {"certified": False}
    assert b.iterations == a.iterations and np.array_equal(b.controls, a.controls)
    assert np.array_equal(b.cost_history, a.cost_history)
    assert np.isnan(b.grad_norm_history[-1]) and b.grad_norm_history.shape == a.grad_norm_history.shape
    c = check(p, opt, b.controls)
    assert c.iterations == 0 and np.array_equal(c.controls, a.controls)
    assert c.extra["optimality"] == a.extra["optimality"]
    assert np.array_equal(c.feedback, a.feedback) and np.array_equal(c.feedforward, a.feedforward)
    assert c.grad_norm == a.grad_norm


# ------------------------------------------------------------------ the unconstrained path, refusals


def test_no_constraints_is_the_unconstrained_solve_bit_for_bit():
    p = paper_problem(horizon=50)
    a = solve(p, _opts(record_controls=True))
    b = solve_constrained(ConstrainedProblem(p), _opts(record_controls=True))
    for f in ("cost_history", "grad_norm_history", "reg_history", "step_history", "controls", "feedback", "q", "v"):
        assert np.array_equal(getattr(a, f), getattr(b, f)), f
    assert a.status == b.status and "constraints" not in b.extra


def test_solve_hands_a_constrained_problem_to_its_outer_loop():
    """geoddp.solve(ConstrainedProblem) is solve_constrained (the same iterates, bit for bit); the
    unconstrained pieces refuse it rather than drop its constraints."""
    cp = ConstrainedProblem(paper_problem(horizon=10), [PointingKeepOut([1, 0, 0], D, 20.0)])
    a, b = solve(cp, _opts()), solve_constrained(cp, _opts())
    assert "constraints" in a.extra and a.cost == b.cost and np.array_equal(a.controls, b.controls)
    assert a.extra["constraints"]["outer_iterations"] == b.extra["constraints"]["outer_iterations"]
    with pytest.raises(InputError, match="solve_constrained") as info:
        cp.linearise(cp.trajectory(np.zeros((10, 3))), 1)
    assert info.value.parameter == "problem"


def test_constrained_problem_refuses_bad_constraints_naming_them():
    p = paper_problem(horizon=10)
    cases = [
        (dict(constraints=[PointingKeepOut([1, 0, 0], D, 20.0), "cone"]), "constraints[1]"),
        (dict(constraints=[StateConstraint(v=np.zeros(3))]), "constraints[0]"),  # an equality on every node
        (dict(terminal_constraints=[StateConstraint(v=np.zeros(4))]), "terminal_constraints[0].v"),
        (dict(constraints=[PointingKeepOut([1, 0, 0], D, 20.0, frame="bsu")]), "constraints[0].frame"),
        (dict(constraints=[JointLimits(joints={"root_joint": [-1, 1]})]), "constraints[0].joints.root_joint"),
        (dict(options={"constraint_tol": -1.0}), "constraint_tol"),
        (dict(options={"penalty_increase": 1.0}), "penalty_increase"),
    ]
    for kw, name in cases:
        with pytest.raises(InputError) as info:
            ConstrainedProblem(p, **kw)
        assert info.value.parameter == name, (kw, info.value)
    with pytest.raises(InputError, match="did you mean 'bus'"):
        ConstrainedProblem(p, [PointingKeepOut([1, 0, 0], D, 20.0, frame="bsu")])
    with pytest.raises(InputError, match="spherical"):
        ConstrainedProblem(p, [JointLimits(joints={"root_joint": [-1, 1]})])
    with pytest.raises(InputError) as info:
        ConstraintOptions(penalty_intial=3.0)
    assert info.value.parameter == "penalty_intial" and "penalty_initial" in str(info.value)
