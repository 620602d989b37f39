"""The grey-/black-box label and the benchmarks' NRMSE and fit (%) in the reports."""

import numpy as np
import pytest

from hysbench.benchmarks.matrix.report import kind_of, ranking_table
from hysbench.benchmarks.reports.bouc_wen import fit_percent, kind, nrmse, rmse
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
