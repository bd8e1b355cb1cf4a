"""Output files: strict JSON and atomic writes.

* :func:`strict_json` never writes NaN or inf (a non-finite number becomes ``null``), so every
  result file parses with a strict JSON parser; :meth:`geoddp.solver.result.Result.from_dict` reads
  ``null`` back as NaN.
* :func:`write_atomic` writes to a temporary file in the target's folder, flushes it to disk and
  renames it into place (``os.replace`` is atomic on POSIX): a kill at any moment leaves either
  the previous file or the new one, never a partial file.
* :func:`check_outputs` refuses, before a solve, output paths that could not be written or that
  name an input; :func:`output_folder` makes a folder to write into after the same checks.

This module imports only :mod:`geoddp.validate`.
"""
from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from .validate import InputError

__all__ = ["finite_or_none", "strict_json", "write_atomic", "check_outputs", "output_folder"]


def finite_or_none(x: Any) -> Any:
    """``x`` with every non-finite float (at any depth of dicts, lists, tuples) replaced by None."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: finite_or_none(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [finite_or_none(v) for v in x]
    return x


def strict_json(obj: Any, indent: int | None = 1) -> str:
    """JSON text of ``obj`` (plain Python data) without NaN or inf: those become null."""
    return json.dumps(finite_or_none(obj), indent=indent, allow_nan=False)


def write_atomic(path: str | Path, data: str | bytes, encoding: str = "utf-8") -> Path:
    """Write ``data`` to ``path`` atomically (temp file in the same folder + fsync + os.replace).

    The parent folder is created if missing. Returns the path. Raises :class:`InputError` naming
    the path if it cannot be written (the previous file, if any, is left untouched).
    """
    path = Path(path)
    if path.is_dir():  # before any temporary file: os.replace onto a folder fails with an odd message
        raise InputError(str(path), "cannot write here: it is a folder; expected a file path")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except (OSError, ValueError) as exc:
        raise InputError(str(path), f"cannot write here ({exc})") from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data.encode(encoding) if isinstance(data, str) else data)
            f.flush()
            os.fsync(f.fileno())
        if os.path.exists(path):
            os.chmod(tmp, os.stat(path).st_mode & 0o777)
        else:
            os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError):
            raise InputError(str(path), f"cannot write here ({exc})") from None
        raise
    return path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def check_outputs(outputs: dict[str, Any], inputs: Iterable[Any] = (), directories: Iterable[str] = ()) -> None:
    """Refuse unusable output paths before any work is done.

    Args:
        outputs: option name (e.g. ``"--json"``) -> path or None (skipped).
        inputs: paths read by the run (scene file, URDF); an output equal to one is refused.
        directories: option names whose path is a folder to write into (``--plots``).

    Raises:
        InputError naming the option: a path with a NUL byte, equal to an input or to another
        output, a folder where a file is expected, a parent that is a file, or a parent that
        exists but is not writable.
    """
    ins = {}
    for p in inputs:
        if p is not None:
            try:
                ins[os.path.realpath(os.fspath(p))] = p
            except (ValueError, TypeError):
                pass
    seen: dict[str, str] = {}
    dirs = set(directories)
    for name, p in outputs.items():
        if p is None:
            continue
        try:
            text = os.fspath(p)
        except TypeError:
            raise InputError(name, f"expected a path, got {type(p).__name__}") from None
        if "\0" in text or not text:
            raise InputError(name, "expected a path, got an empty path or one with a NUL byte")
        real = os.path.realpath(text)
        if real in ins:
            raise InputError(name, f"{text} is an input of this run ({ins[real]}): refusing to overwrite it")
        if real in seen:
            raise InputError(name, f"{text} is also the path of {seen[real]}")
        seen[real] = name
        path = Path(real)
        folder = path if name in dirs else path.parent
        if name not in dirs and path.is_dir():
            raise InputError(name, f"{text} is a folder, expected a file path")
        # the nearest existing ancestor must be a writable folder (missing folders are created)
        anc = folder
        while not anc.exists() and anc != anc.parent:
            anc = anc.parent
        if not anc.is_dir():
            raise InputError(name, f"cannot write {text}: {anc} is not a folder")
        if not os.access(anc, os.W_OK | os.X_OK):
            raise InputError(name, f"cannot write {text}: {anc} is not writable")
        try:  # root passes os.access everywhere; a probe file tells (e.g. /sys, a read-only mount)
            fd, probe = tempfile.mkstemp(prefix=".geoddp-probe.", dir=anc)
            os.close(fd)
            os.unlink(probe)
        except OSError as exc:
            raise InputError(name, f"cannot write {text}: {anc} is not writable ({exc.strerror})") from None


def output_folder(path: str | Path, name: str = "out_dir") -> Path:
    """The folder ``path`` to write files into, created if missing, after :func:`check_outputs`'
    checks of a folder option (InputError naming ``name``: an existing file there or on the way,
    a folder that is not writable)."""
    check_outputs({name: path}, directories=[name])
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(name, f"cannot make the folder {path} ({exc.strerror or exc})") from None
    return path
