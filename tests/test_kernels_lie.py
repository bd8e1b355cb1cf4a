"""The compiled SO(3) kernels (geoddp.kernels.lie) against Pinocchio near 0 and near pi."""
import numpy as np
import pinocchio as pin
import pytest

from geoddp import kernels


def _vectors(rng, scale, n=12):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True) * scale


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
