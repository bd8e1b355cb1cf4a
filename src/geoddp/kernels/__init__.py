"""The compiled kernels over plain arrays: the documented interface.

Everything the solver does per node and in sequence runs in C++ (:mod:`geoddp._core`, built by
``pip install`` from ``cpp/`` against the installed pin), by layer: the backward Riccati-like
recursion and the gradient recursion; SO(3)/SE(3) exp, log and right Jacobians; the satellite (one
rigid body on TSO(3)): rollout and exact expansion; the geodesic attitude cost's derivatives. This
module names them and documents their arrays; it imports nothing from geoddp but the extension:
arrays in, arrays out, no Python call per node. (Until 2026-11-27 these kernels were numba's; the
C++ ones are the same arithmetic, the rollouts and the dense pass bit for bit, and faster: see the
README's "One compiled core".)

Conventions for every kernel below:

* every array is ``float64`` and C-contiguous (``np.ascontiguousarray(x, dtype=float)``); an
  input of another dtype or layout is converted on the way in, an output must already be one
  (ValueError otherwise: a converted copy would drop the writes);
* scalars are Python ``float`` / ``bool``; H is the horizon, n the state tangent dimension, m the
  number of inputs, N a batch size;
* "out" arguments are filled in place (allocated by the caller, any initial content unless
  "added into"); "in" arguments are not modified.

Riccati (``cpp/riccati/riccati.cpp``, ``cpp/tso3/tso3.cpp``)
------------------------------------------------------------
``backward_pass(Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final, Theta, Gamma, Xi, second_order,
reg, k_ff, K_fb, Quu_min_eig_proxy) -> (failed_node: int, d1: float, d2: float)``
    in: Phi (H,n,n), B (H,n,m), lx (H,n), lu (H,m), lxx (H,n,n), lux (H,m,n), luu (H,m,m),
    Vx_final (n,), Vxx_final (n,n), Theta (H,n,n,n), Gamma (H,n,n,m), Xi (H,n,m,m) (read only when
    second_order; may then have length 0 in H otherwise), second_order (bool), reg (float >= 0).
    Symmetric blocks (lxx, luu, Theta_i, Xi_i) are read in their upper triangle only (Vxx_final in
    full).
    out: k_ff (H,m), K_fb (H,m,n), Quu_min_eig_proxy (H,), written for nodes H-1 down to the
    returned failed_node (-1 on success).
``gradient(Phi, B, lx, lu, lx_final, out) -> None``
    in: Phi (H,n,n), B (H,n,m), lx (H,n), lu (H,m), lx_final (n,); out: out (H,m) = dJ/du.

Lie numerics (``cpp/tso3/tso3.cpp``, ``cpp/lie/right_jacobians.hpp``)
---------------------------------------------------------------------
``so3_exp(x0, x1, x2, out) -> None``: x0..x2 floats (rad); out (3,3) = exp(hat(x)).
``so3_log(R, out) -> None``: in R (3,3) rotation; out (3,) rotation vector, angle in [0, pi].
``so3_log_batch(R, out) -> None``: in R (N,3,3); out (N,3).
``so3_right_jacobian(x, inverse) -> (3,3)``: in x (3,); Jr(x) or, if inverse, Jr(x)^-1 (new array).
``se3_right_jacobian(x, inverse) -> (6,6)``: in x (6,) [linear; angular]; Jr(x) or Jr(x)^-1.

Rigid body (``cpp/tso3/tso3.cpp``)
----------------------------------
``satellite_rollout(R0, Om0, R_bar, Om_bar, u_bar, k_ff, K_fb, gamma, use_feedback, inertia,
inertia_inv, actuation, dt, semi_implicit, R_out, Om_out, u_out) -> bool`` (False: non-finite state)
    in: R0 (3,3), Om0 (3,) rad/s, R_bar (H+1,3,3), Om_bar (H+1,3), u_bar (H,m), k_ff (H,m),
    K_fb (H,m,6), gamma (float), use_feedback (bool), inertia (3,3) kg m^2, inertia_inv (3,3),
    actuation (3,m), dt (float, s), semi_implicit (bool). The nominal arrays are read only when
    use_feedback. out: R_out (H+1,3,3), Om_out (H+1,3), u_out (H,m). R_out/Om_out may be the
    same arrays as R_bar/Om_bar when use_feedback is False.
``satellite_rollout_box(R0, Om0, R_bar, Om_bar, u_bar, k_ff, K_fb, gamma, lower, upper, inertia,
inertia_inv, actuation, dt, semi_implicit, R_out, Om_out, u_out) -> bool``
    the same with feedback and control limits lower, upper (H,m): u_k is clamped into the box
    after the feedback law (control limits).
``satellite_linearise(Om, dt, inertia, inertia_inv, actuation, semi_implicit, second_order, Phi, B,
Theta, Gamma, Xi) -> None``
    in: Om (H+1,3) nominal rates, dt, inertia (3,3), inertia_inv (3,3), actuation (3,m), flags.
    out: Phi (H,6,6), B (H,6,m); when second_order also Theta (H,6,6,6), Gamma (H,6,6,m),
    Xi (H,6,m,m) (otherwise they are not touched and may be empty).

Costs (``cpp/tso3/tso3.cpp``)
-----------------------------
``geodesic_attitude_derivatives(E, W, l, g, Hs) -> None``
    in: E (N,3,3) = R_d^T R, W (3,3) symmetric weight; added into: l (N,), g (N,3), Hs (N,3,3).

"""
from __future__ import annotations

import numpy as np

try:  # pinocchio first: its import loads the libpinocchio the extension links
    import pinocchio  # noqa: F401

    from .. import _core as core
except ImportError as exc:  # not built, or built against another pin: nothing can run
    raise ImportError(f"geoddp needs its compiled core, which does not import: {exc}") from exc

backward_pass = core.backward_pass
gradient = core.gradient
so3_exp = core.so3_exp
so3_log = core.so3_log
so3_log_batch = core.so3_log_batch
satellite_rollout = core.satellite_rollout
satellite_rollout_box = core.satellite_rollout_box
satellite_linearise = core.satellite_linearise
geodesic_attitude_derivatives = core.geodesic_attitude_derivatives


def so3_right_jacobian(x: np.ndarray, inverse: bool) -> np.ndarray:
    """Jr(x) or Jr(x)^-1 (3, 3) of SO(3) at x (3,), exact to round-off (Taylor branches near 0)."""
    return core.so3_right_jacobian_inv(x) if inverse else core.so3_right_jacobian(x)


def se3_right_jacobian(x: np.ndarray, inverse: bool) -> np.ndarray:
    """Jr(x) or Jr(x)^-1 (6, 6) of SE(3) at x (6,) = [linear; angular], exact to round-off."""
    return core.se3_right_jacobian_inv(x) if inverse else core.se3_right_jacobian(x)


__all__ = [
    "backward_pass", "gradient", "so3_exp", "so3_log", "so3_log_batch", "so3_right_jacobian",
    "se3_right_jacobian", "satellite_rollout", "satellite_rollout_box", "satellite_linearise", "geodesic_attitude_derivatives",
]
