"""The diagnosis: extension blocks against slow references, the decision rule, and planted effects.

Planted tests draw their data from ``hysbench.benchmarks.diagnosis_accuracy.planted``,
whose effects use functional forms and numerical methods of their own (FFT
convolution, a frequency-domain delay, scipy's RK45 mode, a logarithmic
creep, ...), never the extension code that detects them. Each draw is seeded
and kept only if its strength is above the cause's detection limit measured
by the accuracy benchmark (results/diagnosis_accuracy.md), so a failure
here is a regression, not bad luck. Nulls include AR(1) noise (phi 0.99);
out-of-vocabulary effects must not get a vocabulary cause.
"""

from __future__ import annotations

import copy
import json
import math
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal

from hysbench.benchmarks.diagnosis import diagnose
from hysbench.benchmarks.diagnosis_accuracy.accuracy import judge, parameter_errors
from hysbench.benchmarks.diagnosis.experiment import predict, probe_sine, separation, suggest
from hysbench.benchmarks.diagnosis_accuracy.planted import (
    fractional_delay,
    low_pass_convolution,
    mode_ode,
    piezo_available,
    planted_case,
)
from hysbench.benchmarks.diagnosis_accuracy.stated_limits import LIMITS_PCT, stated_limit
from hysbench.benchmarks.diagnosis.report import verdict_lines
from hysbench.benchmarks.diagnosis.saturation import shows_clip, slope_where_clipped
from hysbench.benchmarks.diagnosis.residuals import (
    RecordResidual,
    coherent_spectrum,
    harmonic_phase_turn,
    ljung_box,
    noise_sd,
    periodic_structure,
    spectral_peaks,
)
from hysbench.benchmarks.diagnosis.candidates import DRIVE_LOCKED, MIN_EXPLAINED, NO_CUT, Candidate
from hysbench.benchmarks.diagnosis.screen import Screen
from hysbench.benchmarks.diagnosis.selection import Z_SAME, Folds, decide, heldout_errors, heldout_null, score
from hysbench.benchmarks.diagnosis.interference import (fold_frequencies, frequencies_agree, on_top,
                                                      same_line)
from hysbench.benchmarks.diagnosis.secondary import _choose, _folds_disagree, replacements, strongest_first
from hysbench.data.dataset import Record, save_dataset
from hysbench.data.protocol import paper_voltage, protocol_time
from hysbench.identification import Fit, identify
from hysbench.models import CAUSES, ExtendedModel, get_model
from hysbench.models.filter_kernels import (first_order_foh, lowpass1, lowpass1_bank, lowpass1_bank_at,
                                           lowpass2_columns_at, lowpass2_rows, second_order_foh)
from measured_data import pzt_dataset

DT = 1e-3


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
    # delay: the base on the input sampled at t - d, from rest at t = d; before, its output for u(0) held
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
    screen = SimpleNamespace(n=t.size, n_held_out_rows=t.size, noise_sd=0.05, creep_min=20.0)
    a = _scored("delay", folds, e_null, e_a, {"delay": {"se": 1e-4, "folds": [0.010, 0.0101, 0.0099]}})
    errors = {id(a): e_a}
    v = decide(screen, folds, [a], [], errors, e_null, structured=True)
    assert v.cause == "delay" and v.remainder == pytest.approx(0.61, abs=0.03) and "unexplained" in v.reason
    level = {"saturation_level": {"se": 1e-3, "se_over_range": 0.01, "folds": [0.50, 0.501, 0.499]}}
    b = _scored("saturation", folds, e_null, e_b, level)
    errors[id(b)] = e_b
    v = decide(screen, folds, [a, b], [], errors, e_null, structured=True)
    assert v.cause == "unexplained" and v.partial is a and "saturation" in v.reason
    # a rival whose own parameters the folds do not agree on is no explanation either: it does not make a guess
    loose = _scored("saturation", folds, e_null, e_b, {"saturation_level": {"se": 0.2, "se_over_range": 0.4,
                                                                           "folds": [0.2, 0.5, 0.9]}})
    v = decide(screen, folds, [a, loose], [], {id(a): e_a, id(loose): e_b}, e_null, structured=True)
    assert v.cause == "delay" and v.remainder == pytest.approx(0.61, abs=0.03), v.reason
    # a sinusoid at a drive harmonic with the same phase in every record is no cause, but with held-out evidence
    # it shows a misfit locked to the drive: removing another part, it makes the partial cause a guess too
    locked = _scored("interference", folds, e_null, e_b, {"amplitude": {"se": 1e-3, "folds": [0.5, 0.5, 0.5]}})
    locked.limit = DRIVE_LOCKED
    v = decide(screen, folds, [a, locked], [], {id(a): e_a, id(locked): e_b}, e_null, structured=True)
    assert v.cause == "unexplained" and "locked to the drive" in v.reason, v.reason
    e_weak = e_null + rng.normal(0, 0.05, t.size)  # no held-out evidence: it does not count
    weak = _scored("interference", folds, e_null, e_weak)
    weak.limit = DRIVE_LOCKED
    v = decide(screen, folds, [a, weak], [], {id(a): e_a, id(weak): e_weak}, e_null, structured=True)
    assert v.cause == "delay", v.reason
    # a rival for the SAME slice (another mode of explaining it, as a short lag for a delay): ambiguous, and the
    # candidate with fewer parameters is named
    e_c = 0.6 * s1 + s2 + rng.normal(0, 0.05, t.size)
    c = _scored("resonance", folds, e_null, e_c, {"natural_frequency": {"relative_se": 0.02, "folds": [9.0, 9.2, 9.1]}})
    c.k = a.k + 1
    errors[id(c)] = e_c
    v = decide(screen, folds, [c, a], [], errors, e_null, structured=True)
    assert v.cause == "delay" and [r.cause for r in v.ambiguous_with] == ["resonance"], v.reason
    assert v.remainder == pytest.approx(0.61, abs=0.03)
    v = decide(screen, folds, [a, b, c], [], errors, e_null, structured=True)  # a rival for another slice: a guess
    assert v.cause == "unexplained" and "another part" in v.reason
    wobbly = _scored("delay", folds, e_null, e_a, {"delay": {"se": 0.004, "folds": [0.004, 0.010, 0.016]}})
    v = decide(screen, folds, [wobbly], [], {id(wobbly): e_a}, e_null, structured=True)
    assert v.cause == "unexplained" and "folds" in v.reason


def test_a_relaxation_whose_second_time_constant_sits_at_its_bound_gives_the_one_it_missed():
    """Accuracy plan seed 35, case 182: one 4.4 s relaxation (weight 0.27, planted by FFT convolution) on MRPIM
    sines. The greedy one-time-constant search stopped at 5.8 s, which predicts the held-out records worse than
    the base; the two-time-constant fit found 4.44 s beside one at the 10 ms bound (not identified), so nothing
    was admissible and the verdict was `unexplained`. The variant of one fewer started from the unpinned one
    (``relaxation.without_pinned``) is the planted relaxation."""
    ds, truth = planted_case(("relaxation",), "mrpim", "sines", 3500182)
    d = diagnose(ds, seed=0, experiments=False, extend=False)
    assert d.cause == "relaxation", (d.verdict.reason, [(c.label, c.heldout, c.estimates) for c in d.candidates])
    assert len(d.parameters["tau_s"]) == 1
    assert parameter_errors(truth, "relaxation", d.parameters)["tau_s"] <= 0.05


def test_without_pinned_needs_a_pinned_time_constant_and_one_left():
    from hysbench.benchmarks.diagnosis.relaxation import without_pinned

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
    screen = SimpleNamespace(n=t.size, n_held_out_rows=t.size, noise_sd=0.01, creep_min=20.0)
    for tau, named in ((25.0, "creep"), (4.0, "relaxation")):
        relax, creep = _scored("relaxation", folds, e_null, e_relax), _scored("creep", folds, e_null, e_creep)
        relax.estimates, creep.estimates = {"tau_s": [tau]}, {"size": 0.3, "time_scale_s": 20.0}
        errors = {id(relax): e_relax, id(creep): e_creep}
        v = decide(screen, folds, [creep], [relax], errors, e_null, structured=True)
        assert v.cause == named, (tau, v.reason)
        assert [c.cause for c in v.ambiguous_with] == ["relaxation" if named == "creep" else "creep"], tau
        assert ("longer than the longest drive period" in v.reason) == (named == "creep"), v.reason


def test_the_slowest_relaxation_part_is_compared_with_creep_only_when_slower_than_every_drive_period():
    """The composite (faster time constants + creep) is built only for a named relaxation of two or more time
    constants whose slowest is longer than the longest drive period (creep_min / CREEP_PERIODS); it is called
    as good when it passes and the relaxation does not predict better by z >= Z_SAME."""
    from hysbench.benchmarks.diagnosis.slow_part import predicts_as_well, slow_part_composite

    screen = SimpleNamespace(creep_min=20.0)  # longest drive period 10 s
    relax = Candidate("relaxation", "relaxation", get_model("mrpim"), {}, 25, 1.0, 10)
    one = Candidate("relaxation", "relaxation", get_model("mrpim"), {}, 23, 1.0, 10, estimates={"tau_s": [0.5]})
    creep = Candidate("creep", "creep", get_model("mrpim"), {}, 23, 1.0, 10)
    for taus in ([0.5, 9.0], [30.0]):  # too fast, or a single time constant: not applicable (the screen is
        relax.estimates = {"tau_s": taus}  # a stub, so going on would raise)
        assert slow_part_composite(screen, None, {}, relax, [creep], [one]) is None, taus
    rng = np.random.default_rng(2)
    folds = Folds(np.array([0, 4000, 8000, 12000]))
    noise = rng.normal(0, 0.01, 12000)
    drift = 0.3 * np.sin(np.arange(12000) / 900.0) ** 2
    e_null, e_relax = drift + noise, 0.05 * drift + noise
    for e_comp, same in ((0.05 * drift + rng.normal(0, 0.01, 12000), True), (0.5 * drift + noise, False)):
        chosen, comp = _scored("relaxation", folds, e_null, e_relax), _scored("creep", folds, e_null, e_comp)
        assert predicts_as_well(folds, {id(chosen): e_relax, id(comp): e_comp}, chosen, comp) is same


def test_creep_planted_on_the_virtual_dea_is_reported_as_ambiguous_with_its_slow_relaxation():
    """A logarithmic creep (not the extension's exponential drift) planted on the virtual DEA's physics, whose own
    relaxation is named: the fitted slowest time constant (15 s) is longer than every drive period (10 s), and its
    faster time constant plus creep predicts the held-out records as well, so creep is reported as ambiguous
    with it, with a suggested experiment; the tested composite is in the JSON either way."""
    ds, truth = planted_case(("creep",), "virtual-dea", "sines", 10)
    d = diagnose(ds, seed=0, experiments=True, extend=False)
    assert d.cause == "relaxation", d.verdict.reason
    assert max(d.chosen.estimates["tau_s"]) > d.screen.creep_min / 2
    twin = [c for c in d.verdict.ambiguous_with if c.cause == "creep"]
    assert twin and "may be creep" in d.verdict.reason, d.verdict.reason
    assert len(twin[0].estimates) == 2 and twin[0].heldout["refit_per_fold"]
    assert ["relaxation", "creep"] in [e["causes"] for e in d.experiments]
    evidence = d.to_json()["evidence"]["slow_part_as_creep"]
    assert evidence["ambiguous"] and evidence["cause"] == "creep"


def test_a_mode_on_the_virtual_dea_kept_as_a_delay_shows_the_mode_and_the_drive_that_separates_them():
    """A 4.75 Hz mode (damping 0.38; RK45 of its own ODE) planted on the virtual DEA's physics under multisines
    (accuracy plan seed 45, case 96): on top of the DEA's own relaxation a delay and a mode predict the held-out
    records as well, so the delay (fewer parameters) is kept. The mode is reported beside it with its fit, and
    a suggested experiment names the drive on which the two composites differ most, well above the noise."""
    ds, truth = planted_case(("resonance",), "virtual-dea", "multisines", 4500096)
    d = diagnose(ds, seed=0, experiments=True)
    assert d.cause == "relaxation", d.verdict.reason
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
    text = "\n".join(verdict_lines(d))
    assert "as good on these records: resonance: natural_frequency_hz" in text
    assert "suggested experiment (delay vs resonance, on top of relaxation)" in text


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
    fake = SimpleNamespace(parts=[SimpleNamespace(record=rec)] * 2)
    fake.drive_harmonic = lambda f, tol: Screen.drive_harmonic(fake, f, tol)
    locked = lambda f, phases: Screen.drive_locked(fake, {"frequency_hz": f, "phase_rad_per_record": phases})  # noqa: E731
    fake.null_residuals = lambda: _sine_residuals(9.0, noise=0.02)  # a misfit the drive repeats
    assert locked(9.0, [2.79, 2.99]) and locked(9.0, [3.1, -3.1])  # the phase wraps
    fake.null_residuals = lambda: _sine_residuals(1.014, noise=0.02)
    assert locked(1.014, [2.79, 2.99])  # 0.09 rad per period: not told from the harmonic
    assert not locked(9.0, [0.3, 2.0])  # its own phase in every record: a disturbance
    assert not locked(9.5, [2.79, 2.99])  # between harmonics
    # within the resolution of 9 Hz, phases alike by chance, but turning 0.94 rad per period: a line off it
    # (planted piezo cases of seeds 0, 19-28: such lines at 0.09-0.24 Hz from a harmonic were unexplained)
    fake.null_residuals = lambda: _sine_residuals(9.15, noise=0.02)
    assert not locked(9.15, [2.79, 2.99])
    fake.null_residuals = lambda: _sine_residuals(9.15, noise=5.0)  # the same turn lost in noise: as before
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
    delay = SimpleNamespace(cause="delay", model=ExtendedModel("mrpim", ("delay",)), params={**base, "delay": 0.02})
    lag = SimpleNamespace(cause="resonance", model=ExtendedModel("mrpim", ("resonance",)),
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
        return SimpleNamespace(cause=cause, params={}, model=SimpleNamespace(param_names=(), simulate=simulate))

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
    """A clip of a kept part (``saturation.clip_on_top``) shares that part's model; its probe prediction must be
    the part's output clipped at the level, not the part's output (before 2026-12-02 the clip was dropped)."""
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
    assert separation(screen, part, clip, u, DT, 0) == pytest.approx(np.sqrt(np.mean((y - got) ** 2)))
    assert separation(screen, part, clip, u, DT, 0) > 0


def test_a_secondary_cause_kept_for_fewer_parameters_lists_the_ones_as_good_with_their_fits():
    """``secondary._choose`` keeps the simplest of the causes on top that the best does not beat by z >= Z_SAME;
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
        return (c, c, e, [], e, e)

    e1, e2 = 0.1 * misfit + noise, 0.1 * misfit + rng.normal(0, 0.05, 12000)
    e_mode, e_delay = sorted((e1, e2), key=lambda e: float(e @ e))  # the mode a little better, by chance
    delay, mode = tried("delay", 1, e_delay), tried("resonance", 2, e_mode)
    assert score(folds, e_delay, e_mode)["z"] < Z_SAME
    creep = tried("creep", 1, 0.8 * misfit + noise)  # clearly worse than the mode
    pick, alike = _choose(screen, folds, [mode, creep, delay], kept)
    assert pick is delay and alike == [mode[0]]
    assert delay[0].heldout["as_good"] == ["resonance"]
    assert _choose(screen, folds, [creep], kept) == (creep, [])
    none_ok = tried("delay", 1, kept)
    none_ok[0].heldout["at_bound"] = ["delay"]
    assert _choose(screen, folds, [none_ok], kept) == (None, [])


# --- planted effects (drawn within the detection limits) --------------------------------------------
# Detection limits (strength: rms of the effect, % of the output's peak-to-peak) measured by the accuracy
# benchmark, the largest over its slot-tied plans of seeds 0-3 (200 cases each, most of them on the Table 2
# MRPIM's sines, as drawn here; results/diagnosis-accuracy-seed0-slot-tied/ and README "On fresh plans");
# None: not reached on some plan (another cause mimics it).
LIMITS = {"relaxation": 1.11, "delay": None, "resonance": None, "creep": None, "interference": 0.195,
          "saturation": 2.42}
# Causes without a limit there, or with one above what these drives reach on the Table 2 MRPIM (a delay of at
# most 30 ms under 0.1-1 Hz sines: strength <= ~1.6 %; a mode: rarely above 5 %): a strong draw must be named
# or reported as ambiguous.
STRONG = {"delay": 1.2, "resonance": 3.0, "creep": 3.0}


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
    validation multisines to the noise. (Each record's own peak left 0.35 and 3.1 mm rms on seed 7, noise
    0.01; the design range 0.5-2.5 kV, above every identification peak of seed 32's case 52, 2.41-2.49 kV,
    left 1.15 x the noise, a structure a sub-sample delay partly explained: that null was confirmed.)"""
    ds, truth = planted_case(("null-white",), "mrpim", "multisines", seed)
    peaks = [float(r.u.max()) for r in ds.records]
    assert max(peaks) - min(peaks) > 0.05  # the records differ in peak: the case that went wrong
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


@pytest.mark.parametrize("seed", [25, 29, 35])
def test_a_delay_on_the_real_piezo_recordings_is_named_despite_an_unidentified_rival(seed):
    """A 27-29 ms output delay planted (frequency domain) on the real piezo recordings, which have slow misfit
    of their own: delay removes under half of the held-out misfit, and a two-time-constant relaxation removes
    another part with its slow time constant not identified (its fold estimates disagree). Such a rival does not
    make the delay a guess: delay is named with the rest unexplained (before 2026-11-25: `unexplained`)."""
    if not piezo_available():
        pytest.skip("the accuracy benchmark's piezo recording is not present")
    ds, truth = planted_case(("delay",), "piezo", "sines", seed)
    assert truth["strength_pct"] >= 6.0
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "delay", (d.verdict.reason, [(c.cause, c.heldout, c.uncertainty) for c in d.candidates])
    assert d.verdict.remainder is not None and d.verdict.remainder > 0.5  # said, not hidden
    assert d.confirmed
    # the piezo's own lag takes some of the delay: within 30 % here (the benchmark reports the rest)
    assert parameter_errors(truth, "delay", d.parameters)["delay_s"] < 0.3
    # three records of one 1 Hz sine: a delay there only reshapes the response, as a dead band could
    assert d.one_drive_caution.startswith("every record (3) has the same drive, 1 Hz over the same input range")
    assert "caution: " + d.one_drive_caution in verdict_lines(d)
    assert d.to_json()["one_drive_caution"] == d.one_drive_caution


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


@pytest.mark.parametrize("kind,seed", [("null-white", 0), ("null-ar1", 1), ("null-ar1", 2)])
def test_noise_alone_white_or_coloured_is_none(kind, seed):
    ds, truth = planted_case((kind,), "mrpim", "sines", seed,
                             effects={"null-ar1": {"ar1": 0.99}} if kind == "null-ar1" else None)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "none", [(c.cause, c.heldout) for c in d.candidates]
    assert d.extended_fit is None and d.also == [] and d.parameters == {}


@pytest.mark.parametrize("kind", ["gain-modulation", "dead-zone"])
def test_an_effect_outside_the_vocabulary_gets_no_vocabulary_cause(kind):
    ds, truth = planted_case((kind,), "mrpim", "sines", 3)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause in ("unexplained", "none"), (d.cause, [(c.cause, c.heldout) for c in d.candidates])
    if d.cause == "unexplained":
        assert d.verdict.reason


@pytest.mark.parametrize("seed", [5, 100083])
def test_a_modulation_slower_than_the_records_is_not_named_interference(seed):
    """A 40-s gain modulation on 15-s multisines: with its phase free per record a sinusoid of under two cycles
    per record is a per-record drift (nearly an offset and a slope), so it is not an interference."""
    ds, truth = planted_case(("gain-modulation",), "mrpim", "multisines", seed,
                             effects={"gain-modulation": {"depth": 0.065, "period_s": 40.0, "phase_rad": 5.75}})
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause in ("unexplained", "none"), (d.cause, [(c.cause, c.heldout) for c in d.candidates])
    slow = [c for c in d.candidates if c.cause == "interference" and c.estimates["frequency_hz"] * 15.0 < 2.0]
    assert all("cycles" in c.limit for c in slow)


def test_an_interference_is_scored_on_top_of_the_base_models_own_held_out_prediction():
    """A 23 Hz numpy sinusoid, its phase drawn per record, on a null of the virtual DEA under triangles (two
    periods per record: the base fitted on two records predicts the 0.1 Hz one poorly). The line's held-out
    residual is checked against a slow reference: the base solved on the other records alone by numpy's lstsq
    (its prediction of the left-out record), the line's amplitude the rms of the training records' own when
    solved together with the base there (since session 40; before, in the base's residual alone), the phase
    fitted on the held-out record. It removes what it should from every record, so the folds agree and it is
    named; before 2026-12-01 the base's prediction came from its fit with the line, and the small change that
    made to the extrapolated 0.1 Hz prediction cost more than the line removed there (seed 36, case 116)."""
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
    without it and does not find 27 Hz. The folds then disagree, which is no line (``same_line``); before
    2026-11-27 every fold was scored at the frequency chosen on all records, the held-out one included."""
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
    on top of a kept cause (``fold_frequencies``); the fit on every record (``fit_interference``), where
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


def test_an_interference_on_top_of_a_kept_cause_is_chosen_without_the_left_out_record():
    """The frequency and amplitude of an interference tried on top of a kept cause come, in each fold, from
    what is kept fitted on the other records alone (``train_residuals``): a strong 41 Hz line added to
    record 0 of the virtual DEA alone leaves fold 0's inputs, and so its frequency, exactly as they were. The
    kept cause's out-of-fold residuals on records 1 and 2 (used before 2026-11-28) come from fits that
    included record 0's rows, and they change."""
    ds, _ = planted_case(("interference",), "virtual-dea", "sines", 4,
                         effects={"interference": {"frequency_hz": 13.7, "amplitude": 0.08}})
    d = diagnose(ds, seed=0, experiments=False, extend=False)
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


def test_an_interference_on_top_reports_and_checks_the_frequencies_it_was_scored_at():
    """A mode planted on the real piezo recording (plan of seed 38, case 36; two 2 s records of the 1 Hz
    drive). The interference tried on top of the named resonance is scored at the frequency each fold
    chose, not at the one fitted on every record against the base alone (3.14 Hz here): its estimates are the
    folds', and its meaning (cycles, drive lock) is checked there (before 2026-11-28 the meaning check saw
    the whole fit). Which spectral peak a fold picks can be a near tie (seed 28 case 156, this test's case
    until session 40: 3.92 Hz in both folds on one host, 2.06 and 3.92 Hz on another; with the line fitted
    jointly with the base since session 40, its whole fit there is drive-locked and no line is tried on top),
    so the test checks the invariants, not the peak."""
    if not piezo_available():
        pytest.skip("the accuracy benchmark's piezo recording is not present")
    ds, _ = planted_case(("resonance",), "piezo", "sines", 3800036)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "resonance", d.verdict.reason
    tried = next(c for c in d.secondary_tried if c.cause == "interference")
    whole = next(c for c in d.candidates if c.cause == "interference")
    folds_f = tried.heldout["fold_frequencies_hz"]
    assert len(folds_f) == 2 and tried.estimates["frequency_hz"] == pytest.approx(np.mean(folds_f))
    assert abs(tried.estimates["frequency_hz"] - whole.estimates["frequency_hz"]) > 0.1
    meaning = d.screen.limit_of("interference", tried.estimates)
    if meaning or frequencies_agree(d.screen, folds_f):
        assert tried.limit == meaning
    else:  # folds that chose lines apart found no one line (from 2026-11-28)
        assert "not one line" in tried.limit
    assert meaning != d.screen.limit_of("interference", {**tried.estimates, "frequency_hz": 0.4})  # < 2 cycles
    if tried.limit:
        assert "interference" not in [c.cause for c in d.also]


def test_one_line_means_frequencies_within_the_coarsest_folds_resolution_and_amplitudes_within_a_quarter():
    spans = [(20.0, 0.01), (5.0, 0.01), (2.0, 0.01)]  # (duration s, dt): fold 0 trains on 5 s at most
    parts = [SimpleNamespace(record=SimpleNamespace(t=np.zeros(int(T / dt)), dt=dt)) for T, dt in spans]
    fake = SimpleNamespace(parts=parts)
    est = lambda fs, amps: [{"interference_frequency": f, "amplitude": a} for f, a in zip(fs, amps)]  # noqa: E731
    assert same_line(fake, est([30.0, 30.19, 30.1], [1.0, 1.1, 0.9]))
    assert not same_line(fake, est([30.0, 30.21, 30.1], [1.0, 1.1, 0.9]))  # beyond 1 / 5 s
    assert not same_line(fake, est([30.0, 30.0, 30.0], [1.0, 1.3, 1.0]))  # amplitudes differ by 30 %
    assert frequencies_agree(fake, [30.0, 30.19, 30.1]) and not frequencies_agree(fake, [30.0, 30.21, 30.1])
    assert not frequencies_agree(fake, [30.0])  # one fold: nothing to agree with
    assert _folds_disagree(fake, [30.0, 30.19]) == ""
    assert "not one line" in _folds_disagree(fake, [2.06, 3.92])  # a line on top is one only if the folds agree


def test_a_line_below_the_gain_floor_is_named_with_the_rest_unexplained():
    """A 35.7 Hz interference planted on the virtual DEA's triangles (accuracy plan seed 0, case 104; strength
    0.26 % of the output's range) removes 0.25 % of the base's large held-out misfit: below the 1 % every other
    cause must remove, so before 2026-11-27 the verdict was `unexplained`. Found at one frequency and amplitude
    on each fold's other records and improving every held-out record (z >= 3), it is named, with the rest
    reported as unexplained and the frequency within 0.1 %."""
    ds, truth = planted_case(("interference",), "virtual-dea", "triangles", 104)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "interference", d.verdict.reason
    h = d.chosen.heldout
    assert h["same_line"] and h["refit_per_fold"] and 0 < h["gain"] < MIN_EXPLAINED
    assert d.verdict.remainder is not None and d.verdict.remainder > 0.9
    assert parameter_errors(truth, "interference", d.parameters)["frequency_hz"] < 1e-3


def test_virtual_dea_relaxation_with_an_interference_on_top():
    """The virtual DEA's physics from rest (its own relaxation) with an interference planted: relaxation is named
    and the interference found on top of it, frequency within 25 %."""
    ds, truth = planted_case(("interference",), "virtual-dea", "sines", 4,
                             effects={"interference": {"frequency_hz": 13.7, "amplitude": 0.08}})
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "relaxation", [(c.cause, c.heldout) for c in d.candidates]
    found = [c for c in d.also if c.cause == "interference"]
    assert found, [(c.cause, c.heldout) for c in d.secondary_tried]
    assert found[0].estimates["frequency_hz"] == pytest.approx(13.7, rel=0.25)



def test_secondary_causes_are_selected_forward_on_top_of_what_is_kept():
    """A weak interference on the virtual DEA removes under 1 % of the held-out misfit left by its relaxation
    alone, but more than that on top of relaxation + the physics' lag: it is found only if each secondary cause
    is tested on top of the ones already kept (and scored against them, not against the named cause alone:
    against relaxation + delay with their parameters as fitted on every record, the delay's held on both sides)."""
    ds, truth = planted_case(("interference",), "virtual-dea", "sines", 4,
                             effects={"interference": {"frequency_hz": 23.8, "amplitude": 0.027}})
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "relaxation", [(c.cause, c.heldout) for c in d.candidates]
    causes = [c.cause for c in d.also]
    assert causes[:1] == ["delay"] and "interference" in causes, [(c.cause, c.heldout) for c in d.secondary_tried]
    inter = d.also[causes.index("interference")]
    held = heldout_errors(d.screen, Folds.of(d.screen), d.also[0])[0]  # relaxation + delay, as fitted on every record
    reference = inter.heldout["sse"] / (1.0 - inter.heldout["gain"])
    assert reference == pytest.approx(float(held @ held), rel=1e-9)  # scored against relaxation + delay
    # the delay judged with its own value refitted on each fold's other records, the time constants held
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
    assert inter.estimates["frequency_hz"] == pytest.approx(23.8, rel=0.25)


def test_a_named_cause_made_redundant_by_the_secondary_ones_is_dropped():
    """A 15.6 ms delay and a logarithmic creep planted on the Table 2 MRPIM under the protocol's sines (the
    balanced plan of seed 0, case 57): a two-time-constant relaxation predicts best alone and is named first,
    with the delay kept on top of it; its slowest time constant (longer than every drive period) already holds
    the drift, so creep adds nothing on top (since session 18, when the delay is judged with its value
    refitted per fold). Delay + creep, creep standing for that slow part, predict the held-out records as well
    without it: the relaxation is dropped and the delay named (within 25 %), creep under "also"."""
    ds, truth = planted_case(("delay", "creep"), "mrpim", "sines", 57)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.dropped is not None and d.dropped.cause == "relaxation", (d.cause, [c.label for c in d.also])
    assert d.cause == "delay" and [c.cause for c in d.also] == ["creep"], d.verdict.reason
    assert parameter_errors(truth, "delay", d.parameters)["delay_s"] <= 0.25
    assert d.to_json()["dropped_as_redundant"]["cause"] == "relaxation"
    assert "creep standing for its time constant" in d.verdict.reason


@pytest.mark.parametrize("seed, says", [(3700057, "relaxation is not needed"),
                                         (3800177, "creep's time scale alone sits at its limit")])
def test_the_backward_step_names_creep_with_the_delay_for_a_relaxation_not_needed(seed, says):
    """A delay and a logarithmic creep planted on the Table 2 MRPIM under the protocol's sines; a
    two-time-constant relaxation is named first, delay and creep kept on top of it.

    * Seed 37, case 57 (15.3 ms, t_c 27 s; relaxation 49 ms and 25 s): the kept causes are composed strongest
      first (creep predicts 87 % of the held-out misfit alone, the delay 19 %). In the order kept the delay is
      searched before the creep, takes up part of the drift (25.7 ms), and the relaxation is still needed;
      creep first, the delay comes out at 15.5 ms.
    * Seed 38, case 177 (26 ms, t_c 12.5 s; relaxation 86 ms and 16 s): creep comes first, and alone its time
      scale sits at its fast limit (two drive periods, 20 s: a logarithmic creep looks that fast); with the
      delay on top it does not. A creep replacing a relaxation slower than every drive period may have its
      time scale at an end (as when it is appended for that slow part); it is reported as not identified.

    Delay + creep then predict the held-out records as well without the relaxation: it is dropped and creep
    named, the delay under "also" within 25 %."""
    ds, truth = planted_case(("delay", "creep"), "mrpim", "sines", seed)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.dropped is not None and d.dropped.cause == "relaxation", d.verdict.reason
    assert d.cause == "creep" and [c.cause for c in d.also] == ["delay"], d.verdict.reason
    assert parameter_errors(truth, "delay", d.also[0].estimates)["delay_s"] <= 0.25
    assert says in d.verdict.reason


def test_the_backward_step_keeps_a_delay_a_mode_alone_would_leave_most_of_the_misfit_of():
    """An 8.8 ms delay (frequency-domain shift) on the Table 2 MRPIM under triangles (fresh plan seed 51, case
    155). The delay removes 75 % of the held-out misfit; on top of it a 220 Hz mode smooths what the generator's
    shift does at the triangles' corners. Alone, the mode found first (29 Hz) removes 22 %, yet the two together
    are not better by z >= 2 (the gain sits in few blocks), and before 2026-12-03 the backward step dropped the
    delay and named the mode. A replacement must now remove at least half of the base's held-out misfit beyond
    noise, as any cause named without a remainder must: the delay stays named, within 25 %."""
    ds, truth = planted_case(("delay",), "mrpim", "triangles", 5100155)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "delay" and d.dropped is None, d.verdict.reason
    assert parameter_errors(truth, "delay", d.parameters)["delay_s"] <= 0.25


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
    slow = SimpleNamespace(cause="relaxation", estimates={"tau_s": [0.05, 13.0]})
    assert replacements(slow, own, ["delay", "resonance"], creep_min=20.0) == [
        ["resonance", "delay"], ["resonance", "delay", "creep"]]
    fast = SimpleNamespace(cause="relaxation", estimates={"tau_s": [0.05, 9.0]})
    assert replacements(fast, own, ["delay", "resonance"], creep_min=20.0) == [["resonance", "delay"]]
    assert replacements(slow, own, ["creep", "delay"], creep_min=20.0) == [["creep", "delay"]]
    named_delay = SimpleNamespace(cause="delay", estimates={"delay_s": 0.02})
    assert replacements(named_delay, own, ["resonance"], creep_min=20.0) == [["resonance"]]


@given(lo=st.floats(1e-3, 1.0), ratio=st.floats(2.0, 1e4), dt=st.floats(1e-4, 1e-3))
def test_a_second_cause_starts_on_a_grid_strictly_inside_its_bounds(lo, ratio, dt):
    """``Screen._starts``: the given start first, then a geometric grid strictly inside each named parameter's
    bounds (a delay from one sample up), 12 points for one parameter, 6 x 6 for a mode; a relaxation of
    several time constants keeps its own start only."""
    bounds = {"delay": (0.0, lo * ratio), "natural_frequency": (lo, lo * ratio), "damping_ratio": (0.01, 1.0),
              "tau1": (lo, lo * ratio), "tau2": (lo, lo * ratio)}
    fake = SimpleNamespace(bounds_of=lambda model, name: bounds[name],
                           parts=[SimpleNamespace(record=SimpleNamespace(dt=dt))])
    start = {"delay": 0.5 * lo, "natural_frequency": 2 * lo, "damping_ratio": 0.3, "tau1": lo, "tau2": 2 * lo}
    for names, n in ((["delay"], 12), (["natural_frequency", "damping_ratio"], 36), (["tau1", "tau2"], 0)):
        starts = Screen._starts(fake, None, start, names)
        assert starts[0] == start and len(starts) == 1 + n
        for name in names if n else []:
            a, b = bounds[name]
            a = dt if name == "delay" else a
            values = np.unique([z[name] for z in starts[1:]])
            assert values.size == (12 if len(names) == 1 else 6)
            assert np.all((values > a) & (values < b)), (name, values, a, b)
            if a < b:
                assert np.allclose(np.diff(np.log(values)), math.log(b / a) / (values.size + 1))


def test_a_second_cause_is_searched_afresh_on_top_of_the_named_one():
    """A delay and a logarithmic creep planted on the Table 2 MRPIM under multisines (the balanced plan of
    seed 0, case 27): the delay is named; the creep, fitted against the base alone, does not pass there, but
    searched again on top of the delay it does, with its drift within 25 %. Trying only causes that passed
    against the base, from their fits there, kept a relaxation that was not planted instead."""
    ds, truth = planted_case(("delay", "creep"), "mrpim", "multisines", 27)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "delay", [(c.cause, c.heldout) for c in d.candidates]
    assert [c.cause for c in d.also] == ["creep"], [(c.label, c.heldout) for c in d.secondary_tried]
    assert parameter_errors(truth, "creep", d.also[0].estimates)["drift"] <= 0.25


def test_a_specific_cause_is_named_when_the_best_predicting_one_is_unstable():
    """A 12.6 Hz interference (0.85 % of p2p) planted on the virtual DEA under triangles (balanced plan of
    seed 22, case 104): a one-time-constant relaxation predicts more of the held-out misfit (the physics' own,
    MRPIM fitted on two triangle records extrapolating to the third) but its time constant differs between the
    folds; the interference removes a small part of its own, at one frequency and amplitude in every fold.
    It is named, with the rest unexplained (before 2026-11-27: `unexplained`)."""
    ds, truth = planted_case(("interference",), "virtual-dea", "triangles", 2200104)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "interference", (d.verdict.reason, [(c.cause, c.heldout, c.uncertainty) for c in d.candidates])
    assert d.verdict.remainder is not None and d.verdict.remainder > 0.5  # said, not hidden
    assert "differ between the folds" in d.verdict.reason
    errors = parameter_errors(truth, "interference", d.parameters)
    assert errors["frequency_hz"] < 0.01 and errors["amplitude"] < 0.25


def test_a_clip_is_searched_on_top_of_the_named_cause():
    """A clip 2-10 % below the top (0.55 % of p2p) planted on the virtual DEA under multisines (balanced plan
    of seed 22, case 46): against the base alone it shows nothing (the physics' relaxation dominates); on top of
    the named relaxation a clip of its prediction is kept, flat where it cuts, at the planted level (before
    2026-11-27 a clip could not be composed, and a delay was kept there)."""
    ds, truth = planted_case(("saturation",), "virtual-dea", "multisines", 2200046)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "relaxation", d.verdict.reason
    clips = [c for c in d.also if c.cause == "saturation"]
    assert clips, [(c.label, c.heldout, c.limit) for c in d.secondary_tried]
    assert abs(clips[0].estimates["slope_where_clipped"]) < 0.5
    assert parameter_errors(truth, "saturation", clips[0].estimates)["level_over_p2p"] < 0.01


def test_a_level_that_cuts_nothing_is_no_clip_on_top():
    """A logarithmic creep on the Table 2 MRPIM under sines (seed 22, case 39): on top of the named creep, a
    'clip' above the prediction's peaks gains on held-out records only by leaving the output's top samples out
    of the linear fit. It cuts no sample of the prediction, so it is not kept (it was, before that check)."""
    ds, _ = planted_case(("creep",), "mrpim", "sines", 2200039)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "creep", d.verdict.reason
    assert "saturation" not in [c.cause for c in d.also]
    tried = [c for c in d.secondary_tried if c.cause == "saturation"]
    assert tried and all(c.limit for c in tried)


def test_a_named_level_must_cut_the_prediction_as_a_clip_on_top_must():
    """The base's own saturation candidate answers to the same meaning as a clip on top: a level that cuts
    fewer than three samples of the prediction (no slope where clipped can be measured) is no clip; before
    2026-11-27 only the clip on top was checked."""
    fake = SimpleNamespace()
    assert Screen.limit_of(fake, "saturation", {"level": 1.0, "side": "upper"}) == NO_CUT
    assert Screen.limit_of(fake, "saturation", {"level": 1.0, "side": "upper", "slope_where_clipped": 0.02}) == ""
    assert "not a clip" in Screen.limit_of(fake, "saturation",
                                           {"level": 1.0, "side": "upper", "slope_where_clipped": 0.8})


def test_with_two_records_only_the_best_predicting_cause_can_be_named_partly():
    """A quadratic sensor nonlinearity (out of vocabulary) on the real piezo recordings, two identification
    records (balanced plan of seed 0, case 84): a relaxation predicts most but is unstable; a delay removes
    another, smaller part with its two fold estimates agreeing. Two agreeing estimates are too weak a check to
    name a cause that does not predict best: no vocabulary cause is named (it was, a confirmed delay, when the
    rule above had no such limit)."""
    if not piezo_available():
        pytest.skip("the accuracy benchmark's piezo recording is not present")
    ds, _ = planted_case(("sensor-nonlinearity",), "piezo", "sines", 84)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause in ("unexplained", "none"), d.verdict.reason


def test_a_mode_above_the_drives_is_named_resonance_not_a_delay():
    """A 12 Hz mode (damping 0.2) under the 0.1-1 Hz sines, integrated by RK45 from equilibrium with the
    plant's first output: mostly a phase lag on these drives (0.57 % of p2p). The extension's mode must start
    where the generator's does, else its start-up ringing costs more than the mode explains and a delay is named."""
    ds, truth = planted_case(("resonance",), "mrpim", "sines", 11,
                             effects={"resonance": {"natural_frequency_hz": 12.0, "damping_ratio": 0.2}})
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "resonance", [(c.cause, c.heldout) for c in d.candidates]
    assert d.parameters["natural_frequency_hz"] == pytest.approx(12.0, rel=0.25)
    assert d.parameters["damping_ratio"] == pytest.approx(0.2, rel=0.25)


@given(fn=st.floats(0.5, 200.0), zeta=st.floats(0.02, 1.0), extra=st.floats(0.0, 0.2))
def test_a_mode_started_on_top_of_a_delay_keeps_the_low_frequency_lag(fn, zeta, extra):
    """``lag_shared``: a mode started on top of a kept delay shortens the delay by the mode's low-frequency
    lag, so the two together lag the input as the delay alone did. Checked on the mode's transfer function
    1 / (1 - r^2 + 2 j zeta r) at r = 1e-3 (its phase per radian, not the formula used)."""
    from hysbench.benchmarks.diagnosis.screen import lag_shared

    wn = 2 * math.pi * fn
    w = 1e-3 * wn
    mode_phase = -np.angle(1.0 / (1.0 - (w / wn) ** 2 + 2j * zeta * w / wn))  # lag in rad
    delay = mode_phase / w + extra  # the delay a fit without the mode would have chosen
    z = lag_shared({"delay": delay, "natural_frequency": fn, "damping_ratio": zeta, "tau1": 0.3})
    assert z["tau1"] == 0.3 and z["natural_frequency"] == fn and z["damping_ratio"] == zeta
    assert z["delay"] == pytest.approx(extra, rel=1e-4, abs=1e-5 * delay)  # the lag is exact only as r -> 0
    short = lag_shared({"delay": 0.5 * mode_phase / w, "natural_frequency": fn, "damping_ratio": zeta})
    assert short["delay"] == 0.0  # never negative


def test_a_mode_under_the_virtual_deas_own_lag_is_found_on_top_of_the_delay_kept_for_it():
    """A 2.12 Hz mode (damping 0.39) planted on the virtual DEA under multisines (balanced plan of seed 31,
    case 96). Relaxation is named (the physics' own), and a 116 ms delay is kept on top of it for the
    physics' lag and the mode's together; the mode searched on top of that delay with the delay held adds its
    lag twice and explained nothing. Started with the delay shortened by the mode's lag, it is found and
    kept, within 25 %."""
    ds, truth = planted_case(("resonance",), "virtual-dea", "multisines", 3100096)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "relaxation", d.verdict.reason
    also = {c.cause: c for c in d.also}
    assert "resonance" in also, [(c.label, c.estimates, c.heldout.get("gain")) for c in d.secondary_tried]
    errors = parameter_errors(truth, "resonance", also["resonance"].estimates)
    assert max(errors.values()) <= 0.25, errors


@pytest.mark.parametrize("left_by_both, named", [(0.3, True), (0.7, False)])
def test_a_partial_cause_is_named_only_if_the_causes_on_top_explain_half_the_misfit_with_it(monkeypatch,
                                                                                             left_by_both, named):
    """``complete_partial``: the forward selection on top of a partial cause (here a stand-in adding one cause
    whose held-out residual leaves a given share of the misfit beyond noise) names it only if what is then kept
    removes at least half of the base's held-out misfit beyond noise; otherwise the verdict stays unexplained."""
    from hysbench.benchmarks.diagnosis import secondary
    from hysbench.benchmarks.diagnosis.selection import Verdict

    rng = np.random.default_rng(5)
    folds = Folds(np.array([0, 4000, 8000, 12000]))
    t = np.arange(12000) * DT
    noise = rng.normal(0, 0.05, t.size)
    signal_ = np.sin(2 * np.pi * 0.37 * t)
    e_null = signal_ + noise
    partial = _scored("relaxation", folds, e_null, 0.75 * signal_ + noise)  # 44 % of the misfit: partial
    both = np.sqrt(left_by_both) * signal_ + noise
    screen = SimpleNamespace(n=t.size, n_held_out_rows=t.size, noise_sd=0.05, null=object())
    excess = float(e_null @ e_null) - t.size * 0.05**2
    assert (float(e_null @ e_null) - float(both @ both)) / excess == pytest.approx(1 - left_by_both, abs=0.03)

    def on_top(diag, result, say):
        assert diag.chosen is partial  # the forward selection runs on top of the partial cause
        diag.also.append(_scored("delay", folds, e_null, both))
        diag.secondary_tried.append(diag.also[-1])

    monkeypatch.setattr(secondary, "secondary_causes", on_top)
    unexplained = Verdict("unexplained", None, reason="the best-predicting cause removes only 44 %", partial=partial)
    result = {"errors": {id(screen.null): e_null}}
    diag = type("D", (), {"chosen": property(lambda self: self.verdict.chosen)})()
    diag.verdict, diag.screen, diag.also, diag.secondary_tried = unexplained, screen, [], []
    assert secondary.complete_partial(diag, result, lambda m: None) is named
    if named:
        assert diag.verdict.cause == "relaxation" and diag.verdict.chosen is partial and len(diag.also) == 1
        assert "two causes at once" in diag.verdict.reason
    else:
        assert diag.verdict is unexplained and diag.also == [] and "what is kept removes" in unexplained.reason


@pytest.mark.parametrize("case, named", [("on every record", True), ("on one record", False),
                                         ("a third of the misfit", False)])
def test_a_promising_cause_is_named_only_if_with_the_causes_on_top_several_records_show_evidence(monkeypatch,
                                                                                                case, named):
    """``complete_promising``: a ``none`` verdict whose best candidate predicts most held-out records better but
    short of evidence runs the forward selection on top of it (a stand-in adding one cause). It is named only if
    what is then kept, refitted per fold, shows evidence against the base that more than one record carries and
    removes at least half of the misfit beyond noise; otherwise the verdict stays ``none``."""
    from hysbench.benchmarks.diagnosis import secondary
    from hysbench.benchmarks.diagnosis.selection import Verdict, evidence, promising

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
    assert promising(p) and not evidence(p.heldout)
    left = {"on every record": 0.1 * signal_,
            "on one record": np.where(t >= 8000 * DT, 0.1, 0.998) * signal_,  # evidence, but that record's
            "a third of the misfit": np.sqrt(0.67) * signal_}[case]
    both = left + noise
    screen = SimpleNamespace(n=t.size, n_held_out_rows=t.size, noise_sd=0.05, null=object())
    kept = _scored("relaxation", folds, e_null, both)
    kept.heldout["refit_per_fold"] = True
    result = {"errors": {id(screen.null): e_null, id(kept): both}, "folds": folds}

    def on_top(diag, result, say):
        assert diag.chosen is p  # the forward selection runs on top of the promising cause
        diag.also.append(kept)
        diag.secondary_tried.append(kept)

    monkeypatch.setattr(secondary, "secondary_causes", on_top)
    none = Verdict("none", None, reason="the best is not evidence")
    diag = type("D", (), {"chosen": property(lambda self: self.verdict.chosen)})()
    diag.verdict, diag.screen, diag.also, diag.secondary_tried, diag.candidates = none, screen, [], [], [p]
    assert secondary.complete_promising(diag, result, lambda m: None) is named
    if named:
        assert diag.verdict.cause == "delay" and diag.verdict.chosen is p and diag.also == [kept]
        assert "two causes at once" in diag.verdict.reason and "short of evidence by itself" in diag.verdict.reason
    else:
        assert diag.verdict is none and diag.also == [] and "no combination predicts" in none.reason
    p.limit = "outside its meaning"  # a candidate outside its cause's meaning is not completed
    diag.verdict, diag.also = Verdict("none", None, reason=""), []
    assert secondary.complete_promising(diag, result, lambda m: None) is False and diag.also == []


def test_a_partial_cause_completed_by_a_cause_on_top_is_named_with_it():
    """A 5.74 Hz mode (damping 0.11) and a logarithmic creep planted on MRPIM sines (balanced plan of seed 35,
    case 88). The mode predicts the held-out records by itself but removes less than half of the misfit beyond
    noise, and a delay predicts about as well, removing another part: `unexplained` until session 26. The
    forward selection on top of the mode keeps creep, and with it the misfit is explained: resonance is named
    with creep under "also". (Until session 38 this test used seed 39 case 96, a mode on virtual-DEA
    multisines; there one identification record now goes beyond the others' input range and is not a held-out
    target, and the physics' relaxation is named by itself, the mode under "also": test_held_out_targets.)"""
    ds, truth = planted_case(("resonance", "creep"), "mrpim", "sines", 3500088)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "resonance" and "two causes at once" in d.verdict.reason, d.verdict.reason
    assert "removes only" in d.verdict.reason  # the partial cause's own share is said
    also = {c.cause: c for c in d.also}
    assert "creep" in also, [(c.label, c.estimates, c.heldout.get("gain")) for c in d.secondary_tried]
    assert parameter_errors(truth, "resonance", d.parameters)["natural_frequency_hz"] <= 0.25
    assert parameter_errors(truth, "creep", also["creep"].estimates)["drift"] <= 0.25
    parts = {k: v for k, v in d.timings.items() if k != "total"}
    assert abs(sum(parts.values()) - d.timings["total"]) <= 0.05 * d.timings["total"], d.timings  # completion timed


def test_a_promising_cause_short_of_evidence_alone_is_completed_by_a_cause_on_top():
    """A 26 ms delay planted on the virtual DEA under triangles (balanced plan of seed 43, case 154). The delay
    predicts the held-out records 76 % better, but mostly the 1 Hz record: no evidence by itself, and the DEA's
    own relaxation alone predicts nothing. Until session 28 the verdict was `none`. The forward selection on
    top of the promising delay keeps the relaxation, and together, every parameter refitted per fold, they
    show evidence on more than one record: the delay is named with the relaxation under "also"."""
    ds, truth = planted_case(("delay",), "virtual-dea", "triangles", 4300154)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "delay" and "two causes at once" in d.verdict.reason, d.verdict.reason
    assert "relaxation" in [c.cause for c in d.also]
    assert "short of evidence by itself" in d.verdict.reason


@pytest.mark.parametrize("seed, end", [(3100177, "its limit"), (3200177, "the end of its search")])
def test_creep_standing_for_a_slow_relaxation_may_have_its_time_scale_at_an_end(seed, end):
    """A delay and a logarithmic creep planted on the Table 2 MRPIM under the protocol's sines (balanced plans of
    seeds 31 and 32, case 177: 24.7 ms and t_c 9.5 s; 8.8 ms and t_c 49 s). A two-time-constant relaxation (29 s
    and 276 s slowest) is named with the delay on top. Creep on top of the delay then has its time scale at
    an end: the fastest its meaning allows (two drive periods: a log creep over 20 s records) or the slowest
    searched (a straight drift). Delay + creep, creep standing for the relaxation's slow part, predict the
    held-out records as well (seed 31: far better): the relaxation is dropped, the delay named within 25 %,
    creep kept under "also", its time scale reported as not identified."""
    from hysbench.benchmarks.diagnosis.report import verdict_lines

    ds, truth = planted_case(("delay", "creep"), "mrpim", "sines", seed)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.dropped is not None and d.dropped.cause == "relaxation", d.verdict.reason
    assert d.cause == "delay" and [c.cause for c in d.also] == ["creep"], d.verdict.reason
    assert parameter_errors(truth, "delay", d.parameters)["delay_s"] <= 0.25
    assert f"creep's time scale sits at {end}" in d.verdict.reason and "not identified" in d.verdict.reason
    assert list(d.to_json()["also_not_identified"]) == ["creep"]
    lines = verdict_lines(d)
    assert any(line.startswith("also: creep (not identified: ") for line in lines)
    assert d.one_drive_caution == ""  # the protocol's seven frequencies
    pinned = any(n.startswith("parameters at their bounds") for n in d.base_fit.notes)
    assert any(line.startswith("caution: the base model's fit has parameters at their search bounds")
               for line in lines) == pinned


def test_creep_whose_time_scale_runs_to_its_upper_bound_is_a_straight_drift_named_with_it_not_identified():
    """A mode (6.3 Hz, damping 0.09) and a logarithmic creep (t_c 23 s) planted on the Table 2 MRPIM under the
    protocol's sines (balanced plan of seed 32, case 148). On the screen, creep's time scale runs to its upper
    search bound: over these records the log creep is a straight drift since the start, 1 - exp(-t / T) -> t / T.
    That end is within creep's meaning (open-ended), not a bound that hides a better fit elsewhere: creep is
    named, its drift over the longest record within 25 %, the time scale reported as not identified, and the
    mode found on top of it within 25 %. (Before: creep 'at bound', the verdict unexplained.)"""
    from hysbench.benchmarks.diagnosis.report import verdict_lines

    ds, truth = planted_case(("resonance", "creep"), "mrpim", "sines", 3200148)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "creep" and [c.cause for c in d.also] == ["resonance"], d.verdict.reason
    assert d.chosen.heldout["open_ended"] == ["creep_time"] and not d.chosen.heldout["at_bound"]
    assert parameter_errors(truth, "creep", d.parameters)["drift"] <= 0.25
    assert max(parameter_errors(truth, "resonance", d.also[0].estimates).values()) <= 0.25
    lines = verdict_lines(d)
    assert "creep_time: not identified" in next(line for line in lines if line.startswith("uncertainty"))
    assert "s (not identified)" in next(line for line in lines if line.startswith("parameters:"))
    assert any(n.startswith("creep: creep_time (longer than these records show") for n in d.to_json()["not_identified"])


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
    1 / T, where the search once did not look (the Bouc-Wen benchmark's mode inside its 5-150 Hz multisine)."""
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


# --- the command line ----------------------------------------------------------------------
def _hysbench(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "hysbench.benchmarks.cli", *args], capture_output=True, text=True,
                          cwd=cwd)


def test_cli_writes_report_and_json(tmp_path):
    ds, truth = _draw_above(("interference",), LIMITS["interference"], start=5)
    save_dataset(ds, tmp_path / "ds")
    out = tmp_path / "out"
    res = _hysbench("diagnose", str(tmp_path / "ds"), "--out", str(out), "--json", str(tmp_path / "d.json"), "--quiet")
    assert res.returncode == 0, res.stderr
    assert "cause: interference" in res.stdout

    def refuse(constant):  # JSON has no NaN or infinity; strict parsers (jq, JavaScript) refuse them
        raise AssertionError(f"diagnosis.json holds {constant}")

    data = json.loads((tmp_path / "d.json").read_text(), parse_constant=refuse)
    for key in ("model", "cause", "reason", "parameters", "uncertainty", "evidence", "extended_model", "before",
                "after", "also", "ambiguous_with", "not_identified"):
        assert key in data
    assert data["cause"] == "interference" and data["interference_check"]["same_amplitude"]
    assert set(data["before"]) == {r.file for r in ds.records} == set(data["after"])
    md = (out / "diagnosis.md").read_text()
    for png in ("residual_time", "residual_input", "residual_phase", "residual_spectrum", "error_vs_frequency",
                "whiteness", "candidates"):
        assert (out / f"diagnosis_{png}.png").stat().st_size > 1000
        assert f"diagnosis_{png}.png" in md


@pytest.mark.parametrize("args,needle", [
    (["diagnose", "/nonexistent/dataset"], "no such dataset"),
    (["diagnose", ".", "--model", "no-such-model"], "unknown model"),
    (["diagnose", ".", "--max-rows", "0"], "integer >= 1"),
    (["diagnose", ".", "--segments", "1"], "integer >= 2"),
])
def test_cli_refuses_bad_input_in_one_line(args, needle):
    res = _hysbench(*args)
    assert res.returncode == 2
    assert needle in res.stderr and len(res.stderr.strip().splitlines()) == 1 and "Traceback" not in res.stderr


def test_measured_pzt_data_with_different_sample_times(shared_datasets, tmp_path):
    """Real measured data (read in place): three records at 0.0025, 0.025 and 0.25 s, two of them identification.
    The verdict is one of the vocabulary, none or unexplained; a named extension never saw the validation record."""
    folder = pzt_dataset(shared_datasets, tmp_path / "pzt")
    res = _hysbench("diagnose", str(folder), "--out", str(tmp_path / "out"), "--json", str(tmp_path / "d.json"),
                    "--quiet")
    assert res.returncode == 0, res.stderr
    data = json.loads((tmp_path / "d.json").read_text())
    assert data["cause"] in ("none", "unexplained", *CAUSES)
    if data["extended_fit"]:
        assert "tri_T01_TEST_0.1Hz_1400V_0.1Hz.csv" not in " ".join(data["extended_fit"]["fitted_on"])
    assert (data["confirmed_on_validation"] is False) == ("warning:" in res.stdout)


def test_one_recording_is_diagnosed_in_segments_without_its_validation_window(shared_datasets, tmp_path):
    """The real piezo recording: one file, an identification window (three periods) and a validation window.
    Without --segments: refused in one line that names the option. With it, the identification window is cut
    at input minima into records of whole periods (two remain after its first minimum), no record the
    diagnosis fits on holds a validation sample, and the cuts cost the base model next to nothing (a cut at
    the window's own start, mid-sweep, had tripled its error: 0.41-0.51 % against 0.14 %)."""
    folder = shared_datasets / "piezo_sindy_1hz"
    res = _hysbench("diagnose", str(folder), "--out", str(tmp_path / "none"), "--quiet")
    assert res.returncode == 2 and "--segments" in res.stderr and len(res.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "none").exists()
    res = _hysbench("diagnose", str(folder), "--segments", "3", "--out", str(tmp_path / "none"), "--quiet")
    assert res.returncode == 2 and "2 whole period(s)" in res.stderr and not (tmp_path / "none").exists()
    res = _hysbench("diagnose", str(folder), "--segments", "2", "--out", str(tmp_path / "out"),
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
    ds, truth = _draw_above((cause,), STRONG[cause], start=11)
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


def test_the_delay_search_on_short_records_reaches_a_delay_between_its_grid_points():
    """On short records the delay is profiled on a geometric grid (about 50 % steps), then refined by Brent
    between the best point's neighbours: a planted 43 ms delay (grid points 36 and 50 ms here) on the exact
    plant is found within
    5 %. Refining only two samples either side of a grid point could not reach it."""
    from hysbench.benchmarks.diagnosis.delay import fit_delay
    ds, truth = planted_case(("delay",), "mrpim", "sines", 2, effects={"delay": {"delay_s": 0.043}})
    d = diagnose(ds, seed=0, experiments=False, extend=False)
    assert d.screen.small
    c = fit_delay(d.screen)
    assert abs(c.estimates["delay_s"] / 0.043 - 1) < 0.05, c.estimates


def test_the_delay_profile_is_scanned_where_it_is_rough_at_the_scale_of_a_sample():
    """A profile with a ripple of one sample's period on a wide valley: a bounded Brent on the bracket stops in a
    ripple minimum away from the valley's floor; the scan (every half sample) then Brent reaches the floor."""
    from scipy.optimize import minimize_scalar

    from hysbench.benchmarks.diagnosis.delay import scan_minimum
    dt, floor = 2e-3, 0.0044

    def rss(d):  # minima at floor + k dt; envelope rising away from the floor
        return ((d - floor) / 0.004) ** 2 + 0.5 * (1 - math.cos(2 * math.pi * (d - floor) / dt))

    plain = minimize_scalar(rss, bounds=(0.0038, 0.00725), method="bounded").x
    assert abs(plain - floor) > dt / 2  # the failure this guards against
    assert abs(scan_minimum(rss, 0.0038, 0.00725, dt) - floor) < dt / 20


def test_a_delay_whose_valley_lies_between_the_profile_grid_points_is_found_by_the_exact_scan():
    """Accuracy plan seed 36, case 93: a 21.9 ms delay (29 % strength) on MRPIM triangles. The exact profile
    is flat (rss 38,900) except within a sample of 21.9 ms (185): the geometric grid steps from 20.3 to 28 ms,
    the first-order profile is flat too, and the verdict was a 12 Hz mode. Scanned exactly every sample, the
    delay is found."""
    ds, truth = planted_case(("delay",), "mrpim", "triangles", 3600093)
    d = diagnose(ds, seed=0, experiments=False, extend=False)
    assert d.cause == "delay", (d.verdict.reason, [(c.cause, c.heldout, c.estimates) for c in d.candidates])
    assert parameter_errors(truth, "delay", d.parameters)["delay_s"] < 0.01


@pytest.mark.parametrize("delay_s", [0.0231, 0.012])
def test_a_delay_under_a_triangle_drive_is_found_where_the_corners_line_up(delay_s):
    """MRPIM's V'' term puts a spike at every corner of a triangle drive; delayed (in the frequency domain, by the
    planted generator) the spikes dominate the misfit, and the delay's profile is a valley about a sample wide.
    Seeded from the first-order search's minima as well as the geometric grid, the search finds it (before
    2026-11-26 a planted 23 ms delay of 29 % strength was `unexplained`, found at 26 ms)."""
    ds, truth = planted_case(("delay",), "mrpim", "triangles", 63, effects={"delay": {"delay_s": delay_s}})
    d = diagnose(ds, seed=0, experiments=False, extend=False)
    assert d.cause == "delay", (d.verdict.reason, [(c.cause, c.heldout, c.estimates) for c in d.candidates])
    assert parameter_errors(truth, "delay", d.parameters)["delay_s"] < 0.05


def test_records_without_a_nominal_frequency_scale_the_causes_by_their_drive_band():
    """Multisines (0.1-2 Hz tones, 15 s records, no ``frequency_hz``): the causes' time scale is the band's
    shortest period (about 0.4 s), not the record's duration, so a 38 Hz interference is within reach and named
    (before 2026-11-26 its search stopped at 500 / 15 s = 33 Hz and the verdict was `none`); creep's floor stays
    the records' duration."""
    ds, truth = planted_case(("interference",), "mrpim", "multisines", 5,
                             effects={"interference": {"frequency_hz": 38.0, "amplitude": 0.05}})
    assert all(r.frequency_hz is None for r in ds.records)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "interference" and d.confirmed, (d.verdict.reason, [(c.cause, c.estimates) for c in d.candidates])
    assert 0.3 < d.screen.drive_time < 0.6 and d.screen.creep_min == pytest.approx(15.0)
    # 500 / T would be about 1 kHz: a mode or a tone above the samples' Nyquist frequency is not searched
    for cause, name in (("resonance", "natural_frequency"), ("interference", "interference_frequency")):
        assert d.screen.bounds_of(d.screen.extension((cause,)), name)[1] == pytest.approx(0.5 / ds.records[0].dt)
    errors = parameter_errors(truth, "interference", d.parameters)
    assert errors["frequency_hz"] < 1e-3 and errors["amplitude"] < 0.25


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
    assert slope_where_clipped(pred, y, side, level) == pytest.approx(reference, rel=1e-9, abs=1e-12)
    assert abs(reference - true_slope) < 0.05
    assert math.isnan(slope_where_clipped(pred, y, side, 10.0 if side == "upper" else -10.0))  # never cut


def test_a_gain_modulation_is_not_named_a_clip():
    """A 2 % slow gain modulation on MRPIM multisines (accuracy plan seed 13, case 113): a censored fit removes
    most of its held-out misfit at the output's top, but there the output still rises with the model (slope
    about 0.8, where a clip leaves it flat), so the clip is outside its meaning. It had been named `saturation`
    and confirmed."""
    ds, truth = planted_case(("gain-modulation",), "mrpim", "multisines", 1300113)
    d = diagnose(ds, seed=0, experiments=False)
    clip = [c for c in d.candidates if c.cause == "saturation"][0]
    assert clip.estimates["slope_where_clipped"] > 0.5 and "not a clip" in clip.limit
    assert d.cause != "saturation"



def test_shows_clip_only_where_the_output_is_flat_at_the_level():
    """A line y = a + b t, clipped at a level: the rows show the clip at that level; unclipped rows do not show
    one at a level below their peak (the output still rises with the model there), nor at a level above it."""
    screen = SimpleNamespace(noise_sd=0.01, n_evaluations=0, solve=Screen.solve)
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
    """Where a fitted clip cuts, an output that moves against the model (slope -1.84 on an AR(1) null of the
    accuracy plan, seed 0, case 172, which had been named `saturation` as a partial cause) is no clip, as one
    that still rises with it is not; a flat top is."""
    for slope, ok in ((-1.84, False), (-0.6, False), (0.03, True), (-0.3, True), (0.81, False)):
        limit = Screen.limit_of(SimpleNamespace(), "saturation", {"slope_where_clipped": slope})
        assert (limit == "") == ok, (slope, limit)
    ds, _ = planted_case(("null-ar1",), "mrpim", "sines", 172)
    d = diagnose(ds, seed=0, experiments=False)
    clip = [c for c in d.candidates if c.cause == "saturation"][0]
    assert clip.estimates["slope_where_clipped"] < -0.5 and "not a clip" in clip.limit
    assert d.cause == "none"


def test_a_clip_is_predicted_only_from_records_that_show_it():
    """A small clip (0.4 % of the output) on MRPIM multisines (accuracy plan seed 16, case 17): one of the three
    identification records reaches the clip clearly, the other two hardly. Left out, that record was predicted
    with a level fitted on the other two, which show no flat top and put the level just under their own peaks,
    so it was cut far below its clip (held-out error x4 there) and the verdict was `none`. A fold whose records
    do not show a clip now predicts the left-out record unclipped."""
    ds, truth = planted_case(("saturation",), "mrpim", "multisines", 1600017)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause == "saturation", [(c.cause, c.heldout) for c in d.candidates]
    folds = d.chosen.uncertainty["saturation_level"]["folds"]
    assert max(folds) - min(folds) > 0.05 * truth["p2p"]  # one fold's records did not pin the level
    assert parameter_errors(truth, "saturation", d.parameters)["level_over_p2p"] <= 0.25


def test_a_held_out_gain_carried_by_one_record_alone_is_not_evidence():
    """Evidence that only the record it improves most carries (coloured noise can throw the base's extrapolation
    to one record far off) is not enough for `unexplained`; a gain spread over the records is; with two records
    nothing is left to check."""
    from hysbench.benchmarks.diagnosis.selection import Folds, carried_by_one_record

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
                                  SimpleNamespace(record=SimpleNamespace(dt=2e-3))])
    assert "shorter than one sample (2 ms)" in Screen.limit_of(fake, "delay", {"delay_s": 1.5e-3})
    assert Screen.limit_of(fake, "delay", {"delay_s": 2e-3}) == ""


def test_a_white_noise_null_is_not_named_a_sub_sample_delay():
    """A white-noise null on the Table 2 MRPIM under multisines (the fresh balanced plan of seed 29, case 139):
    a delay of 0.086 ms (0.04 of the 2 ms sample) predicted the held-out records 11 % better, in every fold,
    and was named and confirmed on validation (0.27 % of its residual removed) -- a rate term of the base's
    misfit, not a delay. It is now outside the delay's meaning, and nothing is named."""
    ds, truth = planted_case(("null-white",), "mrpim", "multisines", 2900139)
    d = diagnose(ds, seed=0, experiments=False)
    assert d.cause in ("none", "unexplained"), d.verdict.reason
    delay = next(c for c in d.candidates if c.cause == "delay")
    assert delay.estimates["delay_s"] < 2e-3 and "shorter than one sample" in delay.limit


def test_no_error_against_frequency_figure_is_drawn_for_records_without_a_drive_frequency(tmp_path):
    """Records without a nominal drive frequency (the Bouc-Wen benchmark's) would leave that figure empty (it was,
    with a warning): it is not drawn; with one it is."""
    from hysbench.benchmarks.diagnosis import report

    record = SimpleNamespace(frequency_hz=None, role="identification")
    diag = SimpleNamespace(before=[SimpleNamespace(record=record)], base_whole=[], after=[])
    path = tmp_path / "error.png"
    report.figure_error_vs_frequency(diag, path)
    assert not path.exists()
    record.frequency_hz = 1.0
    diag.before[0].scores = lambda: {"e_rms": 2.0, "e_rms_whole": 3.0}
    report.figure_error_vs_frequency(diag, path)
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
