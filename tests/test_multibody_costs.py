"""Multibody cost terms: gradients and (0)-Hessians against finite differences along the
retraction curves s -> (integrate(q, s dq), v + s dv), on a free-flyer robot with a 3-joint arm
(SE(3) x U(1) x R x R configuration) and on a fixed-base arm (Euclidean configuration)."""
import numpy as np
import pinocchio as pin
import pytest

from geoddp.costs import CostDerivatives
from geoddp.costs.multibody import (
    ControlRegularisation,
    FramePlacement,
    FrameRotation,
    FrameTranslation,
    MultibodyCostSum,
    StateRegularisation,
    tracking_costs,
)
from geoddp.validate import InputError
from oracle_costs import accumulate as oracle_accumulate, curved_dofs, use_cost_oracle

GRAD_TOL = 1e-7  # relative to max(1, max|l_x|); measured ~1e-10
HESS_TOL = 1e-5  # relative to max(1, max|l_xx|); measured ~1e-8 (4-point stencil, h = 3e-4)


def _arm(model: pin.Model, parent: int, first: pin.JointModel) -> None:
    """Three revolute joints (the first given), unaligned axes and offsets, and a 'tool' frame."""
    j1 = model.addJoint(parent, first, pin.SE3(np.eye(3), np.array([0.1, 0.0, 0.2])), "j1")
    model.appendBodyToJoint(j1, pin.Inertia.Random(), pin.SE3.Identity())
    j2 = model.addJoint(j1, pin.JointModelRY(), pin.SE3(pin.exp3(np.array([0.2, 0.1, 0.0])), np.array([0, 0, 0.3])), "j2")
    model.appendBodyToJoint(j2, pin.Inertia.Random(), pin.SE3.Identity())
    axis = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    j3 = model.addJoint(j2, pin.JointModelRevoluteUnaligned(axis), pin.SE3(np.eye(3), np.array([0, 0, 0.25])), "j3")
    model.appendBodyToJoint(j3, pin.Inertia.Random(), pin.SE3.Identity())
    tool = pin.SE3(pin.exp3(np.array([0.3, -0.2, 0.5])), np.array([0.05, 0.02, 0.1]))
    model.addFrame(pin.Frame("tool", j3, tool, pin.FrameType.OP_FRAME))


def floating_arm() -> pin.Model:
    """Free flyer + unbounded revolute (nq 2, nv 1) + RY + unaligned revolute: nq 11, nv 9."""
    model = pin.Model()
    model.name = "floating_arm"
    root = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "root")
    model.appendBodyToJoint(root, pin.Inertia.Random(), pin.SE3.Identity())
    _arm(model, root, pin.JointModelRUBZ())
    return model


def fixed_arm() -> pin.Model:
    """Three revolute joints on a fixed base: nq = nv = 3 (Euclidean configuration)."""
    model = pin.Model()
    model.name = "fixed_arm"
    _arm(model, 0, pin.JointModelRZ())
    return model


FLOATING = floating_arm()
FIXED = fixed_arm()


@pytest.fixture(autouse=True, params=["kernels", "oracle"])
def evaluation(request, monkeypatch):
    """Every test runs twice: on the package's compiled kernels, and with every cost sum on the
    tests' Python oracle (tests/oracle_costs.py), which the kernels are compared with in
    tests/test_core_costs.py: both must match finite differences."""
    if request.param == "oracle":
        use_cost_oracle(monkeypatch)
    return request.param


def _random_q(model, rng):
    # from the numpy generator (pin.randomConfiguration has its own, unseeded, generator);
    # tangent entries in [-1.5, 1.5] keep every rotation well inside the injectivity radius
    return pin.integrate(model, pin.neutral(model), rng.uniform(-1.5, 1.5, model.nv))


def _spd(n, rng):
    A = rng.normal(size=(n, n))
    return A @ A.T / n + 0.5 * np.eye(n)  # full (non-diagonal) SPD weight


def _tool(model, q):
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    return pin.updateFramePlacement(model, data, model.getFrameId("tool")).copy()


def _fd_errors(cost: MultibodyCostSum, q, v, u):
    """Relative errors (gradient, Hessian) of cost.derivatives against finite differences of
    f(z) = l(integrate(q, z_q), v + z_v, u + z_u) (stencils as in tests/test_costs.py)."""
    model = cost.model
    nv = model.nv
    m = 0 if u is None else u.size
    d = cost.derivatives(q[None], v[None], None if u is None else u[None])

    def f(z):
        qp = pin.integrate(model, q, z[:nv])
        up = None if u is None else (u + z[2 * nv:])[None]
        return cost.value(qp[None], (v + z[nv:2 * nv])[None], up)[0]

    n = 2 * nv + m
    h = 1e-5
    grad = np.array([(f(h * e) - f(-h * e)) / (2 * h) for e in np.eye(n)])
    hh = 3e-4
    E = hh * np.eye(n)
    hess = np.empty((n, n))
    for i in range(n):
        for j in range(i, n):
            # (0)-Hessian: second derivative along one-parameter curves, polarised
            hess[i, j] = hess[j, i] = (f(E[i] + E[j]) - f(E[i] - E[j]) - f(-E[i] + E[j]) + f(-E[i] - E[j])) / (4 * hh * hh)
    an_g = np.concatenate([d.lx[0], d.lu[0]])
    an_h = np.zeros((n, n))
    an_h[:2 * nv, :2 * nv] = d.lxx[0]
    an_h[2 * nv:, 2 * nv:] = d.luu[0]
    an_h[2 * nv:, :2 * nv] = d.lux[0]
    an_h[:2 * nv, 2 * nv:] = d.lux[0].T
    eg = np.abs(grad - an_g).max() / max(1.0, np.abs(grad).max())
    eh = np.abs(hess - an_h).max() / max(1.0, np.abs(hess).max())
    return eg, eh, d, hess


def _target(model, q, rng, angle):
    """A reference placement at relative rotation ``angle`` (rad) from the tool's (not near pi)."""
    ax = rng.normal(size=3)
    return _tool(model, q) * pin.SE3(pin.exp3(angle * ax / np.linalg.norm(ax)), rng.normal(size=3) * 0.3)


def _terms(kind, model, q, rng, angle=1.2, gauss_newton=False):
    M = _target(model, q, rng, angle)
    if kind == "placement":
        return FramePlacement(model, "tool", M, _spd(6, rng), gauss_newton=gauss_newton)
    if kind == "rotation":
        return FrameRotation(model, "tool", M.rotation, _spd(3, rng), gauss_newton=gauss_newton)
    if kind == "translation":
        return FrameTranslation(model, "tool", M.translation, _spd(3, rng), gauss_newton=gauss_newton)
    if kind == "state":
        return StateRegularisation(model, _random_q(model, rng), rng.normal(size=model.nv),
                                   _spd(2 * model.nv, rng), gauss_newton=gauss_newton)
    raise AssertionError(kind)


KINDS = ["placement", "rotation", "translation", "state"]


# --------------------------------------------------------------------------------------
# conventions


def test_local_frame_jacobian_is_right_trivialised(rng):
    """oMf(integrate(q, s dq)) = oMf(q) exp6(s J_LOCAL dq) + O(s^2), [linear; angular]."""
    model, data = FLOATING, FLOATING.createData()
    fid = model.getFrameId("tool")
    q = _random_q(model, rng)
    J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)
    M0 = _tool(model, q)
    h = 1e-6
    for dq in np.eye(model.nv):
        Mp, Mm = _tool(model, pin.integrate(model, q, h * dq)), _tool(model, pin.integrate(model, q, -h * dq))
        fd = (pin.log6(M0.inverse() * Mp).vector - pin.log6(M0.inverse() * Mm).vector) / (2 * h)
        assert np.abs(fd - J @ dq).max() < 1e-8


# --------------------------------------------------------------------------------------
# derivatives against finite differences


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("kind", KINDS)
def test_terms_match_finite_differences_floating(kind, seed):
    rng = np.random.default_rng(100 + seed)
    q, v = _random_q(FLOATING, rng), rng.normal(size=FLOATING.nv)
    term = _terms(kind, FLOATING, q, rng, angle=[0.3, 1.5, 2.6][seed])
    eg, eh, _, _ = _fd_errors(MultibodyCostSum([term]), q, v, None)
    assert eg < GRAD_TOL and eh < HESS_TOL, (eg, eh)


@pytest.mark.parametrize("kind", KINDS)
def test_terms_match_finite_differences_fixed_base(kind, rng):
    q, v = _random_q(FIXED, rng), rng.normal(size=FIXED.nv)
    term = _terms(kind, FIXED, q, rng)
    eg, eh, _, _ = _fd_errors(MultibodyCostSum([term]), q, v, None)
    assert eg < GRAD_TOL and eh < HESS_TOL, (eg, eh)


def test_state_regularisation_is_closed_form_on_euclidean_configurations():
    """The oracle differences no direction on a fixed-base arm; on the floating robot only the
    curved dofs (6 free-flyer + 1 unbounded revolute)."""
    assert curved_dofs(FIXED).size == 0
    assert list(curved_dofs(FLOATING)) == [0, 1, 2, 3, 4, 5, 6]


def test_sum_with_control_matches_finite_differences(rng):
    """A running sum of every term (with a control term: l_u, l_uu, l_ux) against FD."""
    q, v, u = _random_q(FLOATING, rng), rng.normal(size=FLOATING.nv), rng.normal(size=4)
    terms = [_terms(k, FLOATING, q, rng) for k in KINDS]
    terms.append(ControlRegularisation(rng.normal(size=4), _spd(4, rng)))
    eg, eh, d, _ = _fd_errors(MultibodyCostSum(terms), q, v, u)
    assert eg < GRAD_TOL and eh < HESS_TOL, (eg, eh)
    assert d.lu.shape == (1, 4) and d.luu.shape == (1, 4, 4) and np.all(d.lux == 0.0)


@pytest.mark.parametrize("kind", ["placement", "rotation", "translation", "state"])
def test_gauss_newton_misses_the_second_order_part_away_from_the_optimum(kind, rng):
    """The exact Hessian's second-order part is not negligible here, so the exact-vs-FD tests
    above would catch its omission; the GN Hessian fails the same check."""
    q, v = _random_q(FLOATING, rng), rng.normal(size=FLOATING.nv)
    gn = _terms(kind, FLOATING, q, np.random.default_rng(5), gauss_newton=True)
    ex = _terms(kind, FLOATING, q, np.random.default_rng(5), gauss_newton=False)
    _, eh_gn, d_gn, _ = _fd_errors(MultibodyCostSum([gn]), q, v, None)
    _, eh_ex, d_ex, _ = _fd_errors(MultibodyCostSum([ex]), q, v, None)
    assert eh_ex < HESS_TOL and eh_gn > 1e-3, (eh_ex, eh_gn)
    assert np.array_equal(d_gn.lx, d_ex.lx)  # the option only changes l_xx


@pytest.mark.parametrize("model", [FLOATING, FIXED], ids=["floating", "fixed"])
def test_value_and_gradient_exactly_zero_at_the_reference_and_gn_equals_exact(model, rng):
    q, v = _random_q(model, rng), rng.normal(size=model.nv)
    M = _tool(model, q)
    for gn in (False, True):
        terms = [FramePlacement(model, "tool", M, _spd(6, rng), gauss_newton=gn),
                 FrameRotation(model, "tool", M.rotation, _spd(3, rng), gauss_newton=gn),
                 FrameTranslation(model, "tool", M.translation, _spd(3, rng), gauss_newton=gn),
                 StateRegularisation(model, q, v, _spd(2 * model.nv, rng), gauss_newton=gn)]
        for t in terms:
            d = MultibodyCostSum([t]).derivatives(q[None], v[None], None)
            assert d.l[0] == 0.0 and np.all(d.lx == 0.0), type(t).__name__
            assert MultibodyCostSum([t]).value(q[None], v[None], None)[0] == 0.0
    u_ref = rng.normal(size=3)
    dc = MultibodyCostSum([ControlRegularisation(u_ref, [1.0, 2.0, 3.0])], model=model).derivatives(q[None], v[None], u_ref[None])
    assert dc.l[0] == 0.0 and np.all(dc.lu == 0.0)
    # at r = 0 the second-order part vanishes: GN and exact Hessians are identical, and both
    # match finite differences
    for kind_cls, ref in [(FramePlacement, M), (FrameRotation, M.rotation), (FrameTranslation, M.translation)]:
        W = _spd(kind_cls.nr, np.random.default_rng(3))
        a = MultibodyCostSum([kind_cls(model, "tool", ref, W)])
        b = MultibodyCostSum([kind_cls(model, "tool", ref, W, gauss_newton=True)])
        _, eh, da, _ = _fd_errors(a, q, v, None)
        db = b.derivatives(q[None], v[None], None)
        assert np.array_equal(da.lxx, db.lxx) and eh < HESS_TOL, (kind_cls.__name__, eh)
    W = _spd(2 * model.nv, np.random.default_rng(4))
    da = MultibodyCostSum([StateRegularisation(model, q, v, W)]).derivatives(q[None], v[None], None)
    db = MultibodyCostSum([StateRegularisation(model, q, v, W, gauss_newton=True)]).derivatives(q[None], v[None], None)
    assert np.array_equal(da.lxx, db.lxx)


# --------------------------------------------------------------------------------------
# weights, terminal use, tracking


def test_weight_forms_are_equivalent(rng):
    """A scalar, a diagonal vector and the equivalent matrix give the same derivatives."""
    q, v = _random_q(FLOATING, rng), rng.normal(size=FLOATING.nv)
    M = _target(FLOATING, q, rng, 1.0)
    w = np.array([1.0, 2.0, 3.0, 0.5, 0.25, 4.0])
    ds = [MultibodyCostSum([FramePlacement(FLOATING, "tool", M, W)]).derivatives(q[None], v[None], None)
          for W in (w, np.diag(w))]
    assert np.allclose(ds[0].lxx, ds[1].lxx, rtol=0, atol=1e-12) and np.array_equal(ds[0].lx, ds[1].lx)
    d2 = [MultibodyCostSum([FrameTranslation(FLOATING, "tool", M.translation, W)]).derivatives(q[None], v[None], None)
          for W in (2.5, 2.5 * np.eye(3))]
    assert np.array_equal(d2[0].lx, d2[1].lx)


def test_terminal_use_has_empty_control_derivatives(rng):
    q, v = _random_q(FLOATING, rng), rng.normal(size=FLOATING.nv)
    terms = [_terms(k, FLOATING, q, rng) for k in KINDS]
    d = MultibodyCostSum(terms, terminal=True).derivatives(q[None], v[None], None)
    assert d.lu.shape == (1, 0) and d.luu.shape == (1, 0, 0) and d.lux.shape == (1, 0, 18)
    assert d.lx.shape == (1, 18) and d.lxx.shape == (1, 18, 18) and np.all(np.isfinite(d.lxx))
    assert np.array_equal(d.lxx, np.swapaxes(d.lxx, 1, 2))  # exactly symmetric


def test_control_term_in_terminal_sum_is_refused(rng):
    q, v = _random_q(FLOATING, rng), np.zeros(FLOATING.nv)
    terms = [FrameTranslation(FLOATING, "tool", np.zeros(3)), ControlRegularisation(np.zeros(2))]
    with pytest.raises(InputError, match="terminal") as e:
        MultibodyCostSum(terms).derivatives(q[None], v[None], None)
    assert e.value.parameter == "terms[1]"
    with pytest.raises(InputError, match="terminal"):
        MultibodyCostSum(terms).value(q[None], v[None], None)
    with pytest.raises(InputError, match="ControlRegularisation"):
        MultibodyCostSum(terms, terminal=True)


def test_tracking_follows_per_node_references(rng):
    """A term with N references evaluated on N nodes equals N constant terms, node by node;
    and the derivatives of the stacked evaluation pass the FD check node by node."""
    N = 4
    Q = np.array([_random_q(FLOATING, rng) for _ in range(N)])
    V = rng.normal(size=(N, FLOATING.nv))
    U = rng.normal(size=(N, 2))
    Ms = [_target(FLOATING, Q[k], rng, 0.5 + 0.4 * k) for k in range(N)]
    W6 = _spd(6, rng)
    factories = [
        (lambda M: FramePlacement(FLOATING, "tool", M, W6), Ms),
        (lambda R: FrameRotation(FLOATING, "tool", R, 2.0), [M.rotation for M in Ms]),
        (lambda p: FrameTranslation(FLOATING, "tool", p, [1.0, 2.0, 3.0]), [M.translation for M in Ms]),
        (lambda qr: StateRegularisation(FLOATING, qr, None, 1.0), [_random_q(FLOATING, rng) for _ in range(N)]),
        (lambda ur: ControlRegularisation(ur, [1.0, 3.0]), list(rng.normal(size=(N, 2)))),
    ]
    for factory, refs in factories:
        tracked = MultibodyCostSum([tracking_costs(factory, refs)], model=FLOATING)
        d = tracked.derivatives(Q, V, U)
        assert np.all(d.l > 0.0)
        for k in range(N):
            dk = MultibodyCostSum([factory(refs[k])], model=FLOATING).derivatives(Q[k:k + 1], V[k:k + 1], U[k:k + 1])
            for name in ("l", "lx", "lu", "lxx", "lux", "luu"):
                assert np.array_equal(getattr(d, name)[k], getattr(dk, name)[0]), name
        with pytest.raises(InputError, match="per-node reference of 4 nodes"):
            tracked.derivatives(Q[:3], V[:3], U[:3])


def test_tracking_derivatives_match_finite_differences_per_node(rng):
    N = 3
    Q = np.array([_random_q(FLOATING, rng) for _ in range(N)])
    refs = [_target(FLOATING, Q[k], rng, 1.0).translation for k in range(N)]
    term = tracking_costs(lambda p: FrameTranslation(FLOATING, "tool", p, _spd(3, np.random.default_rng(1))), refs)
    d = MultibodyCostSum([term]).derivatives(Q, np.zeros((N, FLOATING.nv)), None)
    for k in range(N):
        single = MultibodyCostSum([FrameTranslation(FLOATING, "tool", refs[k], _spd(3, np.random.default_rng(1)))])
        eg, _, _, hess = _fd_errors(single, Q[k], np.zeros(FLOATING.nv), None)
        assert eg < GRAD_TOL and np.abs(hess - d.lxx[k]).max() < HESS_TOL * max(1.0, np.abs(hess).max())


def test_derivatives_accumulate_into_given_container(rng, evaluation):
    """accumulate adds (it does not overwrite) so terms can share one CostDerivatives."""
    q, v = _random_q(FLOATING, rng), rng.normal(size=FLOATING.nv)
    t = _terms("placement", FLOATING, q, rng)
    d = CostDerivatives.zeros(1, 0, 18)
    add = t.accumulate if evaluation == "kernels" else (lambda *a: oracle_accumulate(t, *a))
    add(q[None], v[None], None, d)
    add(q[None], v[None], None, d)
    d1 = MultibodyCostSum([t]).derivatives(q[None], v[None], None)
    assert np.allclose(d.lx, 2 * d1.lx, rtol=1e-15, atol=0) and np.allclose(d.lxx, 2 * d1.lxx, rtol=1e-15, atol=0)
    assert np.allclose(t.value(q[None], v[None], None), d1.l, rtol=1e-15, atol=0)


def test_data_is_made_once(rng, monkeypatch, evaluation):
    """The pinocchio Data are made on a sum's first call and kept: no createData after it (the
    oracle's, one per term), and the kernels' workspace holds one model however many calls
    follow (none on the oracle)."""
    t = FramePlacement(FLOATING, "tool", pin.SE3.Identity())
    s = MultibodyCostSum([t])
    q, v = _random_q(FLOATING, rng)[None], np.zeros((1, FLOATING.nv))
    s.derivatives(q, v, None)
    calls = []
    monkeypatch.setattr(pin.Model, "createData", lambda self: calls.append(1))
    for _ in range(3):
        s.derivatives(q, v, None)
        s.value(q, v, None)
    assert not calls and s._workspace.models == (1 if evaluation == "kernels" else 0)


# --------------------------------------------------------------------------------------
# bad inputs


def test_unknown_frame_name_is_named_with_a_suggestion():
    with pytest.raises(InputError, match="did you mean 'tool'") as e:
        FramePlacement(FLOATING, "tol", pin.SE3.Identity())
    assert e.value.parameter == "FramePlacement.frame_name"
    for cls, ref in [(FrameRotation, np.eye(3)), (FrameTranslation, np.zeros(3))]:
        with pytest.raises(InputError) as e:
            cls(FLOATING, "nope", ref)
        assert e.value.parameter == f"{cls.__name__}.frame_name"


@pytest.mark.parametrize("make, param", [
    (lambda W: FramePlacement(FLOATING, "tool", pin.SE3.Identity(), W), "FramePlacement.W"),
    (lambda W: FrameRotation(FLOATING, "tool", np.eye(3), W), "FrameRotation.W"),
    (lambda W: FrameTranslation(FLOATING, "tool", np.zeros(3), W), "FrameTranslation.W"),
    (lambda W: StateRegularisation(FLOATING, pin.neutral(FLOATING), None, W), "StateRegularisation.W"),
    (lambda W: ControlRegularisation(np.zeros(3), W), "ControlRegularisation.W"),
])
def test_bad_weights_are_named(make, param):
    with pytest.raises(InputError, match="expected") as e:
        make(np.eye(2))  # wrong shape
    assert e.value.parameter == param
    with pytest.raises(InputError, match="positive semidefinite") as e:
        make(-1.0)  # not PSD
    assert e.value.parameter == param
    with pytest.raises(InputError, match="finite") as e:
        make(np.nan)
    assert e.value.parameter == param
    make(0.0)  # PSD (zero) weights are allowed


def test_nan_and_malformed_references_are_named():
    bad = pin.SE3.Identity()
    bad.translation = np.array([0.0, np.nan, 0.0])
    cases = [
        (lambda: FramePlacement(FLOATING, "tool", bad), "FramePlacement.M_ref"),
        (lambda: FramePlacement(FLOATING, "tool", np.diag([2.0, 2.0, 2.0, 1.0])), "FramePlacement.M_ref (rotation)"),
        (lambda: FramePlacement(FLOATING, "tool", np.eye(4) * 2), "FramePlacement.M_ref"),  # last row
        (lambda: FramePlacement(FLOATING, "tool", [pin.SE3.Identity(), bad]), "FramePlacement.M_ref"),
        (lambda: FrameRotation(FLOATING, "tool", np.full((3, 3), np.nan)), "FrameRotation.R_ref"),
        (lambda: FrameRotation(FLOATING, "tool", np.diag([1.0, 1.0, -1.0])), "FrameRotation.R_ref"),
        (lambda: FrameTranslation(FLOATING, "tool", [0.0, np.nan, 1.0]), "FrameTranslation.p_ref"),
        (lambda: FrameTranslation(FLOATING, "tool", np.zeros(4)), "FrameTranslation.p_ref"),
        (lambda: StateRegularisation(FLOATING, np.full(FLOATING.nq, np.nan)), "StateRegularisation.q_ref"),
        (lambda: StateRegularisation(FLOATING, np.ones(FLOATING.nq)), "StateRegularisation.q_ref"),  # quaternion not unit
        (lambda: StateRegularisation(FLOATING, pin.neutral(FLOATING), np.full(9, np.inf)), "StateRegularisation.v_ref"),
        (lambda: StateRegularisation(FLOATING, np.zeros(9)), "StateRegularisation.q_ref"),  # nv, not nq
        (lambda: ControlRegularisation([1.0, np.nan]), "ControlRegularisation.u_ref"),
        (lambda: FramePlacement("robot", "tool", pin.SE3.Identity()), "FramePlacement.model"),
    ]
    for make, param in cases:
        with pytest.raises(InputError) as e:
            make()
        assert e.value.parameter.startswith(param), (param, e.value.parameter)


def test_sum_checks_shapes_and_models(rng):
    s = MultibodyCostSum([FrameTranslation(FLOATING, "tool", np.zeros(3))])
    q = _random_q(FLOATING, rng)
    with pytest.raises(InputError) as e:
        s.derivatives(q[None, :9], np.zeros((1, 9)), None)
    assert e.value.parameter == "Q"
    with pytest.raises(InputError) as e:
        s.derivatives(q[None], np.zeros((2, 9)), None)
    assert e.value.parameter == "V"
    with pytest.raises(InputError) as e:
        MultibodyCostSum([FrameTranslation(FLOATING, "tool", np.zeros(3)), FrameTranslation(FIXED, "tool", np.zeros(3))])
    assert e.value.parameter == "terms[1]"
    with pytest.raises(InputError) as e:
        MultibodyCostSum([ControlRegularisation(np.zeros(2))])
    assert e.value.parameter == "model"
    assert MultibodyCostSum([ControlRegularisation(np.zeros(2))], model=FIXED).nx == 6


def test_one_attitude_term_serves_tso3_and_a_general_model():
    """The paper's satellite as the general one-body model (satellite.urdf, spherical root, no
    gravity, the paper's inertia) with the SAME AttitudeGeodesic term on the bus frame: the solve
    reaches the TSO(3) backend's J* and controls."""
    import pinocchio as pin

    from geoddp import data
    from geoddp.costs import AttitudeGeodesic
    from geoddp.models.multibody import Multibody
    from geoddp.costs.multibody import ControlRegularisation, MultibodyCostSum, StateRegularisation
    from geoddp.problem import Problem, paper_problem
    from geoddp.solver import SolverOptions, solve

    ref = paper_problem(integrator="semi_implicit", attitude_kind="geodesic", horizon=60, dt=0.05)
    sat = ref.model
    mb = Multibody(data.urdf_path("satellite.urdf"), root="spherical", dt=sat.dt, integrator="semi_implicit",
                   gravity=False)
    pm = mb.pin_model
    pm.inertias[1] = pin.Inertia(pm.inertias[1].mass, np.zeros(3), sat.inertia)
    att = next(t for t in ref.terminal.terms if isinstance(t, AttitudeGeodesic))
    term = AttitudeGeodesic(att.W, att.R_d, frame="bus")
    W = np.zeros((6, 6))
    W[3:, 3:] = 1e4 * np.eye(3)
    running = MultibodyCostSum([ControlRegularisation(np.zeros(3), 0.1 * np.eye(3))], model=pm)
    terminal = MultibodyCostSum([term, StateRegularisation(pm, pin.neutral(pm), np.zeros(3), W)], model=pm, terminal=True)
    assert type(terminal.terms[0]).__name__ == "FrameRotation"
    gen = Problem(mb, pin.neutral(pm), np.zeros(3), ref.horizon, running, terminal)
    # Second order (exact on both): the same iterates (measured: J to 7e-16, controls to 2.3e-15
    # relative). First order and switch: the general model's first-order model is a Gauss-Newton
    # one, TSO(3)'s the paper's exact one, so the paths differ but end at the same verified
    # minimum (measured: J to 4e-15; controls to 4.3e-7 relative since the general model stops
    # at the first point it certifies, Newton decrement <= tol / 10, as J - J* ~ dU^T H dU / 2).
    for expansion in ("second", "first", "switch"):
        a = solve(ref, SolverOptions(verbose=False, expansion=expansion))
        b = solve(gen, SolverOptions(verbose=False, expansion=expansion))
        assert a.converged and b.converged
        assert abs(a.cost - b.cost) <= 1e-12 * a.cost
        close = 1e-12 if expansion == "second" else 2e-6
        assert np.abs(a.controls - b.controls).max() <= close * np.abs(a.controls).max(), expansion
        if expansion == "second":
            assert a.iterations == b.iterations
    with pytest.raises(InputError, match=r"terms\[0\]\.frame"):
        MultibodyCostSum([AttitudeGeodesic(att.W, att.R_d)], model=pm, terminal=True)
