"""The legged problems' base placement target and contact-force regularisation.

Two cost terms beyond Crocoddyl's gaits (geoddp.problem.legged.GaitCosts.base_placement,
force_regularisation): on ANYmal (point feet) and Talos' legs (flat feet, 6D wrenches), at random
states and controls, each term's value, gradient and Gauss-Newton Hessian (the node with the term
minus the node without it) against central differences on the Lie group (q (+) dq), and its exact
Hessian (ContactProblem.second_order_node) against central differences of the analytic gradient
in the nominal's chart (tests/oracle_legged.py), every entry; weights 0 leave the problems as they
were (and compiled); the scene keys ``[costs].base_placement`` and
``[costs].force_regularisation`` (and a phase's ``base_placement``) build those terms, a short solve
ends with the base nearer its target and the forces nearer their reference than without them,
and bad values are refused naming the key path (exit 2, one line, on the command line).
"""
from __future__ import annotations

import copy
import dataclasses
import re
import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from oracle_legged import fd_second_order_node

from geoddp.cli import EXIT_BAD_INPUT, main
from geoddp.models.contact_compiled import build_kernel
from geoddp.problem.contract import Trajectory
from geoddp.problem.legged import GaitCosts, Node
from geoddp.scene import parse_scene
from geoddp.scene.legged import FEET, TALOS_FEET, PhaseSpec, contact_problem, load_anymal, load_robot, phase_nodes
from geoddp.solver import SolverOptions, solve
from geoddp.validate import InputError

LF, RF, LH, RH = FEET
BASE_W, FORCE_W = 1e3, 1e-2


@pytest.fixture(scope="module")
def anymal():
    return load_anymal()


@pytest.fixture(scope="module")
def talos():
    return load_robot("talos_legs")


def _problem(robot, feet, kind, target):
    """A short schedule on ``robot``: 2 knots on every foot, a 3-knot step of the first foot
    (its landing impulse), 1 knot on every foot; every contact node and the terminal node with the
    base target ``target`` (pin.SE3); the new weights 0."""
    model = robot.model
    q0 = model.referenceConfigurations["half_sitting" if kind == "6d" else "standing"].copy()
    phases = (PhaseSpec(feet, 2, None, 0.0, ()), PhaseSpec(feet[1:], 3, 0.05, 0.03, feet[:1]),
              PhaseSpec(feet, 1, None, 0.0, ()))
    nodes, terminal = phase_nodes(model, feet, q0, phases, target)
    costs = GaitCosts.biped() if kind == "6d" else GaitCosts()
    return contact_problem(robot, nodes, terminal, q0, 0.01, (0.0, 30.0 if kind == "6d" else 50.0), costs, feet,
                           kind)


def _target(problem, dp=(0.03, -0.02, -0.04), rpy_deg=(4.0, -3.0, 10.0)):
    """A base target off the start: translated by ``dp`` m, rotated by ``rpy_deg``."""
    d = problem.model.createData()
    pin.framesForwardKinematics(problem.model, d, problem.q0)
    M = d.oMf[problem.base_frame]
    return pin.SE3(M.rotation @ pin.rpy.rpyToMatrix(np.radians(rpy_deg)), M.translation + np.array(dp))


@pytest.fixture(scope="module")
def problems(anymal, talos):
    out = {}
    for name, robot, feet, kind in (("anymal", anymal, FEET, "3d"), ("talos", talos, TALOS_FEET, "6d")):
        p = _problem(robot, feet, kind, None)
        target = _target(p)
        out[name] = _problem(robot, feet, kind, target)
    return out


def _with(problem, base=0.0, force=0.0, reference="weight_share"):
    """A copy of ``problem`` with the two new weights set (the schedule and dynamics shared)."""
    new = copy.copy(problem)
    new.costs = dataclasses.replace(problem.costs, base_placement=base, force_regularisation=force,
                                    force_reference=reference)
    return new


def _nominal(problem, k, seed):
    """A trajectory through node k at a random state: q near the start, v random, u near the
    quasi-static controls (zero at an impulse node); node k + 1 its image."""
    rng = np.random.default_rng(seed)
    m, H = problem.model, problem.horizon
    q = pin.integrate(m, problem.q0, 0.05 * rng.standard_normal(m.nv))
    v = 0.3 * rng.standard_normal(m.nv)
    Q, V, U = np.tile(problem.q0, (H + 1, 1)), np.zeros((H + 1, m.nv)), np.zeros((H, problem.nu))
    Q[k], V[k] = q, v
    if k < H:
        if not problem.impulse_rows[k]:
            U[k] = problem.dyn.quasi_static(q, problem.nodes[k].feet) + 2.0 * rng.standard_normal(problem.nu)
        ev = problem.node(k, q, v, U[k])[0]
        Q[k + 1], V[k + 1] = ev.q_next, ev.v_next
    return Trajectory(Q, V, U)


def _at(problem, k, traj, z):
    """(q, v, u) of node k at z = (dq, dv, du) around the nominal (q (+) dq)."""
    nv = problem.model.nv
    u = traj.u[k] + z[2 * nv:] if k < problem.horizon else None
    return pin.integrate(problem.model, traj.q[k], z[:nv]), traj.v[k] + z[nv:2 * nv], u


def _nodes_of(problem):
    """A contact node with every foot down, one with the step's swing foot up, the terminal node."""
    swing = next(k for k, n in enumerate(problem.nodes) if n.kind == "contact" and n.swing)
    return [0, swing, problem.horizon]


CASES = [(robot, which, term) for robot in ("anymal", "talos") for which in range(3) for term in ("base", "force")
         if not (which == 2 and term == "force")]  # the terminal node has no forces


def _term_problems(problem, term):
    on = _with(problem, base=BASE_W) if term == "base" else _with(problem, force=FORCE_W)
    return on, _with(problem)


@pytest.mark.parametrize("robot,which,term", CASES)
def test_gradient_and_gauss_newton_against_differences(problems, robot, which, term):
    """The term's gradient against central differences of its value on the group, its
    Gauss-Newton Hessian w J^T J against the differences' residual Jacobian (w the weight, times dt
    at a running node), 1e-6 of the largest entry."""
    problem = problems[robot]
    on, off = _term_problems(problem, term)
    k = _nodes_of(problem)[which]
    traj = _nominal(problem, k, 7 + which)
    nz = problem.nx + problem.nu
    cols = problem.nx if k == problem.horizon else nz
    scale = 1.0 if k == problem.horizon else problem.dt

    def node(p, z, derivatives=False):
        return p.node(k, *_at(p, k, traj, z), derivatives=derivatives)

    def residual(z):  # the term's residual at z (the forces' rows stacked, or the base's log6)
        ev = node(on, z)[0]
        if term == "force":
            return np.concatenate([ev.forces[rows] - ref for rows, ref in on.force_references(on.nodes[k].feet)])
        q = _at(on, k, traj, z)[0]
        d = on.model.createData()
        pin.framesForwardKinematics(on.model, d, q)
        return pin.log6(on.nodes[k].base.actInv(d.oMf[on.base_frame]) if k < on.horizon else
                        on.terminal_node.base.actInv(d.oMf[on.base_frame])).vector

    z0 = np.zeros(nz)
    _, c_on, g_on, H_on = node(on, z0, True)
    _, c_off, g_off, H_off = node(off, z0, True)
    w = BASE_W if term == "base" else FORCE_W
    r0 = residual(z0)
    assert c_on - c_off == pytest.approx(0.5 * w * scale * float(r0 @ r0), rel=1e-9)
    assert c_on - c_off > 1e-2  # a term of some size here
    h = 1e-6
    gd, Jd = np.zeros(nz), np.zeros((len(r0), nz))
    for j in range(cols):
        e = np.zeros(nz)
        e[j] = h
        gd[j] = ((node(on, e)[1] - node(off, e)[1]) - (node(on, -e)[1] - node(off, -e)[1])) / (2 * h)
        Jd[:, j] = (residual(e) - residual(-e)) / (2 * h)
    g, Hgn = g_on - g_off, H_on - H_off
    assert np.max(np.abs(g - gd)) <= 1e-6 * np.max(np.abs(gd)), np.max(np.abs(g - gd)) / np.max(np.abs(gd))
    Hd = w * scale * Jd.T @ Jd
    assert np.max(np.abs(Hgn - Hd)) <= 1e-6 * np.max(np.abs(Hd)), np.max(np.abs(Hgn - Hd)) / np.max(np.abs(Hd))
    if term == "base":  # a state term: nothing in the velocity and control columns
        assert np.all(g[problem.model.nv:] == 0.0) and np.all(Hgn[problem.model.nv:] == 0.0)


@pytest.mark.parametrize("robot,which,term", CASES)
def test_exact_hessian_against_differences_of_the_gradient(problems, robot, which, term):
    """The term's exact cost Hessian (Gauss-Newton part plus its residual's curvature: the base
    frame's placement, the forces' second derivatives) against central differences of the
    analytic gradient in the nominal's chart, every entry, 1e-7 of the largest; the curvature is
    a sizeable part of it."""
    problem = problems[robot]
    on, off = _term_problems(problem, term)
    k = _nodes_of(problem)[which]
    traj = _nominal(problem, k, 11 + which)
    H_exact = on.second_order_node(k, traj)[1] - off.second_order_node(k, traj)[1]
    H_fd = fd_second_order_node(on, k, traj)[1] - fd_second_order_node(off, k, traj)[1]
    err = np.max(np.abs(H_exact - H_fd)) / np.max(np.abs(H_fd))
    assert err < 1e-7, err  # measured: at most 1e-8 (the forces' curvature), 3e-10 (the base's)
    nz = problem.nx + problem.nu
    q, v, u = _at(problem, k, traj, np.zeros(nz))
    gn = on.node(k, q, v, u, True)[3] - off.node(k, q, v, u, True)[3]
    assert np.max(np.abs(H_exact - gn)) > 1e-3 * np.max(np.abs(H_fd))  # the curvature counts


def test_weights_zero_leave_the_problem_as_it_was(problems, anymal):
    """The defaults are 0: node costs equal bit for bit with the Node.base targets set or not, the
    compiled backend in use; a nonzero weight puts the problem on the Python node models (and
    their cost there is the compiled one plus the term)."""
    p = problems["anymal"]
    assert p.costs.base_placement == 0.0 and p.costs.force_regularisation == 0.0 and p.compiled
    bare = _problem(anymal, FEET, "3d", None)
    assert all(n.base is None for n in bare.nodes) and p.nodes[0].base is not None
    U = p.quasi_static_controls() + 0.5 * np.random.default_rng(0).standard_normal((p.horizon, p.nu))
    traj = p.trajectory(U)
    for backend in ("compiled", "python"):
        a, b = copy.copy(p), copy.copy(bare)
        a.backend = b.backend = backend
        assert a.compiled == b.compiled == (backend == "compiled")
        assert np.array_equal(a.node_costs(a.trajectory(U)), b.node_costs(b.trajectory(U)))
    python = copy.copy(p)
    python.backend = "python"
    J = python.node_costs(python.trajectory(U))
    for on, terminal in ((_with(p, base=BASE_W), True), (_with(p, force=FORCE_W), False)):
        assert not on.compiled
        with pytest.raises(InputError, match="costs.base_placement" if terminal else "costs.force_regularisation"):
            build_kernel(on)  # the kernel lacks the term: refused, not silently left out
        tr = on.trajectory(U)
        assert np.array_equal(tr.q, python.trajectory(U).q)
        diff = on.node_costs(tr) - J
        assert np.all(diff[:-1][~p.impulse_rows] > 0) and np.all(diff[:-1][p.impulse_rows] == 0.0)
        assert (diff[-1] > 0) if terminal else (diff[-1] == 0.0)


def test_force_references(problems):
    """weight_share: m |g| / n_support along +z per foot (zero torque on a flat foot), zero: zeros."""
    for name, rows in (("anymal", 3), ("talos", 6)):
        p = problems[name]
        feet = p.nodes[0].feet
        mg = pin.computeTotalMass(p.model) * 9.81
        refs = p.force_references(feet)
        assert [r.start for r, _ in refs] == p.force_rows(feet)
        for _, ref in refs:
            assert ref.shape == (rows,) and ref[2] == pytest.approx(mg / len(feet), rel=1e-12)
            assert np.all(np.delete(ref, 2) == 0.0)
        assert all(np.all(ref == 0.0) for _, ref in _with(p, force=1.0, reference="zero").force_references(feet))


def test_python_inputs_refused():
    for kw, name in ((dict(force_reference="half"), "force_reference"), (dict(base_placement=-1.0), "base_placement"),
                     (dict(force_regularisation=float("nan")), "force_regularisation")):
        with pytest.raises(InputError) as e:
            GaitCosts(**kw)
        assert e.value.parameter == name
    with pytest.raises(InputError) as e:
        Node("contact", (), base=np.zeros(3))
    assert e.value.parameter == "base"


# ------------------------------------------------------------------ scene files
SCENE = {"model": {"kind": "legged", "robot": "anymal", "feet": list(FEET)}, "contact": {"dt": 0.01},
         "phases": [{"contacts": list(FEET), "knots": 2},
                    {"contacts": [RF, LH], "knots": 6, "step_length": 0.05, "step_height": 0.05},
                    {"contacts": list(FEET), "knots": 4}],
         "solver": {"max_iter": 60}}


def _scene(**costs):
    d = copy.deepcopy(SCENE)
    if costs:
        d["costs"] = costs
    return d


def _base_error(problem, q):
    d = problem.model.createData()
    pin.framesForwardKinematics(problem.model, d, q)
    return np.linalg.norm(pin.log6(problem.terminal_node.base.actInv(d.oMf[problem.base_frame])).vector)


def _force_error(problem, res):
    """sum over contact nodes and support feet of |f - f_ref|^2, N^2, along the solution."""
    traj = problem.trajectory(res.controls)
    out = 0.0
    for k, n in enumerate(problem.nodes):
        if n.kind == "contact" and n.feet:
            ev = problem.node(k, traj.q[k], traj.v[k], traj.u[k])[0]
            out += sum(float(np.sum((ev.forces[rows] - ref) ** 2)) for rows, ref in problem.force_references(n.feet))
    return out


def test_scene_keys_build_the_terms(anymal):
    """[costs].base_placement (translation, rpy_deg) and force_regularisation become GaitCosts
    fields and Node.base targets at the contact nodes and the terminal node; a phase's own
    base_placement replaces the scene's there."""
    spec = parse_scene(_scene(base_placement={"weight": 500.0, "translation": [0.1, 0.0, 0.4], "rpy_deg": [0, 0, 90]},
                              force_regularisation={"weight": 1e-3, "reference": "zero"}))
    p = spec.build(anymal)
    assert (p.costs.base_placement, p.costs.force_regularisation, p.costs.force_reference) == (500.0, 1e-3, "zero")
    assert not p.compiled
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    for n in [*p.nodes, p.terminal_node]:
        if n.kind == "impulse":
            assert n.base is None
        else:
            assert np.array_equal(n.base.translation, [0.1, 0.0, 0.4])
            assert np.allclose(n.base.rotation, R, rtol=0, atol=1e-12)
    d = _scene(base_placement={"weight": 1.0, "translation": [0.0, 0.0, 0.4], "quaternion": [0.0, 0.0, 0.0, 1.0]})
    d["phases"][1]["base_placement"] = {"translation": [0.02, 0.0, 0.38]}
    p = parse_scene(d).build(anymal)
    z = [n.base.translation[2] for n in p.nodes if n.kind == "contact"]
    assert z == [0.4] * 2 + [0.38] * 6 + [0.4] * 4 and p.terminal_node.base.translation[2] == 0.4
    d["phases"][2]["base_placement"] = {"translation": [0.05, 0.0, 0.42], "rpy_deg": [0.0, 0.0, 0.0]}
    assert parse_scene(d).build(anymal).terminal_node.base.translation[2] == 0.42  # the last phase's


def test_scene_base_target_solved(anymal):
    """Standing 20 knots (0.2 s), solved (first order, Python node models) with [costs].base_placement
    (weight 1e5, the base 2 cm forward and 4 cm down) and without: J* changes, and the base ends
    within 5 mm of its target where it stays 4.5 cm from it without the term."""
    opts = SolverOptions(expansion="first", max_iter=60)
    d = _scene()
    d["phases"] = [{"contacts": list(FEET), "knots": 20}]
    q0 = anymal.model.referenceConfigurations["standing"]
    target = (q0[:3] + [0.02, 0.0, -0.04]).tolist()
    plain = parse_scene(d).build(anymal)
    with_base = parse_scene({**d, "costs": {"base_placement": {"weight": 1e5, "translation": target}}}).build(anymal)
    r0, rb = solve(plain, opts), solve(with_base, opts)
    assert r0.converged and rb.converged
    e0 = _base_error(with_base, plain.trajectory(r0.controls).q[-1])
    eb = _base_error(with_base, with_base.trajectory(rb.controls).q[-1])
    assert e0 == pytest.approx(np.hypot(0.02, 0.04), rel=0.02) and eb < 0.005, (e0, eb)
    assert rb.cost > r0.cost + 10.0  # J* = 24.9 against 3.5
    assert with_base.trajectory_cost(with_base.trajectory(r0.controls)) > rb.cost


def test_scene_force_regularisation_solved(anymal):
    """A short trot step solved with [costs].force_regularisation (weight 0.1, toward the weight
    share) and without: the forces' squared distance to m |g| / n_support over the contact nodes
    falls at least 10x (1.5e5 to 7.5e3 N^2), and J* changes; the switch expansion (exact Hessians)
    reaches the same J*."""
    opts = SolverOptions(expansion="first", max_iter=60)
    plain = parse_scene(_scene()).build(anymal)
    with_f = parse_scene(_scene(force_regularisation={"weight": 0.1})).build(anymal)
    r0, rf = solve(plain, opts), solve(with_f, opts)
    assert r0.converged and rf.converged
    f0, ff = _force_error(with_f, r0), _force_error(with_f, rf)
    assert f0 > 1e5 and ff < 0.1 * f0, (f0, ff)
    assert rf.cost > r0.cost + 1.0 and with_f.trajectory_cost(with_f.trajectory(r0.controls)) > rf.cost
    # the exact second order (the forces' curvature through L2) drives switch to the same minimum
    rs = solve(with_f, SolverOptions(expansion="switch", max_iter=60))
    assert rs.converged and rs.cost == pytest.approx(rf.cost, rel=1e-10)


BAD = {
    "base_not_a_table": ({"base_placement": 1e3}, "[costs].base_placement", "expected a table"),
    "base_weight_missing": ({"base_placement": {"translation": [0, 0, 0.4]}}, "[costs].base_placement.weight",
                            "missing"),
    "base_weight_negative": ({"base_placement": {"weight": -1.0, "translation": [0, 0, 0.4]}},
                             "[costs].base_placement.weight", ">= 0"),
    "base_translation_missing": ({"base_placement": {"weight": 1.0}}, "[costs].base_placement.translation", "missing"),
    "base_translation_shape": ({"base_placement": {"weight": 1.0, "translation": [0, 0.4]}},
                               "[costs].base_placement.translation", "(3,)"),
    "base_quaternion_norm": ({"base_placement": {"weight": 1.0, "translation": [0, 0, 0.4],
                                                 "quaternion": [0, 0, 0, 2]}},
                             "[costs].base_placement.quaternion", "unit quaternion"),
    "base_two_rotations": ({"base_placement": {"weight": 1.0, "translation": [0, 0, 0.4], "rpy_deg": [0, 0, 0],
                                               "quaternion": [0, 0, 0, 1]}},
                           "[costs].base_placement", "rpy_deg and quaternion"),
    "base_rpy_shape": ({"base_placement": {"weight": 1.0, "translation": [0, 0, 0.4], "rpy_deg": [0, 0]}},
                       "[costs].base_placement.rpy_deg", "(3,)"),
    "base_unknown_key": ({"base_placement": {"weight": 1.0, "translation": [0, 0, 0.4], "rpy": [0, 0, 0]}},
                         "[costs].base_placement.rpy", "did you mean 'rpy_deg'"),
    "force_not_a_table": ({"force_regularisation": 1e-3}, "[costs].force_regularisation", "expected a table"),
    "force_weight_missing": ({"force_regularisation": {"reference": "zero"}}, "[costs].force_regularisation.weight",
                             "missing"),
    "force_weight_nan": ({"force_regularisation": {"weight": float("nan")}}, "[costs].force_regularisation.weight",
                         "finite"),
    "force_reference": ({"force_regularisation": {"weight": 1.0, "reference": "half"}},
                        "[costs].force_regularisation.reference", "weight_share"),
    "force_unknown_key": ({"force_regularisation": {"weight": 1.0, "referance": "zero"}},
                          "[costs].force_regularisation.referance", "did you mean 'reference'"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_cost_keys_name_the_key(case):
    costs, parameter, fragment = BAD[case]
    with pytest.raises(InputError) as e:
        parse_scene(_scene(**costs), "scene.toml")
    assert e.value.parameter == parameter, str(e.value)
    assert fragment in str(e.value) and "scene.toml" in str(e.value)


def test_bad_phase_base_keys_name_the_key():
    d = _scene()
    d["phases"][1]["base_placement"] = {"translation": [0.0, 0.0, 0.4]}
    with pytest.raises(InputError) as e:
        parse_scene(d, "scene.toml")
    assert e.value.parameter == "phases[1].base_placement" and "[costs].base_placement" in str(e.value)
    d = _scene(base_placement={"weight": 1.0, "translation": [0.0, 0.0, 0.4]})
    d["phases"][2]["base_placement"] = {"weight": 2.0, "translation": [0.0, 0.0, 0.4]}
    with pytest.raises(InputError) as e:
        parse_scene(d, "scene.toml")
    assert e.value.parameter == "phases[2].base_placement.weight" and "unknown key" in str(e.value)


def test_a_bad_cost_key_is_one_line_and_exit_2(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text('[model]\nkind = "legged"\nrobot = "anymal"\nfeet = ["LF_FOOT", "RF_FOOT", "LH_FOOT", "RH_FOOT"]\n'
                    '[contact]\ndt = 0.01\n[[phases]]\ncontacts = ["LF_FOOT", "RF_FOOT", "LH_FOOT", "RH_FOOT"]\n'
                    'knots = 2\n[costs]\nbase_placement = { weight = 1e3, translation = [0.0, 0.4] }\n')
    assert main(["run", str(path), "--quiet"]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("geoddp: error: [costs].base_placement.translation: expected")


GUIDE = Path(__file__).resolve().parents[1] / "docs" / "guide" / "legged.md"


def test_the_guides_snippet_and_errors_are_the_code(anymal):
    """The legged guide's section on the two terms: its TOML block (with [model] and [contact]
    added) parses to the weights and targets it states, and its error lines are the parser's."""
    text = GUIDE.read_text()
    text = text[text.index("(legged-base-forces)="):]
    block = re.search(r"```toml\n(.*?)```", text, re.S).group(1)
    d = {**copy.deepcopy(SCENE), **tomllib.loads(block)}
    del d["solver"]
    p = parse_scene(d).build(anymal)
    assert (p.costs.base_placement, p.costs.force_regularisation, p.costs.force_reference) == (1e5, 0.1, "weight_share")
    assert [n.base.translation.tolist() for n in p.nodes] == [[0.0, 0.0, 0.45]] * 20
    assert np.array_equal(p.terminal_node.base.translation, [0.0, 0.0, 0.45])
    assert np.array_equal(parse_scene({**d, "phases": SCENE["phases"]}).build(anymal).nodes[0].base.translation,
                          [0.02, 0.0, 0.4392])
    errors = re.search(r"```text\n(.*?)```", text, re.S).group(1).strip().splitlines()
    for line, case in zip(errors, ("base_translation_shape", "force_reference")):
        with pytest.raises(InputError) as e:
            parse_scene(_scene(**BAD[case][0]), "bad.toml")
        assert "geoddp: error: " + str(e.value) == line, (str(e.value), line)
