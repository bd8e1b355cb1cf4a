"""The minimal group interface (geoddp.lie.Group) on SO(3) and SE(3): every operation against its
definition, near the identity and near pi, without NaN."""
import numpy as np
import pinocchio as pin
import pytest

from geoddp.lie import SE3, SO3, Group

ANGLES = [0.0, 1e-300, 1e-12, 1e-6, 1e-3, 0.3, 2.0, np.pi - 1e-6, np.pi]


def _x(G, rng, angle):
    """A tangent vector of G whose rotation part has the given angle (rad)."""
    x = rng.normal(size=G.dim)
    w = x[-3:]
    x[-3:] = angle * w / np.linalg.norm(w)
    return x


def _matrix(G, g):
    return g if G is SO3 else g.homogeneous


@pytest.mark.parametrize("G", [SO3, SE3], ids=["SO3", "SE3"])
def test_groups_implement_the_interface(G):
    assert isinstance(G, Group)
    assert G.structure_constants.shape == (G.dim,) * 3


@pytest.mark.parametrize("angle", ANGLES)
@pytest.mark.parametrize("G", [SO3, SE3], ids=["SO3", "SE3"])
def test_group_operations_against_their_definitions(G, angle, rng):
    x, y = _x(G, rng, angle), rng.normal(size=G.dim)
    g, h = G.exp(x), G.exp(_x(G, rng, 1.0))
    eye = np.eye(3 if G is SO3 else 4)
    # compose / inverse
    assert np.abs(_matrix(G, G.compose(g, G.inverse(g))) - eye).max() < 1e-14
    assert np.abs(_matrix(G, G.compose(g, h)) - _matrix(G, g) @ _matrix(G, h)).max() < 1e-14
    # Ad: g exp(y) g^-1 = exp(Ad(g) y); Ad_exp_neg(x) = Ad(exp(x)^-1)
    lhs = _matrix(G, G.compose(G.compose(h, G.exp(1e-3 * y)), G.inverse(h)))
    assert np.abs(lhs - _matrix(G, G.exp(G.Ad(h) @ (1e-3 * y)))).max() < 1e-14
    assert np.abs(G.Ad_exp_neg(x) - G.Ad(G.inverse(g))).max() < 1e-14
    # the bracket tensor is ad
    assert np.abs(np.einsum("ipq,p,q->i", G.structure_constants, x, y) - G.ad(x) @ y).max() < 1e-14 * (1 + np.abs(x).max())
    # Jr Jr^-1 = I, finite everywhere in [0, pi]
    J, Ji = G.right_jacobian(x), G.right_jacobian_inv(x)
    D = G.right_jacobian_derivative_batch(x[None])
    assert np.all(np.isfinite(J)) and np.all(np.isfinite(Ji)) and np.all(np.isfinite(D))
    assert np.abs(J @ Ji - np.eye(G.dim)).max() < 1e-12 * max(1.0, np.abs(x).max())


@pytest.mark.parametrize("angle", [0.0, 1e-8, 1e-4, 0.5, 3.0])
@pytest.mark.parametrize("G", [SO3, SE3], ids=["SO3", "SE3"])
def test_right_jacobian_and_its_derivative_by_perturbation(G, angle, rng):
    """exp(x + e) = exp(x) exp(Jr e + 1/2 D(e, e) + O(e^3)): the remainder falls at least 8x per
    halving of e (16x near the identity, where the third-order term vanishes; at x = 0 on SO(3)
    exp(e) is exact and only round-off is left)."""
    log = (lambda M: pin.log3(M)) if G is SO3 else (lambda M: pin.log6(M).vector)
    x, d = _x(G, rng, angle), rng.normal(size=G.dim)
    d /= np.linalg.norm(d)
    J, D = G.right_jacobian(x), G.right_jacobian_derivative_batch(x[None])[0]
    errs = []
    for eps in (4e-2, 2e-2, 1e-2):
        e = eps * d
        lhs = log(G.compose(G.inverse(G.exp(x)), G.exp(x + e)))
        errs.append(np.abs(lhs - J @ e - 0.5 * np.einsum("ijl,j,l->i", D, e, e)).max())
    if max(errs) < 1e-16:
        return
    assert errs[0] / errs[1] > 7.0 and errs[1] / errs[2] > 7.0, errs
