"""Each baseline, identified from data simulated from itself, fits back to the noise floor.

Data: the paper's protocol at 0.1, 0.4 and 1 Hz (identification, Table 1's
weights 1, 4, 1) and 0.2 Hz (validation), two periods each, the last one
scored, white noise sigma. The noise floor of eq. 9 is sigma^2 * sum k_m; its
chi-square spread over the ~13,500 scored samples is about 2 % (seeded data).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from hysbench.benchmarks.cli import main as cli_main
from hysbench.data.protocol import dataset_fitness, input_range, simulated_dataset
from hysbench.data.dataset import save_dataset
from hysbench.identification import identify
from hysbench.models import get_model

SIGMA = 0.01
FREQUENCIES = (0.1, 0.2, 0.4, 1.0)


def preisach_truth():
    model = get_model("preisach")
    rng = np.random.default_rng(0)
    return {n: (5.0 if n == "offset" else float(rng.uniform(0.0, 0.3))) for n in model.param_names}


TRUTH = {
    "elliptical": {"m1": 2.0, "b": 0.4, "offset": 5.0},
    "dual-polynomial": {"m1": 2.0, "m2": 0.8, "m3": -0.3, "m4": 0.1, "h0": 0.5, "h1": 0.1, "h2": -0.05,
                        "offset": 5.0},
    "bouc-wen": {"beta": 3.0, "gamma": 1.0, "n": 1.5, "kx": 1.5, "kz": 4.0, "offset": 5.0},
    "preisach": preisach_truth(),
    "rate-dependent-pi": {"beta": 0.03, "p1": 2.0, "a1": 0.8, "a2": 0.5, "a3": 0.4, "a4": 0.3, "a5": 0.2,
                          "a6": 0.2, "a7": 0.1, "a8": 0.1, "a9": 0.05, "a10": 0.05, "offset": 1.0},
}


@pytest.mark.parametrize("name", sorted(TRUTH))
def test_fits_data_simulated_from_itself_to_the_noise_floor(name):
    model = get_model(name)
    truth = TRUTH[name]
    ds = simulated_dataset(model, truth, n_periods=2, noise_sd=SIGMA, seed=1, frequencies=FREQUENCIES)
    floor = SIGMA**2 * sum(r.weight for r in ds.identification)
    fit = identify(model, ds, method="varpro", seed=0)
    assert 0.9 * floor < fit.fitness < 1.1 * floor, (fit.fitness / floor, fit.notes)
    # the optimum found is at least as good as the true parameters
    at_truth = dataset_fitness(model, truth, ds.identification, input_range(ds.identification))
    assert fit.fitness <= at_truth * (1 + 1e-6), (fit.fitness, at_truth)
    # every record, fitted or not, is predicted to the noise: e_rms = 100 sigma / p2p (percent)
    for score, rec in zip(fit.records, ds.records):
        p2p = float(np.ptp(model.simulate(rec.u, rec.dt, truth)[rec.scored]))
        assert score.e_rms < 1.1 * 100 * SIGMA / p2p, (score, 100 * SIGMA / p2p)
    # nonlinear parameters recovered
    for n in model.nonlinear_names:
        assert fit.params[n] == pytest.approx(truth[n], rel=0.03), (n, fit.params[n], truth[n])
    # linear parameters recovered where they are identifiable from major loops (not Preisach's weights)
    if name != "preisach":
        for n in model.linear_names:
            assert fit.params[n] == pytest.approx(truth[n], rel=0.05, abs=0.02), (n, fit.params[n], truth[n])


@pytest.fixture(scope="module")
def dea_like_folder(tmp_path_factory):
    """The Table 2 MRPIM on the protocol (four frequencies, to stay quick), saved as a dataset folder."""
    mrpim = get_model("mrpim")
    ds = simulated_dataset(mrpim, mrpim.preset("paper"), n_periods=2, noise_sd=SIGMA, seed=2,
                           frequencies=FREQUENCIES, name="mrpim-sim")
    return save_dataset(ds, tmp_path_factory.mktemp("data") / "mrpim-sim")


@pytest.mark.parametrize("name", sorted(TRUTH))
def test_cli_fit_works_for_every_baseline(name, dea_like_folder, tmp_path, capsys):
    out = tmp_path / "fit.json"
    assert cli_main(["fit", str(dea_like_folder), "--model", name, "--json", str(out)]) == 0
    assert "fitness" in capsys.readouterr().out
    d = json.loads(out.read_text())
    assert d["model"] == name and len(d["params"]) == get_model(name).n_params
    assert len(d["records"]) == len(FREQUENCIES)
    for rec in d["records"]:
        assert 0 < rec["e_rms"] <= rec["e_m"] < 100
    # elliptical, dual-polynomial and Preisach are linear in every parameter: one solve
    if not get_model(name).nonlinear_names:
        assert d["n_evaluations"] == 1
