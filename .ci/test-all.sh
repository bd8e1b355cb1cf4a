#!/usr/bin/env bash
# The README's test command: from a fresh clone, install everything the tests and the documentation
# need, run the whole suite, build the documentation (warnings as errors; its gallery runs every
# example), then run the Crocoddyl cross-checks in a second environment. `.ci/run` calls it.
#
# Two environments, because Crocoddyl 3.2.1's wheel needs pin 4.0.0 while users get pin 4.1 (the
# main one), and geoddp's core must be built against the pin it runs with: the core is compiled
# twice. The Crocoddyl environment is set up and built in the background at the lowest CPU priority
# (nice 19) while the main one is set up and the suite and the documentation run in the
# foreground: it takes only the cycles they leave idle (pip's downloads, the build's last files,
# the suite waiting on processes and files, the one-core documentation build), so the foreground
# runs about as fast as alone and the whole command ends several minutes sooner. Each build runs
# at most two compile jobs, so that both fit in memory together (a job takes up to 4 GB).
set -euo pipefail
cd "$(dirname "$0")/.."
step() { echo "test-all: $1 (at $((SECONDS / 60)) min $((SECONDS % 60)) s)"; }
export CMAKE_BUILD_PARALLEL_LEVEL=2  # compile jobs per build (both builds run at once)

# 1. The Crocoddyl environment, in the background (its own process group, stopped on any exit).
bench_log=.venv-bench.log
setsid -w nice -n 19 bash -c '
  set -euo pipefail
  python3 -m venv .venv-bench
  .venv-bench/bin/pip install -q "pin==4.0.0" "crocoddyl==3.2.1" "scikit-build-core>=0.10" "pybind11>=2.12" \
    "cmeel-eigen>=3.4,<3.5" cmake ninja
  .venv-bench/bin/pip install -q --no-build-isolation -e ".[test,bench]"
' > "$bench_log" 2>&1 &
bench_pid=$!
trap 'kill -- -"$bench_pid" 2> /dev/null || true' EXIT

# 2. The main environment: pin 4.1, the package and its test and docs extras, the core compiled
#    (pip's build isolation fetches pin, Eigen, pybind11, scikit-build-core, cmake and ninja).
python3 -m venv .venv
.venv/bin/pip install -q -e ".[test,docs]"
step "main environment built"

# 3. Headless Chromium (the viewer's tests), the whole suite on two workers, the documentation.
bash .ci/install-browser.sh
.venv/bin/python -m pytest -q -n 2
step "suite passed"
.venv/bin/sphinx-build -W --keep-going -q -b html docs docs/_build/html
step "documentation built"

# 4. The Crocoddyl cross-checks, once the second environment is built.
if ! wait "$bench_pid"; then
  echo "test-all: setting up the Crocoddyl environment failed; its log ($bench_log):" >&2
  cat "$bench_log" >&2
  exit 1
fi
step "Crocoddyl environment built"
GEODDP_REQUIRE_CROCODDYL=1 .venv-bench/bin/python -m pytest -q tests/test_crocoddyl_multibody.py \
  tests/test_crocoddyl_limits.py tests/test_crocoddyl_defaults.py tests/test_core_dynamics.py \
  tests/test_core_rnea_hessian.py tests/test_contact_crocoddyl.py tests/test_contact6d_crocoddyl.py \
  tests/test_legged_scenes_crocoddyl.py
step "Crocoddyl cross-checks passed"
