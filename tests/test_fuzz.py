"""Issue 13, item 7: generated scene files and API calls (benchmarks/fuzz.py's seeded generator).

Every case either solves with a strict-JSON (finite) result or is refused with exit code 2 and
one line on stderr; no traceback, no hang (60 s per case), no stray stderr line. The 10,000-case
run is ``python benchmarks/fuzz.py --cases 10000`` (outside CI).
"""
from __future__ import annotations

import importlib.util
import time
from pathlib import Path

FUZZ = Path(__file__).resolve().parents[1] / "benchmarks" / "fuzz.py"


def _fuzz_module():
    spec = importlib.util.spec_from_file_location("geoddp_fuzz", FUZZ)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_generated_cases_solve_or_are_refused_in_one_line():
    fuzz = _fuzz_module()
    examples: dict = {}
    t0 = time.time()
    counts = fuzz.fuzz(250, seed=20261123, timeout=60.0, max_iter=30, examples=examples)
    assert sum(counts.values()) == 250
    bad = {k: v for k, v in counts.items() if k not in ("solved", "refused", "slow")}
    assert not bad, {k: [(i, r) for i, _, r in examples[k][:3]] for k in bad}
    assert counts["solved"] >= 10 and counts["refused"] >= 10, counts  # both paths exercised
    assert time.time() - t0 < 600


def test_the_generator_is_seeded():
    fuzz = _fuzz_module()
    scenes = fuzz._base_scenes()
    assert fuzz.make_case(3, 7, scenes, 30) == fuzz.make_case(3, 7, scenes, 30)
    assert fuzz.make_case(3, 7, scenes, 30) != fuzz.make_case(3, 8, scenes, 30)


def test_the_classifier_counts_each_failure_class():
    fuzz = _fuzz_module()
    ok = {"rc": 0, "stderr": [], "json_ok": True, "json_exists": True, "escaped": None}
    assert fuzz.classify(ok) == "solved"
    assert fuzz.classify(None) == "hang"
    assert fuzz.classify({**ok, "json_ok": False}) == "nan_output"
    assert fuzz.classify({**ok, "stderr": ["RuntimeWarning: overflow"]}) == "stray_stderr"
    assert fuzz.classify({**ok, "rc": 3, "stderr": ["geoddp: internal error: ..."]}) == "traceback"
    assert fuzz.classify({**ok, "rc": -1, "escaped": "KeyError: x"}) == "traceback"
    refused = {"rc": 2, "stderr": ["geoddp: error: x"], "json_ok": False, "json_exists": False, "escaped": None}
    assert fuzz.classify(refused) == "refused"
    assert fuzz.classify({**refused, "stderr": ["Error: urdfdom", "geoddp: error: x"]}) == "stray_stderr"
