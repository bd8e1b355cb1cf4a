"""Matplotlib figures: valid PNG files whose plotted data is the Result's."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from PIL import Image

from geoddp.solver.result import rotations_to_quaternions
from geoddp.viz import plot_convergence, plot_trajectory
from viz_fixtures import synthetic_result

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def assert_png(path):
    assert path.exists(), path
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC, f"{path} is not a PNG"
    with Image.open(path) as img:
        img.verify()  # raises on a truncated or corrupt file
    with Image.open(path) as img:
        assert img.width > 300 and img.height > 200
        # Not a blank canvas: a plot has many distinct colours.
        assert len(img.convert("RGB").getcolors(maxcolors=1 << 20)) > 20


def test_trajectory_files_and_data(tmp_path):
    result = synthetic_result(horizon=30, dt=0.1)
    figs = plot_trajectory(result, tmp_path / "plots")
    assert set(figs) == {"quaternion", "angular_velocity", "controls"}
    for name, path in figs.items():
        assert path.name == f"{name}.png" and path.parent == tmp_path / "plots"
        assert_png(path)

    q = figs.data["quaternion"].arrays
    np.testing.assert_allclose(q["quaternions"][-1], result.quaternions[-1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(q["quaternions"], result.quaternions, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(q["t"], result.times)
    assert float(q["target_time"]) == result.times[-1]
    qd = rotations_to_quaternions(result.target_rotation[None])[0]
    # Same attitude as R_d, with the sign that matches q_H (here the target is reached).
    assert min(np.abs(q["target_quaternion"] - qd).max(), np.abs(q["target_quaternion"] + qd).max()) < 1e-12
    assert np.dot(q["target_quaternion"], result.quaternions[-1]) > 0

    w = figs.data["angular_velocity"].arrays
    np.testing.assert_array_equal(w["angular_velocities"], result.angular_velocities)
    np.testing.assert_array_equal(w["target_angular_velocity"], result.target_angular_velocity)

    u = figs.data["controls"].arrays
    np.testing.assert_array_equal(u["controls"], result.controls)
    assert u["edges"].shape == (result.horizon + 1,)


def test_target_sign_follows_final_quaternion(tmp_path):
    # A rotation by more than pi ends with q_H on the w < 0 side of the sign-continuous path.
    result = synthetic_result(horizon=20, total_angle=5.0)
    assert result.quaternions[-1][3] < 0
    q = plot_trajectory(result, tmp_path).data["quaternion"].arrays
    np.testing.assert_allclose(q["target_quaternion"], result.quaternions[-1], atol=1e-9)


def test_convergence_files_and_data(tmp_path):
    runs = {"second order": synthetic_result(iterations=6, seed=0), "first order": synthetic_result(iterations=3, seed=1)}
    figs = plot_convergence(runs, tmp_path, reference_cost=1.5, reference_label="crocoddyl")
    assert set(figs) == {"convergence", "cost_history"}
    for path in figs.values():
        assert_png(path)

    conv = figs.data["convergence"].arrays
    for label, res in runs.items():
        expected = np.array([np.linalg.norm(Ui - res.controls) for Ui in res.control_history])
        np.testing.assert_allclose(conv[f"{label}/error"], expected, rtol=1e-12, atol=1e-15)
        assert expected[-1] == 0.0 and expected[0] > 1.0
        # The plotted pairs are (e_i, e_{i+1}) for the non-zero ones: the last error is 0.
        np.testing.assert_allclose(conv[f"{label}/error_now"], expected[:-2])
        np.testing.assert_allclose(conv[f"{label}/error_next"], expected[1:-1])
        # The fixture converges linearly with ratio 0.3; the plot data must show it.
        np.testing.assert_allclose(conv[f"{label}/error_next"] / conv[f"{label}/error_now"], 0.3, rtol=1e-9)

    cost = figs.data["cost_history"].arrays
    j_min = min(r.cost_history.min() for r in runs.values())
    assert float(cost["j_min"]) == j_min
    assert float(cost["reference_cost"]) == 1.5
    for label, res in runs.items():
        np.testing.assert_array_equal(cost[f"{label}/cost"], res.cost_history)
        np.testing.assert_allclose(cost[f"{label}/cost_minus_min"], res.cost_history - j_min)


def test_convergence_skips_runs_without_history(tmp_path):
    with_history = synthetic_result(iterations=4)
    without = dataclasses.replace(synthetic_result(iterations=2), control_history=None)
    figs = plot_convergence({"a": with_history, "b": without}, tmp_path)
    keys = set(figs.data["convergence"].arrays)
    assert any(k.startswith("a/") for k in keys) and not any(k.startswith("b/") for k in keys)
    assert "b/cost" in figs.data["cost_history"].arrays  # the cost history needs no controls
    assert "reference_cost" not in figs.data["cost_history"].arrays
    for path in figs.values():
        assert_png(path)


def test_convergence_needs_results(tmp_path):
    with pytest.raises(ValueError):
        plot_convergence({}, tmp_path)
