"""Cost terms: trivialised gradients and (0)-Hessians against finite differences."""
import numpy as np
import pinocchio as pin
import pytest

from geoddp.costs import AngularVelocityQuadratic, AttitudeChordal, AttitudeGeodesic, ControlQuadratic, CostSum
from geoddp.lie import TSO3

S3 = np.array([[3.0, 0.5, 0.1], [0.5, 2.0, -0.3], [0.1, -0.3, 1.5]])  # non-scalar SPD weight


def _fd_check(term, rng, R, Om, U):
    d = CostSum([term]).derivatives(R[None], Om[None], None if U is None else U[None])
    m = 0 if U is None else U.size

    def f(z):
        Rp, Op = TSO3.retract(R, Om, z[:6])
        Up = None if U is None else (U + z[6:])[None]
        return CostSum([term]).value(Rp[None], Op[None], Up)[0]

    n = 6 + m
    h = 1e-5
    grad = np.array([(f(h * e) - f(-h * e)) / (2 * h) for e in np.eye(n)])
    hess = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            hh = 3e-4  # balances truncation and round-off for the 4-point stencil
            ei, ej = hh * np.eye(n)[i], hh * np.eye(n)[j]
            # (0)-Hessian: second derivative along one-parameter subgroups, polarised
            hess[i, j] = (f(ei + ej) - f(ei - ej) - f(-ei + ej) + f(-ei - ej)) / (4 * hh * hh)
    scale = max(1.0, np.abs(hess).max())
    assert np.abs(grad[:6] - d.lx[0]).max() < 1e-6 * scale
    assert np.abs(hess[:6, :6] - d.lxx[0]).max() < 1e-5 * scale
    if m:
        assert np.abs(grad[6:] - d.lu[0]).max() < 1e-6 * scale
        assert np.abs(hess[6:, 6:] - d.luu[0]).max() < 1e-5 * scale
        assert np.abs(hess[6:, :6] - d.lux[0]).max() < 1e-5 * scale


@pytest.mark.parametrize("angle", [0.3, 1.5, 2.9])
def test_chordal_attitude(rng, angle):
    Rd = pin.exp3(rng.normal(size=3))
    ax = rng.normal(size=3)
    R = Rd @ pin.exp3(angle * ax / np.linalg.norm(ax))
    _fd_check(AttitudeChordal(S3, Rd), rng, R, rng.normal(size=3), None)


def test_chordal_matches_the_papers_closed_forms(rng):
    Rd, R = pin.exp3(rng.normal(size=3)), pin.exp3(rng.normal(size=3))
    S = 7.0 * np.eye(3)
    d = CostSum([AttitudeChordal(S, Rd)]).derivatives(R[None], np.zeros((1, 3)), None)
    E = Rd.T @ R
    SE = S @ E
    assert np.isclose(d.l[0], 0.5 * np.trace((np.eye(3) - E).T @ S @ (np.eye(3) - E)))
    skew = 0.5 * (SE - SE.T)
    assert np.allclose(d.lx[0, :3], 2 * np.array([skew[2, 1], skew[0, 2], skew[1, 0]]))
    Hm = np.trace(SE) * np.eye(3) - SE
    assert np.allclose(d.lxx[0, :3, :3], 0.5 * (Hm + Hm.T))


@pytest.mark.parametrize("angle", [1e-9, 0.3, 1.5, 2.9])
def test_geodesic_attitude(rng, angle):
    Rd = pin.exp3(rng.normal(size=3))
    ax = rng.normal(size=3)
    R = Rd @ pin.exp3(angle * ax / np.linalg.norm(ax))
    term = AttitudeGeodesic(S3, Rd)
    d = CostSum([term]).derivatives(R[None], np.zeros((1, 3)), None)
    assert np.all(np.isfinite(d.lxx))
    _fd_check(term, rng, R, rng.normal(size=3), None)


def test_angular_velocity_and_control(rng):
    R = pin.exp3(rng.normal(size=3))
    _fd_check(AngularVelocityQuadratic(S3, rng.normal(size=3)), rng, R, rng.normal(size=3), None)
    Su = np.array([[0.3, 0.1], [0.1, 0.2]])
    _fd_check(ControlQuadratic(Su, u_ref=np.array([0.5, -1.0])), rng, R, rng.normal(size=3), rng.normal(size=2))


def test_sum_of_terms_adds_up(rng):
    Rd, R = pin.exp3(rng.normal(size=3)), pin.exp3(rng.normal(size=3))
    Om = rng.normal(size=3)
    a, b = AttitudeGeodesic(S3, Rd), AngularVelocityQuadratic(2.0, np.zeros(3))
    s = CostSum([a, b]).derivatives(R[None], Om[None], None)
    da = CostSum([a]).derivatives(R[None], Om[None], None)
    db = CostSum([b]).derivatives(R[None], Om[None], None)
    assert np.allclose(s.lx, da.lx + db.lx) and np.allclose(s.lxx, da.lxx + db.lxx)
    assert np.isclose(s.l[0], da.l[0] + db.l[0])
