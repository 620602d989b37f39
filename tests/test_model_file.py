"""The model file: save -> load gives the same model (bit for bit); bad files are refused in one line."""

import json
import os
from pathlib import Path

import numpy as np
import pytest

from hysbench.benchmarks.cli import main
from hysbench.models import MRPIM, FittedModel, ModelFileError, get_model, load_model
from hysbench.models.model_file import FORMAT_VERSION, REQUIRED

ROOT = Path(__file__).resolve().parents[1]


def fitted_mrpim_relaxation() -> FittedModel:
    model = get_model("mrpim+relaxation")
    params = dict(MRPIM().preset("paper"), tau1=0.3, c1=0.7123456789012345)
    return FittedModel(model, params, (0.5, 2.5), 1e-3, {"input_unit": "kV", "output_unit": "mm"})


def drive(n=700, dt=1e-3):
    t = np.arange(n) * dt
    return 1.5 - np.cos(2 * np.pi * 1.3 * t) + 0.05 * np.sin(2 * np.pi * 17 * t)


def test_saved_and_loaded_model_simulates_bit_for_bit(tmp_path):
    fitted = fitted_mrpim_relaxation()
    path = fitted.save(tmp_path / "m.json")
    loaded = load_model(path)
    assert loaded.name == "mrpim+relaxation" and loaded.params == fitted.params
    assert loaded.input_range == (0.5, 2.5) and loaded.sample_time == 1e-3
    u = drive()
    assert np.array_equal(loaded.simulate(u), fitted.simulate(u))
    d = json.loads(path.read_text())
    assert d["format_version"] == FORMAT_VERSION and set(REQUIRED) <= set(d)
    assert d["input_unit"] == "kV" and d["hysbench_version"]


@pytest.mark.parametrize("change, named", [
    (lambda d: d.update(format_version=FORMAT_VERSION + 1), "upgrade hysbench"),
    (lambda d: d.pop("sample_time"), "missing field(s) sample_time"),
    (lambda d: d.update(model="no-such-model"), "unknown model 'no-such-model'"),
    (lambda d: d["params"].pop("a3"), "missing a3"),
    (lambda d: d.update(format="something-else"), "not a hysbench model file"),
])
def test_bad_model_file_is_refused_in_one_line(tmp_path, change, named):
    d = fitted_mrpim_relaxation().to_dict()
    change(d)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(d))
    with pytest.raises(ModelFileError) as err:
        load_model(path)
    assert named in str(err.value) and "\n" not in str(err.value)



def _text_of(change) -> str:
    d = fitted_mrpim_relaxation().to_dict()
    d["sample_time"] = "SAMPLE_TIME"
    change(d)
    return json.dumps(d).replace('"SAMPLE_TIME"', "0.001")


@pytest.mark.parametrize("text, named", [
    ("[" * 100000 + "]" * 100000, "nested too deeply"),
    (_text_of(lambda d: None).replace('"sample_time": 0.001', '"sample_time": ' + "1" * 5000), "too many digits"),
    (_text_of(lambda d: None).replace('"sample_time": 0.001', '"sample_time": ' + "1" * 400),
     "sample_time is not a finite number"),
    (_text_of(lambda d: d["params"].update(c1="1" * 400)).replace('"' + "1" * 400 + '"', "1" * 400),
     "params.c1 is not a finite number"),
    (_text_of(lambda d: d.update(model=["mrpim"])), "model must be a registry name"),
    (_text_of(lambda d: d.update(input_range=5)), "input_range must be [low, high]"),
    (_text_of(lambda d: d["params"].update(c1=True)), "params.c1 must be a number, got true"),
    (_text_of(lambda d: None).replace('"sample_time": 0.001', '"sample_time": true'), "sample_time must be a number"),
    (_text_of(lambda d: d.update(scale="x")), "scale must be a JSON object"),
    (_text_of(lambda d: d.update(scale={"time": "x"})), "scale.time must be a number"),
    (_text_of(lambda d: d.update(scale={"time": -1})), "scale.time must be positive"),
    (_text_of(lambda d: d.update(scores=[])), "scores must be a JSON object"),
    (_text_of(lambda d: d.update(output_unit=3)), "output_unit must be a string"),
], ids=["deep", "digits", "int-overflow", "param-overflow", "model-list", "range-number", "param-bool", "time-bool",
        "scale-text", "scale-text-value", "scale-negative", "scores-list", "unit-number"])
def test_a_malformed_model_file_is_refused_in_one_line(tmp_path, text, named):
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(ModelFileError) as err:
        load_model(path)
    assert named in str(err.value) and "\n" not in str(err.value)


def test_a_fifo_or_a_folder_as_model_file_is_refused_without_reading_it(tmp_path):
    os.mkfifo(tmp_path / "m.json")  # reading it would wait for a writer forever
    with pytest.raises(ModelFileError, match="not a regular file"):
        load_model(tmp_path / "m.json")
    with pytest.raises(ModelFileError, match="is a folder"):
        load_model(tmp_path)

@pytest.mark.parametrize("version, spelled", [
    (FORMAT_VERSION + 1, str(FORMAT_VERSION + 1)), (0, "0"), (-3, "-3"), (str(FORMAT_VERSION), f'"{FORMAT_VERSION}"'),
    (float(FORMAT_VERSION), f"{FORMAT_VERSION}.0"), (True, "true"), (None, "null"),
])
def test_model_file_of_another_format_version_is_refused_naming_both_versions(tmp_path, version, spelled):
    d = fitted_mrpim_relaxation().to_dict()
    d["format_version"] = version
    path = tmp_path / "m.json"
    path.write_text(json.dumps(d))
    with pytest.raises(ModelFileError) as err:
        load_model(path)
    message = str(err.value)
    assert f"format_version {spelled}, but this hysbench reads format_version {FORMAT_VERSION} only" in message
    assert "\n" not in message


def test_model_file_without_a_format_version_is_refused(tmp_path):
    d = fitted_mrpim_relaxation().to_dict()
    del d["format_version"]
    with pytest.raises(ModelFileError, match=f"no format_version, but this hysbench reads format_version "
                                             f"{FORMAT_VERSION} only"):
        FittedModel.from_dict(d)


def test_not_json_and_missing_file(tmp_path):
    (tmp_path / "x.json").write_text("{not json")
    with pytest.raises(ModelFileError, match="not JSON"):
        load_model(tmp_path / "x.json")
    with pytest.raises(ModelFileError, match="does not exist"):
        load_model(tmp_path / "none.json")


def test_fit_save_writes_a_model_file_that_reproduces_the_fit(tmp_path, capsys):
    out = tmp_path / "pi.json"
    fit_json = tmp_path / "fit.json"
    code = main(["fit", str(ROOT / "data" / "virtual_dea"), "--model", "classical-pi", "--method", "varpro",
                 "--hyper", "n_operators=5", "--save", str(out), "--json", str(fit_json)])
    assert code == 0, capsys.readouterr().err
    loaded = load_model(out)
    fit = json.loads(fit_json.read_text())
    assert loaded.params == fit["params"] and list(loaded.input_range) == fit["input_range"]
    d = json.loads(out.read_text())
    assert d["dataset"]["content_hash"] == fit["dataset_hash"] and d["identifier"]["method"] == "varpro"
    assert d["sample_time"] > 0 and d["input_unit"] == "kV" and d["output_unit"] == "mm"
    validation = [r["e_rms"] for r in fit["records"] if r["role"] == "validation"]
    assert d["scores"]["validation_e_rms"] == max(validation)
    # the fit's result is not a model file: the refusal names what it is and how a model file is written
    code = main(["export", str(fit_json), "--out", str(tmp_path / "c"), "--prefix", "pi"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and not (tmp_path / "c").exists()
    assert f"format {fit['format']!r}" in err and "--save" in err


@pytest.mark.parametrize("version", [FORMAT_VERSION + 1, 0])
def test_cli_refuses_a_model_file_of_another_format_version_with_status_2(tmp_path, capsys, version):
    d = fitted_mrpim_relaxation().to_dict()
    d["format_version"] = version
    (tmp_path / "m.json").write_text(json.dumps(d))
    code = main(["export", str(tmp_path / "m.json"), "--out", str(tmp_path / "c"), "--prefix", "dea"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert f"format_version {version}, but this hysbench reads format_version {FORMAT_VERSION} only" in err
    assert not (tmp_path / "c").exists()
