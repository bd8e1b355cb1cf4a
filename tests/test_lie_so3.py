"""SO(3) (geoddp.lie.so3) against Pinocchio and finite differences, near 0, near pi, uniform."""
import numpy as np
import pinocchio as pin
import pytest

from geoddp.lie import SO3, hat, vee

SCALES = [0.0, 1e-8, 1e-5, 1e-3, 0.1, 0.3, 1.0, 2.0, 3.0, np.pi - 1e-6]


def _vectors(rng, scale, n=12):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True) * scale


@pytest.mark.parametrize("scale", SCALES)
def test_batched_closed_forms_match_pinocchio(rng, scale):
    X = _vectors(rng, scale)
    for x, J, Ji in zip(X, SO3.right_jacobian_batch(X), SO3.right_jacobian_inv_batch(X)):
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


def test_log_batch_is_accurate_near_pi(rng):
    """Round trip exp(log(R)) = R to 1e-14 from 150 to 180 degrees, and log(exp(x)) = x."""
    for angle in np.linspace(np.radians(150), np.pi - 1e-9, 40):
        ax = rng.normal(size=3)
        x = angle * ax / np.linalg.norm(ax)
        R = pin.exp3(x)
        v = SO3.log_batch(R[None])[0]
        assert np.abs(v - x).max() < 1e-12
        assert np.abs(pin.exp3(v) - R).max() < 1e-14
