"""Hard constraints on a legged problem's contact forces (geoddp.constraints.FrictionCone): the
augmented Lagrangian terms' first and exact second derivatives in z = (dq, dv, du) against
differences, the ANYmal trot kept inside a cone tighter than its unconstrained plan uses (a KKT
point, every stance force inside to 1e-8 N), the scene table and its errors.

Requires example-robot-data (the ``test`` extra).
"""
from __future__ import annotations

import example_robot_data  # noqa: F401  (required)
import numpy as np
import pinocchio as pin
import pytest

from geoddp.constraints import STATUS_KKT, ConstrainedProblem, FrictionCone, solve_constrained
from geoddp.scene import load_scene
from geoddp.scene.legged import anymal_trot
from geoddp.solver import SolverOptions, solve
from geoddp.validate import InputError
from geoddp.viz import legged_forces
from oracle_legged import fd_second_order_node

MU = 0.5
F_MIN = 5.0  # N


@pytest.fixture(scope="module")
def trot():
    return anymal_trot()


@pytest.fixture(scope="module")
def inner(trot):
    """The trot's inner problem at multipliers that make some rows active and others not, along
    the quasi-static rollout."""
    cp = ConstrainedProblem(trot, [FrictionCone(mu=MU, min_normal_force=F_MIN)])
    traj = trot.trajectory(trot.quasi_static_controls())
    c = cp.values(traj)[0]
    rng = np.random.default_rng(3)
    # the forces sit well inside the cone there (c <= -30 N): multipliers that make half the rows
    # active (lambda + mu c in [1, 5]) and leave the others inactive (lambda = 0)
    lam = np.where(rng.random(c.shape) < 0.5, -0.3 * c + rng.uniform(1.0, 5.0, c.shape), 0.0)
    aug = cp.augmented([lam], [0.3])
    return cp, aug.problem, traj, c, lam


def _value(problem, k, traj, z):
    m, nv = problem.model, problem.model.nv
    q = pin.integrate(m, traj.q[k], z[:nv])
    return problem.node(k, q, traj.v[k] + z[nv:2 * nv], traj.u[k] + z[2 * nv:])[1]


def test_force_terms_match_differences(trot, inner):
    """Gradient against central differences of the node cost, and the exact Hessian (Gauss-Newton
    part plus the forces' curvature sum lhat G L2) against differences of the gradient, at contact
    nodes with 2 and 4 feet on the ground where the constraint's terms are nonzero."""
    cp, problem, traj, c, lam = inner
    placed = cp.placed[0]
    nz = problem.nx + problem.nu
    checked = 0
    for k in sorted(set(placed.nodes.tolist()))[::9]:
        assert k in problem._force_at and k not in trot._force_at  # the original problem has none
        ev, val, g, _ = problem.node(k, traj.q[k], traj.v[k], traj.u[k], derivatives=True)
        base = trot.node(k, traj.q[k], traj.v[k], traj.u[k])[1]
        if val == base:
            continue
        h = 1e-6
        fd = np.array([(_value(problem, k, traj, h * e) - _value(problem, k, traj, -h * e)) / (2 * h)
                       for e in np.eye(nz)])
        assert np.max(np.abs(fd - g)) <= 1e-6 * max(1.0, np.max(np.abs(g)))
        _, H = problem.second_order_node(k, traj)
        _, H_fd = fd_second_order_node(problem, k, traj)
        assert np.max(np.abs(H - H_fd)) <= 1e-5 * np.max(np.abs(H))
        # the forces' curvature is in it: without it the Hessian misses the differences by more
        curv = problem._force_terms(k, ev, True, trot.dyn.contact_second(traj.q[k], traj.v[k], traj.u[k],
                                                                         trot.nodes[k].feet, ev)[1])[2]
        assert np.max(np.abs(curv)) > 100 * np.max(np.abs(H - H_fd))
        checked += 1
    assert checked >= 3


@pytest.fixture(scope="module")
def solved(trot):
    free = solve(trot, SolverOptions(expansion="first"))
    cp = ConstrainedProblem(trot, [FrictionCone(mu=MU, min_normal_force=F_MIN)])
    return free, solve_constrained(cp, SolverOptions(expansion="first")), cp


def test_the_trot_in_a_tighter_cone_is_a_kkt_point(trot, solved):
    free, r, cp = solved
    f_free, f = legged_forces(free, trot, mu=MU), legged_forces(r, trot, mu=MU)
    stance = f.active & ~f.impulse[:, None]
    # the unconstrained plan leaves the mu = 0.5 cone by more than a newton
    assert np.min(f_free.facet_margin[stance]) < -1.0
    assert r.status == STATUS_KKT and r.converged
    rep, opt = r.extra["constraints"], r.extra["optimality"]
    assert rep["max_violation"] <= 1e-8 and opt["complementarity"] <= 1e-8
    assert opt["hessian_positive_definite"] and opt["lagrangian_stationarity"] < 1e-4
    # recomputed from the trajectory: every stance force in the cone and above F_MIN, to 1e-8 N
    assert np.min(f.facet_margin[stance]) >= -1e-8
    assert np.min(f.forces[..., 2][stance]) >= F_MIN - 1e-8
    # the constraint binds (rows at zero margin with positive multipliers) and costs something
    item = rep["items"][0]
    lam, c = np.asarray(item["multipliers"]), np.asarray(item["values"])
    assert lam.min() >= 0.0 and np.all(lam[c < -1e-6] == 0.0) and np.any(lam > 1e-3)
    assert free.cost < r.cost < 1.01 * free.cost
    # the report lists the (node, foot) pairs with their rows
    assert len(item["nodes"]) == len(c) and item["labels"][-1] == "min normal force"


def test_the_scene_table_builds_the_same_problem(tmp_path, solved):
    _, r, cp = solved
    text = load_scene("anymal_trot").source
    scene = tmp_path / "trot_cone.toml"
    body = open(text).read().replace('expansion = "switch"', 'expansion = "first"')
    scene.write_text(body + f'\n[[constraints]]\ntype = "friction_cone"\nmu = {MU}\nmin_normal_force = {F_MIN}\n')
    spec = load_scene(scene)
    built = spec.build()
    assert isinstance(built, ConstrainedProblem) and built.constraints[0] == cp.constraints[0]
    assert built.placed[0].nodes.tolist() == cp.placed[0].nodes.tolist()


@pytest.mark.parametrize(("table", "key"), [
    ('mu = 0.0', "constraints[0].mu"),
    ('facets = 3', "constraints[0].facets"),
    ('min_normal_force = -1.0', "constraints[0].min_normal_force"),
    ('min_normal_force = 10.0\nmax_normal_force = 5.0', "constraints[0].max_normal_force"),
    ('feet = ["LF_FOT"]', "constraints[0].feet[0]"),
    ('muu = 0.5', "constraints[0]"),
])
def test_bad_friction_cone_tables_name_the_key(tmp_path, table, key):
    text = open(load_scene("anymal_trot").source).read()
    scene = tmp_path / "bad.toml"
    scene.write_text(text + f'\n[[constraints]]\ntype = "friction_cone"\n{table}\n')
    with pytest.raises(InputError) as info:
        load_scene(scene)
    assert info.value.parameter.startswith(key), info.value.parameter


def test_force_constraints_refuse_what_they_cannot_hold(trot):
    from geoddp.problem import paper_problem

    with pytest.raises(InputError) as info:
        ConstrainedProblem(trot, terminal_constraints=[FrictionCone()])
    assert info.value.parameter == "terminal_constraints[0]"
    with pytest.raises(InputError) as info:
        ConstrainedProblem(paper_problem(horizon=5), [FrictionCone()])
    assert info.value.parameter.startswith("constraints[0]")
    with pytest.raises(InputError) as info:
        ConstrainedProblem(trot, [FrictionCone(feet=["LF_FOOT", "nose"])])
    assert info.value.parameter == "constraints[0].feet[1]"
    for kw, key in ((dict(mu=-1), "mu"), (dict(facets=5), "facets"), (dict(min_normal_force=np.inf), "min_normal_force"),
                    (dict(max_normal_force=0.0), "max_normal_force"), (dict(feet="LF_FOOT"), "feet")):
        with pytest.raises(InputError) as info:
            FrictionCone(**kw)
        assert info.value.parameter == key
