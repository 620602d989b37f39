"""The top-level API (``import hysbench as hb``) and the version the package reports."""

import subprocess
import sys
from importlib.metadata import version

import numpy as np
import pytest

import hysbench as hb
import hysbench.identification
import hysbench.models
from hysbench.benchmarks.cli import main

NAMES = ["load_dataset", "get_model", "list_models", "identify", "run_matrix", "diagnose", "load_model"]


@pytest.mark.parametrize("name", NAMES)
def test_every_name_has_a_docstring_with_an_example(name):
    doc = getattr(hb, name).__doc__
    assert doc and "Example::" in doc and "import hysbench as hb" in doc


def test_the_docstring_examples_give_what_they_show():
    """Every example of the API's docstrings runs and prints what it shows (those marked +SKIP take long)."""
    import doctest

    import hysbench.benchmarks.api as api

    result = doctest.testmod(api, optionflags=doctest.ELLIPSIS, verbose=False)
    assert result.failed == 0 and result.attempted >= 10


def test_version_is_the_installed_distribution():
    assert hb.__version__ == version("hysbench") == "0.2.0"


def test_cli_prints_the_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"hysbench {version('hysbench')}"


def test_import_loads_no_layer():
    code = "import sys, hysbench; print(sorted(m for m in sys.modules if m.startswith('hysbench.')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_registry_names_and_models():
    assert hb.list_models() == hysbench.models.list_models()
    assert hb.list_models(matrix_only=True) == hysbench.models.list_models(matrix_only=True)
    assert hb.get_model("mrpim", offset=False).n_params == 20
    with pytest.raises(hysbench.models.HysbenchError, match="unknown model"):
        hb.get_model("no-such-model")


def test_default_dataset_and_a_folder_are_the_same():
    from hysbench.data.virtual_dea import default_dataset_path

    default = hb.load_dataset()
    assert default.content_hash() == hb.load_dataset(default_dataset_path()).content_hash()
    assert [r.frequency_hz for r in default.records if r.role == "validation"] == [0.05, 0.2, 0.8]


@pytest.fixture(scope="module")
def classical_pi_fit():
    return hb.identify("classical-pi", method="varpro", seed=0, n_candidates=8, n_starts=1)


def test_identify_defaults_to_the_shipped_dataset(classical_pi_fit):
    direct = hysbench.identification.identify("classical-pi", hb.load_dataset(), method="varpro", seed=0,
                                              n_candidates=8, n_starts=1)
    assert classical_pi_fit.params == direct.params
    assert {s.role for s in classical_pi_fit.records} == {"identification", "validation"}


def test_run_matrix_scores_a_cell_as_identify_does(classical_pi_fit, tmp_path):
    # the matrix's varpro budget is n_candidates=8, n_starts=1: the same fit as above
    rows = hb.run_matrix(models=["classical-pi"], methods=["varpro"], out=tmp_path)
    assert [(r["model"], r["method"], r["status"]) for r in rows] == [("classical-pi", "varpro", "ok")]
    assert rows[0]["params"] == pytest.approx(classical_pi_fit.params, rel=1e-12)
    assert len(list((tmp_path / "cells").glob("*.json"))) == 1  # kept for the next call
    again = hb.run_matrix(models=["classical-pi"], methods=["varpro"], out=tmp_path)
    assert again == rows


def test_diagnose_passes_the_default_dataset_and_settings(monkeypatch):
    import hysbench.benchmarks.api as api

    seen = {}
    monkeypatch.setattr(api, "diagnose_model", lambda ds, model, **kw: seen.update(ds=ds, model=model, **kw))
    hb.diagnose(model="classical-pi", seed=3, segments=2)
    assert seen["ds"].content_hash() == hb.load_dataset().content_hash()
    assert (seen["model"], seen["seed"], seen["segments"]) == ("classical-pi", 3, 2)


def test_load_model_gives_back_the_saved_fit(classical_pi_fit, tmp_path):
    record = hb.load_dataset().records[0]
    dt = float(record.t[1] - record.t[0])
    path = classical_pi_fit.fitted_model(dt).save(tmp_path / "m.json")
    loaded = hb.load_model(path)
    assert np.array_equal(loaded.simulate(record.u), classical_pi_fit.simulate(record.u, dt))
