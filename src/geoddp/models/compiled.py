"""The compiled backend of :class:`geoddp.models.multibody.Multibody`: thin checks around
:mod:`geoddp._core` (C++17 over the libpinocchio inside the ``pin`` wheel).

Which backend runs: a multibody model uses the compiled core (any of its four integrators); the
Python path it replaced is the tests' oracle (tests/oracle_multibody.py).

The extension must run with the very pin it was compiled against (the layout of
``pinocchio::Model`` is shared with the Python object): it checks ``pinocchio.__version__`` at
import and refuses with a one-line message saying how to rebuild, and geoddp does not import
without it (:mod:`geoddp.kernels`).

Arrays passed to the core are float64 and C-contiguous; shapes are checked here so that bad input
raises :class:`geoddp.validate.InputError` naming the parameter before any C++ runs.
"""
from __future__ import annotations

import numpy as np

from ..kernels import core as _core
from ..validate import InputError

INTEGRATORS = {"euler": 0, "semi_implicit": 1, "rk4": 2, "variational": 3}
#: the integrators whose second order the core also keeps factored (expansion_contracted)
CONTRACTED_INTEGRATORS = ("euler", "semi_implicit", "variational")


def check_array(x: np.ndarray, name: str, shape: tuple[int, ...]) -> np.ndarray:
    """float64 C-contiguous view (or copy) of x with exactly ``shape``; InputError naming ``name``."""
    a = np.asarray(x)
    if a.shape != shape:
        raise InputError(name, f"expected shape {shape}, got shape {a.shape}")
    return np.ascontiguousarray(a, dtype=np.float64)


def check_output(x: np.ndarray, name: str, shape: tuple[int, ...]) -> np.ndarray:
    """An output buffer the core writes into: float64, C-contiguous, writeable, ``shape``."""
    if not isinstance(x, np.ndarray) or x.shape != shape:
        raise InputError(name, f"expected a float64 array of shape {shape}, got {getattr(x, 'shape', type(x).__name__)}")
    if x.dtype != np.float64 or not x.flags.c_contiguous or not x.flags.writeable:
        raise InputError(name, "expected a writeable C-contiguous float64 array")
    return x
