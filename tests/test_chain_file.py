"""The posterior's chain file read strictly: a damaged, truncated or foreign file, or one of another format, is
refused in one line with exit status 2, before any sampling, and left as it is."""

import json
import shutil

import h5py
import numpy as np
import pytest

from hysbench.benchmarks.cli import main as hysbench
from hysbench.data.dataset import save_dataset
from hysbench.identification.posterior import simulated_ar1_dataset
from hysbench.identification.posterior.backend import CHAIN_FORMAT, ChainFileError, read_chain
from hysbench.models import get_model

SMALL = dict(n_operators=4, poly_order=2)
TRUTH = {"gamma": 0.0305, "lambda": -0.0317, "p1": 3.255, "p2": 0.9785, "q": 0.0251, "a1": -4.6812,
         "a2": 0.8303, "a3": 0.2917, "a4": 2.4706, "offset": 0.4419}
RUN = ["--walkers", "8", "--draws", "4", "--fixed-steps", "--quiet", "--no-figures", "--no-calibration"]


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """(dataset folder, a chain file of 6 steps written by ``hysbench posterior``)."""
    root = tmp_path_factory.mktemp("chain")
    ds = simulated_ar1_dataset(get_model("mrpim", **SMALL), TRUTH, sigma=0.02, phi=0.9, seed=7, n_periods=2,
                               dt=0.02, name="tiny")
    save_dataset(ds, root / "tiny")
    assert hysbench(["posterior", str(root / "tiny"), "--out", str(root / "out"), "--steps", "6", *RUN]) == 0
    return root / "tiny", root / "out" / "posterior_chain.h5"


def _attrs(name, change):
    def damage(path):
        with h5py.File(path, "a") as f:
            change(f)
    damage.__name__ = name
    return damage


def _settings(change):
    def edit(f):
        settings = json.loads(f.attrs["hysbench_settings"])
        change(settings)
        f.attrs["hysbench_settings"] = json.dumps(settings, sort_keys=True)
    return edit


def _start(change):
    def edit(f):
        start = json.loads(f.attrs["hysbench_start"])
        change(start)
        f.attrs["hysbench_start"] = json.dumps(start)
    return edit


def _bytes(change):
    def damage(path):
        path.write_bytes(change(path.read_bytes()))
    return damage


def _shorter_chain(f):
    data = f["mcmc/chain"][:3]
    del f["mcmc/chain"]
    f["mcmc"].create_dataset("chain", data=data, maxshape=(None, *data.shape[1:]))


# damage, then the words its one-line message holds
DAMAGES = {
    "not HDF5": (_bytes(lambda raw: b"not an HDF5 file\n" * 100), "is not an HDF5 chain file, or is truncated"),
    "truncated": (_bytes(lambda raw: raw[:len(raw) // 2]), "is not an HDF5 chain file, or is truncated"),
    "empty": (_bytes(lambda raw: b""), "is not an HDF5 chain file, or is truncated"),
    "no settings": (_attrs("x", lambda f: f.attrs.__delitem__("hysbench_settings")),
                    "no attribute 'hysbench_settings'"),
    "settings of the wrong type": (_attrs("x", lambda f: f.attrs.__setitem__("hysbench_settings", 5)),
                                   "attribute 'hysbench_settings' must be JSON text, got int64"),
    "settings not JSON": (_attrs("x", lambda f: f.attrs.__setitem__("hysbench_settings", "{walkers")),
                          "attribute 'hysbench_settings' is not JSON"),
    "settings not an object": (_attrs("x", lambda f: f.attrs.__setitem__("hysbench_settings", "[1]")),
                               "attribute 'hysbench_settings' must be a JSON object"),
    "no format": (_attrs("x", _settings(lambda s: s.pop("format"))),
                  "attribute 'hysbench_settings' has no field 'format'"),
    "another format version": (_attrs("x", _settings(lambda s: s.update(format="hysbench-posterior-chain/4"))),
                               f"a chain of format 'hysbench-posterior-chain/4'; this hysbench resumes "
                               f"'{CHAIN_FORMAT}' only"),
    "no start": (_attrs("x", lambda f: f.attrs.__delitem__("hysbench_start")), "no attribute 'hysbench_start'"),
    "start without its modes": (_attrs("x", _start(lambda s: s.pop("modes"))),
                                "attribute 'hysbench_start' field 'modes' must be a non-empty list"),
    "a mode's covariance of the wrong shape": (
        _attrs("x", _start(lambda s: s["modes"][0].update(covariance=[[1.0]]))),
        "attribute 'hysbench_start' field 'modes[0].covariance' must be a 4 x 4 list of numbers"),
    "seconds of the wrong type": (_attrs("x", lambda f: f.attrs.__setitem__("hysbench_seconds",
                                                                          '{"wall": "1", "sampling": 1}')),
                                  "attribute 'hysbench_seconds' field 'wall' must be a number"),
    "no iteration": (_attrs("x", lambda f: f["mcmc"].attrs.__delitem__("iteration")),
                     "group 'mcmc' has no attribute 'iteration'"),
    "iteration of the wrong type": (_attrs("x", lambda f: f["mcmc"].attrs.__setitem__("iteration", "6")),
                                    "attribute 'mcmc/iteration' must be an integer >= 0, got '6'"),
    "walkers unlike the settings": (_attrs("x", lambda f: f["mcmc"].attrs.__setitem__("nwalkers", 10)),
                                    "attribute 'mcmc/nwalkers' is 10, its settings say 8"),
    "no random state": (_attrs("x", lambda f: f["mcmc"].attrs.__delitem__("random_state_1")),
                        "group 'mcmc' lacks its random state"),
    "no log_prob": (_attrs("x", lambda f: f["mcmc"].__delitem__("log_prob")), "no dataset 'mcmc/log_prob'"),
    "a chain shorter than its iteration": (_attrs("x", _shorter_chain),
                                           "dataset 'mcmc/chain' has shape (3, 8, 4), expected ('>= 6', 8, 4)"),
}


def damaged(stored, tmp_path, name):
    """A copy of the stored chain with the damage ``name``: (dataset, output folder, chain file, words)."""
    folder, chain = stored
    out = tmp_path / "out"
    out.mkdir()
    copy = out / chain.name
    shutil.copyfile(chain, copy)
    damage, words = DAMAGES[name]
    damage(copy)
    return folder, out, copy, words


@pytest.mark.parametrize("name", DAMAGES)
def test_resuming_a_damaged_chain_file_is_refused_in_one_line_and_the_file_is_left_as_it_is(stored, tmp_path,
                                                                                            capsys, name):
    """Exit status 2, one line naming the file and what is wrong, no sampling and nothing written; the chain
    file's bytes unchanged."""
    folder, out, chain, words = damaged(stored, tmp_path, name)
    before = chain.read_bytes()
    code = hysbench(["posterior", str(folder), "--out", str(out), "--steps", "8", *RUN])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and str(chain) in err and words in err, err
    assert "--restart" in err and "Traceback" not in err
    assert sorted(p.name for p in out.iterdir()) == [chain.name] and chain.read_bytes() == before


def test_restart_replaces_a_damaged_chain_file(stored, tmp_path):
    """``--restart`` discards what cannot be resumed and samples afresh."""
    folder, out, chain, _ = damaged(stored, tmp_path, "no iteration")
    assert hysbench(["posterior", str(folder), "--out", str(out), "--steps", "4", "--restart", *RUN]) == 0
    with h5py.File(chain, "r") as f:
        assert f["mcmc"].attrs["iteration"] == 4


def test_a_sound_chain_file_is_read_whole(stored):
    """What the resumed run loads: every step, the start's modes, the random state."""
    _, chain = stored
    with h5py.File(chain, "r") as f:
        fingerprint = json.loads(f.attrs["hysbench_settings"])
        names = list(json.loads(f.attrs["hysbench_start"])["modes"][0]["mode"])
        expected = f["mcmc/chain"][:]
    got = read_chain(chain, fingerprint, names)
    assert got["iteration"] == 6 and got["chain"].shape == (6, 8, 4) and np.array_equal(got["chain"], expected)
    assert got["start"]["modes"] and len(got["random_state"]) == 5
    with pytest.raises(ChainFileError, match="holds a chain for other settings \\(differs in: walkers\\)"):
        read_chain(chain, {**fingerprint, "walkers": 10}, names)


def test_a_start_that_fails_leaves_no_chain_file(stored, tmp_path, capsys, monkeypatch):
    """A posterior refused before its first step leaves neither a chain file of settings alone nor its folder."""
    from hysbench.identification.errors import IdentificationError
    from hysbench.identification.posterior import run as posterior_run

    def no_mode(post, starts):
        raise IdentificationError("posterior: no mode search started from a finite log posterior")

    monkeypatch.setattr(posterior_run, "find_modes", no_mode)
    folder, _ = stored
    out = tmp_path / "new" / "out"
    assert hysbench(["posterior", str(folder), "--out", str(out), "--steps", "4", *RUN]) == 2
    assert "no mode search started" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()


def test_an_interrupted_run_keeps_its_steps_and_its_seconds(stored, tmp_path, monkeypatch):
    """Ctrl-C during sampling: the chain file keeps every step sampled and the time spent on them, and the resumed
    run's ``wall_seconds`` counts both runs."""
    from hysbench.identification.posterior import run as posterior_run, sample_posterior
    from hysbench.data.dataset import load_dataset

    folder, _ = stored
    chain = tmp_path / "chain.h5"
    real = posterior_run.convergence

    def interrupt_at_first_check(chain_, *args, **kwargs):
        if chain_.shape[0] == 100:
            raise KeyboardInterrupt
        return real(chain_, *args, **kwargs)

    monkeypatch.setattr(posterior_run, "convergence", interrupt_at_first_check)
    model, ds = get_model("mrpim", **SMALL), load_dataset(folder)
    settings = dict(n_walkers=8, min_ess=1e9, seed=0, progress=False, discrepancy="none", calibrate=False,
                    start_params=TRUTH, chain_file=chain)
    with pytest.raises(KeyboardInterrupt):
        sample_posterior(model, ds, max_steps=400, **settings)
    with h5py.File(chain, "r") as f:
        assert f["mcmc"].attrs["iteration"] == 100
        first = json.loads(f.attrs["hysbench_seconds"])
    assert first["wall"] >= first["sampling"] > 0
    run = sample_posterior(model, ds, max_steps=104, fixed_steps=True, **settings)
    assert run.resumed_from == 100 and run.chain.shape[0] == 104
    assert run.wall_seconds == pytest.approx(first["wall"] + run.this_run_seconds)


def test_ctrl_c_in_the_log_posterior_prints_no_traceback(stored, tmp_path, monkeypatch, capfd):
    """Ctrl-C while the log posterior is evaluated reaches the caller as itself, with nothing printed (emcee's
    wrapper would print the walkers and a traceback); the steps sampled before it are in the chain file."""
    from hysbench.identification.posterior import sample_posterior
    from hysbench.identification.posterior.target import LogPosterior
    from hysbench.data.dataset import load_dataset

    real, calls = LogPosterior.__call__, []

    def interrupt_on_the_60th_call(self, X):
        calls.append(1)
        if len(calls) == 60:
            raise KeyboardInterrupt
        return real(self, X)

    monkeypatch.setattr(LogPosterior, "__call__", interrupt_on_the_60th_call)
    folder, _ = stored
    chain = tmp_path / "chain.h5"
    capfd.readouterr()
    with pytest.raises(KeyboardInterrupt):
        sample_posterior(get_model("mrpim", **SMALL), load_dataset(folder), n_walkers=8, max_steps=400, seed=0,
                         progress=False, discrepancy="none", calibrate=False, start_params=TRUTH, chain_file=chain)
    out = capfd.readouterr()
    assert out.out == "" and out.err == "", out
    with h5py.File(chain, "r") as f:
        assert f["mcmc"].attrs["iteration"] >= 20
