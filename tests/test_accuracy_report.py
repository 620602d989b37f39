"""The accuracy study's reports: intervals, a plan's report, pooled plans, the ceiling (``diagnosis_accuracy``)."""

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hysbench.benchmarks.cli import main as hysbench
from hysbench.benchmarks.diagnosis_accuracy import accuracy, pooled, rows as row_file
from hysbench.models.errors import HysbenchError


def score_test_accepts(k: int, n: int, p: np.ndarray, z: float) -> np.ndarray:
    """The two-sided score test of share p does not reject k of n (the Wilson interval's definition)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inside = np.abs(k - n * p) <= z * np.sqrt(n * p * (1 - p))
    return np.where((p == 0.0) | (p == 1.0), k == n * p, inside)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 400), st.data())
def test_the_wilson_interval_is_the_set_of_shares_the_score_test_accepts(n, data):
    k = data.draw(st.integers(0, n))
    lo, hi = accuracy.wilson_interval(k, n)
    z = 1.959963984540054
    grid = np.linspace(0.0, 1.0, 200_001)  # slow reference: scan the shares
    accepted = grid[score_test_accepts(k, n, grid, z)]
    step = grid[1]
    assert abs(lo - accepted.min()) <= step + 1e-9 and abs(hi - accepted.max()) <= step + 1e-9
    assert lo <= k / n <= hi


def test_the_wilson_interval_matches_a_published_value_and_is_empty_without_cases():
    lo, hi = accuracy.wilson_interval(81, 263)  # Newcombe (1998), example: 81/263 -> 0.2553-0.3662
    assert (round(lo, 4), round(hi, 4)) == (0.2553, 0.3662)
    assert all(math.isnan(v) for v in accuracy.wilson_interval(0, 0))


def _row(kinds, right):
    return {"kinds": list(kinds), "base": "mrpim", "drive": "sines", "seed": 0, "strength_pct": 1.0, "effects": {},
            "verdict": "none", "confirmed": False, "also": [], "ambiguous_with": [], "remainder": None,
            "parameters": {}, "parameter_errors": {}, "parameters_within": False, "right": right, "seconds": 1.0}


def test_confirmed_causes_are_counted_on_the_nulls_of_the_mrpim_and_the_piezo_recording_not_the_virtual_dea():
    """A confirmed cause on a null counts on the MRPIM and the real recording; the virtual DEA's own relaxation,
    its physics, does not; ``none`` and ``unexplained`` never do."""
    def null(base, verdict, confirmed):
        r = _row(["null-ar1"], False)
        r.update(base=base, verdict=verdict, confirmed=confirmed)
        return r

    rows = [null("mrpim", "none", None), null("mrpim", "delay", False), null("piezo", "delay", True),
            null("piezo", "unexplained", None), null("virtual-dea", "relaxation", True), _row(["delay"], True)]
    s = accuracy.summary(rows)
    assert (s["confirmed_on_nulls"], s["nulls_checked"]) == (1, 4)
    assert "| confirmed causes on nulls (MRPIM and piezo bases, white and AR(1)) | **1** of 4 | 0 |" in (
        accuracy.markdown(rows, s, 1.0))


def test_the_rules_that_decided_are_counted_from_the_rows_traces_in_the_decision_rules_order():
    """Each rule counts a case once, however often it acted on it; rows without a trace are left out and named; a
    plan without any trace has no such section."""
    rows = [_row(["delay"], True), _row(["delay"], False), _row(["null-white"], True)]
    rows[0]["trace"] = [["also", "relaxation"], ["nothing-passes", "none"], ["also", "creep"]]
    rows[1]["trace"] = [["also", "delay"]]
    s = accuracy.summary(rows)["rules"]
    assert list(s["rules"]) == ["nothing-passes", "also"]  # selection's rules come before those after it
    assert s["rules"]["also"] == {"cases": 2, "right": 1, "outcomes": {"relaxation": 1, "creep": 1, "delay": 1}}
    assert (s["traced"], s["cases"]) == (2, 3) and "validation" in s["never"] and "also" not in s["never"]
    text = accuracy.markdown(rows, accuracy.summary(rows), 1.0)
    assert "| `also` | 2 | 1 | relaxation 1; creep 1; delay 1 |" in text and "(2 of 3 rows here)" in text
    pooled_rules = pooled.pool([stored([dict(r, seed=i) for i, r in enumerate(rows)])])["rules"]
    assert pooled_rules["rules"] == s["rules"] and "### The rules that decided" in pooled.pooled_markdown(
        pooled.pool([stored([dict(r, seed=i) for i, r in enumerate(rows)])]))
    untraced = [_row(["delay"], True)]
    assert "rules" not in accuracy.summary(untraced)
    assert "The rules that decided" not in accuracy.markdown(untraced, accuracy.summary(untraced), 1.0)


def stored(rows, design="balanced", **meta):
    """A plan as the row file holds it (``rows.plan_rows``), its id from its cases' plan seed."""
    seed = rows[0]["seed"] // accuracy.PLAN_STRIDE
    return {"id": f"{design}-{seed}", "meta": {"design": design, "seed": seed, "cases": len(rows), "wall_s": 1.0,
                                                "machine": None, "missing_bases": {}, **meta}, "rows": rows}


def test_pooled_plans_count_confirmed_nulls_from_their_cases():
    """A confirmed cause on a piezo null counts; the pooled count is the cases' own."""
    r = _row(["null-white"], False)
    r.update(base="piezo", verdict="delay", confirmed=True)
    p = pooled.pool([stored([r, _row(["null-ar1"], True), _row(["delay"], True)])])
    assert (p["confirmed_on_nulls"], p["nulls_checked"]) == (1, 2)


def _plan(seed, rights):
    rows = []
    for i, right in enumerate(rights):
        r = _row(["delay"] if i % 2 else ["null-white"], right)
        r["seed"] = seed * accuracy.PLAN_STRIDE + i
        rows.append(r)
    return stored(rows)


def test_the_report_gives_the_verdict_share_with_its_interval_and_the_command_of_its_plan(tmp_path):
    accuracy.write_report(_plan(3, [True] * 7 + [False] * 3), tmp_path / "r.md")
    text = (tmp_path / "r.md").read_text()
    lo, hi = accuracy.wilson_interval(7, 10)
    assert f"7 / 10 = **70.0 %** (95 % interval {100 * lo:.1f}-{100 * hi:.1f} %)" in text
    assert "10 cases (`hysbench accuracy run --seed 3 --cases 10`)" in text
    s = json.loads((tmp_path / "r.json").read_text())["summary"]
    assert s["right_interval"] == pytest.approx([lo, hi]) and s["plan"] == "balanced-3"


def test_pooled_plans_add_their_cases_and_refuse_a_plan_twice_or_a_row_without_its_fields(tmp_path, capsys):
    a, b = _plan(1, [True] * 8 + [False] * 2), _plan(2, [True] * 5 + [False] * 5)
    p = pooled.pool([a, b])
    assert (p["cases"], p["right"], [q["seed"] for q in p["plans"]]) == (20, 13, ["1", "2"])
    assert [q["plan"] for q in p["plans"]] == ["balanced-1", "balanced-2"]
    assert p["right_interval"] == pytest.approx(accuracy.wilson_interval(13, 20))
    assert "13 / 20 = **65.0 %**" in pooled.pooled_markdown(p)
    with pytest.raises(HysbenchError, match="plan seed 1 is given twice"):
        pooled.pool([a, a])
    del b["rows"][3]["seed"]
    with pytest.raises(HysbenchError, match="case 3 has no seed"):
        pooled.pool([a, b])
    with pytest.raises(HysbenchError, match="has no rows"):
        pooled.pool([{**a, "rows": []}])
    file = tmp_path / "rows.jsonl.gz"
    row_file.write_plans(file, {a["id"]: a})
    assert hysbench(["accuracy", "pool", "balanced-1", "balanced-9", "--rows", str(file)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no plan balanced-9" in err


def _case(seed, kinds, base, drive, strength, right):
    return {**_row(kinds, right), "seed": seed, "base": base, "drive": drive, "strength_pct": strength}


def test_pooled_plans_give_the_share_by_effect_and_base_and_the_detection_limit_by_base():
    stride = accuracy.PLAN_STRIDE
    piezo = [(0.1, False), (0.2, False), (0.5, True), (1.0, True), (2.0, True)]  # limit 0.5, 3 cases above it
    rows_a = [_case(5 * stride + i, ["relaxation"], "piezo", "sines", s, r) for i, (s, r) in enumerate(piezo[:3])]
    rows_a += [_case(5 * stride + 9, ["null-white"], "mrpim", "triangles", 0.0, True)]
    rows_b = [_case(6 * stride + i, ["relaxation"], "piezo", "sines", s, r) for i, (s, r) in enumerate(piezo[3:])]
    rows_b += [_case(6 * stride + 5 + i, ["relaxation"], "mrpim", "sines", s, True) for i, s in enumerate((0.3, 0.4))]
    rows_b += [_case(6 * stride + 8, ["delay", "creep"], "mrpim", "sines", 1.0, False)]
    p = pooled.pool([stored(rows_a), stored(rows_b)])
    assert p["bases"] == ["mrpim", "piezo"]
    assert p["by_effect_and_base"]["relaxation"]["piezo"]["cases"] == 5
    assert p["by_effect_and_base"]["relaxation"]["piezo"]["right"] == 3
    assert p["by_effect_and_base"]["relaxation"]["piezo"]["interval"] == pytest.approx(accuracy.wilson_interval(3, 5))
    assert list(p["by_effect_and_base"]) == ["relaxation", "null-white", "delay+creep"]
    limits = p["detection_limits"]["relaxation"]
    assert (limits["piezo"]["strength_pct"], limits["piezo"]["cases_above"]) == (0.5, 3)
    assert limits["piezo"]["strengths_pct"] == [0.1, 2.0]
    assert limits["mrpim"]["strength_pct"] is None  # two cases only: fewer than three above any strength
    assert p["by_base_and_drive"]["mrpim"]["sines"]["cases"] == 3
    assert p["by_base_and_drive"]["mrpim"]["triangles"]["right"] == 1
    assert sum(q["cases"] for per in p["by_effect_and_base"].values() for q in per.values()) == p["cases"] == 9
    assert (p["parameters_judged"], p["parameters_within"]) == (0, 0)  # the stand-in rows name no parameter
    text = pooled.pooled_markdown(p)
    assert "| relaxation | 2/2 (100 %, 34-100) | 3/5 (60 %, 23-88) |" in text
    assert "**0.5** (3 of 5 cases at or above it, 3 of 3 right; drawn 0.1-2)" in text
    rows_b += [_case(6 * stride + 7, ["relaxation"], "mrpim", "sines", 0.2, True)]
    q = pooled.pool([stored(rows_a), stored(rows_b)])["detection_limits"]["relaxation"]["mrpim"]
    assert (q["strength_pct"], q["cases_above"], q["cases"]) == (0.2, 3, 3)
    assert "**<= 0.2** (every case at or above it: 3 of 3 right; drawn 0.2-0.4)" in pooled.pooled_markdown(
        pooled.pool([stored(rows_a), stored(rows_b)]))


def test_pooled_parameters_within_25_percent_count_the_right_vocabulary_verdicts_that_name_parameters():
    rows = []
    for i, (kinds, right, errors, within) in enumerate([(["delay"], True, {"delay_s": 0.1}, True),
                                                        (["delay"], True, {"delay_s": 0.4}, False),
                                                        (["delay"], False, {"delay_s": 0.01}, True),  # wrong verdict
                                                        (["null-white"], True, {}, False),
                                                        (["creep"], True, {"drift": 0.2}, True)]):
        rows.append({**_case(8 * accuracy.PLAN_STRIDE + i, kinds, "mrpim", "sines", 1.0, right),
                     "parameter_errors": errors, "parameters_within": within})
    p = pooled.pool([stored(rows)])
    assert (p["parameters_judged"], p["parameters_within"]) == (3, 2)
    assert "within 25 %: 2 / 3 = **66.7 %**" in pooled.pooled_markdown(p)


def test_a_pooled_report_is_written_whole_with_its_plans_its_command_and_its_note(tmp_path):
    file = tmp_path / "rows.jsonl.gz"
    a, b = _plan(7, [True, False, True]), _plan(8, [True, True])
    row_file.write_plans(file, {a["id"]: a, b["id"]: b})
    report = tmp_path / "out" / "pooled.md"
    assert hysbench(["accuracy", "pool", "balanced-7..8", "--rows", str(file), "--report", str(report),
                     "--note", "Three cases."]) == 0
    text = report.read_text()
    assert text.startswith("# Accuracy of `hysbench diagnose`, plans pooled\n\nPlans pooled: balanced-7..8 (5 cases). "
                           f"Command: `hysbench accuracy pool balanced-7..8 --report {report} --rows {file}`.")
    assert "\n\nThree cases.\n\n| plan seed |" in text
    assert json.loads(report.with_suffix(".json").read_text())["right"] == 4


def test_a_limit_at_the_weakest_drawn_strength_says_how_many_of_its_cases_are_right():
    """95 % of 20 is 19: one miss above the weakest case still puts the limit there, and the report must not
    call every case right."""
    rows = [_case(9 * accuracy.PLAN_STRIDE + i, ["creep"], "mrpim", "sines", 0.5 + 0.1 * i, i != 7) for i in range(20)]
    p = pooled.pool([stored(rows)])
    q = p["detection_limits"]["creep"]["mrpim"]
    assert (q["strength_pct"], q["cases_above"], q["right_above"]) == (0.5, 20, 19)
    assert "**<= 0.5** (every case at or above it: 19 of 20 right; drawn 0.5-2.4)" in pooled.pooled_markdown(p)


def test_detection_limits_are_checked_on_held_out_plans_counted_by_hand():
    """The limits chosen on plan 1 (creep on MRPIM: 0.5; delay on MRPIM: 2; resonance: none reached) checked on
    plan 2: its creep cases at or above 0.5 (0.5, 0.9, 2.0: two right, an interval short of 95 %) and below it
    (0.3, right); its delay case at 9 (right). A plan both pooled and checked is refused: not held out."""
    stride = accuracy.PLAN_STRIDE
    rows = [_case(stride + i, ["creep"], "mrpim", "sines", s, r)
            for i, (s, r) in enumerate([(0.2, False), (0.5, True), (0.7, True), (1.0, True)])]
    rows += [_case(stride + 4 + i, ["delay"], "mrpim", "sines", s, s > 1) for i, s in enumerate((1.0, 2.0, 3.0, 4.0))]
    rows += [_case(stride + 8 + i, ["resonance"], "mrpim", "sines", s, False) for i, s in enumerate((1.0, 2.0, 3.0))]
    fit = stored(rows)
    rows = [_case(2 * stride + i, ["creep"], "mrpim", "triangles", s, r)
            for i, (s, r) in enumerate([(0.3, True), (0.5, True), (0.9, False), (2.0, True)])]
    rows += [_case(2 * stride + 4, ["creep"], "piezo", "sines", 5.0, False),  # no limit on the piezo base
             _case(2 * stride + 5, ["delay"], "mrpim", "sines", 9.0, True),
             _case(2 * stride + 6, ["resonance"], "mrpim", "sines", 9.0, True),
             _case(2 * stride + 7, ["delay", "creep"], "mrpim", "sines", 9.0, False)]
    held = stored(rows)
    p = pooled.pool([fit], check=[held])
    c = p["checked"]
    assert [q["seed"] for q in c["plans"]] == ["2"]
    assert list(c["by_cause_and_base"]) == ["delay", "creep"]
    assert [list(per) for per in c["by_cause_and_base"].values()] == [["mrpim"], ["mrpim"]]
    q = c["by_cause_and_base"]["creep"]["mrpim"]
    assert (q["limit_pct"], q["cases"], q["above"], q["right_above"], q["below"], q["right_below"]) == (
        0.5, 4, 3, 2, 1, 1)
    assert q["interval"] == pytest.approx(accuracy.wilson_interval(2, 3))
    assert q["holds"] is False  # 2 of 3: the interval (21-94 %) does not reach 95 %
    d = c["by_cause_and_base"]["delay"]["mrpim"]
    assert (d["limit_pct"], d["above"], d["right_above"], d["below"], d["holds"]) == (2.0, 1, 1, 0, True)
    assert (c["above"], c["right_above"]) == (4, 3)
    text = pooled.pooled_markdown(p)
    assert "| creep | mrpim | 0.5 | 2 of 3 | 67 % (21-94) | **no** (below 95 %) | 1 of 1 |" in text
    assert "| delay | mrpim | 2 | 1 of 1 | 100 % (21-100) | yes | - |" in text
    assert "3 of 4 cases at or above their limit right = **75.0 %**" in text
    assert c["all_cases"] == {"cases": 8, "right": 5, "interval": pytest.approx(accuracy.wilson_interval(5, 8))}
    assert "Every case of these plans, at any strength: 5 / 8 right = **62.5 %**" in text
    with pytest.raises(HysbenchError, match="cannot check them"):
        pooled.pool([fit, held], check=[held])


def _evidence_case(seed, kinds, base, right, shown, extension, verdict="none", also=()):
    return {**_case(seed, kinds, base, "sines", 1.0, right), "verdict": verdict, "also": list(also),
            "effect_evidence": {}, "effect_shows_evidence": shown, "extension_could_show": extension}


def test_the_pooled_report_gives_the_ceiling_of_every_plan_and_pooled_counted_by_hand():
    """Ceiling: nulls and out-of-vocabulary cases, plus the vocabulary cases with evidence, plus those without it
    that are right anyway. Plan 1: 1 null + (2 with evidence) + (1 right without) = 4 of 5 by the waveform,
    1 + 1 + 1 = 3 by the extensions; plan 2: 1 + 1 + 0 = 2 of 3 by both."""
    stride = accuracy.PLAN_STRIDE
    one = [_evidence_case(stride, ["delay"], "mrpim", True, True, True),
           _evidence_case(stride + 1, ["delay"], "piezo", False, True, False),
           _evidence_case(stride + 2, ["creep"], "piezo", True, False, False),
           _evidence_case(stride + 3, ["creep"], "piezo", False, False, False),
           _evidence_case(stride + 4, ["null-white"], "mrpim", True, False, False)]
    two = [_evidence_case(2 * stride, ["resonance"], "virtual-dea", False, True, True),
           _evidence_case(2 * stride + 1, ["resonance"], "virtual-dea", False, False, False),
           _evidence_case(2 * stride + 2, ["dead-zone"], "mrpim", False, False, False)]
    p = pooled.pool([stored(one), stored(two)])
    assert [(q["ceiling_right"], q["extension_ceiling_right"]) for q in p["plans"]] == [(4, 3), (2, 2)]
    e = p["ceiling"]
    assert (e["ceiling_right"], e["extension_ceiling_right"], e["with_evidence"], e["with_evidence_right"]) == (6, 5, 3, 1)
    assert e["intervals"]["ceiling_right"] == pytest.approx(accuracy.wilson_interval(6, 8))
    piezo = e["by_base"]["piezo"]
    assert (piezo["cases"], piezo["with_evidence"], piezo["with_evidence_right"], piezo["without_evidence_right"]) == (
        3, 1, 0, 1)
    assert (piezo["extension_cases"], piezo["extension_without_right"]) == (0, 1)
    text = pooled.pooled_markdown(p)
    assert "| 1 | 5 | 3 | 60.0 % | 4 | 3 |" in text and "**6 / 8 = 75.0 %**" in text and "**5 / 8 = 62.5 %**" in text
    assert "| piezo | 3 | 1 | 2 | 1 |" in text  # right 1; at most 1 + 1 by the waveforms, 0 + 1 by the extensions
    assert "on top of everything the diagnosis kept" not in text  # no plan has the third reading
    for r in one + two:
        r.pop("effect_shows_evidence")
    assert pooled.pool([stored(one + two)])["ceiling"] == {}  # rows without the evidence check: no ceiling
