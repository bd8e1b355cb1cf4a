"""Input validation (minimal stand-in; the full module lands from the scene branch)."""
from __future__ import annotations

import difflib

import numpy as np


class InputError(ValueError):
    """Invalid input; ``parameter`` names it."""

    def __init__(self, parameter: str, message: str) -> None:
        super().__init__(f"{parameter}: {message}")
        self.parameter = parameter


def finite_array(x, name, shape=None):
    try:
        a = np.array(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(name, f"expected numbers, got {x!r}") from exc
    if shape is not None and (a.ndim != len(shape) or any(s is not None and s != d for s, d in zip(shape, a.shape))):
        raise InputError(name, f"expected shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError(name, "expected finite numbers, got NaN or inf")
    return a


def positive_float(x, name):
    v = float(finite_array(x, name, ()))
    if not v > 0:
        raise InputError(name, f"expected a positive number, got {v}")
    return v


def choice(x, name, options):
    if x not in options:
        close = difflib.get_close_matches(str(x), options, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise InputError(name, f"expected one of {list(options)}, got {x!r}{hint}")
    return x


def inertia_matrix(I, name="inertia"):
    a = finite_array(I, name)
    if a.shape == (3,):
        a = np.diag(a)
    if a.shape != (3, 3):
        raise InputError(name, f"expected 3 numbers or a 3x3 matrix, got shape {a.shape}")
    if not np.allclose(a, a.T, rtol=1e-12, atol=0):
        raise InputError(name, "expected a symmetric matrix")
    if np.any(np.linalg.eigvalsh(a) <= 0):
        raise InputError(name, "expected a positive definite matrix")
    return a


def actuation_matrix(H, name="actuation"):
    a = finite_array(H, name)
    if a.ndim != 2 or a.shape[0] != 3 or a.shape[1] < 1:
        raise InputError(name, f"expected shape (3, m) with m >= 1, got {a.shape}")
    return a


def rotation_matrix(R, name, tol=1e-9):
    a = finite_array(R, name, (3, 3))
    if np.abs(a.T @ a - np.eye(3)).max() > tol:
        raise InputError(name, "expected an orthonormal matrix (R^T R = I)")
    if np.linalg.det(a) < 0:
        raise InputError(name, "expected det = +1, got -1 (a reflection)")
    return a


def spd_matrix(S, name, n, allow_scalar=True, allow_vector=True, semidefinite=False):
    a = finite_array(S, name)
    if a.ndim == 0 and allow_scalar:
        a = float(a) * np.eye(n)
    elif a.shape == (n,) and allow_vector:
        a = np.diag(a)
    if a.shape != (n, n):
        raise InputError(name, f"expected a scalar, {n} numbers or a {n}x{n} matrix, got shape {a.shape}")
    if not np.allclose(a, a.T, rtol=1e-12, atol=0):
        raise InputError(name, "expected a symmetric matrix")
    ev = np.linalg.eigvalsh(a)
    if semidefinite:
        if ev.min() < -1e-12 * max(abs(ev.max()), 1.0):
            raise InputError(name, "expected a positive semidefinite matrix")
    elif ev.min() <= 0:
        raise InputError(name, "expected a positive definite matrix")
    return a


def positive_int(x, name):
    if isinstance(x, bool) or int(x) != x or x < 1:
        raise InputError(name, f"expected an integer >= 1, got {x!r}")
    return int(x)


def nonnegative_float(x, name):
    v = float(finite_array(x, name, ()))
    if v < 0:
        raise InputError(name, f"expected a number >= 0, got {v}")
    return v
