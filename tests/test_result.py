"""Result: JSON round trip, quaternion conversion."""
import numpy as np
import pinocchio as pin

from geoddp.result import Result, rotations_to_quaternions


def test_quaternions_match_pinocchio_and_are_sign_continuous(rng):
    Rs = np.array([pin.exp3(np.array([0.0, 0.0, t])) for t in np.linspace(0, 2 * np.pi - 0.1, 200)])
    q = rotations_to_quaternions(Rs)
    for R, qi in zip(Rs, q):
        ref = pin.Quaternion(R).coeffs()  # (x, y, z, w)
        assert min(np.abs(qi - ref).max(), np.abs(qi + ref).max()) < 1e-14
    assert np.all(np.einsum("ni,ni->n", q[1:], q[:-1]) > 0)
    assert q[0, 3] > 0


def test_json_round_trip(paper_solves, tmp_path):
    r = paper_solves["switch"]
    back = Result.read_json(r.write_json(tmp_path / "r.json"))
    for name in ("rotations", "angular_velocities", "controls", "feedback", "cost_history", "control_history"):
        assert np.array_equal(getattr(back, name), getattr(r, name)), name
    assert back.cost == r.cost and back.status == r.status and back.iterations == r.iterations


def test_time_history_is_monotone_and_one_per_iterate(paper_solves):
    for r in paper_solves.values():
        assert r.time_history.shape == r.cost_history.shape
        assert np.all(np.diff(r.time_history) > 0) and r.time_history[-1] <= r.solve_time_s
