"""Issue 16's surface: ``geoddp simulate`` and the Monte Carlo figures."""
from __future__ import annotations

import json

import numpy as np
import pytest

from geoddp.cli import main
from geoddp.simulate import SimulationSpec, simulate_scene


def _run(capsys, argv):
    code = main(argv)
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_simulate_prints_the_table_and_writes_json_and_figures(tmp_path, capsys):
    out_json, plots = tmp_path / "sim.json", tmp_path / "plots"
    code, out, err = _run(capsys, ["simulate", "satellite_authors_code", "--samples", "12", "--seed", "3", "--noise",
                                   "0.001", "--json", str(out_json), "--plots", str(plots)])
    assert code == 0 and err == ""
    assert "J* = 6.0451953285" in out and "| attitude_rad (rad) | mean |" in out
    d = json.loads(out_json.read_text())
    api = simulate_scene("satellite_authors_code", SimulationSpec(samples=12, seed=3, noise=0.001)).statistics()
    # the CLI's numbers are the API's (same seed, same table)
    for k in ("open.attitude_rad.mean", "feedback.attitude_rad.max", "feedback.effort.p95"):
        assert d["statistics"][k] == api[k]
    assert len(d["measures"]["feedback"]["attitude_rad"]) == 12 and d["simulation"]["noise"] == 0.001
    mean = float(out.split("| attitude_rad (rad) | mean | ")[1].split(" |")[0])
    assert mean == pytest.approx(api["open.attitude_rad.mean"], rel=1e-3)
    for name in ("bundles.png", "errors.png"):
        assert (plots / name).stat().st_size > 10_000


def test_simulate_plant_and_policy_options(capsys):
    code, out, err = _run(capsys, ["simulate", "satellite_authors_code", "--samples", "1", "--noise", "0", "--plant",
                                   "inertia_scale=1.2", "--plant",
                                   "substeps=2", "--policy", "mpc", "--mpc-horizon", "50", "--mpc-every", "5",
                                   "--mpc-max-iter", "2"])
    assert code == 0, err
    assert "'inertia_scale': 1.2" in out and "'substeps': 2" in out and "| open | mpc |" in out
    assert "re-solve median" in out and "real-time factor" in out
    # one sample: a value row per measure; MPC (H_mpc = 50 < H) lands closer than open loop
    row = out.split("| attitude_rad (rad) | value | ")[1].split(" |\n")[0]
    ol, mpc = (float(x) for x in row.split(" | "))
    assert mpc < 0.25 * ol


@pytest.mark.parametrize("argv, param", [
    (["--samples", "0"], "--samples"),
    (["--plant", "inertia=2"], "--plant inertia"),
    (["--plant", "inertia_scale"], "--plant"),
    (["--plant", "inertia_scale=big"], "--plant inertia_scale"),
    (["--plant", "substeps=1.5"], "--plant substeps"),
    (["--plant", "inertia_scale=-1"], "--plant inertia_scale"),
    (["--noise", "-1"], "--noise"),
    (["--steps", "301"], "steps"),
    (["--mpc-every", "0", "--policy", "mpc"], "--mpc-every"),
    (["--mpc-every", "200", "--mpc-horizon", "100", "--policy", "mpc"], "mpc.every"),
])
def test_simulate_bad_input_exits_2_with_one_line(capsys, argv, param):
    code, out, err = _run(capsys, ["simulate", "satellite_paper", *argv])
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"geoddp: error: {param}:"), err


def test_figures_plot_what_the_runs_hold(tmp_path):
    from geoddp.viz import plot_simulation

    mc = simulate_scene("satellite_authors_code", SimulationSpec(samples=5, seed=1, noise=0.001))
    figs = plot_simulation(mc, tmp_path)
    b = figs.data["bundles"].arrays
    for p in ("open", "feedback"):
        np.testing.assert_allclose(b[p][:, -1], mc.measures(p)["attitude_rad"], rtol=1e-12)
        np.testing.assert_allclose(figs.data["errors"].arrays[p], mc.measures(p)["attitude_rad"], rtol=1e-12)
    assert b["plan"][0] == pytest.approx(np.radians(75.0), abs=0.3)  # starts ~1.3 rad from R_d
    # Result.attitude_error_deg takes arccos of the trace (~1e-8 relative at 5e-4 rad); ours the log
    assert b["plan"][-1] == pytest.approx(mc.plan.attitude_error_deg * np.pi / 180, rel=1e-7)


def _plan_and_run_clips(text):
    from geoddp.viz.html import decode_commands

    anims = [c for c in decode_commands(text) if c["type"] == "set_animation"][-1]["animations"]
    out = {}
    for a in anims:
        group, name = a["path"].split("/")[2], a["path"].split("/")[3]
        out[(group, name)] = a["clip"]
    return out


@pytest.mark.parametrize("scene, plant", [("satellite_authors_code", "inertia_scale=1.2"),
                                          ("quadrotor", "mass_scale=1.2")])
def test_html_replays_the_run_beside_an_animated_ghost_of_the_plan(tmp_path, capsys, scene, plant):
    from geoddp.viz.model import check_replayable, placements_at
    from viz_fixtures import keyframes

    out = tmp_path / "run.html"
    code, text, err = _run(capsys, ["simulate", scene, "--samples", "1", "--noise", "0", "--plant", plant, "--html",
                                    str(out)])
    assert code == 0, err
    mc = simulate_scene(scene, SimulationSpec(plant={plant.split("=")[0]: float(plant.split("=")[1])}))
    run, plan = mc.runs["feedback"][0], mc.plan
    clips = _plan_and_run_clips(out.read_text())
    visual, Qplan = check_replayable(plan)
    _, Qrun = check_replayable(run.to_result(plan))
    Pp, Pr = placements_at(visual, Qplan), placements_at(visual, Qrun)
    names = [n for (g, n) in clips if g == "plan_ghost"]
    assert names and sorted(names) == sorted(n for (g, n) in clips if g == "robot")
    i = list(visual.names).index(names[0])
    np.testing.assert_allclose(keyframes(clips[("plan_ghost", names[0])]), Pp[:, i], atol=1e-6)
    np.testing.assert_allclose(keyframes(clips[("robot", names[0])]), Pr[:, i], atol=1e-6)
    # the run left the plan (model error): the two animations differ at the end
    assert np.abs(Pp[-1, i] - Pr[-1, i]).max() > 1e-4


SCENE_WITH_TABLE = """
name = "with_simulation"
[model]
inertia = [10.0, 11.1, 13.0]
[initial]
quaternion = [0.0, 0.0, 0.0, 1.0]
[target]
euler_intrinsic = [["x", 30.0], ["z", 70.0]]
[horizon]
tf = 1.0
dt = 0.01
[cost]
control = 0.001
attitude = 1e4
angular_velocity = 1e4
[simulation]
samples = 6
seed = 4
noise = 0.002
policy = "mpc"
mpc_horizon = 40
mpc_every = 2
[simulation.plant]
inertia_scale = 1.1
"""


def test_the_simulation_table_of_a_scene_file(tmp_path, capsys):
    from geoddp.scene import load_scene
    from geoddp.scene.simulation import SimulationSpec as Spec

    path = tmp_path / "s.toml"
    path.write_text(SCENE_WITH_TABLE)
    spec = load_scene(path)
    assert spec.simulation == Spec(samples=6, seed=4, noise=0.002, policy="mpc", mpc_horizon=40, mpc_every=2,
                                   plant={"inertia_scale": 1.1})
    mc = simulate_scene(spec)  # the table is the default
    assert mc.policies == ("open", "mpc") and mc.samples == 6 and mc.plant == {"inertia_scale": 1.1}
    assert mc.runs["mpc"][0].stats["every"] == 2 and mc.runs["mpc"][0].stats["horizon"] == 40
    same = simulate_scene(spec, Spec(samples=6, seed=4, noise=0.002, policy="mpc", mpc_horizon=40, mpc_every=2,
                                     plant={"inertia_scale": 1.1}))
    assert mc.statistics()["mpc.attitude_rad.mean"] == same.statistics()["mpc.attitude_rad.mean"]
    # the command line starts from the table and overrides what it is given
    code, out, err = _run(capsys, ["simulate", str(path), "--samples", "2", "--policy", "feedback"])
    assert code == 0, err
    assert "simulated 2 sample(s) x open, feedback, seed 4, noise 0.002" in out and "'inertia_scale': 1.1" in out
    # the built-in authors' scene carries the authors' test
    assert load_scene("satellite_authors_code").simulation == Spec(samples=90, seed=0, noise=0.001)


@pytest.mark.parametrize("line, param", [
    ("sample = 3", "[simulation].sample"),
    ("samples = 0", "[simulation].samples"),
    ("policy = \"closed\"", "[simulation].policy"),
    ("noise = -1.0", "[simulation].noise"),
    ("plant = { inertia = 2.0 }", "[simulation].plant.inertia"),
    ("plant = { substeps = 0 }", "[simulation].plant.substeps"),
])
def test_a_bad_simulation_table_names_its_key(tmp_path, capsys, line, param):
    path = tmp_path / "bad.toml"
    head = SCENE_WITH_TABLE.split("[simulation]")[0]
    path.write_text(head + "[simulation]\n" + line + "\n")
    code, out, err = _run(capsys, ["simulate", str(path)])
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and f"{param}:" in lines[0] and str(path) in lines[0], err


def test_simulate_without_noise_says_the_samples_are_identical(capsys):
    # The issue's `geoddp simulate satellite_paper --samples 90`: without any noise the samples are
    # one run repeated (std 0); the command says so instead of presenting it as a distribution.
    code, out, err = _run(capsys, ["simulate", "satellite_paper", "--samples", "4"])
    assert code == 0 and err == ""
    assert "note: no noise" in out and "4 samples are identical" in out
    assert float(out.split("| attitude_rad (rad) | std | ")[1].split(" |")[0]) < 1e-15
    code, out, err = _run(capsys, ["simulate", "satellite_paper", "--samples", "4", "--noise", "0.001"])
    assert code == 0 and "note: no noise" not in out
    assert float(out.split("| attitude_rad (rad) | std | ")[1].split(" |")[0]) > 1e-4
