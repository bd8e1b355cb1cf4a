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
* bad input raises InputError naming the parameter before any C++ runs;
* every built-in multibody scene solves to the same J* (1e-9 relative) in the same iterations.
"""
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from geoddp import configuration as cfg
from geoddp.lie import SE3
from geoddp.models import compiled
from geoddp.models.multibody import Multibody
from geoddp.validate import InputError

if not compiled.available():  # pragma: no cover - the build is part of the install
    pytest.fail(f"geoddp._core does not import: {compiled.IMPORT_ERROR}", pytrace=False)

core = compiled._core
MODELS = Path(__file__).resolve().parents[1] / "models"
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
    py = Multibody(MODELS / urdf, backend="python", **kw)
    cc = Multibody(MODELS / urdf, **kw)
    assert cc.backend == "compiled"
    return py, cc


def _state(model, seed, spread=0.7):
    rng = np.random.default_rng(seed)
    q = pin.integrate(model.pin_model, model.neutral(), spread * rng.normal(size=model.nv))
    return q, rng.normal(size=model.nv), rng.normal(size=model.nu)


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


# ---------------------------------------------------------------------------- rollouts
@pytest.mark.parametrize("integrator", ["euler", "semi_implicit"])
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
    from geoddp.multibody_costs import ControlRegularisation, MultibodyCostSum
    from geoddp.multibody_problem import MultibodyProblem

    cost = MultibodyCostSum([ControlRegularisation(np.zeros(model.nu))], model=model.pin_model)
    return MultibodyProblem(model, q0, v0, H, cost, MultibodyCostSum([], model=model.pin_model, terminal=True))


@pytest.mark.parametrize("integrator", ["euler", "semi_implicit"])
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
    # the feedback really acted (zeta != 0 along the way), far above the agreement tolerance
    assert _rel(outs[1][2], Ubar - 0.5 * kff) > 1e-6
    # a non-finite state stops both passes with False
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
        F1c, F2c = core.velocity_derivatives(cc.pin_model, cc.actuation, cc.dt, q[None], v[None], u[None], 2, 1)
        F1p, F2p = py.velocity_derivatives(q[None], v[None], u[None], order=2)
        assert _rel(F1c, F1p) < 1e-13
        scale = max(1.0, float(np.abs(F2c).max()))
        assert np.abs(F2c).max() > 1e-4  # not trivially zero
        assert np.abs(F2c[0] - _F2_differences(py, q, v, u)).max() / scale < 1e-9
        assert np.abs(F2c - F2p).max() / scale < 2e-8  # the oracle's own differencing error
        assert np.array_equal(F2c, np.swapaxes(F2c, 2, 3))


def test_threads_give_identical_results():
    py, cc = _models(CASES[3], "semi_implicit")
    q0, v0, _ = _state(py, 8)
    U = np.random.default_rng(9).normal(size=(17, py.nu))
    Q, V = cc.rollout(q0, v0, U)
    one = core.expansion(cc.pin_model, cc.actuation, cc.dt, 1, Q, V, U, 2, 1)
    for t in (2, 3, 0):
        other = core.expansion(cc.pin_model, cc.actuation, cc.dt, 1, Q, V, U, 2, t)
        for a, b in zip(one, other):
            assert np.array_equal(a, b)


# ---------------------------------------------------------------------------- reconstruction
ANGLES = [0.0, 1e-8, 1e-6, 1e-4, 1e-3, 1e-2, 0.2, 0.26, 0.49, 0.51, 0.59, 0.61, 1.0, 2.0, 3.0, np.pi - 1e-3]


@pytest.mark.parametrize("angle", ANGLES)
def test_closed_forms_equal_python(angle):
    rng = np.random.default_rng(int(angle * 1e3) + 11)
    ff = Multibody(MODELS / "space_manipulator.urdf", root="free_flyer", dt=0.01)
    sp = Multibody(MODELS / "satellite.urdf", root="spherical", dt=0.01)
    for model in (ff, sp):
        nv = model.nv
        omega = rng.normal(size=nv)
        g = model.groups[0]
        axis = rng.normal(size=3)
        omega[g.idx_v + g.nv - 3 : g.idx_v + g.nv] = angle * axis / np.linalg.norm(axis)
        A, J, D = core.block_ad_jr(model.pin_model, omega)
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
    ep = py.expansion(Q, V, U, order=2)
    for name in ("Theta", "Gamma", "Xi"):
        a, b = getattr(ec, name), getattr(ep, name)
        assert a.shape == b.shape
        assert _rel(a, b) < 2e-8  # the oracle's differencing error
    # the reconstruction alone, tight: the Python assembly fed the core's exact F1, F2
    exact = core.velocity_derivatives(cc.pin_model, cc.actuation, cc.dt, Q[:-1], V[:-1], U, 2, 1)
    monkeypatch.setattr(Multibody, "velocity_derivatives", lambda self, *a, **k: exact)
    ef = py.expansion(Q, V, U, order=2)
    for name in ("Theta", "Gamma", "Xi"):
        assert _rel(getattr(ec, name), getattr(ef, name)) < 1e-11


# ---------------------------------------------------------------------------- bad input
def test_bad_input_names_the_parameter():
    urdf = MODELS / "quadrotor.urdf"
    with pytest.raises(InputError, match="backend"):
        Multibody(urdf, dt=0.01, backend="fast")
    with pytest.raises(InputError, match="backend"):
        Multibody(urdf, dt=0.01, integrator="rk4", backend="compiled")
    with pytest.raises(InputError, match="threads"):
        Multibody(urdf, dt=0.01, threads=-1)
    assert Multibody(urdf, dt=0.01, integrator="rk4").backend == "python"
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
    from geoddp.api import solve_scene

    res = {}
    for backend in ("python", "compiled"):
        monkeypatch.setenv("GEODDP_MULTIBODY_BACKEND", backend)
        res[backend] = solve_scene(EXAMPLES / scene, verbose=False)
    a, b = res["compiled"], res["python"]
    assert a.iterations == b.iterations
    assert a.expansion_history == b.expansion_history
    assert abs(a.cost - b.cost) <= 1e-9 * abs(b.cost)
    # Intermediate J: the quadrotor's iterations amplify round-off ~1e8-fold (measured: 1-ulp
    # noise on the Python path's own Phi, B moves its J history by up to 3.6e-8 relative; the
    # core differs by up to 1.1e-7, also from its exact F2 where the oracle differences).
    assert np.max(np.abs(a.cost_history - b.cost_history) / np.abs(b.cost_history)) < 1e-6
