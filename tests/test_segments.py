"""Records cut to their own samples, and one record cut into segments (hysbench.data.segments)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hysbench.data.dataset import Dataset, DatasetError, Record, load_dataset
from hysbench.data.segments import own_samples, own_stretch, segment_bounds, split_records


def _recording(n, dt=0.01, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    return t, np.sin(2 * np.pi * t), rng.normal(size=n)


def _one_recording_two_windows():
    t, u, y = _recording(1000)
    ident = Record("rec#1.csv", t, u, y, role="identification", frequency_hz=1.0, window=(1.0, 7.0))
    valid = Record("rec#2.csv", t.copy(), u.copy(), y.copy(), role="validation", frequency_hz=1.0, window=(7.0, 9.0))
    t2, u2, y2 = _recording(300, seed=1)
    other = Record("other.csv", t2, u2, y2, role="identification", frequency_hz=1.0, window=(0.0, 3.0))
    return Dataset("d", [ident, valid, other])


def test_records_of_one_recording_keep_only_their_windows():
    ds = _one_recording_two_windows()
    cut = own_samples(ds)
    ident, valid, other = cut.records
    # windows from 1.0 s and 7.0 s; u = sin(2 pi t) is lowest 0.75 s later: each cut starts there
    assert np.array_equal(ident.t, ds.records[0].t[175:700]) and np.array_equal(ident.y, ds.records[0].y[175:700])
    assert np.array_equal(valid.t, ds.records[1].t[775:900]) and np.array_equal(valid.u, ds.records[1].u[775:900])
    assert (ident.start, ident.stop) == (0, 525) and (valid.start, valid.stop) == (0, 125)
    assert [r.file for r in cut.records] == ["rec#1.csv", "rec#2.csv", "other.csv"]
    assert other is ds.records[2]  # a record of its own recording is left whole
    assert ds.records[0].t.size == 1000  # the input dataset is not changed


def test_records_of_separate_recordings_are_left_as_they_are():
    ds = _one_recording_two_windows()
    ds.records[1].y[0] += 1.0  # different samples: another recording
    assert own_samples(ds) is ds


def test_the_real_piezo_recording_is_cut_at_its_validation_window(shared_datasets):
    ds = load_dataset(shared_datasets / "piezo_sindy_1hz")
    ident, valid = own_samples(ds).records
    assert ident.t[0] >= 4.3 - 1e-9 and ident.t[-1] < 7.3
    assert valid.t[0] >= 7.3 - 1e-9 and valid.t[-1] < 9.3
    assert ident.n_scored == ident.t.size and valid.n_scored == valid.t.size


@settings(max_examples=60, deadline=None)
@given(periods=st.integers(1, 12), per=st.integers(8, 40), lead=st.integers(0, 30), extra=st.data(),
       k=st.integers(2, 12))
def test_segments_are_whole_periods_that_tile_the_scored_window(periods, per, lead, extra, k):
    tail = extra.draw(st.integers(0, per - 1))
    dt = 1.0 / per  # one period = per samples at 1 Hz
    n = lead + periods * per + tail
    t = np.arange(n + 5) * dt
    r = Record("r.csv", t, np.sin(2 * np.pi * t), np.cos(t), frequency_hz=1.0, window=(lead * dt, n * dt))
    assert (r.start, r.stop) == (lead, n)
    lowest = min(r.u[lead:lead + per])
    first = next(i for i in range(lead, lead + per) if r.u[i] == lowest)
    available = (n - first) // per
    if k > available:
        with pytest.raises(DatasetError, match="whole period"):
            segment_bounds(r, k)
        return
    bounds = segment_bounds(r, k)
    assert len(bounds) == k and bounds[0][0] == first and bounds[-1][1] == r.stop
    assert all(b0[1] == b1[0] for b0, b1 in zip(bounds, bounds[1:]))
    assert all(abs(r.u[a] - lowest) < 1e-9 for a, _ in bounds)  # every part starts at an input minimum
    size = (available // k) * per
    assert all(b - a == size for a, b in bounds[:-1]) and bounds[-1][1] - bounds[-1][0] >= size


def test_without_a_frequency_segments_have_equal_sample_counts():
    t, u, y = _recording(103)
    r = Record("r.csv", t, u, y, window=(0.0, 1.03))
    assert segment_bounds(r, 4) == [(0, 25), (25, 50), (50, 75), (75, 103)]
    with pytest.raises(DatasetError, match=">= 2"):
        segment_bounds(r, 1)
    with pytest.raises(DatasetError, match="too few for 4 segments"):  # each segment needs two samples
        segment_bounds(Record("r.csv", t[:7], u[:7], y[:7], window=(0.0, 0.07)), 4)


def test_split_records_cuts_identification_only_with_distinct_keys():
    ds = own_samples(_one_recording_two_windows())
    split = split_records(ds, 2)
    keys = [r.file for r in split.records]
    assert keys == ["rec#1~1.csv", "rec#1~2.csv", "rec#2.csv", "other~1.csv", "other~2.csv"]
    first = split.records[:2]  # 5.25 periods from the cut's own minimum: 2 + 3.25 periods
    assert [r.t.size for r in first] == [200, 325]
    assert np.array_equal(np.concatenate([r.y for r in first]), ds.records[0].y)
    assert all(r.role == "identification" and r.frequency_hz == 1.0 for r in first)
    assert split.records[2] is ds.records[1]


def _windows(*windows):
    """One recording of 100 samples (dt 1) listed once per window."""
    t = np.arange(100.0)
    u = np.sin(t / 7)
    return [Record(file=f"r#{k}", t=t, u=u, y=2 * u, window=w) for k, w in enumerate(windows)]


@given(st.integers(0, 97), st.integers(2, 99))
@settings(max_examples=40, deadline=None)
def test_a_records_own_stretch_is_the_widest_run_round_its_window_no_other_record_scores(a, b):
    b = max(a + 2, b)
    mine, *others = _windows((a, b), (0, 10), (90, 100))
    stretch = own_stretch(mine, [mine, *others])
    taken = np.zeros(100, dtype=bool)
    for o in others:
        taken[o.scored] = True
    if taken[mine.scored].any():  # another record scores some of its window: the window alone
        assert stretch == mine.scored
    else:  # every sample of the stretch is free, it holds the window, and it cannot grow
        assert stretch.start <= a and stretch.stop >= b and not taken[stretch].any()
        assert stretch.start == 0 or taken[stretch.start - 1]
        assert stretch.stop == 100 or taken[stretch.stop]


def test_a_record_no_other_shares_is_its_own_stretch_whole():
    mine = _windows((20, 30))[0]
    other = Record(file="x", t=mine.t, u=mine.u, y=mine.y + 1.0, window=(50, 60))  # another recording
    assert own_stretch(mine, [mine, other]) == slice(0, 100)


def test_a_window_next_to_another_records_window_widens_away_from_it():
    """Windows that touch (one ends where the other starts) do not overlap: each stretch grows away from the
    other window, up to the record's ends."""
    left, right = _windows((20, 50), (50, 70))
    assert own_stretch(left, [left, right]) == slice(0, 50)
    assert own_stretch(right, [left, right]) == slice(50, 100)


def test_a_shared_window_too_short_for_a_period_after_its_minimum_is_kept_whole():
    """A window holding less than a whole period after its first input minimum is cut at its own start."""
    t, u, y = _recording(1000)  # u = sin(2 pi t), 100 samples per period, lowest 0.75 s into each period
    ident = Record("rec#1.csv", t, u, y, role="identification", frequency_hz=1.0, window=(1.0, 7.0))
    valid = Record("rec#2.csv", t.copy(), u.copy(), y.copy(), role="validation", frequency_hz=1.0,
                   window=(7.0, 8.5))
    cut_valid = own_samples(Dataset("d", [ident, valid])).records[1]
    assert np.array_equal(cut_valid.t, t[700:850])
