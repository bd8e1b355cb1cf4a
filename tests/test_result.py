"""Result: JSON round trip, quaternion conversion."""
import numpy as np
import pinocchio as pin
import pytest

from geoddp import Result
from geoddp.solver.result import MultibodyResult, SatelliteResult, rotations_to_quaternions


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


# ----------------------------------------------------------------------------- generic Result, old files

import json  # noqa: E402
from pathlib import Path  # noqa: E402

DATA = Path(__file__).resolve().parent / "data"
# Every field of the JSON written by main at 1c82f17 (before the generic Result).
V0_FIELDS = {
    "cost", "iterations", "converged", "status", "message", "expansion", "integrator", "dt", "horizon",
    "cost_history", "grad_norm_history", "reg_history", "step_history", "expansion_history", "attitude_error_deg",
    "angular_velocity_error", "grad_norm", "solve_time_s", "timings", "times", "controls", "quaternions",
    "angular_velocities", "rotations", "feedforward", "feedback", "target_rotation", "target_angular_velocity",
    "control_history", "time_history", "configurations", "velocities", "multibody",
}


@pytest.mark.parametrize("kind", ["satellite", "multibody"])
def test_v0_json_still_loads_and_writes_the_same_fields(kind, tmp_path):
    """A file written before the generic Result loads; its views equal what it stored, and writing
    it again gives every old field with the same values (plus ``model``)."""
    path = DATA / f"result_v0_{kind}.json"
    old = json.loads(path.read_text())
    assert set(old) == V0_FIELDS
    r = Result.read_json(path)
    assert type(r) is (MultibodyResult if kind == "multibody" else SatelliteResult) and isinstance(r, Result)
    assert r.integrator == old["integrator"] and r.dt == old["dt"] and r.horizon == old["horizon"]
    new = json.loads(r.write_json(tmp_path / "again.json").read_text())
    assert set(new) == V0_FIELDS | {"model", "optimality", "limits", "active_set", "constraints"}
    for key in V0_FIELDS - {"solve_time_s"}:
        a, b = old[key], new[key]
        if isinstance(a, list) and a and not isinstance(a[0], str):
            np.testing.assert_allclose(np.array(b, dtype=float), np.array(a, dtype=float), rtol=0, atol=1e-15,
                                       err_msg=key)
        else:
            assert a == b, key
    if kind == "multibody":
        # the root-body views are derived from (q, v) and the description, as main stored them
        assert r.multibody["root"] == old["multibody"]["root"] and r.q.shape == (r.horizon + 1, old["multibody"]["nq"])
        assert np.array_equal(r.configurations, np.array(old["configurations"]))
    else:
        assert not hasattr(r, "configurations") and not hasattr(r, "multibody")  # views of the multibody kind only
        assert new["configurations"] is None and new["velocities"] is None and new["multibody"] is None
        assert np.array_equal(r.q, np.array(old["rotations"]))
    back = Result.read_json(tmp_path / "again.json")  # and the new file reads back the same
    assert back.model.keys() == r.model.keys()
    assert np.array_equal(back.rotations, r.rotations) and np.array_equal(back.feedback, r.feedback)


def test_views_of_a_multibody_solve_match_the_root_joint():
    """Rotations / rates of a multibody Result come from its root joint's slice of (q, v)."""
    from viz_fixtures import multibody_result

    r = multibody_result()  # space manipulator: free-flyer root
    assert type(r) is MultibodyResult and r.model["root"] == "free_flyer"
    for k in (0, r.horizon):
        q = r.q[k]
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).normalized().toRotationMatrix()
        assert np.abs(r.rotations[k] - R).max() <= 1e-15
        assert np.array_equal(r.angular_velocities[k], r.v[k, 3:6])
    assert np.array_equal(r.configurations, r.q) and np.array_equal(r.velocities, r.v)


def test_satellite_result_views_are_the_state_and_the_description(paper_solves):
    r = paper_solves["switch"]
    assert type(r) is SatelliteResult and r.model["kind"] == "satellite" and r.integrator == "euler"
    assert r.rotations is r.q and r.angular_velocities is r.v
    R_d = pin.exp3(np.array([np.pi / 6, 0, 0])) @ pin.exp3(np.array([0, 0, np.radians(70.0)]))
    assert np.abs(r.target_rotation - R_d).max() <= 1e-15
    assert np.array_equal(r.target_angular_velocity, np.zeros(3))


def test_result_accepts_the_pre_generic_keywords():
    from viz_fixtures import synthetic_result

    r = synthetic_result(horizon=4)
    assert r.q.shape == (5, 3, 3) and r.rotations is r.q and r.model["kind"] == "satellite"
    assert r.integrator == "euler" and r.model["dt"] == r.dt


def test_multibody_json_holds_the_urdf_once_and_reads_back(tmp_path):
    from viz_fixtures import multibody_result

    r = multibody_result()
    text = r.write_json(tmp_path / "m.json").read_text()
    d = json.loads(text)
    assert "urdf_xml" not in d["model"] and d["multibody"]["urdf_xml"] == r.model["urdf_xml"]
    back = Result.read_json(tmp_path / "m.json")
    assert back.model.keys() == r.model.keys() and back.multibody == r.multibody
    assert np.array_equal(back.rotations, r.rotations) and np.array_equal(back.configurations, r.configurations)
