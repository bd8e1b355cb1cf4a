"""The Riccati node products: Eigen's against cpp/linalg/small_gemm.hpp's two builds.

Compiles ``benchmarks/small_gemm.cpp`` with the flags CMakeLists.txt gives each file (module code
-O2, kernels -O3, the AVX2 kernel -mavx2 -mfma) against cmeel-eigen's headers, runs it, and prints
per node size the median time of one node's six products (7 interleaved rounds) and the ratios to
Eigen. Needs g++ and the build requirements (cmeel-eigen).

    python benchmarks/small_gemm.py
"""
from __future__ import annotations

import importlib.metadata as md
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    eigen = md.distribution("cmeel-eigen").locate_file("cmeel.prefix/include/eigen3")
    cpp = ROOT / "cpp"
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        base = ["g++", "-std=c++17", "-DNDEBUG", f"-I{cpp}", f"-I{eigen}", "-DGEODDP_GEMM_AVX2=1"]
        steps = [
            base + ["-O3", "-c", str(cpp / "linalg" / "small_gemm_base.cpp"), "-o", str(t / "b.o")],
            base + ["-O3", "-mavx2", "-mfma", "-c", str(cpp / "linalg" / "small_gemm_avx2.cpp"), "-o", str(t / "a.o")],
            base + ["-O2", "-c", str(cpp / "linalg" / "small_gemm.cpp"), "-o", str(t / "s.o")],
            base + ["-O2", "-c", str(ROOT / "benchmarks" / "small_gemm.cpp"), "-o", str(t / "h.o")],
            ["g++", str(t / "h.o"), str(t / "s.o"), str(t / "a.o"), str(t / "b.o"), "-o", str(t / "h")],
        ]
        for cmd in steps:
            subprocess.run(cmd, check=True)
        out = subprocess.run([str(t / "h")], check=True, capture_output=True, text=True).stdout
    sys.stdout.write(out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
