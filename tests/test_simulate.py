"""Issue 16: flying a plan on a plant (geoddp.simulate): open loop, the DDP gains, MPC.

Every test asserts numbers that a wrong simulator, wrong gains or a wrong chart would break.
"""
from __future__ import annotations

import copy

import numpy as np
import pytest

from geoddp.scene.builtin import scene_spec
from geoddp.problem import paper_problem
from geoddp.scene import build_problem
from geoddp.simulate import (MPC, Disturbances, Plant, SimulationSpec, monte_carlo, plant_from, simulate,
                             simulate_scene)
from geoddp.simulate.errors import Targets
from geoddp.solver import SolverOptions, solve
from geoddp.validate import InputError

TIGHT = SolverOptions(verbose=False, tol=1e-15, grad_tol=1e-13)


@pytest.fixture(scope="module")
def paper():
    p = paper_problem()
    return p, solve(p, TIGHT)


@pytest.fixture(scope="module")
def authors():
    """Table I with the authors' code's control weight 0.1 dt = 0.001 (a tight manoeuvre)."""
    p = paper_problem(S_u=0.001)
    return p, solve(p, SolverOptions(verbose=False))


@pytest.fixture(scope="module")
def quad():
    """The quadrotor scene on a 1 s horizon (50 steps of 0.02 s), solved tightly."""
    spec = scene_spec("quadrotor", horizon=50)
    p = build_problem(spec)
    return p, solve(p, TIGHT, initial_controls=spec.initial_control_sequence())


# ------------------------------------------------------------------ no noise, same plant


@pytest.mark.parametrize("policy", ["open", "feedback"])
@pytest.mark.parametrize("case", ["paper", "quad"])
def test_same_plant_without_noise_reproduces_the_plan(case, policy, request):
    p, r = request.getfixturevalue(case)
    s = simulate(r, p, policy)
    # zeta_k = 0 at every step, so u_k = u_bar_k and the plant (the model, with w = 0 in its extra
    # columns) steps as the plan's rollout did: equal to round-off
    assert np.max(np.abs(s.u - r.controls)) <= 1e-12
    assert np.max(np.abs(np.asarray(s.q) - np.asarray(r.q))) <= 1e-12
    assert np.max(np.abs(s.v - r.v)) <= 1e-12
    assert s.errors["state"] <= 1e-12 and s.errors["tracking_rms"] <= 1e-12
    np.testing.assert_allclose(s.times, r.times, rtol=0, atol=1e-15)


def test_substeps_and_another_integrator_change_the_plant_by_o_dt(authors):
    p, r = authors
    base = simulate(r, p, "open")
    fine = simulate(r, p, "open", plant={"substeps": 10})
    rk4 = simulate(r, p, "open", plant={"integrator": "rk4"})
    # a finer or higher-order discretisation of the same ODE: close to, but not, the plan's Euler
    for s in (fine, rk4):
        assert 1e-6 < s.errors["state"] < 0.05
    # the two continuous-time approximations agree better with each other than with Euler at dt
    d = np.linalg.norm(p.model.local(fine.q[-1], fine.v[-1], rk4.q[-1], rk4.v[-1]))
    assert d < 0.2 * fine.errors["state"]
    assert Plant(p.model, substeps=10).dt == pytest.approx(0.001)
    assert base.errors["state"] <= 1e-12


# ------------------------------------------------------------------ the gains


def _gain_errors(p, r, d, eps_list):
    """|closed-loop terminal state - re-solved optimum's| and the same for open loop, per eps."""
    m = p.model
    out = []
    for eps in eps_list:
        q0, v0 = m.retract(p.q0, p.v0, eps * d)
        pp = copy.copy(p)
        pp.q0, pp.v0 = q0, v0
        ro = solve(pp, TIGHT, initial_controls=r.controls)
        assert ro.converged
        cl = simulate(r, p, "feedback", initial_state=(q0, v0))
        ol = simulate(r, p, "open", initial_state=(q0, v0))
        out.append((np.linalg.norm(m.local(ro.q[-1], ro.v[-1], cl.q[-1], cl.v[-1])),
                    np.linalg.norm(m.local(ro.q[-1], ro.v[-1], ol.q[-1], ol.v[-1]))))
    return np.array(out)


@pytest.mark.parametrize("case", ["paper", "quad"])
def test_the_gains_are_right_to_second_order(case, request):
    p, r = request.getfixturevalue(case)
    rng = np.random.default_rng(3)
    d = rng.standard_normal(p.nx)
    d /= np.linalg.norm(d)
    eps = [2e-2, 1e-2, 5e-3] if case == "paper" else [1e-2, 5e-3, 2.5e-3]
    e = _gain_errors(p, r, d, eps)
    closed, open_ = e[:, 0], e[:, 1]
    # closed loop: O(eps^2) (the gains are the optimal policy's derivative): 4x per halving
    ratios = closed[:-1] / closed[1:]
    assert np.all((ratios > 3.5) & (ratios < 4.5)), ratios
    # open loop misses to first order (2x per halving) and is far worse
    assert np.all(np.abs(open_[:-1] / open_[1:] - 2.0) < 0.2)
    assert np.all(closed < 0.1 * open_)


# ------------------------------------------------------------------ the authors' noise test


def test_authors_scene_has_the_stated_optimum():
    from geoddp import solve_scene

    r = solve_scene("satellite_authors_code", verbose=False)
    assert r.converged
    assert r.cost == pytest.approx(6.0451953285, abs=5e-11)


def test_authors_noise_test_90_samples():
    mc = simulate_scene("satellite_authors_code", SimulationSpec(samples=90, seed=0, noise=0.001))
    st = mc.statistics()
    assert mc.policies == ("open", "feedback") and len(mc.runs["open"]) == 90
    open_mean, closed_mean = st["open.attitude_rad.mean"], st["feedback.attitude_rad.mean"]
    # the authors: open loop mean ~0.0445 rad (max ~0.099), closed loop mean ~6.0e-4 (max ~1.5e-3)
    assert open_mean >= 20 * closed_mean
    assert 3.0e-4 <= closed_mean <= 1.2e-3
    assert 0.02 <= open_mean <= 0.09
    # common random numbers: the open-loop effort is the plan's, the same in every sample
    eff = mc.measures("open")["effort"]
    assert np.ptp(eff) <= 1e-9 * eff[0]


def test_monte_carlo_is_reproducible_and_samples_are_independent_of_n(authors):
    p, r = authors
    dist = Disturbances(velocity_noise=0.001)
    a = monte_carlo(r, p, samples=4, seed=7, disturbances=dist)
    b = monte_carlo(r, p, samples=4, seed=7, disturbances=dist)
    c = monte_carlo(r, p, samples=6, seed=7, disturbances=dist)
    d = monte_carlo(r, p, samples=4, seed=8, disturbances=dist)
    for pol in ("open", "feedback"):
        for i in range(4):
            np.testing.assert_array_equal(a.runs[pol][i].v, b.runs[pol][i].v)
            np.testing.assert_array_equal(a.runs[pol][i].v, c.runs[pol][i].v)  # sample i does not depend on N
            assert not np.array_equal(a.runs[pol][i].v, d.runs[pol][i].v)
        # independent streams: different samples see different noise
        assert not np.array_equal(a.runs[pol][0].v, a.runs[pol][1].v)
    assert a.statistics()["feedback.attitude_rad.mean"] == b.statistics()["feedback.attitude_rad.mean"]
    # the noise has the requested law: v_{k+1} - f(x_k, u_k) ~ N(0, 0.001^2) in the open-loop run
    run = a.runs["open"][0]
    steps = np.array([p.model.rollout(run.q[k], run.v[k], run.u[k:k + 1])[1][-1] for k in range(r.horizon)])
    noise = run.v[1:] - steps
    assert 0.0008 < noise.std() < 0.0012 and abs(noise.mean()) < 3e-4


# ------------------------------------------------------------------ disturbances


def test_constant_torque_and_impulse_enter_as_generalised_forces(authors):
    p, r = authors
    w = np.array([0.3, -0.2, 0.1])
    s = simulate(r, p, "open", disturbances=Disturbances(wrench=w, wrench_start=1.0, wrench_duration=0.5))
    U = r.controls.copy()
    U[100:150] += w  # actuation = I: a body torque w adds to H u on steps [1 s, 1.5 s)
    Q, V = p.model.rollout(p.q0, p.v0, U)
    assert np.max(np.abs(s.q - Q)) <= 1e-12 and np.max(np.abs(s.v - V)) <= 1e-12
    J = np.array([0.02, 0.0, -0.01])  # N m s at t = 2.005 s: torque J / dt over step 200
    s = simulate(r, p, "open", disturbances=Disturbances(impulses=((2.005, J),)))
    U = r.controls.copy()
    U[200] += J / p.dt
    Q, V = p.model.rollout(p.q0, p.v0, U)
    assert np.max(np.abs(s.v - V)) <= 1e-12
    np.testing.assert_allclose(s.v[201] - s.v[200] - (r.v[201] - r.v[200]), np.linalg.solve(p.model.inertia, J),
                               rtol=1e-9)


def test_sensor_noise_reaches_only_the_feedback_policy(authors):
    p, r = authors
    dist = Disturbances(sensor_noise=1e-3)
    ol = simulate(r, p, "open", disturbances=dist, seed=1)
    fb = simulate(r, p, "feedback", disturbances=dist, seed=1)
    assert ol.errors["state"] <= 1e-12  # open loop ignores the measurement
    assert fb.errors["state"] > 1e-5 and np.max(np.abs(fb.u - r.controls)) > 1e-3


def test_force_noise_and_velocity_noise_on_a_multibody(quad):
    p, r = quad
    fb = simulate(r, p, "feedback", disturbances=Disturbances(force_noise=0.05, velocity_noise=1e-3), seed=2)
    ol = simulate(r, p, "open", disturbances=Disturbances(force_noise=0.05, velocity_noise=1e-3), seed=2)
    assert fb.errors["tracking_rms"] < 0.5 * ol.errors["tracking_rms"]
    assert set(fb.errors) >= {"position_m", "attitude_rad", "state", "tracking_rms", "effort"}


# ------------------------------------------------------------------ model error


@pytest.mark.parametrize("change", [{"inertia_scale": 1.2}, {"inertia_scale": 0.8}, {"mass_scale": 1.2}])
def test_twenty_percent_inertia_error_feedback_and_mpc_reach_the_target(authors, change):
    p, r = authors
    TOL = 0.01  # rad: the stated tolerance on the terminal attitude error (the plan's own: 4.6e-4)
    ol = simulate(r, p, "open", plant=change)
    fb = simulate(r, p, "feedback", plant=change)
    mpc = simulate(r, p, "mpc", plant=change, horizon=100, max_iter=3, shrink=True)
    assert ol.errors["attitude_rad"] > 0.15
    assert fb.errors["attitude_rad"] < TOL
    assert mpc.errors["attitude_rad"] < TOL


def test_mass_error_on_the_quadrotor(quad):
    p, r = quad
    ol = simulate(r, p, "open", plant={"mass_scale": 1.2})
    fb = simulate(r, p, "feedback", plant={"mass_scale": 1.2})
    plan = Targets(p).terminal(r.q[-1], r.v[-1])["position_m"]
    # 20 % heavier: open loop sinks ~1 m below the plan's end; the gains keep it within 0.1 m of it
    assert ol.errors["state"] > 1.0
    assert abs(fb.errors["position_m"] - plan) < 0.1 and fb.errors["state"] < 0.5 * ol.errors["state"]


def test_plant_changes_reach_the_model():
    p = paper_problem()
    pl = Plant(p.model, inertia_scale=[1.0, 1.2, 0.9], actuator_gain=[1.0, 0.5, 2.0])
    np.testing.assert_allclose(np.diag(pl.stepper.inertia), np.diag(p.model.inertia) * [1.0, 1.2, 0.9])
    np.testing.assert_allclose(pl.stepper.actuation, np.hstack([np.diag([1.0, 0.5, 2.0]), np.eye(3)]))
    assert pl.changed == {"inertia_scale": [1.0, 1.2, 0.9], "actuator_gain": [1.0, 0.5, 2.0]}
    q = build_problem(scene_spec("quadrotor", horizon=5))
    pq = Plant(q.model, mass_scale=1.2)
    m0 = sum(q.model.pin_model.inertias[j].mass for j in range(1, q.model.pin_model.njoints))
    m1 = sum(pq.stepper.pin_model.inertias[j].mass for j in range(1, pq.stepper.pin_model.njoints))
    assert m1 == pytest.approx(1.2 * m0, rel=1e-14)
    assert q.model.pin_model.inertias[1].mass == pytest.approx(m0)  # the plan's model is untouched


# ------------------------------------------------------------------ MPC


def test_mpc_on_a_static_target_converges_and_holds_it(authors):
    p, r = authors
    s = simulate(r, p, "mpc", steps=500, horizon=100, max_iter=3)
    T = Targets(p)
    err = np.array([T.terminal(s.q[k], s.v[k])["attitude_rad"] for k in range(len(s.q))])
    rate = np.linalg.norm(s.v, axis=1)
    assert err[0] > 1.0  # it starts 75 deg away
    assert np.all(err[400:] < 1e-3) and np.all(rate[400:] < 2e-3)  # converged and held for the last 1 s
    assert err[-1] < 3e-4
    st = s.stats
    assert st["solves"] == 500 and st["iterations_max"] <= 3
    assert len(st["solve_times_s"]) == 500 and st["real_time_factor"] > 0


def test_mpc_reuses_the_built_problem(monkeypatch, quad):
    import pinocchio as pin

    import geoddp.models.multibody as mbm
    import geoddp.problem as prob
    import geoddp.scene.build as sb
    import geoddp.scene.load as sl

    p, r = quad
    mpc = MPC(p, horizon=20, every=2, max_iter=2, plan=r)
    plant = Plant(p.model)  # built once, before the loop (it builds its own stepping model)
    counts = {"urdf": 0, "build": 0, "validate": 0}

    def counting(key, fn):
        def wrapped(*a, **k):
            counts[key] += 1
            return fn(*a, **k)
        return wrapped

    monkeypatch.setattr(pin, "buildModelFromUrdf", counting("urdf", pin.buildModelFromUrdf))
    monkeypatch.setattr(mbm, "build_checked_model", counting("urdf", mbm.build_checked_model))
    monkeypatch.setattr(sb, "_multibody", counting("build", sb._multibody))  # the one builder's two backends
    monkeypatch.setattr(sb, "_on_tso3", counting("build", sb._on_tso3))
    monkeypatch.setattr(sl, "_dispatch", counting("build", sl._dispatch))  # every scene read (file or dict)
    monkeypatch.setattr(prob.Problem, "__post_init__", counting("validate", prob.Problem.__post_init__))
    s = simulate(r, p, mpc, plant=plant, steps=10)
    assert counts == {"urdf": 0, "build": 0, "validate": 0}
    assert s.stats["solves"] == 5 and s.stats["every"] == 2
    assert mpc.problem.model is p.model and mpc.problem.running is p.running  # one model, one set of costs
    assert p.horizon == 50 and np.array_equal(p.q0, r.q[0])  # the plan's problem is not changed
    # the counters work: building a plant parses the URDF; loading and building a scene are counted
    Plant(p.model, mass_scale=1.1)
    assert counts["urdf"] == 1
    from geoddp.scene import build_problem as build, load_scene

    build(load_scene("quadrotor"))  # read (1), the TSO(3) backend declines (2), the general one builds (3)
    assert counts["build"] == 3 and counts["validate"] == 1 and counts["urdf"] >= 2


def test_mpc_warm_start_shifts_and_repeats_the_last_control(authors):
    p, r = authors
    mpc = MPC(p, horizon=50, every=5, max_iter=1, plan=r)
    mpc.control(0, p.q0, p.v0)
    prev = mpc._sol.controls.copy()
    U = mpc._warm_start(5, 50)
    np.testing.assert_array_equal(U[:45], prev[5:])
    np.testing.assert_array_equal(U[45:], np.repeat(prev[-1:], 5, axis=0))
    np.testing.assert_array_equal(mpc._first, r.controls[:50])


# ------------------------------------------------------------------ bad input


@pytest.mark.parametrize("call, name", [
    (lambda p, r: simulate(r, p, "closed"), "policy"),
    (lambda p, r: simulate(r, p, "open", plant={"inertia": 2}), "plant.inertia"),
    (lambda p, r: simulate(r, p, "open", plant={"inertia_scale": -1}), "plant.inertia_scale"),
    (lambda p, r: simulate(r, p, "open", plant={"substeps": 0}), "plant.substeps"),
    (lambda p, r: simulate(r, p, "open", plant={"integrator": "rk5"}), "plant.integrator"),
    (lambda p, r: simulate(r, p, "feedback", steps=301), "steps"),
    (lambda p, r: simulate(r, p, "open", disturbances=Disturbances(velocity_noise=-1)), "disturbances.velocity_noise"),
    (lambda p, r: simulate(r, p, "open", disturbances=Disturbances(wrench=[1, 2])), "disturbances.wrench"),
    (lambda p, r: simulate(r, p, "open", disturbances={"velocity_noise": 1}), "disturbances"),
    (lambda p, r: simulate(r, p, "mpc", horizon=0), "mpc.horizon"),
    (lambda p, r: simulate(r, p, "mpc", horizon=10, every=11), "mpc.every"),
    (lambda p, r: simulate("plan", p), "result"),
    (lambda p, r: monte_carlo(r, p, samples=0), "samples"),
    (lambda p, r: monte_carlo(r, p, samples=2, seed=-1), "seed"),
    (lambda p, r: monte_carlo(r, p, samples=2, workers=0), "workers"),
    (lambda p, r: SimulationSpec(policy="mcp"), "simulation.policy"),
    (lambda p, r: SimulationSpec.from_dict({"sample": 3}), "simulation.sample"),
    (lambda p, r: plant_from(p.model, {"mass": 2}), "plant.mass"),
    # a misspelt keyword, or an MPC option with no MPC policy, would have been ignored
    (lambda p, r: simulate(r, p, "feedback", seeed=3), "seeed"),
    (lambda p, r: simulate(r, p, "mpc", horizn=10), "horizn"),
    (lambda p, r: simulate(r, p, "feedback", horizon=10), "horizon"),
    (lambda p, r: monte_carlo(r, p, sample=3), "sample"),
    (lambda p, r: monte_carlo(r, p, samples=2, policies=["open", "feedback"], every=2), "every"),
    (lambda p, r: Disturbances(velocity_nois=0.1), "velocity_nois"),
    (lambda p, r: Plant(p.model, inertia_scal=1.1), "inertia_scal"),
    (lambda p, r: SimulationSpec(sampels=3), "sampels"),
    (lambda p, r: MPC(None), "problem"),
])
def test_bad_input_names_the_parameter(paper, call, name):
    p, r = paper
    with pytest.raises(InputError) as exc:
        call(p, r)
    assert exc.value.parameter == name


def test_satellite_chart_round_trip_and_the_kernels_zeta():
    import pinocchio as pin

    m = paper_problem().model
    rng = np.random.default_rng(0)
    R, Om = pin.exp3(rng.standard_normal(3)), rng.standard_normal(3)
    zeta = 0.5 * rng.standard_normal(6)
    R1, Om1 = m.retract(R, Om, zeta)
    np.testing.assert_allclose(m.local(R, Om, R1, Om1), zeta, atol=1e-13)
    np.testing.assert_allclose(m.local(R, Om, R1, Om1)[:3], pin.log3(R.T @ R1), atol=1e-13)


def test_monte_carlo_in_two_processes_gives_the_same_numbers(authors):
    p, r = authors
    dist = Disturbances(velocity_noise=0.001, sensor_noise=1e-4)
    a = monte_carlo(r, p, samples=5, seed=11, disturbances=dist)
    b = monte_carlo(r, p, samples=5, seed=11, disturbances=dist, workers=2)
    for pol in ("open", "feedback"):
        for x, y in zip(a.runs[pol], b.runs[pol]):
            np.testing.assert_array_equal(x.q, y.q)
            np.testing.assert_array_equal(x.u, y.u)
    assert a.statistics()["feedback.attitude_rad.p95"] == b.statistics()["feedback.attitude_rad.p95"]


@pytest.mark.parametrize("fields, name", [
    ({"noise": -0.1}, "simulation.noise"), ({"noise": "big"}, "simulation.noise"),
    ({"sensor_noise": [[1.0]]}, "simulation.sensor_noise"), ({"wrench": [1.0, float("nan")]}, "simulation.wrench"),
    ({"wrench_start": -1}, "simulation.wrench_start"), ({"mpc_horizon": 0}, "simulation.mpc_horizon"),
    ({"mpc_every": 1.5}, "simulation.mpc_every"), ({"plant": {"substeps": 0}}, "simulation.plant.substeps"),
    ({"plant": {"mass_scale": 0}}, "simulation.plant.mass_scale"), ({"plant": {"integrator": 4}}, "simulation.plant.integrator"),
    ({"compare_open_loop": 1}, "simulation.compare_open_loop"), ({"workers": 0}, "simulation.workers"),
])
def test_simulation_spec_validates_every_field(fields, name):
    with pytest.raises(InputError) as exc:
        SimulationSpec(**fields)
    assert exc.value.parameter == name


def test_mpc_windows_recede_or_shrink_to_the_plan_end(authors):
    p, r = authors
    shrink = MPC(p, horizon=100, every=50, max_iter=1, shrink=True, plan=r)
    simulate(r, p, shrink, steps=300)
    assert shrink.windows == [100, 100, 100, 100, 100, 50]  # window k .. min(k + 100, H = 300)
    recede = MPC(p, horizon=100, every=50, max_iter=1, plan=r)
    simulate(r, p, recede, steps=350)
    assert recede.windows == [100] * 7
    # between re-solves the policy is the latest solution's feedback law: with the model as the
    # plant and no noise, zeta = 0 and the applied controls are that solution's
    mpc = MPC(p, horizon=60, every=4, max_iter=2, plan=r)
    s = simulate(r, p, mpc, steps=4)
    np.testing.assert_array_equal(s.u, mpc._sol.controls[:4])
