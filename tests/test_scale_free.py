"""Scale-free numerics: the output multiplied by any factor the loader accepts gives the same errors and
verdicts (computed at order one, scaled by an exact power of two); a factor that takes a value out of the
representable range (subnormal, or beyond the loader's limit) is refused in one line."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hysbench.benchmarks.cli import main as cli
from hysbench.data.dataset import MAX_MAGNITUDE, MIN_MAGNITUDE, DatasetError, load_dataset
from hysbench.data.metrics import e_m, e_rms, fitness
from hysbench.identification.api import identify

from tiny_dataset import tiny_records, write_tiny_dataset

REL = 1e-9
# factors m * 2^k: the mantissa m makes the scaled data differ in every bit from the original
factors = st.builds(lambda m, k: math.ldexp(m, k), st.sampled_from([1.0, 0.3, 1.7, 0.9]), st.integers(-1080, 400))


def _accepted(factor: float) -> bool:
    ys = [y * factor for _, _, y in tiny_records().values()]
    return all(np.all(np.abs(y) <= MAX_MAGNITUDE) and np.all((y == 0) | (np.abs(y) >= MIN_MAGNITUDE)) for y in ys)


@pytest.fixture(scope="module")
def reference_fit(tmp_path_factory):
    return identify("classical-pi", write_tiny_dataset(tmp_path_factory.mktemp("ref")), method="varpro")


def test_metrics_by_hand_at_extreme_scales():
    y, ya = np.array([1.0, 2.0, 4.0]), np.array([1.5, 2.0, 3.0])
    by_hand = 100 * math.sqrt((0.25 + 0 + 1) / 3) / 1.5  # span of the measured output 1.5
    for factor in (1.0, 1e-200, 1e-300, 2.0**-1000, 1e200):
        assert e_rms(y * factor, ya * factor) == pytest.approx(by_hand, rel=1e-14)
        assert e_m(y * factor, ya * factor) == pytest.approx(100 / 1.5, rel=1e-14)
    assert fitness([y * 1e-100], [ya * 1e-100], [1.0]) == pytest.approx(1.25 / 3 * 1e-200, rel=1e-14)


@settings(max_examples=12, deadline=None)
@given(factor=factors)
@example(factor=1e-200)
@example(factor=1e200)
@example(factor=2.0**-1060)
def test_fit_is_scale_free(tmp_path_factory, reference_fit, factor):
    folder = tmp_path_factory.mktemp("scaled")
    write_tiny_dataset(folder, factor)
    if not _accepted(factor):
        with pytest.raises(DatasetError, match="subnormal|beyond") as err:
            load_dataset(folder)
        assert "\n" not in str(err.value)
        return
    fit = identify("classical-pi", folder, method="varpro")
    for got, want in zip(fit.records, reference_fit.records):
        assert got.e_rms == pytest.approx(want.e_rms, rel=REL) and got.e_m == pytest.approx(want.e_m, rel=REL)
    if fit.fitness > 0 and math.isfinite(fit.fitness):
        assert fit.fitness / factor**2 == pytest.approx(reference_fit.fitness, rel=1e-6)


def _matrix_errors(out) -> dict:
    with open(out / "matrix.csv", newline="") as fh:
        return {row["record"]: (float(row["e_m"]), float(row["e_rms"])) for row in csv.DictReader(fh)}


@settings(max_examples=2, deadline=None)
@given(factor=factors.filter(_accepted))
@example(factor=1e-200)
@example(factor=2.0**-900)
def test_run_metrics_are_scale_free(tmp_path_factory, factor):
    scores = [_run_errors(tmp_path_factory, f) for f in (1.0, factor)]
    assert scores[0].keys() == scores[1].keys()
    for record, (em, erms) in scores[0].items():
        assert scores[1][record][0] == pytest.approx(em, rel=REL)
        assert scores[1][record][1] == pytest.approx(erms, rel=REL)


_done: dict = {}  # (command, factor) -> its outcome: the unscaled reference is computed once


def _run_errors(tmp_path_factory, factor) -> dict:
    if ("run", factor) not in _done:
        root = tmp_path_factory.mktemp("run")
        assert cli(["run", str(write_tiny_dataset(root / "tiny", factor)), "--models", "classical-pi", "--methods",
                    "varpro", "--jobs", "1", "--quiet", "--out", str(root / "out")]) == 0
        _done["run", factor] = _matrix_errors(root / "out")
    return _done["run", factor]


def _diagnosis(tmp_path_factory, factor) -> dict:
    if ("diagnose", factor) not in _done:
        root = tmp_path_factory.mktemp("diagnose")
        assert cli(["diagnose", str(write_tiny_dataset(root / "tiny", factor)), "--model", "classical-pi",
                    "--max-rows", "200", "--quiet", "--out", str(root / "out")]) == 0
        _done["diagnose", factor] = json.loads((root / "out" / "diagnosis.json").read_text())
    return _done["diagnose", factor]


@settings(max_examples=1, deadline=None)
@given(factor=factors.filter(_accepted))
@example(factor=1e-200)
def test_diagnose_verdict_is_scale_free(tmp_path_factory, factor):
    a, b = _diagnosis(tmp_path_factory, 1.0), _diagnosis(tmp_path_factory, factor)
    verdict = lambda d: (d["cause"], d["ambiguous_with"], (d["partial"] or {}).get("cause"))  # noqa: E731
    assert verdict(b) == verdict(a)
    for ca, cb in zip(a["evidence"]["candidates"], b["evidence"]["candidates"], strict=True):
        assert (cb["cause"], cb["admissible"]) == (ca["cause"], ca["admissible"])
        assert cb["heldout"]["gain"] == pytest.approx(ca["heldout"]["gain"], rel=1e-6, abs=1e-9)
        assert cb["heldout"]["folds_improved"] == ca["heldout"]["folds_improved"]
