"""The kernels package's documented interface: it imports nothing from geoddp (numpy and numba
only), and its docstring documents every public kernel it exports."""
import ast
from pathlib import Path

import geoddp.kernels as kernels

KERNELS = Path(kernels.__file__).parent


def test_kernels_import_only_numpy_numba_and_each_other():
    for path in sorted(KERNELS.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                roots = {a.name.split(".")[0] for a in node.names}
                assert roots <= {"numpy", "numba"}, (path.name, roots)
            elif isinstance(node, ast.ImportFrom):
                if node.level == 0:
                    assert node.module.split(".")[0] in {"numpy", "numba", "__future__"}, (path.name, node.module)
                else:  # relative: a sibling module of the package, never a parent
                    assert node.level == 1, (path.name, node.module)


def test_every_exported_kernel_is_documented_with_its_arguments():
    doc = kernels.__doc__
    for name in kernels.__all__:
        assert callable(getattr(kernels, name))
        assert f"``{name}(" in doc, name
