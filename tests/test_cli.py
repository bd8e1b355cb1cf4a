"""Issue 5, bad input via the CLI: ``geoddp.cli.main`` run in-process on scene files in tmp_path.

Every bad scene must give exit code 2 and one line on stderr naming the offending parameter, with
no traceback. A good scene gives 0 and a complete JSON; a run capped at max_iter = 1 gives 1.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from geoddp.cli import EXIT_BAD_INPUT, EXIT_CONVERGED, EXIT_NOT_CONVERGED, main

# The paper's problem on a coarse grid (H = 30) so that the good runs take milliseconds.
GOOD = """\
name = "cli_test"

[model]
inertia = [10.0, 11.1, 13.0]
actuation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]

[initial]
quaternion = [0.0, 0.0, 0.0, 1.0]
angular_velocity = [0.0, 0.0, 0.0]

[target]
euler_intrinsic = [["x", 30.0], ["z", 70.0]]
angular_velocity = [0.0, 0.0, 0.0]

[horizon]
tf = 3.0
dt = 0.1
integrator = "euler"

[cost]
control = 0.1
attitude = 1e4
attitude_kind = "chordal"
angular_velocity = 1e4

[solver]
expansion = "switch"
tol = 1e-8
max_iter = 200
"""
H, M = 30, 3


def _sub(old: str, new: str) -> str:
    assert GOOD.count(old) == 1, old
    return GOOD.replace(old, new)


QUAT = "quaternion = [0.0, 0.0, 0.0, 1.0]"
INERTIA = "inertia = [10.0, 11.1, 13.0]"
ACT = "actuation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]"
OMEGA0 = "[initial]\nquaternion = [0.0, 0.0, 0.0, 1.0]\nangular_velocity = [0.0, 0.0, 0.0]"

# id -> (scene text, parameter that the message must name)
BAD = {
    "rotation_not_orthonormal": (
        _sub(QUAT, "rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.1, 1.0]]"), "[initial].rotation"),
    "rotation_det_minus_1": (
        _sub(QUAT, "rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]"), "[initial].rotation"),
    "target_rotation_scaled": (
        _sub('euler_intrinsic = [["x", 30.0], ["z", 70.0]]',
             "rotation = [[1.1, 0.0, 0.0], [0.0, 1.1, 0.0], [0.0, 0.0, 1.1]]"), "[target].rotation"),
    "quaternion_norm_1p1": (_sub(QUAT, "quaternion = [0.0, 0.0, 0.0, 1.1]"), "[initial].quaternion"),
    "quaternion_3_entries": (_sub(QUAT, "quaternion = [0.0, 0.0, 1.0]"), "[initial].quaternion"),
    "inertia_shape": (_sub(INERTIA, "inertia = [10.0, 11.1]"), "[model].inertia"),
    "inertia_shape_2x3": (_sub(INERTIA, "inertia = [[10.0, 0.0, 0.0], [0.0, 11.1, 0.0]]"), "[model].inertia"),
    "actuation_shape": (_sub(ACT, "actuation = [[1.0, 0.0], [0.0, 1.0]]"), "[model].actuation"),
    "actuation_zero_column": (
        _sub(ACT, "actuation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]]"), "[model].actuation"),
    "weight_shape_attitude": (_sub("attitude = 1e4", "attitude = [1.0, 2.0]"), "[cost].attitude"),
    "weight_shape_control": (
        _sub("control = 0.1", "control = [[0.1, 0.0], [0.0, 0.1]]"), "[cost].control"),
    "initial_controls_shape": (
        _sub("max_iter = 200", "max_iter = 200\ninitial_controls = [[0.0, 0.0, 0.0]]"), "[solver].initial_controls"),
    "initial_controls_nan": (
        _sub("max_iter = 200", "max_iter = 200\ninitial_controls = " + str([[0.0, 0.0, 0.0]] * (H - 1) + [["nan"]])
             .replace("'nan'", "nan, 0.0, 0.0")), "[solver].initial_controls"),
    "nan_angular_velocity": (
        _sub(OMEGA0, OMEGA0.replace("angular_velocity = [0.0, 0.0, 0.0]", "angular_velocity = [nan, 0.0, 0.0]")),
        "[initial].angular_velocity"),
    "nan_quaternion": (_sub(QUAT, "quaternion = [0.0, 0.0, nan, 1.0]"), "[initial].quaternion"),
    "nan_weight": (_sub("control = 0.1", "control = nan"), "[cost].control"),
    "inf_inertia": (_sub(INERTIA, "inertia = [inf, 11.1, 13.0]"), "[model].inertia"),
    "inf_weight": (_sub("angular_velocity = 1e4", "angular_velocity = inf"), "[cost].angular_velocity"),
    "inf_tf": (_sub("tf = 3.0", "tf = inf"), "[horizon].tf"),
    "dt_zero": (_sub("dt = 0.1", "dt = 0.0"), "[horizon].dt"),
    "dt_negative": (_sub("dt = 0.1", "dt = -0.1"), "[horizon].dt"),
    "tf_not_multiple_of_dt": (_sub("tf = 3.0", "tf = 3.05"), "[horizon].tf"),
    "inertia_not_spd": (
        _sub(INERTIA, "inertia = [[10.0, 20.0, 0.0], [20.0, 10.0, 0.0], [0.0, 0.0, 13.0]]"), "[model].inertia"),
    "inertia_negative": (_sub(INERTIA, "inertia = [10.0, -11.1, 13.0]"), "[model].inertia"),
    "inertia_triangle_inequality": (_sub(INERTIA, "inertia = [1.0, 1.0, 10.0]"), "[model].inertia"),
    "control_weight_not_spd": (_sub("control = 0.1", "control = -0.1"), "[cost].control"),
    "control_weight_zero": (_sub("control = 0.1", "control = 0.0"), "[cost].control"),
    "attitude_weight_indefinite": (
        _sub("attitude = 1e4", "attitude = [[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]"), "[cost].attitude"),
    "attitude_weight_not_symmetric": (
        _sub("attitude = 1e4", "attitude = [[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]"), "[cost].attitude"),
    "unknown_expansion": (_sub('expansion = "switch"', 'expansion = "third"'), "[solver].expansion"),
    "unknown_integrator": (_sub('integrator = "euler"', 'integrator = "rk5"'), "[horizon].integrator"),
    "unknown_attitude_kind": (_sub('attitude_kind = "chordal"', 'attitude_kind = "quat"'), "[cost].attitude_kind"),
    "negative_tol": (_sub("tol = 1e-8", "tol = -1e-8"), "[solver].tol"),
    "max_iter_zero": (_sub("max_iter = 200", "max_iter = 0"), "[solver].max_iter"),
    "max_iter_float": (_sub("max_iter = 200", "max_iter = 2.5"), "[solver].max_iter"),
    "malformed_toml": (_sub("tf = 3.0", "tf = 3.0.0"), "scene file"),
    "malformed_toml_unclosed": (_sub("dt = 0.1", "dt = [0.1"), "scene file"),
    "misspelled_key": (_sub(INERTIA, "inertai = [10.0, 11.1, 13.0]"), "[model].inertai"),
    "misspelled_section": (_sub("[horizon]", "[horizion]"), "[horizion]"),
    "missing_key": (_sub("dt = 0.1\n", ""), "[horizon].dt"),
    "string_for_number": (_sub("tf = 3.0", 'tf = "3.0"'), "[horizon].tf"),
}


def _run(capsys, argv):
    code = main(argv)
    cap = capsys.readouterr()
    return code, cap.out, cap.err


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_scene_exits_2_with_one_line_naming_the_parameter(tmp_path, capsys, case):
    text, param = BAD[case]
    path = tmp_path / f"{case}.toml"
    path.write_text(text)
    code, out, err = _run(capsys, ["run", str(path), "--quiet", "--json", str(tmp_path / "out.json")])
    assert code == EXIT_BAD_INPUT, (code, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("geoddp: error: "), err
    assert param in lines[0], (param, lines[0])
    assert "Traceback" not in err and "Traceback" not in out
    assert not (tmp_path / "out.json").exists()


def test_missing_scene_file_exits_2(tmp_path, capsys):
    code, out, err = _run(capsys, ["run", str(tmp_path / "nope.toml"), "--quiet"])
    assert code == EXIT_BAD_INPUT
    assert len(err.strip().splitlines()) == 1 and "scene file" in err and "Traceback" not in err


def test_good_scene_exits_0_and_writes_the_json(tmp_path, capsys):
    path = tmp_path / "good.toml"
    path.write_text(GOOD)
    out_json = tmp_path / "sub" / "result.json"
    code, out, err = _run(capsys, ["run", str(path), "--quiet", "--json", str(out_json)])
    assert code == EXIT_CONVERGED, (out, err)
    assert err == ""
    d = json.loads(out_json.read_text())
    keys = ("cost", "iterations", "converged", "status", "cost_history", "grad_norm_history",
            "attitude_error_deg", "angular_velocity_error", "solve_time_s", "controls", "quaternions",
            "angular_velocities")
    for k in keys:
        assert k in d, k
    assert d["converged"] is True and d["status"].startswith("converged")
    assert isinstance(d["iterations"], int) and d["iterations"] >= 1
    assert len(d["cost_history"]) == len(d["grad_norm_history"]) == d["iterations"] + 1
    assert d["cost"] == d["cost_history"][-1]
    assert np.asarray(d["controls"]).shape == (H, M)
    q = np.asarray(d["quaternions"])
    assert q.shape == (H + 1, 4)
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
    assert np.asarray(d["angular_velocities"]).shape == (H + 1, 3)
    for k in ("cost", "attitude_error_deg", "angular_velocity_error", "solve_time_s"):
        assert np.isfinite(d[k]), k
    assert np.all(np.diff(d["cost_history"]) <= 0.0)


def test_underactuated_json_has_m_columns(tmp_path, capsys):
    path = tmp_path / "two_inputs.toml"
    path.write_text(_sub(ACT, "actuation = [[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]"))
    out_json = tmp_path / "r.json"
    code, out, err = _run(capsys, ["run", str(path), "--quiet", "--json", str(out_json)])
    assert code in (EXIT_CONVERGED, EXIT_NOT_CONVERGED), err
    assert np.asarray(json.loads(out_json.read_text())["controls"]).shape == (H, 2)


def test_max_iter_1_exits_1(tmp_path, capsys):
    path = tmp_path / "capped.toml"
    path.write_text(_sub("max_iter = 200", "max_iter = 1"))
    out_json = tmp_path / "capped.json"
    code, out, err = _run(capsys, ["run", str(path), "--quiet", "--json", str(out_json)])
    assert code == EXIT_NOT_CONVERGED, (out, err)
    assert err == ""
    d = json.loads(out_json.read_text())
    assert d["converged"] is False and d["iterations"] == 1 and "max_iter" in d["status"]


def test_multibody_scene_from_the_cli(tmp_path, capsys):
    from geoddp.cli import main

    out = tmp_path / "quad.json"
    code = main(["multibody", "quadrotor", "--quiet", "--json", str(out)])
    assert code == 0, capsys.readouterr()
    d = json.loads(out.read_text())
    assert d["converged"] and np.array(d["configurations"]).shape == (151, 7)
    assert np.array(d["velocities"]).shape == (151, 6) and np.array(d["controls"]).shape == (150, 4)
    assert np.all(np.diff(d["cost_history"]) <= 0.0)


# ------------------------------------------------------------------ built-in scenes by name (issue 11)


def _j_star(out: str) -> float:
    line = next(ln for ln in out.splitlines() if ln.startswith("J* = "))
    return float(line.split()[2])


def test_run_a_builtin_satellite_scene_by_name(tmp_path, capsys, monkeypatch):
    """`geoddp run satellite_paper` from a folder without the file: the paper's J* (README table)."""
    monkeypatch.chdir(tmp_path)
    out_json = tmp_path / "paper.json"
    code, out, err = _run(capsys, ["run", "satellite_paper", "--quiet", "--json", str(out_json)])
    assert code == EXIT_CONVERGED and err == "", err
    assert abs(_j_star(out) - 510.3726365588) < 1e-9
    d = json.loads(out_json.read_text())
    assert abs(d["cost"] - 510.3726365588) < 1e-9 and d["iterations"] == 4
    assert np.asarray(d["controls"]).shape == (300, 3) and d["multibody"] is None


def test_run_a_builtin_multibody_scene_by_name_equals_the_alias_and_the_file(tmp_path, capsys, monkeypatch):
    """`run quadrotor`, `multibody quadrotor` and `run examples/multibody/quadrotor.toml` are one solve."""
    from geoddp.data import scene_path

    costs = {}
    for key, argv in (("name", ["run", "quadrotor"]), ("alias", ["multibody", "quadrotor"]),
                      ("file", ["run", str(scene_path("quadrotor"))])):
        out_json = tmp_path / f"{key}.json"
        code, out, err = _run(capsys, argv + ["--quiet", "--json", str(out_json)])
        assert code == EXIT_CONVERGED and err == "", (key, err)
        d = json.loads(out_json.read_text())
        assert d["iterations"] == 10 and abs(d["cost"] - 1.552033527923) < 1e-11, (key, d["cost"], d["iterations"])
        assert "terminal frame_placement 'body': position error = 9.481e-04 m  rotation error = 0.1434 deg" in out
        costs[key] = d["cost_history"]
    assert costs["name"] == costs["alias"] == costs["file"]


def test_compare_accepts_a_builtin_name(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = _run(capsys, ["compare", "satellite_semi_implicit", "--quiet"])
    assert code == EXIT_CONVERGED and err == "", err
    rows = [ln for ln in out.splitlines() if ln.startswith("| first") or ln.startswith("| switch")]
    assert len(rows) == 2 and all(abs(float(r.split("|")[3]) - 494.7163633884) < 1e-9 for r in rows)


@pytest.mark.parametrize("name,guess", [("quadrotr", "quadrotor"), ("satelite_paper", "satellite_paper"),
                                        ("tumbling_5rad", "tumbling_5rads")])
def test_unknown_scene_name_exits_2_with_one_line_and_a_suggestion(tmp_path, capsys, monkeypatch, name, guess):
    monkeypatch.chdir(tmp_path)
    code, out, err = _run(capsys, ["run", name, "--quiet"])
    assert code == EXIT_BAD_INPUT and out == ""
    (line,) = err.strip().splitlines()
    assert line.startswith(f"geoddp: error: scene: expected a built-in scene name or a scene file, got {name!r}; "
                           f"did you mean {guess!r}? built-in scenes: "), line
    assert "satellite_paper" in line and "Traceback" not in err


def test_a_file_in_the_current_folder_wins_over_a_builtin_name(tmp_path, capsys, monkeypatch):
    """A file literally called `quadrotor` (here: the coarse satellite scene) is read, not the built-in."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "quadrotor").write_text(GOOD)
    code, out, err = _run(capsys, ["run", "quadrotor", "--quiet", "--json", "r.json"])
    assert code == EXIT_CONVERGED, err
    d = json.loads((tmp_path / "r.json").read_text())
    assert np.asarray(d["controls"]).shape == (H, M) and d["multibody"] is None


def test_multibody_alias_keeps_its_choices(capsys):
    with pytest.raises(SystemExit) as info:
        main(["multibody", "satellite_paper"])
    assert info.value.code == EXIT_BAD_INPUT
    assert "invalid choice: 'satellite_paper'" in capsys.readouterr().err
