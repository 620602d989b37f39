"""The dataset format: round trips, defaults, and one test per refused case."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hysbench.data import Dataset, DatasetError, Record, load_dataset, save_dataset

HEADER = """name = "test"
description = "a test dataset"
time_column = "t"
input_column = "u"
output_column = "y"
input_unit = "V"
output_unit = "um"
"""


def write_csv(path: Path, t, u, y, header="t,u,y"):
    rows = "\n".join(f"{a:.17g},{b:.17g},{c:.17g}" for a, b, c in zip(t, u, y))
    path.write_text(header + "\n" + rows + "\n")


def make(tmp_path: Path, record_toml: str, n=1000, dt=1e-3, f=2.0, header=HEADER, csv=True) -> Path:
    t = np.arange(n) * dt
    u = np.sin(2 * np.pi * f * t)
    y = 2 * u
    if csv:
        write_csv(tmp_path / "r.csv", t, u, y)
    (tmp_path / "dataset.toml").write_text(header + record_toml)
    return tmp_path


GOOD = '\n[[records]]\nfile = "r.csv"\nfrequency_hz = 2.0\nrole = "identification"\nweight = 4\n'


def test_good_dataset_loads_with_last_period_default(tmp_path):
    ds = load_dataset(make(tmp_path, GOOD))
    r = ds.records[0]
    assert (ds.name, ds.input_unit, r.weight, r.role) == ("test", "V", 4.0, "identification")
    assert r.dt == pytest.approx(1e-3)
    assert (r.start, r.stop) == (500, 1000)  # last full period of 2 Hz at 1 ms
    assert ds.identification == [r] and ds.validation == []


def test_window_selects_samples(tmp_path):
    ds = load_dataset(make(tmp_path, GOOD + "window = [0.25, 0.75]\n"))
    r = ds.records[0]
    assert (r.start, r.stop) == (250, 750)
    # a window may end where the record ends (end exclusive)
    ds = load_dataset(make(tmp_path, GOOD + "window = [0.5, 1.0]\n"))
    assert (ds.records[0].start, ds.records[0].stop) == (500, 1000)


def test_aperiodic_record_scored_whole(tmp_path):
    ds = load_dataset(make(tmp_path, '\n[[records]]\nfile = "r.csv"\nrole = "validation"\n'))
    r = ds.records[0]
    assert (r.start, r.stop, r.weight) == (0, 1000, 1.0)


def test_round_trip_npz_and_csv(tmp_path):
    t = np.arange(300) * 0.01
    recs = [Record(file="a.npz", t=t, u=np.cos(t), y=np.sin(t), role="identification", frequency_hz=1.0, weight=2),
            Record(file="b.csv", t=t, u=np.cos(t), y=np.sin(t), role="validation", window=(0.5, 2.5))]
    ds = Dataset(name="rt", records=recs, input_unit="kV", output_unit="mm", description='quote " and \\ slash')
    save_dataset(ds, tmp_path / "out")
    back = load_dataset(tmp_path / "out")
    assert back.description == ds.description
    for a, b in zip(recs, back.records):
        assert (a.file, a.role, a.frequency_hz, a.weight, a.start, a.stop) == (
            b.file, b.role, b.frequency_hz, b.weight, b.start, b.stop)
        np.testing.assert_allclose(b.y, a.y, rtol=1e-9)
    assert back.content_hash() == load_dataset(tmp_path / "out").content_hash()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary left behind


def test_headerless_csv_with_csv_columns(tmp_path):
    """Like the measured piezo file: no header, an empty leading column."""
    t = np.arange(600) * 2e-4
    rows = "\n".join(f",{a:.17g},{2 * np.sin(a):.17g},{np.sin(a):.17g}" for a in t)
    (tmp_path / "p.csv").write_text(rows + "\n")
    (tmp_path / "dataset.toml").write_text(
        'name = "p"\ntime_column = "t"\ninput_column = "V"\noutput_column = "x"\n'
        'csv_columns = ["index", "t", "x", "V"]\n[[records]]\nfile = "p.csv"\nrole = "identification"\n')
    r = load_dataset(tmp_path).records[0]
    np.testing.assert_allclose(r.u, np.sin(t))


# --- refused cases: one test each -------------------------------------------------
def refuse(tmp_path, match, **kw):
    folder = make(tmp_path, **kw)
    with pytest.raises(DatasetError, match=match) as info:
        load_dataset(folder)
    assert "\n" not in str(info.value)
    return str(info.value)


def test_refuses_missing_dataset_toml(tmp_path):
    with pytest.raises(DatasetError, match="no such dataset"):
        load_dataset(tmp_path)


def test_refuses_invalid_toml(tmp_path):
    refuse(tmp_path, "not valid TOML", record_toml="[[records]\n")


def test_refuses_unknown_top_key(tmp_path):
    refuse(tmp_path, "unknown key.*colour", record_toml=GOOD, header=HEADER + 'colour = "red"\n')


def test_refuses_unknown_record_key(tmp_path):
    refuse(tmp_path, "unknown key.*freq", record_toml=GOOD + "freq = 3\n")


def test_refuses_missing_top_key(tmp_path):
    refuse(tmp_path, "missing key.*output_column", record_toml=GOOD,
           header=HEADER.replace('output_column = "y"\n', ""))


def test_refuses_missing_record_key(tmp_path):
    refuse(tmp_path, "missing key.*role", record_toml='\n[[records]]\nfile = "r.csv"\n')


def test_refuses_missing_file(tmp_path):
    msg = refuse(tmp_path, "file not found", record_toml=GOOD.replace("r.csv", "nope.csv"))
    assert "nope.csv" in msg


def test_refuses_missing_column(tmp_path):
    refuse(tmp_path, "r.csv: missing column.*y", record_toml=GOOD,
           header=HEADER.replace('output_column = "y"', 'output_column = "z"').replace('"z"', '"y2"'))


def test_refuses_nan(tmp_path):
    folder = make(tmp_path, GOOD)
    text = (folder / "r.csv").read_text().splitlines()
    text[10] = "0.009,nan,1.0"
    (folder / "r.csv").write_text("\n".join(text))
    with pytest.raises(DatasetError, match="r.csv: column u holds NaN or inf"):
        load_dataset(folder)


def test_refuses_inf_in_npz(tmp_path):
    t = np.arange(1000) * 1e-3
    y = np.ones(1000)
    y[5] = np.inf
    np.savez(tmp_path / "r.npz", t=t, u=t, y=y)
    (tmp_path / "dataset.toml").write_text(HEADER + GOOD.replace("r.csv", "r.npz"))
    with pytest.raises(DatasetError, match="r.npz: column y holds NaN or inf"):
        load_dataset(tmp_path)


def test_refuses_empty_record(tmp_path):
    folder = make(tmp_path, GOOD)
    (folder / "r.csv").write_text("t,u,y\n")
    with pytest.raises(DatasetError, match="r.csv: empty record"):
        load_dataset(folder)


def test_refuses_record_shorter_than_a_period(tmp_path):
    refuse(tmp_path, "r.csv: record is shorter than a period", record_toml=GOOD.replace("2.0", "0.5"))


def test_refuses_time_not_increasing(tmp_path):
    folder = make(tmp_path, GOOD)
    lines = (folder / "r.csv").read_text().splitlines()
    lines[20], lines[21] = lines[21], lines[20]
    (folder / "r.csv").write_text("\n".join(lines))
    with pytest.raises(DatasetError, match="r.csv: time is not increasing"):
        load_dataset(folder)


def test_refuses_time_not_uniform(tmp_path):
    t = np.arange(1000) * 1e-3
    t[500:] += 0.5e-3  # one step of 1.5 ms
    write_csv(tmp_path / "r.csv", t, np.sin(t), t)
    (tmp_path / "dataset.toml").write_text(HEADER + GOOD)
    with pytest.raises(DatasetError, match="r.csv: time step is not uniform.*tolerance 1%"):
        load_dataset(tmp_path)


def test_accepts_jitter_within_tolerance(tmp_path):
    t = np.arange(1000) * 1e-3 + np.random.default_rng(0).uniform(-2e-6, 2e-6, 1000)
    write_csv(tmp_path / "r.csv", t, np.sin(t), t)
    (tmp_path / "dataset.toml").write_text(HEADER + GOOD)
    load_dataset(tmp_path)


def test_refuses_window_outside_record(tmp_path):
    refuse(tmp_path, r"r.csv: window \[0.5, 3\] s is outside", record_toml=GOOD + "window = [0.5, 3.0]\n")


def test_refuses_reversed_window(tmp_path):
    refuse(tmp_path, "window start", record_toml=GOOD + "window = [0.6, 0.5]\n")


def test_refuses_unequal_columns_csv(tmp_path):
    folder = make(tmp_path, GOOD)
    lines = (folder / "r.csv").read_text().splitlines()
    lines[30] = lines[30].rsplit(",", 1)[0]
    (folder / "r.csv").write_text("\n".join(lines))
    with pytest.raises(DatasetError, match="r.csv: columns of unequal length"):
        load_dataset(folder)


def test_refuses_unequal_columns_npz(tmp_path):
    np.savez(tmp_path / "r.npz", t=np.arange(1000) * 1e-3, u=np.zeros(1000), y=np.zeros(999))
    (tmp_path / "dataset.toml").write_text(HEADER + GOOD.replace("r.csv", "r.npz"))
    with pytest.raises(DatasetError, match="r.npz: columns of unequal length"):
        load_dataset(tmp_path)


def test_refuses_unknown_role(tmp_path):
    refuse(tmp_path, "r.csv: role must be", record_toml=GOOD.replace("identification", "training"))


def test_refuses_bad_weight(tmp_path):
    refuse(tmp_path, "weight must", record_toml=GOOD.replace("weight = 4", 'weight = "heavy"'))


def test_npz_with_pickles_is_refused(tmp_path):
    np.savez(tmp_path / "r.npz", t=np.arange(1000) * 1e-3, u=np.array([{}] * 1000, dtype=object), y=np.zeros(1000))
    (tmp_path / "dataset.toml").write_text(HEADER + GOOD.replace("r.csv", "r.npz"))
    with pytest.raises(DatasetError, match="r.npz"):
        load_dataset(tmp_path)


def test_cli_reports_refusal_in_one_line(tmp_path):
    folder = make(tmp_path, GOOD.replace("identification", "training"))
    proc = subprocess.run([sys.executable, "-m", "hysbench.benchmarks.cli", "check", str(folder)],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "role must be" in proc.stderr and "Traceback" not in proc.stderr
    ok = make(tmp_path, GOOD)
    proc = subprocess.run([sys.executable, "-m", "hysbench.benchmarks.cli", "check", str(ok)],
                          capture_output=True, text=True)
    assert proc.returncode == 0 and "r.csv" in proc.stdout
