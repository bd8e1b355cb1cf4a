"""What both scene readers share: the ``[solver]`` table's choices and defaults, and how a
``[model].urdf`` value becomes a file.

:mod:`geoddp.scene` (the satellite reader, and the entry point that dispatches on
``[model].kind``) and :mod:`geoddp.multibody_scene` (the multibody reader) both import this module,
so neither imports the other's internals: the dispatch imports the multibody reader, never the
reverse.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from . import data
from . import validate as v
from .validate import InputError

__all__ = ["EXPANSIONS", "DEFAULT_EXPANSION", "DEFAULT_SWITCH_RATIO", "DEFAULT_TOL", "DEFAULT_GRAD_TOL",
           "DEFAULT_MAX_ITER", "check_urdf"]

# The solver's defaults and expansions have one home, geoddp.solver.options: re-exported here.
from .solver.options import (  # noqa: E402
    DEFAULT_EXPANSION,
    DEFAULT_GRAD_TOL,
    DEFAULT_MAX_ITER,
    DEFAULT_SWITCH_RATIO,
    DEFAULT_TOL,
    EXPANSIONS,
)


def check_urdf(path: Any, name: str, base_dir: Path) -> Path:
    """Resolve a ``[model].urdf`` value to an existing file (absolute path).

    A relative path is taken against ``base_dir`` (the scene file's folder); if no such file
    exists and the value is a bare file name (``"quadrotor.urdf"``), the built-in URDF of that
    name is used (:mod:`geoddp.data`), so a scene names a built-in model the same way from the
    repository, an installed wheel or a copy in any folder. Absolute paths are used as given.
    """
    if not isinstance(path, (str, Path)) or str(path) == "" or "\0" in str(path):
        raise InputError(name, f"expected a file path string, got {path!r}")
    p = Path(path).expanduser()
    if not p.is_absolute():
        p = base_dir / p
    p = p.resolve()
    # Checked now rather than when the model is built, so a typo fails before any work.
    if p.is_file():
        return p
    bare = Path(path).name == str(path)
    builtin = data.builtin_urdf(str(path)) if bare else None
    if builtin is not None:
        return builtin
    hint = ""
    if bare:
        guess = v.closest(str(path), data.urdf_names())
        hint = (f"; did you mean {guess!r}?" if guess else "") + f" built-in URDFs: {', '.join(data.urdf_names())}"
    raise InputError(name, f"expected an existing URDF file, got {str(path)!r} (resolved to {p}, not found){hint}")
