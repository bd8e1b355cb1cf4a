"""SO(3)/SE(3) operators against Pinocchio and finite differences, near 0, near pi, uniform."""
import numpy as np
import pinocchio as pin
import pytest

from geoddp import kernels
from geoddp.lie import SE3, SO3, TSO3, hat, vee

SCALES = [0.0, 1e-8, 1e-5, 1e-3, 0.1, 0.3, 1.0, 2.0, 3.0, np.pi - 1e-6]


def _vectors(rng, scale, n=12):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True) * scale


@pytest.mark.parametrize("scale", SCALES)
def test_batched_closed_forms_match_pinocchio(rng, scale):
    X = _vectors(rng, scale)
    for x, E, J, Ji in zip(X, SO3.exp_batch(X), SO3.right_jacobian_batch(X), SO3.right_jacobian_inv_batch(X)):
        assert np.abs(E - pin.exp3(x)).max() < 1e-14
        assert np.abs(J - pin.Jexp3(x)).max() < 1e-14
        assert np.abs(Ji @ pin.Jexp3(x) - np.eye(3)).max() < 1e-12
        assert np.all(np.isfinite(Ji))


def test_right_jacobian_is_the_paper_dexp_minus_x(rng):
    # exp(x + d) = exp(x) exp(Jr(x) d + O(d^2))
    for x in _vectors(rng, 1.3, 5):
        d = 1e-7 * rng.normal(size=3)
        lhs = pin.log3(pin.exp3(x).T @ pin.exp3(x + d))
        assert np.abs(lhs - SO3.right_jacobian(x) @ d).max() < 1e-13
        assert np.allclose(SO3.left_jacobian(x), SO3.Ad(pin.exp3(x)) @ SO3.right_jacobian(x), atol=1e-14)


@pytest.mark.parametrize("scale", [1e-8, 1e-3, 0.2, 0.45, 1.0, 3.0])
def test_right_jacobian_derivative_by_finite_differences(rng, scale):
    X = _vectors(rng, scale, 4)
    D = SO3.right_jacobian_derivative_batch(X)
    h = 1e-6
    for x, Dx in zip(X, D):
        for l in range(3):
            e = np.zeros(3)
            e[l] = h
            fd = (SO3.right_jacobian_batch((x + e)[None])[0] - SO3.right_jacobian_batch((x - e)[None])[0]) / (2 * h)
            assert np.abs(fd - Dx[:, :, l]).max() < 1e-9


@pytest.mark.parametrize("scale", [0.0, 1e-8, 1e-3, 0.5, 2.0, 3.0])
def test_log_second_order_by_finite_differences(rng, scale):
    X = _vectors(rng, scale, 4)
    T = SO3.log_second_order_batch(X)
    assert np.all(np.isfinite(T))
    for x, Tx in zip(X, T):
        eta = rng.normal(size=3)
        f = lambda s: pin.log3(pin.exp3(x) @ pin.exp3(s * eta))
        d2 = lambda s: (f(s) - 2 * f(0.0) + f(-s)) / s**2
        fd = (4 * d2(5e-4) - d2(1e-3)) / 3  # Richardson: O(s^4) truncation
        assert np.abs(fd - np.einsum("kjl,j,l->k", Tx, eta, eta)).max() < 1e-6


def test_hat_vee_and_ad():
    x, y = np.array([0.3, -1.0, 2.0]), np.array([1.5, 0.2, -0.7])
    assert np.allclose(hat(x) @ y, np.cross(x, y))
    assert np.allclose(vee(hat(x)), x)
    assert np.allclose(SO3.ad(x) @ y, np.cross(x, y))


def test_se3_operators_against_pinocchio(rng):
    x = rng.normal(size=6)
    M = SE3.exp(x)
    assert np.allclose(SE3.log(M), x, atol=1e-12)
    d = 1e-7 * rng.normal(size=6)
    lhs = pin.log6(M.inverse() * SE3.exp(x + d)).vector
    assert np.abs(lhs - SE3.right_jacobian(x) @ d).max() < 1e-12
    assert np.allclose(SE3.right_jacobian_inv(x) @ SE3.right_jacobian(x), np.eye(6), atol=1e-10)
    y = rng.normal(size=6)
    assert np.allclose(SE3.ad(x) @ y, (pin.Motion(x) ^ pin.Motion(y)).vector)
    assert np.allclose(SE3.Ad(M) @ y, M.act(pin.Motion(y)).vector)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-8, 1e-3, 1.0, 3.0, np.pi - 1e-3, np.pi - 1e-7, np.pi])
def test_compiled_log_exp_match_pinocchio_near_zero_and_pi(rng, angle):
    out = np.empty(3)
    E = np.empty((3, 3))
    for x in _vectors(rng, angle, 8):
        R = pin.exp3(x)
        kernels.so3_log(R, out)
        ref = pin.log3(R)
        # at exactly pi both x and -x are valid logs
        assert min(np.abs(out - ref).max(), np.abs(out + ref).max() if angle > 3 else 1) < 1e-9
        assert np.abs(pin.exp3(out) - R).max() < 1e-12
        kernels.so3_exp(*x, E)
        assert np.abs(E - R).max() < 1e-14


def test_tso3_retract_local_round_trip(rng):
    R = pin.exp3(rng.normal(size=3))
    Om = rng.normal(size=3)
    z = 0.3 * rng.normal(size=6)
    R2, Om2 = TSO3.retract(R, Om, z)
    assert np.allclose(TSO3.local(R, Om, R2, Om2), z, atol=1e-13)


def test_log_batch_is_accurate_near_pi(rng):
    """Round trip exp(log(R)) = R to 1e-14 from 150 to 180 degrees, and log(exp(x)) = x."""
    for angle in np.linspace(np.radians(150), np.pi - 1e-9, 40):
        ax = rng.normal(size=3)
        x = angle * ax / np.linalg.norm(ax)
        R = pin.exp3(x)
        v = SO3.log_batch(R[None])[0]
        assert np.abs(v - x).max() < 1e-12
        assert np.abs(pin.exp3(v) - R).max() < 1e-14


# ---------------------------------------------------------------------------- SE(3) right Jacobian
def _se3_jr_series(x, terms=60):
    """sum_k (-ad_x)^k / (k+1)!, summed to convergence (reference, independent of closed forms)."""
    A = -pin.Motion(x).action
    S, T, f = np.eye(6), np.eye(6), 1.0
    for k in range(1, terms):
        T = T @ A
        f *= k + 1
        S = S + T / f
    return S


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-6, 1e-5, 3e-5, 1e-4, 1e-3, 1e-2, 0.1, 0.59, 0.61, 1.0, 2.0, 3.0, np.pi - 1e-6])
def test_se3_right_jacobian_is_exact_at_every_angle(angle, rng):
    """Against the series to 1e-14, including 1e-5..1e-2 rad, where pin.Jexp6 (Pinocchio 4.1)
    is off by up to 3e-5 (cancellation in its coupling block)."""
    from geoddp.lie import SE3

    for _ in range(5):
        x = rng.normal(size=6)
        w = rng.normal(size=3)
        x[3:] = angle * w / np.linalg.norm(w)
        ref = _se3_jr_series(x)
        assert np.abs(SE3.right_jacobian(x) - ref).max() < 1e-14 * max(1.0, np.abs(ref).max())
        assert np.abs(SE3.right_jacobian_inv(x) @ ref - np.eye(6)).max() < 1e-13
        if angle < 1.0:
            assert np.abs(SE3.log_jacobian(pin.exp6(x)) @ ref - np.eye(6)).max() < 1e-13


def test_se3_right_jacobian_by_perturbation(rng):
    """exp(x + d) = exp(x) exp(Jr d + O(d^2)), checked through log6 at small rotations."""
    from geoddp.lie import SE3

    for angle in (1e-4, 1e-3, 0.5):
        x = rng.normal(size=6)
        x[3:] *= angle / np.linalg.norm(x[3:])
        d = 1e-7 * rng.normal(size=6)
        lhs = pin.log6(pin.exp6(x).inverse() * pin.exp6(x + d)).vector
        assert np.abs(lhs - SE3.right_jacobian(x) @ d).max() < 1e-13


def test_difference_jacobian_is_exact_at_small_rotations(rng):
    """d difference(q0, q1 exp(d)) / dd = Jr(difference)^-1 per joint, against the inverse of the
    series Jr (identity on vector and SO(2) joints), with q1 - q0 a metre of translation and
    3e-4..3e-3 rad of rotation per SE(3) joint, where pin.dDifference's SE(3) block is off by
    up to ~5e-8 (and central differences of pin.difference are limited to ~1e-9 by log6's
    own round-off)."""
    from pathlib import Path

    from geoddp import configuration as cfg

    urdf = Path(__file__).resolve().parent / "data" / "test_all_joints.urdf"
    model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
    groups = cfg.joint_groups(model)
    assert [g.kind for g in groups].count("se3") == 2
    for angle in (3e-4, 1e-3, 3e-3):
        q0 = pin.integrate(model, pin.neutral(model), rng.normal(size=model.nv))
        d = angle * rng.normal(size=model.nv)
        for g in groups:
            if g.kind == "se3":
                d[g.idx_v : g.idx_v + 3] = rng.normal(size=3)
        q1 = pin.integrate(model, q0, d)
        ref = np.eye(model.nv)
        for g in groups:
            if g.kind == "se3":
                ref[g.slice, g.slice] = np.linalg.inv(_se3_jr_series(d[g.slice]))
        J = cfg.difference_jacobian(model, groups, q0, q1)
        assert np.abs(J - ref).max() < 1e-10, angle  # log6 returns d to ~1e-12
