"""The accuracy report's intervals and the pooling of several plans (``benchmarks.diagnosis.accuracy``)."""

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hysbench.benchmarks.diagnosis import accuracy
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


def _plan(folder, seed, rights):
    rows = []
    for i, right in enumerate(rights):
        r = _row(["delay"] if i % 2 else ["null-white"], right)
        r["seed"] = seed * accuracy.PLAN_STRIDE + i
        rows.append(r)
    accuracy.write(rows, accuracy.ensure_dir(folder), 1.0)
    return rows


def test_the_report_gives_the_verdict_share_with_its_interval(tmp_path):
    _plan(tmp_path, 3, [True] * 7 + [False] * 3)
    text = (tmp_path / "diagnosis_accuracy.md").read_text()
    lo, hi = accuracy.wilson_interval(7, 10)
    assert f"7 / 10 = **70.0 %** (95 % interval {100 * lo:.1f}-{100 * hi:.1f} %)" in text
    s = json.loads((tmp_path / "diagnosis_accuracy.json").read_text())["summary"]
    assert s["right_interval"] == pytest.approx([lo, hi])


def test_pooled_plans_add_their_cases_and_refuse_a_plan_twice_or_a_folder_without_a_report(tmp_path, capsys):
    a, b = tmp_path / "a", tmp_path / "b"
    _plan(a, 1, [True] * 8 + [False] * 2)
    _plan(b, 2, [True] * 5 + [False] * 5)
    p = accuracy.pool([a, b])
    assert (p["cases"], p["right"], [q["seed"] for q in p["plans"]]) == (20, 13, ["1", "2"])
    assert p["right_interval"] == pytest.approx(accuracy.wilson_interval(13, 20))
    assert "13 / 20 = **65.0 %**" in accuracy.pooled_markdown(p)
    with pytest.raises(HysbenchError, match="plan seed 1 is given twice"):
        accuracy.pool([a, a])
    with pytest.raises(HysbenchError, match="no accuracy report"):
        accuracy.pool([a, tmp_path / "missing"])
    assert accuracy.main(["--pool", str(a), str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no accuracy report" in err


def test_a_rewritten_report_keeps_its_note_also_from_a_report_written_before_the_note_was_stored(tmp_path):
    rows = _plan(tmp_path, 4, [True, False, True])
    accuracy.write(rows, tmp_path, 1.0, note="Rerun with the fixed generator.\n\nSecond paragraph.")
    accuracy.rewrite(tmp_path)
    text = (tmp_path / "diagnosis_accuracy.md").read_text()
    assert text.startswith("# Accuracy of `hysbench diagnose` on planted effects\n\nRerun with the fixed generator."
                           "\n\nSecond paragraph.\n\n3 cases")
    data = json.loads((tmp_path / "diagnosis_accuracy.json").read_text())
    del data["summary"]["note"]  # an older report: the note only in its markdown
    (tmp_path / "diagnosis_accuracy.json").write_text(json.dumps(data))
    accuracy.rewrite(tmp_path)
    assert (tmp_path / "diagnosis_accuracy.md").read_text() == text
