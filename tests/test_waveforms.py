"""The unseen-waveform records of the virtual DEA: range, length, windows, and that they are the physics."""

import numpy as np
import pytest

from hysbench.data.dataset import load_dataset
from hysbench.data.dea_sensor import LaserSensor
from hysbench.data.excitations import excitation
from hysbench.data.virtual_dea import (DEFAULT_SEED, RUN_IN_HZ, RUN_IN_S, WAVEFORM_DRIVES, command_voltage,
                                       default_waveforms_path, displacement_mm, waveform_command, waveform_seed)

SHIPPED = load_dataset(default_waveforms_path())


def test_the_shipped_dataset_holds_every_drive_as_validation_records():
    assert [r.file for r in SHIPPED.records] == [f"{n}.npz" for n in WAVEFORM_DRIVES]
    assert {r.role for r in SHIPPED.records} == {"validation"}
    size = sum(p.stat().st_size for p in default_waveforms_path().iterdir())
    assert size < 12e6


@pytest.mark.parametrize("record", SHIPPED.records, ids=lambda r: r.file)
def test_a_record_is_the_run_in_then_the_drive_in_range_and_scored_on_the_drive(record):
    name = record.file.removesuffix(".npz")
    drive = excitation(name, **WAVEFORM_DRIVES[name])
    u, n_run_in = waveform_command(name)
    assert np.array_equal(record.u, u)
    assert record.t.size == n_run_in + drive.size and record.dt == pytest.approx(1e-3)
    assert RUN_IN_S <= n_run_in * 1e-3 < RUN_IN_S + 1.0 / RUN_IN_HZ
    assert (record.start, record.stop) == (n_run_in, record.t.size)  # only the unseen drive is scored
    assert u.min() >= 0.5 - 1e-4 and u.max() <= 2.5 + 1e-4
    assert np.max(np.abs(np.diff(u))) < 0.05  # no step where the run-in meets the drive
    assert np.allclose(u[n_run_in:], drive, atol=2.0**-16)
    assert np.allclose(u[:n_run_in], command_voltage(RUN_IN_HZ, n_run_in), atol=2.0**-16)


@pytest.mark.parametrize("record", SHIPPED.records, ids=lambda r: r.file)
def test_the_output_is_the_physics_measured_by_the_sensor_with_the_default_seed(record):
    name = record.file.removesuffix(".npz")
    x = displacement_mm(record.u)
    expected = LaserSensor().measure(x, np.random.default_rng(waveform_seed(DEFAULT_SEED, name)))
    assert np.array_equal(record.y, expected)
    assert np.std(record.y - x) < 0.05  # the sensor adds noise of its own size, not a different signal
