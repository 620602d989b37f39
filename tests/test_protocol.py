"""Metrics (eq. 9-10), loop geometry, the protocol and `hysbench reproduce`."""

import json

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hysbench.benchmarks.cli import main as hysbench
from hysbench.data import metrics, protocol
from hysbench.models import get_model


def test_e_m_and_e_rms_by_hand():
    ya = np.array([0.0, 1.0, 2.0, 3.0, 4.0])  # peak-to-peak 4
    y = ya + np.array([0.0, 0.4, -0.2, 0.0, 0.0])
    assert metrics.e_m(y, ya) == pytest.approx(10.0)  # 0.4 / 4
    assert metrics.e_rms(y, ya) == pytest.approx(100 * np.sqrt(0.2 / 5) / 4)


def test_fitness_is_eq9():
    y1, ya1 = np.array([1.0, 2.0]), np.array([1.0, 1.0])  # mean sq 0.5
    y2, ya2 = np.zeros(4), np.full(4, 2.0)  # mean sq 4
    assert metrics.fitness([y1, y2], [ya1, ya2], [4, 1]) == pytest.approx(4 * 0.5 + 4)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=1, max_size=6))
def test_power_of_two_scale_is_the_power_of_two_at_or_below_the_largest_finite_magnitude(values):
    s = metrics.power_of_two_scale(values)
    finite = [abs(v) for v in values if math.isfinite(v)]
    peak = max(finite, default=0.0)
    if peak == 0.0:
        assert s == 1.0
        return
    assert math.frexp(s)[0] == 0.5 and s <= peak < 2 * s  # 2^e <= peak < 2^(e+1)


def test_input_range_covers_every_record():
    """The operators' thresholds follow the input range of all fitted records, not of one of them."""
    from hysbench.data.dataset import Record

    t = np.arange(100) * 0.01
    records = [Record(f"r{k}.csv", t, lo + (hi - lo) * np.sin(np.pi * t) ** 2, t, frequency_hz=None)
               for k, (lo, hi) in enumerate([(0.5, 2.5), (-1.0, 1.0), (0.0, 4.0)])]
    want = (min(float(r.u.min()) for r in records), max(float(r.u.max()) for r in records))
    assert protocol.input_range(records) == want
    assert want[0] < float(records[0].u.min()) and want[1] > float(records[0].u.max())


def test_loop_width_of_an_ellipse():
    """u = cos, y = b sin: the vertical opening is 2b at the centre."""
    phi = np.linspace(0, 2 * np.pi, 20001)[:-1]
    u, y = 1.5 - np.cos(phi), 0.3 * np.sin(phi) + 2 * (1.5 - np.cos(phi))
    assert metrics.loop_width(u, y) == pytest.approx(0.6, rel=1e-4)
    assert metrics.peak_to_peak(y) == pytest.approx(np.ptp(y))
    # a rate-independent single-valued curve has no opening
    assert metrics.loop_width(u, u**2) == pytest.approx(0.0, abs=1e-6)


def test_protocol_constants_match_table1():
    assert protocol.FREQUENCIES_HZ == (0.02, 0.05, 0.1, 0.2, 0.4, 0.8, 1.0)
    assert protocol.IDENTIFICATION_WEIGHTS == {0.02: 4, 0.1: 1, 0.4: 4, 1.0: 1}
    assert [protocol.period_samples(f) for f in (0.02, 0.1, 0.4, 1.0)] == [50000, 10000, 2500, 1000]  # n_m
    total = sum(2 * protocol.period_samples(f) for f in protocol.FREQUENCIES_HZ)
    assert total == 179500
    v = protocol.paper_voltage(np.array([0.0, 12.5, 25.0]), 0.02)
    np.testing.assert_allclose(v, [0.5, 1.5, 2.5], atol=1e-12)


def test_scores_of_a_known_error_on_the_scored_window():
    """A prediction off by a constant c on a record's scored window scores e_m = e_rms = 100 c / ptp
    of the measured window (eq. 10), and records keep the roles of Table 1."""
    model = get_model("mrpim")
    truth = model.preset("paper")
    ds = protocol.simulated_dataset(model, truth, n_periods=1.2, frequencies=(0.4, 0.8, 1.0))
    shifted = {**truth, "offset": truth["offset"] + 0.05}
    scores = protocol.score_records(model, shifted, ds.records)
    assert [s.role for s in scores] == ["identification", "validation", "identification"]
    for s, r in zip(scores, ds.records):
        window = r.y[r.scored]
        assert s.e_m == pytest.approx(100 * 0.05 / (window.max() - window.min()), rel=1e-9)
        assert s.e_rms == pytest.approx(s.e_m, rel=1e-9)
    assert ds.records[0].n_scored == 2500  # the last whole period of 0.4 Hz at 1 kHz


def test_reproduce_writes_report(tmp_path, capsys):
    assert hysbench(["reproduce", "--out", str(tmp_path)]) == 0, capsys.readouterr().err
    r = json.loads((tmp_path / "paper_reproduction.json").read_text())
    assert set(r["frequencies"]) == {"0.02", "0.05", "0.1", "0.2", "0.4", "0.8", "1"}
    # the stable (second) period's peak-to-peak, computed here from a plain simulation
    model = get_model("mrpim", offset=False)
    p2p = {}
    for f in (0.02, 1.0):
        n = int(round(1 / (f * 1e-3)))
        u = 1.5 + np.sin(2 * np.pi * f * np.arange(2 * n) * 1e-3 - np.pi / 2)
        y = model.simulate(u, 1e-3, model.preset("paper"))[n:]
        p2p[f] = y.max() - y.min()
        assert r["frequencies"][f"{f:g}"]["p2p"] == pytest.approx(p2p[f], rel=1e-9)
    assert r["p2p_change_pct"] == pytest.approx(100 * (p2p[1.0] - p2p[0.02]) / p2p[0.02], rel=1e-9)
    assert r["p2p_change_pct"] == pytest.approx(-40.3, abs=0.05)  # docs/interpretations.md: the paper says -27.26
    assert "width_change_pct" in r and (tmp_path / "paper_reproduction.md").is_file()


def test_reproduce_unwritable_output_is_one_line(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    status = hysbench(["reproduce", "--out", str(blocker / "sub")])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "Traceback" not in err
