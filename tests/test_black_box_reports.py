"""The grey-/black-box label and the benchmarks' NRMSE and fit (%) in the reports."""

import json
import re
from pathlib import Path

import numpy as np
import pytest

from hysbench.benchmarks.matrix.report import kind_of, ranking_table
from hysbench.benchmarks.reports.bouc_wen import _label, fit_percent, kind, nrmse, render, rmse
from hysbench.models import get_model, list_models


def test_nrmse_and_fit_by_hand():
    y = np.array([1.0, 2.0, 4.0, 5.0])
    y_hat = np.array([1.5, 2.0, 3.0, 5.0])
    by_hand = np.sqrt((0.25 + 0 + 1 + 0) / 4) / np.sqrt(((y - 3.0) ** 2).mean())
    assert nrmse(y_hat, y) == pytest.approx(by_hand)
    assert fit_percent(y_hat, y) == pytest.approx(100 * (1 - np.linalg.norm(y - y_hat) / np.linalg.norm(y - y.mean())))
    assert fit_percent(y, y) == 100.0 and rmse(y, y) == 0.0


def test_every_registered_model_is_labelled():
    black = {"narx-sparse", "narx-mlp", "gru"}
    for name in list_models():
        assert kind_of(name) == ("black-box" if name in black else "grey-box")
        assert kind(get_model(name)) == kind_of(name)
    assert kind_of("no-such-model") == "–"


def test_the_ranking_table_names_the_kind():
    res = {"model": "narx-sparse", "method": "native", "n_params": 40, "fitness": 1.0, "fit_seconds": 1.0,
           "simulate_seconds": 0.1}
    summary = {"val_mean": 5.0, "val_worst": 8.0, "val_em_worst": 15.0, "ranked_on": "validation"}
    lines = ranking_table([(res, summary)])
    assert "| kind |" in lines[0] and "| narx-sparse | black-box | native |" in lines[2]


def test_the_bouc_wen_report_lists_a_black_box_by_its_count_of_values_not_its_weights():
    stored = json.loads((Path(__file__).parents[1] / "results" / "bouc_wen_benchmark.json").read_text())
    text = render(stored)
    for row in stored["rows"]:
        line = next(ln for ln in text.splitlines() if ln.startswith(f"- {_label(row)} ({row['how']}):"))
        if row["kind"] == "black-box":
            assert f"{len(row['params'])} values" in line and " = " not in line
        else:
            assert all(f"{k} = " in line for k in row["params"])


def test_the_bouc_wen_report_names_a_learner_it_did_not_run():
    """Without PyTorch the report has no gru row; it says so instead of reading as every learner."""
    stored = json.loads((Path(__file__).parents[1] / "results" / "bouc_wen_benchmark.json").read_text())
    assert "not_run" not in stored and "Not run:" not in render(stored)
    stored["rows"] = [row for row in stored["rows"] if row["model"] != "gru"]
    stored["not_run"] = [{"model": "gru", "reason": "PyTorch is not installed"}]
    text = render(stored)
    assert "Not run: gru (PyTorch is not installed); the table and the comparisons below leave it out." in text
    assert "| gru |" not in text


def test_the_bouc_wen_report_gives_each_parameter_in_the_datasets_units():
    stored = json.loads((Path(__file__).parents[1] / "results" / "bouc_wen_benchmark.json").read_text())
    text = render({**stored, "input_unit": "N", "output_unit": "m"})
    assert re.search(r"m = [\d.]+ N\*s\^2/m, c = [\d.]+ N\*s/m, k = [\d.]+ N/m", text)
    assert re.search(r"a2 = [-\d.e]+ m/N", text)
