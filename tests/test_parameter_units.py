"""Every parameter of every model declares its unit, and the unit agrees with how its search bounds follow the
data's scale: a parameter in y/u has bounds that grow with the output's scale and shrink with the input's."""

import json
import math
import re

import pytest
from hypothesis import given, settings, strategies as st

from hysbench.identification.fit import Fit
from hysbench.models import get_model, list_models
from hysbench.models.base import DataScale
from hysbench.models.errors import ModelError
from hysbench.models.extended import ExtendedModel
from hysbench.models.units import dimension, factors, render

EVERY_COMPONENT = ("relaxation", "delay", "resonance", "creep", "interference")
VARIANTS = {name: (lambda name=name: get_model(name)) for name in list_models()} | {
    "mrpim+every-component": lambda: ExtendedModel("mrpim", EVERY_COMPONENT, n_relaxation=2, relaxation_powers=[1, 2]),
    "mrpim+saturation-lower": lambda: get_model("mrpim+saturation", saturation_side="lower"),
    "bouc-wen-oscillator-nu": lambda: get_model("bouc-wen-oscillator", fixed_nu=None),
}

# bounds that do not follow the data's scale, and why
FIXED_BOUNDS = {
    "viscoelastic": {"length": "its bounds come from the hyperparameter length0 (output unit per unit stretch)"},
    "bouc-wen-oscillator": {n: "scaled by the fixed beta, whose unit is 1/y" for n in ("gamma", "delta")},
    **{m: {"sample_time": "fixed to the data's sample time, not searched"} for m in ("narx-mlp", "narx-sparse", "gru")},
}


@pytest.mark.parametrize("name", VARIANTS)
def test_every_parameter_declares_a_unit_that_parses(name):
    model = VARIANTS[name]()
    for p in model.parameters():
        assert p.unit is not None, f"{name}: {p.name} declares no unit"
        factors(p.unit)  # raises on a malformed unit


@settings(max_examples=25, deadline=None)
@given(ku=st.floats(-3, 3), ky=st.floats(-3, 3), kt=st.floats(-3, 3))
def test_bounds_follow_the_scale_as_the_unit_says(ku, ky, kt):
    base = DataScale(u=2.5, y=10.0, time=1.0)
    scaled = DataScale(u=2.5 * 10**ku, y=10.0 * 10**ky, time=10**kt)
    for name, make in VARIANTS.items():
        model = make()
        before = {p.name: p for p in model.parameters(base)}
        for p in model.parameters(scaled):
            dims = dimension(p.unit)
            if dims is None or p.name in FIXED_BOUNDS.get(name.split("+")[0].removesuffix("-nu"), ()):
                continue
            factor = 10 ** (dims[0] * ku + dims[1] * ky + dims[2] * kt)
            for bound in ("min", "max"):
                want = getattr(before[p.name], bound) * factor
                assert math.isclose(getattr(p, bound), want, rel_tol=1e-9, abs_tol=0.0), (
                    f"{model.name}: {p.name} ({p.unit}) {bound} {getattr(p, bound)!r}, expected {want!r}")


def test_units_render_in_the_datasets_terms():
    assert render("y/u^2", "kV", "mm") == "mm/kV^2"
    assert render("u*s^2/y", "N", "m") == "N*s^2/m"
    assert render("y*s^2/u", "V", "m/s") == "(m/s)*s^2/V"
    assert render("1", "kV", "mm") == ""
    assert render("Hz") == "Hz"
    assert render("y/u") == "out/in"
    assert render("u^-1*y") == "out/in"
    assert dimension("kPa*s") is None
    assert dimension("y*s^2/u") == (-1, 1, 2)


@pytest.mark.parametrize("bad", ["", "mm", "y//u", "/y", "y^x", "y*"])
def test_a_malformed_unit_is_refused(bad):
    with pytest.raises(ModelError, match="unit"):
        factors(bad)


def _fit_tiny(tmp_path, units: bool):
    from hysbench.benchmarks.cli import main
    from tiny_dataset import write_tiny_dataset

    folder = write_tiny_dataset(tmp_path / "tiny")
    if units:
        toml = folder / "dataset.toml"
        toml.write_text(toml.read_text().replace('name = "tiny"', 'name = "tiny"\ninput_unit = "V"\noutput_unit = "um"'))
    code = main(["fit", str(folder), "--model", "classical-pi", "--method", "varpro", "--json", str(tmp_path / "fit.json"),
                 "--save", str(tmp_path / "model.json")])
    assert code == 0
    return json.loads((tmp_path / "fit.json").read_text()), json.loads((tmp_path / "model.json").read_text())


def test_a_fit_states_each_parameters_unit_in_the_datasets_units(tmp_path, capsys):
    fit, model_file = _fit_tiny(tmp_path, units=True)
    printed = capsys.readouterr().out
    assert fit["input_unit"] == "V" and fit["param_units"]["a1"] == "um/V" and fit["param_units"]["offset"] == "um"
    assert model_file["param_units"] == fit["param_units"]
    assert re.search(r"a1 = \S+ um/V", printed) and "do not name" not in printed
    assert Fit.from_dict(fit).param_units == fit["param_units"]


def test_without_the_datasets_units_in_and_out_stand_for_them(tmp_path, capsys):
    fit, _ = _fit_tiny(tmp_path, units=False)
    printed = capsys.readouterr().out
    assert fit["param_units"]["a1"] == "out/in"
    assert re.search(r"a1 = \S+ out/in", printed) and "which the dataset does not name" in printed
