"""Input validation: turn user-supplied values into clean float64 arrays or fail loudly.

Every public function takes the raw value and the *name* of the parameter it came from
(e.g. ``"initial.quaternion"`` or ``"[cost].attitude"``), and either returns a fresh float64
copy (or a Python ``float``/``int``/``str`` for scalar checks) or raises :class:`InputError`
whose message reads ``"<name>: <what was expected>, got <what was got>"``.

This module deliberately imports nothing from the rest of geoddp so that every other module
(scene parser, models, solver, CLI) can depend on it without cycles.
"""
from __future__ import annotations

import difflib
import math
import numbers
import os
import re
from collections.abc import Iterable
from typing import Any

import numpy as np

__all__ = [
    "InputError",
    "finite_array",
    "finite_float",
    "rotation_matrix",
    "unit_quaternion",
    "quaternion_to_rotation",
    "spd_matrix",
    "inertia_matrix",
    "actuation_matrix",
    "positive_float",
    "nonnegative_float",
    "bounded_float",
    "positive_int",
    "nonnegative_int",
    "choice",
    "closest",
    "time_grid",
]


class InputError(ValueError):
    """A user-supplied value is invalid.

    Attributes:
        parameter: the name of the offending parameter, e.g. ``"inertia"`` or
            ``"[cost].attitude_kind"``.
        detail: what was expected and what was got (the message without the parameter).
        source: where the value came from (a scene file path), or ``None``.
    """

    def __init__(self, parameter: str, detail: str, source: str | None = None) -> None:
        self.parameter = parameter
        self.detail = detail
        self.source = source
        msg = f"{parameter}: {detail}"
        if source is not None:
            msg += f" (in {source})"
        super().__init__(msg)

    def with_source(self, source: str) -> "InputError":
        """Return a copy of this error that also names the file the value came from."""
        return InputError(self.parameter, self.detail, source)


THREADS_ENV = "GEODDP_THREADS"


def threads_from_environment() -> int:
    """Threads per process for the compiled passes, from the environment variable GEODDP_THREADS;
    0 when it is unset or empty (the core's default: min(2, cores in the process's affinity mask)).

    A sweep's local workers get it set (cores / workers), so that two worker processes on two
    cores do not each start two threads; set it on the workers of any cluster for the same reason.

    Raises:
        InputError: naming GEODDP_THREADS, if it is not a whole number from 1 to 1024.
    """
    raw = os.environ.get(THREADS_ENV, "").strip()
    if not raw:
        return 0
    try:
        n = int(raw)
    except ValueError:
        n = 0
    if not 1 <= n <= 1024:
        raise InputError(THREADS_ENV, f"expected a whole number of threads from 1 to 1024, got {raw!r}")
    return n


SPIN_ENV = "GEODDP_SPIN_US"
SPIN_US_MAX = 100_000  # the core's bound (cpp/runtime/pool.hpp, geoddp._core.SPIN_US_MAX)


def spin_from_environment() -> int | None:
    """How long the compiled core's idle workers poll for the next task before they sleep, in
    microseconds, from the environment variable GEODDP_SPIN_US (the core reads it itself, once, at
    its first parallel call; cpp/runtime/pool.hpp); None when it is unset or empty (the core's default,
    1000 us).

    Raises:
        InputError: naming GEODDP_SPIN_US, if it is not a whole number from 0 to SPIN_US_MAX written
            with the digits 0-9 alone (the core would otherwise fall back to its default without a
            word).
    """
    raw = os.environ.get(SPIN_ENV, "")
    if not raw:
        return None
    if re.fullmatch(r"[0-9]{1,6}", raw) is None or int(raw) > SPIN_US_MAX:
        raise InputError(SPIN_ENV, f"expected a whole number of microseconds from 0 to {SPIN_US_MAX}, got {raw!r}")
    return int(raw)


MAX_HORIZON = 10_000_000  # steps: beyond this the arrays over the horizon alone exceed any memory
MAX_WEIGHT = 1e100  # largest accepted weight entry: J = x^T S x stays finite for |x| up to ~1e100

# --------------------------------------------------------------------------------------
# helpers


def _quiet(fn):
    """Run a check without numpy floating-point warnings: finite but huge entries overflow in
    norms and products, and the check's own test then refuses them with a message naming the
    parameter (a warning line on stderr would only precede that message)."""
    import functools

    @functools.wraps(fn)
    def wrapper(*args, **kw):
        with np.errstate(all="ignore"):
            return fn(*args, **kw)

    return wrapper


def _describe(x: Any) -> str:
    """Short human description of a raw value for error messages (never huge)."""
    if isinstance(x, np.ndarray):
        if x.size <= 9:
            return f"{np.array2string(x, precision=6)} (shape {x.shape})"
        return f"an array of shape {x.shape}"
    r = repr(x)
    if len(r) > 80:
        r = r[:77] + "..."
    return f"{r} ({type(x).__name__})"


def _fmt_shape(shape: tuple[int | None, ...]) -> str:
    if len(shape) == 0:
        return "a scalar"
    inner = ", ".join("*" if s is None else str(s) for s in shape)
    if len(shape) == 1:
        inner += ","
    return f"shape ({inner})"


def _is_real_scalar(v: Any) -> bool:
    # bool is an int subclass in Python; a boolean where a number is expected is a mistake.
    return isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_))


def closest(x: str, options: Iterable[str]) -> str | None:
    """The option most similar to ``x`` (difflib), or ``None`` if nothing is close."""
    match = difflib.get_close_matches(x, list(options), n=1, cutoff=0.6)
    if not match:
        # Case slips ("Euler") score low with difflib; compare case-folded as a fallback.
        folded = {o.casefold(): o for o in options}
        match = difflib.get_close_matches(x.casefold(), list(folded), n=1, cutoff=0.6)
        return folded[match[0]] if match else None
    return match[0]


# --------------------------------------------------------------------------------------
# arrays


def finite_array(x: Any, name: str, shape: tuple[int | None, ...] | None = None) -> np.ndarray:
    """Validate a finite numeric array.

    Args:
        x: anything numpy can read as a real numeric array (nested lists, arrays, scalars).
        name: parameter name used in the error message.
        shape: required shape; ``None`` entries are wildcards (any length), ``None`` for the
            whole argument accepts any shape. ``()`` requires a scalar.

    Returns:
        A float64 copy of ``x`` with the requested shape.

    Raises:
        InputError: ``x`` is not numeric (strings, booleans, None, ragged lists, complex),
            has the wrong shape, or contains NaN or +-inf.
    """
    if type(x) is np.ndarray and x.dtype == np.float64:
        # The solver's own arrays, many times per iteration: the same checks in fewer numpy calls
        # (15.6 -> 6 us; the UR5 pose reach made 31 of these per solve). Anything that fails them
        # falls through to the full checks, which name the problem.
        if shape is None or (x.ndim == len(shape) and all(w is None or w == g for w, g in zip(shape, x.shape))):
            if np.isfinite(x).all():
                return x.copy()
    if isinstance(x, (str, bytes)) or x is None:
        raise InputError(name, f"expected a numeric array, got {_describe(x)}")
    try:
        arr = np.asarray(x)
    except (ValueError, TypeError) as exc:  # ragged nested lists
        raise InputError(name, f"expected a numeric array, got {_describe(x)} ({exc})") from None
    if arr.dtype == object:
        # Python ints beyond int64 or mixed containers land here; accept only real numbers.
        flat = arr.ravel()
        if not all(_is_real_scalar(v) for v in flat):
            bad = next(v for v in flat if not _is_real_scalar(v))
            raise InputError(
                name, f"expected a numeric array, got an entry {_describe(bad)} in {_describe(x)}"
            )
        try:
            arr = arr.astype(np.float64)
        except (OverflowError, ValueError, TypeError) as exc:
            raise InputError(name, f"expected a numeric array, got {_describe(x)} ({exc})") from None
    elif arr.dtype.kind not in "iuf":
        kind = {"b": "booleans", "c": "complex numbers", "U": "strings", "S": "bytes"}.get(
            arr.dtype.kind, f"dtype {arr.dtype}"
        )
        raise InputError(name, f"expected real numbers, got {kind}: {_describe(x)}")
    out = np.array(arr, dtype=np.float64, copy=True)
    if shape is not None:
        ok = out.ndim == len(shape) and all(
            want is None or want == got for want, got in zip(shape, out.shape)
        )
        if not ok:
            raise InputError(name, f"expected {_fmt_shape(shape)}, got shape {out.shape}")
    if not np.all(np.isfinite(out)):
        idx = tuple(int(i) for i in np.argwhere(~np.isfinite(out))[0])
        where = f" at index {idx}" if idx else ""
        raise InputError(
            name, f"expected finite numbers, got {out[idx] if idx else out.item()}{where}"
        )
    return out


def finite_float(x: Any, name: str) -> float:
    """Validate a finite real scalar and return it as a Python float."""
    if type(x) is float and math.isfinite(x):
        return x  # what the checks below return for it, without numpy (~1 instead of ~12 us)
    if not _is_real_scalar(x) and not (isinstance(x, np.ndarray) and x.ndim == 0):
        raise InputError(name, f"expected a real number, got {_describe(x)}")
    return float(finite_array(x, name, shape=()))


@_quiet
def rotation_matrix(R: Any, name: str, tol: float = 1e-9) -> np.ndarray:
    """Validate a rotation matrix (an element of SO(3)).

    Args:
        R: (3, 3) array.
        name: parameter name used in the error message.
        tol: maximum allowed entry of ``|R^T R - I|``.

    Returns:
        (3, 3) float64 copy of ``R``.

    Raises:
        InputError: wrong shape, non-finite, not orthonormal (``max|R^T R - I| > tol``) or
            orthonormal with determinant -1 (a reflection).
    """
    M = finite_array(R, name, shape=(3, 3))
    err = float(np.max(np.abs(M.T @ M - np.eye(3))))
    if err > tol:
        raise InputError(
            name,
            f"expected an orthonormal 3x3 rotation matrix (max |R^T R - I| <= {tol:g}), "
            f"got max |R^T R - I| = {err:.3g}",
        )
    det = float(np.linalg.det(M))
    # Orthonormal matrices have det = +-1; the sign alone separates rotations from reflections.
    if det < 0.0:
        raise InputError(
            name, f"expected det(R) = +1 (a proper rotation), got det(R) = {det:.6g} (a reflection)"
        )
    return M


@_quiet
def unit_quaternion(q: Any, name: str, tol: float = 1e-9) -> np.ndarray:
    """Validate a unit quaternion in (x, y, z, w) order (Pinocchio's storage order).

    Args:
        q: (4,) array ``[x, y, z, w]``.
        name: parameter name used in the error message.
        tol: maximum allowed ``| ||q|| - 1 |``.

    Returns:
        (4,) float64 copy of ``q`` (not renormalised, so exact input comes out exactly).
    """
    v = finite_array(q, name, shape=(4,))
    norm = float(np.linalg.norm(v))
    if abs(norm - 1.0) > tol:
        raise InputError(
            name, f"expected a unit quaternion (x, y, z, w) with norm 1 +- {tol:g}, got norm {norm:.12g}"
        )
    return v


def quaternion_to_rotation(q: Any, name: str = "quaternion") -> np.ndarray:
    """Convert a unit quaternion (x, y, z, w) to a (3, 3) rotation matrix.

    The quaternion is validated with :func:`unit_quaternion` and then renormalised, so the
    result is orthonormal to machine precision even when ``q`` is only unit to 1e-9.
    """
    v = unit_quaternion(q, name)
    x, y, z, w = v / np.linalg.norm(v)
    # Standard Hamilton formula; identical to pinocchio.Quaternion(w, x, y, z).toRotationMatrix().
    return np.array(
        [
            [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
            [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
            [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
        ]
    )


# --------------------------------------------------------------------------------------
# weights and physical parameters


@_quiet
def spd_matrix(
    S: Any,
    name: str,
    n: int,
    allow_scalar: bool = True,
    allow_vector: bool = True,
    semidefinite: bool = False,
) -> np.ndarray:
    """Validate a symmetric positive (semi)definite weight matrix.

    Args:
        S: a scalar ``s`` (meaning ``s I_n``, if ``allow_scalar``), a length-n vector (meaning
            ``diag(S)``, if ``allow_vector``) or an (n, n) matrix.
        name: parameter name used in the error message.
        n: matrix dimension.
        semidefinite: accept positive semidefinite (eigenvalues >= -1e-12 * max|eig|)
            instead of requiring positive definite (Cholesky succeeds).

    Returns:
        (n, n) float64 symmetric matrix (symmetrised; exact for exactly symmetric input).

    Raises:
        InputError: wrong shape, non-finite, not symmetric (relative tolerance 1e-12),
            not positive (semi)definite.
    """
    forms = []
    if allow_scalar:
        forms.append("a scalar")
    if allow_vector:
        forms.append(f"a length-{n} vector")
    forms.append(f"a {n}x{n} matrix")
    expected_forms = ", ".join(forms[:-1]) + (" or " if len(forms) > 1 else "") + forms[-1]
    A = finite_array(S, name)
    if (A.ndim == 0 and allow_scalar) or (A.ndim == 1 and allow_vector and A.shape == (n,)):
        # s I or diag(S): symmetric, with its entries for eigenvalues, so the checks below reduce
        # to the entries' signs (the same decisions; a refusal's message comes from those checks)
        d = np.full(n, float(A)) if A.ndim == 0 else A
        top = float(np.max(np.abs(d))) if n else 0.0
        low = float(np.min(d)) if n else 0.0
        if top <= MAX_WEIGHT and (low >= -1e-12 * top if semidefinite else low > 0.0):
            return np.diag(d)
    if A.ndim == 0 and allow_scalar:
        M = float(A) * np.eye(n)
    elif A.ndim == 1 and allow_vector and A.shape == (n,):
        M = np.diag(A)
    elif A.shape == (n, n):
        M = A
    else:
        raise InputError(name, f"expected {expected_forms}, got shape {A.shape}")

    scale = float(np.max(np.abs(M))) if M.size else 0.0
    if scale > MAX_WEIGHT:
        # a weight this large overflows the cost and its derivatives (squares of 1e154 are inf)
        raise InputError(name, f"expected entries of magnitude <= {MAX_WEIGHT:.0e}, got {scale:.3g}")
    asym = float(np.max(np.abs(M - M.T)))
    if asym > 1e-12 * scale:
        raise InputError(
            name, f"expected a symmetric matrix, got max |S - S^T| = {asym:.3g} (max |S| = {scale:.3g})"
        )
    M = 0.5 * (M + M.T)
    kind = "positive semidefinite" if semidefinite else "positive definite"
    if semidefinite:
        eig = np.linalg.eigvalsh(M)
        if eig.min() < -1e-12 * max(float(np.max(np.abs(eig))), 0.0):
            raise InputError(name, f"expected a {kind} matrix, got smallest eigenvalue {eig.min():.6g}")
    else:
        try:
            np.linalg.cholesky(M)
        except np.linalg.LinAlgError:
            eig = np.linalg.eigvalsh(M)
            raise InputError(
                name, f"expected a {kind} matrix, got smallest eigenvalue {eig.min():.6g}"
            ) from None
    return M


@_quiet
def inertia_matrix(I: Any, name: str = "inertia") -> np.ndarray:  # noqa: E741
    """Validate a rigid-body inertia tensor in kg m^2.

    Args:
        I: 3 principal moments ``[I1, I2, I3]`` or a (3, 3) matrix.

    Returns:
        (3, 3) float64 symmetric positive definite inertia.

    Raises:
        InputError: not SPD, or the principal moments violate the triangle inequality
            ``I_i <= I_j + I_k`` (relative tolerance 1e-9), which every real mass
            distribution satisfies (equality only for a flat lamina).
    """
    M = spd_matrix(I, name, 3, allow_scalar=False, allow_vector=True)
    moments = np.linalg.eigvalsh(M)
    total = float(np.sum(moments))
    for i in range(3):
        others = total - moments[i]
        if moments[i] > others + 1e-9 * total:
            raise InputError(
                name,
                "expected principal moments satisfying the triangle inequality "
                "I_i <= I_j + I_k (physically realisable body), got principal moments "
                f"{np.array2string(moments, precision=6)} where {moments[i]:.6g} > {others:.6g}",
            )
    return M


@_quiet
def actuation_matrix(Hm: Any, name: str = "actuation") -> np.ndarray:
    """Validate the torque actuation matrix mapping m inputs to body torques.

    Args:
        Hm: (3, m) array with m >= 1; column j is the body-frame torque axis of input j.

    Returns:
        (3, m) float64 copy.

    Raises:
        InputError: wrong shape (including a flat length-3 vector; write ``[[a], [b], [c]]``
            for one input), non-finite, or an all-zero column (an input with no effect makes
            Q_uu singular).
    """
    A = finite_array(Hm, name)
    if A.ndim != 2 or A.shape[0] != 3 or A.shape[1] < 1:
        hint = " (for a single input write [[a], [b], [c]])" if A.shape == (3,) else ""
        raise InputError(name, f"expected shape (3, m) with m >= 1, got shape {A.shape}{hint}")
    norms = np.linalg.norm(A, axis=0)
    zero = np.flatnonzero(norms == 0.0)
    if zero.size:
        raise InputError(name, f"expected every column to be non-zero, got an all-zero column {int(zero[0])}")
    return A


# --------------------------------------------------------------------------------------
# scalars


def bounded_float(
    x: Any,
    name: str,
    low: float | None = None,
    high: float | None = None,
    low_inclusive: bool = True,
    high_inclusive: bool = True,
) -> float:
    """Validate a finite real number in an interval and return it as a Python float."""
    v = finite_float(x, name)
    lo_ok = low is None or (v >= low if low_inclusive else v > low)
    hi_ok = high is None or (v <= high if high_inclusive else v < high)
    if not (lo_ok and hi_ok):
        lb = "-inf" if low is None else f"{low:g}"
        ub = "inf" if high is None else f"{high:g}"
        lbr = "[" if (low is not None and low_inclusive) else "("
        ubr = "]" if (high is not None and high_inclusive) else ")"
        raise InputError(name, f"expected a number in {lbr}{lb}, {ub}{ubr}, got {v!r}")
    return v


def positive_float(x: Any, name: str) -> float:
    """Validate a finite number > 0 and return it as a Python float."""
    v = finite_float(x, name)
    if not v > 0.0:
        raise InputError(name, f"expected a number > 0, got {v!r}")
    return v


def nonnegative_float(x: Any, name: str) -> float:
    """Validate a finite number >= 0 and return it as a Python float."""
    v = finite_float(x, name)
    if not v >= 0.0:
        raise InputError(name, f"expected a number >= 0, got {v!r}")
    return v


def unknown_keyword(key: str, owner: str, known: Iterable[str], listing: str) -> InputError:
    """The InputError for a keyword ``key`` that ``owner`` does not take: the closest of ``known``
    suggested, and ``listing`` (what it does take) in parentheses."""
    hint = closest(key, known)
    return InputError(key, f"unknown keyword of {owner}" + (f"; did you mean {hint!r}?" if hint else "") + f" ({listing})")


def keywords_checked(cls: type) -> type:
    """Class decorator for a dataclass that users build by keywords: a keyword that is none of its
    fields raises an InputError naming it, with the closest field (the generated __init__ raised
    a bare TypeError). Positional arguments, defaults and dataclasses.replace are unchanged."""
    import dataclasses
    import functools

    names = tuple(f.name for f in dataclasses.fields(cls) if f.init)
    init = cls.__init__

    @functools.wraps(init)
    def checked(self: Any, *args: Any, **kw: Any) -> None:
        for key in kw:
            if key not in names:
                raise unknown_keyword(key, cls.__name__, names, f"keywords: {', '.join(names)}")
        init(self, *args, **kw)

    cls.__init__ = checked  # type: ignore[method-assign]
    return cls


def _integer(x: Any, name: str, what: str) -> int:
    # Floats are refused even when integral: a float where a count is expected usually
    # means the wrong field was filled in, and silently truncating would hide it.
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (numbers.Integral, np.integer)):
        raise InputError(name, f"expected {what}, got {_describe(x)}")
    return int(x)


def positive_int(x: Any, name: str) -> int:
    """Validate an integer >= 1 (not a bool, not a float) and return it as a Python int."""
    v = _integer(x, name, "an integer >= 1")
    if v < 1:
        raise InputError(name, f"expected an integer >= 1, got {v}")
    return v


def nonnegative_int(x: Any, name: str) -> int:
    """Validate an integer >= 0 (not a bool, not a float) and return it as a Python int."""
    v = _integer(x, name, "an integer >= 0")
    if v < 0:
        raise InputError(name, f"expected an integer >= 0, got {v}")
    return v


def choice(x: Any, name: str, options: Iterable[str]) -> str:
    """Validate that ``x`` is one of the strings in ``options``.

    The error message lists the options and suggests the closest one (difflib).
    """
    opts = sorted(options)
    listing = " | ".join(opts)
    if not isinstance(x, str):
        raise InputError(name, f"expected one of {listing}, got {_describe(x)}")
    if x not in opts:
        guess = closest(x, opts)
        hint = f"; did you mean {guess!r}?" if guess else ""
        raise InputError(name, f"expected one of {listing}, got {x!r}{hint}")
    return x


def time_grid(tf: Any, dt: Any, *, tf_name: str = "horizon.tf", dt_name: str = "horizon.dt") -> int:
    """Validate the time grid and return the horizon length H (number of control steps).

    Args:
        tf: final time in seconds, > 0.
        dt: time step in seconds, > 0, with ``tf`` an integer multiple of ``dt`` to within
            1e-9 relative (``|tf - H dt| <= 1e-9 tf``).

    Returns:
        H = round(tf / dt) >= 1.
    """
    tf_v = positive_float(tf, tf_name)
    dt_v = positive_float(dt, dt_name)
    ratio = tf_v / dt_v
    if not ratio <= MAX_HORIZON:  # also catches an overflow to inf
        raise InputError(tf_name, f"expected at most {MAX_HORIZON} steps, got tf / dt = {ratio:.3g}")
    H = int(round(ratio))
    if H < 1:
        raise InputError(tf_name, f"expected tf >= {dt_name} = {dt_v!r}, got {tf_v!r}")
    if abs(tf_v - H * dt_v) > 1e-9 * tf_v:
        raise InputError(
            tf_name,
            f"expected an integer multiple of {dt_name} = {dt_v!r} (within 1e-9 relative), "
            f"got {tf_v!r} = {ratio:.9g} steps",
        )
    return H

