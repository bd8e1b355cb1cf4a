"""Integrator accuracy against cost: terminal-state error vs step size and vs solve time.

For each integrator (explicit Euler = the paper's, semi-implicit Euler = Crocoddyl's, both on the
TSO(3) closed forms; RKMK4 and the forward variational Euler step, on the general one-body model
of the same satellite) and step dt, solve the paper's problem (tf = 3 s, running weight S_u scaled by dt / 0.01 so that every dt
discretises the same continuous problem) with geoddp, then integrate the *continuous* dynamics
under the same zero-order-hold controls with scipy's DOP853 (rtol 1e-12) and report the terminal
error of the discrete trajectory: the geodesic angle between R_H and the continuous R(tf), and
||Omega_H - Omega(tf)||. The Euler schemes and the variational step are first order (slope 1),
RKMK4 fourth order (slope 4, until the error reaches the continuous reference's).

Run: ``python benchmarks/integrators.py [--plots DIR]`` (prints a Markdown table; writes
integrator_error.png).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pinocchio as pin
from scipy.integrate import solve_ivp

from geoddp.problem import paper_problem
from geoddp.solver import SolverOptions, solve

DTS = [0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001]
TF = 3.0


INTEGRATORS = ("euler", "semi_implicit", "rk4", "variational")
COLOURS = {"euler": "tab:red", "semi_implicit": "tab:blue", "rk4": "tab:green", "variational": "tab:purple"}


def satellite_of(problem) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]:
    """I, I^-1 (3, 3), H (3, m), dt, R0 (3, 3), Omega0 (3,) of the problem's satellite, whichever
    model runs it (TSO(3) closed forms, or the general one-body model: its spherical root's
    inertia, q0 a quaternion (x, y, z, w))."""
    m = problem.model
    if hasattr(m, "inertia"):
        return m.inertia, m.inertia_inv, m.actuation, m.dt, problem.R0, problem.Omega0
    inertia = m.pin_model.inertias[1].inertia.copy()
    R0 = pin.Quaternion(np.asarray(problem.q0)).toRotationMatrix()
    return inertia, np.linalg.inv(inertia), m.actuation, m.dt, R0, np.asarray(problem.v0)


def terminal_state(problem, r) -> tuple[np.ndarray, np.ndarray]:
    """R_H, Omega_H of a solve's trajectory."""
    if hasattr(problem.model, "inertia"):
        return r.rotations[-1], r.angular_velocities[-1]
    return pin.Quaternion(np.asarray(r.q[-1])).toRotationMatrix(), np.asarray(r.v[-1])


def continuous_terminal_state(problem, controls):
    """R(tf), Omega(tf) of dR/dt = R hat(Omega), I dOmega/dt = (I Omega) x Omega + H u(t), u ZOH."""
    I, Iinv, Hm, dt, R0, Om0 = satellite_of(problem)

    def rhs(t, y, tau):
        R = y[:9].reshape(3, 3)
        Om = y[9:]
        W = np.array([[0, -Om[2], Om[1]], [Om[2], 0, -Om[0]], [-Om[1], Om[0], 0]])
        return np.concatenate([(R @ W).ravel(), Iinv @ (np.cross(I @ Om, Om) + tau)])

    y = np.concatenate([R0.ravel(), Om0])
    for k, u in enumerate(controls):
        sol = solve_ivp(rhs, (k * dt, (k + 1) * dt), y, method="DOP853", rtol=1e-12, atol=1e-13, args=(Hm @ u,))
        y = sol.y[:, -1]
    R = y[:9].reshape(3, 3)
    U_, _, Vt = np.linalg.svd(R)  # re-orthonormalise the (1e-12-accurate) integrated matrix
    return U_ @ Vt, y[9:]


def measure(integrator: str, dt: float, repeats: int = 3) -> dict:
    horizon = int(round(TF / dt))
    # S_u scaled by dt / 0.01: a Riemann sum of one continuous-time problem (= the paper's at
    # dt = 0.01), so that every dt discretises the same manoeuvre.
    p = paper_problem(integrator=integrator, dt=dt, horizon=horizon, S_u=0.1 * dt / 0.01)
    times = []
    for _ in range(repeats):
        r = solve(p, SolverOptions(verbose=False))
        times.append(r.solve_time_s)
    Rc, Omc = continuous_terminal_state(p, r.controls)
    RH, OmH = terminal_state(p, r)
    # the angle of Rc^T R_H from its log (arccos of the trace resolves no better than ~1e-6 deg,
    # which RK4 reaches at dt = 0.05)
    angle = float(np.degrees(np.linalg.norm(pin.log3(Rc.T @ RH))))
    return dict(integrator=integrator, dt=dt, H=horizon, iterations=r.iterations, cost=r.cost,
                time_s=float(np.median(times)), attitude_err_deg=angle,
                rate_err=float(np.linalg.norm(OmH - Omc)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plots", type=Path, default=Path("docs/figures"))
    args = ap.parse_args()
    rows = [measure(integ, dt) for integ in INTEGRATORS for dt in DTS]
    print("| integrator | dt (s) | H | iterations | J* | solve time (ms) | terminal attitude error (deg) | terminal rate error (rad/s) |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['integrator']} | {r['dt']:g} | {r['H']} | {r['iterations']} | {r['cost']:.6f} | "
              f"{r['time_s'] * 1e3:.1f} | {r['attitude_err_deg']:.2e} | {r['rate_err']:.2e} |")
    for integ in INTEGRATORS:
        sel = [r for r in rows if r["integrator"] == integ]
        if integ == "rk4":  # the slope before the error meets round-off and the reference's
            sel = [r for r in sel if r["attitude_err_deg"] > 1e-12]
        slope = np.polyfit(np.log([r["dt"] for r in sel]), np.log([r["attitude_err_deg"] for r in sel]), 1)[0]
        print(f"{integ}: log-log slope of attitude error vs dt = {slope:.2f} (dt {sel[-1]['dt']:g} to {sel[0]['dt']:g})")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    for integ, c in COLOURS.items():
        sel = [r for r in rows if r["integrator"] == integ]
        dts = np.array([r["dt"] for r in sel])
        err = np.array([r["attitude_err_deg"] for r in sel])
        a.loglog(dts, err, "o-", color=c, label=integ)
        b.loglog([r["time_s"] * 1e3 for r in sel], err, "o-", color=c, label=integ)
    a.loglog(DTS, np.array(DTS) * rows[3]["attitude_err_deg"] / 0.01, ":", color="grey", label="slope 1")
    a.set(xlabel="dt (s)", ylabel="terminal attitude error (deg)", title="Error against step size")
    b.set(xlabel="solve time (ms)", ylabel="terminal attitude error (deg)", title="Error against solve time")
    for ax in (a, b):
        ax.grid(alpha=0.3, which="both")
        ax.legend()
    args.plots.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(args.plots / "integrator_error.png", dpi=110)
    print(f"wrote {args.plots / 'integrator_error.png'}")


if __name__ == "__main__":
    main()
