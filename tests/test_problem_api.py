"""The Problem as users meet it: a clear error for a model that is not a geoddp model (a bare
pin.Model says how to wrap it), and with_initial_state (a new problem from another initial state,
validated, the original unchanged), which MPC re-solves from."""
from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from geoddp import Problem, SolverOptions, solve
from geoddp.constraints import ConstrainedProblem, solve_constrained
from geoddp.models.multibody import Multibody
from geoddp.problem import paper_problem
from geoddp.scene import build_problem, load_scene
from geoddp.simulate import MPC, simulate
from geoddp.validate import InputError

QUIET = SolverOptions(max_iter=30)


def _same_run(a, b) -> None:
    assert a.iterations == b.iterations and a.status == b.status
    np.testing.assert_array_equal(a.cost_history, b.cost_history)
    np.testing.assert_array_equal(a.controls, b.controls)
    np.testing.assert_array_equal(a.feedback, b.feedback)


# ------------------------------------------------------------------ the model a Problem takes

def _arm() -> pin.Model:
    return pin.buildSampleModelManipulator()


def test_a_bare_pin_model_is_refused_with_how_to_wrap_it():
    pm = _arm()
    with pytest.raises(InputError) as info:
        Problem(pm, pin.neutral(pm), np.zeros(pm.nv), 10, None, None)
    e = info.value
    assert e.parameter == "model"
    assert "got a bare pinocchio.Model" in e.detail
    assert "from geoddp.models.multibody import Multibody; model = Multibody.from_model(model, dt=0.01)" in e.detail
    # what it says works: the wrapped model makes a problem
    from geoddp.costs.multibody import ControlRegularisation, MultibodyCostSum, StateRegularisation

    mb = Multibody.from_model(pm, dt=0.01)
    running = MultibodyCostSum([ControlRegularisation(np.zeros(mb.nu))], model=mb.pin_model)
    terminal = MultibodyCostSum([StateRegularisation(mb.pin_model, pin.neutral(pm), W=np.ones(2 * pm.nv))],
                                model=mb.pin_model, terminal=True)
    p = Problem(mb, pin.neutral(pm), np.zeros(pm.nv), 10, running, terminal)
    assert p.nu == pm.nv and p.nx == 2 * pm.nv
    assert solve(p, QUIET).converged


@pytest.mark.parametrize("make, says", [
    (lambda pm: pm.createData(), "got a pinocchio.Data (a model's workspace); wrap the pinocchio.Model: "
                                 "from geoddp.models.multibody import Multibody; model = Multibody.from_model(model"),
    (lambda pm: pin.RobotWrapper(pm), "got a RobotWrapper; wrap its pinocchio.Model and visuals: from "
                                      "geoddp.models.multibody import Multibody; model = Multibody.from_model("
                                      "robot.model, robot.visual_model, dt=0.01)"),
    (lambda pm: "arm.urdf", "got the path 'arm.urdf'; load the URDF: from geoddp.models.multibody import Multibody; "
                            'model = Multibody(path, root="fixed", dt=0.01)'),
    (lambda pm: None, "got NoneType; from a pinocchio.Model: from geoddp.models.multibody import Multibody"),
])
def test_other_wrong_models_are_named_with_a_way_out(make, says):
    pm = _arm()
    with pytest.raises(InputError) as info:
        Problem(make(pm), pin.neutral(pm), np.zeros(pm.nv), 10, None, None)
    assert info.value.parameter == "model" and says in info.value.detail


def test_a_model_missing_part_of_the_contract_is_told_which_part():
    class Half:
        nx, nu, dt = 6, 3, 0.01

        def check_state(self, q, v, name="initial"):
            return q, v

    with pytest.raises(InputError, match=r"^model: .*got Half \(it has no rollout, rollout_closed_loop, expansion, "
                                         r"description\)"):
        Problem(Half(), np.eye(3), np.zeros(3), 10, None, None)


# ------------------------------------------------------------------ with_initial_state

R1 = pin.exp3(np.array([0.3, -0.2, 0.5]))
W1 = np.array([0.05, -0.02, 0.01])


def test_satellite_with_initial_state_is_the_problem_built_from_that_state():
    p = paper_problem()
    R0, Om0 = p.q0.copy(), p.v0.copy()
    moved = p.with_initial_state(R1, W1)
    assert moved is not p and moved.model is p.model and moved.running is p.running and moved.terminal is p.terminal
    np.testing.assert_array_equal(p.q0, R0)  # the original is unchanged
    np.testing.assert_array_equal(p.v0, Om0)
    np.testing.assert_array_equal(moved.R0, R1)
    np.testing.assert_array_equal(moved.Omega0, W1)
    _same_run(solve(moved, QUIET), solve(paper_problem(R0=R1, Omega0=W1), QUIET))
    assert solve(moved, QUIET).cost != solve(p, QUIET).cost


@pytest.mark.parametrize("q0, v0, name, says", [
    (np.eye(4), W1, "q0", "expected shape (3, 3)"),
    (np.diag([1.0, 1.0, -1.0]), W1, "q0", "(a reflection)"),
    (1.01 * np.eye(3), W1, "q0", "expected an orthonormal 3x3 rotation matrix"),
    (np.full((3, 3), np.nan), W1, "q0", "expected finite numbers"),
    (R1, np.zeros(4), "v0", "expected shape (3,)"),
    (R1, [0.0, np.inf, 0.0], "v0", "expected finite numbers"),
])
def test_satellite_with_initial_state_names_q0_or_v0(q0, v0, name, says):
    p = paper_problem()
    with pytest.raises(InputError) as info:
        p.with_initial_state(q0, v0)
    assert info.value.parameter == name and says in info.value.detail


@pytest.fixture(scope="module")
def quadrotor():
    spec = load_scene("quadrotor")
    return spec, build_problem(spec)


def test_multibody_with_initial_state_is_the_problem_built_from_that_state(quadrotor):
    spec, p = quadrotor
    q1 = p.q0.copy()
    q1[:3] += [0.2, -0.1, 0.3]
    q1[3:7] = pin.Quaternion(pin.exp3(np.array([0.1, 0.05, 0.0]))).coeffs()
    v1 = np.linspace(-0.2, 0.2, p.model.nv)
    q_before = p.q0.copy()
    moved = p.with_initial_state(q1, v1)
    np.testing.assert_array_equal(p.q0, q_before)
    fresh = Problem(p.model, q1, v1, p.horizon, p.running, p.terminal, p.limits)
    U0 = moved.quasi_static_controls()
    _same_run(solve(moved, QUIET, initial_controls=U0), solve(fresh, QUIET, initial_controls=U0))
    assert moved.total_cost(U0) != p.total_cost(U0)


@pytest.mark.parametrize("change, name, says", [
    (lambda q, v: (q[:-1], v), "q0", "expected shape (7,)"),
    (lambda q, v: (np.r_[q[:3], 0.5, 0.0, 0.0, 0.5], v), "q0", "expected unit quaternions"),
    (lambda q, v: (q, np.r_[v[:-1], np.nan]), "v0", "expected finite numbers"),
    (lambda q, v: (q, v[:3]), "v0", "expected shape (6,)"),
])
def test_multibody_with_initial_state_names_q0_or_v0(quadrotor, change, name, says):
    _, p = quadrotor
    with pytest.raises(InputError) as info:
        p.with_initial_state(*change(p.q0, p.v0))
    assert info.value.parameter == name and says in info.value.detail


def test_constrained_problem_with_initial_state_keeps_its_constraints():
    spec = load_scene("satellite_keep_out")
    cp = build_problem(spec)
    R0 = cp.problem.q0.copy()
    R_start = pin.exp3(np.array([0.0, 0.0, -0.2]))
    moved = cp.with_initial_state(R_start, np.zeros(3))
    assert isinstance(moved, ConstrainedProblem) and moved.placed is cp.placed and moved.options is cp.options
    np.testing.assert_array_equal(cp.problem.q0, R0)  # the original is unchanged
    opt = SolverOptions(tol=spec.tol, grad_tol=spec.grad_tol)
    fresh = ConstrainedProblem(cp.problem.with_initial_state(R_start, np.zeros(3)), cp.constraints,
                               cp.terminal_constraints, cp.options)
    a, b = solve_constrained(moved, opt), solve_constrained(fresh, opt)
    _same_run(a, b)
    assert a.converged and a.extra["constraints"]["max_violation"] <= spec.constraint_tol
    with pytest.raises(InputError, match="^q0: "):
        cp.with_initial_state(np.eye(2), np.zeros(3))


# ------------------------------------------------------------------ MPC re-solves with it

def test_mpc_starts_each_resolve_with_with_initial_state(monkeypatch):
    p = paper_problem(S_u=0.001)
    plan = solve(p, SolverOptions())
    seen = []
    real = Problem.with_initial_state

    def spy(self, q0, v0):
        seen.append((self.horizon, np.array(q0), np.array(v0)))
        return real(self, q0, v0)

    monkeypatch.setattr(Problem, "with_initial_state", spy)
    s = simulate(plan, p, MPC(p, horizon=40, every=5, max_iter=1, plan=plan), steps=20)
    assert [h for h, _, _ in seen] == [40] * 4  # one per re-solve, on the window's problem
    for j, (_, q, v) in enumerate(seen):  # from the measured state at k = 0, 5, 10, 15
        np.testing.assert_array_equal(q, s.q[5 * j])
        np.testing.assert_array_equal(v, s.v[5 * j])


def test_mpc_with_control_limits_keeps_every_control_inside():
    """The windows take the plan's limits at their own horizon (the shallow copy of the plan's
    problem kept the plan's (H, m) bounds: a shorter window failed to broadcast)."""
    spec = load_scene("satellite_wheel_limits")  # |u_i| <= 5 N m; the plan saturates axis 3
    p = build_problem(spec)
    plan = solve(p, SolverOptions(tol=spec.tol))
    # re-solved at every step: every applied control is a re-solve's first (between re-solves the
    # feedback law, like the plan's gains, is not clamped)
    s = simulate(plan, p, "mpc", horizon=50, every=1, max_iter=3, steps=60, plant={"inertia_scale": 1.2})
    assert s.stats["solves"] == 60 and s.stats["iterations_max"] <= 3
    assert np.abs(s.u).max() == 5.0 and np.all(np.abs(s.u[:20]) == 5.0)  # on the bounds, never beyond
    per_node = p.with_limits((np.linspace(-5, -4, p.horizon)[:, None] * np.ones(3), 5.0))
    with pytest.raises(InputError, match=r"^policy: MPC needs time-invariant control limits"):
        MPC(per_node, horizon=50)
