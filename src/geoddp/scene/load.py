"""Loading a scene: a file or a built-in scene's name to a validated spec of its kind
(``[model].kind``: :data:`KINDS`)."""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..validate import InputError
from . import legged, multibody, satellite
from .build import AnySceneSpec
from .reader import read_toml, scene_file

KINDS = {"legged": legged.parse_legged_scene, "multibody": multibody.parse_multibody_scene,
         "satellite": satellite.parse}  # [model].kind -> parser
SCENE_KINDS = tuple(sorted(KINDS))  # absent [model].kind means "satellite"


def load_scene(path: str | Path) -> AnySceneSpec:
    """Read and validate a TOML scene file: a :class:`~geoddp.scene.satellite.SceneSpec`, a
    :class:`~geoddp.scene.multibody.MultibodySceneSpec` if ``[model] kind = "multibody"`` or a
    :class:`~geoddp.scene.legged.LeggedSceneSpec` if ``[model] kind = "legged"``.

    Args:
        path: scene file, or the name of a built-in scene (``"satellite_paper"``,
            ``"quadrotor"``; see :func:`~geoddp.scene.reader.scene_file`). Relative paths inside it
            (``[model].urdf``) are resolved against the file's directory; a bare URDF file
            name not found there is the built-in URDF of that name.

    Raises:
        InputError: the file is missing or unreadable, is not valid TOML (the message gives
            the line and column), or any key is unknown, missing or invalid; ``scene`` for a
            name that is neither a file nor a built-in scene.
    """
    p = scene_file(path)
    return _dispatch(read_toml(p), str(p), base_dir=p.resolve().parent, default_name=p.stem)


def parse_scene(data: Mapping[str, Any], source: str = "<dict>") -> AnySceneSpec:
    """Validate an already-parsed scene (the dict a TOML parser would produce).

    Relative ``[model].urdf`` paths are resolved against the directory of ``source`` if it is
    a file path, else against the current directory.
    """
    if not isinstance(data, Mapping):
        raise InputError("scene", f"expected a table (dict), got {type(data).__name__}", source)
    base = Path(source).resolve().parent if source != "<dict>" else Path.cwd()
    default_name = Path(source).stem if source != "<dict>" else "scene"
    return _dispatch(data, source, base_dir=base, default_name=default_name)


def _dispatch(data: Mapping[str, Any], source: str, base_dir: Path, default_name: str) -> AnySceneSpec:
    """Route to the parser of ``[model].kind``."""
    model = data.get("model")
    kind = model.get("kind", "satellite") if isinstance(model, Mapping) else "satellite"
    if not isinstance(kind, str) or kind not in KINDS:
        raise InputError("[model].kind", f"expected one of {' | '.join(sorted(KINDS))} (default satellite), "
                         f"got {kind!r}", source)
    return KINDS[kind](data, source, base_dir=base_dir, default_name=default_name)
