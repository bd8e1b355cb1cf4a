"""The minimal interface of a matrix Lie group as geoddp uses it (right / local conventions).

A group G of dimension d with Lie algebra ~ R^d provides, for x, y (d,) and elements g, h:

* ``exp(x)``, ``log(g)``: the exponential and its inverse near the identity;
* ``compose(g, h)`` = g h and ``inverse(g)``;
* ``Ad(g)`` (d, d), with g exp(x) g^-1 = exp(Ad(g) x), and ``Ad_exp_neg(x)`` = Ad(exp(-x)), how a
  right step by exp(x) moves a body-frame perturbation: exp(eta) exp(x) = exp(x) exp(Ad_exp_neg(x) eta);
* ``ad(x)`` (d, d) = [x, .] and ``structure_constants`` C (d, d, d), [x, y]_i = C[i, p, q] x_p y_q;
* the right Jacobian ``right_jacobian(x)`` Jr (d, d), exp(x + e) = exp(x) exp(Jr(x) e + O(e^2)),
  its inverse ``right_jacobian_inv(x)`` and its derivative
  ``right_jacobian_derivative_batch(X)`` (N, d) -> (N, d, d, d), D[n, i, j, l] = d Jr(x_n)[i, j] / d x_l,
  so that exp(x + e) = exp(x) exp(Jr e + 1/2 D(e, e) + O(e^3)).

Implementations: :class:`geoddp.lie.SO3`, :class:`geoddp.lie.SE3`; the product over a Pinocchio
model's joints is :mod:`geoddp.lie.product` (commutative factors have Ad = Jr = I, D = C = 0).
"""
from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class Group(Protocol):
    """What :mod:`geoddp.lie.product` and :mod:`geoddp.models.integrators` need of a non-commutative group."""

    dim: int
    structure_constants: np.ndarray

    @staticmethod
    def exp(x: np.ndarray) -> Any: ...

    @staticmethod
    def log(g: Any) -> np.ndarray: ...

    @staticmethod
    def compose(g: Any, h: Any) -> Any: ...

    @staticmethod
    def inverse(g: Any) -> Any: ...

    @staticmethod
    def Ad(g: Any) -> np.ndarray: ...

    @staticmethod
    def Ad_exp_neg(x: np.ndarray) -> np.ndarray: ...

    @staticmethod
    def ad(x: np.ndarray) -> np.ndarray: ...

    @staticmethod
    def right_jacobian(x: np.ndarray) -> np.ndarray: ...

    @staticmethod
    def right_jacobian_inv(x: np.ndarray) -> np.ndarray: ...

    @staticmethod
    def right_jacobian_derivative_batch(X: np.ndarray) -> np.ndarray: ...
