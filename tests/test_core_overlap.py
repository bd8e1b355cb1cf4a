"""The forward pass feeding the next first-order expansion (geoddp._core.rollout_closed_loop_expanding).

After a first-order linearisation, a compiled multibody problem's forward pass runs on the core's
first worker while its second worker expands, at order 1, the nodes the pass has written; the
linearisation of the trajectory the line search keeps finishes the rest (expansion_rest). These
tests assert that nothing changes but the time:

* the trial's states and controls are bitwise those of rollout_closed_loop, with and without
  control limits, for every integrator;
* the prefix's Phi, B (nodes 0 .. d-1), and the completed expansion, are bitwise those of
  expansion(order=1), and the prefix really ran (d > 0 on a 2-worker machine);
* with one worker (threads = 1) there is no prefix and the expansion is still the same;
* a failed pass gives no prefix; expansion_rest checks its arguments;
* whole solves (first order and switch) give the same iterates, bit for bit, with the overlap on
  and off (the solver's histories).
"""
import numpy as np
import pinocchio as pin
import pytest

from urdfs import urdf as urdf_file
from geoddp.models import compiled
from geoddp.models.multibody import Multibody
from geoddp.problem import Problem
from geoddp.solver import SolverOptions, solve
from geoddp.solver.backward import Workspace, backward

if not compiled.available():  # pragma: no cover - the build is part of the install
    pytest.fail(f"geoddp._core does not import: {compiled.IMPORT_ERROR}", pytrace=False)

core = compiled._core
CASES = [
    ("quadrotor.urdf", "free_flyer", True),
    ("space_manipulator.urdf", "fixed", True),
    ("satellite.urdf", "spherical", False),
    ("test_all_joints.urdf", "fixed", True),
]
IDS = [f"{u.split('.')[0]}-{r}" for u, r, _ in CASES]
INTEGRATORS = ["euler", "semi_implicit", "rk4", "variational"]


def _problem(case, integrator, H=40, limits=None, threads=0):
    from geoddp.multibody_costs import ControlRegularisation, MultibodyCostSum, StateRegularisation

    urdf, root, gravity = case
    mb = Multibody(urdf_file(urdf), root=root, dt=0.01, integrator=integrator, gravity=gravity, threads=threads)
    assert mb.backend == "compiled" and mb.overlaps_first_order
    rng = np.random.default_rng(5)
    q0 = pin.integrate(mb.pin_model, mb.neutral(), 0.5 * rng.normal(size=mb.nv))
    v0 = 0.3 * rng.normal(size=mb.nv)
    running = MultibodyCostSum([ControlRegularisation(np.zeros(mb.nu), W=np.full(mb.nu, 1e-2)),
                                StateRegularisation(mb.pin_model, mb.neutral(), W=np.ones(2 * mb.nv))],
                               model=mb.pin_model)
    terminal = MultibodyCostSum([StateRegularisation(mb.pin_model, mb.neutral(), W=np.full(2 * mb.nv, 10.0))],
                                model=mb.pin_model, terminal=True)
    return Problem(mb, q0, v0, H, running, terminal, limits=limits)


def _step_gains(p):
    """A nominal, its first-order linearisation and gains of a regularised pass (as the solver)."""
    U = 0.1 * np.random.default_rng(6).normal(size=(p.horizon, p.nu))
    if p.control_bounds() is not None:
        U = np.clip(U, *p.control_bounds())
    traj = p.trajectory(U)
    lin = p.linearise(traj, 1)
    ws = Workspace(p.horizon, p.nu, p.nx, p.control_bounds())
    backward(lin, ws, 1e-3, traj.u)
    return traj, ws.k.copy(), ws.K.copy()


@pytest.mark.parametrize("integrator", INTEGRATORS)
@pytest.mark.parametrize("case", CASES, ids=IDS)
@pytest.mark.parametrize("limited", [False, True], ids=["free", "limits"])
def test_overlapped_trial_and_expansion_are_bitwise_the_plain_ones(case, integrator, limited):
    p = _problem(case, integrator, limits=(-0.5, 0.5) if limited else None)
    traj, k, K = _step_gains(p)
    assert p._first_order_next  # set by the first-order linearisation
    trial = p.rollout_policy(traj, k, K, 1.0)
    assert trial is not None and trial.precomputed is not None
    exp, d = trial.precomputed
    assert 0 <= d <= p.horizon  # how far the second worker got is timing (see the test below)
    mb = p.model
    code = compiled.INTEGRATORS[integrator]
    Phi, B, *_ = core.expansion(mb.pin_model, mb.actuation, mb.dt, code, trial.q, trial.v, trial.u, 1, 1)
    assert np.array_equal(exp.Phi[:d], Phi[:d]) and np.array_equal(exp.B[:d], B[:d])
    lin = p.linearise(trial, 1)  # completes the prefix
    assert lin.Phi is exp.Phi and np.array_equal(lin.Phi, Phi) and np.array_equal(lin.B, B)
    # the trial is the plain forward pass's, bit for bit
    p._first_order_next = False
    plain = p.rollout_policy(traj, k, K, 1.0)
    assert plain.precomputed is None
    for a, b in ((trial.q, plain.q), (trial.v, plain.v), (trial.u, plain.u)):
        assert np.array_equal(a, b)
    if limited:
        lo, hi = p.control_bounds()
        assert np.all(trial.u >= lo) and np.all(trial.u <= hi) and np.any((trial.u == hi) | (trial.u == lo))
    # and the linearisation too, cost terms included
    lin_plain = p.linearise(plain, 1)
    for name in ("Phi", "B", "l_x", "l_u", "l_xx", "l_ux", "l_uu", "lf_x", "lf_xx"):
        assert np.array_equal(getattr(lin, name), getattr(lin_plain, name)), name


@pytest.mark.skipif(core.default_threads() < 2, reason="one core: the pass has no second worker")
def test_the_second_worker_expands_while_the_pass_runs():
    # timing decides how many nodes the second worker finishes before the pass returns (none when
    # it wakes late); over 30 passes of 200 nodes, some must have a prefix, or the overlap is dead
    p = _problem(CASES[1], "semi_implicit", H=200)
    traj, k, K = _step_gains(p)
    done = [p.rollout_policy(traj, k, K, 1.0).precomputed[1] for _ in range(30)]
    assert max(done) > 0 and max(done) <= p.horizon


def test_one_worker_gives_no_prefix_and_the_same_expansion():
    p = _problem(CASES[0], "semi_implicit", threads=1)
    traj, k, K = _step_gains(p)
    trial = p.rollout_policy(traj, k, K, 0.5)
    exp, d = trial.precomputed
    assert d == 0
    lin = p.linearise(trial, 1)
    mb = p.model
    Phi, B, *_ = core.expansion(mb.pin_model, mb.actuation, mb.dt, 1, trial.q, trial.v, trial.u, 1, 1)
    assert np.array_equal(lin.Phi, Phi) and np.array_equal(lin.B, B)


def test_second_order_linearisation_stops_the_overlap():
    p = _problem(CASES[1], "semi_implicit")
    traj, k, K = _step_gains(p)
    p.linearise(traj, 2)
    assert not p._first_order_next
    assert p.rollout_policy(traj, k, K, 1.0).precomputed is None


def test_a_failed_pass_gives_no_prefix_and_rest_checks_its_arguments():
    p = _problem(CASES[0], "semi_implicit")
    traj, k, K = _step_gains(p)
    mb = p.model
    H, m = p.horizon, p.nu
    q, v, u = np.empty(traj.q.shape), np.empty(traj.v.shape), np.empty(traj.u.shape)
    with np.errstate(all="ignore"):
        ok, Phi, B, d = core.rollout_closed_loop_expanding(
            mb.pin_model, mb.actuation, mb.dt, 1, p.q0, p.v0, traj.q, traj.v, traj.u, np.full((H, m), 1e308), K,
            -1e10, q, v, u)
    assert not ok and d == 0
    with np.errstate(all="ignore"):
        assert p.rollout_policy(traj, np.full((H, m), 1e308), K, -1e10) is None
    n = p.nx
    Phi, B = np.zeros((H, n, n)), np.zeros((H, n, m))
    for first in (-1, H + 1):
        with pytest.raises(ValueError, match="first"):
            core.expansion_rest(mb.pin_model, mb.actuation, mb.dt, 1, traj.q, traj.v, traj.u, Phi, B, first)
    with pytest.raises(ValueError, match="Phi"):
        core.expansion_rest(mb.pin_model, mb.actuation, mb.dt, 1, traj.q, traj.v, traj.u, Phi[:-1], B, 0)
    # first = H computes nothing; first = 0 is the whole expansion
    core.expansion_rest(mb.pin_model, mb.actuation, mb.dt, 1, traj.q, traj.v, traj.u, Phi, B, H)
    assert not Phi.any()
    core.expansion_rest(mb.pin_model, mb.actuation, mb.dt, 1, traj.q, traj.v, traj.u, Phi, B, 0)
    ref = core.expansion(mb.pin_model, mb.actuation, mb.dt, 1, traj.q, traj.v, traj.u, 1, 1)
    assert np.array_equal(Phi, ref[0]) and np.array_equal(B, ref[1])


@pytest.mark.parametrize("expansion", ["first", "switch"])
@pytest.mark.parametrize("integrator", ["semi_implicit", "variational"])
def test_solves_are_bitwise_the_same_with_and_without_the_overlap(expansion, integrator, monkeypatch):
    p = _problem(CASES[1], integrator, H=30)
    opt = SolverOptions(expansion=expansion, verbose=False, max_iter=40)
    with_overlap = solve(p, opt)
    original = Problem.linearise

    def no_overlap(self, traj, order):
        lin = original(self, traj, order)
        self._first_order_next = False
        return lin

    monkeypatch.setattr(Problem, "linearise", no_overlap)
    without = solve(p, opt)
    assert with_overlap.iterations == without.iterations > 2
    for name in ("cost_history", "grad_norm_history", "reg_history", "step_history"):
        assert np.array_equal(getattr(with_overlap, name), getattr(without, name)), name
    assert with_overlap.expansion_history == without.expansion_history
    assert np.array_equal(with_overlap.controls, without.controls)
    assert np.array_equal(with_overlap.feedback, without.feedback)
