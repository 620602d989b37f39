"""Drive waveforms: range, length, reproducibility, spectral content, refusals."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hysbench.data.excitations import (EXCITATIONS, ExcitationError, band_limited_random, decaying_sine, drive_band,
                                       excitation, multisine, reversal_curves, triangle)


@pytest.mark.parametrize("name", list(EXCITATIONS))
def test_every_named_drive_stays_in_the_dea_range(name):
    u = excitation(name)
    assert np.all(np.isfinite(u))
    assert u.min() >= 0.5 - 1e-12 and u.max() <= 2.5 + 1e-12
    assert np.max(np.abs(np.diff(u))) < 0.05  # no step at 1 kHz


@settings(max_examples=25, deadline=None)
@given(low=st.floats(-5, 5), width=st.floats(0.1, 10), seed=st.integers(0, 2**31))
def test_random_drives_span_the_range_and_repeat_with_the_seed(low, width, seed):
    high = low + width
    for make in (multisine, band_limited_random):
        u = make(duration_s=20.0, dt=0.01, low=low, high=high, seed=seed)
        assert u.min() >= low - 1e-9 * width and u.max() <= high + 1e-9 * width
        assert np.array_equal(u, make(duration_s=20.0, dt=0.01, low=low, high=high, seed=seed))


def test_band_limited_random_has_no_power_above_its_band_after_the_fade():
    dt, f_max = 1e-3, 2.0
    u = band_limited_random(duration_s=100.0, dt=dt, f_max=f_max, seed=3)
    tail = u[2000:] - u[2000:].mean()  # past the 0.5 s fade-in; the window edges leak a little
    power = np.abs(np.fft.rfft(tail * np.hanning(tail.size))) ** 2
    f = np.fft.rfftfreq(tail.size, dt)
    assert power[f > 2 * f_max].sum() < 1e-6 * power.sum()


def test_multisine_tones_are_where_they_are_asked_for():
    dt = 1e-2
    u = multisine(duration_s=500.0, dt=dt, f_min=0.1, f_max=1.0, n_tones=4, seed=1)
    tail = u[1000:] - u[1000:].mean()
    power = np.abs(np.fft.rfft(tail * np.hanning(tail.size))) ** 2
    f = np.fft.rfftfreq(tail.size, dt)
    for tone in np.geomspace(0.1, 1.0, 4):
        near = np.abs(f - tone) < 0.01
        assert power[near].max() > 100 * np.median(power)


def test_triangle_is_piecewise_linear_between_its_extremes():
    u = triangle(frequency_hz=1.0, duration_s=3.0, dt=1e-3)
    slopes = np.abs(np.diff(u)) / 1e-3
    assert np.allclose(slopes[slopes > 0.1], 4.0, rtol=1e-6)  # 2 kV up and down per second
    assert u[0] == 0.5 and np.isclose(u.max(), 2.5, atol=1e-9)


def test_decaying_sine_shrinks_to_the_final_fraction():
    u = decaying_sine(frequency_hz=1.0, duration_s=20.0, dt=1e-3, final_fraction=0.2)
    first, last = u[:1000], u[-1000:]
    assert np.isclose(np.ptp(first), 2.0, rtol=0.1)
    assert np.isclose(np.ptp(last), 0.4, rtol=0.15)


def test_reversal_curves_turn_at_evenly_spaced_points():
    u = reversal_curves(n_curves=4, rate_per_s=1.0, dt=1e-3)
    d = np.sign(np.diff(u))
    turns = u[1:-1][(d[1:] != d[:-1]) & (d[1:] != 0)]
    minima = np.sort(turns[turns < 2.5 - 1e-9])
    assert np.allclose(minima, [0.5, 1.0, 1.5, 2.0], atol=1e-9)


def test_bad_options_are_refused():
    with pytest.raises(ExcitationError, match="unknown excitation"):
        excitation("square")
    with pytest.raises(ExcitationError, match="low < high"):
        triangle(1.0, 1.0, low=2.0, high=1.0)
    with pytest.raises(ExcitationError, match="Nyquist"):
        band_limited_random(10.0, dt=0.1, f_max=6.0)
    with pytest.raises(ExcitationError, match="bad options"):
        excitation("triangle", colour="red")


@given(st.floats(0.05, 5.0), st.floats(1.5, 6.0), st.integers(0, 3))
@settings(max_examples=25, deadline=None)
def test_drive_band_of_two_tones_is_their_frequencies(f_lo, ratio, seed):
    """Two tones on whole periods of the record: the band's ends are the tones (the slow, obvious answer)."""
    dt, n = 1e-3, 20_000
    t = np.arange(n) * dt
    k_lo = max(1, int(round(f_lo * n * dt)))
    k_hi = max(k_lo + 1, int(round(k_lo * ratio)))
    phase = np.random.default_rng(seed).uniform(0, 2 * np.pi, 2)
    u = (1.5 + np.sin(2 * np.pi * k_lo / (n * dt) * t + phase[0])
         + 0.5 * np.sin(2 * np.pi * k_hi / (n * dt) * t + phase[1]))
    lo, hi = drive_band(u, dt)
    assert lo == pytest.approx(k_lo / (n * dt)) and hi == pytest.approx(k_hi / (n * dt))


@given(st.floats(0.05, 2.0), st.floats(1.5, 6.0), st.floats(0.0, 1.0), st.integers(0, 3))
@settings(max_examples=40, deadline=None)
def test_drive_band_of_tones_cut_anywhere_is_their_frequencies(f_lo, ratio, cut, seed):
    """Two tones off the record's bins, cut wherever (the record's end does not join its start): the jump the
    periodogram sees at the wrap would leak power far above the tones; the band still ends at the fast tone,
    within the bins that a tone off the grid spreads over. The low end may only err low (there leakage
    widens the band)."""
    dt = 1e-3
    n = int((20.0 + cut) / dt)
    t = np.arange(n) * dt
    phase = np.random.default_rng(seed).uniform(0, 2 * np.pi, 2)
    f_hi = f_lo * ratio
    u = 1.5 + np.sin(2 * np.pi * f_lo * t + phase[0]) + 0.5 * np.sin(2 * np.pi * f_hi * t + phase[1])
    lo, hi = drive_band(u, dt)
    bin_hz = 1.0 / (n * dt)
    assert bin_hz * 0.999 <= lo <= f_lo + 3 * bin_hz
    assert f_hi - 3 * bin_hz <= hi <= f_hi + 3 * bin_hz


def test_drive_band_of_a_multisine_spans_its_tones_and_a_constant_has_none():
    lo, hi = drive_band(multisine(60.0, 2e-3, f_min=0.1, f_max=2.0, n_tones=12, seed=1), 2e-3)
    assert 0.05 <= lo <= 0.1 and 2.0 <= hi <= 2.6  # the fade-in leaks a little power beyond the tones
    assert drive_band(np.full(500, 1.5), 1e-3) is None
