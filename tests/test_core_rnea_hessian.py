"""RNEA's second derivatives contracted with a vector by a spatial-vector recursion
(cpp/rigid_body/rnea_hessian.hpp), the contracted backward pass's second order for articulated models.

For phi(q, v) = mu^T RNEA(q, v, a) at fixed a and mu, _core.testing.rnea_hessian gives
Hqq = d_l d_j phi (trivialised, iterated), Hvv, Hqv = d_j dphi/dv_l and Dm = d_l (M mu)_j. Checked

* against Pinocchio's ComputeRNEASecondOrderDerivatives (what it replaces) contracted with mu,
  sum_i mu_i X(i, j, l), to 1e-12 relative;
* against central differences of Pinocchio's analytic first derivatives mu^T dtau/dq,
  mu^T dtau/dv (computeRNEADerivatives) and of M(q) mu along q exp(+-h e_l) and v +- h e_l, to
  1e-7 relative;

on the kinetic-energy tests' six models (a free-flyer arm, a fixed base with every URDF joint
type, a spherical root carrying a chain, a branching tree with mid-tree spherical, translation,
prismatic and unaligned joints, the UR5 and Solo12), gravity on and off, near the identity and at
random configurations. Then the pass that uses it: the contracted S, the backward pass and whole
solves equal those from Pinocchio's tensors (the form before, kept behind
_core.testing.set_rnea_hessian_recursion(False)) to round-off.
"""
import numpy as np
import pinocchio as pin
import pytest

from geoddp.models import compiled
from geoddp.models.multibody import Multibody
from geoddp.solver import SolverOptions, solve
from test_core_kinetic_hessian import MODELS
from urdfs import urdf as urdf_file

core = compiled._core


def _states(model, seed):
    rng = np.random.default_rng(seed)
    for spread in (1e-6, 0.7, 2.0):
        q = pin.integrate(model, pin.neutral(model), spread * rng.normal(size=model.nv))
        yield q, rng.normal(size=model.nv), rng.normal(size=model.nv), rng.normal(size=model.nv)


def _contracted_pinocchio(model, q, v, a, mu):
    tensors = core.rnea_second_order(model, q, v, a, False)
    return [np.einsum("i,ijl->jl", mu, X) for X in tensors]


def _differenced(model, q, v, a, mu, h=1e-6):
    """Central differences of Pinocchio's analytic first derivatives: (Hqq, Hvv, Hqv, Dm)."""
    data = model.createData()

    def first(qq, vv):
        pin.computeRNEADerivatives(model, data, qq, vv, a)
        M = pin.crba(model, model.createData(), qq)
        M = np.triu(M) + np.triu(M, 1).T
        return mu @ data.dtau_dq, mu @ data.dtau_dv, M @ mu

    nv = model.nv
    Hqq, Hvv, Hqv, Dm = (np.empty((nv, nv)) for _ in range(4))
    for l in range(nv):
        e = np.zeros(nv)
        e[l] = h
        gp, gm = first(pin.integrate(model, q, e), v), first(pin.integrate(model, q, -e), v)
        Hqq[:, l] = (gp[0] - gm[0]) / (2 * h)
        Dm[:, l] = (gp[2] - gm[2]) / (2 * h)
        gp, gm = first(q, v + e), first(q, v - e)
        Hqv[:, l] = (gp[0] - gm[0]) / (2 * h)
        Hvv[:, l] = (gp[1] - gm[1]) / (2 * h)
    return Hqq, Hvv, Hqv, Dm


NAMES = ["Hqq", "Hvv", "Hqv", "Dm"]


@pytest.mark.parametrize("gravity", [True, False], ids=["gravity", "no_gravity"])
@pytest.mark.parametrize("name", list(MODELS))
def test_rnea_hessian_equals_pinocchio_and_differences(name, gravity):
    model = MODELS[name]()
    if not gravity:
        model.gravity.setZero()
    for q, v, a, mu in _states(model, seed=len(name) + gravity):
        got = core.testing.rnea_hessian(model, q, v, a, mu)
        ref = _contracted_pinocchio(model, q, v, a, mu)
        fd = _differenced(model, q, v, a, mu)
        for label, x, r, d in zip(NAMES, got, ref, fd):
            scale = max(1.0, np.abs(r).max())
            assert np.abs(r).max() > 1e-3, (name, label)  # not a comparison of zeros
            assert np.abs(x - r).max() <= 1e-12 * scale, (name, label, np.abs(x - r).max() / scale)
            assert np.abs(x - d).max() <= 1e-7 * scale, (name, label, np.abs(x - d).max() / scale)
        # Hvv is symmetric (v is flat); Hqq is not in a free-flyer's or spherical joint's own block
        assert np.abs(got[1] - got[1].T).max() <= 1e-12 * max(1.0, np.abs(got[1]).max())


def test_rnea_hessian_refuses_bad_input():
    model = MODELS["free_flyer_arm"]()
    q, v = pin.neutral(model), np.zeros(model.nv)
    with pytest.raises(ValueError, match="mu"):
        core.testing.rnea_hessian(model, q, v, v, np.zeros(model.nv + 1))
    with pytest.raises(ValueError, match="q"):
        core.testing.rnea_hessian(model, q[:-1], v, v, v)


CASES = [
    ("space_manipulator.urdf", "free_flyer", True),
    ("space_manipulator.urdf", "fixed", True),
    ("space_manipulator.urdf", "spherical", False),
    ("test_all_joints.urdf", "fixed", True),
]
IDS = [f"{u.split('.')[0]}-{r}-{'g' if g else 'nog'}" for u, r, g in CASES]


@pytest.fixture
def tensor_form():
    """Runs the body with Pinocchio's tensors in the contracted pass; the recursion after."""
    def use(on):
        core.testing.set_rnea_hessian_recursion(not on)
    yield use
    core.testing.set_rnea_hessian_recursion(True)


@pytest.mark.parametrize("integrator", ["euler", "semi_implicit"])
@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_contracted_terms_equal_pinocchio_form(case, integrator, tensor_form):
    """S = sum_i Vx_i G2_i from the recursion equals S from Pinocchio's stored tensors (the dense
    Theta, Gamma, Xi are compared with the default, recursive form in tests/test_core_contracted.py)."""
    urdf, root, gravity = case
    mb = Multibody(urdf_file(urdf), root=root, dt=0.01, integrator=integrator, gravity=gravity)
    rng = np.random.default_rng(5)
    q0 = pin.integrate(mb.pin_model, mb.neutral(), 0.7 * rng.normal(size=mb.nv))
    U = rng.normal(size=(8, mb.nu))
    Q, V = mb.rollout(q0, rng.normal(size=mb.nv), U)
    assert core.testing.rnea_hessian_recursion()
    t = mb.expansion(Q, V, U, order=2, contracted=True).terms
    tensor_form(True)
    ref = mb.expansion(Q, V, U, order=2, contracted=True).terms
    tensor_form(False)
    assert t.recursion and not ref.recursion
    for k in range(U.shape[0]):
        Vx = rng.normal(size=2 * mb.nv) * 10.0 ** rng.uniform(-2, 2)
        S, R = t.contract(k, Vx), ref.contract(k, Vx)
        assert np.abs(R).max() > 1e-6
        assert np.abs(S - R).max() <= 1e-13 * max(1.0, np.abs(R).max())


def test_terms_keep_their_model_alive():
    """The terms read the model in the pass: deleting every other reference to it is safe."""
    import gc

    mb = Multibody(urdf_file("space_manipulator.urdf"), root="free_flyer", dt=0.01, integrator="semi_implicit",
                   gravity=True)
    rng = np.random.default_rng(2)
    U = rng.normal(size=(4, mb.nu))
    Q, V = mb.rollout(mb.neutral(), np.zeros(mb.nv), U)
    t = mb.expansion(Q, V, U, order=2, contracted=True).terms
    Vx = rng.normal(size=2 * mb.nv)
    before = t.contract(2, Vx)
    del mb
    gc.collect()
    assert np.array_equal(t.contract(2, Vx), before)


@pytest.mark.parametrize("expansion", ["second", "switch"])
def test_solve_history_equals_pinocchio_form(expansion, tensor_form):
    """A whole semi-implicit solve of the space manipulator with the recursion keeps the iterations
    and expansion sequence of the solve on Pinocchio's tensors, and its histories to round-off."""
    from geoddp.scene import builtin as scenes

    res = {}
    for recursion in (True, False):
        tensor_form(not recursion)
        res[recursion] = solve(scenes.space_manipulator(integrator="semi_implicit"),
                               SolverOptions(expansion=expansion, verbose=False))
    tensor_form(False)
    a, b = res[True], res[False]
    assert a.iterations == b.iterations and a.status == b.status
    assert a.expansion_history == b.expansion_history
    for name in ("cost_history", "reg_history", "step_history"):
        x, y = np.asarray(getattr(a, name), float), np.asarray(getattr(b, name), float)
        assert x.shape == y.shape
        assert np.all(np.abs(x - y) <= 1e-10 * np.abs(y)), name
    assert abs(a.cost - b.cost) <= 1e-12 * abs(b.cost)
    assert np.abs(a.controls - b.controls).max() <= 1e-10 * np.abs(b.controls).max()
