"""Identifiers as strategy objects, the Jacobian driver, the NaN policy and the Fit's information criteria."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hysbench.data.dataset import Dataset, Record
from hysbench.data.protocol import simulated_dataset
from hysbench.identification import Fit, IdentificationError, identify
from hysbench.models import get_model
from hysbench.models.base import HysteresisModel, Parameter


@pytest.fixture(scope="module")
def noisy():
    model = get_model("mrpim", offset=False)
    return simulated_dataset(model, model.preset("paper"), noise_sd=0.01, seed=1)


class _PartlyNaN(HysteresisModel):
    """y = gain * u + offset, but NaN for gain above 1.5: a model that fails in part of its bounds."""

    name = "test-partly-nan"

    def __init__(self, always_nan: bool = False):
        self.always_nan = always_nan

    def declare_parameters(self, scale):
        return [Parameter("gain", 1.0, 0.0, 2.0), Parameter("offset", 0.0, -1.0, 1.0)]

    def simulate_batch(self, u, dt, param_sets, input_range=None):
        P = self._check_param_sets(param_sets)
        y = P[:, :1] * np.asarray(u)[None, :] + P[:, 1:2]
        y[(P[:, 0] > 1.5) | self.always_nan] = np.nan
        return y


def _linear_dataset(gain=1.2, offset=0.1):
    t = np.arange(2000) * 1e-3
    u = 1.5 + np.sin(2 * np.pi * t)
    recs = [Record(file=f"r{i}.csv", t=t, u=u * (1 + 0.1 * i), y=gain * u * (1 + 0.1 * i) + offset,
                   role="identification") for i in range(2)]
    return Dataset(name="linear", records=recs)


def test_non_finite_evaluations_are_counted_and_reported():
    fit = identify(_PartlyNaN(), _linear_dataset(), method="mpso", seed=1, swarm_size=10, iterations=5)
    assert fit.success
    assert fit.n_nonfinite > 0  # a uniform swarm over gain in [0, 2] samples gain > 1.5
    assert any("non-finite" in note for note in fit.notes)
    assert abs(fit.params["gain"] - 1.2) < 0.2


def test_a_model_with_non_finite_output_is_not_scored():
    fit = identify(_PartlyNaN(always_nan=True), _linear_dataset(), method="lsq", seed=0)
    assert not fit.success and "not finite" in fit.message
    assert math.isnan(fit.fitness) and math.isnan(fit.aic)
    assert "FAILED" in fit.summary()
    back = Fit.from_dict(json.loads(json.dumps(fit.to_dict())))
    assert not back.success and back.message == fit.message and back.n_nonfinite == fit.n_nonfinite


def test_fit_information_criteria_follow_the_gaussian_likelihood():
    fit = identify("classical-pi", _linear_dataset(), method="varpro", seed=0)
    n, k = fit.n_rows, sum(1 for lo, hi in fit.bounds.values() if hi > lo)
    assert n == 4000
    m2ll = n * math.log(2 * math.pi * fit.fitness / n) + n
    assert fit.aic == pytest.approx(m2ll + 2 * k, rel=1e-12)
    assert fit.bic == pytest.approx(m2ll + k * math.log(n), rel=1e-12)


# --- identifiers as strategy objects, the Jacobian driver -----------------------------------------
def test_identifier_objects_are_what_identify_builds(noisy):
    from hysbench.identification import Chain, LeastSquares, Varpro, build_identifier

    direct = Varpro(n_starts=1, n_candidates=4).fit(get_model("mrpim"), noisy, seed=3)
    named = identify("mrpim", noisy, "varpro", seed=3, n_starts=1, n_candidates=4)
    assert direct.params == named.params and direct.method == "varpro"
    assert Varpro(n_starts=1).get_params()["n_starts"] == 1 and Varpro().get_params()["n_candidates"] == 12
    chain = build_identifier("varpro+lsq", get_model("mrpim"), {"lsq.max_nfev": 3})
    assert isinstance(chain, Chain) and chain.method == "varpro+lsq"
    assert [type(s) for s in chain.stages()] == [Varpro, LeastSquares]
    assert chain.get_params()["lsq"]["max_nfev"] == 3
    with pytest.raises(IdentificationError, match="no linear parameters"):
        Varpro().fit(_PartlyNaN(), _linear_dataset())


def test_forward_difference_against_the_analytic_jacobian():
    from hysbench.identification.jacobian import CachedResidual, forward_difference

    def batch(Z):
        return np.column_stack([np.sin(Z[:, 0]) * Z[:, 1], Z[:, 0] ** 2 + np.exp(Z[:, 1]), Z[:, 0] * Z[:, 1] ** 3])

    def analytic(z):
        return np.array([[np.cos(z[0]) * z[1], np.sin(z[0])], [2 * z[0], np.exp(z[1])],
                         [z[1] ** 3, 3 * z[0] * z[1] ** 2]])

    step = np.array([1e-7, 1e-7])
    for z, upper in ((np.array([0.3, -1.2]), np.array([5.0, 5.0])), (np.array([1.0, 2.0]), np.array([1.0, 2.0]))):
        J = forward_difference(batch, z, batch(z[None])[0], step, upper)  # the second: steps taken backwards
        np.testing.assert_allclose(J, analytic(z), rtol=1e-5, atol=1e-6)
    calls = []
    cached = CachedResidual(lambda z: calls.append(1) or batch(z[None])[0])
    z = np.array([0.1, 0.2])
    cached(z), cached(z.copy()), cached(z + 1e-3)
    assert len(calls) == 2


# --- the fitness's unit ---------------------------------------------------------------
def _with_unit(unit):
    ds = _linear_dataset()
    ds.output_unit = unit
    return ds


def test_the_fit_knows_the_output_unit_and_prints_the_fitness_in_its_square():
    """``identify`` takes the unit from the dataset; the summary prints eq. 9's fitness in its square, the JSON
    carries it, and it round-trips."""
    fit = identify("classical-pi", _with_unit("mm"), method="varpro", seed=0)
    assert fit.output_unit == "mm"
    line = fit.summary().splitlines()[1]
    assert line.startswith(f"fitness (eq. 9) {fit.fitness:.6g} mm²   evaluations"), line
    d = json.loads(json.dumps(fit.to_dict()))
    assert d["output_unit"] == "mm" and Fit.from_dict(d).output_unit == "mm"
    assert fit.fitted_model(1e-3).metadata["output_unit"] == "mm"  # the model file's unit, the fit's own


def test_a_fit_without_an_output_unit_prints_the_fitness_alone():
    """A dataset that names no unit, and a fit written before the unit was recorded: no unit printed."""
    fit = identify("classical-pi", _with_unit(""), method="varpro", seed=0)
    assert fit.summary().splitlines()[1].startswith(f"fitness (eq. 9) {fit.fitness:.6g}   evaluations")
    older = {k: v for k, v in identify("classical-pi", _with_unit("mm"), method="varpro", seed=0).to_dict().items()
             if k != "output_unit"}
    assert Fit.from_dict(older).output_unit == "" and " mm²" not in Fit.from_dict(older).summary()
    with pytest.raises(IdentificationError, match="output_unit must be a string"):
        Fit.from_dict({**older, "output_unit": 3})


def test_a_unit_squared():
    from hysbench.identification.fit import squared_unit
    assert [squared_unit(u) for u in ("mm", "µm", "kV", "m/s", "N m", "")] == ["mm²", "µm²", "kV²", "(m/s)²",
                                                                               "(N m)²", ""]


def test_hysbench_fit_prints_the_fitness_with_its_unit_and_writes_it_to_the_json(tmp_path, capsys):
    from hysbench.benchmarks.cli import main as cli_main
    from hysbench.data.dataset import save_dataset

    save_dataset(_with_unit("um"), tmp_path / "ds")
    assert cli_main(["fit", str(tmp_path / "ds"), "--model", "classical-pi", "--json", "-"]) == 0
    out = capsys.readouterr()
    d = json.loads(out.out)
    assert d["output_unit"] == "um"
    assert f"fitness (eq. 9) {d['fitness']:.6g} um²   evaluations" in out.err


@pytest.mark.parametrize("make,option", [
    (lambda I: I.Varpro(n_starts=0), "n_starts"),
    (lambda I: I.Varpro(n_candidates="4"), "n_candidates"),
    (lambda I: I.LeastSquares(tol=-1.0), "tol"),
    (lambda I: I.Varpro(stable_inverse=1), "stable_inverse"),
    (lambda I: I.Chain(I.Varpro(), I.LeastSquares(max_nfev=0)), "max_nfev"),
])
def test_an_identifier_object_refuses_the_options_identify_refuses(make, option):
    """An identifier built directly checks its options in fit with identify's rules, and fit leaves them as given."""
    import hysbench.identification as I

    identifier = make(I)
    given = repr(identifier)
    with pytest.raises(IdentificationError, match=f"option {option} must"):
        identifier.fit(get_model("classical-pi"), _linear_dataset(), seed=0)
    assert repr(identifier) == given


def test_fit_leaves_the_identifier_and_the_model_configured_as_given():
    """Fitting changes neither the identifier's get_params nor the model's hyperparameters; repr shows both."""
    from hysbench.identification import Chain, LeastSquares, Varpro

    model, identifier = get_model("classical-pi", n_operators=5), Chain(Varpro(n_starts=1), LeastSquares(max_nfev=5))
    before = (identifier.get_params(), model.get_hyperparameters(), repr(identifier), repr(model))
    fit = identifier.fit(model, _linear_dataset(), seed=0)
    assert (identifier.get_params(), model.get_hyperparameters(), repr(identifier), repr(model)) == before
    assert repr(identifier).startswith("Chain(Varpro(n_starts=1, ") and "LeastSquares(n_starts=1, max_nfev=5" in repr(identifier)
    assert fit.options["lsq"]["max_nfev"] == 5 and fit.hyperparameters == model.get_hyperparameters()


def test_the_summary_shows_a_huge_error_in_three_digits_not_thirty():
    from hysbench.identification.fit import _percent

    assert _percent(2.71828) == "   2.718" and _percent(99999.0) == "99999.000"
    assert _percent(3.1e30) == " 3.1e+30" and _percent(float("nan")) == "non-finite"
