"""Scene keys for control limits (issue 15): ``[limits] control_min / control_max`` (a number or one
per input) for every kind, ``effort_limits = "urdf"`` for multibody scenes; the example scenes
(satellite with reaction-wheel limits, quadrotor with rotor thrust limits) solved from the CLI and
the API; bad values named by their key path and file."""
import json
import tomllib

import numpy as np
import pytest

from geoddp import cli
from geoddp import solve_scene
from geoddp.scene import build_problem, load_scene, parse_scene, scene_file
from geoddp.validate import InputError


def scene_dict(name: str) -> dict:
    return tomllib.loads(scene_file(name).read_text())


def with_limits(name: str, **limits) -> dict:
    d = scene_dict(name)
    d["limits"] = limits
    return d


def test_satellite_wheel_limits_example():
    spec = load_scene("satellite_wheel_limits")
    np.testing.assert_array_equal(spec.control_min, [-5.0] * 3)
    np.testing.assert_array_equal(spec.control_max, [5.0] * 3)
    r = solve_scene(spec, verbose=False)
    assert r.converged, r.message
    assert r.cost == pytest.approx(609.5420669, rel=1e-9)
    np.testing.assert_array_equal((r.active_set != 0).any(axis=0), [False, False, True])
    assert r.extra["optimality"]["kkt_residual"] <= 1e-5
    # the same scene without its limits is the paper's problem
    free = solve_scene(spec.with_overrides(control_min=None, control_max=None), verbose=False)
    assert free.cost == pytest.approx(510.3726366, rel=1e-9) and free.limits is None
    # |u_i| <= 3 through an override: all three axes saturate
    r3 = solve_scene(spec.with_overrides(control_min=-3.0, control_max=3.0), verbose=False)
    np.testing.assert_array_equal((r3.active_set != 0).any(axis=0), [True, True, True])
    assert r3.cost == pytest.approx(1392.846355, rel=1e-9)


def test_quadrotor_thrust_limits_example():
    spec = load_scene("quadrotor_thrust_limits")
    p = build_problem(spec)
    lo, hi = p.control_bounds()
    assert np.all(lo == 0.0) and np.all(hi == 4.0)
    r = solve_scene(spec, verbose=False)
    assert r.converged, r.message
    assert r.cost == pytest.approx(1.760971054, rel=1e-8)
    assert (r.active_set == 1).sum() == 138 and not (r.active_set == -1).any()
    assert np.all(r.controls >= 0.0) and np.all(r.controls <= 4.0)


def test_cli_run_reports_limits_and_writes_them(tmp_path, capsys):
    out = tmp_path / "r.json"
    code = cli.main(["run", "satellite_wheel_limits", "--quiet", "--json", str(out), "--plots", str(tmp_path)])
    assert code == 0
    text = capsys.readouterr().out
    assert "limits: 210 of 900 (node, input) pairs on a bound (u_1: 0, u_2: 0, u_3: 210)" in text
    d = json.loads(out.read_text())
    assert d["limits"]["upper"][0] == [5.0, 5.0, 5.0]
    assert sum(a != 0 for row in d["active_set"] for a in row) == 210
    assert (tmp_path / "controls.png").stat().st_size > 0


def test_effort_limits_from_the_urdf():
    d = with_limits("space_manipulator", effort_limits="urdf")
    p = build_problem(parse_scene(d))
    lo, hi = p.control_bounds()
    np.testing.assert_array_equal(hi[0], [50.0, 50.0, 50.0])
    np.testing.assert_array_equal(lo[0], [-50.0, -50.0, -50.0])
    # with numbers too: the tighter bound per input
    d = with_limits("space_manipulator", effort_limits="urdf", control_max=[20.0, 80.0, np.inf])
    lo, hi = build_problem(parse_scene(d)).control_bounds()
    np.testing.assert_array_equal(hi[0], [20.0, 50.0, 50.0])
    np.testing.assert_array_equal(lo[0], [-50.0, -50.0, -50.0])
    # numbers that contradict the URDF
    d = with_limits("space_manipulator", effort_limits="urdf", control_min=60.0)
    with pytest.raises(InputError) as e:
        build_problem(parse_scene(d))
    assert e.value.parameter == "[limits].control_min" and "effort" in str(e.value)


@pytest.mark.parametrize("name, limits, parameter, words", [
    ("satellite_paper", {"control_min": 1.0, "control_max": -1.0}, "[limits].control_min", "lower <= upper"),
    ("satellite_paper", {"control_min": [1.0, 2.0]}, "[limits].control_min", "3 numbers"),
    ("satellite_paper", {"control_max": [1.0, float("nan"), 2.0]}, "[limits].control_max", "NaN"),
    ("satellite_paper", {"control_max": "five"}, "[limits].control_max", "expected a number"),
    ("satellite_paper", {"control_min": float("inf")}, "[limits].control_min", "+inf"),
    ("satellite_paper", {"effort_limits": "urdf"}, "[limits].effort_limits", "only multibody"),
    ("space_manipulator", {"effort_limits": "sdf"}, "[limits].effort_limits", "urdf"),
    ("satellite_paper", {"control_maximum": 3.0}, "[limits].control_maximum", "control_max"),
])
def test_bad_limit_keys_name_the_key(name, limits, parameter, words):
    with pytest.raises(InputError) as e:
        parse_scene(with_limits(name, **limits), source="scene.toml")
    assert e.value.parameter == parameter, str(e.value)
    assert words in str(e.value) and "scene.toml" in str(e.value)


def test_effort_limits_need_joint_motors():
    with pytest.raises(InputError) as e:
        build_problem(parse_scene(with_limits("quadrotor", effort_limits="urdf")))
    assert e.value.parameter == "[limits].effort_limits" and "not a joint motor" in str(e.value)


def test_initial_guess_outside_the_limits_names_the_key():
    d = with_limits("quadrotor", control_min=0.0, control_max=3.0)  # "hover" is 3.68 N per rotor
    with pytest.raises(InputError) as e:
        parse_scene(d, source="q.toml")
    assert e.value.parameter == "[solver].initial_controls" and "outside the limits" in str(e.value)
    d = with_limits("satellite_paper", control_max=1.0)
    d["solver"]["initial_controls"] = [[2.0, 0.0, 0.0]] * 300
    with pytest.raises(InputError) as e:
        parse_scene(d)
    assert e.value.parameter == "[solver].initial_controls"
    spec = load_scene("satellite_wheel_limits")
    with pytest.raises(InputError) as e:
        spec.with_overrides(initial_controls=np.full((300, 3), 6.0))
    assert e.value.parameter == "initial_controls"
