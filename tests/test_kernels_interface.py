"""The kernels module's documented interface: it imports nothing from geoddp but the compiled
core (numpy and geoddp._core only), every kernel it exports is the core's (no Python loop behind
a name) and its docstring documents each one with its arguments."""
import ast
import subprocess
import sys
from pathlib import Path

import geoddp.kernels as kernels

KERNELS = Path(kernels.__file__).parent


def test_kernels_import_only_numpy_pinocchio_and_the_core():
    files = sorted(KERNELS.glob("*.py"))
    assert [p.name for p in files] == ["__init__.py"]
    for node in ast.walk(ast.parse(files[0].read_text())):
        if isinstance(node, ast.Import):
            assert {a.name.split(".")[0] for a in node.names} <= {"numpy", "pinocchio"}, node.names
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                assert node.module == "__future__", node.module
            else:  # from .. import _core: the extension, nothing else of geoddp
                assert node.level == 2 and node.module is None and [a.name for a in node.names] == ["_core"]


def test_every_exported_kernel_is_documented_and_compiled():
    doc = kernels.__doc__
    for name in kernels.__all__:
        f = getattr(kernels, name)
        assert callable(f)
        assert f"``{name}(" in doc, name
        if name not in ("so3_right_jacobian", "se3_right_jacobian"):  # choose Jr or its inverse, one call
            assert f is getattr(kernels.core, name), name


def test_geoddp_refuses_to_import_without_its_core_and_says_why():
    """Under another pin than the core was built against, importing geoddp's modules fails at
    once with one message naming both versions and the rebuild (no Python fallback to run)."""
    code = ("import pinocchio; built = pinocchio.__version__; pinocchio.__version__ = '0.0.0'\n"
            "try:\n    import geoddp\nexcept ImportError as e:\n    print(e)\nelse:\n    print('imported')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    msg = out.stdout.strip()
    assert msg.startswith("geoddp needs its compiled core, which does not import: geoddp._core was built against pin ")
    assert "but pin 0.0.0 is installed; rebuild it against that pin" in msg
