"""Synthetic Results for the visualisation tests (no solver involved).

Kept out of conftest.py on purpose: the main branch owns that file.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from geoddp import Result
from geoddp.solver import STATUS_CONVERGED_COST
from geoddp.solver.result import SatelliteResult


def keyframes(clip: dict) -> np.ndarray:
    """(n_keys, 4, 4) transforms from a clip's position and quaternion (x, y, z, w) tracks."""
    tracks = {t["name"]: t["keys"] for t in clip["tracks"]}
    pos, quat = tracks[".position"], tracks[".quaternion"]
    assert [k["time"] for k in pos] == [k["time"] for k in quat] == list(range(len(pos)))
    out = np.tile(np.eye(4), (len(pos), 1, 1))
    for k, (p, q) in enumerate(zip(pos, quat)):
        x, y, z, w = q["value"]
        out[k, :3, :3] = pin.Quaternion(w, x, y, z).toRotationMatrix()
        out[k, :3, 3] = p["value"]
    return out


def synthetic_result(
    horizon: int = 40,
    dt: float = 0.05,
    axis=(1.0, 2.0, 2.0),
    total_angle: float = 2.0,
    iterations: int = 6,
    m: int = 3,
    seed: int = 0,
) -> Result:
    """A smooth rest-to-rest rotation about a fixed axis, with a fake solver history.

    The angle follows a smoothstep theta(s) = total_angle (3 s^2 - 2 s^3), s = t / t_f, so
    Omega = theta' * axis (body frame = world frame for a fixed axis) vanishes at both ends.
    The control history contracts geometrically towards the final controls, so the
    convergence errors are known exactly.
    """
    rng = np.random.default_rng(seed)
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    times = dt * np.arange(horizon + 1)
    tf = times[-1]
    s = times / tf
    theta = total_angle * (3 * s**2 - 2 * s**3)
    theta_dot = total_angle * (6 * s - 6 * s**2) / tf
    rotations = np.stack([pin.exp3(th * a) for th in theta])
    omegas = theta_dot[:, None] * a[None, :]
    controls = np.diff(omegas, axis=0) / dt  # unit inertia: torque = angular acceleration
    controls = controls[:, :m]

    # U_i = U* + 0.3^i * D: linear convergence with known errors ||U_i - U*|| = 0.3^i ||D||.
    direction = rng.standard_normal(controls.shape)
    control_history = np.stack([controls + 0.3**i * direction for i in range(iterations + 1)])
    control_history[-1] = controls
    cost_history = 1.0 + 10.0 * 0.25 ** np.arange(iterations + 1)
    grad_norm_history = 0.3 ** np.arange(iterations + 1)

    return SatelliteResult(
        times=times,
        rotations=rotations,
        angular_velocities=omegas,
        controls=controls,
        feedforward=np.zeros_like(controls),
        feedback=np.zeros((horizon, controls.shape[1], 6)),
        target_rotation=pin.exp3(total_angle * a),
        target_angular_velocity=np.zeros(3),
        cost=float(cost_history[-1]),
        iterations=iterations,
        converged=True,
        status=STATUS_CONVERGED_COST,
        message="synthetic",
        cost_history=cost_history,
        grad_norm_history=grad_norm_history,
        reg_history=np.full(iterations, 1e-6),
        step_history=np.ones(iterations),
        expansion_history=["second"] * iterations,
        solve_time_s=0.0,
        timings={},
        expansion="second",
        integrator="euler",
        dt=dt,
        control_history=control_history,
    )


def multibody_result(scene: str = "space_manipulator", horizon: int = 20, dt: float = 0.05, max_iter: int = 2) -> Result:
    """A real (short, few-iteration) multibody solve of a built-in scene, through the solver:
    model -> problem -> solver -> Result, as the CLI does it. ~0.1 s."""
    from geoddp.scene import builtin as multibody_scenes
    from geoddp.solver import SolverOptions, solve

    problem = getattr(multibody_scenes, scene)(horizon=horizon, dt=dt)
    init = multibody_scenes.hover_controls(problem) if scene == "quadrotor" else None
    return solve(problem, SolverOptions(expansion="first", max_iter=max_iter, verbose=False), initial_controls=init)


# ---------------------------------------------------------------------------------------
# Headless Chromium helpers (static HTML and live viewer tests).

import os  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

CHROMIUM = "/usr/bin/chromium"
# Verified to render meshcat's WebGL with Debian's chromium 156 in a container without GPU:
# --disable-gpu alone falls back to SwiftShader through ANGLE; the two swiftshader flags make
# that fallback explicit (newer Chromium refuses the implicit one). "--use-gl=swiftshader"
# gives a blank page. The host-resolver rule makes any network access fail, proving the
# static page needs none.
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--window-size=800,600",
    "--virtual-time-budget=5000",
]
OFFLINE_FLAG = "--host-resolver-rules=MAP * ~NOTFOUND"
CHROMIUM_TIMEOUT_S = 60


def chromium_or_skip() -> str:
    """Path of Chromium; fail when missing under CI (env CI set), skip otherwise."""
    import pytest

    if os.path.exists(CHROMIUM):
        return CHROMIUM
    msg = f"{CHROMIUM} not found: run .ci/install-browser.sh"
    if os.environ.get("CI"):
        pytest.fail(msg + " (CI is set, so this is an error, not a skip)")
    pytest.skip(msg)


def run_chromium(url: str, *extra: str) -> subprocess.CompletedProcess:
    """Run headless Chromium once on ``url`` with a throw-away profile and a timeout."""
    with tempfile.TemporaryDirectory(prefix="geoddp-chromium-") as profile:
        cmd = [CHROMIUM, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", *extra, url]
        return subprocess.run(cmd, capture_output=True, text=True, timeout=CHROMIUM_TIMEOUT_S, check=False)


def screenshot(url: str, png: Path, *extra: str) -> np.ndarray:
    """Screenshot of ``url`` as an (H, W, 3) uint8 array."""
    from PIL import Image

    proc = run_chromium(url, f"--screenshot={png}", *extra)
    assert png.exists() and png.stat().st_size > 0, f"no screenshot; chromium stderr:\n{proc.stderr[-2000:]}"
    return np.asarray(Image.open(png).convert("RGB"))


def changed_fraction(img: np.ndarray, background: np.ndarray, tol: int = 12) -> float:
    """Fraction of pixels in the central half (each axis) differing from ``background``."""
    h, w, _ = img.shape
    centre = img[h // 4: 3 * h // 4, w // 4: 3 * w // 4].astype(int)
    diff = np.abs(centre - np.asarray(background, dtype=int)[None, None, :]).max(axis=2)
    return float(np.mean(diff > tol))


def have_chromium() -> bool:
    return shutil.which(CHROMIUM) is not None
