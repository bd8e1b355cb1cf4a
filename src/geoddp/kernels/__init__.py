"""Compiled hot loops over plain arrays (numba, cached to disk): the documented interface.

Everything the solver does per node and in sequence lives in this package, by layer:

* :mod:`.riccati`    the backward Riccati-like recursion and the gradient recursion;
* :mod:`.lie`        SO(3)/SE(3) exp, log, right Jacobians and their Taylor coefficients;
* :mod:`.rigid_body` the satellite (one rigid body on TSO(3)): rollout and exact expansion;
* :mod:`.costs`      the geodesic attitude cost's derivatives.

The package imports nothing from geoddp (numpy and numba only): arrays in, arrays out, no Python
call per node. Why numba: a Python loop over 300 nodes with a dozen small numpy calls per node
costs ~10 ms per pass; compiled, the same recursion costs ~1 us per node. ``cache=True`` keeps the
compiled code on disk (``__pycache__`` next to each module), so only the first run after install
pays the compilation (a few seconds). numba's cache is invalidated per source file: after editing
:mod:`.lie`, delete the ``__pycache__/*.nbi|nbc`` files of the modules that call it.

Conventions for every kernel below:

* every array is ``float64`` and C-contiguous (``np.ascontiguousarray(x, dtype=float)``); other
  dtypes or layouts compile a second, slower specialisation or write truncated values;
* scalars are Python ``float`` / ``bool``; H is the horizon, n the state tangent dimension, m the
  number of inputs, N a batch size;
* "out" arguments are filled in place (allocated by the caller, any initial content unless
  "added into"); "in" arguments are not modified.

Riccati (:mod:`.riccati`)
-------------------------
``backward_pass(Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final, Theta, Gamma, Xi, second_order,
reg, k_ff, K_fb, Quu_min_eig_proxy) -> (failed_node: int, d1: float, d2: float)``
    in: Phi (H,n,n), B (H,n,m), lx (H,n), lu (H,m), lxx (H,n,n), lux (H,m,n), luu (H,m,m),
    Vx_final (n,), Vxx_final (n,n), Theta (H,n,n,n), Gamma (H,n,n,m), Xi (H,n,m,m) (read only when
    second_order; may then have length 0 in H otherwise), second_order (bool), reg (float >= 0).
    Symmetric blocks (lxx, luu, Vxx_final, Theta_i, Xi_i) are read in their upper triangle only.
    out: k_ff (H,m), K_fb (H,m,n), Quu_min_eig_proxy (H,), written for nodes H-1 down to the
    returned failed_node (-1 on success).
``gradient(Phi, B, lx, lu, lx_final, out) -> None``
    in: Phi (H,n,n), B (H,n,m), lx (H,n), lu (H,m), lx_final (n,); out: out (H,m) = dJ/du.

Lie numerics (:mod:`.lie`)
--------------------------
``so3_exp(x0, x1, x2, out) -> None``: x0..x2 floats (rad); out (3,3) = exp(hat(x)).
``so3_log(R, out) -> None``: in R (3,3) rotation; out (3,) rotation vector, angle in [0, pi].
``so3_log_batch(R, out) -> None``: in R (N,3,3); out (N,3).
``so3_right_jacobian(x, inverse) -> (3,3)``: in x (3,); Jr(x) or, if inverse, Jr(x)^-1 (new array).
``se3_right_jacobian(x, inverse) -> (6,6)``: in x (6,) [linear; angular]; Jr(x) or Jr(x)^-1.
Kernel-side helpers (callable from numba code): ``matmul33(A, B, out)``, ``jr_coefficients(t)``,
``jr_and_derivative(x, Jr, Dsym, K, K2, E, EK, KE, D, derivative)``.

Rigid body (:mod:`.rigid_body`)
-------------------------------
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
    after the feedback law (issue 15).
``satellite_linearise(Om, dt, inertia, inertia_inv, actuation, semi_implicit, second_order, Phi, B,
Theta, Gamma, Xi) -> None``
    in: Om (H+1,3) nominal rates, dt, inertia (3,3), inertia_inv (3,3), actuation (3,m), flags.
    out: Phi (H,6,6), B (H,6,m); when second_order also Theta (H,6,6,6), Gamma (H,6,6,m),
    Xi (H,6,m,m) (otherwise they are not touched and may be empty).

Costs (:mod:`.costs`)
---------------------
``geodesic_attitude_derivatives(E, W, l, g, Hs) -> None``
    in: E (N,3,3) = R_d^T R, W (3,3) symmetric weight; added into: l (N,), g (N,3), Hs (N,3,3).

``warm_up()`` loads (or compiles) every kernel above but the cost kernel on tiny inputs; see its
docstring.
"""
from __future__ import annotations

import numpy as np

from .costs import geodesic_attitude_derivatives
from .lie import se3_right_jacobian, so3_exp, so3_log, so3_log_batch, so3_right_jacobian
from .riccati import backward_pass, gradient
from .rigid_body import satellite_linearise, satellite_rollout, satellite_rollout_box

__all__ = [
    "backward_pass", "gradient", "so3_exp", "so3_log", "so3_log_batch", "so3_right_jacobian",
    "se3_right_jacobian", "satellite_rollout", "satellite_rollout_box", "satellite_linearise", "geodesic_attitude_derivatives",
    "warm_up",
]

_WARM = False


def warm_up() -> None:
    """Load (or compile, on the first run after install) every kernel on tiny inputs.

    Idempotent. The solver calls it before starting its clock so that ``solve_time_s`` measures
    the solve, not numba's one-off loading of cached machine code (~0.4 s per process).
    """
    global _WARM
    if _WARM:
        return
    H, m = 2, 3
    I3 = np.eye(3)
    R = np.broadcast_to(I3, (H + 1, 3, 3)).copy()
    Om = np.zeros((H + 1, 3))
    U = np.zeros((H, m))
    for semi in (False, True):
        satellite_rollout(I3, np.zeros(3), R, Om, U, U, np.zeros((H, m, 6)), 1.0, True, I3, I3, I3, 0.1, semi,
                          R.copy(), Om.copy(), U.copy())
        satellite_rollout_box(I3, np.zeros(3), R, Om, U, U, np.zeros((H, m, 6)), 1.0, U - 1.0, U + 1.0, I3, I3, I3,
                              0.1, semi, R.copy(), Om.copy(), U.copy())
        for second in (False, True):
            satellite_linearise(Om, 0.1, I3, I3, I3, semi, second, np.empty((H, 6, 6)), np.empty((H, 6, m)),
                                np.empty((H, 6, 6, 6)), np.empty((H, 6, 6, m)), np.empty((H, 6, m, m)))
    Phi = np.broadcast_to(np.eye(6), (H, 6, 6)).copy()
    B = np.zeros((H, 6, m))
    for second in (False, True):
        backward_pass(Phi, B, np.zeros((H, 6)), U, np.zeros((H, 6, 6)), np.zeros((H, m, 6)),
                      np.broadcast_to(I3, (H, m, m)).copy(), np.zeros(6), np.eye(6), np.zeros((H, 6, 6, 6)),
                      np.zeros((H, 6, 6, m)), np.zeros((H, 6, m, m)), second, 0.0, np.zeros((H, m)),
                      np.zeros((H, m, 6)), np.zeros(H))
    gradient(Phi, B, np.zeros((H, 6)), U, np.zeros(6), np.zeros((H, m)))
    so3_log_batch(R, np.empty((H + 1, 3)))
    for inverse in (False, True):
        se3_right_jacobian(np.zeros(6), inverse)
    _WARM = True
