"""Layering: every module under src/geoddp imports only from its own floor or below, and no set of
modules imports itself round in a circle. The floors are those of the design page, docs/design.md.

The imports are read from the source with :mod:`ast` (nothing is imported), *every* import counts:
module level, inside functions (lazy), under ``if TYPE_CHECKING:``, and
``importlib.import_module("geoddp...")`` with a literal name. A relative ``from . import x`` is an
edge to the module ``x`` if there is one, else to the package itself.

FLOORS places every module: a key is a module or a package (a package places everything under it;
the root package ``geoddp`` is a key for its ``__init__`` only). A module that no key places fails
the test, so a new module must be given a floor here. Same-floor imports are allowed; the circle
check keeps them one-way.

The floors follow docs/design.md ("Floors"), mapped onto today's module names. Where the code
taught otherwise:

* ``data`` (the built-in URDFs and scenes) is on floor 0, not under ``scene/``: the models read
  ``satellite.urdf`` from it.
* ``output_files`` (strict JSON, atomic writes) is on floor 0, not in ``cli/``: the Result, the
  viewers and the sweep runner write files too. ``interrupts`` (the signals the CLI received, for
  long loops to raise again) is on floor 0 for the same reason: the sweep runner checks it.
* ``problem.limits`` sits with the problem (floor 2): the problem resolves them, the solver and the
  scene readers use the box arithmetic.
* ``models.integrators``, ``models.variational`` and ``models.urdf`` are on floor 1 with the
  models that use them (the expansion layout, the implicit step's error, the URDF checks).
* ``solver.result`` is on floor 3, inside the solver that builds it; ``solver.reference`` (scipy's
  L-BFGS on the same problem) is a second solver, floor 3 too.
* ``scene.solve`` (solve_scene) and ``scene.simulation`` (the ``[simulation]`` table's values)
  are on floor 4, with the scene readers: simulate/ and sweep/ (floor 5) call them.
* The root package's ``__init__`` is the public facade, floor 6: nothing inside imports it.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"

FLOORS: dict[str, int] = {
    # 0: leaves: input checks, files, signals, the compiled kernels, package data
    "geoddp.validate": 0,
    "geoddp.output_files": 0,  # strict JSON, atomic writes, output-path checks; imports only validate
    "geoddp.interrupts": 0,  # signals the CLI received, for loops to raise again; imports nothing
    "geoddp.kernels": 0,
    "geoddp._core": 0,
    "geoddp.data": 0,
    # 1: Lie groups; models (satellite, multibody, compiled backend, actuation, robots, URDF checks,
    #    integrators, the variational step)
    "geoddp.lie": 1,
    "geoddp.models": 1,
    # 2: costs; the problem, its limits and the contract between a problem and the solver
    "geoddp.costs": 2,
    "geoddp.problem": 2,
    # 3: the solver (loop, policy, callbacks, passes, options, status), its result, the reference solver
    "geoddp.solver": 3,
    "geoddp.constraints": 3,  # constraint kinds, the augmented Lagrangian and its outer loop around the solver
    # 4: scenes: readers, builders, built-in scenes, the [simulation] table, solve_scene
    "geoddp.scene": 4,
    # 5: what reads Results: viewers and figures, closed-loop simulation, sweeps
    "geoddp.viz": 5,
    "geoddp.simulate": 5,
    "geoddp.sweep": 5,
    # 6: the command line and the package's public facade
    "geoddp.cli": 6,
    "geoddp": 6,
}

ROOT_PACKAGE = "geoddp"


# ------------------------------------------------------------------ reading the imports


def discover(src: Path = SRC, package: str = ROOT_PACKAGE) -> dict[str, tuple[Path | None, bool]]:
    """Module name -> (source path or None for a compiled module, is a package)."""
    out: dict[str, tuple[Path | None, bool]] = {}
    for p in sorted((src / package).rglob("*")):
        rel = p.relative_to(src)
        if p.suffix == ".py":
            if p.name == "__init__.py":
                out[".".join(rel.parent.parts)] = (p, True)
            else:
                out[".".join(rel.with_suffix("").parts)] = (p, False)
        elif p.suffix in (".so", ".pyd"):  # a compiled extension: geoddp/_core.cpython-311-....so
            out[".".join(rel.parent.parts + (p.name.split(".", 1)[0],))] = (None, False)
    return out


def _nearest(name: str, known: set[str]) -> str | None:
    """``name`` or its closest enclosing known module (``geoddp.viz.scene.X`` -> ``geoddp.viz.scene``)."""
    parts = name.split(".")
    while parts:
        candidate = ".".join(parts)
        if candidate in known or candidate in FLOORS:
            return candidate
        parts.pop()
    return None


def imports_of(source: str, module: str, is_package: bool, known: set[str]) -> set[str]:
    """The geoddp modules that ``source`` (the text of ``module``) imports, anywhere in the file."""
    package = module if is_package else module.rpartition(".")[0]
    found: set[str] = set()

    def add(name: str) -> None:
        if name == ROOT_PACKAGE or name.startswith(ROOT_PACKAGE + "."):
            target = _nearest(name, known)
            if target is not None and target != module:
                found.add(target)

    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if not (mod == ROOT_PACKAGE or mod.startswith(ROOT_PACKAGE + ".")):
                continue
            for alias in node.names:
                sub = f"{mod}.{alias.name}"
                # `from . import x`: an edge to the module x if there is one, else to the package.
                add(sub if sub in known or sub in FLOORS else mod)
        elif isinstance(node, ast.Call):
            fn = node.func
            name = fn.attr if isinstance(fn, ast.Attribute) else fn.id if isinstance(fn, ast.Name) else ""
            if name in ("import_module", "__import__") and node.args and isinstance(node.args[0], ast.Constant) \
                    and isinstance(node.args[0].value, str):
                add(node.args[0].value)
    return found


def import_graph(src: Path = SRC) -> dict[str, set[str]]:
    """Module -> the geoddp modules it imports (every module under ``src/geoddp``)."""
    mods = discover(src)
    known = set(mods)
    return {m: (imports_of(path.read_text(encoding="utf-8"), m, is_pkg, known) if path else set())
            for m, (path, is_pkg) in mods.items()}


# ------------------------------------------------------------------ the checks


def floor_of(module: str, floors: dict[str, int]) -> int | None:
    """The floor of ``module``: its own key, else its innermost placed package (not the root)."""
    if module in floors:
        return floors[module]
    parts = module.split(".")
    for n in range(len(parts) - 1, 1, -1):  # stop before the root package: it places only itself
        key = ".".join(parts[:n])
        if key in floors:
            return floors[key]
    return None


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Every strongly connected component with more than one module (Tarjan), as a closed path."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(_cycle_path(sorted(comp), graph))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def _cycle_path(comp: list[str], graph: dict[str, set[str]]) -> list[str]:
    """A readable closed path a -> ... -> a through one component (breadth-first from its first module)."""
    start, members = comp[0], set(comp)
    prev: dict[str, str] = {}
    frontier = [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in sorted(graph.get(v, ()) & members):
                if w == start:
                    path = [v]
                    while path[-1] != start:
                        path.append(prev[path[-1]])
                    return path[::-1] + [start]
                if w not in prev:
                    prev[w] = v
                    nxt.append(w)
        frontier = nxt
    return comp + [start]


def problems(graph: dict[str, set[str]], floors: dict[str, int]) -> list[str]:
    """Unplaced modules, upward imports and circles, one message each (empty: the layering holds)."""
    out = []
    for m in sorted(set(graph) | {t for ts in graph.values() for t in ts}):
        if floor_of(m, floors) is None:
            out.append(f"{m}: not placed on a floor (add it to FLOORS in tests/test_layering.py)")
    for m in sorted(graph):
        fm = floor_of(m, floors)
        for t in sorted(graph[m]):
            ft = floor_of(t, floors)
            if fm is not None and ft is not None and ft > fm:
                out.append(f"upward import: {m} (floor {fm}) imports {t} (floor {ft})")
    for path in circles(graph):
        out.append("import circle: " + " -> ".join(path))
    return out


# ------------------------------------------------------------------ the layering of geoddp


def test_every_module_is_read():
    """The scan sees the package (so an empty graph cannot pass) and the imports it should."""
    graph = import_graph()
    assert {"geoddp.cli", "geoddp.scene", "geoddp.scene.reader", "geoddp.scene.builtin", "geoddp.viz.scene",
            "geoddp.validate", "geoddp.data"} <= set(graph)
    assert "geoddp.models.multibody" in graph["geoddp.scene.multibody"]  # lazy, inside functions
    assert "geoddp.scene.reader" in graph["geoddp.scene.multibody"]
    assert "geoddp.validate" in graph["geoddp.data"]
    assert "geoddp.viz" in graph["geoddp.cli.commands"]            # `from .. import viz`, lazy
    assert "geoddp.models.multibody" in graph["geoddp.viz.model"]  # `from ..models.multibody import`


def test_no_upward_imports_no_circles_and_every_module_placed():
    found = problems(import_graph(), FLOORS)
    assert not found, "\n".join(found)


def test_the_table_names_no_ghosts():
    """Every key of FLOORS is a module or package that exists (or the compiled core)."""
    mods = set(discover())
    ghosts = [k for k in FLOORS if k not in mods and not any(m.startswith(k + ".") for m in mods)
              and k != "geoddp._core"]
    assert not ghosts, ghosts


# ------------------------------------------------------------------ the test can fail


def test_a_circle_is_caught():
    graph = {"p.a": {"p.b"}, "p.b": {"p.c"}, "p.c": {"p.a"}, "p.d": {"p.a"}}
    floors = {"p.a": 1, "p.b": 1, "p.c": 1, "p.d": 2}
    found = problems(graph, floors)
    assert found == ["import circle: p.a -> p.b -> p.c -> p.a"], found


def test_an_upward_import_is_caught():
    graph = {"p.low": {"p.high"}, "p.high": set()}
    found = problems(graph, {"p.low": 0, "p.high": 3})
    assert found == ["upward import: p.low (floor 0) imports p.high (floor 3)"], found


def test_an_unplaced_module_is_caught():
    graph = {"geoddp.new_thing": {"geoddp.validate"}, "geoddp.validate": set()}
    found = problems(graph, FLOORS)
    assert found == ["geoddp.new_thing: not placed on a floor (add it to FLOORS in tests/test_layering.py)"], found


def test_a_package_places_its_modules_but_the_root_places_only_itself():
    assert floor_of("geoddp.viz.html", FLOORS) == 5 and floor_of("geoddp.solver.loop", FLOORS) == 3
    assert floor_of("geoddp", FLOORS) == 6 and floor_of("geoddp.unknown", FLOORS) is None


@pytest.mark.parametrize("code,expected", [
    ("def f():\n    from .scene import load_scene\n", {"geoddp.scene"}),                      # lazy
    ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .cli import main\n", {"geoddp.cli"}),
    ("from . import viz, scene\n", {"geoddp.viz", "geoddp.scene"}),                                # submodules
    ("from . import __version__\n", {"geoddp"}),                                                # the package
    ("import geoddp.viz.scene as s\n", {"geoddp.viz.scene"}),
    ("from ..result import Result\n", set()),                                                   # too far up
    ("import importlib\nm = importlib.import_module('geoddp.cli')\n", {"geoddp.cli"}),
    ("import numpy as np\nfrom pinocchio import SE3\n", set()),                                 # not ours
])
def test_the_reader_sees_every_kind_of_import(code, expected):
    known = {"geoddp", "geoddp.scene", "geoddp.viz", "geoddp.viz.scene", "geoddp.validate",
             "geoddp.cli", "geoddp.solver.result"}
    assert imports_of(code, "geoddp.validate", False, known) == expected


def test_a_synthetic_source_tree_with_a_lazy_circle_fails(tmp_path):
    """End to end on files: a circle closed only by a function-level import is still a circle."""
    pkg = tmp_path / "geoddp"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "viz.py").write_text("def build():\n    from .sweep import parse\n")
    (pkg / "sweep.py").write_text("from .viz import build\n")
    (pkg / "validate.py").write_text("def f():\n    from . import viz\n")
    found = problems(import_graph(tmp_path), FLOORS)
    assert found == ["upward import: geoddp.validate (floor 0) imports geoddp.viz (floor 5)",
                     "import circle: geoddp.sweep -> geoddp.viz -> geoddp.sweep"], found



# ------------------------------------------------------------------ the compiled core's layers (cpp/)
# The same rule for the C++ sources: every file sits in a layer folder of cpp/, and a file includes
# (#include "folder/file") only files of its own folder or of a lower layer; no set of files
# includes itself round in a circle. Includes are written from the cpp/ root (the include path the
# build gives), so each one names its folder. cpp/README.md describes the layers.

CPP = Path(__file__).resolve().parents[1] / "cpp"

LAYERS: dict[str, int] = {
    "runtime": 0,     # arrays, the worker pool, the node split, recycled buffers
    "linalg": 1,      # the Riccati products (small_gemm) and Cholesky
    "lie": 1,         # SO(3)/SE(3) right Jacobians, joint groups, block-diagonal joint operators
    "rigid_body": 2,  # Pinocchio-level: the wheel's algorithms, one-body tensors, kinetic and RNEA Hessians
    "costs": 2,       # cost terms over N nodes
    "tso3": 2,        # the satellite's closed forms
    "dynamics": 3,    # the integrators, rollouts, expansions, the factored second order
    "riccati": 4,     # the backward passes (dense, box, contracted) and the regularisation ladder
    "bindings": 5,    # the Python module: argument checks and bind_* per area
}

_INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"', re.MULTILINE)
_SYSTEM_INCLUDE = re.compile(r"^\s*#\s*include\s*<([^>]+)>", re.MULTILINE)


def cpp_sources(root: Path = CPP) -> list[str]:
    """Every C++ source under ``root``, as a path relative to it (``dynamics/euler.cpp``)."""
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*") if p.suffix in (".cpp", ".hpp"))


def cpp_include_graph(root: Path = CPP) -> tuple[dict[str, set[str]], list[str]]:
    """File -> the files it includes with quotes; and the quoted includes that name no file of ``root``."""
    graph: dict[str, set[str]] = {}
    unresolved = []
    for rel in cpp_sources(root):
        graph[rel] = set()
        for name in _INCLUDE.findall((root / rel).read_text(encoding="utf-8")):
            if (root / name).is_file():
                graph[rel].add(name)
            else:
                unresolved.append(f'{rel}: #include "{name}" is not a file of cpp/ (write it from the cpp/ root)')
    return graph, unresolved


def layer_of(rel: str, layers: dict[str, int]) -> int | None:
    """The layer of a file: its top folder's (None at the root or in an unknown folder)."""
    folder, sep, _ = rel.partition("/")
    return layers.get(folder) if sep else None


def cpp_problems(graph: dict[str, set[str]], layers: dict[str, int]) -> list[str]:
    """Unplaced files, includes of a higher or another same-layer folder, and circles (empty: it holds)."""
    out = []
    for f in sorted(graph):
        if layer_of(f, layers) is None:
            out.append(f"{f}: not in a layer folder (add its folder to LAYERS in tests/test_layering.py)")
    for f in sorted(graph):
        lf = layer_of(f, layers)
        for t in sorted(graph[f]):
            lt = layer_of(t, layers)
            if lf is None or lt is None or f.partition("/")[0] == t.partition("/")[0]:
                continue
            if lt > lf:
                out.append(f"upward include: {f} (layer {lf}) includes {t} (layer {lt})")
            elif lt == lf:
                out.append(f"sideways include: {f} includes {t}, another folder of layer {lf}")
    for path in circles(graph):
        out.append("include circle: " + " -> ".join(path))
    return out


def test_the_cpp_tree_is_read():
    """The scan sees the sources (an empty graph cannot pass) and the includes it should."""
    graph, _ = cpp_include_graph()
    assert {"bindings/module.cpp", "dynamics/euler.cpp", "lie/joint_blocks.hpp", "riccati/contracted.cpp"} <= set(graph)
    assert "dynamics/second_order_terms.hpp" in graph["riccati/contracted.hpp"]
    assert "lie/joint_groups.hpp" in graph["lie/joint_blocks.hpp"]
    assert "dynamics/euler.cpp" in graph["dynamics/core_algorithms.cpp"]  # the unity files' .cpp includes
    assert "dynamics/contact_second.cpp" in graph["dynamics/contact_algorithms.cpp"]


def test_no_upward_include_no_circle_every_file_in_a_layer():
    graph, unresolved = cpp_include_graph()
    found = unresolved + cpp_problems(graph, LAYERS)
    assert not found, "\n".join(found)


def test_every_cpp_folder_has_a_layer_and_the_table_names_no_ghosts():
    folders = {p.name for p in CPP.iterdir() if p.is_dir()}
    assert folders == set(LAYERS), (sorted(folders - set(LAYERS)), sorted(set(LAYERS) - folders))


def test_only_the_bindings_include_python_and_the_avx2_build_includes_no_eigen():
    """pybind11 and Python headers only in bindings/ (the kernels stay callable without Python); the
    AVX2/FMA build of the products (compiled with -mavx2 -mfma) includes no Eigen or Pinocchio header,
    whose inline functions would otherwise be compiled twice with different instruction sets."""
    found = []
    for rel in cpp_sources():
        system = _SYSTEM_INCLUDE.findall((CPP / rel).read_text(encoding="utf-8"))
        if not rel.startswith("bindings/") and any(s.startswith(("pybind11/", "Python.h", "boost/python")) for s in system):
            found.append(f"{rel} includes Python headers")
    for rel in ("linalg/small_gemm_avx2.cpp", "linalg/small_gemm_impl.hpp"):
        text = (CPP / rel).read_text(encoding="utf-8")
        if any(s.startswith(("Eigen", "pinocchio")) for s in _SYSTEM_INCLUDE.findall(text)) or _INCLUDE.findall(text) != (
                ["linalg/small_gemm_impl.hpp"] if rel.endswith(".cpp") else []):
            found.append(f"{rel} includes more than the kernel")
    assert not found, found


# Pinocchio's algorithms that the pin wheel compiles (PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION) and
# rigid_body/pinocchio_compiled.hpp calls with the library's own template arguments. Called on
# pinocchio:: directly, their arguments deduce to other types (VectorXd for Ref, Blocks, Maps) and
# the algorithm is instantiated again over every joint type: what once made the core's unity file
# take 15 minutes to compile.
_WHEEL_ALGORITHMS = re.compile(
    r"\bpinocchio::(forwardKinematics|computeForwardKinematicsDerivatives|computeJointJacobians|computeAllTerms|"
    r"computeFrameJacobian|updateFramePlacements|getFrameJacobian|getFrameAccelerationDerivatives|"
    r"getFrameVelocityDerivatives|centerOfMass|jacobianCenterOfMass|aba|crba|rnea|computeGeneralizedGravity|"
    r"computeABADerivatives|computeRNEADerivatives|computeGeneralizedGravityDerivatives|integrate|difference|"
    r"dIntegrate|dDifference|ComputeRNEASecondOrderDerivatives)\s*\(")


def test_the_unity_files_call_pinocchio_only_through_the_wheels_instantiations():
    """In the files of the unity files (dynamics/, rigid_body/, lie/), every call of a
    Pinocchio algorithm goes through rigid_body/pinocchio_compiled.hpp (libpin::), and the
    second-order RNEA only through rigid_body/pinocchio_second_order.cpp, its one instantiation."""
    allowed = {"rigid_body/pinocchio_compiled.hpp", "rigid_body/pinocchio_second_order.cpp"}
    found = []
    for rel in cpp_sources():
        if rel.split("/")[0] not in ("dynamics", "rigid_body", "lie") or rel in allowed:
            continue
        code = re.sub(r"//[^\n]*", "", (CPP / rel).read_text(encoding="utf-8"))
        found += [f"{rel}: pinocchio::{m.group(1)}(" for m in _WHEEL_ALGORITHMS.finditer(code)]
    assert not found, found
    assert _WHEEL_ALGORITHMS.search("x = pinocchio::aba(m, d, q, v, tau);")  # the pattern can fail
    assert not _WHEEL_ALGORITHMS.search("x = libpin::aba(m, d, q, v, tau);")


def test_an_upward_or_sideways_cpp_include_and_a_circle_are_caught():
    graph = {"lie/a.hpp": {"dynamics/b.hpp"}, "dynamics/b.hpp": {"dynamics/c.hpp"},
             "dynamics/c.hpp": {"dynamics/b.hpp"}, "linalg/d.hpp": {"lie/a.hpp"}, "e.hpp": set()}
    found = cpp_problems(graph, LAYERS)
    assert found == ["e.hpp: not in a layer folder (add its folder to LAYERS in tests/test_layering.py)",
                     "upward include: lie/a.hpp (layer 1) includes dynamics/b.hpp (layer 3)",
                     "sideways include: linalg/d.hpp includes lie/a.hpp, another folder of layer 1",
                     "include circle: dynamics/b.hpp -> dynamics/c.hpp -> dynamics/b.hpp"], found


def test_the_cpp_reader_on_files(tmp_path):
    """End to end on files: quoted includes from the root count, system includes and comments do not,
    and an include that names no file is reported."""
    (tmp_path / "lie").mkdir()
    (tmp_path / "dynamics").mkdir()
    (tmp_path / "lie" / "g.hpp").write_text('#pragma once\n#include <vector>\n// #include "dynamics/s.hpp"\n')
    (tmp_path / "dynamics" / "s.hpp").write_text('#include "lie/g.hpp"\n  #  include "s.hpp"\n')
    graph, unresolved = cpp_include_graph(tmp_path)
    assert graph == {"dynamics/s.hpp": {"lie/g.hpp"}, "lie/g.hpp": set()}, graph
    assert unresolved == ['dynamics/s.hpp: #include "s.hpp" is not a file of cpp/ (write it from the cpp/ root)']
