"""The compiled multibody core (geoddp._core) against the Python oracle and finite differences.

* rollout and the closed-loop forward pass equal the Python path to 1e-12;
* Phi, B equal the Pinocchio-based Python expansion to 1e-12;
* the velocity update's second derivatives F2 (exact, from ComputeRNEASecondOrderDerivatives) equal
  Richardson-extrapolated central differences of Pinocchio's analytic first derivatives tightly,
  and the Python oracle (itself differences, ~1e-10) at its own accuracy, on a free flyer (gravity
  on and off), a fixed base, a spherical root (gravity on and off) and every supported joint type;
* the reconstruction's SO(3)/SE(3) closed forms equal the Python ones from 0 through 1e-8..1e-2 to
  near pi, and the exact SE(3) dJr equals high-order differences of the closed-form Jr;
* Theta, Gamma, Xi equal the Python reconstruction fed the same exact F2 (tight), and the Python
  oracle (at the oracle's accuracy);
* rk4 (cpp/dynamics/rkmk4.cpp): rollouts and Phi, B equal the Python RKMK4 to 1e-12, its second order
  (central differences of the analytic step Jacobian, as in Python) equals the Python one and
  second differences of the compiled step; threads do not change a bit; a solve equals Python's;
* variational (cpp/dynamics/variational_*.cpp): rollouts equal the Python step to 1e-12, F1 equals the Python
  implicit differentiation (whose kinetic-energy Hessian is differenced) to 1e-10, and F2 (one
  difference of the analytic residual Jacobian) equals Richardson differences of the compiled F1
  tightly and the Python oracle (a difference of a difference) at its accuracy; a solve equals
  Python's; a step that cannot converge raises the Python path's error;
* bad input raises InputError naming the parameter before any C++ runs;
* every built-in multibody scene solves to the same J* (1e-9 relative) in the same iterations.
"""
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from geoddp.problem.contract import Trajectory
from geoddp import lie as cfg
from urdfs import urdf as urdf_file
from geoddp.lie import SE3
from geoddp.models import compiled
from geoddp.models.multibody import Multibody
from oracle_multibody import OracleMultibody, use_oracle
from geoddp.validate import InputError


core = compiled._core
EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "multibody"

# (urdf, root, gravity): free flyer (gravity on / off), fixed base, spherical root (off / on),
# every supported joint type (revolute, continuous = SO(2), prismatic, spherical, ...)
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


def _models(case, integrator="euler", dt=0.01):
    urdf, root, gravity = case
    kw = dict(root=root, dt=dt, integrator=integrator, gravity=gravity)
    py = OracleMultibody(urdf_file(urdf), **kw)
    cc = Multibody(urdf_file(urdf), **kw)
    assert cc.backend == "compiled"
    return py, cc


def _state(model, seed, spread=0.7):
    rng = np.random.default_rng(seed)
    q = pin.integrate(model.pin_model, model.neutral(), spread * rng.normal(size=model.nv))
    return q, rng.normal(size=model.nv), rng.normal(size=model.nu)


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


# ---------------------------------------------------------------------------- rollouts
@pytest.mark.parametrize("integrator", ["euler", "semi_implicit", "rk4", "variational"])
@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_rollout_equals_python(case, integrator):
    py, cc = _models(case, integrator)
    q0, v0, _ = _state(py, 1)
    U = np.random.default_rng(2).normal(size=(30, py.nu))
    Qp, Vp = py.rollout(q0, v0, U)
    Qc, Vc = cc.rollout(q0, v0, U)
    assert np.abs(Vp).max() > 0.5
    assert _rel(Qc, Qp) < 1e-12 and _rel(Vc, Vp) < 1e-12


def _problem(model, q0, v0, H):
    from geoddp.costs.multibody import ControlRegularisation, MultibodyCostSum
    from geoddp.problem import Problem

    cost = MultibodyCostSum([ControlRegularisation(np.zeros(model.nu))], model=model.pin_model)
    return Problem(model, q0, v0, H, cost, MultibodyCostSum([], model=model.pin_model, terminal=True))


@pytest.mark.parametrize("integrator", ["euler", "semi_implicit", "rk4", "variational"])
@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_closed_loop_rollout_equals_python(case, integrator):
    py, cc = _models(case, integrator)
    q0, v0, _ = _state(py, 3)
    H, m, n = 25, py.nu, py.nx
    rng = np.random.default_rng(4)
    Ubar = rng.normal(size=(H, m))
    Qbar, Vbar = py.rollout(q0, v0, Ubar)
    kff, K = rng.normal(size=(H, m)), 0.3 * rng.normal(size=(H, m, n))
    outs = []
    for model in (py, cc):
        p = _problem(model, q0, v0, H)
        Qo, Vo, Uo = np.empty_like(Qbar), np.empty_like(Vbar), np.empty_like(Ubar)
        assert p.rollout_closed_loop(Qbar, Vbar, Ubar, kff, K, 0.5, Qo, Vo, Uo)
        outs.append((Qo, Vo, Uo))
    for a, b in zip(outs[1], outs[0]):
        assert _rel(a, b) < 1e-12
    # the solver's route (rollout_policy: checked=True, no Python checks) is bitwise the checked call
    trial = _problem(cc, q0, v0, H).rollout_policy(Trajectory(Qbar, Vbar, Ubar), kff, K, 0.5)
    for a, b in zip((trial.q, trial.v, trial.u), outs[1]):
        assert np.array_equal(a, b)
    # the feedback really acted (zeta != 0 along the way), far above the agreement tolerance
    assert _rel(outs[1][2], Ubar - 0.5 * kff) > 1e-6
    # a non-finite state (the implicit step: a step whose Newton iteration does not converge)
    # stops both passes with False: the line search rejects the trial
    for model in (py, cc):
        p = _problem(model, q0, v0, H)
        Qo, Vo, Uo = np.empty_like(Qbar), np.empty_like(Vbar), np.empty_like(Ubar)
        with np.errstate(all="ignore"):
            assert not p.rollout_closed_loop(Qbar, Vbar, Ubar, np.full((H, m), 1e308), K, -1e10, Qo, Vo, Uo)


# ---------------------------------------------------------------------------- velocity derivatives
def _F1(model, q, v, u):
    """Python (Pinocchio analytic) F1 at one node, (nv, nz)."""
    F1, _ = model.velocity_derivatives(q[None], v[None], u[None], order=1)
    return F1[0]


def _F2_differences(model, q, v, u, h=2e-3):
    """Richardson-extrapolated central differences of the analytic F1 along z, symmetrised
    (the (0)-Hessian): error O(h^4) + round-off ~1e-13."""
    nv, m = model.nv, model.nu
    nz = 2 * nv + m

    def moved(j, s):
        dq, dv, du = np.zeros(nv), np.zeros(nv), np.zeros(m)
        (dq if j < nv else dv if j < 2 * nv else du)[j if j < nv else j - nv if j < 2 * nv else j - 2 * nv] = s
        return _F1(model, pin.integrate(model.pin_model, q, dq), v + dv, u + du)

    D = np.empty((nv, nz, nz))
    for j in range(nz):
        c1 = (moved(j, h) - moved(j, -h)) / (2 * h)
        c2 = (moved(j, h / 2) - moved(j, -h / 2)) / h
        D[:, :, j] = (4 * c2 - c1) / 3
    return 0.5 * (D + np.swapaxes(D, 1, 2))


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_velocity_second_derivatives_exact(case):
    py, cc = _models(case)
    for seed in (5, 6):
        q, v, u = _state(py, seed)
        F1c, F2c = core.testing.velocity_derivatives(cc.pin_model, cc.actuation, cc.dt, q[None], v[None], u[None], 2, 1)
        F1p, F2p = py.velocity_derivatives(q[None], v[None], u[None], order=2)
        assert _rel(F1c, F1p) < 1e-13
        scale = max(1.0, float(np.abs(F2c).max()))
        assert np.abs(F2c).max() > 1e-4  # not trivially zero
        assert np.abs(F2c[0] - _F2_differences(py, q, v, u)).max() / scale < 1e-9
        assert np.abs(F2c - F2p).max() / scale < 2e-8  # the oracle's own differencing error
        assert np.array_equal(F2c, np.swapaxes(F2c, 2, 3))


@pytest.mark.parametrize("integrator, H", [("semi_implicit", 17), ("rk4", 5), ("variational", 5)])
def test_threads_give_identical_results(integrator, H):
    py, cc = _models(CASES[3], integrator)
    q0, v0, _ = _state(py, 8)
    U = np.random.default_rng(9).normal(size=(H, py.nu))
    Q, V = cc.rollout(q0, v0, U)
    code = compiled.INTEGRATORS[integrator]
    one = core.expansion(cc.pin_model, cc.actuation, cc.dt, code, Q, V, U, 2, 1)
    for t in (2, 3, 0):
        other = core.expansion(cc.pin_model, cc.actuation, cc.dt, code, Q, V, U, 2, t)
        for a, b in zip(one, other):
            assert np.array_equal(a, b)
    if integrator not in compiled.CONTRACTED_INTEGRATORS:  # their second order is formed, never factored
        with pytest.raises(ValueError, match="integrator"):
            core.expansion_contracted(cc.pin_model, cc.actuation, cc.dt, code, Q, V, U, 0)


# ---------------------------------------------------------------------------- reconstruction
ANGLES = [0.0, 1e-8, 1e-6, 1e-4, 1e-3, 1e-2, 0.2, 0.26, 0.49, 0.51, 0.59, 0.61, 1.0, 2.0, 3.0, np.pi - 1e-3]


@pytest.mark.parametrize("angle", ANGLES)
def test_closed_forms_equal_python(angle):
    rng = np.random.default_rng(int(angle * 1e3) + 11)
    ff = Multibody(urdf_file("space_manipulator.urdf"), root="free_flyer", dt=0.01)
    sp = Multibody(urdf_file("satellite.urdf"), root="spherical", dt=0.01)
    for model in (ff, sp):
        nv = model.nv
        omega = rng.normal(size=nv)
        g = model.groups[0]
        axis = rng.normal(size=3)
        omega[g.idx_v + g.nv - 3 : g.idx_v + g.nv] = angle * axis / np.linalg.norm(axis)
        A, J, D = core.testing.block_ad_jr(model.pin_model, omega)
        Ap, Jp = cfg.block_Ad_Jr(model.groups, nv, omega)
        assert np.abs(A - Ap).max() < 1e-14 and np.abs(J - Jp).max() < 1e-14
        Dp, _ = cfg.second_order_tensors(model.groups, nv, omega)
        # SO(3): the same closed form; SE(3): the oracle differences its Jr (step 1e-5)
        assert np.abs(D - Dp).max() < (1e-14 if g.kind == "so3" else 1e-9)
        if g.kind == "se3":  # exact dJr against O(h^4) differences of the closed-form Jr
            w = omega[g.slice]
            for l in range(6):
                def jr(s):
                    return SE3.right_jacobian(w + s * np.eye(6)[l])
                h = 1e-3
                d = (8 * (jr(h) - jr(-h)) - (jr(2 * h) - jr(-2 * h))) / (12 * h)
                assert np.abs(D[g.slice, g.slice, g.idx_v + l] - d).max() < 1e-10


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-5, 1e-2, 0.3, 0.59, 0.61, 1.0, 2.0, 3.1, np.pi - 1e-6])
def test_se3_djr_transpose_apply_equals_the_derivative(angle):
    """The variational step's dK^T terms take (dJr(x)/dx_l)^T s of SE(3) from closed-form gradients of
    s^T Q(r, p) (cpp/lie/right_jacobians.hpp, se3_djr_transpose_apply) instead of forming dJr: equal to the dual-number
    dJr of block_ad_jr applied to s to round-off, and to O(h^4) differences of the Python closed-form
    Jr, from the identity through both sides of the coupling's series branch (|w| = 0.6) to near pi."""
    ff = Multibody(urdf_file("spacecraft.urdf"), root="free_flyer", dt=0.01)
    rng = np.random.default_rng(int(angle * 1e4) + 5)
    for _ in range(20):
        x, s = rng.normal(size=6), rng.normal(size=6)
        axis = rng.normal(size=3)
        x[3:] = angle * axis / np.linalg.norm(axis)
        N = core.testing.se3_djr_transpose_apply(x, s)
        _, _, D = core.testing.block_ad_jr(ff.pin_model, x)
        expected = np.einsum("ijl,i->jl", D, s)
        assert np.abs(N - expected).max() <= 1e-14 * max(1.0, np.abs(expected).max())
        h = 1e-3
        for l in range(6):
            e = h * np.eye(6)[l]
            d = (8 * (SE3.right_jacobian(x + e) - SE3.right_jacobian(x - e))
                 - (SE3.right_jacobian(x + 2 * e) - SE3.right_jacobian(x - 2 * e))) / (12 * h)
            assert np.abs(N[:, l] - d.T @ s).max() < 1e-9 * max(1.0, np.abs(s).max())


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-5, 1e-2, 0.3, 0.59, 0.61, 1.0, 1.49, 1.51, 2.0, 3.1, np.pi - 1e-6])
def test_jr_transpose_hessian_equals_the_derivative_of_djr(angle):
    """The variational second order's exact d/dx terms of d/dx[Jr(x)^-T p] rest on E[i, a, b] =
    d^2 (Jr(x)^T u)_i / dx_a dx_b in closed form (cpp/lie/right_jacobians.hpp, jr_transpose_hessian): equal to O(h^4)
    differences of the first derivatives, for SO(3) the Python closed form dJr
    (SO3.right_jacobian_derivative_batch) and for SE(3) se3_djr_transpose_apply (checked above against
    the Python Jr), from the identity through both sides of every series branch (|w| = 0.6 and 1.5) to
    near pi; symmetric in (a, b) to round-off, and zero along two linear directions of SE(3)."""
    rng = np.random.default_rng(int(angle * 1e4) + 9)
    h = 2e-3
    for _ in range(10):
        axis = rng.normal(size=3)
        w = angle * axis / np.linalg.norm(axis)
        u3, x6, u6 = rng.normal(size=3), np.concatenate([rng.normal(size=3), w]), rng.normal(size=6)
        E3, E6 = core.testing.jr_transpose_hessian(w, u3), core.testing.jr_transpose_hessian(x6, u6)

        def g3(x):  # (dJr(x)/dx_l)^T u, (3, 3) over (i, l)
            return np.einsum("jil,j->il", cfg.SO3.right_jacobian_derivative_batch(x[None])[0], u3)

        for E, g, x, u in ((E3, g3, w, u3), (E6, lambda y: core.testing.se3_djr_transpose_apply(y, u6), x6, u6)):
            n = len(x)
            for b in range(n):
                e = h * np.eye(n)[b]
                d = (8 * (g(x + e) - g(x - e)) - (g(x + 2 * e) - g(x - 2 * e))) / (12 * h)
                assert np.abs(E[:, :, b] - d).max() < 1e-10 * max(1.0, np.abs(d).max()), (n, b)
            assert np.abs(E - np.swapaxes(E, 1, 2)).max() <= 1e-15 * max(1.0, np.abs(E).max())
        assert np.abs(E6[:, :3, :3]).max() == 0.0 and np.abs(E6[:3, :, :3]).max() == 0.0
    with pytest.raises(ValueError, match="x: expected shape"):
        core.testing.jr_transpose_hessian(np.zeros(4), np.zeros(4))


@pytest.mark.parametrize("integrator", ["euler", "semi_implicit"])
@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_expansion_equals_python(case, integrator, monkeypatch):
    py, cc = _models(case, integrator)
    q0, v0, _ = _state(py, 12)
    U = np.random.default_rng(13).normal(size=(6, py.nu))
    Q, V = py.rollout(q0, v0, U)
    e1 = cc.expansion(Q, V, U, order=1)
    ep1 = py.expansion(Q, V, U, order=1)
    assert e1.Theta is None
    assert _rel(e1.Phi, ep1.Phi) < 1e-12 and _rel(e1.B, ep1.B) < 1e-12
    ec = cc.expansion(Q, V, U, order=2)
    assert np.array_equal(ec.Phi, e1.Phi) and np.array_equal(ec.B, e1.B)
    # the problem's path (checked=True: no input checks, no copies) computes the very same arrays
    for order in (1, 2):
        trusted, full = cc.expansion(Q, V, U, order=order, checked=True), (e1 if order == 1 else ec)
        for name in ("Phi", "B") + (("Theta", "Gamma", "Xi") if order == 2 else ()):
            assert np.array_equal(getattr(trusted, name), getattr(full, name)), (order, name)
    ep = py.expansion(Q, V, U, order=2)
    for name in ("Theta", "Gamma", "Xi"):
        a, b = getattr(ec, name), getattr(ep, name)
        assert a.shape == b.shape
        assert _rel(a, b) < 2e-8  # the oracle's differencing error
    # the reconstruction alone, tight: the Python assembly fed the core's exact F1, F2
    exact = core.testing.velocity_derivatives(cc.pin_model, cc.actuation, cc.dt, Q[:-1], V[:-1], U, 2, 1)
    monkeypatch.setattr(OracleMultibody, "velocity_derivatives", lambda self, *a, **k: exact)
    ef = py.expansion(Q, V, U, order=2)
    for name in ("Theta", "Gamma", "Xi"):
        assert _rel(getattr(ec, name), getattr(ef, name)) < 1e-11


# ---------------------------------------------------------------------------- bad input
def test_bad_input_names_the_parameter():
    urdf = urdf_file("quadrotor.urdf")
    for backend in ("fast", "python"):  # the Python path is the tests' oracle, not a backend of the package
        with pytest.raises(InputError, match="backend"):
            Multibody(urdf, dt=0.01, backend=backend)
    with pytest.raises(InputError, match="threads"):
        Multibody(urdf, dt=0.01, threads=-1)
    for integrator in ("rk4", "variational"):  # compiled; rk4's second order formed, the variational factored
        assert Multibody(urdf, dt=0.01, integrator=integrator).backend == "compiled"
        assert Multibody(urdf, dt=0.01, integrator=integrator).contracts_second_order == (integrator == "variational")
    cc = Multibody(urdf, dt=0.01)
    q0, v0 = cc.neutral(), np.zeros(cc.nv)
    U = np.zeros((4, cc.nu))
    Q, V = cc.rollout(q0, v0, U)
    with pytest.raises(InputError, match="controls"):
        cc.rollout(q0, v0, np.zeros((4, cc.nu + 1)))
    with pytest.raises(InputError, match="initial.q"):
        cc.rollout(q0[:-1], v0, U)
    with pytest.raises(InputError, match="Q"):
        cc.expansion(Q[:-1], V, U)
    with pytest.raises(InputError, match="V"):
        cc.expansion(Q, V[:, :-1], U)
    with pytest.raises(InputError, match="order"):
        cc.expansion(Q, V, U, order=3)
    p = _problem(cc, q0, v0, 4)
    Qo, Vo, Uo = np.empty_like(Q), np.empty_like(V), np.empty_like(U)
    good = dict(Q_bar=Q, V_bar=V, u_bar=U, k_ff=np.zeros_like(U), K_fb=np.zeros((4, cc.nu, cc.nx)))
    for name, bad in [("Q_bar", Q[:-1]), ("V_bar", V[:, 1:]), ("u_bar", U[:-1]), ("k_ff", U[:, 1:]),
                      ("K_fb", np.zeros((4, cc.nu, cc.nx + 1)))]:
        args = dict(good, **{name: bad})
        with pytest.raises(InputError, match=name):
            p.rollout_closed_loop(args["Q_bar"], args["V_bar"], args["u_bar"], args["k_ff"], args["K_fb"], 1.0, Qo, Vo, Uo)
    with pytest.raises(InputError, match="Q_out"):
        p.rollout_closed_loop(Q, V, U, good["k_ff"], good["K_fb"], 1.0, Qo.astype(np.float32), Vo, Uo)
    with pytest.raises(InputError, match="u_out"):
        p.rollout_closed_loop(Q, V, U, good["k_ff"], good["K_fb"], 1.0, Qo, Vo, np.empty((4, cc.nu + 1)))


def test_extension_records_its_pin():
    assert core.PINOCCHIO_VERSION == pin.__version__


# ---------------------------------------------------------------------------- whole solves
@pytest.mark.parametrize("scene", sorted(p.name for p in EXAMPLES.glob("*.toml")))
def test_scene_solves_equal_python(scene, monkeypatch):
    from geoddp import solve_scene

    res = {}
    for backend in ("python", "compiled"):
        with pytest.MonkeyPatch.context() as mp:
            if backend == "python":
                use_oracle(mp)
            res[backend] = solve_scene(EXAMPLES / scene, verbose=False)
    a, b = res["compiled"], res["python"]
    assert a.iterations == b.iterations
    assert a.expansion_history == b.expansion_history
    assert abs(a.cost - b.cost) <= 1e-9 * abs(b.cost)
    # Intermediate J: the quadrotor's iterations amplify round-off ~1e8-fold (measured: 1-ulp
    # noise on the Python path's own Phi, B moves its J history by up to 3.6e-8 relative; the
    # core differs by up to 1.1e-7, also from its exact F2 where the oracle differences).
    assert np.max(np.abs(a.cost_history - b.cost_history) / np.abs(b.cost_history)) < 1e-6


# ---------------------------------------------------------------------------- rk4 (cpp/dynamics/rkmk4.cpp)
def _second_order_scale(e):
    return max(np.abs(e.Theta).max(), np.abs(e.Gamma).max(), np.abs(e.Xi).max())


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_rk4_expansion_equals_python(case):
    py, cc = _models(case, "rk4")
    q0, v0, _ = _state(py, 12)
    U = np.random.default_rng(13).normal(size=(4, py.nu))
    Q, V = py.rollout(q0, v0, U)
    e1, ep1 = cc.expansion(Q, V, U, order=1), py.expansion(Q, V, U, order=1)
    assert e1.Theta is None
    assert _rel(e1.Phi, ep1.Phi) < 1e-12 and _rel(e1.B, ep1.B) < 1e-12
    ec, ep = cc.expansion(Q, V, U, order=2), py.expansion(Q, V, U, order=2)
    assert np.array_equal(ec.Phi, e1.Phi) and np.array_equal(ec.B, e1.B)
    scale = _second_order_scale(ep)
    assert scale > 1e-3  # the second order is there to compare
    for name in ("Theta", "Gamma", "Xi"):
        a, b = getattr(ec, name), getattr(ep, name)
        assert a.shape == b.shape
        # the same differences of Jacobians that agree to round-off (block inverses in C++, LU
        # in numpy): ~1e-16 / 1e-5; measured <= 8e-10 of the largest second-order entry
        assert np.abs(a - b).max() < 1e-8 * scale, name
        if name != "Gamma":  # the (0)-Hessian blocks on the diagonal are exactly symmetric
            assert np.array_equal(a, np.swapaxes(a, 2, 3)), name


def _compiled_step_map(cc, Q, V, U, k):
    """z = (zeta, du) -> zeta+ about the nominal next state, through the compiled rollout."""
    nx = cc.nx

    def f(z):
        qp, vp = cc.retract(Q[k], V[k], z[:nx])
        Qn, Vn = cc.rollout(qp, vp, (U[k] + z[nx:])[None])
        return cc.local(Q[k + 1], V[k + 1], Qn[1], Vn[1])

    return f


@pytest.mark.parametrize("case", [CASES[0], CASES[3], CASES[5], CASES[6]], ids=[IDS[0], IDS[3], IDS[5], IDS[6]])
def test_rk4_expansion_against_differences_of_the_compiled_step(case):
    _, cc = _models(case, "rk4", dt=0.05)
    q0, v0, _ = _state(cc, 21)
    U = np.random.default_rng(22).normal(size=(2, cc.nu))
    Q, V = cc.rollout(q0, v0, U)
    e = cc.expansion(Q, V, U, order=2)
    n, nz = cc.nx, cc.nx + cc.nu
    f = _compiled_step_map(cc, Q, V, U, 1)
    h = 1e-3
    E = np.eye(nz)
    J = np.array([(-f(2 * h * a) + 8 * f(h * a) - 8 * f(-h * a) + f(-2 * h * a)) / (12 * h) for a in E]).T
    assert np.abs(J - np.hstack([e.Phi[1], e.B[1]])).max() < 1e-8 * max(1.0, np.abs(J).max())
    h2 = 2e-4
    f0 = f(np.zeros(nz))
    ref = np.empty((n, nz, nz))
    for i in range(nz):
        ref[:, i, i] = (f(h2 * E[i]) - 2 * f0 + f(-h2 * E[i])) / h2**2
        for j in range(i):
            a, b = h2 * E[i], h2 * E[j]
            ref[:, i, j] = ref[:, j, i] = (f(a + b) - f(a - b) - f(b - a) + f(-a - b)) / (4 * h2**2)
    T = np.zeros((n, nz, nz))
    T[:, :n, :n], T[:, :n, n:], T[:, n:, n:] = e.Theta[1], e.Gamma[1], e.Xi[1]
    T[:, n:, :n] = np.swapaxes(e.Gamma[1], 1, 2)
    assert np.abs(ref).max() > 1e-2  # a real second order
    assert np.abs(T - ref).max() < 2e-6 * max(1.0, np.abs(ref).max())


@pytest.mark.parametrize("integrator", ["rk4", "variational"])
def test_solve_equals_python(integrator, monkeypatch):
    """A whole switch solve with rk4 or the variational step (first- and second-order iterations,
    the exact certificate) takes the same iterations to the same optimum on both backends (the
    compiled one ~75x / ~40x faster, 2026-11-25: benchmarks/core_dynamics_rk4_2026-11-25.log,
    benchmarks/variational_2026-11-25b.log; not asserted)."""
    from geoddp.scene import build_problem, load_scene
    from geoddp.solver import solve
    from geoddp.solver.options import SolverOptions

    spec = load_scene(EXAMPLES / "spacecraft_docking.toml").with_overrides(integrator=integrator, horizon=20)
    res = {}
    for backend in ("compiled", "python"):
        with pytest.MonkeyPatch.context() as mp:
            if backend == "python":
                use_oracle(mp)
            p = build_problem(spec)
            assert p.model.backend == backend and p.model.integrator == integrator
            res[backend] = solve(p, SolverOptions(verbose=False))
    a, b = res["compiled"], res["python"]
    assert a.converged and b.converged
    assert "second" in a.expansion_history and a.expansion_history == b.expansion_history
    assert abs(a.cost - b.cost) <= 1e-10 * abs(b.cost)
    assert np.max(np.abs(a.cost_history - b.cost_history) / np.abs(b.cost_history)) < 1e-9


# ---------------------------------------------------------------------------- variational (cpp/dynamics/variational_*.cpp)
def _var_F(cc, Q, V, Vn, order=2, threads=1):
    return core.testing.variational_velocity_derivatives(cc.pin_model, cc.actuation, cc.dt, Q, V, Vn, order, threads)


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_variational_velocity_derivatives_equal_python_and_differences(case):
    py, cc = _models(case, "variational")
    q0, v0, _ = _state(py, 31)
    U = np.random.default_rng(32).normal(size=(3, py.nu))
    Q, V = py.rollout(q0, v0, U)
    F1c, F2c = _var_F(cc, Q[:-1], V[:-1], V[1:])
    F1p, F2p = py._variational.velocity_derivatives(Q[:-1], V[:-1], V[1:], U, 2)
    # the Python F1 differences the kinetic-energy Hessian (~1e-10); the compiled one is exact
    assert _rel(F1c, F1p) < 1e-10
    scale = max(1.0, float(np.abs(F2c).max()))
    assert np.abs(F2c).max() > 1e-4
    assert np.abs(F2c - F2p).max() / scale < 2e-6  # the oracle's nested differences (measured 1.4e-7)
    assert np.array_equal(F2c, np.swapaxes(F2c, 2, 3))
    # against Richardson differences of the compiled (analytic) F1 along z, at the solved v+ of
    # each perturbed state: the implicit function's own second derivative
    nv, m = cc.nv, cc.nu
    nz = 2 * nv + m
    k = 1

    def F1_at(z):
        q = pin.integrate(cc.pin_model, Q[k], z[:nv])
        v, u = V[k] + z[nv : 2 * nv], U[k] + z[2 * nv :]
        Qs, Vs = cc.rollout(q, v, u[None])
        return _var_F(cc, Qs[:1], Vs[:1], Vs[1:], order=1)[0][0]

    h = 2e-3
    D = np.empty((nv, nz, nz))
    for j in range(nz):
        e = np.zeros(nz)
        e[j] = 1.0
        c1 = (F1_at(h * e) - F1_at(-h * e)) / (2 * h)
        c2 = (F1_at(h / 2 * e) - F1_at(-h / 2 * e)) / h
        D[:, :, j] = (4 * c2 - c1) / 3
    ref = 0.5 * (D + np.swapaxes(D, 1, 2))
    assert np.abs(F2c[k] - ref).max() / scale < 1e-7


@pytest.mark.parametrize("urdf, root, nroot, tilts", [("space_manipulator.urdf", "free_flyer", 6, True),
                                                       ("spacecraft.urdf", "free_flyer", 6, True),
                                                       ("satellite.urdf", "spherical", 3, False)])
def test_variational_root_pose_directions(urdf, root, nroot, tilts):
    """Perturbing a free-flyer or spherical root's pose moves the whole mechanism rigidly: without
    gravity the variational step's velocity update does not change, so F2 is exactly zero along
    those eta directions (the core skips their differences); with gravity only the gravity terms
    change there, and F2 agrees with the oracle and with differences of F1 (test above). (``tilts``:
    gravity acts through the root's attitude; not on the satellite, whose centre of mass is its
    spherical joint's centre.)"""
    for gravity in (False, True):
        py, cc = _models((urdf, root, gravity), "variational")
        q0, v0, _ = _state(py, 51)
        U = np.random.default_rng(52).normal(size=(3, py.nu))
        Q, V = cc.rollout(q0, v0, U)
        _, F2c = _var_F(cc, Q[:-1], V[:-1], V[1:])
        _, F2p = py._variational.velocity_derivatives(Q[:-1], V[:-1], V[1:], U, 2)
        scale = max(1.0, float(np.abs(F2c).max()))
        block = np.abs(F2c[:, :, :nroot, :]).max()
        if gravity and tilts:
            assert block > 1e-3 * scale  # gravity depends on the root's attitude
        elif not gravity:
            assert block == 0.0 and np.abs(F2c[:, :, :, :nroot]).max() == 0.0
            assert np.abs(F2p[:, :, :nroot, :]).max() < 1e-6 * scale  # the oracle: differences of zero
        assert np.abs(F2c - F2p).max() / scale < 2e-6


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_variational_expansion_equals_python(case, monkeypatch):
    """The core's whole expansion (its F1, F2 and the explicit-Euler reconstruction in C++) equals
    the Python reconstruction fed the core's F1, F2 (tight), and the Python oracle (at its
    accuracy)."""
    py, cc = _models(case, "variational")
    q0, v0, _ = _state(py, 41)
    U = np.random.default_rng(42).normal(size=(3, py.nu))
    Q, V = py.rollout(q0, v0, U)
    e1, e2 = cc.expansion(Q, V, U, order=1), cc.expansion(Q, V, U, order=2)
    assert e1.Theta is None and np.array_equal(e1.Phi, e2.Phi) and np.array_equal(e1.B, e2.B)
    exact = _var_F(cc, Q[:-1], V[:-1], V[1:])
    monkeypatch.setattr(type(py._variational), "velocity_derivatives", lambda self, *a, **k: exact)
    ef = py.expansion(Q, V, U, order=2)
    assert _rel(e2.Phi, ef.Phi) < 1e-13 and _rel(e2.B, ef.B) < 1e-13
    for name in ("Theta", "Gamma", "Xi"):
        assert _rel(getattr(e2, name), getattr(ef, name)) < 1e-12, name
    monkeypatch.undo()
    ep = py.expansion(Q, V, U, order=2)
    assert _rel(e2.Phi, ep.Phi) < 1e-10 and _rel(e2.B, ep.B) < 1e-10
    for name in ("Theta", "Gamma", "Xi"):
        assert _rel(getattr(e2, name), getattr(ep, name)) < 2e-6, name


def test_variational_step_that_cannot_converge_raises_or_rejects_the_trial():
    from geoddp.models.variational import StepDidNotConverge

    urdf = urdf_file("test_all_joints.urdf")
    for cls in (Multibody, OracleMultibody):
        mb = cls(urdf, root="free_flyer", dt=2.0, integrator="variational")
        with pytest.raises(StepDidNotConverge, match=r"dt = 2.0 s \(\|v\| = 155\)"):
            mb.rollout(mb.neutral(), np.full(mb.nv, 40.0), np.zeros((3, mb.nu)))
        # in a forward pass the same step is a rejected trial (False), as a non-finite state is
        p = _problem(mb, mb.neutral(), np.full(mb.nv, 40.0), 3)
        Qb, Vb, Ub = np.tile(mb.neutral(), (4, 1)), np.zeros((4, mb.nv)), np.zeros((3, mb.nu))
        Qo, Vo, Uo = np.empty_like(Qb), np.empty_like(Vb), np.empty_like(Ub)
        assert not p.rollout_closed_loop(Qb, Vb, Ub, np.zeros((3, mb.nu)), np.zeros((3, mb.nu, mb.nx)), 1.0, Qo, Vo, Uo)


def test_compiled_joint_classification_is_the_python_one():
    """cpp/lie/joint_groups.hpp and geoddp.lie.product.joint_groups accept and refuse the same joints:
    thirteen joint types of pin, one per model on a fixed base (a structural rule, nq == nv means
    R^k, would accept the helical and universal joints that the Python rule refuses)."""
    makers = {
        "RX": pin.JointModelRX, "PY": pin.JointModelPY, "RUBZ": pin.JointModelRUBZ,
        "RevoluteUnaligned": lambda: pin.JointModelRevoluteUnaligned(np.array([0.0, 0.6, 0.8])),
        "PrismaticUnaligned": lambda: pin.JointModelPrismaticUnaligned(np.array([0.6, 0.0, 0.8])),
        "RevoluteUnboundedUnaligned": pin.JointModelRevoluteUnboundedUnaligned,
        "Spherical": pin.JointModelSpherical, "SphericalZYX": pin.JointModelSphericalZYX,
        "FreeFlyer": pin.JointModelFreeFlyer, "Translation": pin.JointModelTranslation,
        "Planar": pin.JointModelPlanar, "HX": pin.JointModelHX,
        "Universal": lambda: pin.JointModelUniversal(np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])),
    }
    accepted = set()
    for name, make in makers.items():
        model = pin.Model()
        j = model.addJoint(0, make(), pin.SE3.Identity(), "j")
        model.appendBodyToJoint(j, pin.Inertia.Random(), pin.SE3.Identity())
        try:
            cfg.joint_groups(model)
            python_ok = True
        except ValueError:
            python_ok = False
        try:
            core.testing.block_ad_jr(model, np.zeros(model.nv))
            compiled_ok = True
        except ValueError as exc:
            assert "is not supported" in str(exc) and "'j'" in str(exc), str(exc)
            compiled_ok = False
        assert compiled_ok == python_ok, name
        if python_ok:
            accepted.add(name)
    assert {"RX", "RUBZ", "Spherical", "FreeFlyer", "Translation"} <= accepted
    assert not {"Planar", "HX", "Universal", "SphericalZYX"} & accepted


def test_spherical_zyx_is_refused_because_pinocchio_derivatives_do_not_hold_for_it():
    """Why the joint groups refuse spherical ZYX (its motion subspace moves with q): Pinocchio's
    analytic RNEA and ABA derivatives along q disagree with central differences of rnea and aba on a
    chain holding one (measured 4.1 and 27 at 1e-6, against ~1e-8 on the same chain with a
    spherical joint instead). Should Pinocchio's derivatives come to hold for it, this fails and the
    joint can be accepted again."""
    def chain(middle):
        rng = np.random.default_rng(5)
        model, parent = pin.Model(), 0
        for i, joint in enumerate([pin.JointModelFreeFlyer(), pin.JointModelRX(), middle, pin.JointModelRY()]):
            parent = model.addJoint(parent, joint, pin.SE3(pin.exp3(rng.normal(size=3)), rng.normal(size=3) * 0.3), f"j{i}")
            model.appendBodyToJoint(parent, pin.Inertia(1.0 + i, rng.normal(size=3) * 0.2, np.diag([0.1, 0.2, 0.3])),
                                    pin.SE3.Identity())
        return model

    def worst(model):
        data, rng, h = model.createData(), np.random.default_rng(6), 1e-6
        q = pin.integrate(model, pin.neutral(model), 0.7 * rng.normal(size=model.nv))
        v, a = rng.normal(size=model.nv), rng.normal(size=model.nv)
        pin.computeRNEADerivatives(model, data, q, v, a)
        dtau = data.dtau_dq.copy()
        pin.computeABADerivatives(model, data, q, v, a)
        dddq = data.ddq_dq.copy()
        errors = [0.0, 0.0]
        for j in range(model.nv):
            e = np.zeros(model.nv)
            e[j] = h
            qp, qm = pin.integrate(model, q, e), pin.integrate(model, q, -e)
            fd_tau = (pin.rnea(model, data, qp, v, a) - pin.rnea(model, data, qm, v, a)) / (2 * h)
            fd_ddq = (pin.aba(model, data, qp, v, a) - pin.aba(model, data, qm, v, a)) / (2 * h)
            errors = [max(errors[0], np.abs(dtau[:, j] - fd_tau).max()), max(errors[1], np.abs(dddq[:, j] - fd_ddq).max())]
        return errors

    assert max(worst(chain(pin.JointModelSpherical()))) < 1e-6
    assert min(worst(chain(pin.JointModelSphericalZYX()))) > 1e-2


def test_default_threads_counts_the_cores_this_process_may_use():
    """default_threads() is min(2, cores in the process's affinity mask), not the machine's core
    count: under `taskset -c 0` two workers would time-slice one core (the two-worker backward
    pass had run 36x slower so). A child pinned to one core must see 1; this process, min(2, its
    mask)."""
    import os
    import subprocess
    import sys

    allowed = os.sched_getaffinity(0)
    assert compiled._core.default_threads() == min(2, len(allowed))
    one = min(allowed)
    code = ("import os; os.sched_setaffinity(0, {%d}); from geoddp.models import compiled; "
            "print(compiled._core.default_threads())" % one)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == "1"
