"""``experiment.one_drive``: whether every record shares one periodic drive, under which a delay, a lag or a mode
only reshapes the response's harmonics (the diagnosis then says so: ``Diagnosis.one_drive_caution``)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy import signal

from hysbench.benchmarks.diagnosis.experiment import SAME_DRIVE, one_drive
from hysbench.data.dataset import Record

DT = 1e-3


def _record(name, u, frequency_hz=1.0, role="identification"):
    t = np.arange(u.size) * DT
    return Record(name, t, u, np.zeros_like(u), role=role, frequency_hz=frequency_hz)


def _sine(amplitude=1.0, offset=0.0, frequency_hz=1.0, phase=0.0, periods=4):
    t = np.arange(int(periods * round(1.0 / (frequency_hz * DT)))) * DT
    return offset + amplitude * np.sin(2 * np.pi * frequency_hz * t + phase)


def test_three_records_of_one_sine_share_one_drive_whatever_their_phase():
    records = [_record("a.npz", _sine()), _record("b.npz", _sine(phase=1.0)),
               _record("c.npz", _sine(phase=2.0), role="validation")]
    drive = one_drive(records)
    assert drive is not None and drive["frequency_hz"] == 1.0 and drive["records"] == 3
    assert drive["input_low"] == pytest.approx(-1.0, abs=1e-3) and drive["input_high"] == pytest.approx(1.0, abs=1e-3)
    assert one_drive(records[::-1]) == pytest.approx(drive)


def test_a_record_with_part_of_a_period_beyond_its_whole_ones_shares_the_drive():
    """As the last segment of a recording cut with --segments: 2.39 periods of the same sine (the part period
    alone would shift the quantiles by more than the tolerance)."""
    u = _sine(periods=3)[:2390]
    assert abs(np.quantile(u, 0.5)) > 0.2  # over all of it the median moves by a tenth of the range
    part = Record("b~2.npz", np.arange(u.size) * DT, u, np.zeros_like(u), frequency_hz=1.0, start=0, stop=u.size)
    assert part.scored == slice(0, u.size)  # scored whole, as a segment is
    assert one_drive([_record("a.npz", _sine(periods=2)), part]) is not None


def test_another_frequency_waveform_level_or_a_record_without_a_frequency_is_another_drive():
    sine = _record("a.npz", _sine())
    t = np.arange(4000) * DT
    triangle = _record("t.npz", signal.sawtooth(2 * np.pi * t, 0.5))  # the same frequency and range
    assert one_drive([sine, triangle]) is None
    assert one_drive([sine, _record("f.npz", _sine(frequency_hz=2.0), frequency_hz=2.0)]) is None
    assert one_drive([sine, _record("o.npz", _sine(offset=0.2))]) is None
    assert one_drive([sine, _record("n.npz", _sine(), frequency_hz=None)]) is None
    assert one_drive([]) is None


@settings(max_examples=60, deadline=None)
@given(ratio=st.floats(0.5, 2.0))
def test_two_centred_sines_are_one_drive_exactly_when_their_amplitudes_are_within_the_tolerance(ratio):
    """For centred sines of amplitudes 1 and r the quantiles differ most at the extremes, by |r - 1| of the
    common extreme, over a width of 2 max(1, r) of it: one drive iff |r - 1| <= 2 SAME_DRIVE max(1, r), i.e.
    r in [1 - 2 s, 1 / (1 - 2 s)] (the tolerance s = SAME_DRIVE)."""
    lo, hi = 1.0 - 2 * SAME_DRIVE, 1.0 / (1.0 - 2 * SAME_DRIVE)
    assume(min(abs(ratio - lo), abs(ratio - hi)) >= 2e-3)  # at the edge a sampled sine's quantiles decide
    same = one_drive([_record("a.npz", _sine()), _record("b.npz", _sine(amplitude=ratio))]) is not None
    assert same == (lo <= ratio <= hi)
