"""The unseen-waveform protocol (scores from stored Fits) and `hysbench run --suite measured`."""

import csv
import math

import numpy as np
import pytest

from hysbench.benchmarks.cli import main
from hysbench.benchmarks.matrix import measured, unseen
from hysbench.benchmarks.matrix.cells import plan_cells, run_cell
from hysbench.data import load_dataset, save_dataset
from hysbench.data.metrics import e_rms
from hysbench.data.protocol import simulated_dataset
from hysbench.identification import Fit
from hysbench.models import get_model, list_models

FAST = ["--models", "classical-pi", "--methods", "lsq", "--option", "lsq.max_nfev=30", "--jobs", "1", "--quiet"]


def _simulated(folder, name, frequencies, seed):
    model = get_model("mrpim")
    ds = simulated_dataset(model, model.preset("paper"), n_periods=1.5, noise_sd=0.01, seed=seed,
                           frequencies=frequencies, name=name)
    return save_dataset(ds, folder)


@pytest.fixture(scope="module")
def sines(tmp_path_factory):
    """A small dataset named like the virtual DEA, and records at frequencies it does not hold."""
    root = tmp_path_factory.mktemp("unseen")
    return (_simulated(root / "sines", unseen.IDENTIFIED_ON, (0.4, 1.0), seed=1),
            _simulated(root / "other", "other-drives", (0.2, 0.8), seed=2))


def test_unseen_records_are_scored_from_the_stored_fit_without_refitting(sines):
    fitted, other = load_dataset(sines[0]), load_dataset(sines[1])
    cell = plan_cells([(sines[0], fitted)], ["classical-pi"], ["lsq"], seed=0,
                      method_options={"lsq": {"max_nfev": 30}})[0]
    result = run_cell(cell)
    assert result["status"] == "ok"
    scored = unseen.score_cells([result], other)
    assert len(scored) == 1 and scored[0]["status"] == "ok"
    fit = Fit.from_dict(result["fit"])
    assert not set(fit.fitted_on) & {r.file for r in other.records}  # records it was not fitted on
    for rec, s in zip(other.records, scored[0]["records"]):
        y = fit.model_instance().simulate(rec.u, rec.dt, result["params"], input_range=fit.input_range)
        assert s["e_rms"] == pytest.approx(e_rms(y[rec.scored], rec.y[rec.scored]), rel=1e-12)
        assert 0 < s["e_rms"] < 50
    broken = {**result, "fit": {**result["fit"], "params": {k: math.nan for k in result["params"]}}}
    bad = unseen.score_unseen(broken, other)
    assert bad["status"] == "nonfinite" and bad["records"] == []
    assert set(bad["nonfinite_records"]) == {r.file for r in other.records} and "non-finite" in bad["error"]
    assert "non-finite" in unseen.unseen_csv([bad]).replace("nonfinite", "non-finite")


def test_unseen_scores_are_read_back_for_the_same_cell_and_dataset_and_scored_again_otherwise(sines, tmp_path,
                                                                                             monkeypatch):
    fitted, other = load_dataset(sines[0]), load_dataset(sines[1])
    cell = plan_cells([(sines[0], fitted)], ["classical-pi"], ["lsq"], seed=0,
                      method_options={"lsq": {"max_nfev": 30}})[0]
    result = run_cell(cell)
    cache = tmp_path / unseen.CACHE_FILE
    first = unseen.score_cells([result], other, cache=cache)
    calls = []
    real = unseen.score_unseen
    monkeypatch.setattr(unseen, "score_unseen", lambda r, ds: calls.append(ds.name) or real(r, ds))
    assert unseen.score_cells([result], other, cache=cache) == first and calls == []  # read back, exactly
    unseen.score_cells([result], fitted, cache=cache)  # another dataset: scored
    assert calls == [fitted.name]
    cache.write_text("{not json")
    assert unseen.score_cells([result], other, cache=cache) == first and calls[-1] == other.name


def test_hysbench_run_reports_both_protocols(sines, tmp_path):
    assert main(["run", str(sines[0]), "--unseen", str(sines[1]), "--out", str(tmp_path), *FAST]) == 0
    report = (tmp_path / "report.md").read_text()
    assert "## Unseen waveforms" in report and "| classical-pi (lsq) |" in report.split("## Unseen")[1]
    with open(tmp_path / unseen.UNSEEN_CSV) as fh:
        rows = list(csv.DictReader(fh))
    assert {r["record"] for r in rows} == {r.file for r in load_dataset(sines[1]).records}


def test_the_measured_suite_scores_every_manifest_and_hints_at_bare_csvs(sines, tmp_path, capsys):
    root = tmp_path / "datasets"
    _simulated(root / "piezo_a", "piezo-a", (0.4, 1.0), seed=3)
    bare = root / "bare_csv"
    bare.mkdir()
    ds = load_dataset(sines[1])
    rec = ds.records[0]
    np.savetxt(bare / "rec.csv", np.column_stack([rec.t, rec.u, rec.y]), delimiter=",", fmt="%.12g")
    out = tmp_path / "results"
    assert main(["run", str(bare), "--out", str(out)]) == 2  # run on the bare folder itself: the same hint
    assert "hysbench dataset init" in capsys.readouterr().err
    assert main(["run", "--suite", "measured", "--datasets-root", str(root), "--out", str(out), *FAST]) == 0
    err = capsys.readouterr().err
    assert "hysbench dataset init" in err and "bare_csv" in err and len(err.strip().splitlines()) == 1
    assert (out / measured.MEASURED_REPORT).is_file() and (out / measured.MEASURED_CELLS).is_dir()
    assert not (out / "report.md").exists() and not (out / "matrix.csv").exists()
    # the hint's two commands: describe the CSV, then score it
    assert main(["dataset", "init", str(bare / "rec.csv"), "--time", "0", "--input", "1", "--output", "2",
                 "--frequency", str(rec.frequency_hz)]) == 0
    assert main(["run", "--suite", "measured", "--datasets-root", str(root), "--out", str(out), *FAST]) == 0
    with open(out / measured.MEASURED_CSV) as fh:
        assert {r["dataset"] for r in csv.DictReader(fh)} == {"piezo-a", "rec"}
    assert "no dataset.toml" not in (out / measured.MEASURED_REPORT).read_text()


def test_the_measured_suite_refuses_a_missing_root_and_a_dataset_argument(tmp_path, capsys):
    assert main(["run", "--suite", "measured", "--datasets-root", str(tmp_path / "none")]) == 2
    assert main(["run", "--suite", "measured", "somewhere", "--datasets-root", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "is not a folder" in err[0] and "takes no DATASET" in err[1]


def test_the_shared_measured_datasets_are_found(shared_datasets):
    found, skipped = measured.discover(shared_datasets)
    names = {ds.name for _, ds in found}
    assert {"piezo-sindy-1hz", "pzt-ceramic", "bouc-wen-benchmark"} <= names


def test_the_measured_suite_adds_the_bouc_wen_oscillator_to_the_matrix_models():
    models = measured.suite_models()
    assert models[:len(list_models(matrix_only=True))] == list_models(matrix_only=True)
    assert "bouc-wen-oscillator" in models and "bouc-wen-oscillator" not in list_models(matrix_only=True)
