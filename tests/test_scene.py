"""Tests for geoddp.scene: the example scenes load to the intended numbers, and every kind of
bad scene file fails with an InputError naming the key path and the file."""
from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from geoddp.scene import SceneSpec, load_scene, parse_scene
from geoddp.validate import InputError

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
PAPER = EXAMPLES / "satellite_paper.toml"
PAPER_TEXT = PAPER.read_text()

# Independent construction of the paper's target: intrinsic X then Z (scipy: upper case).
RD_PAPER = Rotation.from_euler("XZ", [30.0, 70.0], degrees=True).as_matrix()


def write(tmp_path: Path, text: str, name: str = "scene.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def edit(text: str, old: str, new: str) -> str:
    assert old in text, f"test setup: {old!r} not in scene text"
    return text.replace(old, new, 1)


def load_error(tmp_path: Path, text: str) -> InputError:
    p = write(tmp_path, text)
    with pytest.raises(InputError) as info:
        load_scene(p)
    err = info.value
    # Every scene error names the file it came from.
    assert str(p) in str(err), str(err)
    return err


# ------------------------------------------------------------------ the paper scene


def test_paper_scene_is_table_1():
    s = load_scene(PAPER)
    assert s.name == "satellite_paper"
    assert s.source == str(PAPER)
    np.testing.assert_array_equal(s.inertia, np.diag([10.0, 11.1, 13.0]))
    np.testing.assert_array_equal(s.actuation, np.eye(3))
    assert s.num_inputs == 3
    assert s.urdf is None
    np.testing.assert_array_equal(s.R0, np.eye(3))
    np.testing.assert_array_equal(s.Omega0, np.zeros(3))
    np.testing.assert_allclose(s.Rd, RD_PAPER, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(s.Omegad, np.zeros(3))
    assert s.tf == 3.0 and s.dt == 0.01 and s.horizon == 300
    assert s.integrator == "euler"
    np.testing.assert_array_equal(s.S_u, 0.1 * np.eye(3))
    np.testing.assert_array_equal(s.S_R, 1e4 * np.eye(3))
    np.testing.assert_array_equal(s.S_Omega, 1e4 * np.eye(3))
    assert s.attitude_kind == "chordal"
    np.testing.assert_array_equal(s.running_S_R, np.zeros((3, 3)))
    np.testing.assert_array_equal(s.running_S_Omega, np.zeros((3, 3)))
    assert s.expansion == "switch" and s.switch_ratio == 0.1
    assert s.tol == 1e-8 and s.grad_tol == 1e-10 and s.max_iter == 200
    assert s.second_order == "exact"
    assert s.initial_controls is None


def test_paper_rd_is_not_the_extrinsic_composition():
    # Guards the intrinsic/extrinsic convention: the extrinsic "xz" rotation differs.
    s = load_scene(PAPER)
    assert not np.allclose(s.Rd, Rotation.from_euler("xz", [30.0, 70.0], degrees=True).as_matrix())


def test_paper_header_cites_table_1():
    assert "Table I" in PAPER_TEXT.split("name =")[0]


def test_semi_implicit_scene_differs_only_in_integrator_and_attitude_kind():
    a = load_scene(PAPER)
    b = load_scene(EXAMPLES / "satellite_semi_implicit.toml")
    assert b.integrator == "semi_implicit" and b.attitude_kind == "geodesic"
    assert b == a.with_overrides(
        integrator="semi_implicit", attitude_kind="geodesic", name=b.name,
        description=b.description, source=b.source,
    )


def test_parse_scene_dict_equals_load_scene():
    d = tomllib.loads(PAPER_TEXT)
    assert parse_scene(d, source=str(PAPER)) == load_scene(PAPER)
    s = parse_scene(d)
    assert s.source == "<dict>"


def test_spec_arrays_are_read_only_copies():
    s = load_scene(PAPER)
    with pytest.raises(ValueError):
        s.S_R[0, 0] = 0.0
    with pytest.raises(AttributeError):
        s.tf = 4.0  # type: ignore[misc]


# ------------------------------------------------------------------ hard scenes


def _angle_deg(R: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))))


def _rot(axis, deg) -> np.ndarray:
    a = np.asarray(axis, float)
    return Rotation.from_rotvec(np.deg2rad(deg) * a / np.linalg.norm(a)).as_matrix()


HARD = {
    "target_179deg_x.toml": lambda s: np.testing.assert_allclose(s.Rd, _rot([1, 0, 0], 179.0), atol=1e-15),
    "target_179p9deg_x.toml": lambda s: np.testing.assert_allclose(s.Rd, _rot([1, 0, 0], 179.9), atol=1e-15),
    "target_179deg_axis111.toml": lambda s: np.testing.assert_allclose(s.Rd, _rot([1, 1, 1], 179.0), atol=1e-14),
    "target_179p9deg_axis111.toml": lambda s: np.testing.assert_allclose(s.Rd, _rot([1, 1, 1], 179.9), atol=1e-14),
    "target_180deg_x.toml": lambda s: np.testing.assert_array_equal(s.Rd, np.diag([1.0, -1.0, -1.0])),
    "tumbling_2rads.toml": lambda s: (
        np.testing.assert_allclose(np.linalg.norm(s.Omega0), 2.0, rtol=1e-15),
        np.testing.assert_array_equal(np.sign(s.Omega0), [1, -1, 1]),
    ),
    "tumbling_5rads.toml": lambda s: (
        np.testing.assert_allclose(np.linalg.norm(s.Omega0), 5.0, rtol=1e-15),
        np.testing.assert_array_equal(np.sign(s.Omega0), [1, -1, 1]),
    ),
    "long_horizon_H3000.toml": lambda s: (s.tf, s.horizon) == (30.0, 3000) or pytest.fail(str(s.horizon)),
    "inertia_ratio_1000.toml": lambda s: np.testing.assert_array_equal(s.inertia, np.diag([1.0, 1000.0, 1000.0])),
    "underactuated_2inputs.toml": lambda s: (
        np.testing.assert_array_equal(s.actuation, [[1, 0], [0, 1], [0, 0]]),
        np.testing.assert_array_equal(s.S_u, 0.1 * np.eye(2)),
    ),
    "coarse_dt_0p1.toml": lambda s: (s.dt, s.horizon) == (0.1, 30) or pytest.fail(str(s.horizon)),
    "fine_dt_1e-4.toml": lambda s: (s.tf, s.dt, s.horizon) == (0.5, 1e-4, 5000) or pytest.fail(str(s.horizon)),
    "extreme_weights.toml": lambda s: (
        np.testing.assert_array_equal(s.S_R, 1e8 * np.eye(3)),
        np.testing.assert_array_equal(s.S_Omega, 1e8 * np.eye(3)),
        np.testing.assert_array_equal(s.S_u, 1e-8 * np.eye(3)),
    ),
}


def test_every_hard_scene_file_is_covered():
    assert sorted(p.name for p in (EXAMPLES / "hard").glob("*.toml")) == sorted(HARD)


@pytest.mark.parametrize("fname", sorted(HARD))
def test_hard_scene_loads(fname):
    path = EXAMPLES / "hard" / fname
    first = path.read_text().splitlines()[0]
    assert first.startswith("# Hard case: "), "each hard scene states what it tests on line 1"
    s = load_scene(path)
    HARD[fname](s)


@pytest.mark.parametrize("fname, deg", [
    ("target_179deg_x.toml", 179.0), ("target_179p9deg_x.toml", 179.9),
    ("target_179deg_axis111.toml", 179.0), ("target_179p9deg_axis111.toml", 179.9),
    ("target_180deg_x.toml", 180.0),
])
def test_hard_target_angles(fname, deg):
    assert _angle_deg(load_scene(EXAMPLES / "hard" / fname).Rd) == pytest.approx(deg, abs=1e-9)


# ------------------------------------------------------------------ file-level errors


def test_malformed_toml_names_file_and_line(tmp_path):
    text = 'name = "x"\n[model]\ninertia = [10.0, 11.1\n'
    err = load_error(tmp_path, text)
    assert err.parameter == "scene file"
    assert "malformed TOML" in str(err)
    assert "line 3" in str(err) and "inertia = [10.0, 11.1" in str(err)


def test_malformed_toml_reports_line_and_column(tmp_path):
    text = edit(PAPER_TEXT, 'integrator = "euler"', "integrator = euler")
    lineno = text.splitlines().index(next(t for t in text.splitlines() if t.startswith("integrator"))) + 1
    err = load_error(tmp_path, text)
    assert f"line {lineno}, column" in str(err)


def test_malformed_toml_duplicate_key(tmp_path):
    err = load_error(tmp_path, edit(PAPER_TEXT, "\ndt = 0.01", "\ndt = 0.01\ndt = 0.02"))
    assert "malformed TOML" in str(err) and "line" in str(err)


def test_missing_file(tmp_path):
    with pytest.raises(InputError) as info:
        load_scene(tmp_path / "nope.toml")
    assert info.value.parameter == "scene file" and "nope.toml" in str(info.value)


def test_non_utf8_file(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_bytes(b'name = "\xff"\n')
    with pytest.raises(InputError) as info:
        load_scene(p)
    assert "UTF-8" in str(info.value)


# ------------------------------------------------------------------ key errors


def test_misspelled_key_suggests(tmp_path):
    err = load_error(tmp_path, edit(PAPER_TEXT, "attitude = 1e4", "atitude = 1"))
    assert err.parameter == "[cost].atitude"
    assert "did you mean 'attitude'?" in str(err)
    assert str(err).startswith("[cost].atitude: unknown key")


def test_misspelled_key_even_when_correct_key_present(tmp_path):
    err = load_error(tmp_path, edit(PAPER_TEXT, "[cost]\n", "[cost]\natitude = 1\n"))
    assert err.parameter == "[cost].atitude"


def test_unknown_top_level_key(tmp_path):
    err = load_error(tmp_path, edit(PAPER_TEXT, 'name = "satellite_paper"', 'nmae = "x"'))
    assert err.parameter == "nmae" and "did you mean 'name'?" in str(err)


def test_unknown_section_suggests(tmp_path):
    err = load_error(tmp_path, edit(PAPER_TEXT, "[cost]", "[costs]"))
    assert err.parameter == "[costs]" and "did you mean [cost]?" in str(err)


def test_key_in_wrong_section_points_to_home(tmp_path):
    err = load_error(tmp_path, edit(PAPER_TEXT, "max_iter = 200", "max_iter = 200\ndt = 0.01"))
    assert err.parameter == "[solver].dt" and "[horizon].dt" in str(err)


@pytest.mark.parametrize("section", ["model", "initial", "target", "horizon", "cost"])
def test_missing_section(tmp_path, section):
    d = tomllib.loads(PAPER_TEXT)
    del d[section]
    with pytest.raises(InputError) as info:
        parse_scene(d, source="mine.toml")
    assert info.value.parameter == f"[{section}]"
    assert "missing required section" in str(info.value) and "mine.toml" in str(info.value)


def test_missing_section_from_file(tmp_path):
    text = PAPER_TEXT.split("[horizon]")[0] + "[cost]" + PAPER_TEXT.split("[cost]")[1]
    err = load_error(tmp_path, text)
    assert err.parameter == "[horizon]"


def test_solver_section_optional_with_defaults():
    d = tomllib.loads(PAPER_TEXT)
    del d["solver"]
    for k in ("running_attitude", "running_angular_velocity", "attitude_kind"):
        del d["cost"][k]
    del d["horizon"]["integrator"]
    del d["model"]["actuation"]
    del d["initial"]["angular_velocity"], d["target"]["angular_velocity"]
    del d["name"], d["description"]
    s = parse_scene(d)
    # without [solver] the stopping tolerances are unset (None: the solver's relative default),
    # where the paper's file sets the absolute tol = 1e-8 and grad_tol = 1e-10
    assert (s.tol, s.rtol, s.grad_tol, s.grad_rtol) == (None, None, None, None)
    assert s == load_scene(PAPER).with_overrides(name="scene", description="", source="<dict>", tol=None,
                                                 grad_tol=None)


@pytest.mark.parametrize("section, key", [
    ("model", "inertia"), ("horizon", "tf"), ("horizon", "dt"),
    ("cost", "control"), ("cost", "attitude"), ("cost", "angular_velocity"),
])
def test_missing_required_key(section, key):
    d = tomllib.loads(PAPER_TEXT)
    del d[section][key]
    with pytest.raises(InputError) as info:
        parse_scene(d)
    assert info.value.parameter == f"[{section}].{key}" and "missing required key" in str(info.value)


def test_section_not_a_table():
    d = tomllib.loads(PAPER_TEXT)
    d["horizon"] = 3.0
    with pytest.raises(InputError) as info:
        parse_scene(d)
    assert info.value.parameter == "[horizon]" and "table" in str(info.value)


# ------------------------------------------------------------------ attitude forms


def test_initial_both_quaternion_and_rotation(tmp_path):
    text = edit(PAPER_TEXT, "quaternion = [0.0, 0.0, 0.0, 1.0]",
                "quaternion = [0.0, 0.0, 0.0, 1.0]\nrotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]")
    err = load_error(tmp_path, text)
    assert err.parameter == "[initial]"
    assert "exactly one of quaternion | rotation" in str(err) and "quaternion and rotation" in str(err)


def test_initial_neither():
    d = tomllib.loads(PAPER_TEXT)
    del d["initial"]["quaternion"]
    with pytest.raises(InputError) as info:
        parse_scene(d)
    assert info.value.parameter == "[initial]" and "got none" in str(info.value)


def test_initial_euler_not_allowed():
    d = tomllib.loads(PAPER_TEXT)
    del d["initial"]["quaternion"]
    d["initial"]["euler_intrinsic"] = [["x", 10.0]]
    with pytest.raises(InputError) as info:
        parse_scene(d)
    assert info.value.parameter == "[initial].euler_intrinsic"


def test_target_two_forms():
    d = tomllib.loads(PAPER_TEXT)
    d["target"]["quaternion"] = [0.0, 0.0, 0.0, 1.0]
    with pytest.raises(InputError) as info:
        parse_scene(d)
    assert info.value.parameter == "[target]" and "got quaternion and euler_intrinsic" in str(info.value)


def test_target_rotation_and_quaternion_forms_agree():
    d = tomllib.loads(PAPER_TEXT)
    del d["target"]["euler_intrinsic"]
    d["target"]["quaternion"] = Rotation.from_matrix(RD_PAPER).as_quat().tolist()  # (x, y, z, w)
    a = parse_scene(d)
    del d["target"]["quaternion"]
    d["target"]["rotation"] = RD_PAPER.tolist()
    b = parse_scene(d)
    np.testing.assert_allclose(a.Rd, RD_PAPER, atol=1e-15)
    np.testing.assert_array_equal(b.Rd, RD_PAPER)


@pytest.mark.parametrize("value, param, fragment", [
    ([0.0, 0.0, 0.0, 1.1], "[initial].quaternion", "norm"),
    ([0.0, 0.0, 1.0], "[initial].quaternion", "shape (4,)"),
    ([0.0, 0.0, float("nan"), 1.0], "[initial].quaternion", "finite"),
])
def test_bad_initial_quaternion(value, param, fragment):
    d = tomllib.loads(PAPER_TEXT)
    d["initial"]["quaternion"] = value
    with pytest.raises(InputError) as info:
        parse_scene(d)
    assert info.value.parameter == param and fragment in str(info.value)


def test_bad_target_rotation_reflection():
    d = tomllib.loads(PAPER_TEXT)
    del d["target"]["euler_intrinsic"]
    d["target"]["rotation"] = [[1, 0, 0], [0, 1, 0], [0, 0, -1]]
    with pytest.raises(InputError) as info:
        parse_scene(d)
    assert info.value.parameter == "[target].rotation" and "det" in str(info.value)


@pytest.mark.parametrize("value, param", [
    ([["w", 30.0]], "[target].euler_intrinsic[0] axis"),
    ([["x", 30.0], ["z"]], "[target].euler_intrinsic[1]"),
    ([["x", "thirty"]], "[target].euler_intrinsic[0] angle (degrees)"),
    ([], "[target].euler_intrinsic"),
    ("xz", "[target].euler_intrinsic"),
])
def test_bad_euler(value, param):
    d = tomllib.loads(PAPER_TEXT)
    d["target"]["euler_intrinsic"] = value
    with pytest.raises(InputError) as info:
        parse_scene(d)
    assert info.value.parameter == param


def test_euler_upper_case_axis_accepted():
    d = tomllib.loads(PAPER_TEXT)
    d["target"]["euler_intrinsic"] = [["X", 30.0], ["Z", 70.0]]
    np.testing.assert_allclose(parse_scene(d).Rd, RD_PAPER, atol=1e-15)


def test_euler_y_axis_and_three_angles():
    d = tomllib.loads(PAPER_TEXT)
    d["target"]["euler_intrinsic"] = [["z", 10.0], ["y", -20.0], ["x", 95.0]]
    expect = Rotation.from_euler("ZYX", [10.0, -20.0, 95.0], degrees=True).as_matrix()
    np.testing.assert_allclose(parse_scene(d).Rd, expect, atol=1e-15)


# ------------------------------------------------------------------ value errors carry key paths


@pytest.mark.parametrize("old, new, param, fragment", [
    ("tf = 3.0", "tf = 3.005", "[horizon].tf", "multiple of [horizon].dt"),
    ("\ndt = 0.01", "\ndt = 0.0", "[horizon].dt", "> 0"),
    ("\ndt = 0.01", "\ndt = -0.01", "[horizon].dt", "> 0"),
    ("tf = 3.0", "tf = true", "[horizon].tf", "real number"),
    ('integrator = "euler"', 'integrator = "semi-implicit"', "[horizon].integrator", "did you mean 'semi_implicit'?"),
    ("control = 0.1", "control = [[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]", "[cost].control", "symmetric"),
    ("control = 0.1", "control = [1.0, -1.0, 1.0]", "[cost].control", "positive definite"),
    ("control = 0.1", "control = 0.0", "[cost].control", "positive definite"),
    ("attitude = 1e4", "attitude = [1.0, -1.0, 1.0]", "[cost].attitude", "positive semidefinite"),
    ("attitude = 1e4", "attitude = nan", "[cost].attitude", "finite"),
    ("angular_velocity = 1e4", "angular_velocity = inf", "[cost].angular_velocity", "finite"),
    ('attitude_kind = "chordal"', 'attitude_kind = "geodesics"', "[cost].attitude_kind", "did you mean 'geodesic'?"),
    ("running_attitude = 0.0", "running_attitude = -1.0", "[cost].running_attitude", "semidefinite"),
    ("inertia = [10.0, 11.1, 13.0]", "inertia = [10.0, 1.0, 13.0]", "[model].inertia", "triangle inequality"),
    ("inertia = [10.0, 11.1, 13.0]", "inertia = [-10.0, 11.1, 13.0]", "[model].inertia", "positive definite"),
    ("inertia = [10.0, 11.1, 13.0]", "inertia = 10.0", "[model].inertia", "got shape ()"),
    ("[0.0, 0.0, 1.0]]", "[0.0, 0.0, 0.0]]", "[model].actuation", "non-zero"),
    ('expansion = "switch"', 'expansion = "swich"', "[solver].expansion", "did you mean 'switch'?"),
    ("switch_ratio = 0.1", "switch_ratio = 1.0", "[solver].switch_ratio", "(0, 1)"),
    ("tol = 1e-8", "tol = -1e-8", "[solver].tol", ">= 0"),
    ("grad_tol = 1e-10", "grad_tol = -1.0", "[solver].grad_tol", ">= 0"),
    ("max_iter = 200", "max_iter = 0", "[solver].max_iter", ">= 1"),
    ("max_iter = 200", "max_iter = 200.0", "[solver].max_iter", "integer"),
    ('second_order = "exact"', 'second_order = "papr"', "[solver].second_order", "did you mean 'paper'?"),
    ("angular_velocity = [0.0, 0.0, 0.0]               # rad/s\n\n[target]",
     "angular_velocity = [0.0, 0.0]\n\n[target]", "[initial].angular_velocity", "shape (3,)"),
    ('name = "satellite_paper"', "name = 3", "name", "string"),
])
def test_bad_values_name_key_path_and_file(tmp_path, old, new, param, fragment):
    err = load_error(tmp_path, edit(PAPER_TEXT, old, new))
    assert err.parameter == param, str(err)
    assert str(err).startswith(f"{param}: ")
    assert fragment in str(err), str(err)


def test_control_weight_must_match_number_of_inputs():
    d = tomllib.loads((EXAMPLES / "hard" / "underactuated_2inputs.toml").read_text())
    d["cost"]["control"] = [0.1, 0.1, 0.1]
    with pytest.raises(InputError) as info:
        parse_scene(d)
    assert info.value.parameter == "[cost].control" and "length-2 vector" in str(info.value)


def test_initial_controls():
    d = tomllib.loads(PAPER_TEXT)
    d["horizon"]["tf"] = 0.05  # H = 5
    U = np.arange(15.0).reshape(5, 3)
    d["solver"]["initial_controls"] = U.tolist()
    np.testing.assert_array_equal(parse_scene(d).initial_controls, U)
    d["solver"]["initial_controls"] = U[:4].tolist()
    with pytest.raises(InputError) as info:
        parse_scene(d)
    assert info.value.parameter == "[solver].initial_controls" and "(5, 3)" in str(info.value)


# ------------------------------------------------------------------ urdf


def test_urdf_resolved_relative_to_scene_file(tmp_path):
    (tmp_path / "models").mkdir()
    urdf = tmp_path / "models" / "sat.urdf"
    urdf.write_text("<robot name='sat'><link name='body'/></robot>")  # read and built when the scene is
    sub = tmp_path / "scenes"
    sub.mkdir()
    text = edit(PAPER_TEXT, "[model]\n", '[model]\nurdf = "../models/sat.urdf"\n')
    s = load_scene(write(sub, text))
    assert s.urdf == urdf.resolve() and s.urdf.is_absolute()


def test_urdf_missing_is_an_error(tmp_path):
    err = load_error(tmp_path, edit(PAPER_TEXT, "[model]\n", '[model]\nurdf = "nope.urdf"\n'))
    assert err.parameter == "[model].urdf" and "not found" in str(err)


# ------------------------------------------------------------------ with_overrides


def test_with_overrides_expansion():
    s = load_scene(PAPER)
    t = s.with_overrides(expansion="second")
    assert t.expansion == "second" and s.expansion == "switch"
    assert t.with_overrides(expansion="switch") == s


def test_with_overrides_validates():
    s = load_scene(PAPER)
    with pytest.raises(InputError) as info:
        s.with_overrides(expansion="secnd")
    assert info.value.parameter == "expansion" and "did you mean 'second'?" in str(info.value)
    for kw, param in [
        ({"max_iter": 0}, "max_iter"), ({"tol": -1.0}, "tol"), ({"switch_ratio": 0.0}, "switch_ratio"),
        ({"dt": 0.007}, "tf"), ({"dt": -0.01}, "dt"), ({"Rd": np.diag([1.0, 1.0, -1.0])}, "Rd"),
        ({"S_u": [[1.0, 2.0], [2.0, 1.0]]}, "S_u"), ({"inertia": [1.0, 1.0, 3.0]}, "inertia"),
        ({"Omega0": [np.nan, 0.0, 0.0]}, "Omega0"),
        ({"actuation": [[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]}, "S_u"),  # S_u is 3x3, now m = 2
    ]:
        with pytest.raises(InputError) as info:
            s.with_overrides(**kw)
        assert info.value.parameter == param, (kw, str(info.value))


def test_with_overrides_unknown_field_and_horizon():
    s = load_scene(PAPER)
    with pytest.raises(InputError) as info:
        s.with_overrides(expanson="second")
    assert info.value.parameter == "expanson" and "did you mean 'expansion'?" in str(info.value)
    with pytest.raises(InputError) as info:
        s.with_overrides(horizon=10)
    assert info.value.parameter == "horizon" and "derived" in str(info.value)


def test_with_overrides_recomputes_horizon_and_converts_weights():
    s = load_scene(PAPER)
    t = s.with_overrides(tf=6.0)
    assert t.horizon == 600
    assert s.with_overrides(dt=0.1).horizon == 30
    u = s.with_overrides(S_R=[1.0, 2.0, 3.0], actuation=[[1.0], [0.0], [0.0]], S_u=0.5)
    np.testing.assert_array_equal(u.S_R, np.diag([1.0, 2.0, 3.0]))
    np.testing.assert_array_equal(u.S_u, [[0.5]])
    assert not u.S_R.flags.writeable


def test_with_overrides_initial_controls_follow_horizon():
    s = load_scene(PAPER).with_overrides(initial_controls=np.zeros((300, 3)))
    with pytest.raises(InputError) as info:
        s.with_overrides(tf=6.0)
    assert info.value.parameter == "initial_controls" and "(600, 3)" in str(info.value)


def test_direct_construction_is_validated():
    s = load_scene(PAPER)
    import dataclasses

    kw = {f.name: getattr(s, f.name) for f in dataclasses.fields(s)}
    kw["horizon"] = 301
    with pytest.raises(InputError) as info:
        SceneSpec(**kw)
    assert info.value.parameter == "horizon"


def test_solver_defaults_have_one_home():
    """The scene readers' [solver] defaults are SolverOptions' defaults (geoddp.solver.options)."""
    import dataclasses

    from geoddp import scene
    from geoddp.solver import options

    defaults = {f.name: f.default for f in dataclasses.fields(options.SolverOptions)}
    assert scene.EXPANSIONS is options.EXPANSIONS
    for name in ("expansion", "switch_ratio", "max_iter"):
        assert getattr(scene, f"DEFAULT_{name.upper()}") == defaults[name], name
    # the stopping tolerances default to None (not set) in both; their values live in options only
    assert (scene.DEFAULT_RTOL, scene.DEFAULT_GRAD_RTOL, scene.DEFAULT_GRAD_TOL) == (
        options.DEFAULT_RTOL, options.DEFAULT_GRAD_RTOL, options.DEFAULT_GRAD_TOL)
    mb = {f.name: f.default for f in dataclasses.fields(scene.MultibodySceneSpec)}
    for name in ("expansion", "switch_ratio", "tol", "rtol", "grad_tol", "grad_rtol", "max_iter"):
        assert mb[name] == defaults[name], name
    assert defaults["tol"] is None and defaults["rtol"] is None
