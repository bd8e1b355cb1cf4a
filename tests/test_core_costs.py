"""The compiled cost kernels (geoddp._core, cpp/costs/costs.cpp) against the Python oracle
(tests/oracle_costs.py) and against differences of their own gradient.

Models: the space manipulator URDF on a free-flyer root, a fixed base and a spherical root, the
all-joints URDF (two free flyers, an unbounded revolute, a prismatic joint) and the satellite
(spherical root). The compiled second-order parts are exact; the oracle differences its gradient
(O(h^2), ~1e-8 relative), so Hessians are compared to the oracle at that accuracy and to
Richardson-extrapolated differences of the compiled gradient much more tightly.
"""
from pathlib import Path

import zlib

import numpy as np
import pinocchio as pin
import pytest


from geoddp.costs import CostDerivatives
from geoddp.lie import SE3, SO3
from geoddp.models import compiled
from geoddp.costs.multibody import (
    ControlRegularisation,
    FramePlacement,
    FrameRotation,
    FrameRotationChordal,
    FrameTranslation,
    MultibodyCostSum,
    MultibodyCostTerm,
    StateRegularisation,
)
from geoddp.validate import InputError
from oracle_costs import OracleCostSum
from urdfs import urdf as urdf_file

CORE = compiled._core

VALUE_TOL = 1e-12      # values, gradients, GN Hessians; relative to max(1, max|oracle|); measured 2e-14
ORACLE_HESS_TOL = 1e-7  # relative; the oracle's central differences (h = 1e-5): measured 4e-10
EXACT_HESS_TOL = 1e-9   # relative, against Richardson differences of the gradient: measured 2e-12


def _load(name: str, root) -> pin.Model:
    path = str(urdf_file(f"{name}.urdf"))
    model = pin.buildModelFromUrdf(path) if root is None else pin.buildModelFromUrdf(path, root)
    model.name = name
    return model


MODELS = {
    "free_flyer": (_load("space_manipulator", pin.JointModelFreeFlyer()), "ee"),
    "fixed": (_load("space_manipulator", None), "ee"),
    "spherical": (_load("space_manipulator", pin.JointModelSpherical()), "ee"),
    "all_joints": (_load("test_all_joints", pin.JointModelFreeFlyer()), "payload"),
    "satellite": (_load("satellite", pin.JointModelSpherical()), "bus"),
}
# "state_diagonal": per-coordinate weights, the compiled kernel's scaling path (some zero)
KINDS = ["placement", "rotation", "chordal", "translation", "state", "state_diagonal", "control"]


def _random_q(model, rng, scale=1.5):
    return pin.integrate(model, pin.neutral(model), rng.uniform(-scale, scale, model.nv))


def _spd(n, rng):
    A = rng.normal(size=(n, n))
    return A @ A.T / n + 0.5 * np.eye(n)


def _placement(model, frame, q):
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    return pin.updateFramePlacement(model, data, model.getFrameId(frame)).copy()


def _rotated(M, rng, angle):
    """M times a rotation of ``angle`` rad about a random axis and a random offset."""
    ax = rng.normal(size=3)
    return M * pin.SE3(pin.exp3(angle * ax / np.linalg.norm(ax)), rng.normal(size=3) * 0.3)


def _term(kind, model, frame, Q, rng, per_node, angle=1.2, gauss_newton=False):
    """A term of ``kind`` whose reference sits ``angle`` rad from the frame at each node
    (per_node) or at node 0 (one reference)."""
    nodes = range(len(Q)) if per_node else [0]
    Ms = [_rotated(_placement(model, frame, Q[k]), rng, angle) for k in nodes]
    one = (lambda xs: xs) if per_node else (lambda xs: xs[0])
    if kind == "placement":
        return FramePlacement(model, frame, one(Ms), _spd(6, rng), gauss_newton=gauss_newton)
    if kind == "rotation":
        return FrameRotation(model, frame, one(np.array([M.rotation for M in Ms])), _spd(3, rng),
                             gauss_newton=gauss_newton)
    if kind == "chordal":
        return FrameRotationChordal(model, frame, one(np.array([M.rotation for M in Ms])), _spd(3, rng),
                                    gauss_newton=gauss_newton)
    if kind == "translation":
        return FrameTranslation(model, frame, one(np.array([M.translation for M in Ms])), _spd(3, rng),
                                gauss_newton=gauss_newton)
    if kind == "state":
        q_ref = one(np.array([_random_q(model, rng) for _ in nodes]))
        v_ref = one(rng.normal(size=(len(nodes), model.nv)))
        return StateRegularisation(model, q_ref, v_ref, _spd(2 * model.nv, rng), gauss_newton=gauss_newton)
    if kind == "state_diagonal":
        q_ref = one(np.array([_random_q(model, rng) for _ in nodes]))
        W = rng.uniform(0.5, 2.0, size=2 * model.nv) * (rng.uniform(size=2 * model.nv) > 0.2)
        return StateRegularisation(model, q_ref, None, np.diag(W), gauss_newton=gauss_newton)
    if kind == "control":
        return ControlRegularisation(one(rng.normal(size=(len(nodes), 3))), _spd(3, rng))
    raise AssertionError(kind)


def _nodes(model, rng, N):
    return (np.array([_random_q(model, rng) for _ in range(N)]), rng.normal(size=(N, model.nv)),
            rng.normal(size=(N, 3)))


def _rel(a, b):
    assert a.shape == b.shape
    if a.size == 0:
        return 0.0
    return np.abs(a - b).max() / max(1.0, np.abs(b).max())


def _both(terms, model, **kw):
    return (OracleCostSum(terms, model=model, **kw), MultibodyCostSum(terms, model=model, **kw))


# --------------------------------------------------------------------------------------
# against the Python oracle


@pytest.mark.parametrize("per_node", [False, True], ids=["constant", "per_node"])
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", list(MODELS))
def test_compiled_matches_the_python_oracle(name, kind, per_node):
    model, frame = MODELS[name]
    # a fixed seed per case (hash() of a str changes with PYTHONHASHSEED, so the data did too)
    rng = np.random.default_rng(zlib.crc32(f"{name}/{kind}/{per_node}".encode()))
    N = 5
    Q, V, U = _nodes(model, rng, N)
    for gn in (False, True):
        term = _term(kind, model, frame, Q, np.random.default_rng(7), per_node, gauss_newton=gn)
        py, cc = _both([term], model)
        assert type(cc) is MultibodyCostSum and cc.backend == "compiled"
        u = U if kind == "control" else None
        dp, dc = py.derivatives(Q, V, u), cc.derivatives(Q, V, u)
        assert _rel(cc.value(Q, V, u), py.value(Q, V, u)) < VALUE_TOL
        for f in ("l", "lx", "lu", "luu", "lux"):
            assert _rel(getattr(dc, f), getattr(dp, f)) < VALUE_TOL, f
        assert np.array_equal(dc.lxx, np.swapaxes(dc.lxx, 1, 2))  # exactly symmetric
        # Gauss-Newton Hessians involve no differences: equal to round-off
        assert _rel(dc.lxx, dp.lxx) < (VALUE_TOL if gn or kind == "control" else ORACLE_HESS_TOL), gn
        if not gn and kind in ("placement", "rotation", "chordal", "translation") and np.any(dp.lxx):
            assert _rel(dc.lxx, dp.lxx) > 0.0  # the oracle differences: not the same numbers


def test_sum_of_every_term_matches_the_oracle():
    model, frame = MODELS["all_joints"]
    rng = np.random.default_rng(3)
    Q, V, U = _nodes(model, rng, 7)
    terms = [_term(k, model, frame, Q, rng, per_node=(i % 2 == 0)) for i, k in enumerate(KINDS)]
    py, cc = _both(terms, model)
    dp, dc = py.derivatives(Q, V, U), cc.derivatives(Q, V, U)
    for f in ("l", "lx", "lu", "luu", "lux"):
        assert _rel(getattr(dc, f), getattr(dp, f)) < VALUE_TOL, f
    assert _rel(dc.lxx, dp.lxx) < ORACLE_HESS_TOL
    # a terminal sum: no control
    pyt, cct = _both(terms[:4], model, terminal=True)
    assert _rel(cct.derivatives(Q, V, None).lxx, pyt.derivatives(Q, V, None).lxx) < ORACLE_HESS_TOL


# --------------------------------------------------------------------------------------
# exactness of the compiled second-order parts


def _richardson_hessian(cost, q, v):
    """sym d/ds l_x(integrate(q, s e_j), v + s e_j'), Richardson-extrapolated central differences
    (error O(h^4)): the (0)-Hessian, since the Lie-bracket term is antisymmetric."""
    model = cost.model
    nv = model.nv

    def grad(z):
        return cost.derivatives(pin.integrate(model, q, z[:nv])[None], (v + z[nv:])[None], None).lx[0]

    def D(h):
        return np.stack([(grad(h * e) - grad(-h * e)) / (2 * h) for e in np.eye(2 * nv)], axis=1)

    h = 1e-3
    H = (4.0 * D(h / 2) - D(h)) / 3.0
    return 0.5 * (H + H.T)


@pytest.mark.parametrize("angle", [1e-6, 0.3, 1.5, 2.6])
@pytest.mark.parametrize("kind", ["placement", "rotation", "chordal", "translation", "state"])
@pytest.mark.parametrize("name", ["free_flyer", "fixed", "spherical", "all_joints"])
def test_compiled_hessian_is_exact(name, kind, angle):
    model, frame = MODELS[name]
    rng = np.random.default_rng(11)
    q, v = _random_q(model, rng), rng.normal(size=model.nv)
    term = _term(kind, model, frame, q[None], rng, per_node=False, angle=angle)
    cost = MultibodyCostSum([term], backend="compiled")
    H = _richardson_hessian(cost, q, v)
    lxx = cost.derivatives(q[None], v[None], None).lxx[0]
    assert _rel(lxx, H) < EXACT_HESS_TOL


def _state_near(model, q, angle, rng):
    """A reference configuration whose root rotation is ``angle`` rad from q's."""
    dq = np.zeros(model.nv)
    ax = rng.normal(size=3)
    root = model.joints[1]
    dq[root.idx_v + root.nv - 3: root.idx_v + root.nv] = angle * ax / np.linalg.norm(ax)
    return pin.integrate(model, q, dq)


@pytest.mark.parametrize("name", ["free_flyer", "spherical"])
@pytest.mark.parametrize("gap", [0.0, 1e-12, 1e-7, 1e-3])
def test_residuals_near_pi_stay_finite(name, gap):
    """Relative rotations of pi - gap: every number finite; at gap 1e-3 still exact (the
    differences stay on one side of the cut locus)."""
    model, frame = MODELS[name]
    rng = np.random.default_rng(5)
    q, v = _random_q(model, rng), rng.normal(size=model.nv)
    M = _rotated(_placement(model, frame, q), rng, np.pi - gap)
    terms = [FramePlacement(model, frame, M, _spd(6, rng)), FrameRotation(model, frame, M.rotation, _spd(3, rng)),
             StateRegularisation(model, _state_near(model, q, np.pi - gap, rng), None, _spd(2 * model.nv, rng))]
    for t in terms:
        cost = MultibodyCostSum([t], backend="compiled")
        d = cost.derivatives(q[None], v[None], None)
        assert all(np.all(np.isfinite(a)) for a in (d.l, d.lx, d.lxx)), type(t).__name__
        if gap == 1e-3:
            h = 1e-4  # central differences stay 10 h away from pi
            nv = model.nv

            def grad(z):
                return cost.derivatives(pin.integrate(model, q, z[:nv])[None], (v + z[nv:])[None], None).lx[0]
            Dh = np.stack([(grad(h * e) - grad(-h * e)) / (2 * h) for e in np.eye(2 * nv)], axis=1)
            assert _rel(d.lxx[0], 0.5 * (Dh + Dh.T)) < 1e-6, type(t).__name__


@pytest.mark.parametrize("name", ["free_flyer", "fixed", "spherical", "all_joints"])
def test_near_identity_and_at_the_reference(name):
    """At the reference: value and gradient exactly 0 and GN == exact bit for bit; at 1e-9 rad:
    finite and equal to the oracle."""
    model, frame = MODELS[name]
    rng = np.random.default_rng(9)
    q, v = _random_q(model, rng), rng.normal(size=model.nv)
    M = _placement(model, frame, q)
    for gn in (False, True):
        for t in [FramePlacement(model, frame, M, _spd(6, rng), gauss_newton=gn),
                  FrameRotation(model, frame, M.rotation, _spd(3, rng), gauss_newton=gn),
                  FrameTranslation(model, frame, M.translation, _spd(3, rng), gauss_newton=gn),
                  StateRegularisation(model, q, v, _spd(2 * model.nv, rng), gauss_newton=gn)]:
            d = MultibodyCostSum([t], backend="compiled").derivatives(q[None], v[None], None)
            assert d.l[0] == 0.0 and np.all(d.lx == 0.0), type(t).__name__
    W = _spd(6, np.random.default_rng(1))
    a = MultibodyCostSum([FramePlacement(model, frame, M, W)], backend="compiled").derivatives(q[None], v[None], None)
    b = MultibodyCostSum([FramePlacement(model, frame, M, W, gauss_newton=True)],
                         backend="compiled").derivatives(q[None], v[None], None)
    assert np.array_equal(a.lxx, b.lxx)
    Mt = _rotated(M, rng, 1e-9)
    for t in [FramePlacement(model, frame, Mt, W), FrameRotation(model, frame, Mt.rotation, W[3:, 3:]),
              StateRegularisation(model, _state_near(model, q, 1e-9, rng) if name != "fixed" else q, None,
                                  _spd(2 * model.nv, rng))]:
        py, cc = _both([t], model)
        dp, dc = py.derivatives(q[None], v[None], None), cc.derivatives(q[None], v[None], None)
        assert np.all(np.isfinite(dc.lxx)) and _rel(dc.lx, dp.lx) < VALUE_TOL
        assert _rel(dc.lxx, dp.lxx) < ORACLE_HESS_TOL


# --------------------------------------------------------------------------------------
# closed forms of the Lie groups


def test_closed_forms_match_geoddp_and_differences():
    rng = np.random.default_rng(2)
    for scale in (1e-7, 0.1, 0.55, 0.65, 2.0, 3.1):
        x = rng.normal(size=6)
        x[3:] *= scale / np.linalg.norm(x[3:])
        assert np.abs(CORE.se3_right_jacobian_inv(x) - SE3.right_jacobian_inv(x)).max() < 1e-13
        assert np.abs(CORE.se3_right_jacobian(x) - SE3.right_jacobian(x)).max() < 1e-13
        assert np.abs(CORE.so3_right_jacobian_inv(x[3:]) - SO3.right_jacobian_inv(x[3:])).max() < 1e-13
        D6 = CORE.se3_jr_derivative(x).reshape(6, 6, 6)
        assert np.abs(D6 - SE3.right_jacobian_derivative(x)).max() < 1e-9  # geoddp differences its Jr (~1e-10)
        D3 = CORE.so3_jr_derivative(x[3:]).reshape(3, 3, 3)
        assert np.abs(D3 - SO3.right_jacobian_derivative_batch(x[None, 3:])[0]).max() < 1e-12
        # exact: Richardson differences of the compiled Jr
        h = 1e-3

        def c(hh):
            return np.stack([(CORE.se3_right_jacobian(x + hh * e) - CORE.se3_right_jacobian(x - hh * e)) / (2 * hh)
                             for e in np.eye(6)], axis=-1)
        assert np.abs(D6 - (4 * c(h / 2) - c(h)) / 3).max() < 1e-11


# --------------------------------------------------------------------------------------
# choice of backend, fallbacks and bad input


def test_backend_choice_is_validated():
    """"auto" (the default) and "compiled" are the kernels; the Python code is the tests' oracle,
    no backend of the package: "python" is refused, naming backend."""
    model, frame = MODELS["fixed"]
    t = FrameTranslation(model, frame, np.zeros(3))
    with pytest.raises(InputError, match="did you mean 'compiled'") as e:
        MultibodyCostSum([t], backend="compild")
    assert e.value.parameter == "backend"
    with pytest.raises(InputError, match="auto | compiled") as e:
        MultibodyCostSum([t], backend="python")
    assert e.value.parameter == "backend"
    for backend in ("auto", "compiled"):
        assert MultibodyCostSum([t], backend=backend).backend == "compiled"
    assert MultibodyCostSum([t]).backend == "compiled"


class Speed(MultibodyCostTerm):
    """1/2 |v|^2: a term of the user's own (no kernel), for the sums' Python path."""

    def __init__(self, nv: int) -> None:
        self.nv = nv

    def value(self, Q, V, U):
        return 0.5 * np.sum(V**2, axis=1)

    def accumulate(self, Q, V, U, d):
        d.l += self.value(Q, V, U)
        d.lx[:, self.nv:] += V
        d.lxx[:, self.nv:, self.nv:] += np.eye(self.nv)


def test_terms_without_a_compiled_twin_run_their_python_code(rng):
    model, frame = MODELS["free_flyer"]

    class Doubled(FrameTranslation):  # a subclass may compute something else: its own code runs
        def value(self, Q, V, U):
            return 2.0 * super().value(Q, V, U)

        def accumulate(self, Q, V, U, d, gauss_newton=False):
            once = CostDerivatives.zeros(Q.shape[0], 0, d.lx.shape[1])
            super().accumulate(Q, V, U, once, gauss_newton)
            d.l += 2.0 * once.l
            d.lx += 2.0 * once.lx
            d.lxx += 2.0 * once.lxx

    class Renamed(FrameTranslation):  # inherits the kernels' value and accumulate
        pass

    Q, V, U = _nodes(model, rng, 3)
    terms = [Speed(model.nv), Doubled(model, frame, np.zeros(3)), Renamed(model, frame, 0.5 * np.ones(3)),
             FrameTranslation(model, frame, np.ones(3))]
    py, cc = _both(terms, model)
    assert [t for t in cc._own_terms] == terms[:3] and cc._kernel_terms == terms[3:]
    dp, dc = py.derivatives(Q, V, None), cc.derivatives(Q, V, None)
    assert _rel(dc.lx, dp.lx) < VALUE_TOL and _rel(dc.lxx, dp.lxx) < ORACLE_HESS_TOL
    assert _rel(cc.value(Q, V, None), py.value(Q, V, None)) < VALUE_TOL
    # Doubled is twice the plain term; Renamed is the plain term, through the kernels
    one = lambda t: MultibodyCostSum([t], model=model).derivatives(Q, V, None)  # noqa: E731
    plain = one(FrameTranslation(model, frame, np.zeros(3)))
    assert np.array_equal(one(terms[1]).lxx, 2.0 * plain.lxx)
    assert np.array_equal(one(terms[2]).lx, one(FrameTranslation(model, frame, 0.5 * np.ones(3))).lx)
    gn = cc.derivatives(Q, V, None, gauss_newton=True)
    assert _rel(gn.lxx, py.derivatives(Q, V, None, gauss_newton=True).lxx) < VALUE_TOL


def test_bad_input_raises_the_oracles_errors(rng):
    model, frame = MODELS["free_flyer"]
    Q, V, U = _nodes(model, rng, 4)
    refs = np.array([_placement(model, frame, q).translation for q in Q])
    cc = MultibodyCostSum([FrameTranslation(model, frame, refs)], backend="compiled")
    with pytest.raises(InputError, match="per-node reference of 4 nodes") as e:
        cc.derivatives(Q[:3], V[:3], None)
    assert e.value.parameter == "FrameTranslation.p_ref"
    with pytest.raises(InputError) as e:
        cc.value(Q[:, :5], V, None)
    assert e.value.parameter == "Q"
    st = MultibodyCostSum([StateRegularisation(model, Q, None)], backend="compiled")
    with pytest.raises(InputError) as e:
        st.derivatives(Q[:2], V[:2], None)
    assert e.value.parameter == "StateRegularisation.q_ref"
    ctrl = MultibodyCostSum([ControlRegularisation(np.zeros(2))], model=model, backend="compiled")
    with pytest.raises(InputError) as e:
        ctrl.derivatives(Q, V, U)  # m = 3, the term has 2
    assert e.value.parameter == "U"
    with pytest.raises(InputError, match="terminal"):
        ctrl.derivatives(Q, V, None)
    # non-contiguous and integer-free float views are accepted (copied), results unchanged
    Qf = np.asfortranarray(Q)
    assert np.array_equal(cc.value(Qf, V, None), cc.value(Q, V, None))


def test_a_term_alone_checks_its_input_and_matches_its_sum(rng):
    """term.value and term.accumulate (the kernels, one term) name bad arrays as a sum does, and
    give the one-term sum's numbers bit for bit, for a frame, a state and a control term."""
    model, frame = MODELS["free_flyer"]
    Q, V, U = _nodes(model, rng, 4)
    terms = [_term(k, model, frame, Q, rng, per_node=True) for k in ("placement", "state", "control")]
    for t in terms:
        u = U if t.uses_control else None
        alone = t.value(Q, V, u)
        assert np.array_equal(alone, MultibodyCostSum([t], model=model).value(Q, V, u))
        d = CostDerivatives.zeros(4, 0 if u is None else 3, 2 * model.nv)
        t.accumulate(Q, V, u, d)
        ds = MultibodyCostSum([t], model=model).derivatives(Q, V, u)
        assert np.array_equal(d.l, alone) and np.array_equal(d.lxx, ds.lxx) and np.array_equal(d.luu, ds.luu)
    with pytest.raises(InputError) as e:
        terms[0].value(Q[:, :5], V, None)
    assert e.value.parameter == "Q"
    with pytest.raises(InputError) as e:
        terms[1].value(Q, V[:3], None)
    assert e.value.parameter == "V"
    with pytest.raises(InputError, match="per-node reference of 4 nodes") as e:
        terms[0].value(Q[:3], V[:3], None)
    assert e.value.parameter == "FramePlacement.M_ref"
    with pytest.raises(InputError, match="terminal"):
        terms[2].value(Q, V, None)
    with pytest.raises(InputError) as e:
        terms[2].value(Q, V, U[:2])
    assert e.value.parameter == "U"
    for args, name in (((Q.tolist(), V, None), "Q"), ((Q, V.tolist(), None), "V"), ((Q, V, U.tolist()), "U")):
        for call in (terms[1].value, MultibodyCostSum(terms[:2], model=model).value):
            with pytest.raises(InputError, match="expected a numpy array, got list") as e:
                call(*args)
            assert e.value.parameter == name


def test_kernels_check_sizes_themselves():
    """Direct calls with inconsistent sizes raise (ValueError), never read out of bounds."""
    model, frame = MODELS["fixed"]
    fid = model.getFrameId(frame)
    Q = np.zeros((2, model.nq))
    nx = 2 * model.nv
    ok = dict(l=np.zeros(2), lx=np.zeros((2, nx)), lxx=np.zeros((2, nx * nx)))
    with pytest.raises(ValueError, match="refs"):
        CORE.testing.cost_frame_term(model, fid, 2, Q, np.zeros((3, 3)), np.eye(3), False, True, **ok)
    with pytest.raises(ValueError, match="lxx"):
        CORE.testing.cost_frame_term(model, fid, 2, Q, np.zeros((1, 3)), np.eye(3), False, True, ok["l"], ok["lx"],
                             np.zeros((2, nx)))
    with pytest.raises(ValueError, match="frame_id"):
        CORE.testing.cost_frame_term(model, 10_000, 2, Q, np.zeros((1, 3)), np.eye(3), False, True, **ok)
    with pytest.raises(ValueError, match="W"):
        CORE.testing.cost_state_regularisation(model, Q, np.zeros((2, model.nv)), Q[:1], np.zeros((1, model.nv)),
                                       np.eye(3), False, True, **ok)
    with pytest.raises(TypeError, match="pinocchio.Model"):
        CORE.testing.cost_frame_term("robot", fid, 2, Q, np.zeros((1, 3)), np.eye(3), False, True, **ok)


# --------------------------------------------------------------------------------------
# the whole sum in one call (cpp/bindings/bind_cost_sum.cpp)


class _term_by_term:
    """The same sum evaluated one per-term kernel call at a time (cost_frame_term,
    cost_state_regularisation, cost_control_regularisation; a fresh pinocchio Data each), the
    reference for cost_sum's one call."""

    def __init__(self, sum_):
        self.sum = sum_

    def _add(self, Q, V, U, d, gauss_newton):
        from geoddp.costs.multibody import _FRAME_KINDS

        N, Q, V = Q.shape[0], np.ascontiguousarray(Q), np.ascontiguousarray(V)
        e = np.empty((0, 0))
        rows = (lambda A: A.reshape(N, -1)) if d is not None else (lambda A: e)
        for t in self.sum.terms:
            if type(t) is ControlRegularisation:
                CORE.testing.cost_control_regularisation(np.ascontiguousarray(U), t.u_ref, t.W, d is not None, d.l if d else
                                                 self.l, rows(d.lu) if d else e, rows(d.luu) if d else e)
            elif type(t) is StateRegularisation:
                CORE.testing.cost_state_regularisation(t.model, Q, V, t.q_ref, t.v_ref, t.W, t.gauss_newton or gauss_newton,
                                               d is not None, d.l if d else self.l, rows(d.lx) if d else e,
                                               rows(d.lxx) if d else e)
            else:
                code, refs, W = _FRAME_KINDS[type(t)](t)
                CORE.testing.cost_frame_term(t.model, t.frame_id, code, Q, refs, W, t.gauss_newton or gauss_newton,
                                     d is not None, d.l if d else self.l, rows(d.lx) if d else e,
                                     rows(d.lxx) if d else e)

    def value(self, Q, V, U):
        self.l = np.zeros(Q.shape[0])
        self._add(Q, V, U, None, False)
        return self.l

    def derivatives(self, Q, V, U, gauss_newton=False):
        from geoddp.costs import CostDerivatives

        d = CostDerivatives.zeros(Q.shape[0], 0 if U is None else U.shape[1], self.sum.nx)
        self._add(Q, V, U, d, gauss_newton)
        return d


@pytest.mark.parametrize("threads", [1, 2])
def test_whole_sum_is_bitwise_the_term_by_term_kernels(threads):
    model, frame = MODELS["all_joints"]
    rng = np.random.default_rng(5)
    N = 40  # two chunks of 20 nodes with two workers
    Q, V, U = _nodes(model, rng, N)
    terms = [_term(k, model, frame, Q, rng, per_node=(i % 2 == 0)) for i, k in enumerate(KINDS)]
    terms += [_term("placement", model, frame, Q, rng, per_node=True, gauss_newton=True)]
    cc = MultibodyCostSum(terms, model=model, backend="compiled")
    cc.threads = threads
    assert cc._kernel_terms == terms and not cc._own_terms
    ref = _term_by_term(cc)
    assert np.array_equal(cc.value(Q, V, U), ref.value(Q, V, U))
    for gn in (False, True):
        dc, dr = cc.derivatives(Q, V, U, gauss_newton=gn), ref.derivatives(Q, V, U, gauss_newton=gn)
        for f in ("l", "lx", "lu", "lxx", "lux", "luu"):
            assert np.array_equal(getattr(dc, f), getattr(dr, f)), (gn, f)
    # a terminal sum of one node, and the same sum again (its pinocchio Data reused)
    term = MultibodyCostSum([terms[1], terms[3]], model=model, terminal=True, backend="compiled")  # one reference each
    for _ in range(2):
        dt_, dr_ = term.derivatives(Q[-1:], V[-1:], None), _term_by_term(term).derivatives(Q[-1:], V[-1:], None)
        assert np.array_equal(dt_.lxx, dr_.lxx) and np.array_equal(dt_.l, dr_.l)


def test_whole_sum_keeps_a_data_per_model_and_remakes_it_when_the_model_grows():
    model, frame = MODELS["fixed"]
    rng = np.random.default_rng(9)
    Q, V, U = _nodes(model, rng, 20)
    other = model.copy()  # the same structure, another pin.Model object: its own Data
    terms = [_term("placement", model, frame, Q, rng, per_node=False),
             _term("translation", other, frame, Q, rng, per_node=True)]
    cc = MultibodyCostSum(terms, model=model, backend="compiled")
    d1 = cc.derivatives(Q, V, None)
    assert cc._workspace.models == 2
    assert np.array_equal(d1.lxx, _term_by_term(cc).derivatives(Q, V, None).lxx)
    # a frame added after the first call: the kept Data no longer fits and is remade
    other.addFrame(pin.Frame("extra", 1, 0, pin.SE3.Identity(), pin.FrameType.OP_FRAME))
    d2 = cc.derivatives(Q, V, None)
    assert np.array_equal(d2.lxx, d1.lxx) and np.array_equal(d2.lx, d1.lx)


def test_whole_sum_sees_rebound_terms_and_changed_arrays():
    """The sum caches its compiled specs per (terms, N, U shape): a term attribute rebound after
    a call, an array changed in place and another node count all give the oracle's values."""
    model, frame = MODELS["fixed"]
    rng = np.random.default_rng(21)
    Q, V, U = _nodes(model, rng, 12)
    terms = [_term("placement", model, frame, Q, rng, per_node=False), _term("state", model, frame, Q, rng, per_node=False),
             _term("control", model, frame, Q, rng, per_node=False)]
    py, cc = _both(terms, model)
    assert cc._kernel_terms == terms and np.array_equal(cc.value(Q, V, U), _term_by_term(cc).value(Q, V, U))
    for change in (lambda: setattr(terms[0], "W", _spd(6, rng)),        # rebound
                   lambda: terms[1].W.__imul__(2.0),                      # in place
                   lambda: setattr(terms[2], "u_ref", rng.normal(size=(1, 3)))):
        before = cc.value(Q, V, U)
        change()
        after = cc.value(Q, V, U)
        assert not np.array_equal(after, before)
        assert _rel(after, py.value(Q, V, U)) < VALUE_TOL
        assert _rel(cc.derivatives(Q, V, U).lxx, py.derivatives(Q, V, U).lxx) < ORACLE_HESS_TOL
    assert _rel(cc.value(Q[:5], V[:5], U[:5]), py.value(Q[:5], V[:5], U[:5])) < VALUE_TOL


def test_a_sum_follows_its_terms_list():
    """A sum's ``terms`` is a list the user may change after a call: an appended term (built-in
    or the user's own), a replaced one and a rebound list are all evaluated, as the oracle does."""
    model, frame = MODELS["fixed"]
    rng = np.random.default_rng(22)
    Q, V, U = _nodes(model, rng, 6)
    terms = [_term("placement", model, frame, Q, rng, per_node=False)]
    py, cc = _both(terms, model)
    before = cc.value(Q, V, U)

    for change in (lambda s: s.terms.append(_term("state", model, frame, Q, rng, per_node=True)),
                   lambda s: s.terms.append(Speed(model.nv)),
                   lambda s: s.terms.__setitem__(0, _term("rotation", model, frame, Q, rng, per_node=False)),
                   lambda s: setattr(s, "terms", [_term("translation", model, frame, Q, rng, per_node=True)])):
        change(cc)
        py.terms = list(cc.terms)
        assert _rel(cc.value(Q, V, U), py.value(Q, V, U)) < VALUE_TOL
        dc, dp = cc.derivatives(Q, V, U), py.derivatives(Q, V, U)
        assert _rel(dc.lx, dp.lx) < VALUE_TOL and _rel(dc.lxx, dp.lxx) < ORACLE_HESS_TOL
        assert not np.array_equal(cc.value(Q, V, U), before)
        before = cc.value(Q, V, U)


def test_cost_sum_checks_sizes_itself():
    """Direct calls with inconsistent sizes raise ValueError before any chunk runs: a stack of
    20 references on 40 nodes must not pass as two chunks of 20."""
    model, frame = MODELS["fixed"]
    fid = model.getFrameId(frame)
    N, nx = 40, 2 * model.nv
    Q, V = np.tile(pin.neutral(model), (N, 1)), np.zeros((N, model.nv))
    ws, e = CORE.CostWorkspace(), np.empty((0, 0))
    out = dict(l=np.zeros(N), lx=np.zeros((N, nx)), lxx=np.zeros((N, nx * nx)), lu=e, luu=e)
    term = (0, model, fid, 2, np.zeros((20, 3)), np.eye(3), False)
    with pytest.raises(ValueError, match="refs: a per-node reference of 20 nodes"):
        CORE.cost_sum(ws, [term], Q, V, e, True, False, 2, **out)
    with pytest.raises(ValueError, match="lx: expected shape"):
        CORE.cost_sum(ws, [(0, model, fid, 2, np.zeros((1, 3)), np.eye(3), False)], Q, V, e, True, False, 2,
                      out["l"], np.zeros((N, 3)), out["lxx"], e, e)
    with pytest.raises(ValueError, match="term types"):
        CORE.cost_sum(ws, [(7,)], Q, V, e, False, False, 1, **out)
    with pytest.raises(ValueError, match="U"):
        CORE.cost_sum(ws, [(2, np.zeros((1, 2)), np.eye(2))], Q, V, np.zeros((3, 2)), False, False, 1, **out)
    with pytest.raises(TypeError, match="pinocchio.Model"):
        CORE.cost_sum(ws, [(1, "robot", Q[:1], V[:1], np.eye(nx), False)], Q, V, e, False, False, 1, **out)
    with pytest.raises(ValueError, match="V: expected"):  # chunks of V must not run past its end
        CORE.cost_sum(ws, [(1, model, Q[:1], V[:1], np.eye(nx), False)], Q, V[:20], e, False, False, 2, **out)
    assert not out["l"].any()  # nothing was added by a refused call


def test_chordal_term_names_itself_in_its_errors():
    model, frame = MODELS["satellite"]
    Q = np.array([_random_q(model, np.random.default_rng(k)) for k in range(5)])
    V = np.zeros((5, model.nv))
    with pytest.raises(InputError, match=r"FrameRotationChordal\.W"):
        FrameRotationChordal(model, frame, np.eye(3), W=-np.eye(3))
    term = FrameRotationChordal(model, frame, np.stack([np.eye(3)] * 3), W=2.0)
    for kind in (OracleCostSum, MultibodyCostSum):
        with pytest.raises(InputError, match=r"FrameRotationChordal\.R_ref"):
            kind([term], model=model).value(Q, V, None)


def test_a_problem_names_misplaced_control_terms_and_a_users_term_of_the_wrong_shape(rng):
    """A control term in the terminal cost, a control term on another number of inputs, and a
    user's term whose value is not one number per node: each an InputError naming the term by its
    place, at construction (the problem) or at the first evaluation (the sum), where a sum had
    said only "terms[1]" or "U", or numpy had failed to broadcast."""
    from geoddp.costs import ControlQuadratic
    from geoddp.models.multibody import Multibody
    from geoddp.problem import Problem

    mb = Multibody(urdf_file("space_manipulator.urdf"), root="fixed", dt=0.01)
    pm, q0 = mb.pin_model, pin.neutral(mb.pin_model)
    state = StateRegularisation(pm, q0)
    running = MultibodyCostSum([state, ControlRegularisation(np.zeros(mb.nu))])
    with pytest.raises(InputError, match="cannot be part of the terminal cost") as e:
        Problem(mb, q0, np.zeros(mb.nv), 5, running, MultibodyCostSum([state, ControlRegularisation(np.zeros(mb.nu))]))
    assert e.value.parameter == "terminal.terms[1]"
    with pytest.raises(InputError, match=f"model's {mb.nu} inputs, got one on {mb.nu + 1}") as e:
        Problem(mb, q0, np.zeros(mb.nv), 5, MultibodyCostSum([state, ControlRegularisation(np.zeros(mb.nu + 1))]),
                MultibodyCostSum([state], terminal=True))
    assert e.value.parameter == "running.terms[1]"

    class PerTerm(MultibodyCostTerm):  # a value per term, not per node
        def value(self, Q, V, U):
            return np.zeros(3)

        def accumulate(self, Q, V, U, d):
            pass

    bad = MultibodyCostSum([state, PerTerm()])
    with pytest.raises(InputError, match=r"PerTerm.value returned shape \(3,\), expected \(5,\)") as e:
        bad.value(np.tile(q0, (5, 1)), np.zeros((5, mb.nv)), None)
    assert e.value.parameter == "terms[1]"
    with pytest.raises(InputError, match="a scalar does not fix the number of inputs") as e:
        ControlQuadratic(0.1)
    assert e.value.parameter == "cost.control"
