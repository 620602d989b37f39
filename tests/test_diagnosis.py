"""The diagnosis: extension blocks against slow references, the decision rule, and planted effects.

Planted tests draw their data from ``hysbench.benchmarks.diagnosis_accuracy.planted``,
whose effects use functional forms and numerical methods of their own (FFT
convolution, a frequency-domain delay, scipy's RK45 mode, a logarithmic
creep, ...), never the extension code that detects them. The pinned planted
cases are one table (``PINNED``: the case -> the verdict's structured fields
and the rules its trace must hold), each case diagnosed once per process
(``diagnosed_cases``) and read by every test that checks more of it. Draws
above a detection limit are seeded and kept only if their strength is at or
above it, so a failure here is a regression, not bad luck. Nulls include
AR(1) noise (phi 0.99); out-of-vocabulary effects must not get a vocabulary
cause.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import matplotlib.figure
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal, stats

from hysbench.benchmarks.cli import main as hysbench_main
from hysbench.benchmarks.plots import unreadable
from hysbench.benchmarks.diagnosis import diagnose
from hysbench.benchmarks.diagnosis.diagnose import build_screen
from hysbench.benchmarks.diagnosis_accuracy.accuracy import judge, parameter_errors
from hysbench.benchmarks.diagnosis.experiment import predict, probe_sine, suggest
from hysbench.benchmarks.diagnosis_accuracy.planted import (
    fractional_delay,
    low_pass_convolution,
    mode_ode,
    piezo_available,
    planted_case,
)
from hysbench.benchmarks.diagnosis_accuracy.stated_limits import LIMITS_PCT, stated_limit
from hysbench.benchmarks.diagnosis.report import verdict_lines
from hysbench.benchmarks.diagnosis.causes.saturation import shows_clip, slope_where_clipped
from hysbench.benchmarks.diagnosis.residuals import (
    RecordResidual,
    coherent_spectrum,
    harmonic_phase_turn,
    ljung_box,
    noise_sd,
    periodic_structure,
    spectral_peaks,
)
from hysbench.benchmarks.diagnosis.candidates import DRIVE_LOCKED, NO_CUT, Candidate
from hysbench.benchmarks.diagnosis.policy import Policy, PolicyError
from hysbench.benchmarks.diagnosis.screen import Screen
from hysbench.benchmarks.diagnosis.heldout import Folds, HeldOut, heldout_errors, heldout_null, pairwise_z, passes, score
from hysbench.benchmarks.diagnosis.selection import decide
from hysbench.benchmarks.diagnosis.causes import get_cause
from hysbench.benchmarks.diagnosis.composite import composite_starts
from hysbench.benchmarks.diagnosis.causes.interference import same_line
from hysbench.benchmarks.diagnosis.lines import drive_locked, fold_frequencies, frequencies_agree, on_top
from hysbench.benchmarks.diagnosis.backward import replacements, strongest_first
from hysbench.benchmarks.diagnosis.secondary import Tried, _choose, _folds_disagree
from hysbench.data.dataset import Record, save_dataset
from hysbench.data.segments import own_samples
from hysbench.data.protocol import paper_voltage, protocol_time
from hysbench.identification import Fit, identify
from hysbench.models import CAUSES, ExtendedModel, get_model
from hysbench.models.filter_kernels import (first_order_foh, lowpass1, lowpass1_bank, lowpass1_bank_at,
                                           lowpass2_columns_at, lowpass2_rows, second_order_foh)
from diagnosed_cases import diagnosed, planted
from measured_data import pzt_dataset

DT = 1e-3
POLICY = Policy()


# --- blocks against slow references --------------------------------------------------
def _lsim(num, den, x, t):
    return signal.lsim((num, den), x, t, interp=True)[1]


@given(tau=st.floats(0.003, 30.0), seed=st.integers(0, 10_000))
def test_first_order_low_pass_is_the_continuous_response(tau, seed):
    """Exact first-order-hold discretisation == scipy's continuous-time simulation (from rest)."""
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.normal(size=400)) + 3.0
    t = np.arange(x.size) * DT
    y = lowpass1(x, *first_order_foh(tau, DT))
    np.testing.assert_allclose(y, _lsim([1.0], [tau, 1.0], x, t), atol=1e-8 * np.max(np.abs(x)))


@given(fn=st.floats(0.5, 60.0), zeta=st.floats(0.02, 2.5), seed=st.integers(0, 10_000))
def test_second_order_low_pass_is_the_continuous_response(fn, zeta, seed):
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.normal(size=(2, 400)), axis=1) + 1.0
    t = np.arange(x.shape[1]) * DT
    w = 2 * np.pi * fn
    y = lowpass2_rows(np.ascontiguousarray(x), *second_order_foh(fn, zeta, DT))
    for j in range(2):  # at rest at the first value: that value plus the response to the rest, from zero
        ref = x[j, 0] + _lsim([w * w], [1.0, 2 * zeta * w, w * w], x[j] - x[j, 0], t)
        np.testing.assert_allclose(y[j], ref, atol=1e-7 * np.max(np.abs(x)))


@given(fn=st.floats(0.5, 60.0), zeta=st.floats(0.02, 2.5), seed=st.integers(0, 10_000),
       rows=st.lists(st.integers(0, 399), min_size=1, max_size=40, unique=True).map(sorted))
def test_second_order_low_pass_kept_at_rows_is_the_whole_response_there(fn, zeta, seed, rows):
    """The kernel that keeps only some samples (no stacked copy of its signals) runs the same recurrence."""
    from numba.typed import List

    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.normal(size=(3, 400)), axis=1) + 1.0
    rows = np.array(rows, dtype=np.int64)
    whole = lowpass2_rows(np.ascontiguousarray(x), *second_order_foh(fn, zeta, DT))
    kept = lowpass2_columns_at(List([np.ascontiguousarray(r) for r in x]), *second_order_foh(fn, zeta, DT), rows)
    np.testing.assert_array_equal(kept, whole[:, rows])


@given(taus=st.lists(st.floats(0.003, 30.0), min_size=1, max_size=3), seed=st.integers(0, 10_000),
       rows=st.lists(st.integers(0, 399), min_size=1, max_size=40, unique=True).map(sorted))
def test_first_order_bank_kept_at_rows_is_the_whole_bank_there(taus, seed, rows):
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.normal(size=400)) + 1.0
    a, b0, b1 = (np.array(c) for c in zip(*(first_order_foh(t, DT) for t in taus)))
    rows = np.array(rows, dtype=np.int64)
    np.testing.assert_array_equal(lowpass1_bank_at(x, a, b0, b1, rows), lowpass1_bank(x, a, b0, b1)[:, rows])
    model = ExtendedModel("mrpim", ("relaxation",), n_relaxation=len(taus), relaxation_powers=[1, 2])
    whole = model._relaxation_columns(x, DT, taus)
    np.testing.assert_array_equal(model._relaxation_columns(x, DT, taus, at=rows), whole[:, rows])


@settings(max_examples=25, deadline=None)
@given(st.lists(st.lists(st.sampled_from([0.003, 0.02, 0.05, 0.4]), min_size=1, max_size=3, unique=True),
                min_size=1, max_size=5), st.integers(0, 2**31 - 1))
def test_relaxation_columns_from_the_cache_are_those_filtered_afresh(calls, seed):
    """Time constants seen before come from the caller's cache, new ones are filtered: the same rows either
    way, over a sequence of calls that repeat, reorder and mix them."""
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.normal(size=300)) + 1.0
    rows = np.sort(rng.choice(300, 60, replace=False)).astype(np.int64)
    cache = {}
    for taus in calls:
        model = ExtendedModel("mrpim", ("relaxation",), n_relaxation=len(taus), relaxation_powers=[1, 2])
        fresh = model._relaxation_columns(x, DT, taus, at=rows)
        np.testing.assert_array_equal(model._relaxation_columns(x, DT, taus, at=rows, cache=cache), fresh)
    assert set(cache) == {(t, p) for taus in calls for t in taus for p in (1, 2)}


def test_first_order_by_hand():
    """A step from rest: x = 1 - exp(-t/tau) at the samples (the step is held from t = 0)."""
    tau = 0.05
    y = lowpass1(np.ones(200), *first_order_foh(tau, DT))
    np.testing.assert_allclose(y, 1 - np.exp(-np.arange(200) * DT / tau), atol=1e-12)


PARAMS = {"tau1": 0.7, "tau2": 4.0, "c1": 0.4, "c2": -0.2, "delay": 0.0234, "natural_frequency": 3.3,
          "damping_ratio": 0.2, "creep_time": 30.0, "creep_size": 0.5, "interference_frequency": 7.3,
          "interference_sin": 0.05, "interference_cos": -0.02, "saturation_level": 5.0}


def _input(f=0.4, periods=2):
    t = protocol_time(f, periods)
    return t, paper_voltage(t, f)


@pytest.mark.parametrize("components", [(c,) for c in CAUSES if c != "saturation"]
                         + [("relaxation", "delay", "resonance", "creep", "interference")])
def test_regressors_times_linear_parameters_is_the_simulation(components):
    m = ExtendedModel("mrpim", components, n_relaxation=2)
    base = get_model("mrpim").preset("paper")
    p = {**base, "offset": 0.3, **{k: v for k, v in PARAMS.items() if k in m.param_names}}
    _, u = _input()
    y = m.simulate(u, DT, p)
    Phi = m.regressors(u, DT, {k: p[k] for k in m.nonlinear_names})
    np.testing.assert_allclose(Phi @ np.array([p[k] for k in m.linear_names]), y, atol=1e-9)
    Y = m.simulate_batch(u, DT, np.tile(m.pack(p), (3, 1)))
    np.testing.assert_allclose(Y[2], y, atol=1e-12)


def test_each_block_against_a_slow_reference():
    """The chain of the module docstring, computed the obvious way (scipy lsim, np.interp, loops)."""
    base = get_model("mrpim")
    bp = {**base.preset("paper"), "offset": 0.3}
    t, u = _input(1.0, 3)
    yb = base.simulate(u, DT, bp)
    # relaxation + creep + resonance (offset not filtered) + interference
    m = ExtendedModel("mrpim", ("relaxation", "creep", "resonance", "interference"))
    p = {**bp, **{k: v for k, v in PARAMS.items() if k in m.param_names}}
    act = yb - 0.3 + p["c1"] * _lsim([1.0], [p["tau1"], 1.0], u, t) + p["creep_size"] * (1 - np.exp(-t / p["creep_time"]))
    w = 2 * np.pi * p["natural_frequency"]
    ref = act[0] + _lsim([w * w], [1.0, 2 * p["damping_ratio"] * w, w * w], act - act[0], t) + 0.3  # mode at rest at act[0]
    ph = 2 * np.pi * p["interference_frequency"] * t
    ref += p["interference_sin"] * np.sin(ph) + p["interference_cos"] * np.cos(ph)
    np.testing.assert_allclose(m.simulate(u, DT, p), ref, atol=1e-7)
    # delay: the base on the input sampled at t - d, from rest at t = d (not its output for u(0) held)
    d = PARAMS["delay"]
    md = ExtendedModel("mrpim", ("delay",))
    k0 = int(math.ceil(d / DT))
    late = base.simulate(np.interp(t[k0:] - d, t, u), DT, bp, input_range=(u.min(), u.max()))
    rest = base.simulate(u[:1], DT, bp, input_range=(u.min(), u.max()))[0]
    np.testing.assert_allclose(md.simulate(u, DT, {**bp, "delay": d}), np.r_[np.full(k0, rest), late], atol=1e-12)
    # saturation clips
    ms = ExtendedModel("mrpim", ("saturation",), saturation_side="lower")
    np.testing.assert_allclose(ms.simulate(u, DT, {**bp, "saturation_level": 3.0}), np.maximum(yb, 3.0))


def test_extended_models_are_registered_and_round_trip():
    for cause in CAUSES:
        m = get_model(f"mrpim+{cause}")
        assert m.name == f"mrpim+{cause}"
        again = get_model(m.name, **json.loads(json.dumps(m.get_hyperparameters())))
        assert again.param_names == m.param_names
    sat = get_model("mrpim+saturation")
    assert not sat.has_linear_part and get_model("mrpim+relaxation").has_linear_part
    assert set(get_model("mrpim+delay").nonlinear_names) == {"gamma", "lambda", "delay"}


def test_windowed_regressors_are_rows_of_the_whole():
    m = ExtendedModel("mrpim", ("relaxation", "delay", "resonance", "creep", "interference"))
    p = {**get_model("mrpim").preset("paper"), **{k: v for k, v in PARAMS.items() if k in m.param_names}}
    _, u = _input(1.0, 3)
    nl = {k: p[k] for k in m.nonlinear_names}
    whole = m.regressors(u, DT, nl)
    for w in (slice(0, 7), slice(10, 40), slice(1500, 3000)):
        np.testing.assert_allclose(m.windowed_regressors(u, DT, nl, w), whole[w], atol=1e-12)


def test_an_extended_model_is_identified_and_round_trips_through_json():
    """The identifiers know the extension only through the interface; a Fit rebuilds it from the registry."""
    ds, _ = planted_case(("relaxation",), "mrpim", "sines", 1)
    fit = identify("mrpim+relaxation", ds, method="varpro", seed=0, n_candidates=4)
    again = Fit.from_dict(json.loads(json.dumps(fit.to_dict())))
    r = ds.records[-1]
    np.testing.assert_allclose(again.predict(r), fit.predict(r), atol=1e-12)
    assert again.model == "mrpim+relaxation" and again.params == fit.params


# --- residual statistics ------------------------------------------------------------------
def test_noise_estimate_and_whiteness():
    rng = np.random.default_rng(5)
    t = np.arange(20_000) * DT
    smooth = 0.5 * np.sin(2 * np.pi * 0.5 * t)
    e = rng.normal(0, 0.01, t.size)
    assert noise_sd(smooth + e) == pytest.approx(0.01, rel=0.05)
    assert ljung_box(e)[1] > 0.01
    ar = signal.lfilter([1.0], [1.0, -0.5], e)
    assert ljung_box(ar)[1] < 1e-6


def test_coherent_spectrum_adds_a_common_phase_disturbance():
    rng = np.random.default_rng(6)
    recs = []
    for f in (0.1, 0.4, 1.0):
        t = np.arange(int(2 / f / DT)) * DT
        y = 0.02 * np.sin(2 * np.pi * 13.3 * t + 1.0) + 0.3 * np.sin(2 * np.pi * 3 * f * t) + rng.normal(0, 0.01, t.size)
        recs.append(RecordResidual(Record("r.npz", t, np.zeros_like(t), y, frequency_hz=f), np.zeros_like(t)))
    f, a = coherent_spectrum(recs, 5.0, 100.0)
    (fp, ap), = spectral_peaks(f, a, n=1)
    assert fp == pytest.approx(13.3, abs=0.05) and ap == pytest.approx(0.02, rel=0.25)


def test_coherent_spectrum_over_different_sample_times():
    """Records sampled at 1, 2 and 5 ms: each record's DFT on one common grid equals a slow direct sum
    there, and a common-phase disturbance still adds up."""
    rng = np.random.default_rng(7)
    recs = []
    for f, h in ((0.1, 0.005), (0.4, 0.002), (1.0, 0.001)):
        t = np.arange(int(2 / f / h)) * h
        y = 0.02 * np.sin(2 * np.pi * 13.3 * t + 1.0) + 0.3 * np.sin(2 * np.pi * 3 * f * t) + rng.normal(0, 0.01, t.size)
        recs.append(RecordResidual(Record("r.npz", t, np.zeros_like(t), y, frequency_hz=f), np.zeros_like(t)))
    f, a = coherent_spectrum(recs, 5.0, 100.0)
    assert f[-1] <= 0.5 / 0.005 + 1e-9  # the coarsest record's Nyquist frequency
    for k in (0, 1234, f.size - 1):  # the slow, obvious DFT
        total = sum(np.sum((rr.residual - rr.residual.mean()) * np.exp(-2j * np.pi * f[k] * rr.record.t))
                    for rr in recs)
        assert a[k] == pytest.approx(2 * abs(total) / sum(rr.residual.size for rr in recs), rel=1e-6, abs=1e-12)
    (fp, ap), = spectral_peaks(f, a, n=1)
    assert fp == pytest.approx(13.3, abs=0.05) and ap == pytest.approx(0.02, rel=0.25)


def test_incoherent_spectrum_adds_powers_of_per_record_phases():
    """A disturbance whose phase differs per record: the coherent sum cancels, the power sum keeps its amplitude."""
    rng = np.random.default_rng(8)
    recs = []
    for k, f in enumerate((0.1, 0.4, 1.0)):
        t = np.arange(int(2 / f / DT)) * DT
        y = 0.02 * np.sin(2 * np.pi * 13.3 * t + 2.1 * k) + rng.normal(0, 0.01, t.size)
        recs.append(RecordResidual(Record("r.npz", t, np.zeros_like(t), y, frequency_hz=f), np.zeros_like(t)))
    f, a = coherent_spectrum(recs, 5.0, 100.0, coherent=False)
    (fp, ap), = spectral_peaks(f, a, n=1)
    assert fp == pytest.approx(13.3, abs=0.05) and ap == pytest.approx(0.02, rel=0.25)


def _residual_records(make, freqs=(0.1, 0.4, 1.0), periods=3):
    out = []
    for f in freqs:
        t = np.arange(int(periods / f / DT)) * DT
        out.append(RecordResidual(Record("r.npz", t, np.zeros_like(t), make(t, f), frequency_hz=f), np.zeros_like(t)))
    return out


def test_periodic_structure_tells_a_repeating_misfit_from_coloured_noise():
    rng = np.random.default_rng(9)
    ar = _residual_records(lambda t, f: signal.lfilter([1.0], [1.0, -0.99], rng.normal(0, 0.01, t.size)))
    assert periodic_structure(ar)["F"] < 3.0
    repeat = _residual_records(lambda t, f: 0.02 * np.sign(np.sin(2 * np.pi * f * t)) + rng.normal(0, 0.01, t.size))
    assert periodic_structure(repeat)["F"] > 20.0


def test_periodic_structure_takes_one_period_records_of_one_drive_together():
    """Segments of one period each (``--segments`` on one recording): alone, none counts; together, a misfit
    that repeats in every segment is structure and independent coloured noise is not."""
    rng = np.random.default_rng(11)
    f = 1.0
    repeat = _residual_records(lambda t, f: 0.02 * np.sign(np.sin(2 * np.pi * f * t)) + rng.normal(0, 0.01, t.size),
                               freqs=(f,) * 4, periods=1)
    for k, rr in enumerate(repeat):
        rr.record.file = f"rec~{k + 1}.csv"
    assert math.isnan(periodic_structure(repeat[:1])["F"]) and periodic_structure(repeat[:1])["records"] == []
    got = periodic_structure(repeat)
    assert got["F"] > 20.0 and got["records"] == [rr.file for rr in repeat]
    ar = _residual_records(lambda t, f: signal.lfilter([1.0], [1.0, -0.9], rng.normal(0, 0.01, t.size)),
                           freqs=(f,) * 4, periods=1)
    assert periodic_structure(ar)["F"] < 4.0
    other = _residual_records(lambda t, f: 0.02 * np.sign(np.sin(2 * np.pi * f * t)), freqs=(f, 2 * f), periods=1)
    assert periodic_structure(other)["records"] == []  # one period at two frequencies: no two of one drive


# --- the independent generators against slow references --------------------------------------
def test_planted_low_pass_delay_and_mode_against_scipy():
    t = np.arange(3000) * DT
    u = 1.5 + np.sin(2 * np.pi * 0.7 * t) + 0.3 * np.sin(2 * np.pi * 3.1 * t)
    ref = signal.lsim(([1.0], [0.2, 1.0]), u, t, interp=True)[1]
    np.testing.assert_allclose(low_pass_convolution(u, DT, 0.2), ref, atol=2e-4)
    # a delay of 7.3 samples of a smooth signal, against the analytic shift (away from the start)
    d = 0.0073
    y = np.sin(2 * np.pi * 0.7 * t)
    np.testing.assert_allclose(fractional_delay(y, DT, d, rest=0.0)[200:2800], np.sin(2 * np.pi * 0.7 * (t - d))[200:2800],
                               atol=1e-3)
    w = 2 * np.pi * 6.0
    y = 1.0 + 0.5 * np.sin(2 * np.pi * 0.7 * t)
    ref = signal.lsim(([w * w], [1.0, 2 * 0.2 * w, w * w]), y - y[0], t, interp=True)[1] + y[0]
    np.testing.assert_allclose(mode_ode(y, DT, 6.0, 0.2), ref, atol=1e-5)


# --- the decision rule's pieces ------------------------------------------------------------------
def test_heldout_score_counts_blocks_not_samples():
    rng = np.random.default_rng(10)
    folds = Folds(np.array([0, 4000, 8000, 12000]))
    e_ref = rng.normal(0, 1.0, 12000)
    same = rng.normal(0, 1.0, 12000)  # as good, by chance
    better = 0.5 * e_ref
    s_same, s_better = score(folds, e_ref, same), score(folds, e_ref, better)
    assert abs(s_same["z"]) < 3.0 and abs(s_same["gain"]) < 0.05
    assert s_better["z"] > 4.0 and s_better["gain"] == pytest.approx(0.75) and s_better["folds_improved"] == 3


def _scored(cause, folds, e_null, e, uncertainty=None):
    c = Candidate(cause, cause, get_model("mrpim"), {}, 22, float(e @ e), e.size)
    c.heldout = {**score(folds, e_null, e), "at_bound": []}
    c.uncertainty = uncertainty or {}
    return c


def test_a_specific_partial_cause_is_named_with_the_rest_unexplained_and_a_rival_makes_it_unexplained():
    """A cause that removes 39 % of a large structured misfit on every held-out block is named, the other 61 %
    reported as unexplained remainder; with a second cause taking a slice of about the same size from another
    component, the verdict is unexplained (either would be a guess), unless the rival's own parameters disagree
    across the folds (then it is no explanation either); with a rival removing the same component,
    the simpler is named and the other listed as ambiguous; with fold estimates that disagree, unexplained."""
    rng = np.random.default_rng(3)
    folds = Folds(np.array([0, 4000, 8000, 12000]))
    t = np.arange(12000) * DT
    s1, s2 = np.sin(2 * np.pi * 0.37 * t), 0.8 * np.sin(2 * np.pi * 1.3 * t)
    noise = rng.normal(0, 0.05, t.size)
    e_null = s1 + s2 + noise
    e_a = 0.6 * s1 + s2 + noise  # removes part of one component: 39 % of the misfit
    e_b = s1 + 0.22 * s2 + noise  # another slice of about the same size (37 %)
    screen = SimpleNamespace(n=t.size, n_held_out_rows=t.size, noise_sd=0.05, creep_min=20.0, policy=POLICY)

    def last(v):  # the rule that decided, and why a partial cause was not named
        return v.trace[-1]["rule"], v.trace[-1]["inputs"].get("not_specific")

    a = _scored("delay", folds, e_null, e_a, {"delay": {"se": 1e-4, "folds": [0.010, 0.0101, 0.0099]}})
    held = HeldOut(folds, e_null, [(a, e_a)])
    v = decide(screen, held, [a], [], structured=True)
    assert v.cause == "delay" and v.remainder == pytest.approx(0.61, abs=0.03) and last(v)[0] == "partial-specific"
    level = {"saturation_level": {"se": 1e-3, "se_over_range": 0.01, "folds": [0.50, 0.501, 0.499]}}
    b = _scored("saturation", folds, e_null, e_b, level)
    held.add(b, e_b)
    v = decide(screen, held, [a, b], [], structured=True)
    assert v.cause == "unexplained" and v.partial is a
    assert last(v) == ("partial-not-specific", {"why": "rivals", "rivals": ["saturation"]})
    # a rival whose own parameters the folds do not agree on is no explanation either: it does not make a guess
    loose = _scored("saturation", folds, e_null, e_b, {"saturation_level": {"se": 0.2, "se_over_range": 0.4,
                                                                           "folds": [0.2, 0.5, 0.9]}})
    v = decide(screen, HeldOut(folds, e_null, [(a, e_a), (loose, e_b)]), [a, loose], [], structured=True)
    assert v.cause == "delay" and v.remainder == pytest.approx(0.61, abs=0.03), v.reason
    # a sinusoid at a drive harmonic with the same phase in every record is no cause, but with held-out evidence
    # it shows a misfit locked to the drive: removing another part, it makes the partial cause a guess too
    locked = _scored("interference", folds, e_null, e_b, {"amplitude": {"se": 1e-3, "folds": [0.5, 0.5, 0.5]}})
    locked.limit = DRIVE_LOCKED
    v = decide(screen, HeldOut(folds, e_null, [(a, e_a), (locked, e_b)]), [a, locked], [], structured=True)
    assert v.cause == "unexplained" and last(v) == ("partial-not-specific", {"why": "rivals", "rivals": ["drive-locked"]})
    e_weak = e_null + rng.normal(0, 0.05, t.size)  # no held-out evidence: it does not count
    weak = _scored("interference", folds, e_null, e_weak)
    weak.limit = DRIVE_LOCKED
    v = decide(screen, HeldOut(folds, e_null, [(a, e_a), (weak, e_weak)]), [a, weak], [], structured=True)
    assert v.cause == "delay", v.reason
    # a rival for the SAME slice (another mode of explaining it, as a short lag for a delay): ambiguous, and the
    # candidate with fewer parameters is named
    e_c = 0.6 * s1 + s2 + rng.normal(0, 0.05, t.size)
    c = _scored("resonance", folds, e_null, e_c, {"natural_frequency": {"relative_se": 0.02, "folds": [9.0, 9.2, 9.1]}})
    c.k = a.k + 1
    held.add(c, e_c)
    v = decide(screen, held, [c, a], [], structured=True)
    assert v.cause == "delay" and [r.cause for r in v.ambiguous_with] == ["resonance"], v.reason
    assert v.remainder == pytest.approx(0.61, abs=0.03)
    v = decide(screen, held, [a, b, c], [], structured=True)  # a rival for another slice: a guess
    assert v.cause == "unexplained" and last(v) == ("partial-not-specific", {"why": "rivals", "rivals": ["saturation"]})
    wobbly = _scored("delay", folds, e_null, e_a, {"delay": {"se": 0.004, "folds": [0.004, 0.010, 0.016]}})
    v = decide(screen, HeldOut(folds, e_null, [(wobbly, e_a)]), [wobbly], [], structured=True)
    assert v.cause == "unexplained" and last(v) == ("partial-not-specific", {"why": "folds", "rivals": []})


def test_without_pinned_needs_a_pinned_time_constant_and_one_left():
    from hysbench.benchmarks.diagnosis.causes.relaxation import without_pinned

    c = SimpleNamespace(model=SimpleNamespace(nonlinear_names=("gamma", "lambda", "tau1")), params={"tau1": 0.01},
                        hyperparameters={"n_relaxation": 1})
    assert without_pinned(None, c, []) is None and without_pinned(None, c, ["tau1"]) is None
    assert without_pinned(None, c, ["gamma"]) is None  # a base parameter at its bound is not the relaxation's


def test_a_relaxation_slower_than_every_drive_period_that_creep_predicts_as_well_gives_way_to_creep():
    """Under drives of one mean level a low-pass slower than the longest drive period (10 s here) is a drift
    since the start: with creep predicting the held-out records as well, creep (no input dependence: the weaker
    claim) is named and the relaxation listed as ambiguous; a relaxation faster than the drive period is kept."""
    rng = np.random.default_rng(4)
    folds = Folds(np.array([0, 4000, 8000, 12000]))
    t = np.arange(12000) * DT
    drift = 0.3 * (1 - np.exp(-(t % 8.0) / 3.0))
    noise = rng.normal(0, 0.01, t.size)
    e_null = drift + noise
    e_relax, e_creep = sorted([0.05 * drift + noise, 0.05 * drift + rng.normal(0, 0.01, t.size)],
                              key=lambda e: float(e @ e))  # as good; the relaxation by a hair
    screen = SimpleNamespace(n=t.size, n_held_out_rows=t.size, noise_sd=0.01, creep_min=20.0, policy=POLICY)
    for tau, named in ((25.0, "creep"), (4.0, "relaxation")):
        relax, creep = _scored("relaxation", folds, e_null, e_relax), _scored("creep", folds, e_null, e_creep)
        relax.estimates, creep.estimates = {"tau_s": [tau]}, {"size": 0.3, "time_scale_s": 20.0}
        held = HeldOut(folds, e_null, [(relax, e_relax), (creep, e_creep)])
        v = decide(screen, held, [creep], [relax], structured=True)
        assert v.cause == named, (tau, v.reason)
        assert [c.cause for c in v.ambiguous_with] == ["relaxation" if named == "creep" else "creep"], tau
        assert ("slow-relaxation-twin" in [t["rule"] for t in v.trace]) == (named == "creep"), v.trace


def test_the_slowest_relaxation_part_is_compared_with_creep_only_when_slower_than_every_drive_period():
    """The composite (faster time constants + creep) is built only for a named relaxation of two or more time
    constants whose slowest is longer than the longest drive period (creep_min / creep_periods); it is called
    as good when it passes and the relaxation does not predict better by z >= z_same (the policy)."""
    from hysbench.benchmarks.diagnosis.rule import Verdict
    from hysbench.benchmarks.diagnosis.slow_part import SlowPart, decide_slow_part, slow_part_composite

    screen = SimpleNamespace(creep_min=20.0, policy=POLICY)  # longest drive period 10 s
    relax = Candidate("relaxation", "relaxation", get_model("mrpim"), {}, 25, 1.0, 10)
    one = Candidate("relaxation", "relaxation", get_model("mrpim"), {}, 23, 1.0, 10, estimates={"tau_s": [0.5]})
    creep = Candidate("creep", "creep", get_model("mrpim"), {}, 23, 1.0, 10)
    for taus in ([0.5, 9.0], [30.0]):  # too fast, or a single time constant: not applicable (the screen is
        relax.estimates = {"tau_s": taus}  # a stub, so going on would raise)
        assert slow_part_composite(screen, None, relax, [creep], [one]) is None, taus
    rng = np.random.default_rng(2)
    folds = Folds(np.array([0, 4000, 8000, 12000]))
    noise = rng.normal(0, 0.01, 12000)
    drift = 0.3 * np.sin(np.arange(12000) / 900.0) ** 2
    e_null, e_relax = drift + noise, 0.05 * drift + noise
    for e_comp, same in ((0.05 * drift + rng.normal(0, 0.01, 12000), True), (0.5 * drift + noise, False)):
        chosen, comp = _scored("relaxation", folds, e_null, e_relax), _scored("creep", folds, e_null, e_comp)
        chosen.estimates = {"tau_s": [0.5, 30.0]}
        z = pairwise_z(HeldOut(folds, e_null, [(chosen, e_relax), (comp, e_comp)]), chosen, comp)
        v, entry = decide_slow_part(SlowPart(comp, z), Verdict("relaxation", chosen), POLICY)
        assert (entry["rule"], entry["outcome"], entry["inputs"]["predicts_as_well"]) == (
            "slow-part-twin", "creep ambiguous" if same else "relaxation alone", same)
        assert [c.cause for c in v.ambiguous_with] == (["creep"] if same else [])


def _sine_residuals(f: float, n_records: int = 2, n: int = 2000, noise: float = 0.0, seed: int = 0):
    """Residuals of records (1 Hz drive, 1 ms) holding a sinusoid at f (one phase running through them all,
    as a disturbance does), drive-locked harmonics 1-3 and white noise."""
    rng = np.random.default_rng(seed)
    out = []
    for m in range(n_records):
        t = np.arange(n) * DT
        start = m * n * DT
        locked = sum(0.3 / k * np.sin(2 * np.pi * k * t + k) for k in (1, 2, 3))
        r = 0.1 * np.sin(2 * np.pi * f * (start + t) + 0.4) + locked + noise * rng.standard_normal(n)
        rec = Record(f"r{m}.npz", t, np.zeros(n), r, frequency_hz=1.0)
        out.append(RecordResidual(rec, np.zeros(n)))
    return out


def test_an_interference_at_a_drive_harmonic_with_one_phase_in_every_record_is_drive_locked():
    rec = Record("r.npz", np.arange(2000) * DT, np.zeros(2000), np.zeros(2000), frequency_hz=1.0)
    fake = SimpleNamespace(parts=[SimpleNamespace(record=rec)] * 2, policy=POLICY)
    locked = lambda f, phases: drive_locked(fake, {"frequency_hz": f, "phase_rad_per_record": phases})  # noqa: E731
    fake.null_residuals = lambda: _sine_residuals(9.0, noise=0.02)  # a misfit the drive repeats
    assert locked(9.0, [2.79, 2.99]) and locked(9.0, [3.1, -3.1])  # the phase wraps
    fake.null_residuals = lambda: _sine_residuals(1.014, noise=0.02)
    assert locked(1.014, [2.79, 2.99])  # 0.09 rad per period: not told from the harmonic
    assert not locked(9.0, [0.3, 2.0])  # its own phase in every record: a disturbance
    assert not locked(9.5, [2.79, 2.99])  # between harmonics
    # within the resolution of 9 Hz, phases alike by chance, but turning 0.94 rad per period: a line off it
    # (a line 0.09-0.24 Hz from a harmonic, as planted on the piezo recording)
    fake.null_residuals = lambda: _sine_residuals(9.15, noise=0.02)
    assert not locked(9.15, [2.79, 2.99])
    fake.null_residuals = lambda: _sine_residuals(9.15, noise=5.0)  # the same turn lost in noise: locked
    assert locked(9.15, [2.79, 2.99])


def _turn_reference(residuals, f):
    """harmonic_phase_turn written out: loops over periods and samples."""
    pairs = []
    for rr in residuals:
        r = rr.record
        n_p = int(round(1 / (r.frequency_hz * r.dt)))
        h = max(round(f / r.frequency_hz), 1) * r.frequency_hz
        cs = []
        for j in range(r.t.size // n_p):
            x = [rr.residual[j * n_p + i] for i in range(n_p)]
            mean = sum(x) / n_p
            re = sum((x[i] - mean) * math.cos(2 * math.pi * h * i * r.dt) for i in range(n_p)) * 2 / n_p
            im = -sum((x[i] - mean) * math.sin(2 * math.pi * h * i * r.dt) for i in range(n_p)) * 2 / n_p
            cs.append(complex(re, im))
        pairs += list(zip(cs[:-1], cs[1:]))
    turn = math.atan2(sum((b * a.conjugate()).imag for a, b in pairs), sum((b * a.conjugate()).real for a, b in pairs))
    rot = complex(math.cos(turn), math.sin(turn))
    misfit = math.sqrt(sum(abs(b - a * rot) ** 2 for a, b in pairs) / len(pairs))
    amp = math.sqrt(sum(abs(a) ** 2 + abs(b) ** 2 for a, b in pairs) / (2 * len(pairs)))
    return turn, misfit / amp / math.sqrt(len(pairs))


@given(st.integers(3, 30), st.floats(-0.3, 0.3), st.floats(0.0, 0.05))
def test_a_lines_phase_turn_per_period_is_its_distance_from_the_harmonic(k, df, noise):
    """Turn = 2 pi df T per drive period (T = 1 s), up to the line's leakage from its mirror frequency; and the
    vectorised function agrees with the loop reference."""
    res = _sine_residuals(k + df, n_records=2, n=3000, noise=noise, seed=k)
    turn, se = harmonic_phase_turn(res, k + df)
    assert turn == pytest.approx(2 * math.pi * df, abs=0.15)
    ref = _turn_reference(res, k + df)
    assert turn == pytest.approx(ref[0], abs=1e-9) and se == pytest.approx(ref[1], rel=1e-6)
    assert harmonic_phase_turn(res[:1], k + df) is not None  # three periods: two pairs
    assert harmonic_phase_turn(_sine_residuals(k, n_records=1, n=1999), k) is None  # one whole period


def test_suggested_experiment_separates_a_delay_from_a_lag_at_high_frequency():
    """A pure delay d and a first-order lag tau = d agree at low frequency (both a phase lag w d) and differ
    most at the highest probe frequency at which the fits stay near the recorded output range (Table 2's MRPIM
    driven from rest at 5 Hz leaves it by more than its width: its rate terms extrapolate)."""
    base = get_model("mrpim").preset("paper")
    t = np.arange(2000) * DT
    y = get_model("mrpim").simulate(paper_voltage(t, 1.0), DT, base, input_range=(0.5, 2.5))
    rec = Record("r.npz", t, paper_voltage(t, 1.0), y, frequency_hz=1.0)
    screen = SimpleNamespace(parts=[SimpleNamespace(record=rec)], input_range=(0.5, 2.5), noise_sd=0.01)
    delay = SimpleNamespace(cause="delay", kind=get_cause("delay"), model=ExtendedModel("mrpim", ("delay",)), params={**base, "delay": 0.02})
    lag = SimpleNamespace(cause="resonance", kind=get_cause("resonance"), model=ExtendedModel("mrpim", ("resonance",)),
                          params={**base, "natural_frequency": 1 / (2 * np.pi * 0.01), "damping_ratio": 1.0})
    out = suggest(screen, delay, lag)
    sines = [p for p in out["probes"] if p["drive"].startswith("sine")]
    inside = [p for p in sines if not p["outside_recorded"]]
    assert [p["outside_recorded"] for p in sines] == [False] * (len(sines) - 1) + [True]
    assert out["separation"] == max(p["separation"] for p in out["probes"] if not p["outside_recorded"])
    assert out["frequency_hz"] == inside[-1]["frequency_hz"]
    assert inside[-1]["separation"] > 5 * inside[0]["separation"]


def test_a_suggested_experiment_is_never_a_probe_on_which_a_fit_leaves_the_recorded_range():
    """Two fits that agree on the records but one of which runs away on a long hold (two slow time constants with
    large opposite weights do): the hold is not suggested, whatever its separation; if every probe runs away,
    no drive is suggested and the note says why. The probe sine is eq. 1's form over the input range."""
    t = np.arange(2000) * DT
    rec = Record("r.npz", t, np.zeros(2000), np.linspace(-1.0, 1.0, 2000), frequency_hz=1.0)
    screen = SimpleNamespace(parts=[SimpleNamespace(record=rec)], input_range=(-150.0, 150.0), noise_sd=0.01)

    def fit(cause, run_away_on_hold=False, run_away=False):
        def simulate(u, dt, params, input_range=None):
            y = u / 150.0 * 0.9
            if run_away or (run_away_on_hold and np.ptp(u) == 0):
                y = y + np.arange(u.size) * dt * 1e3
            return y
        return SimpleNamespace(cause=cause, kind=get_cause(cause), params={}, model=SimpleNamespace(param_names=(), simulate=simulate))

    out = suggest(screen, fit("relaxation", run_away_on_hold=True), fit("creep"))
    hold = [p for p in out["probes"] if p["drive"].startswith("input held")]
    assert hold and hold[0]["outside_recorded"] and hold[0]["separation"] > 100
    assert not out["drive"].startswith("input held") and not out["outside_recorded"]
    out = suggest(screen, fit("relaxation", run_away=True), fit("creep"))
    assert out["drive"] is None and "recorded output range" in out["note"]
    u = probe_sine(t, 1.0, -150.0, 150.0)
    assert u[0] == pytest.approx(-150.0) and u.max() == pytest.approx(150.0, rel=1e-6)
    np.testing.assert_allclose(probe_sine(t, 1.0, 0.5, 2.5), paper_voltage(t, 1.0))


def test_a_clip_on_top_is_clipped_in_the_suggested_experiments_probes():
    """A clip of a kept part (``Saturation.on_top``) shares that part's model; its probe prediction must be
    the part's output clipped at the level, not the part's output."""
    base = get_model("mrpim").preset("paper")
    rec = Record("r.npz", np.arange(2000) * DT, np.zeros(2000), np.zeros(2000), frequency_hz=1.0)
    screen = SimpleNamespace(parts=[SimpleNamespace(record=rec)], input_range=(0.5, 2.5), noise_sd=0.01)
    model = ExtendedModel("mrpim", ("delay",))
    part = Candidate("delay", "pure delay", model, {**base, "delay": 0.01}, 1, 1.0, 10)
    t = np.arange(4000) * DT
    u = paper_voltage(t, 1.0)
    y = model.simulate(u, DT, part.params, input_range=screen.input_range)
    level = float(np.quantile(y, 0.8))
    clip = Candidate("saturation", "pure delay + clipped from above", model, {**part.params, "saturation_level": level},
                     2, 1.0, 10, hyperparameters={"saturation_side": "upper"}, clips=part)
    got = predict(screen, clip, u, DT)
    np.testing.assert_array_equal(got, np.where(y > level, level, y))


def test_a_secondary_cause_kept_for_fewer_parameters_lists_the_ones_as_good_with_their_fits():
    """``secondary._choose`` keeps the simplest of the causes on top that the best does not beat by z >= z_same;
    it returns those as good (the best among them), whose fits the report shows and the suggested experiment
    separates; a cause the best beats clearly is not among them."""
    rng = np.random.default_rng(3)
    folds = Folds(np.array([0, 4000, 8000, 12000]))
    misfit = np.sin(np.arange(12000) / 300.0)
    noise = rng.normal(0, 0.05, 12000)
    kept = misfit + noise
    screen = SimpleNamespace(noise_sd=0.05, n=12000, n_held_out_rows=12000)

    def tried(cause, k, e):
        c = Candidate(cause, cause, None, {}, k, 1.0, 12000)
        c.heldout = {**score(folds, kept, e), "at_bound": [], "open_ended": []}
        return Tried(c, c, e, [], e, e, None)

    e1, e2 = 0.1 * misfit + noise, 0.1 * misfit + rng.normal(0, 0.05, 12000)
    e_mode, e_delay = sorted((e1, e2), key=lambda e: float(e @ e))  # the mode a little better, by chance
    delay, mode = tried("delay", 1, e_delay), tried("resonance", 2, e_mode)
    assert score(folds, e_delay, e_mode)["z"] < POLICY.z_same
    creep = tried("creep", 1, 0.8 * misfit + noise)  # clearly worse than the mode
    pick, alike = _choose(screen, folds, [mode, creep, delay], kept)
    assert pick is delay and alike == [mode.composite]
    assert delay.composite.heldout["as_good"] == ["resonance"]
    assert _choose(screen, folds, [creep], kept) == (creep, [])
    none_ok = tried("delay", 1, kept)
    none_ok.composite.heldout["at_bound"] = ["delay"]
    assert _choose(screen, folds, [none_ok], kept) == (None, [])


# --- planted effects (drawn within the detection limits) --------------------------------------------
# Detection limits (strength: rms of the effect, % of the output's peak-to-peak) on the Table 2 MRPIM's sines,
# measured by the accuracy benchmark; None: not reached (another cause mimics it).
LIMITS = {"relaxation": 1.11, "delay": None, "resonance": None, "creep": None, "interference": 0.195,
          "saturation": 2.42}
# Causes without a limit there, or with one above what these drives reach on the Table 2 MRPIM (a delay of at
# most 30 ms under 0.1-1 Hz sines: strength <= ~1.6 %; a mode: rarely above 5 %): a strong draw must be named
# or reported as ambiguous.
STRONG = {"delay": 1.2, "resonance": 3.0, "creep": 3.0}
# where those strong draws start: seed 11, but resonance's first draw from 11 at or above 3 % is seed 22, and each
# draw integrates the mode over every record (about 1 s): its search starts there
STRONG_START = {"delay": 11, "resonance": 22, "creep": 11}


def _draw_above(kinds, limit, base="mrpim", drive="sines", start=0):
    """The first seeded draw at or after ``start`` whose strength is at least ``limit``."""
    for seed in range(start, start + 200):
        ds, truth = planted_case(kinds, base, drive, seed)
        if truth["strength_pct"] >= limit:
            return ds, truth
    raise AssertionError(f"no draw of {kinds} above {limit} %")


@pytest.mark.parametrize("seed", [7, 3200052])
def test_the_planted_mrpim_plant_is_one_system_that_varpro_recovers_on_multisines(seed):
    """Every record of the Table 2 MRPIM plant has the same thresholds (not each record's own peak, which a
    multisine does not always reach), over the identification drives' range -- the range eq. 8 gives a model
    fitted to them: varpro on the three identification multisines then fits them and predicts the two
    validation multisines to the noise: thresholds from each record's own peak, or from a design range above
    every identification peak, leave a misfit several times the noise."""
    ds, truth = planted_case(("null-white",), "mrpim", "multisines", seed)
    peaks = [float(r.u.max()) for r in ds.records]
    assert max(peaks) - min(peaks) > 0.05  # the records differ in peak: each record's own thresholds would differ
    fit = identify(get_model("mrpim"), ds, method="varpro", seed=0)
    for r in ds.records:
        assert np.sqrt(np.mean((r.y - fit.predict(r)) ** 2)) < 1.05 * truth["noise_sd"], r.file


@pytest.mark.parametrize("cause", [c for c in CAUSES if c not in STRONG])
def test_planted_effect_is_named_measured_and_confirmed(cause):
    ds, truth = _draw_above((cause,), LIMITS[cause], start=11)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == cause, (truth, [(c.cause, c.heldout) for c in d.candidates])
    errors = parameter_errors(truth, cause, d.parameters)
    assert errors and all(v <= 0.25 for v in errors.values()), (errors, d.parameters, truth["effects"])
    v = d.gain()["validation"]
    fitted = d.extended_fit.fitted_on if d.extended_fit else [r.file for r in ds.identification]
    assert set(v["records"]).isdisjoint(fitted)  # validation records took part in no fit and no choice
    assert d.confirmed and not d.warning


# the bases other than the plant the base model represents, one drive each (the limits pool the drives)
BEYOND_MRPIM = [("delay", "virtual-dea", "triangles"), ("interference", "virtual-dea", "multisines"),
                ("relaxation", "piezo", "sines"), ("delay", "piezo", "sines"), ("resonance", "piezo", "sines"),
                ("creep", "piezo", "sines"), ("interference", "piezo", "sines"), ("saturation", "piezo", "sines")]


@pytest.mark.parametrize("cause, base, drive", BEYOND_MRPIM)
def test_an_effect_at_or_above_the_stated_detection_limit_of_its_base_is_named(cause, base, drive):
    """The first seeded draw (from 7,000,000, no plan's seed) at or above the cause's stated detection limit on
    that base (``stated_limits``: seeds 35-62, at least 20 cases at or above it), on a plant other than the
    Table 2 MRPIM, must be right by the benchmark's rule."""
    if base == "piezo" and not piezo_available():
        pytest.skip("the accuracy benchmark's piezo recording is not present")
    limit = stated_limit(cause, base)
    ds, truth = _draw_above((cause,), limit, base, drive, start=7_000_000)
    d = diagnose(ds, seed=0, experiments=False)
    also = [c.cause for c in d.also]
    assert judge(truth, d.cause, also), (truth["seed"], truth["strength_pct"], d.cause, also, d.verdict.reason)


def test_every_stated_limit_beyond_the_mrpim_plant_is_tested_here():
    stated = {(c, b) for (c, b), v in LIMITS_PCT.items() if b != "mrpim" and v is not None}
    assert stated == {(c, b) for c, b, _ in BEYOND_MRPIM}


def test_an_interference_is_scored_on_top_of_the_base_models_own_held_out_prediction():
    """A 23 Hz numpy sinusoid, its phase drawn per record, on a null of the virtual DEA under triangles (two
    periods per record: the base fitted on two records predicts the 0.1 Hz one poorly). The line's held-out
    residual is checked against a slow reference: the base solved on the other records alone by numpy's lstsq
    (its prediction of the left-out record), the line's amplitude the rms of the training records' own when
    solved together with the base there, the phase fitted on the held-out record. It removes what it should
    from every record, so the folds agree and it is named. (The base's prediction does not come from its fit
    with the line: the small change that makes to an extrapolated prediction can cost more than the line
    removes.)"""
    ds, _ = planted_case(("null-white",), "virtual-dea", "triangles", 7)
    rng = np.random.default_rng(3)
    for r in ds.records:
        r.y = r.y + 0.1 * np.sin(2 * np.pi * 23.3 * r.t + rng.uniform(0, 2 * np.pi))
    d = diagnose(ds, seed=0, experiments=False, extend=False)
    s, folds = d.screen, Folds.of(d.screen)
    c = next(c for c in d.candidates if c.cause == "interference")
    f = c.params["interference_frequency"]
    assert f == pytest.approx(23.3, abs=0.05)
    A = s.design(s.base, {k: c.params[k] for k in s.base_nl_names})
    times = [p.rows * p.record.dt for p in s.parts]

    def sinusoid(t):
        return np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t)])

    def together(m):  # the base and one sinusoid per training record, solved together
        others = [k for k in range(folds.n) if k != m]
        S = np.zeros((s.n, 2 * len(others)))
        for j, k in enumerate(others):
            S[folds.test(k), 2 * j:2 * j + 2] = sinusoid(times[k])
        train = ~folds.test(m)
        coef = np.linalg.lstsq(np.column_stack([A[train], S[train]]), s.y[train], rcond=None)[0]
        pairs = coef[A.shape[1]:].reshape(-1, 2)
        return np.hypot(pairs[:, 0], pairs[:, 1]), s.y[train] - np.column_stack([A[train], S[train]]) @ coef

    expected = np.empty(s.n)
    for m in range(folds.n):
        test = folds.test(m)
        theta = np.linalg.lstsq(A[~test], s.y[~test], rcond=None)[0]
        amps, _ = together(m)
        res = s.y[test] - A[test] @ theta
        ab = np.linalg.lstsq(sinusoid(times[m]), res, rcond=None)[0]
        expected[test] = res - sinusoid(times[m]) @ (math.sqrt(np.mean(np.square(amps))) * ab / math.hypot(*ab))
    train = []
    e, fold_est = heldout_errors(s, folds, c, train_residuals=train)
    assert np.allclose(e, expected, rtol=0, atol=1e-6 * np.abs(s.y).max())
    assert np.allclose(train[0], together(0)[1], rtol=0, atol=1e-6 * np.abs(s.y).max())
    assert fold_est[0]["amplitude"] == pytest.approx(math.sqrt(np.mean(np.square(together(0)[0]))), rel=1e-6)
    assert c.heldout["folds_improved"] == folds.n and c.heldout["same_line"]
    assert d.cause == "interference" and d.parameters["frequency_hz"] == pytest.approx(23.3, abs=0.05)


def test_an_interference_refitted_per_fold_takes_its_frequency_from_the_other_records_only():
    """A 27 Hz sinusoid (numpy, not the extension) added to one identification record of a null on the Table 2
    MRPIM: the fit on all records finds it, but the record's own fold searches the frequency on the two records
    without it and does not find 27 Hz. The folds then disagree, which is no line (``same_line``): no fold is
    scored at a frequency chosen with its held-out record."""
    ds, _ = planted_case(("null-white",), "mrpim", "sines", 0)
    r = ds.identification[0]
    r.y = r.y + 0.05 * np.sin(2 * np.pi * 27.0 * r.t + 0.3)
    d = diagnose(ds, seed=0, experiments=False, extend=False)
    s, folds = d.screen, Folds.of(d.screen)
    null_train = []
    heldout_null(s, folds, null_train)
    assert abs(fold_frequencies(s, null_train)[0] - 27.0) > 1.0
    c = next(c for c in d.candidates if c.cause == "interference")
    # chosen on all records, with one amplitude for all (``loo_rss``): a little off 27 Hz, where records 1 and 2,
    # which lack the line, pay less for it
    assert c.estimates["frequency_hz"] == pytest.approx(27.0, abs=0.1)
    _, fold_est = heldout_errors(s, folds, c, refit=True)
    assert abs(fold_est[0]["interference_frequency"] - 27.0) > 1.0
    assert not same_line(s, fold_est)


def test_a_fold_chooses_the_line_of_one_amplitude_over_a_stronger_line_in_one_record():
    """Two numpy sinusoids on a null of the Table 2 MRPIM: 27 Hz at one amplitude in records 1 and 2, and a
    three times stronger 41 Hz in record 1 alone. Fitted with amplitude and phase free per record (the slow
    reference below), 41 Hz leaves less of the two records; but an interference is scored with the other
    records' amplitude, so a fold trained on records 1 and 2 chooses 27 Hz (``loo_rss``), as do the search
    on top of a kept cause (``fold_frequencies``); the fit on every record (``Interference.fit``), where
    record 0 lacks both lines, does not choose 41 Hz either."""
    ds, _ = planted_case(("null-white",), "mrpim", "sines", 0)
    for k, phase in ((1, 0.4), (2, 2.1)):
        r = ds.identification[k]
        r.y = r.y + 0.05 * np.sin(2 * np.pi * 27.0 * r.t + phase)
    r = ds.identification[1]
    r.y = r.y + 0.15 * np.sin(2 * np.pi * 41.0 * r.t)
    d = diagnose(ds, seed=0, experiments=False, extend=False)
    s, folds = d.screen, Folds.of(d.screen)
    base_rows = s.design(s.base, s.base_nl)
    train = ~folds.test(0)
    y = s.y[train] - base_rows[train] @ np.linalg.lstsq(base_rows[train], s.y[train], rcond=None)[0]
    sizes = [s.parts[k].rows.size for k in (1, 2)]

    def free_rss(g):  # amplitude and phase free in each record
        out = 0.0
        for part, res in zip((s.parts[1], s.parts[2]), np.split(y, [sizes[0]])):
            t = part.rows * part.record.dt
            S = np.column_stack([np.sin(2 * np.pi * g * t), np.cos(2 * np.pi * g * t)])
            left = res - S @ np.linalg.lstsq(S, res, rcond=None)[0]
            out += float(left @ left)
        return out

    assert free_rss(41.0) < free_rss(27.0)
    null_train = []
    heldout_null(s, folds, null_train)
    assert fold_frequencies(s, null_train)[0] == pytest.approx(27.0, abs=0.02)
    whole = next(c for c in d.candidates if c.cause == "interference")  # on every record: not record 1's line
    assert abs(whole.estimates["frequency_hz"] - 41.0) > 1.0


def test_one_line_means_frequencies_within_the_coarsest_folds_resolution_and_amplitudes_within_a_quarter():
    spans = [(20.0, 0.01), (5.0, 0.01), (2.0, 0.01)]  # (duration s, dt): fold 0 trains on 5 s at most
    parts = [SimpleNamespace(record=SimpleNamespace(t=np.zeros(int(T / dt)), dt=dt)) for T, dt in spans]
    fake = SimpleNamespace(parts=parts, policy=POLICY)
    est = lambda fs, amps: [{"interference_frequency": f, "amplitude": a} for f, a in zip(fs, amps)]  # noqa: E731
    assert same_line(fake, est([30.0, 30.19, 30.1], [1.0, 1.1, 0.9]))
    assert not same_line(fake, est([30.0, 30.21, 30.1], [1.0, 1.1, 0.9]))  # beyond 1 / 5 s
    assert not same_line(fake, est([30.0, 30.0, 30.0], [1.0, 1.3, 1.0]))  # amplitudes differ by 30 %
    assert frequencies_agree(fake, [30.0, 30.19, 30.1]) and not frequencies_agree(fake, [30.0, 30.21, 30.1])
    assert not frequencies_agree(fake, [30.0])  # one fold: nothing to agree with
    assert _folds_disagree(fake, [30.0, 30.19]) == ""
    assert "not one line" in _folds_disagree(fake, [2.06, 3.92])  # a line on top is one only if the folds agree


def test_strongest_first_orders_by_own_heldout_gain_and_puts_the_unscored_last():
    own = {c: SimpleNamespace(heldout_gain=g) for c, g in
           (("delay", 0.19), ("creep", 0.87), ("resonance", math.nan), ("relaxation", 0.5))}
    assert strongest_first(own, ["delay", "resonance", "creep", "relaxation"]) == [
        "creep", "relaxation", "delay", "resonance"]
    assert strongest_first(own, ["delay"]) == ["delay"]


def test_the_backward_steps_creep_standing_in_follows_the_secondary_causes_strongest_first():
    """Creep stands for a named relaxation's slow part only after the kept causes, and those in the same order
    as without it (strongest first), and only when the slowest time constant is past every drive period."""
    own = {c: SimpleNamespace(heldout_gain=g) for c, g in (("delay", 0.2), ("resonance", 0.6), ("creep", 0.4))}
    slow = SimpleNamespace(cause="relaxation", kind=get_cause("relaxation"), estimates={"tau_s": [0.05, 13.0]})
    assert replacements(slow, own, ["delay", "resonance"], creep_min=20.0, policy=POLICY) == [
        ["resonance", "delay"], ["resonance", "delay", "creep"]]
    fast = SimpleNamespace(cause="relaxation", kind=get_cause("relaxation"), estimates={"tau_s": [0.05, 9.0]})
    assert replacements(fast, own, ["delay", "resonance"], creep_min=20.0, policy=POLICY) == [["resonance", "delay"]]
    assert replacements(slow, own, ["creep", "delay"], creep_min=20.0, policy=POLICY) == [["creep", "delay"]]
    named_delay = SimpleNamespace(cause="delay", kind=get_cause("delay"), estimates={"delay_s": 0.02})
    assert replacements(named_delay, own, ["resonance"], creep_min=20.0, policy=POLICY) == [["resonance"]]


@given(lo=st.floats(1e-3, 1.0), ratio=st.floats(2.0, 1e4), dt=st.floats(1e-4, 1e-3))
def test_a_second_cause_starts_on_a_grid_strictly_inside_its_bounds(lo, ratio, dt):
    """``composite_starts``: the given start first, then a geometric grid strictly inside each named parameter's
    bounds (a delay from one sample up), 12 points for one parameter, 6 x 6 for a mode; a relaxation of
    several time constants keeps its own start only."""
    bounds = {"delay": (0.0, lo * ratio), "natural_frequency": (lo, lo * ratio), "damping_ratio": (0.01, 1.0),
              "tau1": (lo, lo * ratio), "tau2": (lo, lo * ratio)}
    fake = SimpleNamespace(bounds_of=lambda model, name: bounds[name],
                           parts=[SimpleNamespace(record=SimpleNamespace(dt=dt))])
    start = {"delay": 0.5 * lo, "natural_frequency": 2 * lo, "damping_ratio": 0.3, "tau1": lo, "tau2": 2 * lo}
    for names, n in ((["delay"], 12), (["natural_frequency", "damping_ratio"], 36), (["tau1", "tau2"], 0)):
        starts = composite_starts(fake, None, start, names)
        assert starts[0] == start and len(starts) == 1 + n
        for name in names if n else []:
            a, b = bounds[name]
            a = dt if name == "delay" else a
            values = np.unique([z[name] for z in starts[1:]])
            assert values.size == (12 if len(names) == 1 else 6)
            assert np.all((values > a) & (values < b)), (name, values, a, b)
            if a < b:
                assert np.allclose(np.diff(np.log(values)), math.log(b / a) / (values.size + 1))


def test_a_named_level_must_cut_the_prediction_as_a_clip_on_top_must():
    """The base's own saturation candidate answers to the same meaning as a clip on top: a level that cuts
    fewer than ``min_clipped_samples`` samples of the prediction (no slope where clipped can be measured) is no
    clip."""
    fake = SimpleNamespace(policy=POLICY)
    assert Screen.limit_of(fake, "saturation", {"level": 1.0, "side": "upper"}) == NO_CUT
    assert Screen.limit_of(fake, "saturation", {"level": 1.0, "side": "upper", "slope_where_clipped": 0.02}) == ""
    assert "not a clip" in Screen.limit_of(fake, "saturation",
                                           {"level": 1.0, "side": "upper", "slope_where_clipped": 0.8})


@given(fn=st.floats(0.5, 200.0), zeta=st.floats(0.02, 1.0), extra=st.floats(0.0, 0.2))
def test_a_mode_started_on_top_of_a_delay_keeps_the_low_frequency_lag(fn, zeta, extra):
    """``lag_shared``: a mode started on top of a kept delay shortens the delay by the mode's low-frequency
    lag, so the two together lag the input as the delay alone did. Checked on the mode's transfer function
    1 / (1 - r^2 + 2 j zeta r) at r = 1e-3 (its phase per radian, not the formula used)."""
    from hysbench.benchmarks.diagnosis.causes.resonance import lag_shared

    wn = 2 * math.pi * fn
    w = 1e-3 * wn
    mode_phase = -np.angle(1.0 / (1.0 - (w / wn) ** 2 + 2j * zeta * w / wn))  # lag in rad
    delay = mode_phase / w + extra  # the delay a fit without the mode would have chosen
    z = lag_shared({"delay": delay, "natural_frequency": fn, "damping_ratio": zeta, "tau1": 0.3})
    assert z["tau1"] == 0.3 and z["natural_frequency"] == fn and z["damping_ratio"] == zeta
    assert z["delay"] == pytest.approx(extra, rel=1e-4, abs=1e-5 * delay)  # the lag is exact only as r -> 0
    short = lag_shared({"delay": 0.5 * mode_phase / w, "natural_frequency": fn, "damping_ratio": zeta})
    assert short["delay"] == 0.0  # never negative


def _completion_context(monkeypatch, on: Candidate, kept: Candidate, folds, e_null, result=None):
    """A stand-in for the forward selection (it keeps ``kept`` on top of ``on``) and the context it runs in."""
    from hysbench.benchmarks.diagnosis import secondary
    from hysbench.benchmarks.diagnosis.rule import Context

    def forward(ctx, p, taken):
        assert p is on and taken == {on.cause}  # the forward selection runs on top of the completed cause
        return secondary.Forward(p, (kept,), (kept,), ())

    monkeypatch.setattr(secondary, "forward", forward)
    t = np.arange(e_null.size)
    screen = SimpleNamespace(n=t.size, n_held_out_rows=t.size, noise_sd=0.05, null=object(), policy=POLICY)
    diag = SimpleNamespace(screen=screen, candidates=[on], structure={"structured": False})
    return Context(diag, result or {"heldout": HeldOut(folds, e_null), "folds": folds}, lambda m: None)


@pytest.mark.parametrize("left_by_both, named", [(0.3, True), (0.7, False)])
def test_a_partial_cause_is_named_only_if_the_causes_on_top_explain_half_the_misfit_with_it(monkeypatch,
                                                                                             left_by_both, named):
    """``complete-partial``: the forward selection on top of a partial cause (here a stand-in adding one cause
    whose held-out residual leaves a given share of the misfit beyond noise) names it only if what is then kept
    removes at least half of the base's held-out misfit beyond noise; otherwise the verdict stays unexplained."""
    from hysbench.benchmarks.diagnosis.rule import Verdict, apply
    from hysbench.benchmarks.diagnosis.secondary import COMPLETE_PARTIAL

    rng = np.random.default_rng(5)
    folds = Folds(np.array([0, 4000, 8000, 12000]))
    t = np.arange(12000) * DT
    noise = rng.normal(0, 0.05, t.size)
    signal_ = np.sin(2 * np.pi * 0.37 * t)
    e_null = signal_ + noise
    partial = _scored("relaxation", folds, e_null, 0.75 * signal_ + noise)  # 44 % of the misfit: partial
    both = np.sqrt(left_by_both) * signal_ + noise
    excess = float(e_null @ e_null) - t.size * 0.05**2
    assert (float(e_null @ e_null) - float(both @ both)) / excess == pytest.approx(1 - left_by_both, abs=0.03)
    ctx = _completion_context(monkeypatch, partial, _scored("delay", folds, e_null, both), folds, e_null)
    unexplained = Verdict("unexplained", None, reason="the best-predicting cause removes only 44 %", partial=partial)
    v = apply(COMPLETE_PARTIAL, COMPLETE_PARTIAL.gather(ctx, unexplained), unexplained, POLICY)
    assert [(t["rule"], t["outcome"], t["inputs"].get("kept")) for t in v.trace] == [
        ("also", "delay", None), ("complete-partial", "relaxation" if named else "unexplained", ["delay"])]
    if named:
        assert v.cause == "relaxation" and v.chosen is partial and v.partial is None and len(v.also) == 1
    else:
        assert (v.cause, v.partial, v.also) == ("unexplained", partial, ())
        assert unexplained.trace == ()  # the verdict passed in is not changed


@pytest.mark.parametrize("case, named", [("on every record", True), ("on one record", False),
                                         ("a third of the misfit", False)])
def test_a_promising_cause_is_named_only_if_with_the_causes_on_top_several_records_show_evidence(monkeypatch,
                                                                                                case, named):
    """``complete-promising``: a ``none`` verdict whose best candidate predicts most held-out records better but
    short of evidence runs the forward selection on top of it (a stand-in adding one cause). It is named only if
    what is then kept, refitted per fold, shows evidence against the base that more than one record carries and
    removes at least half of the misfit beyond noise; otherwise the verdict stays ``none``."""
    from hysbench.benchmarks.diagnosis.heldout import evidence, promising
    from hysbench.benchmarks.diagnosis.rule import Verdict, apply
    from hysbench.benchmarks.diagnosis.secondary import COMPLETE_PROMISING

    rng = np.random.default_rng(8)
    folds = Folds(np.array([0, 4000, 8000, 12000]))
    t = np.arange(12000) * DT
    noise = rng.normal(0, 0.05, t.size)
    signal_ = np.where(t >= 8000 * DT, 3.0, 1.0) * np.sin(2 * np.pi * 0.37 * t)  # most of it on one record
    e_null = signal_ + noise
    weak = signal_.copy()
    weak[8000:] *= 0.6  # the promising cause alone: better on one record only
    p = _scored("delay", folds, e_null, weak + noise)
    p.heldout["folds_improved"] = 2  # and slightly on another: most records, no evidence
    assert promising(p, POLICY) and not evidence(p.heldout, POLICY)
    left = {"on every record": 0.1 * signal_,
            "on one record": np.where(t >= 8000 * DT, 0.1, 0.998) * signal_,  # evidence, but that record's
            "a third of the misfit": np.sqrt(0.67) * signal_}[case]
    both = left + noise
    kept = _scored("relaxation", folds, e_null, both)
    kept.heldout["refit_per_fold"] = True
    result = {"heldout": HeldOut(folds, e_null, [(kept, both)]), "folds": folds}
    ctx = _completion_context(monkeypatch, p, kept, folds, e_null, result)
    none = Verdict("none", None, reason="the best is not evidence")
    v = apply(COMPLETE_PROMISING, COMPLETE_PROMISING.gather(ctx, none), none, POLICY)
    assert [(t["rule"], t["outcome"], t["inputs"].get("kept")) for t in v.trace] == [
        ("also", "relaxation", None), ("complete-promising", "delay" if named else "none", ["relaxation"])]
    if named:
        assert v.cause == "delay" and v.chosen is p and v.also == (kept,)
    else:
        assert (v.cause, v.chosen, v.also) == ("none", None, ())
    p.limit = "outside its meaning"  # a candidate outside its cause's meaning is not completed
    assert COMPLETE_PROMISING.gather(ctx, none) is None


def test_a_base_fit_pinned_at_a_bound_is_a_caution_on_the_verdict():
    from hysbench.benchmarks.diagnosis.report import base_bound_caution

    pinned = SimpleNamespace(params={"gamma": 0.0197, "lambda": -0.0197, "a1": 2.0},
                             diagnostics={"at_bounds": ["gamma", "lambda"]})
    assert base_bound_caution(pinned) == (
        "the base model's fit has parameters at their search bounds (gamma = 0.0197, lambda = -0.0197): part of "
        "the misfit the diagnosis explains may be that bound's, not the actuator's")
    assert base_bound_caution(SimpleNamespace(params={"a1": 2.0}, diagnostics={"at_bounds": []})) == ""
    # a real fit pinned at a bound says so in the same place as its note
    ds, _ = planted_case(("null-white",), "mrpim", "sines", 1)
    fit = identify(get_model("mrpim"), ds, method="varpro", seed=0, bounds={"gamma": [0.05, 0.1]})  # truth 0.0323
    pinned = fit.diagnostics["at_bounds"]
    assert pinned and all(f"{n} = " in base_bound_caution(fit) for n in pinned)


def test_a_mode_inside_a_broadband_drive_is_searched_and_named():
    """Multisines of 0.5-10 Hz (no nominal frequency: the causes' time scale is 1 / 10 Hz) through the Table 2
    MRPIM and a 4 Hz mode (damping 0.2) integrated by RK45: the mode lies inside the drive's band, below
    1 / T (as the Bouc-Wen benchmark's mode lies inside its 5-150 Hz multisine)."""
    from hysbench.data.dataset import Dataset
    from hysbench.data.excitations import HIGH_KV, LOW_KV, multisine

    model, rng, dt = get_model("mrpim"), np.random.default_rng(3), 2e-3
    params, records = model.preset("paper"), []
    for i, role in enumerate(("identification", "identification", "validation", "identification")):
        u = multisine(12.0, dt, f_min=0.5, f_max=10.0, n_tones=12, seed=40 + i)
        y = mode_ode(model.simulate(u, dt, params, input_range=(LOW_KV, HIGH_KV)), dt, 4.0, 0.2)
        records.append(Record(f"ms{i}.csv", np.arange(u.size) * dt, u, y + rng.normal(0.0, 0.005, u.size),
                              role=role))
    d = diagnose(Dataset(name="broadband-mode", records=records, input_unit="kV", output_unit="mm"), seed=0,
                 experiments=False)
    assert d.cause == "resonance", [(c.cause, c.heldout, c.estimates) for c in d.candidates]
    assert d.parameters["natural_frequency_hz"] == pytest.approx(4.0, rel=0.25)
    assert d.parameters["damping_ratio"] == pytest.approx(0.2, rel=0.25)
    from hysbench.benchmarks.diagnosis.report import verdict_lines

    named = next(line for line in verdict_lines(d) if line.startswith("parameters: "))
    assert "natural_frequency_hz = " in named and "damping_ratio = " in named  # both named, not only one


# --- pinned planted cases: one table, each case diagnosed once ------------------------------------------------
@dataclass(frozen=True)
class Pin:
    """A planted case and what the diagnosis must give on it. ``cause``: the named cause (a tuple: any of them);
    ``also``: exactly these causes kept on top (None: not checked), ``also_has`` / ``also_not``: among them or
    not; ``dropped``: the first named cause dropped by the backward step (False: none dropped); ``confirmed``
    (None: not checked); ``remainder``: the least unexplained remainder said with it; ``ambiguous``: causes
    listed as ambiguous with it; ``rules``: (rule id, outcome) entries its trace must hold (outcome None: any);
    ``errors``: {cause: {parameter: largest relative error}}, of the named cause or of one kept under also;
    ``variant``: the same rule path and outcome as another pinned case (another seed, drive or plant), run with
    ``-m slow`` (pyproject's addopts leave the slow tests out of the default run)."""

    kinds: tuple
    base: str
    drive: str
    seed: int
    effects: dict | None = None
    extend: bool = True
    experiments: bool = False
    cause: str | tuple = ()
    also: tuple | None = None
    also_has: tuple = ()
    also_not: tuple = ()
    dropped: str | bool | None = None
    confirmed: bool | None = None
    remainder: float | None = None
    ambiguous: tuple = ()
    rules: tuple = ()
    errors: dict = field(default_factory=dict)
    variant: bool = False

    def diagnosed(self):
        if self.base == "piezo" and not piezo_available():
            pytest.skip("the accuracy benchmark's piezo recording is not present")
        return diagnosed(self.kinds, self.base, self.drive, self.seed, self.effects, self.extend, self.experiments)


NOT_A_CAUSE = ("none", "unexplained")
# a test that reads a pinned case runs in the process that diagnosed it (pyproject: --dist loadgroup)
same_worker = pytest.mark.xdist_group
PINNED = {
    # a relaxation whose second time constant sits at its bound gives the variant of one fewer
    "relaxation-one-fewer-than-a-pinned-pair": Pin(("relaxation",), "mrpim", "sines", 3500182, extend=False,
                                                   cause="relaxation", errors={"relaxation": {"tau_s": 0.05}}),
    "white-noise-is-none": Pin(("null-white",), "mrpim", "sines", 0, cause="none"),
    "ar1-noise-is-none": Pin(("null-ar1",), "mrpim", "sines", 1, {"null-ar1": {"ar1": 0.99}}, cause="none"),
    "ar1-noise-is-none-again": Pin(("null-ar1",), "mrpim", "sines", 2, {"null-ar1": {"ar1": 0.99}}, cause="none",
                                   variant=True),
    "gain-modulation-is-no-vocabulary-cause": Pin(("gain-modulation",), "mrpim", "sines", 3, cause=NOT_A_CAUSE),
    "dead-zone-is-no-vocabulary-cause": Pin(("dead-zone",), "mrpim", "sines", 3, cause=NOT_A_CAUSE, variant=True),
    # a sinusoid of under two cycles per record is a per-record drift, not an interference
    "modulation-slower-than-the-records": Pin(
        ("gain-modulation",), "mrpim", "multisines", 5,
        {"gain-modulation": {"depth": 0.065, "period_s": 40.0, "phase_rad": 5.75}}, cause=NOT_A_CAUSE),
    # one line on every fold names an interference below the gain floor, the rest unexplained
    "line-below-the-gain-floor": Pin(("interference",), "virtual-dea", "triangles", 104, cause="interference",
                                     remainder=0.9, rules=(("specific-part", "interference"),),
                                     errors={"interference": {"frequency_hz": 1e-3}}),
    "line-on-top-of-the-physics-relaxation": Pin(
        ("interference",), "virtual-dea", "sines", 4, {"interference": {"frequency_hz": 13.7, "amplitude": 0.08}},
        cause="relaxation", also_has=("interference",), errors={"interference": {"frequency_hz": 0.25}}),
    "weak-line-found-on-top-of-what-is-kept": Pin(
        ("interference",), "virtual-dea", "sines", 4, {"interference": {"frequency_hz": 23.8, "amplitude": 0.027}},
        cause="relaxation", also_has=("delay", "interference"), errors={"interference": {"frequency_hz": 0.25}}),
    # the backward step: the secondary causes alone predict as well, the named relaxation is not needed
    "relaxation-dropped-for-delay-with-creep-standing-in": Pin(
        ("delay", "creep"), "mrpim", "sines", 57, cause="delay", also=("creep",), dropped="relaxation",
        rules=(("drop-redundant-primary", "delay"),), errors={"delay": {"delay_s": 0.25}}),
    "relaxation-dropped-causes-composed-strongest-first": Pin(
        ("delay", "creep"), "mrpim", "sines", 3700057, cause="creep", also=("delay",), dropped="relaxation",
        rules=(("drop-redundant-primary", "creep"),), errors={"delay": {"delay_s": 0.25}}, variant=True),
    "relaxation-dropped-creep-alone-at-its-limit": Pin(
        ("delay", "creep"), "mrpim", "sines", 3800177, cause="creep", also=("delay",), dropped="relaxation",
        rules=(("drop-redundant-primary", "creep"),), errors={"delay": {"delay_s": 0.25}}),
    "creep-standing-in-at-its-limit": Pin(
        ("delay", "creep"), "mrpim", "sines", 3100177, cause="delay", also=("creep",), dropped="relaxation",
        rules=(("drop-redundant-primary", "delay"),), errors={"delay": {"delay_s": 0.25}}, variant=True),
    "creep-standing-in-at-the-end-of-its-search": Pin(
        ("delay", "creep"), "mrpim", "sines", 3200177, cause="delay", also=("creep",), dropped="relaxation",
        rules=(("drop-redundant-primary", "delay"),), errors={"delay": {"delay_s": 0.25}}),
    # a replacement must remove half of the misfit, as a named cause must: the delay stays
    "delay-kept-against-a-mode-that-explains-less": Pin(("delay",), "mrpim", "triangles", 5100155, cause="delay",
                                                        dropped=False, errors={"delay": {"delay_s": 0.25}}),
    "second-cause-searched-afresh-on-top": Pin(("delay", "creep"), "mrpim", "multisines", 27, cause="delay",
                                               also=("creep",), errors={"creep": {"drift": 0.25}}),
    # the best-predicting relaxation's folds disagree: the specific interference is named with the rest
    "specific-part-named-beside-an-unstable-best": Pin(
        ("interference",), "virtual-dea", "triangles", 2200104, cause="interference", remainder=0.5,
        rules=(("specific-part", "interference"),),
        errors={"interference": {"frequency_hz": 0.01, "amplitude": 0.25}}, variant=True),
    "clip-searched-on-top-of-the-named-cause": Pin(
        ("saturation",), "virtual-dea", "multisines", 2200046, cause="relaxation", also_has=("saturation",),
        errors={"saturation": {"level_over_p2p": 0.01}}),
    "level-that-cuts-nothing-is-no-clip-on-top": Pin(("creep",), "mrpim", "sines", 2200039, cause="creep",
                                                     also_not=("saturation",)),
    # two records: two agreeing fold estimates do not name a cause that does not predict best
    "two-records-name-no-partial-rival": Pin(("sensor-nonlinearity",), "piezo", "sines", 84, cause=NOT_A_CAUSE),
    "mode-above-the-drives-is-resonance": Pin(
        ("resonance",), "mrpim", "sines", 11, {"resonance": {"natural_frequency_hz": 12.0, "damping_ratio": 0.2}},
        cause="resonance", errors={"resonance": {"natural_frequency_hz": 0.25, "damping_ratio": 0.25}}),
    # a mode searched on top of a kept delay starts with the delay shortened by its lag
    "mode-on-top-of-the-delay-kept-for-the-physics-lag": Pin(
        ("resonance",), "virtual-dea", "multisines", 3100096, cause="relaxation", also_has=("resonance",),
        errors={"resonance": {"natural_frequency_hz": 0.25, "damping_ratio": 0.25}}),
    "partial-mode-completed-by-creep": Pin(
        ("resonance", "creep"), "mrpim", "sines", 3500088, cause="resonance", also_has=("creep",),
        rules=(("complete-partial", "resonance"),),
        errors={"resonance": {"natural_frequency_hz": 0.25}, "creep": {"drift": 0.25}}),
    "promising-delay-completed-by-relaxation": Pin(
        ("delay",), "virtual-dea", "triangles", 4300154, cause="delay", also_has=("relaxation",),
        rules=(("nothing-passes", "none"), ("complete-promising", "delay"))),
    "creep-open-ended-named-with-a-mode-on-top": Pin(
        ("resonance", "creep"), "mrpim", "sines", 3200148, cause="creep", also=("resonance",),
        errors={"creep": {"drift": 0.25}, "resonance": {"natural_frequency_hz": 0.25, "damping_ratio": 0.25}}),
    "delay-found-by-the-exact-scan": Pin(("delay",), "mrpim", "triangles", 3600093, extend=False, cause="delay",
                                         errors={"delay": {"delay_s": 0.01}}),
    "delay-at-triangle-corners": Pin(("delay",), "mrpim", "triangles", 63, {"delay": {"delay_s": 0.0231}},
                                     extend=False, cause="delay", errors={"delay": {"delay_s": 0.05}}, variant=True),
    "short-delay-at-triangle-corners": Pin(("delay",), "mrpim", "triangles", 63, {"delay": {"delay_s": 0.012}},
                                           extend=False, cause="delay", errors={"delay": {"delay_s": 0.05}}),
    "line-within-a-broadband-drives-reach": Pin(
        ("interference",), "mrpim", "multisines", 5, {"interference": {"frequency_hz": 38.0, "amplitude": 0.05}},
        cause="interference", confirmed=True, errors={"interference": {"frequency_hz": 1e-3, "amplitude": 0.25}}),
    "gain-modulation-is-no-clip": Pin(("gain-modulation",), "mrpim", "multisines", 1300113,
                                      cause=("none", "unexplained", *(c for c in CAUSES if c != "saturation"))),
    "clip-against-the-model-is-none": Pin(("null-ar1",), "mrpim", "sines", 172, cause="none"),
    "clip-predicted-from-records-that-show-it": Pin(("saturation",), "mrpim", "multisines", 1600017,
                                                    cause="saturation", errors={"saturation": {"level_over_p2p": 0.25}}),
    "sub-sample-delay-on-white-noise-is-none": Pin(("null-white",), "mrpim", "multisines", 2900139,
                                                   cause=NOT_A_CAUSE),
    "creep-on-the-physics-is-ambiguous-with-its-slow-relaxation": Pin(
        ("creep",), "virtual-dea", "sines", 10, extend=False, experiments=True, cause="relaxation",
        ambiguous=("creep",), rules=(("slow-part-twin", "creep ambiguous"),)),
    "mode-kept-as-a-delay-on-the-physics": Pin(("resonance",), "virtual-dea", "multisines", 4500096,
                                               experiments=True, cause="relaxation", also_has=("delay",)),
    "mode-on-the-piezo-with-a-line-tried-on-top": Pin(("resonance",), "piezo", "sines", 3800036, cause="resonance"),
    # the piezo's own slow misfit: an unidentified rival does not make the delay a guess
    "delay-on-the-piezo-beside-an-unidentified-rival": Pin(
        ("delay",), "piezo", "sines", 25, cause="delay", remainder=0.5, confirmed=True,
        errors={"delay": {"delay_s": 0.3}}),
}


def pinned_param(name: str, *values):
    """A test parameter that reads the pinned case ``name``: in its worker, and slow if it is a variant."""
    marks = [same_worker(name)] + ([pytest.mark.slow] if PINNED[name].variant else [])
    return pytest.param(*(values or (name,)), marks=marks)


@pytest.mark.parametrize("name", [pinned_param(n) for n in PINNED])
def test_a_pinned_planted_case_gives_its_verdict(name):
    pin = PINNED[name]
    d, truth = pin.diagnosed()
    why = (d.cause, d.verdict.reason, d.trace)
    assert d.cause in ((pin.cause,) if isinstance(pin.cause, str) else pin.cause), why
    also = [c.cause for c in d.also]
    assert pin.also is None or also == list(pin.also), (also, why)
    assert set(pin.also_has) <= set(also) and not set(pin.also_not) & set(also), (also, why)
    if pin.dropped is not None:
        assert (d.dropped.cause if d.dropped is not None else False) == pin.dropped, why
    if pin.confirmed is not None:
        assert d.confirmed is pin.confirmed, why
    if pin.remainder is not None:
        assert d.verdict.remainder is not None and d.verdict.remainder > pin.remainder, why
    assert set(pin.ambiguous) <= {c.cause for c in d.verdict.ambiguous_with}, why
    for rule, outcome in pin.rules:
        assert any(t["rule"] == rule and outcome in (None, t["outcome"]) for t in d.trace), (rule, outcome, why)
    for cause, bounds in pin.errors.items():
        found = d.parameters if cause == d.cause else next(c.estimates for c in d.also if c.cause == cause)
        errors = parameter_errors(truth, cause, found)
        assert all(errors[k] <= v for k, v in bounds.items()), (cause, errors, found)
    if d.cause == "none":
        assert d.extended_fit is None and d.also == [] and d.parameters == {}


def pinned(name):
    return PINNED[name].diagnosed()


@same_worker("relaxation-one-fewer-than-a-pinned-pair")
def test_a_relaxation_of_one_fewer_time_constant_replaces_a_pair_with_one_pinned():
    d, _ = pinned("relaxation-one-fewer-than-a-pinned-pair")
    assert len(d.parameters["tau_s"]) == 1


@same_worker("modulation-slower-than-the-records")
def test_a_slow_modulation_is_outside_the_interferences_meaning():
    d, _ = pinned("modulation-slower-than-the-records")
    slow = [c for c in d.candidates if c.cause == "interference"
            and c.estimates["frequency_hz"] * d.screen.shortest_span < d.policy.interference_min_cycles]
    assert all(c.limit for c in slow)


@same_worker("line-below-the-gain-floor")
def test_a_line_below_the_gain_floor_is_one_line_on_every_fold():
    d, _ = pinned("line-below-the-gain-floor")
    h = d.chosen.heldout
    assert h["same_line"] and h["refit_per_fold"] and 0 < h["gain"] < d.policy.min_explained


@pytest.mark.parametrize("name, end, alone", [
    pinned_param(name, name, end, alone) for name, end, alone in (
        ("creep-standing-in-at-its-limit", "limit", False),
        ("creep-standing-in-at-the-end-of-its-search", "search", False),
        ("relaxation-dropped-creep-alone-at-its-limit", "limit", True))])
def test_a_creep_replacing_a_relaxation_may_sit_at_either_end_of_its_time_scale(name, end, alone):
    """Creep standing for a relaxation slower than every drive period: its time scale at the fastest its meaning
    allows or the slowest searched; reported as not identified, in the trace, the JSON and the also line."""
    d, _ = pinned(name)
    step_ = next(t for t in d.trace if t["rule"] == "drop-redundant-primary")
    assert step_["inputs"]["creep_time_end"]["end"] == end and step_["inputs"]["creep_time_end"]["alone"] is alone
    if d.cause == "delay":
        assert list(d.to_json()["also_not_identified"]) == ["creep"]
        assert any(line.startswith("also: creep (not identified: ") for line in verdict_lines(d))
        assert d.one_drive_caution == ""  # the protocol's seven frequencies
    lines = verdict_lines(d)
    pinned_base = any(n.startswith("parameters at their bounds") for n in d.base_fit.notes)
    assert any(line.startswith("caution: the base model's fit has parameters at their search bounds")
               for line in lines) == pinned_base


@same_worker("relaxation-dropped-for-delay-with-creep-standing-in")
def test_a_dropped_relaxation_is_in_the_json_with_the_creep_that_stands_in_for_it():
    d, _ = pinned("relaxation-dropped-for-delay-with-creep-standing-in")
    assert next(t for t in d.trace if t["rule"] == "drop-redundant-primary")["inputs"]["creep_standing_in"]
    assert d.to_json()["dropped_as_redundant"]["cause"] == "relaxation"


@same_worker("creep-open-ended-named-with-a-mode-on-top")
def test_a_creep_running_to_its_upper_bound_is_open_ended_not_at_bound():
    d, _ = pinned("creep-open-ended-named-with-a-mode-on-top")
    assert d.chosen.heldout["open_ended"] == ["creep_time"] and not d.chosen.heldout["at_bound"]
    lines = verdict_lines(d)
    spread = next(line for line in lines if line.startswith("uncertainty"))  # by the reported name, with its mean
    assert re.search(r"time_scale_s \([^)]* s\): not identified", spread), spread
    assert "s (not identified)" in next(line for line in lines if line.startswith("parameters:"))
    assert any(n.startswith("creep: creep_time (") for n in d.to_json()["not_identified"])


@same_worker("clip-searched-on-top-of-the-named-cause")
def test_a_clip_on_top_is_flat_where_it_cuts():
    d, _ = pinned("clip-searched-on-top-of-the-named-cause")
    clip = next(c for c in d.also if c.cause == "saturation")
    assert abs(clip.estimates["slope_where_clipped"]) < d.policy.max_clipped_slope


@same_worker("level-that-cuts-nothing-is-no-clip-on-top")
def test_a_clip_level_on_top_that_cuts_nothing_is_outside_its_meaning():
    d, _ = pinned("level-that-cuts-nothing-is-no-clip-on-top")
    tried = [c for c in d.secondary_tried if c.cause == "saturation"]
    assert tried and all(c.limit for c in tried)


@same_worker("gain-modulation-is-no-clip")
def test_a_clip_candidate_where_the_output_still_rises_with_the_model_is_outside_its_meaning():
    """Where a fitted clip cuts, an output that still rises with the model is no clip."""
    d, _ = pinned("gain-modulation-is-no-clip")
    clip = next(c for c in d.candidates if c.cause == "saturation")
    assert clip.estimates["slope_where_clipped"] > d.policy.max_clipped_slope and clip.limit


@same_worker("clip-against-the-model-is-none")
def test_a_clip_candidate_where_the_output_moves_against_the_model_is_outside_its_meaning():
    d, _ = pinned("clip-against-the-model-is-none")
    clip = next(c for c in d.candidates if c.cause == "saturation")
    assert clip.estimates["slope_where_clipped"] < -d.policy.max_clipped_slope and clip.limit


@same_worker("clip-predicted-from-records-that-show-it")
def test_a_fold_whose_records_show_no_clip_leaves_the_level_open():
    d, truth = pinned("clip-predicted-from-records-that-show-it")
    folds = d.chosen.uncertainty["saturation_level"]["folds"]
    assert max(folds) - min(folds) > 0.05 * truth["p2p"]  # one fold's records did not pin the level


@same_worker("sub-sample-delay-on-white-noise-is-none")
def test_a_delay_shorter_than_one_sample_on_a_null_is_outside_its_meaning():
    d, _ = pinned("sub-sample-delay-on-white-noise-is-none")
    delay = next(c for c in d.candidates if c.cause == "delay")
    assert delay.estimates["delay_s"] < 2e-3 and delay.limit


@same_worker("partial-mode-completed-by-creep")
def test_a_partial_cause_completed_on_top_is_timed():
    d, _ = pinned("partial-mode-completed-by-creep")
    parts = {k: v for k, v in d.timings.items() if k != "total"}
    assert abs(sum(parts.values()) - d.timings["total"]) <= 0.05 * d.timings["total"], d.timings


@same_worker("creep-on-the-physics-is-ambiguous-with-its-slow-relaxation")
def test_creep_ambiguous_with_a_slow_relaxation_is_scored_and_separated_by_a_suggested_experiment():
    d, _ = pinned("creep-on-the-physics-is-ambiguous-with-its-slow-relaxation")
    assert max(d.chosen.estimates["tau_s"]) > d.screen.creep_min / d.policy.creep_periods
    twin = next(c for c in d.verdict.ambiguous_with if c.cause == "creep")
    assert len(twin.estimates) == 2 and twin.heldout["refit_per_fold"]
    assert ["relaxation", "creep"] in [e["causes"] for e in d.experiments]
    evidence = d.to_json()["evidence"]["slow_part_as_creep"]
    assert evidence["ambiguous"] and evidence["cause"] == "creep"


@same_worker("mode-kept-as-a-delay-on-the-physics")
def test_a_cause_kept_on_top_lists_those_as_good_with_their_fits_and_the_drive_that_separates_them():
    d, truth = pinned("mode-kept-as-a-delay-on-the-physics")
    delay = next(c for c in d.also if c.cause == "delay")
    alike = d.as_good_as(delay)
    assert [a.cause for a in alike] == ["resonance"] and alike[0].heldout_gain > delay.heldout_gain
    assert parameter_errors(truth, "resonance", alike[0].estimates)["natural_frequency_hz"] < 0.25
    e = next(e for e in d.experiments if e["causes"] == ["delay", "resonance"])
    assert e["on_top_of"] == "relaxation" and e["frequency_hz"] > 1.0 and e["separation"] > 10 * e["noise_sd"]
    out = d.to_json()
    assert out["also_as_good"] == {"delay": ["resonance"]}
    assert out["also_as_good_fits"]["delay"][0]["estimates"]["natural_frequency_hz"] == alike[0].estimates[
        "natural_frequency_hz"]


@same_worker("delay-on-the-piezo-beside-an-unidentified-rival")
def test_one_drive_is_a_caution_on_a_delay():
    d, _ = pinned("delay-on-the-piezo-beside-an-unidentified-rival")
    # three records of one 1 Hz sine: a delay there only reshapes the response, as a dead band could
    assert d.one_drive_caution.startswith("every record (3) has the same drive, 1 Hz over the same input range")
    assert "caution: " + d.one_drive_caution in verdict_lines(d)
    assert d.to_json()["one_drive_caution"] == d.one_drive_caution


@same_worker("line-within-a-broadband-drives-reach")
def test_records_without_a_nominal_frequency_scale_the_causes_by_their_drive_band():
    """Multisines of 0.1-2 Hz tones (no ``frequency_hz``): the causes' time scale is the band's shortest period,
    not the record's duration (so a 38 Hz line is within reach); creep's floor stays the records' duration; a
    mode or a line is searched up to the samples' Nyquist frequency."""
    d, _ = pinned("line-within-a-broadband-drives-reach")
    assert all(r.frequency_hz is None for r in d.dataset.records)
    assert 0.3 < d.screen.drive_time < 0.6 and d.screen.creep_min == pytest.approx(15.0)
    for cause, name in (("resonance", "natural_frequency"), ("interference", "interference_frequency")):
        assert d.screen.bounds_of(d.screen.extension((cause,)), name)[1] == pytest.approx(
            0.5 / d.dataset.records[0].dt)


@same_worker("line-on-top-of-the-physics-relaxation")
def test_an_interference_on_top_of_a_kept_cause_is_chosen_without_the_left_out_record():
    """The frequency and amplitude of an interference tried on top of a kept cause come, in each fold, from
    what is kept fitted on the other records alone (``train_residuals``): a strong 41 Hz line added to
    record 0 alone leaves fold 0's inputs, and so its frequency, exactly as they were, while the kept cause's
    out-of-fold residuals on records 1 and 2 (fits that included record 0's rows) change."""
    d, _ = pinned("line-on-top-of-the-physics-relaxation")
    s, folds, c = d.screen, Folds.of(d.screen), d.chosen
    assert c.cause == "relaxation" and c.heldout["refit_per_fold"]
    loud = copy.copy(s)
    rows = folds.test(0)
    part = s.parts[0]
    loud.y = s.y.copy()
    loud.y[rows] += 0.3 * np.sin(2 * np.pi * 41.0 * part.rows * part.record.dt)
    quiet_train, loud_train = [], []
    quiet_e, _ = heldout_errors(s, folds, c, refit=True, train_residuals=quiet_train)
    loud_e, _ = heldout_errors(loud, folds, c, refit=True, train_residuals=loud_train)
    assert np.allclose(quiet_train[0], loud_train[0], rtol=0, atol=1e-9 * np.abs(quiet_train[0]).max())
    assert not np.allclose(quiet_train[1], loud_train[1])
    assert not np.allclose(quiet_e[~rows], loud_e[~rows])  # the out-of-fold residuals of records 1, 2 do change
    assert fold_frequencies(s, quiet_train)[0] == fold_frequencies(loud, loud_train)[0]
    assert np.allclose(on_top(s, folds, quiet_e, quiet_train, 13.7)[rows],
                       on_top(loud, folds, quiet_e, loud_train, 13.7)[rows])


@same_worker("weak-line-found-on-top-of-what-is-kept")
def test_secondary_causes_are_selected_forward_on_top_of_what_is_kept():
    """A weak interference on the virtual DEA removes under 1 % of the held-out misfit left by its relaxation
    alone, but more than that on top of relaxation + the physics' lag: it is found only if each secondary cause
    is tested on top of the ones already kept, and scored against them (relaxation + delay with their
    parameters as fitted on every record, the delay's held on both sides). The delay is judged with its own
    value refitted on each fold's other records, the time constants held."""
    d, _ = pinned("weak-line-found-on-top-of-what-is-kept")
    causes = [c.cause for c in d.also]
    assert causes[0] == "delay"
    inter = d.also[causes.index("interference")]
    held = heldout_errors(d.screen, Folds.of(d.screen), d.also[0])[0]  # relaxation + delay, as fitted on every record
    reference = inter.heldout["sse"] / (1.0 - inter.heldout["gain"])
    assert reference == pytest.approx(float(held @ held), rel=1e-9)  # scored against relaxation + delay
    folds, delay = Folds.of(d.screen), d.also[0]
    assert delay.heldout["refit_per_fold"] and set(delay.uncertainty) == {"delay"}
    e, fold_est = heldout_errors(d.screen, folds, delay, refit=True, only=["delay"])
    assert [f["delay"] for f in fold_est] == delay.uncertainty["delay"]["folds"]
    relaxation = heldout_errors(d.screen, folds, d.chosen)[0]
    assert score(folds, relaxation, e)["gain"] == pytest.approx(delay.heldout["gain"], rel=1e-9)
    # fold 0's delay does not see record 0: another output there leaves it as it was
    other = copy.copy(d.screen)
    other.y = d.screen.y.copy()
    other.y[folds.test(0)] += 0.5 * np.sin(np.arange(int(folds.test(0).sum())) * 0.01)
    moved = heldout_errors(other, folds, delay, refit=True, only=["delay"])[1]
    assert moved[0]["delay"] == pytest.approx(fold_est[0]["delay"], rel=1e-9)
    assert moved[1]["delay"] != pytest.approx(fold_est[1]["delay"], rel=1e-6)


@same_worker("mode-on-the-piezo-with-a-line-tried-on-top")
def test_an_interference_on_top_reports_and_checks_the_frequencies_it_was_scored_at():
    """The interference tried on top of a named mode (the piezo recording's two 2-s records of the 1 Hz drive) is
    scored at the frequency each fold chose, not at the one fitted on every record against the base alone: its
    estimates are the folds', and its meaning (cycles, drive lock, one line) is checked there. Which spectral
    peak a fold picks can be a near tie, so the test checks the invariants, not the peak."""
    d, _ = pinned("mode-on-the-piezo-with-a-line-tried-on-top")
    tried = next(c for c in d.secondary_tried if c.cause == "interference")
    whole = next(c for c in d.candidates if c.cause == "interference")
    folds_f = tried.heldout["fold_frequencies_hz"]
    assert len(folds_f) == 2 and tried.estimates["frequency_hz"] == pytest.approx(np.mean(folds_f))
    assert abs(tried.estimates["frequency_hz"] - whole.estimates["frequency_hz"]) > 0.1
    meaning = d.screen.limit_of("interference", tried.estimates)
    if meaning or frequencies_agree(d.screen, folds_f):
        assert tried.limit == meaning
    else:  # folds that chose lines apart found no one line
        assert tried.limit and not frequencies_agree(d.screen, folds_f)
    assert meaning != d.screen.limit_of("interference", {**tried.estimates, "frequency_hz": 0.4})  # < 2 cycles
    if tried.limit:
        assert "interference" not in [c.cause for c in d.also]


def test_the_delay_search_on_short_records_reaches_a_delay_between_its_grid_points():
    """On short records the delay is profiled on a geometric grid (about 50 % steps), then refined by Brent
    between the best point's neighbours: a planted 43 ms delay (grid points 36 and 50 ms here) on the exact
    plant is found within 5 %."""
    from hysbench.benchmarks.diagnosis.causes.delay import fit_delay

    ds, _ = planted(("delay",), "mrpim", "sines", 2, {"delay": {"delay_s": 0.043}})
    screen = build_screen(own_samples(ds), get_model("mrpim"))[-1]
    assert screen.small
    c = fit_delay(screen)
    assert abs(c.estimates["delay_s"] / 0.043 - 1) < 0.05, c.estimates


# --- the policy ----------------------------------------------------------------------------------
def test_the_policy_is_frozen_checked_and_overridden_by_key():
    p = Policy()
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.z_pass = 2.0
    assert p.z_confirm == pytest.approx(stats.norm.isf(0.05)) and p.changed() == {}
    q = p.with_overrides(["z_pass=2.5", "max-secondary=2"])
    assert (q.z_pass, q.max_secondary, q.changed()) == (2.5, 2, {"z_pass": 2.5, "max_secondary": 2})
    assert Policy(z_pass=2.5) == p.with_overrides(["z_pass=2.5"]) and "z_pass = 2.5" in q.summary()
    for bad in (["z_pass"], ["nope=1"], ["version=2"], ["n_blocks=0"], ["same_slice=0"], ["confirm_p=x"]):
        with pytest.raises(PolicyError):
            p.with_overrides(bad)
    assert set(p.as_dict()) == {f.name for f in dataclasses.fields(Policy)} | {"z_confirm"}


def test_every_policy_field_is_in_the_documented_table_with_its_value():
    """docs/diagnosis.md lists every field of ``Policy`` with the value ``Policy()`` holds."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "diagnosis.md").read_text()
    rows = dict(re.findall(r"^\| `(\w+)` \| ([^|]+) \|", text, flags=re.M))
    for name, value, doc in Policy.described():
        assert name in rows, name
        shown = rows[name].strip()
        assert shown.startswith(f"{value:g}") or f"({value:.3f})" in shown, (name, value, shown)
        assert doc.split(" (")[0][:30] in text or doc[:30] in text, name


@same_worker("level-that-cuts-nothing-is-no-clip-on-top")
def test_a_different_policy_gives_the_verdict_its_thresholds_decide():
    """The policy is passed down: with ``z_pass`` above every candidate's block z and ``strong_gain`` above every
    gain nothing is evidence, and a planted creep the default rule names gives no cause."""
    d, _ = pinned("level-that-cuts-nothing-is-no-clip-on-top")
    top = max(c.heldout.get("z", 0.0) for c in d.candidates)
    strict = Policy(z_pass=top + 1.0, strong_gain=1.0)
    again = diagnose(d.dataset, seed=0, experiments=False, extend=False, policy=strict)
    assert again.policy is strict and again.screen.policy is strict
    assert d.cause == "creep" and again.cause in ("none", "unexplained")
    assert not any(passes(c, strict) for c in again.candidates)


# --- the command line ----------------------------------------------------------------------
def _hysbench(capsys, *args):
    """`hysbench ARGS` run in this process (the console script has its own tests in test_bad_inputs):
    its exit status, stdout and stderr."""
    capsys.readouterr()
    code = hysbench_main(list(args))
    out = capsys.readouterr()
    return SimpleNamespace(returncode=code, stdout=out.out, stderr=out.err)


def _json_fields_documented() -> set[str]:
    """The field names (in backticks) of docs/diagnosis.md's section on diagnosis.json."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "diagnosis.md").read_text()
    section = text.split("## diagnosis.json, field by field", 1)[1].split("\n## ", 1)[0]
    return set(re.findall(r"`([a-z_0-9]+)`", section))


def test_cli_writes_report_and_json(tmp_path, capsys, monkeypatch):
    drawn, savefig = [], matplotlib.figure.Figure.savefig

    def save_and_keep(fig, *args, **kwargs):
        drawn.append(fig)
        return savefig(fig, *args, **kwargs)

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", save_and_keep)
    ds, truth = _draw_above(("interference",), LIMITS["interference"], start=5)
    save_dataset(ds, tmp_path / "ds")
    out = tmp_path / "out"
    res = _hysbench(capsys, "diagnose", str(tmp_path / "ds"), "--out", str(out), "--json", str(tmp_path / "d.json"), "--quiet",
                    "--policy", "max_secondary=3")
    assert res.returncode == 0, res.stderr
    assert "cause: interference" in res.stdout

    def refuse(constant):  # JSON has no NaN or infinity; strict parsers (jq, JavaScript) refuse them
        raise AssertionError(f"diagnosis.json holds {constant}")

    data = json.loads((tmp_path / "d.json").read_text(), parse_constant=refuse)
    for key in ("model", "cause", "reason", "parameters", "uncertainty", "evidence", "extended_model", "before",
                "after", "also", "ambiguous_with", "not_identified"):
        assert key in data
    assert data["cause"] == "interference" and data["interference_check"]["same_amplitude"]
    # the policy used, every field in the JSON, what differs from the default in the report; the trace
    assert data["policy"] == {**Policy(max_secondary=3).as_dict()} and data["policy"]["max_secondary"] == 3
    assert [t["rule"] for t in data["trace"]][0] in ("simplest-as-good", "nothing-passes")
    assert data["trace"][-1]["rule"] == "validation"
    assert data["trace"][-1]["outcome"] == ("confirmed" if data["confirmed_on_validation"] else "not confirmed")
    assert set(data["before"]) == {r.file for r in ds.records} == set(data["after"])
    documented = _json_fields_documented()
    summaries = [data["evidence"]["null"], *data["evidence"]["candidates"], *data["evidence"]["secondary_tried"]]
    fields = {*data, *data["evidence"], *(k for c in summaries for k in c), *(k for c in summaries for k in c["heldout"])}
    assert fields <= documented, f"diagnosis.json fields not in docs/diagnosis.md: {sorted(fields - documented)}"
    md = (out / "diagnosis.md").read_text()
    assert "Policy v1, changed from the default rule: max_secondary = 3" in md and "## Why" in md
    for png in ("residual_time", "residual_input", "residual_phase", "residual_spectrum", "error_vs_frequency",
                "whiteness", "candidates"):
        assert (out / f"diagnosis_{png}.png").stat().st_size > 1000
        assert f"diagnosis_{png}.png" in md
    assert len(drawn) == 7 and [unreadable(fig) for fig in drawn] == [[]] * 7  # each figure reads on its own


@pytest.mark.parametrize("args,needle", [
    (["diagnose", "/nonexistent/dataset"], "no such dataset"),
    (["diagnose", ".", "--model", "no-such-model"], "unknown model"),
    (["diagnose", ".", "--max-rows", "0"], "integer >= 1"),
    (["diagnose", ".", "--segments", "1"], "integer >= 2"),
    (["diagnose", ".", "--policy", "z_pas=2.5"], "unknown policy field 'z_pas'"),
    (["diagnose", ".", "--policy", "z_pass=high"], "z_pass takes a number"),
    (["diagnose", ".", "--policy", "explain_share=1.5"], "explain_share = 1.5: needs a number in (0, 1]"),
    (["diagnose", ".", "--policy", "n_blocks=2.5"], "n_blocks takes an integer"),
])
def test_cli_refuses_bad_input_in_one_line(args, needle, capsys):
    """Bad input, a bad policy field or value included, is one line and exit status 2, before any work."""
    res = _hysbench(capsys, *args)
    assert res.returncode == 2
    assert needle in res.stderr and len(res.stderr.strip().splitlines()) == 1 and "Traceback" not in res.stderr


def test_measured_pzt_data_with_different_sample_times(shared_datasets, tmp_path, capsys):
    """Real measured data (read in place): three records at 0.0025, 0.025 and 0.25 s, two of them identification.
    The verdict is one of the vocabulary, none or unexplained; a named extension never saw the validation record."""
    folder = pzt_dataset(shared_datasets, tmp_path / "pzt")
    res = _hysbench(capsys, "diagnose", str(folder), "--out", str(tmp_path / "out"), "--json", str(tmp_path / "d.json"),
                    "--quiet")
    assert res.returncode == 0, res.stderr
    data = json.loads((tmp_path / "d.json").read_text())
    assert data["cause"] in ("none", "unexplained", *CAUSES)
    if data["extended_fit"]:
        assert "tri_T01_TEST_0.1Hz_1400V_0.1Hz.csv" not in " ".join(data["extended_fit"]["fitted_on"])
    assert (data["confirmed_on_validation"] is False) == ("warning:" in res.stdout)


def test_one_recording_is_diagnosed_in_segments_without_its_validation_window(shared_datasets, tmp_path, capsys):
    """The real piezo recording: one file, an identification window (three periods) and a validation window.
    Without --segments: refused in one line that names the option. With it, the identification window is cut
    at input minima into records of whole periods (two remain after its first minimum), no record the
    diagnosis fits on holds a validation sample, and the cuts cost the base model next to nothing (a cut at
    the window's own start, mid-sweep, would triple its error: 0.41-0.51 % against 0.14 %)."""
    folder = shared_datasets / "piezo_sindy_1hz"
    res = _hysbench(capsys, "diagnose", str(folder), "--out", str(tmp_path / "none"), "--quiet")
    assert res.returncode == 2 and "--segments" in res.stderr and len(res.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "none").exists()
    res = _hysbench(capsys, "diagnose", str(folder), "--segments", "3", "--out", str(tmp_path / "none"), "--quiet")
    assert res.returncode == 2 and "2 whole period(s)" in res.stderr and not (tmp_path / "none").exists()
    res = _hysbench(capsys, "diagnose", str(folder), "--segments", "2", "--out", str(tmp_path / "out"),
                    "--json", str(tmp_path / "d.json"), "--quiet")
    assert res.returncode == 0, res.stderr
    data = json.loads((tmp_path / "d.json").read_text())
    assert data["settings"]["segments"] == 2
    ident = [f"hysteresis_v_150_1hz#1~{k}.csv" for k in (1, 2)]
    assert set(data["before"]) == {*ident, "hysteresis_v_150_1hz#2.csv"}
    if data["extended_fit"]:
        assert sorted(data["extended_fit"]["fitted_on"]) == ident
    scores = data["before"]["hysteresis_v_150_1hz#2.csv"]
    assert scores["e_rms_whole"] == scores["e_rms"]  # the validation record is its window: nothing else scored
    assert max(s["e_rms"] for s in data["before"].values()) < 0.25  # % of p2p; the benchmark's fit: 0.144 %
    assert data["evidence"]["periodic_structure"]["records"] == ident  # one-period segments taken together
    reshaping = {data["cause"], *data["also"]} & {"relaxation", "delay", "resonance"}
    assert bool(data["one_drive_caution"]) == bool(reshaping)  # one recording at one drive: said if one is named


@pytest.mark.parametrize("cause", list(STRONG))
def test_planted_effect_without_a_reachable_limit_is_named_or_ambiguous(cause):
    """A cause whose detection limit is not reached on these drives (another cause mimics it): strongly planted,
    it is named or listed as ambiguous with the named one, with a suggested experiment."""
    ds, truth = _draw_above((cause,), STRONG[cause], start=STRONG_START[cause])
    d = diagnose(ds, seed=0)
    ambiguous = [c.cause for c in d.verdict.ambiguous_with]
    assert d.cause == cause or cause in ambiguous, (d.cause, ambiguous, truth)
    if cause in ambiguous:
        assert any(cause in e["causes"] and e["drive"] for e in d.experiments)


def test_the_accuracy_report_counts_virtual_dea_verdicts_that_the_nulls_give_too():
    """A planted relaxation or delay on the virtual DEA is judged right when its own relaxation is named
    (the delay under "also"): what its nulls give. The report counts such cases and how many of them
    recovered the planted time constant or delay (the one under "also" within 25 %), so the headline cannot
    hide verdicts that show no detection."""
    from hysbench.benchmarks.diagnosis_accuracy.accuracy import judge, markdown, summary

    def row(kinds, base, verdict, also=(), within=False, also_error=None):
        truth = {"kinds": list(kinds), "base": base}
        return {"kinds": list(kinds), "base": base, "drive": "sines", "seed": 7, "strength_pct": 1.0,
                "effects": {}, "verdict": verdict, "confirmed": True, "also": list(also), "ambiguous_with": [],
                "remainder": None, "parameters": {}, "parameter_errors": {"tau_s": 0.1 if within else 0.9},
                "parameters_within": within, "right": judge(truth, verdict, list(also)), "seconds": 1.0,
                "also_parameter_errors": {} if also_error is None else {"delay": {"delay_s": also_error}}}

    rows = [row(["relaxation"], "virtual-dea", "relaxation", ["delay"]),  # the nulls' verdict, tau missed
            row(["relaxation"], "virtual-dea", "relaxation", [], within=True),  # the nulls' verdict, tau found
            row(["delay"], "virtual-dea", "relaxation", ["delay"], also_error=1.0),  # the nulls' lag, not the delay
            row(["delay"], "virtual-dea", "relaxation", ["delay"], also_error=0.1),  # the planted delay found
            row(["delay"], "virtual-dea", "delay"),  # the planted cause named: evidence
            row(["resonance"], "virtual-dea", "relaxation", ["delay"]),  # wrong, not counted
            row(["relaxation"], "mrpim", "relaxation")]  # another base
    assert [r["right"] for r in rows] == [True, True, True, True, True, False, True]
    s = summary(rows)
    assert (s["vdea_null_verdicts"], s["vdea_null_verdicts_recovered"]) == (4, 2)
    assert "| 4 / 2 |" in markdown(rows, s, 1.0)


def test_planted_signals_are_what_each_effect_added():
    """``truth["signals"]``: per effect and record, what the effect added before the noise. Here a creep,
    its logarithmic law written out again; what is left of the output is the plant plus white noise of the
    stated sd."""
    from hysbench.benchmarks.diagnosis_accuracy.planted import DT as PLANT_DT
    ds, truth = planted_case(("creep",), "mrpim", "sines", 5)
    e = truth["effects"]["creep"]
    model = get_model("mrpim")
    for r in ds.records:
        s = truth["signals"]["creep"][r.file]
        law = e["drift"] * np.log1p(r.t / e["t_c_s"]) / math.log1p(truth["longest_s"] / e["t_c_s"])
        np.testing.assert_allclose(s, law, rtol=1e-12, atol=1e-15)
        plant = model.simulate(r.u, PLANT_DT, model.preset("paper"), input_range=(0.5, 2.5))
        left = r.y - s - plant
        assert abs(np.std(left) / truth["noise_sd"] - 1) < 0.1 and abs(np.mean(left)) < 0.1 * truth["noise_sd"]


@pytest.mark.parametrize("weight,shown", [(0.3, True), (3e-5, False)])
def test_the_evidence_ceiling_sees_a_planted_effect_only_when_it_is_there(weight, shown):
    """The planted effect's own waveform as a regressor passes the diagnosis's held-out test when the
    effect is strong (1 s relaxation, 0.3 mm/kV) and not when it is 10^4 times weaker (below the noise)."""
    from hysbench.benchmarks.diagnosis_accuracy.evidence_ceiling import effect_evidence, extension_could_show, shows_evidence
    ds, truth = planted_case(("relaxation",), "mrpim", "sines", 3,
                             effects={"relaxation": {"tau_s": 1.0, "weight": weight}})
    d = diagnose(ds, seed=0, experiments=False, extend=False)
    ev = effect_evidence(d, truth)
    assert set(ev) == {"relaxation"} and "base" in ev["relaxation"]
    assert shows_evidence(ev) is shown, ev
    # the vocabulary's own extension at the planted time constant: the same answer
    assert ev["relaxation"]["extension_at_truth_on_base"]["evidence"] is shown
    assert extension_could_show(ev) is shown
    assert (d.cause == "relaxation") is shown


def test_the_delay_profile_is_scanned_where_it_is_rough_at_the_scale_of_a_sample():
    """A profile with a ripple of one sample's period on a wide valley: a bounded Brent on the bracket stops in a
    ripple minimum away from the valley's floor; the scan (every half sample) then Brent reaches the floor."""
    from scipy.optimize import minimize_scalar

    from hysbench.benchmarks.diagnosis.causes.delay import scan_minimum
    dt, floor = 2e-3, 0.0044

    def rss(d):  # minima at floor + k dt; envelope rising away from the floor
        return ((d - floor) / 0.004) ** 2 + 0.5 * (1 - math.cos(2 * math.pi * (d - floor) / dt))

    plain = minimize_scalar(rss, bounds=(0.0038, 0.00725), method="bounded").x
    assert abs(plain - floor) > dt / 2  # Brent alone stops in a ripple minimum
    assert abs(scan_minimum(rss, 0.0038, 0.00725, dt) - floor) < dt / 20


def test_the_accuracy_report_states_the_ceiling_that_the_planted_effects_allow():
    """Vocabulary cases whose planted effect shows no held-out evidence by itself bound the verdict share:
    every other case right, and of those only the ones already right."""
    from hysbench.benchmarks.diagnosis_accuracy.accuracy import ceiling, markdown, summary

    def row(kinds, right, shown):
        return {"kinds": list(kinds), "base": "mrpim", "drive": "sines", "seed": 7, "strength_pct": 1.0,
                "effects": {}, "verdict": "none", "confirmed": False, "also": [], "ambiguous_with": [],
                "remainder": None, "parameters": {}, "parameter_errors": {}, "parameters_within": False,
                "right": right, "seconds": 1.0, "effect_evidence": {}, "effect_shows_evidence": shown}

    rows = [row(["delay"], True, True), row(["delay"], False, True), row(["creep"], False, False),
            row(["creep"], True, False), row(["null-white"], True, False), row(["dead-zone"], False, True)]
    e = ceiling(rows)["evidence"]
    counts = (e["vocabulary_cases"], e["with_evidence"], e["with_evidence_right"], e["without_evidence_right"])
    assert counts == (4, 2, 1, 1)
    assert e["ceiling_right"] == 2 + 2 + 1  # nulls and out-of-vocabulary, with evidence, right without
    assert "**5 / 6 = 83.3 %**" in markdown(rows, summary(rows), 1.0)
    assert ceiling([{k: v for k, v in r.items() if k != "effect_shows_evidence"} for r in rows]) == {}
    for r, reach in zip(rows, [True, False, False, False, False, False]):  # the extension reaches only the first
        r["extension_could_show"] = reach
    e = ceiling(rows)["evidence"]
    assert (e["extension_cases"], e["extension_cases_right"], e["extension_ceiling_right"]) == (1, 1, 2 + 1 + 1)
    assert "kept_ceiling_right" not in e  # rows from before the third reading
    for r, reach in zip(rows, [False, True, False, False, False, False]):
        r["shows_on_kept"] = reach
    e = ceiling(rows)["evidence"]
    assert (e["kept_cases"], e["kept_cases_right"], e["kept_ceiling_right"]) == (1, 0, 2 + 1 + 2)
    assert "ceiling **5 / 6 = 83.3 %**" in markdown(rows, summary(rows), 1.0)
    # the strictest, from each row's evidence: the second case's delay by its extension on the base and kept
    on, off = ({"gain": g, "z": z, "folds_improved": 3, "n_folds": 3, "evidence": g > 0} for g, z in ((0.2, 3.5), (-0.1, 0.0)))
    rows[1]["effect_evidence"] = {"delay": {"base": on, "extension_at_truth_on_base": on, "kept": off,
                                            "extension_at_truth_on_kept": on}}
    e = ceiling(rows)["evidence"]
    assert (e["strict_cases"], e["strict_cases_right"], e["strict_ceiling_right"]) == (1, 0, 2 + 1 + 2)
    assert "ceiling **5 / 6 = 83.3 %**." in markdown(rows, summary(rows), 1.0).split("The strictest")[1]


def test_the_third_ceiling_reading_is_on_top_of_everything_kept_unless_a_planted_cause_is_in_it():
    """``kept_composite``: the last kept candidate when the diagnosis kept more than the named cause, none
    of it planted and all of it one design; ``shows_on_kept``: evidence against the base or the named cause,
    and where everything kept is a reference, against it too."""
    from types import SimpleNamespace as NS

    from hysbench.benchmarks.diagnosis_accuracy.evidence_ceiling import kept_composite, shows_on_kept

    def cand(*parts):
        return NS(cause=parts[-1], model=NS(components=parts))

    relax, relax_delay = cand("relaxation"), cand("relaxation", "delay")
    diag = NS(chosen=relax, also=[relax_delay])
    assert kept_composite(diag, ["resonance"]) is relax_delay
    assert kept_composite(diag, ["delay"]) is None  # a planted cause kept: nothing to add on top
    assert kept_composite(NS(chosen=relax, also=[]), ["resonance"]) is None  # the named cause alone
    assert kept_composite(NS(chosen=relax, also=[relax_delay, cand("interference")]), ["creep"]) is None
    assert kept_composite(NS(chosen=None, also=[]), ["creep"]) is None

    yes, no = {"evidence": True}, {"evidence": False}
    assert shows_on_kept({"resonance": {"base": no, "named": yes}})  # no kept reference: as before
    assert not shows_on_kept({"resonance": {"base": no, "named": yes, "kept": no, "extension_at_truth_on_kept": no}})
    assert shows_on_kept({"resonance": {"base": no, "named": yes, "kept": no, "extension_at_truth_on_kept": yes}})
    assert not shows_on_kept({"resonance": {"base": no, "named": no, "kept": yes}})  # needs the first reading too


def test_the_strictest_ceiling_reading_asks_the_extension_on_the_base_or_named_and_on_everything_kept():
    """``extension_could_show``: a mode by its extension at the planted values on the base or the named cause
    (not on what was kept), an effect without such an extension by its waveform; ``extension_on_kept``: that,
    and on top of everything kept by the same rule, per effect."""
    from hysbench.benchmarks.diagnosis_accuracy.evidence_ceiling import extension_could_show, extension_on_kept

    yes, no = {"evidence": True}, {"evidence": False}
    mode = {"base": yes, "extension_at_truth_on_base": no, "named": no, "extension_at_truth_on_named": yes}
    assert extension_could_show({"resonance": mode}) and extension_on_kept({"resonance": mode})  # nothing kept
    assert not extension_could_show({"resonance": {**mode, "extension_at_truth_on_named": no,
                                                   "extension_at_truth_on_kept": yes}})  # kept alone: not this reading
    kept_waveform_only = {**mode, "kept": yes, "extension_at_truth_on_kept": no}
    assert extension_could_show({"resonance": kept_waveform_only})
    assert not extension_on_kept({"resonance": kept_waveform_only})  # its extension does not show on what was kept
    assert extension_on_kept({"resonance": {**mode, "kept": no, "extension_at_truth_on_kept": yes}})
    creep = {"base": yes, "kept": no}  # no extension at planted values: the waveform, on base and on kept
    assert extension_could_show({"creep": creep}) and not extension_on_kept({"creep": creep})
    # per effect: one effect on the base, another on what was kept, is neither on both
    assert not extension_on_kept({"creep": creep, "relaxation": {"base": no, "extension_at_truth_on_base": no,
                                                                 "kept": yes, "extension_at_truth_on_kept": yes}})






@given(st.integers(0, 10_000), st.sampled_from(["upper", "lower"]), st.floats(-1.0, 2.0))
def test_slope_where_clipped_is_the_least_squares_slope_on_the_cut_samples(seed, side, true_slope):
    rng = np.random.default_rng(seed)
    pred = rng.normal(0.0, 1.0, 300)
    level = 0.5 if side == "upper" else -0.5
    cut = pred > level if side == "upper" else pred < level
    y = np.where(cut, level + true_slope * (pred - level), pred) + rng.normal(0.0, 0.01, pred.size)
    reference = np.polyfit(pred[cut], y[cut], 1)[0]  # the obvious way
    assert slope_where_clipped(pred, y, side, level, POLICY.min_clipped_samples) == pytest.approx(reference, rel=1e-9, abs=1e-12)
    assert abs(reference - true_slope) < 0.05
    assert math.isnan(slope_where_clipped(pred, y, side, 10.0 if side == "upper" else -10.0, POLICY.min_clipped_samples))  # never cut


def test_shows_clip_only_where_the_output_is_flat_at_the_level():
    """A line y = a + b t, clipped at a level: the rows show the clip at that level; unclipped rows do not show
    one at a level below their peak (the output still rises with the model there), nor at a level above it."""
    screen = SimpleNamespace(noise_sd=0.01, n_evaluations=0, solve=Screen.solve, policy=POLICY)
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 1.0, 400)
    A = np.column_stack([np.ones_like(t), np.sin(2 * np.pi * t)])
    clean = 0.2 + np.sin(2 * np.pi * t)
    y_clipped = np.minimum(clean, 0.8) + rng.normal(0.0, 0.01, t.size)
    y_free = clean + rng.normal(0.0, 0.01, t.size)
    assert shows_clip(screen, A, y_clipped, "upper", 0.8)
    assert not shows_clip(screen, A, y_free, "upper", 0.8)  # passes the level, but rises with the model
    assert not shows_clip(screen, A, y_free, "upper", 2.0)  # never reaches it
    assert shows_clip(screen, A, -y_clipped, "lower", -0.8)
    y_against = np.where(clean > 0.8, 0.8 - 1.5 * (clean - 0.8), clean) + rng.normal(0.0, 0.01, t.size)
    assert not shows_clip(screen, A, y_against, "upper", 0.8)  # moves against the model: not flat either


def test_a_clip_must_be_flat_either_way():
    """Where a fitted clip cuts, an output that moves against the model is no clip, as one that still rises
    with it is not; a flat top is (planted: ``clip-against-the-model-is-none``, ``gain-modulation-is-no-clip``)."""
    for slope, ok in ((-1.84, False), (-0.6, False), (0.03, True), (-0.3, True), (0.81, False)):
        limit = Screen.limit_of(SimpleNamespace(policy=POLICY), "saturation", {"slope_where_clipped": slope})
        assert (limit == "") == ok, (slope, limit)


def test_a_held_out_gain_carried_by_one_record_alone_is_not_evidence():
    """Evidence that only the record it improves most carries (coloured noise can throw the base's extrapolation
    to one record far off) is not enough for `unexplained`; a gain spread over the records is; with two records
    nothing is left to check."""
    from hysbench.benchmarks.diagnosis.heldout import Folds, carried_by_one_record

    rng = np.random.default_rng(3)
    folds = Folds(np.array([0, 4000, 6000, 7000]))
    e_null = rng.normal(size=7000)
    one = e_null.copy()
    one[6000:] *= 0.3  # the third record predicted much better, the others as the base
    one[:6000] += 0.01 * rng.normal(size=6000)
    spread = 0.8 * e_null  # every record 36 % better
    assert carried_by_one_record(folds, e_null, one)
    assert not carried_by_one_record(folds, e_null, spread)
    two = Folds(np.array([0, 4000, 7000]))
    assert not carried_by_one_record(two, e_null, one)


def test_a_delay_shorter_than_one_sample_is_not_a_delay():
    """An input late by less than a sample is the input plus a first difference of it (a rate term): such a
    delay is outside the cause's meaning. ``Screen.limit_of`` against the coarsest record's sample time."""
    fake = SimpleNamespace(parts=[SimpleNamespace(record=SimpleNamespace(dt=1e-3)),
                                  SimpleNamespace(record=SimpleNamespace(dt=2e-3))], policy=POLICY)
    assert "shorter than one sample (2 ms)" in Screen.limit_of(fake, "delay", {"delay_s": 1.5e-3})
    assert Screen.limit_of(fake, "delay", {"delay_s": 2e-3}) == ""


def test_no_error_against_frequency_figure_is_drawn_for_records_without_a_drive_frequency(tmp_path):
    """Records without a nominal drive frequency (the Bouc-Wen benchmark's) would leave that figure empty: it is
    not drawn; with one it is."""
    from hysbench.benchmarks.diagnosis import figures

    record = SimpleNamespace(frequency_hz=None, role="identification")
    diag = SimpleNamespace(before=[SimpleNamespace(record=record)], base_whole=[], after=[], model="mrpim",
                           extended_model="mrpim+creep")
    path = tmp_path / "error.png"
    figures.figure_error_vs_frequency(diag, path)
    assert not path.exists()
    record.frequency_hz = 1.0
    diag.before[0].scores = lambda: {"e_rms": 2.0, "e_rms_whole": 3.0}
    figures.figure_error_vs_frequency(diag, path)
    assert path.stat().st_size > 0


def test_thorough_tries_every_cause_on_top_also_on_records_taken_as_long(monkeypatch):
    """On long records only the causes that nearly pass against the base alone are tried on top of the named one
    (cost); with ``thorough`` every other cause is, as on short records."""
    monkeypatch.setattr(Screen, "small", property(lambda self: False))  # these short records taken as long
    ds, _ = planted_case(("relaxation",), "mrpim", "sines", 1)
    tried = {}
    for thorough in (False, True):
        said = []
        d = diagnose(ds, experiments=False, thorough=thorough, progress=said.append)
        assert d.cause == "relaxation" and d.settings["thorough"] is thorough
        pools = [line.split(" on top of ")[0].removeprefix("trying ").split(", ") for line in said
                 if line.startswith("trying ")]
        tried[thorough] = set(pools[0]) if pools else set()
    # every cause but the named one (an interference outside its meaning is never tried: no disturbance)
    assert set(CAUSES) - {"relaxation", "interference"} <= tried[True]
    assert tried[False] < tried[True]


@pytest.mark.parametrize("lead_s", [0.0, 0.008])
def test_the_own_lead_is_the_output_delay_at_which_the_base_model_fits_the_records_best(lead_s):
    """A plant whose output leads its model by L: the classical P-I model (rate-independent, so it cannot
    absorb a lead) identified on Table 2 MRPIM data, then driven by the input L ahead (1-2.5 Hz sines, eq. 1's
    form, written here). The base model alone fits best with the output delayed by L, so a planted delay d
    shows beyond it as d - L. Nothing planted here (the delay's signal is zero)."""
    from hysbench.benchmarks.diagnosis.diagnose import build_screen
    from hysbench.benchmarks.diagnosis_accuracy.own_timing import own_lead
    from hysbench.data.dataset import Dataset

    mrpim, base, rng, dt = get_model("mrpim"), get_model("classical-pi"), np.random.default_rng(11), 1e-3
    plan = [(1.0, "identification"), (2.0, "identification"), (1.5, "validation"), (2.5, "identification")]

    def records(plant, lead):
        out = []
        for i, (f, role) in enumerate(plan):
            t = np.arange(int(round(3 / f / dt))) * dt
            y = plant(1.5 - np.cos(2 * np.pi * f * (t + lead)))  # eq. 1's form, 0.5-2.5 kV
            out.append(Record(f"s{i}.csv", t, 1.5 - np.cos(2 * np.pi * f * t), y + rng.normal(0, 0.003, t.size),
                              role=role, frequency_hz=f))
        return Dataset(name="leading-plant", records=out, input_unit="kV", output_unit="mm")

    table2 = records(lambda u: mrpim.simulate(u, dt, mrpim.preset("paper"), input_range=(0.5, 2.5)), 0.0)
    fit = identify(base, table2, method="varpro", seed=0)
    ds = records(lambda u: base.simulate(u, dt, fit.params, input_range=fit.input_range), lead_s)
    screen = build_screen(ds, base)[-1]
    found = own_lead(screen, {"delay": {r.file: np.zeros(r.t.size) for r in ds.identification}})
    assert found == pytest.approx(lead_s, abs=5e-4)
    # every planted effect is taken off: half the output 10 ms earlier, planted on top, leaves the lead where it
    # was (left on, it would lengthen the lead by about 5 ms)
    leading = {r.file: 0.5 * (np.interp(r.t + 0.010, r.t, r.y) - r.y) for r in ds.identification}
    planted = copy.deepcopy(ds)
    for r in planted.identification:
        r.y = r.y + leading[r.file]
    screen = build_screen(planted, base)[-1]
    nothing = {f: 0 * v for f, v in leading.items()}
    assert own_lead(screen, {"delay": nothing, "other": leading}) == pytest.approx(found, abs=2e-4)
    assert own_lead(screen, {"delay": nothing}) - found > 2e-3
    assert own_lead(screen, {"delay": {r.file: np.zeros(3) for r in ds.identification}}) is None  # not these records


def test_a_delay_is_judged_against_the_planted_delay_less_the_base_s_own_lead():
    from hysbench.benchmarks.diagnosis_accuracy.accuracy import with_own_lead
    from hysbench.benchmarks.diagnosis_accuracy.own_timing import needs_lead

    truth = {"kinds": ["delay"], "effects": {"delay": {"delay_s": 0.0214}}}
    assert with_own_lead(truth, None) is truth and with_own_lead(truth, 0.0) is truth
    judged = with_own_lead(truth, 0.0075)
    assert judged["effects"]["delay"]["delay_s"] == pytest.approx(0.0139)
    assert truth["effects"]["delay"]["delay_s"] == 0.0214  # the truth itself untouched
    assert parameter_errors(judged, "delay", {"delay_s": 0.0139})["delay_s"] == pytest.approx(0.0, abs=1e-12)
    assert parameter_errors(truth, "delay", {"delay_s": 0.0139})["delay_s"] == pytest.approx(0.35, abs=0.01)
    row = {"kinds": ["delay"], "base": "piezo", "verdict": "none", "also": []}
    assert not needs_lead(row)
    assert needs_lead({**row, "verdict": "delay"}) and needs_lead({**row, "also": ["delay"]})
    assert not needs_lead({**row, "verdict": "delay", "base": "mrpim"})  # the plant is the base model
