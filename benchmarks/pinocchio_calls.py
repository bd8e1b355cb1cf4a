"""Per-call cost of the Pinocchio algorithms behind each node of an iteration.

Compiles ``benchmarks/pinocchio_calls.cpp`` with CMakeLists.txt's flags (-O2, the wheel's
template-instantiation and Boost limits, never -march=native) against the installed pin's headers
and libpinocchio_default and cmeel-eigen, runs it, and prints one table: ABA instantiated in the
program against the wheel's own instantiation (why cpp/rigid_body/aba_compiled.hpp calls through
Eigen::Ref), computeABADerivatives (a first-order node) and ComputeRNEASecondOrderDerivatives (an
exact second-order node), medians of 7 interleaved rounds; the RNEA column's ratio is the floor
Pinocchio sets under the second-order expansion's cost relative to the first-order one. The last
two columns time geoddp's kinetic-energy Hessian (cpp/rigid_body/kinetic_hessian.cpp) against the
second-order RNEA at (q, 0, y) from which the variational step had contracted it, and the last two
its tensors dM/dq and d/dq D(q, y) (mass_tensors, the same file) against that RNEA, which had
given them at the variational step's base points. The last three: RNEA's second order contracted
with a vector by the recursion (cpp/rigid_body/rnea_hessian.cpp) against ComputeRNEASecondOrderDerivatives at
(q, v, a), which the contracted pass's expansion had run per node, and the recursion's part that
needs the vector (rnea_hessian_contract), which runs in the pass.
Needs g++ and the build requirements; the compile takes about 90 s.

    python benchmarks/pinocchio_calls.py
"""
from __future__ import annotations

import importlib.metadata as md
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# the flags CMakeLists.txt gives the module (target_compile_definitions there)
DEFINES = ["-DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION", "-DBOOST_MPL_LIMIT_LIST_SIZE=30",
           "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30", "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS",
           "-DBOOST_FUSION_INVOKE_MAX_ARITY=12"]


def main() -> int:
    pin = Path(str(md.distribution("libpinocchio").locate_file("cmeel.prefix")))
    eigen = Path(str(md.distribution("cmeel-eigen").locate_file("cmeel.prefix/include/eigen3")))
    with tempfile.TemporaryDirectory() as tmp:
        exe = Path(tmp) / "calls"
        cmd = ["g++", "-std=c++17", "-O2", "-DNDEBUG", *DEFINES, f"-I{pin / 'include'}", f"-I{eigen}",
               f"-I{ROOT / 'cpp'}", str(ROOT / "benchmarks" / "pinocchio_calls.cpp"), "-o", str(exe), f"-L{pin / 'lib'}",
               "-lpinocchio_default", f"-Wl,-rpath,{pin / 'lib'}"]
        subprocess.run(cmd, check=True)
        out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout
    sys.stdout.write(out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
