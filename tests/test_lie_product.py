"""The product group over a Pinocchio model's joints (geoddp.lie.product) and its TSO(3) instance:
block Ad / Jr / dJr / bracket tensors, difference and its Jacobian, the reconstruction's second
order."""
import numpy as np
import pinocchio as pin
import pytest

from geoddp import lie
from geoddp.lie import TSO3
from test_lie_se3 import se3_jr_series
from urdfs import urdf


def test_tso3_retract_local_round_trip(rng):
    R = pin.exp3(rng.normal(size=3))
    Om = rng.normal(size=3)
    z = 0.3 * rng.normal(size=6)
    R2, Om2 = TSO3.retract(R, Om, z)
    assert np.allclose(TSO3.local(R, Om, R2, Om2), z, atol=1e-13)


def test_difference_jacobian_is_exact_at_small_rotations(rng):
    """d difference(q0, q1 exp(d)) / dd = Jr(difference)^-1 per joint, against the inverse of the
    series Jr (identity on vector and SO(2) joints), with q1 - q0 a metre of translation and
    3e-4..3e-3 rad of rotation per SE(3) joint, where pin.dDifference's SE(3) block is off by
    up to ~5e-8 (and central differences of pin.difference are limited to ~1e-9 by log6's
    own round-off)."""
    model = pin.buildModelFromUrdf(str(urdf("test_all_joints.urdf")), pin.JointModelFreeFlyer())
    groups = lie.joint_groups(model)
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
                ref[g.slice, g.slice] = np.linalg.inv(se3_jr_series(d[g.slice]))
        J = lie.difference_jacobian(model, groups, q0, q1)
        assert np.abs(J - ref).max() < 1e-10, angle  # log6 returns d to ~1e-12


@pytest.mark.parametrize("kind", ["so3", "se3"])
def test_reconstruction_second_order_term_is_exact_to_third_order(kind, rng):
    """eta+ = log(exp(-omega) exp(eta) exp(omega + rho)) against
    Ad_A eta + Jr rho + 1/2 dJr[rho] rho + 1/2 [Ad_A eta, Jr rho]: error ~8x per halving."""
    dim = 3 if kind == "so3" else 6
    groups = [lie.JointGroup("j", kind, 0, dim)]
    if kind == "so3":
        exp, log = pin.exp3, pin.log3
        compose = lambda a, b: a @ b  # noqa: E731
    else:
        exp, log = (lambda x: pin.exp6(x)), (lambda M: pin.log6(M).vector)
        compose = lambda a, b: a * b  # noqa: E731
    ratios = []
    for _ in range(5):
        omega = rng.normal(size=dim)
        A, Jr = lie.block_Ad_Jr(groups, dim, omega)
        D, C = lie.second_order_tensors(groups, dim, omega)
        d = rng.normal(size=2 * dim)
        d /= np.linalg.norm(d)
        errs = []
        for eps in (4e-2, 2e-2, 1e-2, 5e-3):
            eta, rho = eps * d[:dim], eps * d[dim:]
            exact = log(compose(compose(exp(-omega), exp(eta)), exp(omega + rho)))
            Ae, Jp = A @ eta, Jr @ rho
            pred = Ae + Jp + 0.5 * np.einsum("ijl,j,l->i", D, rho, rho) + 0.5 * np.einsum("ipq,p,q->i", C, Ae, Jp)
            errs.append(np.linalg.norm(exact - pred))
        ratios.append([errs[i] / errs[i + 1] for i in range(3)])
    ratios = np.array(ratios)
    assert np.all((ratios > 7.0) & (ratios < 9.0)), ratios


def test_se3_structure_constants_are_the_motion_cross_product(rng):
    x, y = rng.normal(size=6), rng.normal(size=6)
    _, C = lie.second_order_tensors([lie.JointGroup("j", "se3", 0, 6)], 6, np.zeros(6))
    assert np.abs(np.einsum("ipq,p,q->i", C, x, y) - pin.Motion(x).cross(pin.Motion(y)).vector).max() < 1e-14
    _, C3 = lie.second_order_tensors([lie.JointGroup("j", "so3", 0, 3)], 3, np.zeros(3))
    assert np.abs(np.einsum("ipq,p,q->i", C3, x[:3], y[:3]) - np.cross(x[:3], y[:3])).max() < 1e-14
