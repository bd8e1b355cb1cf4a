"""The one scene reader: a TOML file (or a built-in scene's name) to a plain table, and a
:class:`Reader` that walks that table against a schema, naming the key path and the file in every
error and suggesting the closest key (did you mean).

A schema is data: ``{table: {key: required?}}`` for the ``[tables]``, plus the names of the
``[[arrays of tables]]`` and of the required tables. Every scene kind (:mod:`.satellite`,
:mod:`.multibody`) declares its own and reads its values through one :class:`Reader`, so the key
checks, their messages and the value readers shared by the kinds (strings, booleans, weights,
rotations, URDF paths) exist once.
"""
from __future__ import annotations

import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from .. import data
from .. import validate as v
from ..validate import InputError

TOP_KEYS = ("name", "description")
Schema = dict[str, dict[str, bool]]  # [table] -> key -> required?


# ------------------------------------------------------------------ files


def scene_file(scene: str | Path) -> Path:
    """The scene file that ``scene`` names: a path, or a built-in scene's name.

    An existing file always wins. Otherwise a bare name (no folder, no ``.toml``), such as
    ``"quadrotor"`` or ``"satellite_paper"``, is a built-in scene (:func:`geoddp.data.scene_names`);
    anything else is returned as a path for the reader to report.

    Raises:
        InputError: naming ``scene``: a bare name that is neither a file nor a built-in scene (the
            message suggests the closest built-in name and lists them).
    """
    p = Path(scene)
    text = str(scene)
    if p.is_file() or Path(text).name != text or p.suffix == ".toml" or not text:
        return p
    return data.scene_path(text, "scene")


MAX_NESTING = 32  # levels of tables and arrays in a scene or sweep file (the files here use at most 4)
_INT64 = 2**63  # TOML integers are 64-bit signed (TOML 1.0, "Integer")
_UTF16_32_BOMS = (b"\xff\xfe", b"\xfe\xff", b"\x00\x00\xfe\xff")


def read_toml(path: Path, name: str = "scene file") -> dict[str, Any]:
    """The parsed TOML file (UTF-8, a leading byte-order mark allowed), checked by
    :func:`check_tree`. Errors name ``name`` and the file: missing or unreadable, not UTF-8
    (a UTF-16 file said so), malformed (line and column), nested too deep for the parser, an
    integer outside 64 bits."""
    src = str(path)
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise InputError(name, f"expected a readable TOML file, got {src!r} ({exc.strerror or exc})") from None
    if raw.startswith(_UTF16_32_BOMS):
        raise InputError(name, "expected UTF-8 text (TOML files are UTF-8), got a UTF-16 or UTF-32 byte-order mark; "
                         "save the file as UTF-8", src)
    text = ""
    try:
        text = raw.decode("utf-8-sig")  # a UTF-8 byte-order mark (some Windows editors write one) is dropped
        data = tomllib.loads(text)
    except UnicodeDecodeError as exc:
        raise InputError(name, f"expected UTF-8 text, got invalid bytes at offset {exc.start} "
                         f"({raw[exc.start:exc.start + 1]!r}); save the file as UTF-8", src) from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(name, _toml_error_detail(exc, text), src) from None
    except RecursionError:  # tomllib recurses once per nested array or inline table
        raise InputError(name, f"arrays or inline tables nested too deep for the TOML parser (expected at most "
                         f"{MAX_NESTING} levels)", src) from None
    except ValueError as exc:  # int() of a decimal integer beyond Python's 4300-digit limit
        raise InputError(name, f"malformed TOML ({str(exc).split(';')[0]}); TOML integers are 64-bit", src) from None
    check_tree(data, name, src)
    return data


def check_tree(data: Mapping[str, Any], name: str, source: str | None = None) -> None:
    """Refuse, naming ``name``, the key path and ``source``: tables and arrays nested more than
    :data:`MAX_NESTING` levels deep (every later step walks the tree: hashing, copying, messages)
    and integers outside the 64-bit range of TOML (a hexadecimal literal of any length parses,
    and Python cannot even print a decimal integer of more than 4300 digits). Iterative: a deep
    tree cannot exhaust the stack here."""
    stack: list[tuple[Any, int, str]] = [(data, 1, "")]
    while stack:
        node, depth, path = stack.pop()
        for key, val in (node.items() if isinstance(node, Mapping) else enumerate(node)):
            if isinstance(val, (Mapping, list)):
                where = _join(path, key)
                if depth >= MAX_NESTING:
                    raise InputError(name, f"expected tables and arrays nested at most {MAX_NESTING} levels deep, got "
                                     f"deeper at {where}", source)
                stack.append((val, depth + 1, where))
            elif isinstance(val, int) and not isinstance(val, bool) and not -_INT64 <= val < _INT64:
                raise InputError(name, f"{_join(path, key)}: expected a 64-bit integer (TOML's range, |n| < 2^63), got "
                                 f"one of {val.bit_length()} bits", source)


def _join(path: str, key: Any) -> str:
    return f"{path}[{key}]" if isinstance(key, int) else (f"{path}.{key}" if path else str(key))


def _toml_error_detail(exc: tomllib.TOMLDecodeError, text: str) -> str:
    """Normalise a tomllib error to "malformed TOML at line L, column C: ...; the line reads ..."."""
    msg = str(exc)
    lines = text.splitlines()
    m = re.search(r"\s*\(at line (\d+), column (\d+)\)$", msg)
    if m:
        line, where = int(m.group(1)), f"line {m.group(1)}, column {m.group(2)}"
        msg = msg[: m.start()]
    else:
        # Python 3.11's tomllib reports unterminated constructs only as "at end of document";
        # point at the last non-blank line, which is where such a construct was left open.
        msg = re.sub(r"\s*\(at end of document\)$", "", msg)
        line = max((i + 1 for i, t in enumerate(lines) if t.strip()), default=1)
        where = f"line {line} (end of file)"
    shown = lines[line - 1].strip() if 0 < line <= len(lines) else ""
    tail = f"; the line reads {shown!r}" if shown else ""
    return f"malformed TOML at {where}: {msg}{tail}"


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


# ------------------------------------------------------------------ the reader


class Reader:
    """Walks one parsed scene against its schema; every error is an :class:`InputError` naming the
    key path (``[cost].attitude``, ``running_costs[1].frame``) and the file.

    Args:
        data: the parsed TOML table.
        source: the file path (for messages) or ``"<dict>"``.
        schema: ``{table: {key: required?}}`` of the scene kind.
        arrays: names of its ``[[arrays of tables]]``.
        required: tables that must be present.
    """

    def __init__(self, data: Mapping[str, Any], source: str, schema: Schema, arrays: tuple[str, ...] = (),
                 required: tuple[str, ...] = ()) -> None:
        self.data, self.source, self.schema, self.arrays = data, source, schema, arrays
        self.required = required

    def err(self, param: str, detail: str) -> InputError:
        return InputError(param, detail, self.source)

    def check(self, fn: Any, *args: Any, **kw: Any) -> Any:
        """Run validator ``fn(*args, **kw)``; its error names the file too."""
        try:
            return fn(*args, **kw)
        except InputError as e:
            raise e.with_source(self.source) from None

    # ---------------------------------------------------------------- keys
    def top(self) -> None:
        """Check the top level: known keys, tables that are tables, required tables present."""
        for key, val in self.data.items():
            if key in self.schema:
                if not isinstance(val, Mapping):
                    raise self.err(f"[{key}]", f"expected a table, got {type(val).__name__} {val!r}")
            elif key not in TOP_KEYS and key not in self.arrays:
                if isinstance(val, Mapping):
                    guess = v.closest(key, list(self.schema))
                    hint = f"did you mean [{guess}]? " if guess else ""
                    raise self.err(f"[{key}]", f"unknown section; {hint}allowed sections: {', '.join(self.schema)}")
                allowed = list(TOP_KEYS) + [f"[{s}]" for s in self.schema] + [f"[[{a}]]" for a in self.arrays]
                raise self.unknown_key(key, allowed, key, "the top level")
        for s in self.required:
            if s not in self.data:
                raise self.err(f"[{s}]", "missing required section")

    def unknown_key(self, key: str, allowed: list[str], path: str, where: str, context: str = "") -> InputError:
        """``path: unknown key in <where>; did you mean ...? allowed keys: ...``; a key that belongs to
        another table points there."""
        guess = v.closest(key, allowed)
        if guess:
            hint = f"did you mean {guess!r}? "
        else:
            homes = [f"[{s}].{key}" for s, keys in self.schema.items() if key in keys and f"[{s}]" != where]
            hint = f"did you mean {' or '.join(homes)}? " if homes else ""
        return self.err(path, f"unknown key in {where}{context}; {hint}allowed keys: {', '.join(allowed)}")

    def keys(self, table: Mapping[str, Any], allowed: tuple[str, ...] | list[str], path: str, context: str = "") -> None:
        """Every key of ``table`` (at ``path``) is one of ``allowed``."""
        for key in table:
            if key not in allowed:
                raise self.unknown_key(key, list(allowed), f"{path}.{key}", path, context)

    def table(self, name: str) -> dict[str, Any]:
        """The schema's table ``[name]`` (empty if absent), its keys checked and required keys present."""
        table = self.data.get(name, {})
        if not isinstance(table, Mapping):
            raise self.err(f"[{name}]", f"expected a table, got {type(table).__name__} {table!r}")
        spec = self.schema[name]
        self.keys(table, list(spec), f"[{name}]")
        for key, required in spec.items():
            if required and key not in table:
                raise self.err(f"[{name}].{key}", "missing required key")
        return dict(table)

    def array(self, name: str) -> list[tuple[str, Mapping[str, Any]]]:
        """The ``[[name]]`` array of tables as (key path, table) pairs."""
        items = self.data.get(name, [])
        if not isinstance(items, list):
            raise self.err(name, f"expected an array of tables ([[{name}]] headers), got {type(items).__name__}")
        for i, item in enumerate(items):
            if not isinstance(item, Mapping):
                raise self.err(f"{name}[{i}]", f"expected a table, got {item!r}")
        return [(f"{name}[{i}]", item) for i, item in enumerate(items)]

    # ---------------------------------------------------------------- values
    def string(self, val: Any, path: str) -> str:
        if not isinstance(val, str):
            raise self.err(path, f"expected a string, got {val!r} ({type(val).__name__})")
        return val

    def boolean(self, val: Any, path: str) -> bool:
        if not isinstance(val, bool):
            raise self.err(path, f"expected true or false, got {val!r} ({type(val).__name__})")
        return val

    def weight(self, val: Any, path: str, n: int, semidefinite: bool = True) -> np.ndarray:
        """(n, n) weight from a scalar, n numbers (diagonal) or an n x n matrix; PSD (or SPD)."""
        return self.check(v.spd_matrix, val, path, n, semidefinite=semidefinite)

    def rotation(self, table: Mapping[str, Any], path: str, forms: tuple[str, ...], required: bool = True
                 ) -> np.ndarray | None:
        """(3, 3) rotation from exactly one of ``forms`` in ``table`` (at ``path``): quaternion
        (x, y, z, w), rotation (3x3), euler_intrinsic ([axis, degrees] pairs), rpy_deg (roll,
        pitch, yaw in degrees: Rz(yaw) Ry(pitch) Rx(roll), Pinocchio's rpyToMatrix), axis +
        angle_deg; None if none is given and not ``required``."""
        given = [f for f in forms if f in table]
        if "axis" in forms and "angle_deg" in table and "axis" not in table:
            raise self.err(f"{path}.angle_deg", "expected together with axis (a rotation of angle_deg about axis)")
        if len(given) > 1 or (required and not given):
            listing = " | ".join(f if f != "axis" else "axis + angle_deg" for f in forms)
            got = "none" if not given else " and ".join(given)
            raise self.err(path, f"expected exactly one rotation form (exactly one of {listing}), got {got}")
        if not given:
            return None
        form = given[0]
        val = table[form]
        if form == "quaternion":
            return self.check(v.quaternion_to_rotation, val, f"{path}.quaternion")
        if form == "rotation":
            return self.check(v.rotation_matrix, val, f"{path}.rotation")
        if form == "euler_intrinsic":
            return self.euler(val, f"{path}.euler_intrinsic")
        if form == "rpy_deg":
            rpy = self.check(v.finite_array, val, f"{path}.rpy_deg", (3,))
            return pin.rpy.rpyToMatrix(np.radians(rpy))
        axis = self.check(v.finite_array, val, f"{path}.axis", (3,))
        norm = float(np.linalg.norm(axis))
        if norm == 0.0:
            raise self.err(f"{path}.axis", "expected a non-zero rotation axis, got [0, 0, 0]")
        if "angle_deg" not in table:
            raise self.err(f"{path}.angle_deg", "missing: axis needs angle_deg (degrees)")
        angle = self.check(v.finite_float, table["angle_deg"], f"{path}.angle_deg")
        return pin.exp3(np.radians(angle) * (axis / norm))

    def euler(self, val: Any, path: str) -> np.ndarray:
        """Intrinsic rotations ``[[axis, degrees], ...]``: R = Rot_a1(t1) Rot_a2(t2) ..."""
        example = 'a list of [axis, degrees] pairs such as [["x", 30.0], ["z", 70.0]]'
        if not isinstance(val, list) or not val:
            raise self.err(path, f"expected {example}, got {val!r}")
        R = np.eye(3)
        for i, item in enumerate(val):
            ipath = f"{path}[{i}]"
            if not isinstance(item, list) or len(item) != 2:
                raise self.err(ipath, f"expected an [axis, degrees] pair, got {item!r}")
            axis, deg = item
            if isinstance(axis, str):
                axis = axis.lower()  # "X" and "x" name the same body axis here
            axis = self.check(v.choice, axis, f"{ipath} axis", ("x", "y", "z"))
            angle = np.deg2rad(self.check(v.finite_float, deg, f"{ipath} angle (degrees)"))
            # Intrinsic composition: each rotation is about the already-rotated body axis,
            # which is right-multiplication.
            R = R @ _axis_rotation(axis, angle)
        return R


def _axis_rotation(axis: str, angle: float) -> np.ndarray:
    """Elementary rotation (3, 3) by ``angle`` radians about body axis "x" | "y" | "z"."""
    c, s = np.cos(angle), np.sin(angle)
    if axis == "x":
        return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    if axis == "y":
        return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
