"""The compiled backend of :class:`geoddp.models.multibody.Multibody`: thin checks around
:mod:`geoddp._core` (C++17 over the libpinocchio inside the ``pin`` wheel).

Which backend runs: a multibody model uses the compiled core (any of its four integrators) when
the extension imports. The Python path stays as the oracle the tests compare the core against.

The extension must run with the very pin it was compiled against (the layout of
``pinocchio::Model`` is shared with the Python object): it checks ``pinocchio.__version__`` at
import and refuses with a one-line message saying how to rebuild. :data:`IMPORT_ERROR` keeps that
message when the import fails.

Arrays passed to the core are float64 and C-contiguous; shapes are checked here so that bad input
raises :class:`geoddp.validate.InputError` naming the parameter before any C++ runs.
"""
from __future__ import annotations

import numpy as np

from ..validate import InputError

INTEGRATORS = {"euler": 0, "semi_implicit": 1, "rk4": 2, "variational": 3}
#: the integrators whose second order the core also keeps factored (expansion_contracted)
CONTRACTED_INTEGRATORS = ("euler", "semi_implicit", "variational")

try:  # pinocchio first: its import loads the libpinocchio the extension links
    import pinocchio  # noqa: F401

    from .. import _core
except ImportError as exc:  # not built, or built against another pin
    _core = None
    IMPORT_ERROR: str | None = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
else:
    IMPORT_ERROR = None


def available() -> bool:
    """True if :mod:`geoddp._core` imported (built, and against the installed pin)."""
    return _core is not None


def require() -> None:
    """Raise InputError("backend") if the extension is not available."""
    if _core is None:
        raise InputError("backend", f"expected the compiled core geoddp._core to import, got: {IMPORT_ERROR}")


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
