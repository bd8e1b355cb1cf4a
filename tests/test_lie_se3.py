"""SE(3) (geoddp.lie.se3) against Pinocchio, the series of its right Jacobian and finite differences."""
import numpy as np
import pinocchio as pin
import pytest

from geoddp.lie import SE3


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


def se3_jr_series(x, terms=60):
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
    for _ in range(5):
        x = rng.normal(size=6)
        w = rng.normal(size=3)
        x[3:] = angle * w / np.linalg.norm(w)
        ref = se3_jr_series(x)
        assert np.abs(SE3.right_jacobian(x) - ref).max() < 1e-14 * max(1.0, np.abs(ref).max())
        assert np.abs(SE3.right_jacobian_inv(x) @ ref - np.eye(6)).max() < 1e-13
        if angle < 1.0:
            assert np.abs(SE3.log_jacobian(pin.exp6(x)) @ ref - np.eye(6)).max() < 1e-13


def test_se3_right_jacobian_by_perturbation(rng):
    """exp(x + d) = exp(x) exp(Jr d + O(d^2)), checked through log6 at small rotations."""
    for angle in (1e-4, 1e-3, 0.5):
        x = rng.normal(size=6)
        x[3:] *= angle / np.linalg.norm(x[3:])
        d = 1e-7 * rng.normal(size=6)
        lhs = pin.log6(pin.exp6(x).inverse() * pin.exp6(x + d)).vector
        assert np.abs(lhs - SE3.right_jacobian(x) @ d).max() < 1e-13


def test_right_jacobian_derivative_against_richardson(rng):
    x = rng.normal(size=6)
    D = SE3.right_jacobian_derivative(x)

    def fd(h):
        return np.stack([(pin.Jexp6(x + h * e) - pin.Jexp6(x - h * e)) / (2 * h) for e in np.eye(6)], axis=-1)

    rich = (4.0 * fd(1e-3) - fd(2e-3)) / 3.0
    assert np.abs(D - rich).max() < 1e-9
