"""Drive waveforms: range, length, reproducibility, spectral content, refusals."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hysbench.data.excitations import (EXCITATIONS, ExcitationError, band_limited_random, decaying_sine,
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
