"""Model hyperparameters are validated, never coerced (models/hyperparameters.py).

A boolean hyperparameter takes only True/False (not "no", "off", 2 or None); an
integer one only an integer within its bounds (not True, not 13.0); size
hyperparameters have an upper bound. Each refusal is a ModelError naming the
hyperparameter and the value, which the CLI prints as one line with status 2.
"""

import inspect

import numpy as np
import pytest

from hysbench.benchmarks.cli import main as hysbench
from hysbench.data.virtual_dea import default_dataset_path
from hysbench.models import ModelError, get_model, list_models
from hysbench.models.hyperparameters import MAX_OPERATORS, check_bool, check_int, check_number
from hysbench.models.registry import _REGISTRY

NOT_BOOLEANS = ["no", "off", "maybe", "true", "false", 2, 1, 0, None, 1.0, [True]]
NOT_INTEGERS = [True, False, 13.0, 2.5, "13", None, [13]]

# (model, boolean hyperparameter): every one the registered models take
BOOLEANS = [
    ("mrpim", "q_term"), ("mrpim", "envelopes"), ("mrpim", "offset"),
    ("classical-pi", "offset"), ("rate-dependent-pi", "offset"), ("preisach", "offset"),
    ("bouc-wen", "offset"), ("elliptical", "offset"), ("dual-polynomial", "offset"), ("viscoelastic", "offset"),
]

# (model, integer hyperparameter, lowest, highest allowed)
INTEGERS = [
    ("mrpim", "n_operators", 1, MAX_OPERATORS), ("mrpim", "poly_order", 0, 12),
    ("classical-pi", "n_operators", 1, MAX_OPERATORS), ("classical-pi", "poly_order", 0, 12),
    ("rate-dependent-pi", "n_operators", 1, MAX_OPERATORS), ("rate-dependent-pi", "poly_order", 0, 12),
    ("preisach", "grid_size", 1, 100), ("elliptical", "poly_order", 1, 8), ("dual-polynomial", "order", 2, 12),
    ("viscoelastic", "n_branches", 0, 8), ("viscoelastic", "warmup_stride", 1, 1000),
    ("bouc-wen-oscillator", "n_substeps", 1, 1000), ("mrpim+relaxation", "n_relaxation", 1, 6),
    ("narx-sparse", "n_output_lags", 1, 20), ("narx-sparse", "n_input_lags", 1, 20), ("narx-sparse", "degree", 1, 5),
    ("narx-sparse", "n_thresholds", 1, 100), ("narx-sparse", "max_iter", 1, 10_000),
    ("narx-mlp", "n_output_lags", 1, 20), ("narx-mlp", "n_input_lags", 1, 20), ("narx-mlp", "width", 1, 1024),
    ("narx-mlp", "depth", 1, 8), ("narx-mlp", "max_epochs", 1, 100_000), ("narx-mlp", "max_rows", 10, 10_000_000),
    ("narx-mlp", "seed", 0, 2**32 - 1), ("gru", "width", 1, 1024), ("gru", "window", 2, 1_000_000),
    ("gru", "washout", 0, 1_000_000), ("gru", "max_epochs", 1, 100_000), ("gru", "seed", 0, 2**32 - 1),
]


def _defaults(name: str) -> dict:
    """Constructor defaults of a registered model class (empty for factories such as mrpim+delay)."""
    factory = _REGISTRY[name]
    if not inspect.isclass(factory):
        return {}
    return {k: p.default for k, p in inspect.signature(factory.__init__).parameters.items()
            if k != "self" and p.default is not inspect.Parameter.empty}


def test_the_tables_cover_every_boolean_and_integer_hyperparameter():
    for name in list_models():
        for key, default in _defaults(name).items():
            if isinstance(default, bool):
                assert (name, key) in BOOLEANS, f"add {name}.{key} to BOOLEANS"
            elif isinstance(default, int):
                assert any(m == name and k == key for m, k, _, _ in INTEGERS), f"add {name}.{key} to INTEGERS"


@pytest.mark.parametrize("model,key", BOOLEANS)
@pytest.mark.parametrize("value", NOT_BOOLEANS, ids=repr)
def test_boolean_hyperparameters_refuse_anything_but_a_bool(model, key, value):
    with pytest.raises(ModelError, match=rf"{model}: {key} must be true or false, got ") as info:
        get_model(model, **{key: value})
    assert repr(value) in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("model,key", BOOLEANS)
def test_boolean_hyperparameters_take_true_and_false(model, key):
    for value in (True, False, np.True_, np.False_):
        m = get_model(model, **{key: value})
        assert getattr(m, key) is bool(value)  # numpy booleans are stored as plain bools
    assert get_model(model, **{key: False}).n_params == get_model(model, **{key: True}).n_params - (
        1 if key in ("q_term", "offset") else 2)


def test_q_term_takes_only_true_or_false():
    """q_term="no" is refused, not read as true (which would keep 21 parameters)."""
    assert get_model("mrpim", q_term=False).n_params == 20
    with pytest.raises(ModelError, match="q_term must be true or false, got 'no'"):
        get_model("mrpim", q_term="no")
    with pytest.raises(ModelError, match="offset must be true or false, got None"):  # null is not "off"
        get_model("mrpim", offset=None)


@pytest.mark.parametrize("model,key,lo,hi", INTEGERS)
def test_integer_hyperparameters_refuse_bools_and_non_integers(model, key, lo, hi):
    for value in NOT_INTEGERS:
        with pytest.raises(ModelError, match=rf"{key} must be an integer in {lo}\.\.{hi}, got ") as info:
            get_model(model, **{key: value})
        assert repr(value) in str(info.value)


@pytest.mark.parametrize("model,key,lo,hi", INTEGERS)
def test_integer_hyperparameters_are_bounded(model, key, lo, hi):
    for value in (lo - 1, hi + 1):
        with pytest.raises(ModelError, match=rf"{key} must be an integer in {lo}\.\.{hi}, got {value}"):
            get_model(model, **{key: value})
    for value in (lo, hi, np.int64(hi)):
        got = getattr(get_model(model, **{key: value}), key)
        assert got == value and type(got) is int


def test_n_operators_has_an_upper_bound():
    """n_operators=100000000 is refused before any memory is allocated for it."""
    for model in ("classical-pi", "mrpim", "rate-dependent-pi"):
        with pytest.raises(ModelError, match=r"n_operators must be an integer in 1\.\.1000, got 100000000"):
            get_model(model, n_operators=100_000_000)
        assert get_model(model, n_operators=1000).n_operators == 1000


def test_number_hyperparameters_refuse_bools_and_text():
    for model, key in (("mrpim", "derivative_window"), ("rate-dependent-pi", "derivative_window"),
                       ("viscoelastic", "gent_limit"), ("bouc-wen-oscillator", "beta")):
        for value in (True, "0.1", None, float("nan"), float("inf"), 0.0, -1.0):
            with pytest.raises(ModelError, match=rf"{key} must be a positive number, got "):
                get_model(model, **{key: value})
    with pytest.raises(ModelError, match="fixed_nu"):
        get_model("bouc-wen-oscillator", fixed_nu=True)
    assert get_model("bouc-wen-oscillator", fixed_nu=None).fixed_nu is None


def test_choice_hyperparameters_refuse_other_values():
    for model, key in (("mrpim", "derivative"), ("rate-dependent-pi", "derivative"), ("elliptical", "linearise"),
                       ("bouc-wen-oscillator", "input_interpolation"), ("mrpim+saturation", "saturation_side")):
        for value in ("nope", True, None, ["backward"]):
            with pytest.raises(ModelError, match=rf"{key} must be one of "):
                get_model(model, **{key: value})


def test_extended_model_hyperparameters():
    with pytest.raises(ModelError, match="q_term must be true or false, got 'no'"):
        get_model("mrpim+relaxation", base_hyperparameters={"q_term": "no"})
    with pytest.raises(ModelError, match="base_hyperparameters must be a mapping"):
        get_model("mrpim+relaxation", base_hyperparameters="q_term=false")
    for value in ([1.5], [True], "12", [], [0], [5], 2, [1, 1]):
        with pytest.raises(ModelError, match="relaxation_powers"):
            get_model("mrpim+relaxation", relaxation_powers=value)
    assert get_model("mrpim+relaxation", relaxation_powers=[1, np.int64(2)]).relaxation_powers == (1, 2)
    with pytest.raises(ModelError, match="components must be a list of names, got 'relaxation'"):
        get_model("mrpim+relaxation", components="relaxation")  # not its letters
    assert get_model("mrpim+relaxation", components=["relaxation"]).components == ("relaxation",)


def test_the_helpers_name_owner_key_and_value():
    assert check_bool("m", "flag", np.True_) is True
    with pytest.raises(ModelError, match=r"^m: flag must be true or false, got 'off'$"):
        check_bool("m", "flag", "off")
    assert check_int("m", "n", np.int32(3), 1) == 3
    with pytest.raises(ModelError, match=r"^m: n must be an integer >= 2, got 1$"):
        check_int("m", "n", 1, 2)
    assert check_number("m", "x", 2, positive=True) == 2.0


@pytest.mark.parametrize("name", list_models())
def test_an_unknown_hyperparameter_is_named_with_the_model_and_what_the_model_takes(name):
    takes = ", ".join(get_model(name).get_hyperparameters())
    with pytest.raises(ModelError) as info:
        get_model(name, n_operatorz=9)
    message = str(info.value)
    assert message.startswith(f"unknown hyperparameter 'n_operatorz' for model {name!r}")
    assert message.endswith(f"; it takes: {takes}") and "\n" not in message


def test_an_unknown_hyperparameter_suggests_the_closest_name():
    with pytest.raises(ModelError, match=r"for model 'mrpim' \(did you mean n_operators\?\); it takes: n_operators,"):
        get_model("mrpim", n_operatorz=9)


def test_an_unknown_hyperparameter_like_no_name_gets_no_suggestion():
    with pytest.raises(ModelError, match="unknown hyperparameter 'nope'") as info:
        get_model("mrpim", nope=1)
    assert "did you mean" not in str(info.value)


def test_cli_refuses_a_bad_boolean_in_one_line_with_status_2(tmp_path, capsys):
    dataset = str(default_dataset_path())
    for hyper, named in (("q_term=no", "q_term must be true or false, got 'no'"),
                         ("n_operators=100000000", "n_operators must be an integer in 1..1000, got 100000000")):
        out = tmp_path / "fit.json"
        status = hysbench(["fit", dataset, "--model", "classical-pi" if hyper.startswith("n_") else "mrpim",
                           "--hyper", hyper, "--json", str(out)])
        err = capsys.readouterr().err
        assert status == 2, err
        lines = err.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in err, err
        assert lines[0].startswith("hysbench fit: error: ") and named in lines[0]
        assert not out.exists()
