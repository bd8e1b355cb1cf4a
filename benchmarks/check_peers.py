"""Convention checks for benchmarks/peers.py (run in the bench venv).

1. pin 4.0.0 + crocoddyl 3.2.1 ABI sanity: frame placement after forwardKinematics.
2. numpy exp3/log3 against pinocchio.exp3/log3; the CasADi versions used by
   the IPOPT transcription too (with finite Jacobians at 0).
3. crocoddyl rollout of random controls == numpy semi-implicit Euler rollout (1e-12).
4. crocoddyl's total cost == peers.cost (1e-10 relative) with the S_u/dt weight.
5. crocoddyl's ResidualModelFrameRotation == log3(Rd^T R).
6. crocoddyl FDDP optimum: its cost and trajectory equal the numpy ones.
7. IPOPT (exact Hessian) reaches the same J* to 1e-9 relative.
8. A general actuation matrix H (Python actuation model) gives the same dynamics and cost.
"""
from __future__ import annotations

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peers  # noqa: E402


def main() -> int:
    import crocoddyl
    import pinocchio as pin

    rng = np.random.default_rng(0)
    pin.seed(0)
    p = peers.satellite_params()
    problem, model, fid = peers.build_crocoddyl_problem(p)
    data = model.createData()

    # 1. frame placement
    q = pin.randomConfiguration(model)
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    err1 = np.abs(data.oMf[fid].rotation - peers._quat_xyzw_to_R(q)).max()
    print(f"[1] frame placement vs quaternion(x,y,z,w) -> R: {err1:.2e}")
    assert err1 < 1e-14

    # 2. exp3 / log3
    e2 = 0.0
    for scale in (1e-9, 1e-5, 1e-3, 0.1, 1.0, 3.0, np.pi - 1e-6):
        for _ in range(20):
            w = rng.standard_normal(3)
            w *= scale / np.linalg.norm(w)
            R = peers.exp3(w)
            e2 = max(e2, np.abs(R - pin.exp3(w)).max(), np.abs(peers.log3(R) - pin.log3(R)).max())
    print(f"[2] exp3/log3 vs pinocchio: {e2:.2e}")
    assert e2 < 1e-9

    # 2b. CasADi exp3/log3 (IPOPT's transcription) vs pinocchio, and finite
    #     derivatives at the small-angle branches.
    import casadi as ca

    w_ = ca.SX.sym("w", 3)
    M_ = ca.SX.sym("M", 3, 3)
    fexp = ca.Function("e", [w_], [peers._cs_exp3(ca, w_), ca.jacobian(peers._cs_exp3(ca, w_), w_)])
    flog = ca.Function("l", [M_], [peers._cs_log3(ca, M_), ca.jacobian(peers._cs_log3(ca, M_), M_)])
    e2b = 0.0
    for scale in (0.0, 1e-9, 1e-5, 1e-3, 0.1, 1.0, 3.0):
        for _ in range(10):
            w = rng.standard_normal(3)
            w *= scale / np.linalg.norm(w)
            E, dE = fexp(w)
            R = pin.exp3(w)
            L, dL = flog(R)
            assert np.all(np.isfinite(np.array(dE))) and np.all(np.isfinite(np.array(dL)))
            e2b = max(e2b, np.abs(np.array(E) - R).max(), np.abs(np.array(L).ravel() - pin.log3(R)).max())
    print(f"[2b] CasADi exp3/log3 vs pinocchio (angles 0..3 rad): {e2b:.2e}; Jacobians finite")
    assert e2b < 1e-12

    # 3. dynamics
    N = p["horizon"]
    U = rng.standard_normal((N, 3)) * 20.0
    xs = problem.rollout(list(U))
    Rn, Wn = peers.rollout(p, U)
    Rc = np.array([peers._quat_xyzw_to_R(x[:4]) for x in xs])
    Wc = np.array(xs)[:, 4:]
    err3 = max(np.abs(Rc - Rn).max(), np.abs(Wc - Wn).max())
    print(f"[3] crocoddyl vs numpy rollout, random u (|Omega_N|={np.linalg.norm(Wn[-1]):.2f}): {err3:.2e}")
    assert err3 < 1e-12

    # 4. cost
    Jc = problem.calc(xs, list(U))
    Jn = peers.cost(p, U)
    print(f"[4] crocoddyl cost {Jc:.15g} vs numpy {Jn:.15g}: rel {abs(Jc - Jn) / abs(Jn):.2e}")
    assert abs(Jc - Jn) <= 1e-10 * abs(Jn)

    # 5. frame-rotation residual convention
    state = crocoddyl.StateMultibody(model)
    res = crocoddyl.ResidualModelFrameRotation(state, fid, p["Rd"], 3)
    rd = res.createData(crocoddyl.DataCollectorMultibody(data))
    x = np.concatenate([pin.randomConfiguration(model), np.zeros(3)])
    pin.forwardKinematics(model, data, x[:4])
    pin.updateFramePlacements(model, data)
    res.calc(rd, x, np.zeros(3))
    R = peers._quat_xyzw_to_R(x[:4])
    err5 = np.abs(rd.r - peers.log3(p["Rd"].T @ R)).max()
    print(f"[5] FrameRotation residual vs log3(Rd^T R): {err5:.2e} (vs log3(R^T Rd): "
          f"{np.abs(rd.r - peers.log3(R.T @ p['Rd'])).max():.2e})")
    assert err5 < 1e-12
    # 6. solutions: crocoddyl's own cost and trajectory vs numpy on its controls;
    #    IPOPT's objective vs the rollout-evaluated J; all solvers agree.
    rf = peers.solve_crocoddyl(p, "fddp")
    Rr, Wr = peers.rollout(p, rf["controls"])
    e6 = max(np.abs(rf["rotations"] - Rr).max(), np.abs(rf["omegas"] - Wr).max())
    rel6 = abs(rf["cost_solver"] - rf["cost"]) / rf["cost"]
    print(f"[6] FDDP optimum: J={rf['cost']:.12f} ({rf['iterations']} it), crocoddyl cost rel diff {rel6:.1e}, "
          f"trajectory vs numpy rollout {e6:.1e}")
    assert rel6 < 1e-10 and e6 < 1e-12
    # crocoddyl's per-iteration cost is the rollout cost of that iterate's controls
    import crocoddyl as _c
    problem6, _, _ = peers.build_crocoddyl_problem(p)
    sv = _c.SolverFDDP(problem6)
    sv.th_stop = peers.CROCODDYL_TH_STOP
    us_it: list[np.ndarray] = []
    cs_it: list[float] = []

    class _Keep(_c.CallbackAbstract):
        def __init__(self) -> None:
            _c.CallbackAbstract.__init__(self)

        def __call__(self, s: object) -> None:
            us_it.append(np.array(s.us))
            cs_it.append(float(s.cost))

    sv.setCallbacks([_Keep()])
    us0 = [np.zeros(3)] * p["horizon"]
    sv.solve(problem6.rollout(us0), us0, 100, True)
    e6b = max(abs(c - peers.cost(p, u)) / c for c, u in zip(cs_it, us_it, strict=True))
    print(f"[6b] FDDP per-iteration cost vs rollout cost of its controls: max rel {e6b:.1e} "
          f"over {len(cs_it)} iterations")
    assert e6b < 1e-12
    ri = peers.solve_ipopt(p, "exact")
    h = ri["cost_history_rollout"]
    print(f"     IPOPT history: objective {ri['cost_history'][1]:.4g} vs rollout J {h[1]:.4g} at iteration 1")
    rel7 = abs(ri["cost"] - rf["cost"]) / rf["cost"]
    print(f"[7] IPOPT exact: J={ri['cost']:.12f} ({ri['iterations']} it, {ri['status']}), "
          f"objective - rollout J = {ri['cost_solver'] - ri['cost']:.1e}, rel diff to FDDP {rel7:.1e}")
    assert rel7 < 1e-9
    # 8. a general actuation matrix H (3x2) goes through the Python actuation model
    H = np.array([[1.0, 0.2], [0.0, 1.0], [0.3, 0.5]])
    pH = peers.satellite_params(actuation=H, S_u=0.1 * np.eye(2))
    probH, _, _ = peers.build_crocoddyl_problem(pH)
    UH = rng.standard_normal((pH["horizon"], 2)) * 20.0
    xsH = probH.rollout(list(UH))
    _, WH = peers.rollout(pH, UH)
    e8 = np.abs(np.array(xsH)[:, 4:] - WH).max()
    rel8 = abs(probH.calc(xsH, list(UH)) - peers.cost(pH, UH)) / peers.cost(pH, UH)
    print(f"[8] general H (3x2): rollout {e8:.1e}, cost rel {rel8:.1e}")
    assert e8 < 1e-12 and rel8 < 1e-10
    print("all checks passed")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
