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


def test_byte_level_cases_solve_or_are_refused_in_one_line():
    # mutated bytes of scene files, the URDFs and the SRDF scenes name, and sweep files: no
    # traceback, no crash, no NaN in a result, every target and most mutations exercised
    fuzz = _fuzz_module()
    examples: dict = {}
    stats = fuzz.new_stats()
    counts = fuzz.fuzz(200, seed=20261207, timeout=60.0, max_iter=20, examples=examples, mode="bytes", stats=stats)
    assert sum(counts.values()) == 200
    bad = {k: v for k, v in counts.items() if k not in ("solved", "refused", "slow")}
    assert not bad, {k: [(i, r) for i, _, r in examples[k][:3]] for k in bad}
    assert stats["tracebacks"] == 0 and stats["nan_outputs"] == 0
    assert counts["solved"] >= 10 and counts["refused"] >= 100, counts
    assert {t.split(":")[0] for t in stats["by_target"]} == {"scene", "urdf", "srdf", "sweep"}
    assert len(stats["ops"]) >= 10, stats["ops"]


def test_the_byte_generator_is_seeded_and_mutates():
    fuzz = _fuzz_module()
    scenes, hosts = fuzz._base_scenes(), fuzz._urdf_hosts(20)
    a, b = (fuzz.make_bytes_case(3, 7, scenes, hosts, 20) for _ in range(2))
    assert a == b and a != fuzz.make_bytes_case(3, 8, scenes, hosts, 20)
    import random

    base = b"[solver]\nmax_iter = 30\n"
    outs = [fuzz.mutate_bytes(random.Random(k), base, xml=False)[0] for k in range(50)]
    assert len(set(outs)) >= 45 and sum(o == base for o in outs) <= 2  # two swaps of one pair undo each other
