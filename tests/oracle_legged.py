"""The legged problem's second-order terms by differences: the tests' oracle for the exact ones
(geoddp.problem.legged.ContactProblem.second_order_node).

Central differences (step h) of the analytic first derivatives of the whole node map
zeta -> difference(x_bar+, f(x_bar (+) zeta, u_bar + du)) and of the node cost's gradient
(ContactProblem._node_map), symmetrised: what geoddp computed before the KKT system was
differentiated twice.
"""
import numpy as np

FD_STEP = 1e-4  # 1e-5 lets the round-off of the KKT solves show


def fd_second_order_node(problem, k, traj, h=FD_STEP):
    """(T (nx, nz, nz), cost Hessian (nz, nz)) of node k by differences; k = H: (None, Hessian)."""
    nx, nu = problem.nx, problem.nu
    nz = nx + nu
    cols = nx if (k == problem.horizon or problem.impulse_rows[k]) else nz  # impulse: no control dependence
    T = None if k == problem.horizon else np.zeros((nx, nz, nz))
    Hc = np.zeros((nz, nz))
    if k < problem.horizon and problem.impulse_rows[k]:
        Hc[nx:, nx:] = problem.costs.impulse_control * np.eye(nu)
    z = np.zeros(nz)
    for j in range(cols):
        z[j] = h
        Gp, gp = problem._node_map(k, traj, z)
        z[j] = -h
        Gm, gm = problem._node_map(k, traj, z)
        z[j] = 0.0
        if T is not None:
            T[:, :, j] = (Gp - Gm) / (2 * h)
        Hc[:, j] = (gp - gm) / (2 * h)
    if cols < nz:
        Hc[:cols, cols:] = Hc[cols:, :cols].T
    Hc = 0.5 * (Hc + Hc.T)
    if T is not None:
        T = 0.5 * (T + T.transpose(0, 2, 1))
    return T, Hc
