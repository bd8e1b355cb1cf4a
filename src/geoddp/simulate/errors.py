"""What a simulated run is measured by: terminal errors against the problem's targets, the
tracking error against the plan, and the control effort.

Targets are read once from the problem's terminal cost:

* satellite (TSO(3) backend): ``attitude_rad`` = the angle of R_d^T R_N (rad, geodesic) and
  ``rate`` = |Omega_N - Omega_d| (rad/s), from the attitude and angular-velocity terms;
* multibody: for the first terminal frame term (placement, rotation or translation),
  ``position_m`` = |p_N - p_ref| (m) and ``attitude_rad`` = the angle of R_ref^T R_N (rad), as
  that term constrains them.

Always: ``state`` = |zeta| with zeta = local(x_bar_H, x_H), the tangent distance of the final
state from the plan's final state (mixed units, as the gains see it); ``tracking_rms`` = the
root mean square of |local(x_bar_k, x_k)| over k = 0 .. H; ``effort`` = sum_k |u_k|^2 dt over the
applied controls ((input units)^2 s).
"""
from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from .. import kernels
from ..models.satellite import Satellite
from ..costs.multibody import FramePlacement, FrameRotation, FrameTranslation


def _angle(R: np.ndarray) -> float:
    """|log(R)| in rad, by the robust log (arccos of the trace loses half the digits near 0)."""
    out = np.empty(3)
    kernels.so3_log(np.ascontiguousarray(R, dtype=float), out)
    return float(np.linalg.norm(out))


class Targets:
    """The terminal targets of a problem and the error measures of a run (module docstring)."""

    def __init__(self, problem: Any) -> None:
        self.model = problem.model
        self.satellite = isinstance(self.model, Satellite)
        terms = list(getattr(problem.terminal, "terms", []))
        self.R_d: np.ndarray | None = None
        self.Omega_d: np.ndarray | None = None
        self.frame: tuple[int, np.ndarray | None, np.ndarray | None] | None = None
        if self.satellite:
            desc = problem.describe()
            self.R_d, self.Omega_d = desc["target_rotation"], desc["target_angular_velocity"]
            return
        for t in terms:
            if isinstance(t, FramePlacement):
                self.frame = (t.frame_id, t.M_ref[-1, :3, 3].copy(), t.M_ref[-1, :3, :3].copy())
            elif isinstance(t, FrameRotation):
                self.frame = (t.frame_id, None, t.R_ref[-1].copy())
            elif isinstance(t, FrameTranslation):
                self.frame = (t.frame_id, t.p_ref[-1].copy(), None)
            if self.frame is not None:
                break
        self._data = self.model.pin_model.createData()

    def terminal(self, q: np.ndarray, v: np.ndarray) -> dict[str, float]:
        """Terminal errors of the final state (q, v) (see the module docstring)."""
        if self.satellite:
            return {"attitude_rad": _angle(self.R_d.T @ q), "rate": float(np.linalg.norm(v - self.Omega_d))}
        out: dict[str, float] = {}
        if self.frame is not None:
            fid, p_ref, R_ref = self.frame
            pm = self.model.pin_model
            pin.framesForwardKinematics(pm, self._data, q)
            M = self._data.oMf[fid]
            if p_ref is not None:
                out["position_m"] = float(np.linalg.norm(M.translation - p_ref))
            if R_ref is not None:
                out["attitude_rad"] = _angle(R_ref.T @ M.rotation)
        return out

    @property
    def series_name(self) -> str:
        """The measure :meth:`series` follows over time: "attitude_rad" (satellite; a frame term
        with a rotation only), "position_m" (a frame term with a position) or "state"."""
        if self.satellite:
            return "attitude_rad"
        if self.frame is None:
            return "state"
        return "position_m" if self.frame[1] is not None else "attitude_rad"

    def series(self, q: np.ndarray, v: np.ndarray, plan_q: np.ndarray, plan_v: np.ndarray) -> np.ndarray:
        """(N+1,) distance to the target at every step of a run (:attr:`series_name`; "state" is the
        tangent distance from the plan's final state)."""
        name = self.series_name
        if name == "state":
            return np.array([np.linalg.norm(self.model.local(plan_q[-1], plan_v[-1], q[k], v[k])) for k in range(len(q))])
        if self.satellite:
            E = np.ascontiguousarray(np.einsum("ji,njk->nik", self.R_d, q))  # R_d^T R_k
            out = np.empty((len(E), 3))
            kernels.so3_log_batch(E, out)
            return np.linalg.norm(out, axis=1)
        return np.array([self.terminal(q[k], v[k])[name] for k in range(len(q))])

    def measures(self, plan_q: np.ndarray, plan_v: np.ndarray, q: np.ndarray, v: np.ndarray, u: np.ndarray,
                 dt: float) -> dict[str, float]:
        """All measures of a run: states q (N+1, ...), v (N+1, nv), applied u (N, m) against the
        plan's plan_q (H+1, ...), plan_v; N may exceed H (MPC): tracking covers k <= min(N, H)."""
        n = min(len(q), len(plan_q))
        dev = np.array([np.linalg.norm(self.model.local(plan_q[k], plan_v[k], q[k], v[k])) for k in range(n)])
        final = self.model.local(plan_q[-1], plan_v[-1], q[-1], v[-1])
        out = {"state": float(np.linalg.norm(final)),
               "tracking_rms": float(np.sqrt(np.mean(dev**2))),
               "effort": float(np.sum(u * u) * dt)}
        out.update(self.terminal(q[-1], v[-1]))
        return out
