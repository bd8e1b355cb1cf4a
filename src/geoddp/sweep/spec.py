"""Sweep files: a base scene and what varies, expanded into cases that are each a full, validated
scene table with a content hash.

A sweep file (TOML)::

    [sweep]
    scene = "satellite_paper"   # a scene file (relative to the sweep file) or a built-in name
    name? = file stem            description? = ""
    seed? = 0                    # random draws: numpy PCG64 seeded with (seed, draw)
    samples? = 1                 # random draws per grid point (cases = grid points x samples)

    [scene]                      # optional: keys set in every case (a partial scene, deep-merged)
    target.euler_intrinsic = [["x", 0.0]]

    [grid]                       # optional: the cartesian product of these lists (last key fastest)
    "target.euler_intrinsic[0][1]" = [10.0, 20.0, 30.0]
    horizon.tf = [2.0, 3.0]

    [[random]]                   # optional, any number: one value per draw, in file order
    key = "target.quaternion"
    distribution = "haar"        # haar (uniform on SO(3); key ends in .quaternion or .rotation)
                                 # | normal (mean, std) | uniform (low, high)
                                 # | integers (low <= n < high: a per-case seed, for example)
                                 # | perturb (around = "base" | a posture name | numbers; std; indices?)

    [postures]                   # optional: named postures for perturb's `around`
    crouch = [0.0, 0.3, -0.6]

    [simulation]                 # optional: each case is solved, then simulated in closed loop
    samples = 20                 # (keys: geoddp.scene.simulation.SimulationSpec)

A key path is the scene's TOML path: ``table.key`` with ``[i]`` for list entries and arrays of
tables (``terminal_costs[0].weight``, ``initial.q[7]``); ``simulation.<key>`` varies the
simulation table. Setting one rotation form of a table (quaternion, rotation, euler_intrinsic,
axis/angle_deg) removes the table's other forms, so a sampled ``target.quaternion`` replaces the
base scene's ``target.euler_intrinsic``.

Random draws use common random numbers: draw d is the same at every grid point, and does not
depend on how many cases run or in which order (each draw has its own generator, seeded with
``(seed, d)``). Haar-uniform rotations are unit quaternions drawn from a normalised 4-D standard
normal, whose law is the Haar measure on SO(3) (Shoemake 1992); the sign is fixed to w >= 0.

Every case is validated by the scene reader before anything runs
(:func:`expand`); a bad key, an empty grid or an impossible distribution raises
:class:`~geoddp.validate.InputError` naming the sweep key path.
"""
from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import validate as v
from ..scene import parse_scene, scene_file
from ..scene.reader import MAX_NESTING, read_toml
from ..validate import InputError

SWEEP_KEYS = {"scene": True, "name": False, "description": False, "seed": False, "samples": False}
TOP_TABLES = ("sweep", "scene", "grid", "random", "postures", "simulation")
DISTRIBUTIONS = {  # distribution -> (required keys, optional keys)
    "haar": ((), ()),
    "normal": (("mean", "std"), ()),
    "uniform": (("low", "high"), ()),
    "integers": (("low", "high"), ()),
    "perturb": (("std",), ("around", "indices")),
}
# A table's rotation forms (the scene reader accepts exactly one per table): setting one drops the others.
ROTATION_FORMS = ("quaternion", "rotation", "euler_intrinsic", "axis", "angle_deg")
_AXIS_ANGLE = ("axis", "angle_deg")
SIMULATION = "simulation"
MAX_CASES = 10_000_000
_TOKEN = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


# ------------------------------------------------------------------ key paths


def parse_key(path: str, where: str) -> tuple[str | int, ...]:
    """``"terminal_costs[0].weight"`` -> ``("terminal_costs", 0, "weight")``; errors name ``where``."""
    if not isinstance(path, str) or not path:
        raise InputError(where, f"expected a key path such as 'horizon.tf', got {path!r}")
    tokens: list[str | int] = []
    pos = 0
    for m in _TOKEN.finditer(path):
        sep = path[pos:m.start()]
        if sep not in ("", ".") or (sep == "." and m.group(1) is None) or (pos == 0 and sep):
            raise InputError(where, f"malformed key path {path!r} (expected table.key, [i] for list entries)")
        tokens.append(m.group(1) if m.group(1) is not None else int(m.group(2)))
        pos = m.end()
    if pos != len(path) or not tokens or not isinstance(tokens[0], str):
        raise InputError(where, f"malformed key path {path!r} (expected table.key, [i] for list entries)")
    if len(tokens) > MAX_NESTING:  # no scene key is this deep; a case built on it would be nested as deep
        raise InputError(where, f"expected a key path of at most {MAX_NESTING} parts, got {len(tokens)}")
    if len(tokens) < 2 and tokens[0] != SIMULATION:
        raise InputError(where, f"expected a key inside a table such as 'horizon.tf', got {path!r}")
    return tuple(tokens)


def get_key(table: Mapping[str, Any], keys: tuple[str | int, ...], where: str) -> Any:
    """The value at ``keys`` in ``table`` (the base scene); errors name ``where``."""
    node: Any = table
    for k in keys:
        try:
            node = node[k]
        except (KeyError, IndexError, TypeError):
            raise InputError(where, f"the base scene has no value at {_fmt(keys)}") from None
    return node


def set_key(table: dict[str, Any], keys: tuple[str | int, ...], value: Any, where: str) -> None:
    """Set ``keys`` to ``value`` in ``table`` in place, creating missing tables (not list entries).

    Setting one rotation form of a table removes that table's other rotation forms."""
    node: Any = table
    for i, k in enumerate(keys[:-1]):
        nxt = keys[i + 1]
        if isinstance(k, int):
            if not isinstance(node, list) or not -len(node) <= k < len(node):
                raise InputError(where, f"{_fmt(keys[:i + 1])}: no list entry {k} in the base scene")
            node = node[k]
        else:
            if not isinstance(node, dict):
                raise InputError(where, f"{_fmt(keys[:i])} is not a table")
            if k not in node:
                if isinstance(nxt, int):
                    raise InputError(where, f"{_fmt(keys[:i + 1])}: no list in the base scene to index")
                node[k] = {}
            node[k] = copy.copy(node[k]) if isinstance(node[k], (dict, list)) else node[k]
            node = node[k]
    last = keys[-1]
    if isinstance(last, int):
        if not isinstance(node, list) or not -len(node) <= last < len(node):
            raise InputError(where, f"{_fmt(keys)}: no list entry {last} in the base scene")
        node[last] = value
        return
    if not isinstance(node, dict):
        raise InputError(where, f"{_fmt(keys[:-1])} is not a table")
    if last in ROTATION_FORMS:
        keep = _AXIS_ANGLE if last in _AXIS_ANGLE else (last,)
        for form in ROTATION_FORMS:
            if form not in keep:
                node.pop(form, None)
    node[last] = value


def _fmt(keys: tuple[str | int, ...]) -> str:
    out = ""
    for k in keys:
        out += f"[{k}]" if isinstance(k, int) else (f".{k}" if out else k)
    return out


def _leaves(table: Mapping[str, Any], prefix: str = "") -> Iterator[tuple[str, Any]]:
    """(dotted path, value) of every non-table value of a nested table."""
    for k, val in table.items():
        path = f"{prefix}.{k}" if prefix else str(k)
        if isinstance(val, Mapping):
            yield from _leaves(val, path)
        else:
            yield path, val


# ------------------------------------------------------------------ sweep file


@dataclass(frozen=True)
class RandomSpec:
    """One ``[[random]]`` entry: ``key`` (parsed key path), its distribution and parameters."""

    where: str  # "random[i]"
    key: str
    keys: tuple[str | int, ...]
    distribution: str
    params: dict[str, Any]

    def draw(self, rng: np.random.Generator, base: Mapping[str, Any], postures: Mapping[str, Any]) -> Any:
        """One value (plain floats / lists) for this entry from ``rng``."""
        p = self.params
        if self.distribution == "haar":
            q = rng.standard_normal(4)
            q /= np.linalg.norm(q)
            q = -q if q[3] < 0 else q  # (x, y, z, w), w >= 0: one of the two equal quaternions
            if self.keys[-1] == "rotation":
                import pinocchio as pin

                return pin.Quaternion(q[3], q[0], q[1], q[2]).toRotationMatrix().tolist()
            return q.tolist()
        if self.distribution == "normal":
            return _plain(p["mean"] + p["std"] * rng.standard_normal(np.shape(p["mean"] + p["std"])))
        if self.distribution == "integers":
            return int(rng.integers(p["low"], p["high"]))
        if self.distribution == "uniform":
            shape = np.shape(p["low"] + p["high"])
            return _plain(p["low"] + (p["high"] - p["low"]) * rng.random(shape))
        # perturb: around + N(0, std) on the chosen entries
        around = np.array(p["around_value"], dtype=float)
        idx = p["indices"] if p["indices"] is not None else list(range(around.size))
        out = around.copy()
        out[idx] += p["std"] * rng.standard_normal(len(idx))
        return _plain(out)


def _plain(x: np.ndarray) -> Any:
    """numpy -> plain float / nested lists of floats (what TOML and JSON hold)."""
    a = np.asarray(x, dtype=float)
    return float(a) if a.ndim == 0 else a.tolist()


@dataclass(frozen=True)
class Case:
    """One case of a sweep: a full scene table (and simulation table), validated, with its hash.

    Attributes:
        index: position in the sweep (0-based; grid points outer, draws inner).
        draw: the random draw number (0 if the sweep has no [[random]] entries).
        params: key path -> value of every varied key (grid values and draws), in file order.
        scene: the full scene table of this case (plain TOML data).
        simulation: the case's [simulation] table, or None for a solve-only case.
        source: the base scene's file (relative paths inside the scene resolve against it).
        hash: sha256 (hex) of the case's full spec: the scene and simulation tables.
    """

    index: int
    draw: int
    params: dict[str, Any]
    scene: dict[str, Any]
    simulation: dict[str, Any] | None
    source: str
    hash: str = field(default="")

    @property
    def kind(self) -> str:
        """"solve" or "simulate" (solve, then simulate the plan in closed loop)."""
        return "solve" if self.simulation is None else "simulate"


def case_hash(scene: Mapping[str, Any], simulation: Mapping[str, Any] | None) -> str:
    """Content hash of a case's full spec: sha256 of its canonical JSON (sorted keys; floats in
    shortest round-trip form, so equal values hash equally and different values differently)."""
    text = json.dumps({"scene": scene, "simulation": simulation}, sort_keys=True, separators=(",", ":"),
                      allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()


@dataclass(frozen=True)
class Sweep:
    """A parsed sweep file: the base scene table and what varies (:func:`load_sweep`).

    Iterate cases with :meth:`cases` (validated lazily) or :func:`expand` (all validated first).
    """

    name: str
    description: str
    source: str
    scene_source: str
    base: dict[str, Any]
    grid: dict[str, list[Any]]
    grid_keys: dict[str, tuple[str | int, ...]]
    random: tuple[RandomSpec, ...]
    seed: int
    samples: int
    simulation: dict[str, Any] | None

    @property
    def n_grid(self) -> int:
        return math.prod(len(vals) for vals in self.grid.values())

    def __len__(self) -> int:
        return self.n_grid * self.samples

    def cases(self) -> Iterator[Case]:
        """Every case in order, unvalidated (:func:`expand` validates)."""
        draws = [self._draw(d) for d in range(self.samples)] if self.random else [{}] * self.samples
        index = 0
        for point in itertools.product(*self.grid.values()):
            for d, drawn in enumerate(draws):
                params = dict(zip(self.grid, point))
                params.update(drawn)
                scene = copy.deepcopy(self.base)
                simulation = copy.deepcopy(self.simulation)
                for key, value in params.items():
                    keys = self.grid_keys[key] if key in self.grid_keys else _random_keys(self.random, key)
                    where = f"[grid].{key}" if key in self.grid_keys else _random_where(self.random, key)
                    if keys[0] == SIMULATION:
                        if simulation is None:
                            simulation = {}
                        if len(keys) == 1:
                            raise InputError(where, "expected a key inside [simulation], e.g. simulation.samples")
                        set_key(simulation, keys[1:], value, where)
                    else:
                        set_key(scene, keys, value, where)
                yield Case(index, d, params, scene, simulation, self.scene_source, case_hash(scene, simulation))
                index += 1

    def _draw(self, d: int) -> dict[str, Any]:
        rng = np.random.default_rng([self.seed, d])
        return {r.key: r.draw(rng, self.base, {}) for r in self.random}


def _random_keys(random: tuple[RandomSpec, ...], key: str) -> tuple[str | int, ...]:
    return next(r.keys for r in random if r.key == key)


def _random_where(random: tuple[RandomSpec, ...], key: str) -> str:
    return next(f"{r.where}.key" for r in random if r.key == key)


def sweep_dir() -> Path:
    """Folder of the built-in sweep files (package data: geoddp/data/scenes/sweeps, which the
    repository's ``examples/sweeps`` is)."""
    from .. import data

    return data.sweep_dir()


def sweep_names() -> tuple[str, ...]:
    """Names (file stems) of the built-in sweeps."""
    return tuple(sorted(p.stem for p in sweep_dir().glob("*.toml")))


def load_sweep(path: str | Path) -> Sweep:
    """Read a sweep file (see the module docstring), or a built-in sweep by name
    (:func:`sweep_names`: ``"satellite_slew"``, ``"satellite_noise_mc"``, ``"ur5_reach_grid"``), without validating
    the cases.

    Raises:
        InputError: naming the key path (``[sweep].scene``, ``[grid].horizon.tf``,
            ``random[0].std``): unknown keys, an empty grid, an impossible distribution, a base
            scene that does not exist.
    """
    p = Path(path)
    if not p.exists() and p.name == str(path) and p.suffix != ".toml" and (sweep_dir() / f"{p}.toml").is_file():
        p = sweep_dir() / f"{p}.toml"
    src = str(p)
    data = read_toml(p, "sweep file")  # UTF-8, nesting and integer range checked, errors name the file
    try:
        return parse_sweep(data, p.resolve().parent, default_name=p.stem, source=src)
    except InputError as e:
        raise e.with_source(src) from None


def parse_sweep(data: Mapping[str, Any], base_dir: Path, default_name: str = "sweep", source: str = "<dict>"
                ) -> Sweep:
    """:func:`load_sweep` on an already-parsed table; ``base_dir`` resolves a relative ``[sweep].scene``."""
    for key, val in data.items():
        if key not in TOP_TABLES:
            hint = v.closest(key, TOP_TABLES)
            raise InputError(f"[{key}]", "unknown section of a sweep file" + (f"; did you mean [{hint}]?" if hint else "")
                             + f"; allowed: {', '.join(TOP_TABLES)}")
        want = list if key == "random" else Mapping
        if not isinstance(val, want):
            raise InputError(f"[{key}]" if key != "random" else "random",
                             "expected [[random]] tables" if key == "random" else f"expected a table, got {val!r}")
    sweep_t = data.get("sweep")
    if sweep_t is None:
        raise InputError("[sweep]", "missing required section (with scene = a scene file or a built-in name)")
    for key in sweep_t:
        if key not in SWEEP_KEYS:
            hint = v.closest(key, SWEEP_KEYS)
            raise InputError(f"[sweep].{key}", "unknown key" + (f"; did you mean {hint!r}?" if hint else "")
                             + f"; allowed keys: {', '.join(SWEEP_KEYS)}")
    if "scene" not in sweep_t:
        raise InputError("[sweep].scene", "missing required key (a scene file or a built-in scene's name)")
    scene_arg = sweep_t["scene"]
    if not isinstance(scene_arg, str) or not scene_arg:
        raise InputError("[sweep].scene", f"expected a scene file or a built-in scene's name, got {scene_arg!r}")
    rel = base_dir / scene_arg
    try:
        scene_path = rel if rel.is_file() else scene_file(scene_arg)
    except InputError as e:
        raise InputError("[sweep].scene", e.detail) from None
    try:
        base = read_toml(Path(scene_path))
    except InputError as exc:
        raise InputError("[sweep].scene", f"cannot read the scene file: {exc}") from None
    name = sweep_t.get("name", default_name)
    description = sweep_t.get("description", "")
    for key, val in (("name", name), ("description", description)):
        if not isinstance(val, str):
            raise InputError(f"[sweep].{key}", f"expected a string, got {val!r}")
    seed = v.nonnegative_int(sweep_t.get("seed", 0), "[sweep].seed")
    samples = v.positive_int(sweep_t.get("samples", 1), "[sweep].samples")

    simulation = data.get("simulation")
    simulation = copy.deepcopy(dict(simulation)) if simulation is not None else None
    for path, val in _leaves(data.get("scene", {})):
        where = f"[scene].{path}"
        keys = parse_key(path, where)
        if keys[0] == SIMULATION:
            raise InputError(where, "set simulation keys in the [simulation] table")
        set_key(base, keys, copy.deepcopy(val), where)

    grid: dict[str, list[Any]] = {}
    grid_keys: dict[str, tuple[str | int, ...]] = {}
    for path, vals in _leaves(data.get("grid", {})):
        where = f"[grid].{path}"
        keys = parse_key(path, where)
        if not isinstance(vals, list):
            raise InputError(where, f"expected a list of values to sweep, got {vals!r}")
        if not vals:
            raise InputError(where, "empty grid: expected at least one value")
        grid[path] = vals
        grid_keys[path] = keys

    postures = data.get("postures", {})
    for pname, pval in postures.items():
        v.finite_array(pval, f"[postures].{pname}")
    randoms = []
    for i, item in enumerate(data.get("random", [])):
        randoms.append(_parse_random(i, item, base, postures, grid_keys, randoms))
    n = math.prod(len(x) for x in grid.values()) * samples
    if n > MAX_CASES:
        raise InputError("[grid]", f"expected at most {MAX_CASES} cases, got {n}")
    if samples > 1 and not randoms:
        raise InputError("[sweep].samples", f"expected [[random]] entries to draw {samples} samples from "
                         "(without them every sample would be the same case)")
    return Sweep(name, description, source, str(Path(scene_path).resolve()), base, grid, grid_keys,
                 tuple(randoms), seed, samples, simulation)


def _parse_random(i: int, item: Any, base: Mapping[str, Any], postures: Mapping[str, Any],
                  grid_keys: Mapping[str, Any], earlier: list[RandomSpec]) -> RandomSpec:
    where = f"random[{i}]"
    if not isinstance(item, Mapping):
        raise InputError(where, f"expected a table, got {item!r}")
    if "key" not in item:
        raise InputError(f"{where}.key", "missing required key (the scene key path to draw)")
    key = item["key"]
    keys = parse_key(key, f"{where}.key")
    if key in grid_keys or any(r.key == key for r in earlier):
        raise InputError(f"{where}.key", f"{key!r} is already varied by the grid or an earlier [[random]]")
    dist = v.choice(item.get("distribution"), f"{where}.distribution", tuple(DISTRIBUTIONS))
    required, optional = DISTRIBUTIONS[dist]
    allowed = ("key", "distribution") + required + optional
    for k in item:
        if k not in allowed:
            raise InputError(f"{where}.{k}", f"unknown key for distribution {dist!r}; allowed keys: {', '.join(allowed)}")
    for k in required:
        if k not in item:
            raise InputError(f"{where}.{k}", f"missing: distribution {dist!r} needs {' and '.join(required)}")
    params: dict[str, Any] = {}
    if dist == "haar":
        if keys[-1] not in ("quaternion", "rotation"):
            raise InputError(f"{where}.key", f"a Haar-uniform rotation needs a key ending in .quaternion or .rotation, "
                             f"got {key!r}")
    elif dist == "normal":
        params["mean"] = v.finite_array(item["mean"], f"{where}.mean")
        params["std"] = v.finite_array(item["std"], f"{where}.std")
        if np.any(params["std"] < 0):
            raise InputError(f"{where}.std", f"expected a standard deviation >= 0, got {item['std']!r}")
        _broadcast(where, params["mean"], params["std"], "mean", "std")
    elif dist == "uniform":
        params["low"] = v.finite_array(item["low"], f"{where}.low")
        params["high"] = v.finite_array(item["high"], f"{where}.high")
        _broadcast(where, params["low"], params["high"], "low", "high")
        if np.any(params["low"] > params["high"]):
            raise InputError(f"{where}.high", f"expected high >= low, got low = {item['low']!r}, high = {item['high']!r}")
    elif dist == "integers":
        params["low"] = v.nonnegative_int(item["low"], f"{where}.low")
        params["high"] = v.positive_int(item["high"], f"{where}.high")
        if params["high"] <= params["low"]:
            raise InputError(f"{where}.high", f"expected high > low (integers low <= n < high), got low = "
                             f"{item['low']!r}, high = {item['high']!r}")
    else:
        std = v.finite_float(item["std"], f"{where}.std")
        if std < 0:
            raise InputError(f"{where}.std", f"expected a standard deviation >= 0, got {std!r}")
        around = item.get("around", "base")
        if isinstance(around, str):
            if around == "base":
                value = get_key(base, keys, f"{where}.around")
            elif around in postures:
                value = postures[around]
            else:
                raise InputError(f"{where}.around", f"expected 'base', a list of numbers or a posture of [postures] "
                                 f"({', '.join(postures) or 'none defined'}), got {around!r}")
        else:
            value = around
        arr = v.finite_array(value, f"{where}.around")
        if arr.ndim != 1:
            raise InputError(f"{where}.around", f"expected a list of numbers, got {value!r}")
        indices = item.get("indices")
        if indices is not None:
            if (not isinstance(indices, list) or not indices
                    or not all(isinstance(j, int) and not isinstance(j, bool) and 0 <= j < arr.size for j in indices)):
                raise InputError(f"{where}.indices", f"expected a non-empty list of entry numbers in 0..{arr.size - 1}, "
                                 f"got {indices!r}")
        params.update(std=std, around_value=arr.tolist(), indices=indices)
    return RandomSpec(where, key, keys, dist, params)


def _broadcast(where: str, a: np.ndarray, b: np.ndarray, na: str, nb: str) -> None:
    try:
        np.broadcast_shapes(a.shape, b.shape)
    except ValueError:
        raise InputError(f"{where}.{nb}", f"shape {b.shape} does not match {na}'s {a.shape}") from None


# ------------------------------------------------------------------ validation


def validate_case(case: Case, sweep: Sweep) -> Any:
    """The case's scene spec (the scene reader's validation); errors name the sweep key that set
    the offending scene key when there is one, and the case."""
    try:
        spec = parse_scene(case.scene, case.source)
        if case.simulation is not None:
            check_simulation(case.simulation)
        return spec
    except InputError as e:
        where = _culprit(e.parameter, case, sweep)
        params = ", ".join(f"{k} = {_short(val)}" for k, val in case.params.items())
        detail = f"{e.parameter}: {e.detail}" if where != e.parameter else e.detail
        raise InputError(where, f"{detail} (case {case.index}{': ' + params if params else ''})") from None


def check_simulation(table: Mapping[str, Any]) -> None:
    """Validate a [simulation] table with the closed-loop module's own spec (InputError names
    ``simulation.<key>``)."""
    from ..scene.simulation import SimulationSpec

    SimulationSpec.from_dict(dict(table))


def _short(x: Any) -> str:
    s = json.dumps(x)
    return s if len(s) <= 40 else s[:37] + "..."


def _culprit(parameter: str, case: Case, sweep: Sweep) -> str:
    """The sweep key path whose value the scene reader refused, if one matches ``parameter``
    (``[target].quaternion`` or ``[horizon].tf``), else the reader's own key path."""
    norm = parameter.replace("[", "").replace("]", "").strip()
    for key in case.params:
        plain = re.sub(r"\[\d+\]", "", key)
        if key in sweep.grid_keys and (plain == norm or norm.startswith(plain) or plain.startswith(norm + ".")):
            return f"[grid].{key}"
        if key not in sweep.grid_keys and (plain == norm or norm.startswith(plain) or plain.startswith(norm + ".")):
            return _random_where(sweep.random, key)
    return parameter


def _validated(sweep: Sweep) -> Iterator[tuple[Case, Any]]:
    """Every case of ``sweep`` with its scene spec, each validated by the scene reader."""
    for case in sweep.cases():
        yield case, validate_case(case, sweep)


def validate_all(sweep: Sweep, specs: list[Any] | None = None) -> list[str]:
    """Validate every case of ``sweep`` (as :func:`expand`) and return their hashes in case
    order, keeping no case: a runner regenerates the cases from ``sweep.cases()`` as it submits
    them, so a sweep of 10^5 cases holds 10^5 hashes, not 10^5 scene tables (~4 kB each).

    Args:
        specs: if a list, the validated scene specs are appended to it, in case order.
    """
    hashes = []
    for case, spec in _validated(sweep):
        if specs is not None:
            specs.append(spec)
        hashes.append(case.hash)
    return hashes


def expand(sweep: Sweep) -> list[Case]:
    """Every case of ``sweep``, each validated by the scene reader before any runs.

    Raises:
        InputError: the first invalid case, naming the sweep key path and the case.
    """
    return [case for case, _ in _validated(sweep)]
