"""geoddp against Crocoddyl on the same multibody problems (issue 6).

Semi-implicit Euler, the same costs and weights, Crocoddyl's running weights divided by dt
(its Euler integrator multiplies the running cost by dt): Crocoddyl's cost of any control
sequence equals geoddp's, and geoddp's solve reaches Crocoddyl FDDP's optimal cost.

Needs crocoddyl (the ``bench`` extra: crocoddyl 3.2.1 with pin 4.0.0; the 3.2.1 wheels are
ABI-broken against pin 4.1.0). Skipped when crocoddyl cannot be imported.
"""
import sys
from pathlib import Path

import numpy as np
import pytest

import os  # noqa: E402

if os.environ.get("GEODDP_REQUIRE_CROCODDYL") == "1":
    import crocoddyl  # CI's bench environment: a missing crocoddyl must fail, not skip
else:
    crocoddyl = pytest.importorskip(
        "crocoddyl", reason="crocoddyl not installed: install the 'bench' extra (crocoddyl 3.2.1 + pin 4.0.0) "
        "to compare geoddp with Crocoddyl on the multibody scenes")

from geoddp.scene import builtin as scenes  # noqa: E402
from geoddp.costs.multibody import ControlRegularisation, MultibodyCostSum  # noqa: E402
from geoddp.solver import SolverOptions, solve  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import multibody_peers as peers  # noqa: E402

# (scene, scale of the random controls: large enough to move the system well away from x0)
SCENES = [("spacecraft_docking", 50.0), ("space_manipulator", 1.0)]


@pytest.fixture(scope="module")
def problems():
    # the scenes' default horizons and time steps (H = 200, dt = 0.05; H = 150, dt = 0.02):
    # both solvers take a few seconds at most on 2 cores
    return {name: getattr(scenes, name)(integrator="semi_implicit") for name, _ in SCENES}


@pytest.mark.parametrize("name,scale", SCENES)
def test_crocoddyl_cost_equals_geoddp_cost_on_random_controls(problems, name, scale):
    """Checks dynamics (ABA + actuation), the semi-implicit integrator, every cost term and the
    running-cost dt scaling at once."""
    p = problems[name]
    U = scale * np.random.default_rng(7).normal(size=(p.horizon, p.nu))
    chk = peers.check_cost_equivalence(p, U)
    Q, V = p.rollout(U)
    assert np.abs(V).max() > 0.1  # the controls really move the system
    assert chk["state_err"] < 1e-12, chk
    assert chk["rel"] < 1e-12, chk


@pytest.mark.parametrize("name", [n for n, _ in SCENES])
def test_geoddp_reaches_crocoddyl_fddp_optimum(problems, name):
    p = problems[name]
    ref = peers.solve_crocoddyl(p, "fddp", th_stop=1e-9)
    assert ref["status"] == "converged", ref["status"]
    assert abs(ref["cost"] - ref["cost_solver"]) <= 1e-12 * ref["cost"]  # Crocoddyl's J is geoddp's J
    res = solve(p, SolverOptions(expansion="switch", verbose=False))
    assert res.converged, res.message
    rel = abs(res.cost - ref["cost"]) / abs(ref["cost"])
    assert rel < 1e-7, (res.cost, ref["cost"], rel)


def test_unsupported_problems_fail_clearly(problems):
    p = problems["space_manipulator"]
    euler = scenes.space_manipulator(integrator="euler", horizon=3)
    with pytest.raises(NotImplementedError, match="semi-implicit"):
        peers.crocoddyl_problem(euler)
    W = np.full((p.nu, p.nu), 1e-3) + np.eye(p.nu)
    p2 = scenes.space_manipulator(horizon=3)
    p2.running = MultibodyCostSum([ControlRegularisation(np.zeros(p.nu), W=W)], model=p.model.pin_model)
    with pytest.raises(NotImplementedError, match="diagonal"):
        peers.crocoddyl_problem(p2)
