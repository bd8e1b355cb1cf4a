"""Package data (issue 11, item 8): the built-in URDFs and scenes live inside the package.

Checks that every built-in scene is reachable by name and loads, that names are unique, that a
scene's bare URDF name resolves to the built-in model from any folder while relative and absolute
paths keep working, that the build declares every data file (so a plain ``pip install .`` ships
them), and that nothing in ``src/`` finds data through ``parents[...]`` any more.
"""
from __future__ import annotations

import re
import shutil
import tomllib
from pathlib import Path, PurePosixPath

import pytest

from geoddp import data
from geoddp.scene import LeggedSceneSpec, MultibodySceneSpec
from geoddp.scene import SceneSpec, load_scene
from geoddp.validate import InputError

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "geoddp"
SATELLITE = ("satellite_authors_code", "satellite_keep_out", "satellite_paper", "satellite_semi_implicit",
             "satellite_wheel_limits")
MULTIBODY = ("quadrotor", "quadrotor_thrust_limits", "space_manipulator", "spacecraft_docking")
HARD = tuple(sorted(p.stem for p in (PACKAGE / "data" / "scenes" / "hard").glob("*.toml")))
ROBOTS = ("hector_fly", "solo12_reorient", "ur5_constraints", "ur5_reach")  # example-robot-data's robots by name
LEGGED = ("anymal_jump", "anymal_trot", "anymal_walk", "talos_walk")  # legged scenes: Crocoddyl's ANYmal gaits, its biped walk

QUAD_SCENE = (data.scene_dir() / "multibody" / "quadrotor.toml").read_text()


def test_the_builtin_data_is_the_package_folder():
    assert data.urdf_dir() == PACKAGE / "data" / "urdf" and data.scene_dir() == PACKAGE / "data" / "scenes"
    assert data.urdf_names() == ("quadrotor.urdf", "satellite.urdf", "space_manipulator.urdf", "spacecraft.urdf")
    assert len(HARD) == 13
    assert data.scene_names() == tuple(sorted(SATELLITE + MULTIBODY + HARD + ROBOTS + LEGGED))
    # The repository's examples/ holds the gallery's scripts beside links to the package's scenes,
    # not copies: each top-level scene file and each scene folder is the package's own.
    examples = ROOT / "examples"
    top = sorted(p.name for p in data.scene_dir().glob("*.toml"))
    assert top == sorted(p.name for p in examples.glob("*.toml")) and len(top) == len(SATELLITE)
    for name in top:
        assert (examples / name).samefile(data.scene_dir() / name)
    folders = sorted(p.name for p in data.scene_dir().iterdir() if p.is_dir())
    assert folders == ["hard", "legged", "multibody", "robots", "sweeps"]
    for folder in folders:
        assert (examples / folder).samefile(data.scene_dir() / folder)


@pytest.mark.parametrize("name", SATELLITE + MULTIBODY + HARD + ROBOTS + LEGGED)
def test_every_builtin_scene_loads_by_name_as_from_its_file(name):
    path = data.scene_path(name)
    by_name, by_file = load_scene(name), load_scene(path)
    assert by_name.name == name and by_name.source == by_file.source == str(path)
    kind = MultibodySceneSpec if name in MULTIBODY + ROBOTS else LeggedSceneSpec if name in LEGGED else SceneSpec
    assert isinstance(by_name, kind)
    if name in LEGGED:
        robot = {"anymal": "anymal", "talos": "talos_legs"}[name.split("_")[0]]
        assert by_name.robot == robot and by_name.gait["type"] == name.split("_")[1]
    if name in ROBOTS:
        assert by_name.robot == name.split("_")[0] and by_name.urdf == by_file.urdf
    if name in MULTIBODY:
        assert by_name.urdf.parent == data.urdf_dir() and by_name.urdf == by_file.urdf


def test_unknown_scene_name_names_the_parameter_and_suggests():
    with pytest.raises(InputError) as info:
        data.scene_path("quadrotr")
    assert info.value.parameter == "scene"
    assert "did you mean 'quadrotor'?" in info.value.detail and "satellite_paper" in info.value.detail
    with pytest.raises(InputError) as info:
        load_scene("sattelite_paper")
    assert info.value.parameter == "scene" and "did you mean 'satellite_paper'?" in info.value.detail
    # Something that looks like a path stays a file error, as before.
    with pytest.raises(InputError) as info:
        load_scene("nope/quadrotor.toml")
    assert info.value.parameter == "scene file"
    with pytest.raises(FileNotFoundError, match="built-in URDFs: quadrotor.urdf"):
        data.urdf_path("nope.urdf")
    with pytest.raises(FileNotFoundError, match="did you mean 'satellite.urdf'"):
        data.urdf_path("satelite.urdf")
    assert data.urdf_path("satellite") == data.urdf_path("satellite.urdf") == data.urdf_dir() / "satellite.urdf"


def test_a_bare_urdf_name_is_the_builtin_model_from_any_folder(tmp_path):
    p = tmp_path / "quad.toml"
    p.write_text(QUAD_SCENE)
    assert load_scene(p).urdf == data.urdf_dir() / "quadrotor.urdf"


def test_a_urdf_next_to_the_scene_wins_over_the_builtin_one(tmp_path):
    mine = tmp_path / "quadrotor.urdf"
    shutil.copy(data.urdf_path("quadrotor.urdf"), mine)
    p = tmp_path / "quad.toml"
    p.write_text(QUAD_SCENE)
    assert load_scene(p).urdf == mine.resolve()


@pytest.mark.parametrize("form", ["relative", "absolute"])
def test_relative_and_absolute_urdf_paths_still_work(tmp_path, form):
    (tmp_path / "models").mkdir()
    (tmp_path / "scenes").mkdir()
    mine = tmp_path / "models" / "q.urdf"
    shutil.copy(data.urdf_path("quadrotor.urdf"), mine)
    value = "../models/q.urdf" if form == "relative" else mine.as_posix()
    p = tmp_path / "scenes" / "quad.toml"
    p.write_text(QUAD_SCENE.replace('urdf = "quadrotor.urdf"', f'urdf = "{value}"'))
    assert load_scene(p).urdf == mine.resolve()


@pytest.mark.parametrize("value,hint", [("quadrotr.urdf", "did you mean 'quadrotor.urdf'?"),
                                        ("../models/quadrotor.urdf", None)])
def test_a_missing_urdf_keeps_its_key_path(tmp_path, value, hint):
    p = tmp_path / "quad.toml"
    p.write_text(QUAD_SCENE.replace('urdf = "quadrotor.urdf"', f'urdf = "{value}"'))
    with pytest.raises(InputError) as info:
        load_scene(p)
    assert info.value.parameter == "[model].urdf" and "not found" in info.value.detail
    assert (hint in info.value.detail) if hint else ("built-in URDFs" not in info.value.detail)


def _data_files() -> list[PurePosixPath]:
    return sorted(PurePosixPath(p.relative_to(PACKAGE).as_posix()) for p in (PACKAGE / "data").rglob("*")
                  if p.is_file() and p.suffix in (".urdf", ".toml"))


def test_the_build_ships_every_data_file():
    """What a plain (non-editable) ``pip install .`` copies: every URDF and scene under data/."""
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    backend = cfg["build-system"]["build-backend"]
    files = _data_files()
    assert len(files) == 4 + 22 + 4 + 3 + 4  # 4 URDFs; 22 scenes (2 with control limits, 1 with constraints); 4 robots (1 with constraints); 3 sweeps; 4 legged
    if backend.startswith("setuptools"):
        globs = cfg["tool"]["setuptools"]["package-data"]["geoddp"]
        missing = [f for f in files if not any(f.match(g) and len(f.parts) == len(PurePosixPath(g).parts)
                                               for g in globs)]
        assert not missing, f"add these to [tool.setuptools.package-data]: {missing}"
    else:  # scikit-build-core: the whole package directory is copied unless excluded
        assert backend.startswith("scikit_build_core"), backend
        skb = cfg["tool"]["scikit-build"]
        packages = skb.get("wheel", {}).get("packages", skb.get("wheel.packages", ["src/geoddp"]))
        assert "src/geoddp" in packages
        excluded = skb.get("wheel", {}).get("exclude", skb.get("wheel.exclude", []))
        assert not [f for f in files for g in excluded if f.match(g)], excluded


def test_nothing_in_src_finds_data_through_parents():
    hits = [f"{p.relative_to(ROOT)}:{i}" for p in PACKAGE.rglob("*.py")
            for i, line in enumerate(p.read_text().splitlines(), 1) if re.search(r"parents\[\d+\]", line)]
    assert not hits, hits


def test_the_api_solves_a_builtin_scene_by_name():
    import geoddp as api

    assert api.load_scene("satellite_semi_implicit") == load_scene(data.scene_path("satellite_semi_implicit"))
    r = api.solve_scene("satellite_semi_implicit", verbose=False)
    assert r.converged and r.iterations == 3 and abs(r.cost - 494.7163633884) < 1e-9


def test_the_sweep_files_are_examples_but_not_scenes():
    from geoddp import data
    from geoddp.sweep.spec import sweep_names

    assert (ROOT / "examples" / "sweeps").samefile(data.sweep_dir())  # examples/sweeps is the package's folder
    assert set(sweep_names()) == {"satellite_slew", "satellite_noise_mc", "ur5_reach_grid"}
    assert not set(sweep_names()) & set(data.scene_names())  # a sweep file is not a scene


def test_readme_test_command_is_exactly_what_ci_runs():
    """The README's second set-up command, the one on the documentation's getting-started page and
    the last line of .ci/run are one command (they had drifted apart: the README left out the
    Crocoddyl limits cross-check). It builds the documentation, whose gallery runs the examples,
    and runs every Crocoddyl cross-check file in the pin 4.0.0 environment."""
    root = Path(__file__).resolve().parents[1]
    ci = (root / ".ci" / "run").read_text().strip().splitlines()[-1]
    assert ci == "bash .ci/test-all.sh"
    for page in ("README.md", "docs/getting_started.md"):
        lines = (root / page).read_text().splitlines()
        assert [line for line in lines if line.startswith("bash .ci/test-all.sh")] == [ci], page
    script = (root / ".ci" / "test-all.sh").read_text()
    code = "\n".join(line for line in script.splitlines() if not line.lstrip().startswith("#"))
    assert '.venv/bin/pip install -q -e ".[test,docs]"' in code and ".venv/bin/python -m pytest -q -n 2" in code
    assert "sphinx-build -W " in code and '"pin==4.0.0" "crocoddyl==3.2.1"' in code
    crocoddyl_files = sorted(p.name for p in (root / "tests").glob("test_*crocoddyl*.py"))
    assert crocoddyl_files and all(f"tests/{name}" in code for name in crocoddyl_files), crocoddyl_files