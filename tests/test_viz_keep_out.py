"""The keep-out figure: a valid PNG with the boresight path and the cone drawn, and the arrays it
drew equal to the result's (R_k a on the satellite; the frame's rotation by Pinocchio on a
multibody)."""
from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from PIL import Image

from geoddp import solve_scene
from geoddp.constraints import ConstrainedProblem, PointingKeepOut, solve_constrained
from geoddp.scene.builtin import space_manipulator
from geoddp.problem import paper_problem
from geoddp.solver import SolverOptions, solve
from geoddp.validate import InputError
from geoddp.viz import plot_keep_out
from geoddp.viz.keep_out import CONE_COLOR, FREE_COLOR, PATH_COLOR
from viz_fixtures import synthetic_result

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _pixels_of(path, hex_color: str, tol: int = 12) -> int:
    """How many pixels of the PNG are within ``tol`` of the colour (per channel)."""
    rgb = np.array([int(hex_color[i:i + 2], 16) for i in (1, 3, 5)])
    with Image.open(path) as img:
        a = np.asarray(img.convert("RGB"), dtype=int)
    return int(np.sum(np.all(np.abs(a - rgb) <= tol, axis=-1)))


@pytest.fixture(scope="module")
def solved():
    return solve_scene("satellite_keep_out", verbose=False, expansion="second"), \
        solve(paper_problem(), SolverOptions(verbose=False))


def test_the_keep_out_figure_reads_back_as_a_png_with_the_path_drawn(solved, tmp_path):
    r, free = solved
    fd = plot_keep_out(r, tmp_path / "figs" / "keep_out.png", unconstrained=free)
    data = fd.path.read_bytes()
    assert data[:8] == PNG_MAGIC
    with Image.open(fd.path) as img:
        img.verify()
    with Image.open(fd.path) as img:
        assert img.width >= 1000 and img.height >= 500
    # the constrained path, the unconstrained one and the cone are all drawn in their colours
    assert _pixels_of(fd.path, PATH_COLOR) > 500
    assert _pixels_of(fd.path, FREE_COLOR) > 300
    assert _pixels_of(fd.path, CONE_COLOR) > 300
    # the arrays drawn are the result's: R_k e_x, its angle to d, the cone at 20 degrees
    d = np.array([0.849, 0.482, 0.215]) / np.linalg.norm([0.849, 0.482, 0.215])
    np.testing.assert_allclose(fd.arrays["boresight"], r.rotations[:, :, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(fd.arrays["direction"], d, rtol=0, atol=1e-15)
    assert fd.arrays["angle_deg"][1:].min() >= 20.0 - 1e-6 and fd.arrays["free_angle_deg"].min() < 0.02
    np.testing.assert_allclose(np.degrees(np.arccos(fd.arrays["cone_rim"] @ d)), 20.0, atol=1e-9)
    # written atomically: nothing but the figure in its folder
    assert sorted(p.name for p in fd.path.parent.iterdir()) == ["keep_out.png"]


def test_a_multibody_frame_boresight_is_the_frame_rotation(tmp_path):
    p = space_manipulator(horizon=10, dt=0.1)
    cp = ConstrainedProblem(p, [PointingKeepOut([1.0, 0.0, 0.0], [0.0, 0.0, 1.0], 30.0, frame="ee")])
    r = solve_constrained(cp, SolverOptions(verbose=False, max_iter=3))
    fd = plot_keep_out(r, tmp_path / "arm.png")
    pm = p.model.pin_model
    data = pm.createData()
    for k in (0, 5, 10):
        pin.framesForwardKinematics(pm, data, r.q[k])
        np.testing.assert_allclose(fd.arrays["boresight"][k], data.oMf[pm.getFrameId("ee")].rotation[:, 0],
                                   rtol=0, atol=1e-12)


def test_refusals(solved, tmp_path):
    r, _ = solved
    with pytest.raises(InputError) as info:
        plot_keep_out(synthetic_result(horizon=5), tmp_path / "x.png")
    assert info.value.parameter == "result" and "constrained solve" in info.value.detail
    with pytest.raises(InputError) as info:
        plot_keep_out(r, tmp_path / "x.png", name="moon")
    assert info.value.parameter == "name" and "sun_keep_out" in info.value.detail
    (tmp_path / "folder.png").mkdir()
    with pytest.raises(InputError) as info:
        plot_keep_out(r, tmp_path / "folder.png")
    assert info.value.parameter == "path"
