"""Built-in data shipped inside the package: URDF models and scene files.

Layout (package data, installed with the wheel; found through :mod:`importlib.resources`, so the
same lookups work from a source checkout, an editable install and a plain ``pip install .``)::

    geoddp/data/urdf/NAME.urdf                 the built-in models (satellite, spacecraft, ...)
    geoddp/data/scenes/NAME.toml               satellite scenes (satellite_paper, satellite_wheel_limits, ...)
    geoddp/data/scenes/multibody/NAME.toml     the multibody scenes (the three built-in ones and quadrotor_thrust_limits)
    geoddp/data/scenes/hard/NAME.toml          the 13 hard cases
    geoddp/data/scenes/robots/NAME.toml        real robots of example-robot-data by name
                                               (ur5_reach, solo12_reorient, hector_fly)
    geoddp/data/scenes/sweeps/NAME.toml        the built-in sweep files (sweeps, not
                                               scenes: :func:`sweep_dir`)

A built-in scene is named by its file stem (``quadrotor``, ``satellite_paper``,
``tumbling_5rads``); stems are unique across the scene folders. The repository's ``examples/``
is a symlink to the scene folder, so ``examples/satellite_paper.toml`` is the same file.

The data lives here rather than under ``scene/`` because the models below the scene layer use it
too (``models/satellite.py`` builds the satellite from ``satellite.urdf``, the viewer replays it):
this module imports only :mod:`geoddp.validate` and sits on the lowest floor.
"""
from __future__ import annotations

from functools import lru_cache
from importlib import resources
from pathlib import Path

from ..validate import InputError, closest

__all__ = ["urdf_dir", "scene_dir", "sweep_dir", "urdf_path", "builtin_urdf", "urdf_names", "scene_names", "scene_path",
           "builtin_scene"]


@lru_cache(maxsize=1)
def _root() -> Path:
    root = resources.files(__name__)
    # Pinocchio and the TOML reader need real files: geoddp is installed as files, never zipped
    # (its compiled core is a shared library beside the modules), so the traversable is a plain path.
    if not isinstance(root, Path):
        raise RuntimeError(f"geoddp's package data must be installed as files, got {root!r}")
    return root


def urdf_dir() -> Path:
    """Folder of the built-in URDF models."""
    return _root() / "urdf"


def scene_dir() -> Path:
    """Folder of the built-in scene files (``examples/`` in the repository links here)."""
    return _root() / "scenes"


def sweep_dir() -> Path:
    """Folder of the built-in sweep files (``examples/sweeps/`` in the repository); its files
    describe sweeps over scenes and are not scenes themselves."""
    return scene_dir() / "sweeps"


def urdf_names() -> tuple[str, ...]:
    """File names of the built-in URDF models, sorted (``("quadrotor.urdf", ...)``)."""
    return tuple(sorted(p.name for p in urdf_dir().glob("*.urdf")))


def builtin_urdf(name: str) -> Path | None:
    """The built-in URDF called ``name`` (a bare file name such as ``"quadrotor.urdf"``), or None."""
    if not name or Path(name).name != name:
        return None
    p = urdf_dir() / name
    return p if p.is_file() else None


def urdf_path(name: str) -> Path:
    """Absolute path of the built-in URDF ``name`` (``"satellite.urdf"``, or ``"satellite"``).

    Raises:
        FileNotFoundError: no built-in URDF of that name (the message suggests the closest name
            and lists them).
    """
    p = builtin_urdf(name)
    if p is None and isinstance(name, str) and not name.endswith(".urdf"):
        p = builtin_urdf(name + ".urdf")
    if p is None:
        guess = closest(name, urdf_names()) if isinstance(name, str) else None
        hint = f"did you mean {guess!r}? " if guess else ""
        raise FileNotFoundError(f"no built-in URDF {name!r}; {hint}built-in URDFs: {', '.join(urdf_names())}")
    return p


@lru_cache(maxsize=1)
def _scenes() -> dict[str, Path]:
    found: dict[str, Path] = {}
    for p in sorted(scene_dir().rglob("*.toml")):
        if p.parent == sweep_dir():
            continue
        if p.stem in found:  # two files would answer to one name: refuse rather than pick one
            raise RuntimeError(f"built-in scene name {p.stem!r} is taken twice: {found[p.stem]} and {p}")
        found[p.stem] = p
    return found


def scene_names() -> tuple[str, ...]:
    """Names (file stems) of every built-in scene, sorted."""
    return tuple(sorted(_scenes()))


def builtin_scene(name: str) -> Path | None:
    """Path of the built-in scene ``name`` (a file stem such as ``"quadrotor"``), or None."""
    return _scenes().get(name)


def scene_path(name: str, parameter: str = "scene") -> Path:
    """Path of the built-in scene ``name``.

    Raises:
        InputError: naming ``parameter``: no built-in scene of that name (the message suggests the
            closest name and lists them all).
    """
    p = builtin_scene(name) if isinstance(name, str) else None
    if p is None:
        guess = closest(name, scene_names()) if isinstance(name, str) else None
        hint = f"did you mean {guess!r}? " if guess else ""
        raise InputError(parameter, f"expected a built-in scene name or a scene file, got {name!r}; {hint}"
                                    f"built-in scenes: {', '.join(scene_names())}")
    return p
