"""Compiled cost kernels (geoddp._core) against the Python oracle, per call on a 300-node trajectory.

For each term type and for the sum of all five, on the space manipulator (free-flyer root, nv 9)
and the all-joints model (two free flyers, nv 15): the time of ``MultibodyCostSum.derivatives``
(value, gradient, (0)-Hessian with the exact / differenced second-order part) and of ``value``,
the tests' Python oracle (tests/oracle_costs.py) against the package's kernels. Medians of ``--repeats`` calls after one warm-up call.
The compiled Hessians are exact; the Python ones are central differences (~1e-8 relative).

Run: ``python benchmarks/costs_compiled.py [--nodes 300] [--repeats 5]`` (needs the extension).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

from geoddp.data import urdf_path

from geoddp.costs.multibody import (
    ControlRegularisation,
    FramePlacement,
    FrameRotation,
    FrameTranslation,
    MultibodyCostSum,
    StateRegularisation,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from oracle_costs import OracleCostSum  # noqa: E402  (the tests' oracle)



# the all-joints model is the tests' (tests/data), not package data
TEST_URDFS = Path(__file__).resolve().parents[1] / "tests" / "data"


def _model(name: str) -> tuple[pin.Model, str]:
    path = TEST_URDFS / f"{name}.urdf" if name == "test_all_joints" else urdf_path(f"{name}.urdf")
    model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    return model, {"space_manipulator": "ee", "test_all_joints": "payload"}[name]


def _terms(model: pin.Model, frame: str, Q: np.ndarray, rng: np.random.Generator) -> dict:
    data = model.createData()
    fid = model.getFrameId(frame)
    Ms = []
    for q in Q:  # per-node targets 1 rad away from the frame (tracking: the general case)
        pin.forwardKinematics(model, data, q)
        M = pin.updateFramePlacement(model, data, fid)
        Ms.append(M * pin.SE3(pin.exp3(rng.normal(size=3)), rng.normal(size=3) * 0.2))
    nv = model.nv
    return {
        "FramePlacement": FramePlacement(model, frame, Ms, 1.0),
        "FrameRotation": FrameRotation(model, frame, np.array([M.rotation for M in Ms]), 1.0),
        "FrameTranslation": FrameTranslation(model, frame, np.array([M.translation for M in Ms]), 1.0),
        "StateRegularisation": StateRegularisation(model, pin.neutral(model), None, np.full(2 * nv, 0.1)),
        "ControlRegularisation": ControlRegularisation(np.zeros(4), 0.01),
    }


def _median_time(f, repeats: int) -> float:
    f()
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nodes", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    N = args.nodes
    print(f"{N} nodes, median of {args.repeats} calls; times in ms\n")
    print(f"| model (nv) | term | derivatives python | compiled | speed-up | value python | compiled | speed-up |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for name in ("space_manipulator", "test_all_joints"):
        model, frame = _model(name)
        Q = np.array([pin.integrate(model, pin.neutral(model), rng.uniform(-1, 1, model.nv)) for _ in range(N)])
        V = rng.normal(size=(N, model.nv))
        U = rng.normal(size=(N, 4))
        terms = _terms(model, frame, Q, rng)
        cases = [(k, [t]) for k, t in terms.items()] + [("sum of all five", list(terms.values()))]
        for label, ts in cases:
            row = []
            for method in ("derivatives", "value"):
                times = {}
                for backend, kind in (("python", OracleCostSum), ("compiled", MultibodyCostSum)):
                    s = kind(ts, model=model)
                    times[backend] = _median_time(lambda: getattr(s, method)(Q, V, U), args.repeats)
                row += [times["python"] * 1e3, times["compiled"] * 1e3, times["python"] / times["compiled"]]
            print(f"| {name} ({model.nv}) | {label} | {row[0]:.2f} | {row[1]:.3f} | {row[2]:.0f}x "
                  f"| {row[3]:.2f} | {row[4]:.3f} | {row[5]:.0f}x |")


if __name__ == "__main__":
    main()
