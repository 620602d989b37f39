"""The stated detection limits and the plan drawn within them (``stated_limits``, ``hysbench accuracy run --plan
within-limits``)."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from hysbench.benchmarks.cli import main as hysbench
from hysbench.benchmarks.diagnosis_accuracy import accuracy, rows, stated_limits
from hysbench.benchmarks.diagnosis_accuracy.planted import BASES, VOCABULARY, piezo_available, planted_case
from hysbench.benchmarks.diagnosis_accuracy.shares import PLAN_STRIDE
from hysbench.models.errors import HysbenchError

ROWS = Path(__file__).resolve().parents[1] / "results" / rows.ROWS_FILE.name


def limit_by_hand(rows, cause, base, min_cases):
    """Slow reference: scan every strength drawn, weakest first, for the first whose tail is >= 95 % right."""
    cases = [r for r in rows if r["kinds"] == [cause] and r["base"] == base]
    for s in sorted(r["strength_pct"] for r in cases):
        tail = [r["right"] for r in cases if r["strength_pct"] >= s]
        if len(tail) >= min_cases and sum(tail) >= 0.95 * len(tail):
            return s
    return None


def test_the_stated_limits_are_those_of_the_plans_they_were_stated_from():
    """Recomputed by hand from the stored rows of the plans the file names: a rerun of those plans that moves a
    limit makes this fail, so the limits are stated again (and the within-limits plans scored again) on purpose."""
    source = stated_limits.stated_from()
    assert source["plans"] == rows.expand(stated_limits.STATING_PLANS)
    plans = rows.plan_rows(rows.read_plans(ROWS), source["plans"])
    stored = [r for p in plans for r in p["rows"]]
    assert sorted({r["seed"] // PLAN_STRIDE for r in stored}) == source["seeds"]
    assert set(stated_limits.LIMITS_PCT) == {(c, b) for c in VOCABULARY for b in BASES}
    for (cause, base), stated in stated_limits.LIMITS_PCT.items():
        assert limit_by_hand(stored, cause, base, source["min_cases"]) == stated, (cause, base)


def test_the_command_writes_the_limits_it_states_and_they_are_read_back(tmp_path, monkeypatch):
    """``hysbench accuracy limits`` on two small stored plans: the file holds what the slow reference gives, and
    pointed at that file the within-limits plan draws at those limits."""
    stride = PLAN_STRIDE
    cases = [{"kinds": ["creep"], "base": "mrpim", "drive": "sines", "seed": stride * (1 + i // 5) + i,
              "strength_pct": 0.1 * (i + 1), "right": i not in (0, 2)} for i in range(10)]
    plans = {f"balanced-{k}": {"meta": {"design": "balanced", "seed": k, "cases": 5},
                                "rows": [c for c in cases if c["seed"] // stride == k]} for k in (1, 2)}
    path, out = tmp_path / "rows.jsonl.gz", tmp_path / "limits.json"
    rows.write_plans(path, plans)
    assert hysbench(["accuracy", "limits", "balanced-1..2", "--min-cases", "3", "--rows", str(path),
                     "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert (data["plans"], data["seeds"], data["min_cases"]) == (["balanced-1", "balanced-2"], [1, 2], 3)
    table = {(q["cause"], q["base"]): q for q in data["limits"]}
    assert set(table) == {(c, b) for c in VOCABULARY for b in BASES}
    creep = table[("creep", "mrpim")]
    assert creep["limit_pct"] == limit_by_hand(cases, "creep", "mrpim", 3) == pytest.approx(0.4)
    assert (creep["cases"], creep["cases_above"], creep["right_above"]) == (10, 7, 7)
    assert table[("delay", "mrpim")] == {"cause": "delay", "base": "mrpim", "limit_pct": None, "cases": 0,
                                          "cases_above": 0, "right_above": 0}
    monkeypatch.setattr(stated_limits, "LIMITS_FILE", out)
    monkeypatch.setattr(stated_limits, "_loaded", {})
    assert stated_limits.stated_limit("creep", "mrpim") == creep["limit_pct"]
    assert stated_limits.stated_limit("delay", "mrpim") is None and not stated_limits.in_scope(["delay"], "mrpim")


def test_a_within_limits_plan_plants_each_cause_only_where_it_has_a_limit_and_says_its_minimum():
    cases = accuracy.plan(200, 7, design="within-limits")
    assert len(cases) == 200 and len({c["seed"] for c in cases}) == 200
    for c in cases:
        vocab = [k for k in c["kinds"] if k in VOCABULARY]
        assert c["min_strength_pct"] == {k: stated_limits.stated_limit(k, c["base"]) for k in vocab}
        assert all(v is not None for v in c["min_strength_pct"].values())
    planted = {(k, c["base"]) for c in cases for k in c["kinds"] if k in VOCABULARY}
    assert not planted & set(stated_limits.out_of_scope())
    assert {tuple(c["kinds"]) for c in cases} == set(accuracy.PATTERN)  # every effect still drawn
    assert all("min_strength_pct" not in c for c in accuracy.plan(50, 7))  # the balanced plan is unchanged


def strength_by_hand(ds, truth, kind):
    """Each effect's own strength from what it added, over the identification records, % of p2p."""
    ident = [r.file for r in ds.records if r.role == "identification"]
    added = np.concatenate([truth["signals"][kind][f] for f in ident])
    return 100 * math.sqrt(np.mean(added ** 2)) / truth["p2p"]


@pytest.mark.parametrize("kinds,base,drive", [(("relaxation",), "piezo", "sines"),
                                              (("delay", "creep"), "mrpim", "sines")])
def test_a_within_limits_case_is_the_first_draw_whose_every_effect_reaches_its_limit(kinds, base, drive):
    if base == "piezo" and not piezo_available():
        pytest.skip("the piezo recording is not in ../shared/datasets")
    least = {k: stated_limits.stated_limit(k, base) for k in kinds}
    seed = 9 * PLAN_STRIDE + 3
    ds, truth, used, attempts = accuracy.planted_within(
        {"kinds": kinds, "base": base, "drive": drive, "seed": seed, "min_strength_pct": least})
    for a in range(attempts):  # slow reference: draw by hand, seed by seed
        ref_ds, ref_truth = planted_case(kinds, base, drive, seed + accuracy.ATTEMPT_STRIDE * a)
        strengths = {k: strength_by_hand(ref_ds, ref_truth, k) for k in kinds}
        assert all(s >= least[k] for k, s in strengths.items()) == (a == attempts - 1), (a, strengths)
    assert used == seed + accuracy.ATTEMPT_STRIDE * (attempts - 1)
    assert used // PLAN_STRIDE == seed // PLAN_STRIDE  # the redraws stay within the plan's seeds
    for k in kinds:
        assert truth["strength_by_effect_pct"][k] == pytest.approx(strength_by_hand(ds, truth, k), rel=1e-12)
    np.testing.assert_array_equal(ds.records[0].y, ref_ds.records[0].y)


def test_a_case_that_never_reaches_its_limit_stops_with_a_message(monkeypatch):
    monkeypatch.setattr(accuracy, "MAX_ATTEMPTS", 2)
    with pytest.raises(HysbenchError, match="reached its stated limits"):
        accuracy.planted_within({"kinds": ("delay",), "base": "mrpim", "drive": "sines", "seed": 5,
                                 "min_strength_pct": {"delay": 1e9}})


def test_the_report_says_whether_a_within_limits_plan_took_part_in_stating_them():
    def lines(plan_seed):
        row = {"kinds": ["delay"], "seed": plan_seed * PLAN_STRIDE + 1, "attempts": 3}
        return "\n".join(accuracy._within_limits_lines([row], {"plan_design": "within-limits"}))

    assert "2 redraws" in lines(63) and "took no part in stating the limits" in lines(63)
    assert "does not measure them" in lines(40)
    assert accuracy._within_limits_lines([], {"plan_design": "balanced"}) == []
