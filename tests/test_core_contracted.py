"""The factored second-order terms of the compiled core (geoddp._core.SecondOrderTerms) and the
backward pass that contracts them with V_x' (cpp/contracted.*), against the formed tensors.

* Phi, B of the contracted expansion are bitwise those of the order-1 expansion;
* S = terms.contract(k, Vx) equals sum_i Vx_i [[Theta_i, Gamma_i], [Gamma_i^T, Xi_i]] built from
  the compiled Theta, Gamma, Xi (themselves checked against the Python oracle and differences in
  tests/test_core_dynamics.py) to round-off, on a free flyer (gravity on / off), a fixed base, a
  spherical root (gravity on / off) and every supported joint type, both integrators;
* the contracted backward pass gives the gains, (d1, d2), quu_eig and failed node of the tensor
  pass to round-off;
* a whole solve (second order and switch) has the same history with either form;
* a branched tree's terms do not depend on what their recycled buffers held before.
"""
import numpy as np
import pinocchio as pin
import pytest

from geoddp.problem.contract import Linearisation
from geoddp.models import compiled
from geoddp.models.multibody import Multibody
from geoddp.solver import SolverOptions, solve
from geoddp.solver.backward import Workspace, backward, node_quu
from geoddp.validate import InputError
from urdfs import urdf as urdf_file

core = compiled._core
CASES = [
    ("quadrotor.urdf", "free_flyer", True),
    ("spacecraft.urdf", "free_flyer", False),
    ("space_manipulator.urdf", "fixed", True),
    ("space_manipulator.urdf", "free_flyer", True),
    ("satellite.urdf", "spherical", False),
    ("satellite.urdf", "spherical", True),
    ("test_all_joints.urdf", "fixed", True),
]
IDS = [f"{u.split('.')[0]}-{r}-{'g' if g else 'nog'}" for u, r, g in CASES]


def _setup(case, integrator, H=6, seed=3):
    urdf, root, gravity = case
    mb = Multibody(urdf_file(urdf), root=root, dt=0.01, integrator=integrator, gravity=gravity)
    rng = np.random.default_rng(seed)
    q0 = pin.integrate(mb.pin_model, mb.neutral(), 0.7 * rng.normal(size=mb.nv))
    v0 = rng.normal(size=mb.nv)
    U = rng.normal(size=(H, mb.nu))
    Q, V = mb.rollout(q0, v0, U)
    return mb, Q, V, U, rng


def _dense(e, k, Vx):
    n, m = e.B.shape[1], e.B.shape[2]
    S = np.zeros((n + m, n + m))
    S[:n, :n] = np.einsum("i,iab->ab", Vx, e.Theta[k])
    S[n:, :n] = np.einsum("i,iac->ca", Vx, e.Gamma[k])
    S[:n, n:] = S[n:, :n].T
    S[n:, n:] = np.einsum("i,iab->ab", Vx, e.Xi[k])
    return S


@pytest.mark.parametrize("integrator", ["euler", "semi_implicit", "variational"])
@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_contraction_equals_tensors(case, integrator):
    mb, Q, V, U, rng = _setup(case, integrator)
    e = mb.expansion(Q, V, U, order=2)
    ec = mb.expansion(Q, V, U, order=2, contracted=True)
    e1 = mb.expansion(Q, V, U, order=1)
    assert ec.Theta is None and ec.Gamma is None and ec.Xi is None and ec.terms is not None
    assert np.array_equal(ec.Phi, e1.Phi) and np.array_equal(ec.B, e1.B)
    t = ec.terms
    assert (t.N, t.nv, t.m) == (U.shape[0], mb.nv, mb.nu)
    for k in range(U.shape[0]):
        Vx = rng.normal(size=mb.nx) * 10.0 ** rng.uniform(-2, 2)
        S, ref = t.contract(k, Vx), _dense(e, k, Vx)
        assert S.shape == ref.shape
        assert np.abs(S - ref).max() <= 1e-13 * max(1.0, np.abs(ref).max())
        assert np.abs(S - S.T).max() <= 1e-14 * max(1.0, np.abs(ref).max())
        # linear in Vx: each unit vector picks one output row of the tensors
        i = int(rng.integers(mb.nx))
        ei = np.zeros(mb.nx)
        ei[i] = 1.0
        assert np.abs(t.contract(k, ei) - _dense(e, k, ei)).max() <= 1e-13 * max(1.0, np.abs(_dense(e, k, ei)).max())


def _linearisations(mb, Q, V, U, rng):
    H, n, m = U.shape[0], mb.nx, mb.nu
    A = rng.normal(size=(H, n + m, n + m))
    L = np.einsum("kab,kcb->kac", A, A) + 1e-2 * np.eye(n + m)  # SPD cost Hessians
    costs = dict(l_x=rng.normal(size=(H, n)), l_u=rng.normal(size=(H, m)), l_xx=L[:, :n, :n].copy(),
                 l_ux=L[:, n:, :n].copy(), l_uu=L[:, n:, n:].copy(), lf_x=rng.normal(size=n),
                 lf_xx=np.eye(n) * 3.0)
    e = mb.expansion(Q, V, U, order=2)
    ec = mb.expansion(Q, V, U, order=2, contracted=True)
    lt = Linearisation(order=2, Phi=e.Phi, B=e.B, Theta=e.Theta, Gamma=e.Gamma, Xi=e.Xi, **costs)
    lc = Linearisation(order=2, Phi=ec.Phi, B=ec.B, Theta=None, Gamma=None, Xi=None, second_order=ec.terms, **costs)
    return lt, lc


@pytest.mark.parametrize("integrator", ["euler", "semi_implicit", "variational"])
@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_contracted_backward_pass_equals_tensor_pass(case, integrator):
    mb, Q, V, U, rng = _setup(case, integrator)
    lt, lc = _linearisations(mb, Q, V, U, rng)
    H, m, n = U.shape[0], mb.nu, mb.nx
    for reg in (0.0, 1e-3, 1e2):
        wt, wc = Workspace(H, m, n), Workspace(H, m, n)
        ft, d1t, d2t = backward(lt, wt, reg)
        fc, d1c, d2c = backward(lc, wc, reg)
        assert fc == ft
        assert abs(d1c - d1t) <= 1e-11 * max(1.0, abs(d1t)) and abs(d2c - d2t) <= 1e-11 * max(1.0, abs(d2t))
        lo = ft + 1
        for a, b in ((wc.k, wt.k), (wc.K, wt.K), (wc.quu_eig, wt.quu_eig)):
            assert np.abs(a[lo:] - b[lo:]).max() <= 1e-10 * max(1.0, np.abs(b[lo:]).max())
        # the numpy mirror used on the saddle path reads the factored terms too
        for k in (H - 1, max(lo, 0)):
            assert np.abs(node_quu(lc, k) - node_quu(lt, k)).max() <= 1e-10 * max(1.0, np.abs(node_quu(lt, k)).max())


@pytest.mark.parametrize("integrator", ["euler", "semi_implicit", "variational"])
@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_two_worker_pass_equals_one_worker_pass(case, integrator):
    """The pass with each node's contraction on the core's second worker (workers=2) gives bitwise
    the one-worker pass's results: the failed node, (d1, d2) and every written gain, also when it
    stops at a failed node (the worker must then stop too: the repeated calls would hang
    otherwise). workers=0, what the solver runs when two cores may be used, picks one of the two
    by their measured times (its first two calls for a shape run each once). H = 1 has no hand-over."""
    for H in (1, 30):
        mb, Q, V, U, rng = _setup(case, integrator, H=H)
        _, lc = _linearisations(mb, Q, V, U, rng)
        m, n = mb.nu, mb.nx
        indefinite = lc.l_uu.copy()
        indefinite[[H // 3, H - 1]] -= 40.0 * np.eye(m)  # fails at node H - 1 for small reg
        for l_uu in (lc.l_uu, indefinite):
            for reg in (0.0, 1e-3, 1e2):
                out = {}
                for workers in (1, 2, 2, 2, 0, 0, 0):  # repeated: a race would show as a difference
                    w = Workspace(H, m, n)
                    w.k[:], w.K[:], w.quu_eig[:] = 7.0, -3.0, 5.0  # same stale contents before the call
                    r = core.backward_pass_contracted(lc.Phi, lc.B, lc.l_x, lc.l_u, lc.l_xx, lc.l_ux, l_uu,
                                                      lc.lf_x, lc.lf_xx, lc.second_order, reg, w.k, w.K,
                                                      w.quu_eig, workers)
                    got = (r, w.k.copy(), w.K.copy(), w.quu_eig.copy())
                    ref = out.setdefault("ref", got)
                    assert got[0] == ref[0], (workers, got[0], ref[0])
                    assert all(np.array_equal(a, b) for a, b in zip(got[1:], ref[1:]))
                if l_uu is indefinite and reg == 0.0:
                    assert out["ref"][0][0] == H - 1  # the failure path was exercised


def test_contracted_pass_rejects_wrong_shapes():
    mb, Q, V, U, rng = _setup(CASES[0], "euler", H=4)
    lt, lc = _linearisations(mb, Q, V, U, rng)
    ws = Workspace(4, mb.nu, mb.nx)
    other = mb.expansion(Q[:-1], V[:-1], U[:-1], order=2, contracted=True).terms  # 3 nodes
    with pytest.raises(ValueError, match="terms"):
        core.backward_pass_contracted(lc.Phi, lc.B, lc.l_x, lc.l_u, lc.l_xx, lc.l_ux, lc.l_uu, lc.lf_x, lc.lf_xx,
                                      other, 0.0, ws.k, ws.K, ws.quu_eig)
    with pytest.raises(ValueError, match="k_ff"):
        core.backward_pass_contracted(lc.Phi, lc.B, lc.l_x, lc.l_u, lc.l_xx, lc.l_ux, lc.l_uu, lc.lf_x, lc.lf_xx,
                                      lc.second_order, 0.0, ws.k[1:], ws.K, ws.quu_eig)
    with pytest.raises(ValueError, match="workers"):
        core.backward_pass_contracted(lc.Phi, lc.B, lc.l_x, lc.l_u, lc.l_xx, lc.l_ux, lc.l_uu, lc.lf_x, lc.lf_xx,
                                      lc.second_order, 0.0, ws.k, ws.K, ws.quu_eig, 3)
    with pytest.raises(IndexError):
        lc.second_order.contract(4, np.zeros(mb.nx))
    with pytest.raises(ValueError, match="Vx"):
        lc.second_order.contract(0, np.zeros(mb.nx + 1))
    with pytest.raises(InputError, match="contract"):
        Multibody(urdf_file("quadrotor.urdf"), dt=0.01, contract="yes")
    from oracle_multibody import OracleMultibody

    py = OracleMultibody(urdf_file("quadrotor.urdf"), dt=0.01)  # the tests' Python oracle forms the tensors
    assert not py.contracts_second_order
    with pytest.raises(ValueError, match="contracted"):
        py.expansion(Q, V, U, order=2, contracted=True)


@pytest.mark.parametrize("expansion, integrator", [("second", "semi_implicit"), ("switch", "semi_implicit"),
                                                   ("second", "variational"), ("switch", "variational")])
def test_solve_history_equals_tensor_form(expansion, integrator):
    from geoddp.scene import builtin as scenes

    res = {}
    for contract in (True, False):
        p = scenes.space_manipulator(integrator=integrator)
        p.model.contract = contract
        assert p.model.contracts_second_order == contract
        res[contract] = solve(p, SolverOptions(expansion=expansion, verbose=False))
    a, b = res[True], res[False]
    assert a.iterations == b.iterations and a.status == b.status
    assert a.expansion_history == b.expansion_history
    # The variational second-order solve's early iterates are ill-conditioned: relative noise of
    # 1e-14 put on the tensor form's Theta, Gamma, Xi alone moves its cost history by up to 6.4e-8
    # relative (semi-implicit: 1e-13), and the two forms differ by round-off (1e-14 of each
    # contracted block, test_contraction_equals_tensors): measured 5.5e-8 at the fourth iterate
    # (2026-11-27, b329e27), J* and the controls equal to 5e-16 and 8e-14. Its switch solve agrees
    # to 4e-16 throughout. A wrong contraction term moves these by orders of magnitude more.
    tol = 3e-7 if (integrator, expansion) == ("variational", "second") else 1e-10
    for name in ("cost_history", "reg_history", "step_history"):
        x, y = np.asarray(getattr(a, name), float), np.asarray(getattr(b, name), float)
        assert x.shape == y.shape
        assert np.all(np.abs(x - y) <= (tol if name == "cost_history" else 1e-10) * np.abs(y)), name
    assert abs(a.cost - b.cost) <= 1e-12 * abs(b.cost)
    assert np.abs(a.controls - b.controls).max() <= 1e-10 * np.abs(b.controls).max()
    # ||dJ/dU|| falls by 1e11 over the solve: near the optimum it is the round-off of the iterate,
    # so it agrees to tol of the largest gradient (measured: 2.3e-11 absolute at 237), not relatively
    x, y = a.grad_norm_history, b.grad_norm_history
    assert x.shape == y.shape and np.abs(x - y).max() <= tol * y.max()


@pytest.mark.parametrize("integrator", ["semi_implicit", "variational"])
def test_threads_give_identical_terms(integrator):
    mb, Q, V, U, rng = _setup(CASES[3], integrator, H=9)
    args = (mb.pin_model, mb.actuation, mb.dt, compiled.INTEGRATORS[integrator], Q, V, U)
    Phi1, B1, t1 = core.expansion_contracted(*args, 1)
    Phi2, B2, t2 = core.expansion_contracted(*args, 2)
    assert np.array_equal(Phi1, Phi2) and np.array_equal(B1, B2)
    for k in range(U.shape[0]):
        Vx = rng.normal(size=mb.nx)
        assert np.array_equal(t1.contract(k, Vx), t2.contract(k, Vx))


def _child_expansion(conn, case):
    mb, Q, V, U, _ = _setup(case, "euler", H=40)
    conn.send(mb.expansion(Q, V, U, order=1).Phi)  # default threads: 2 workers on >= 2 cores
    conn.close()


def test_worker_pool_survives_fork():
    """The core's persistent worker pool (cpp/runtime/pool.hpp) after a fork: the child builds its own."""
    import multiprocessing as mp

    mb, Q, V, U, _ = _setup(CASES[0], "euler", H=40)
    ref = mb.expansion(Q, V, U, order=1).Phi  # the parent's pool is running now
    ctx = mp.get_context("fork")
    parent, child = ctx.Pipe()
    proc = ctx.Process(target=_child_expansion, args=(child, CASES[0]))
    proc.start()
    assert parent.poll(60), "the forked child did not answer (pool deadlock?)"
    got = parent.recv()
    proc.join(10)
    assert proc.exitcode == 0 and np.array_equal(got, ref)
    assert np.array_equal(mb.expansion(Q, V, U, order=1).Phi, ref)  # the parent's pool still works


def test_pool_spin_changes_timing_only():
    """How long idle workers poll before sleeping (cpp/runtime/pool.hpp, GEODDP_SPIN_US) changes when a
    worker wakes, never what it computes: the two-worker expansions of orders 1 and 2 are bitwise
    equal for 0 (sleep at once), the default and 100000 us; out-of-range values are refused, at the
    bound the Python check of GEODDP_SPIN_US uses too."""
    from geoddp.validate import SPIN_US_MAX

    assert core.SPIN_US_MAX == SPIN_US_MAX == 100_000
    mb, Q, V, U, _ = _setup(CASES[3], "euler", H=48)
    saved = core.spin_microseconds()
    try:
        runs = []
        for us in (0, 1000, 100_000, 0):
            core.set_spin_microseconds(us)
            assert core.spin_microseconds() == us
            e1 = mb.expansion(Q, V, U, order=1)
            e2 = mb.expansion(Q, V, U, order=2)
            runs.append((e1.Phi, e1.B, e2.Theta, e2.Gamma, e2.Xi))
        for run in runs[1:]:
            assert all(np.array_equal(a, b) for a, b in zip(run, runs[0]))
        for bad in (-1, 100_001):
            with pytest.raises(ValueError, match="0..100000"):
                core.set_spin_microseconds(bad)
        assert core.spin_microseconds() == 0
    finally:
        core.set_spin_microseconds(saved)


_SPIN_CHILD = """
import numpy as np, pinocchio as pin
from geoddp.models import compiled
from geoddp.models.multibody import Multibody
core = compiled._core
print(core.spin_microseconds())
mb = Multibody({urdf!r}, root="free_flyer", dt=0.01, gravity=True)
rng = np.random.default_rng(0)
U = rng.normal(size=(32, mb.nu))
Q, V = mb.rollout(pin.integrate(mb.pin_model, mb.neutral(), rng.normal(size=mb.nv)), rng.normal(size=mb.nv), U)
ref = mb.expansion(Q, V, U, order=1).Phi
# many short dispatches, each setting, the workers asleep, spinning or between the two, on two
# and three workers (a dispatch that leaves one of the pool's workers out)
for i in range(600):
    core.set_spin_microseconds((0, 5, 1000)[i % 3])
    mb.threads = (2, 3)[(i // 3) % 2]
    assert np.array_equal(mb.expansion(Q, V, U, order=1).Phi, ref)
print("ok")
"""


@pytest.mark.parametrize("env, expected", [(None, 1000), ("0", 0), ("250", 250)])
def test_pool_spin_from_environment(env, expected):
    """The core reads GEODDP_SPIN_US when it loads (default 1000 us); 600 back-to-back dispatches
    on two and three workers, alternating sleep-at-once, short and long polls, all return (no lost
    wake-up: a deadlock would hit the timeout) with the same result."""
    import os
    import subprocess
    import sys

    env_vars = {k: v for k, v in os.environ.items() if k not in ("GEODDP_SPIN_US", "GEODDP_THREADS")}
    if env is not None:
        env_vars["GEODDP_SPIN_US"] = env
    code = _SPIN_CHILD.format(urdf=str(urdf_file("quadrotor.urdf")))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env_vars)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == [str(expected), "ok"]


@pytest.mark.parametrize("raw", ["-5", "abc", "100001", "1.5", " 50", "50 ", "²"])
def test_bad_pool_spin_is_refused(monkeypatch, raw):
    """A GEODDP_SPIN_US the core cannot use is an InputError naming it when a model is built (the
    core alone would fall back to its default without a word)."""
    monkeypatch.setenv("GEODDP_SPIN_US", raw)
    with pytest.raises(InputError, match="GEODDP_SPIN_US"):
        Multibody(urdf_file("quadrotor.urdf"), root="free_flyer", dt=0.01)


def _one_rung_loop(lin, ws, lam, opt, u_bar=None):
    """The paper's loop, one pass per rung: ((lambda, d1, d2, rungs), failed node of the last pass)."""
    rungs = 0
    while True:
        failed, d1, d2 = backward(lin, ws, lam, u_bar)
        if failed < 0:
            break
        rungs += 1
        lam = max(lam * opt.reg_increase, opt.reg_min)
        if lam > opt.reg_max:
            break
    return (lam, d1, d2, rungs), failed


@pytest.mark.parametrize("speculate", [True, False], ids=["side_by_side", "one_thread"])
@pytest.mark.parametrize("contract", [True, False])
def test_ladder_search_equals_one_rung_at_a_time(contract, speculate, monkeypatch):
    """regularised_backward climbs the regularisation ladder by galloping and bisection, two rungs
    side by side where it may (in C++ for the contracted pass, _core.regularised_contracted; in
    Python for the tensor one); here factorising is monotone in lambda, so lambda, (d1, d2), the
    rungs climbed and every gain of the nodes the last pass solved equal the paper's loop, one
    pass per rung, exactly, and with fewer passes."""
    from geoddp.solver import backward as bw

    if not speculate:
        monkeypatch.setenv("GEODDP_THREADS", "1")

    mb, Q, V, U, rng = _setup(CASES[3], "semi_implicit", H=30)
    mb.contract = contract
    lt, lc = _linearisations(mb, Q, V, U, rng)
    lin = lc if contract else lt
    H, m, n = U.shape[0], mb.nu, mb.nx
    opt = SolverOptions()

    passes = {"n": 0}
    real_backward = bw.backward

    def counted(*a, **k):
        passes["n"] += 1
        return real_backward(*a, **k)

    climbed = []
    for shift in (40.0, 2.0):  # an indefinite control Hessian at a few nodes: many rungs, then few
        lin.l_uu = lt.l_uu.copy()
        lin.l_uu[[3, 17, 29]] -= shift * np.eye(mb.nu)
        for lam0, reg_max in ((0.0, opt.reg_max), (1e-3, opt.reg_max), (1.0, opt.reg_max), (4.0, opt.reg_max), (20.0, opt.reg_max), (30.0, opt.reg_max),
                              (0.0, 1e-2), (0.0, 1e-2 * opt.reg_increase)):
            o = SolverOptions(reg_max=reg_max)
            wa, wb = Workspace(H, m, n), Workspace(H, m, n)
            for w in (wa, wb):  # same stale contents before the call
                w.k[:], w.K[:], w.quu_eig[:] = 7.0, -3.0, 5.0
            passes["n"] = 0
            monkeypatch.setattr(bw, "backward", counted)
            a = bw.regularised_backward(lin, wa, lam0, o)
            monkeypatch.setattr(bw, "backward", real_backward)
            b, failed = _one_rung_loop(lin, wb, lam0, o)
            assert a == b, (a, b)
            lo = failed + 1  # the nodes the last pass solved (all of them when it factorised)
            assert np.array_equal(wa.k[lo:], wb.k[lo:]) and np.array_equal(wa.K[lo:], wb.K[lo:])
            assert np.array_equal(wa.quu_eig[lo:], wb.quu_eig[lo:])
            if not contract and a[3] >= 20:  # the Python loop's passes, counted: far fewer than rungs
                # (one at a time: 1 + galloping's ~log2 + bisection's ~log2; side by side, two a round)
                assert passes["n"] <= (16 if bw._can_speculate(lin) else 12), (passes["n"], a[3])
            climbed.append(a[3])
    assert max(climbed) >= 20 and {1, 2, 3} & set(climbed), climbed
    assert bw._can_speculate(lin) == (speculate and core.default_threads() >= 2)


def test_regularised_contracted_refuses_a_ladder_that_would_not_end():
    """The C++ search's own guard (SolverOptions validates the solver's options; this is the
    binding called directly): a NaN or negative lambda, a factor <= 1, a floor <= 0 or an infinite
    ceiling would climb forever."""
    mb, Q, V, U, rng = _setup(CASES[3], "semi_implicit", H=5)
    lt, lc = _linearisations(mb, Q, V, U, rng)
    H, m, n = U.shape[0], mb.nu, mb.nx
    ws, spare = Workspace(H, m, n), Workspace(H, m, n)
    for bad, name in (((float("nan"), 1.9, 1e-8, 1e10), "lam"), ((-1.0, 1.9, 1e-8, 1e10), "lam"),
                      ((0.0, 1.0, 1e-8, 1e10), "reg_increase"), ((0.0, 1.9, 0.0, 1e10), "reg_min"),
                      ((0.0, 1.9, 1e-8, float("inf")), "reg_max")):
        with pytest.raises(ValueError, match=name):
            core.regularised_contracted(lc.Phi, lc.B, lc.l_x, lc.l_u, lc.l_xx, lc.l_ux, lc.l_uu, lc.lf_x, lc.lf_xx,
                                        lc.second_order, *bad, False, ws.k, ws.K, ws.quu_eig, spare.k, spare.K,
                                        spare.quu_eig)
    # and the same call with a ladder that ends runs
    out = core.regularised_contracted(lc.Phi, lc.B, lc.l_x, lc.l_u, lc.l_xx, lc.l_ux, lc.l_uu, lc.lf_x, lc.lf_xx,
                                      lc.second_order, 0.0, 1.9, 1e-8, 1e10, False, ws.k, ws.K, ws.quu_eig, spare.k,
                                      spare.K, spare.quu_eig)
    assert np.isfinite(out[0]) and np.isfinite(out[2])


@pytest.mark.parametrize("contract", [True, False])
def test_box_pass_climbs_one_rung_at_a_time(contract):
    """With control limits the box pass warm-starts from the previous pass's feedforward, so
    regularised_backward climbs the ladder one rung per pass there: lambda, (d1, d2), the rungs
    climbed, the gains and the active set equal the paper's loop run by hand, bit for bit."""
    from geoddp.solver import backward as bw

    mb, Q, V, U, rng = _setup(CASES[3], "semi_implicit", H=30)
    mb.contract = contract
    lt, lc = _linearisations(mb, Q, V, U, rng)
    lin = lc if contract else lt
    lin.l_uu = lt.l_uu.copy()
    lin.l_uu[[3, 17, 29]] -= 40.0 * np.eye(mb.nu)
    H, m, n = U.shape[0], mb.nu, mb.nx
    bounds = (U - 0.05, U + 0.05)  # tight: the unconstrained steps leave the box
    for lam0 in (0.0, 1.0):
        o = SolverOptions()
        wa, wb = Workspace(H, m, n, bounds), Workspace(H, m, n, bounds)
        a = bw.regularised_backward(lin, wa, lam0, o, U)
        b, _ = _one_rung_loop(lin, wb, lam0, o, U)
        assert a == b and b[3] >= 1, (a, b)
        assert np.array_equal(wa.k, wb.k) and np.array_equal(wa.K, wb.K) and np.array_equal(wa.active, wb.active)
        assert wa.active.any()  # the box pass ran, with inputs on a bound


def test_linearisation_tensors_materialise_the_factored_terms():
    mb, Q, V, U, rng = _setup(CASES[3], "semi_implicit", H=5)
    lt, lc = _linearisations(mb, Q, V, U, rng)
    for a, b in zip(lc.tensors(), lt.tensors()):
        assert a.shape == b.shape and np.abs(a - b).max() <= 1e-13 * max(1.0, np.abs(b).max())
    assert lt.tensors()[0] is lt.Theta
    with pytest.raises(ValueError):
        Linearisation(order=1, Phi=lt.Phi, B=lt.B, Theta=None, Gamma=None, Xi=None, l_x=lt.l_x, l_u=lt.l_u,
                      l_xx=lt.l_xx, l_ux=lt.l_ux, l_uu=lt.l_uu, lf_x=lt.lf_x, lf_xx=lt.lf_xx).tensors()


def _revolute_tree(path, parents):
    """A URDF of revolute links: link i + 1 hangs from link parents[i] (0 = the base), offset and
    tilted so that no two axes align."""
    inertial = ("<inertial><origin xyz='0.1 {y} 0.3'/><mass value='{m}'/>"
                "<inertia ixx='0.2' ixy='0.01' ixz='0' iyy='0.3' iyz='0.02' izz='0.1'/></inertial>")
    links = [f"<link name='l0'>{inertial.format(y=0.0, m=2.0)}</link>"]
    joints = []
    for i, p in enumerate(parents, start=1):
        links.append(f"<link name='l{i}'>{inertial.format(y=0.02 * i, m=1 + 0.1 * i)}</link>")
        axis = ("1 0 0", "0 1 0", "0 0 1")[i % 3]
        joints.append(f"<joint name='j{i}' type='revolute'><parent link='l{p}'/><child link='l{i}'/>"
                      f"<origin xyz='0.05 0.1 0.4' rpy='0.3 {0.1 * i} 0.2'/><axis xyz='{axis}'/>"
                      "<limit lower='-3' upper='3' effort='10' velocity='10'/></joint>")
    path.write_text(f"<robot name='{path.stem}'>{''.join(links)}{''.join(joints)}</robot>")
    return path


@pytest.mark.parametrize("root", ["fixed", "free_flyer"])
def test_branched_tree_terms_do_not_depend_on_recycled_buffers(tmp_path, root):
    """Pinocchio's second-order recursion never writes the entries that couple dofs on different
    branches, and the contracted expansion's tensor buffers are recycled (cpp/runtime/buffers.hpp, Buffer)
    holding whatever the last user left. A chain writes every entry, so expanding a chain of the
    same size first leaves its numbers in the buffers the tree's expansion takes next: the tree's
    contraction must still equal its dense expansion (from Pinocchio's own zeroed tensors)."""
    chain = Multibody(_revolute_tree(tmp_path / "chain.urdf", [0, 1, 2, 3]), root=root, dt=0.01,
                      integrator="semi_implicit")
    tree = Multibody(_revolute_tree(tmp_path / "tree.urdf", [0, 1, 0, 3]), root=root, dt=0.01,
                     integrator="semi_implicit")
    assert chain.nv == tree.nv
    rng = np.random.default_rng(5)
    H = 4
    for mb in (chain, tree):
        q0 = pin.integrate(mb.pin_model, mb.neutral(), 0.7 * rng.normal(size=mb.nv))
        Q, V = mb.rollout(q0, 0.3 * rng.normal(size=mb.nv), U := 0.3 * rng.normal(size=(H, mb.nu)))
        ec = mb.expansion(Q, V, U, order=2, contracted=True)
        if mb is chain:
            del ec  # its buffers go back to the pool, holding the chain's numbers
            continue
        e = mb.expansion(Q, V, U, order=2)
        for k in range(H):
            Vx = rng.normal(size=mb.nx)
            ref = _dense(e, k, Vx)
            assert np.abs(ec.terms.contract(k, Vx) - ref).max() <= 1e-13 * max(1.0, np.abs(ref).max())
