"""The dataset format: round trips, defaults, and one test per refused case."""

import re
from pathlib import Path

import numpy as np
import pytest

from hysbench.benchmarks.cli import main
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


@pytest.mark.parametrize("ending", ["\n", "\r\n", "\r"])
@pytest.mark.parametrize("header", ["t,u,y", "t, u, y"])
def test_any_line_ending_and_spaces_after_the_header_commas_read_the_same_samples(tmp_path, ending, header):
    t = np.arange(1000) * 1e-3
    u = np.sin(4 * np.pi * t)
    rows = [header] + [f"{a:.17g},{b:.17g},{2 * b:.17g}" for a, b in zip(t, u)]
    (tmp_path / "r.csv").write_bytes((ending.join(rows) + ending).encode())
    (tmp_path / "dataset.toml").write_text(HEADER + GOOD)
    r = load_dataset(tmp_path).records[0]
    assert np.array_equal(r.t, t) and np.array_equal(r.u, u) and np.array_equal(r.y, 2 * u)


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
    with pytest.raises(DatasetError, match=r"r.csv: column u holds NaN or inf \(first on line 11\)"):
        load_dataset(folder)


@pytest.mark.parametrize("header_row", [True, False])
@pytest.mark.parametrize("cell, refused", [("oops", "non-numeric value on line {line}, column u"),
                                           ("nan", r"column u holds NaN or inf \(first on line {line}\)"),
                                           ("", "empty cell on line {line}, column u")])
def test_a_bad_cell_is_named_by_the_line_an_editor_shows_it_on(tmp_path, header_row, cell, refused):
    """Counting the header row and the blank lines the loader skips, whichever message names it."""
    t = np.arange(1000) * 1e-3
    lines = [f"{a:.17g},{np.sin(4 * np.pi * a):.17g},{2 * np.sin(4 * np.pi * a):.17g}" for a in t]
    lines[40] = f"{t[40]:.17g},{cell},1.0"
    lines.insert(5, "")
    if header_row:
        lines.insert(0, "t,u,y")
    (tmp_path / "r.csv").write_text("\r\n".join(lines) + "\r\n")
    columns = "" if header_row else 'csv_columns = ["t", "u", "y"]\n'
    (tmp_path / "dataset.toml").write_text(HEADER + columns + GOOD)
    line = lines.index(f"{t[40]:.17g},{cell},1.0") + 1
    with pytest.raises(DatasetError, match=refused.format(line=line)):
        load_dataset(tmp_path)


@pytest.mark.parametrize("separator", [";", "\t"])
def test_a_header_separated_otherwise_is_refused_with_the_separator_it_looks_like(tmp_path, separator):
    lines = [separator.join(("t", "u", "y"))] + [separator.join((f"{k * 1e-3:g}", "1.0", "2.0")) for k in range(50)]
    (tmp_path / "r.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "dataset.toml").write_text(HEADER + GOOD)
    with pytest.raises(DatasetError, match=f"missing column.*separated by {re.escape(repr(separator))}"):
        load_dataset(tmp_path)


def test_refuses_inf_in_npz(tmp_path):
    t = np.arange(1000) * 1e-3
    y = np.ones(1000)
    y[5] = np.inf
    np.savez(tmp_path / "r.npz", t=t, u=t, y=y)
    (tmp_path / "dataset.toml").write_text(HEADER + GOOD.replace("r.csv", "r.npz"))
    with pytest.raises(DatasetError, match=r"r.npz: column y holds NaN or inf \(first at sample 5\)"):
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
    with pytest.raises(DatasetError, match=r"r.csv: time is not increasing \(on line 22\)"):
        load_dataset(folder)


def test_refuses_time_not_uniform(tmp_path):
    t = np.arange(1000) * 1e-3
    t[500:] += 0.015e-3  # one step of 1.015 ms: 1.5 % off the median, just beyond the tolerance
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


def test_cli_reports_refusal_in_one_line(tmp_path, capsys):
    folder = make(tmp_path, GOOD.replace("identification", "training"))
    assert main(["check", str(folder)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "role must be" in err and "Traceback" not in err
    ok = make(tmp_path, GOOD)
    assert main(["check", str(ok)]) == 0 and "r.csv" in capsys.readouterr().out


@pytest.mark.parametrize("frequency", ["500.0", "1e6"])  # Nyquist of a 1 ms step is 500 Hz
def test_refuses_frequency_at_or_above_nyquist(tmp_path, capsys, frequency):
    refuse(tmp_path, "r.csv: frequency_hz .* Hz is at or above the Nyquist frequency 500 Hz",
           record_toml=GOOD.replace("2.0", frequency))
    assert main(["check", str(tmp_path)]) == 2  # refused in one line: a default window would be empty
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Nyquist" in err


@pytest.mark.parametrize("frequency, samples", [("1e-300", "1e+303"), ("1e-320", "more than 1e308")])
def test_refuses_a_period_too_long_in_plain_numbers(tmp_path, frequency, samples):
    msg = refuse(tmp_path, "r.csv: record is shorter than a period", record_toml=GOOD.replace("2.0", frequency))
    assert f"is {samples} samples" in msg and len(msg) < 200


def test_refuses_output_constant_in_scored_window(tmp_path):
    t = np.arange(1000) * 1e-3
    u = np.sin(2 * np.pi * 2.0 * t)
    y = np.where(t < 0.5, u, 3.0)  # varies in the warm-up, constant in the last period
    write_csv(tmp_path / "r.csv", t, u, y)
    (tmp_path / "dataset.toml").write_text(HEADER + GOOD)
    with pytest.raises(DatasetError, match=r"r.csv: output is constant in the scored window.*e_m and e_rms"):
        load_dataset(tmp_path)


@pytest.mark.parametrize("column", ["u", "y"])
def test_refuses_values_whose_squares_overflow(tmp_path, column):
    """1e308 is refused: max - min of the output would be inf, and an input of 1e308 would give parameter bounds
    near 1e-306."""
    t = np.arange(1000) * 1e-3
    u = np.sin(2 * np.pi * 2.0 * t)
    big = 1e308 * np.sign(u)
    write_csv(tmp_path / "r.csv", t, big if column == "u" else u, big if column == "y" else u)
    (tmp_path / "dataset.toml").write_text(HEADER + GOOD)
    with pytest.raises(DatasetError, match=f"r.csv: column {column} holds .* beyond 1e\\+100 in magnitude"):
        load_dataset(tmp_path)


@pytest.mark.parametrize("first, second", [("time", "input"), ("input", "output"), ("time", "output")])
def test_refuses_the_same_column_for_two_roles(tmp_path, first, second):
    names = {"time": "t", "input": "u", "output": "y"}
    header = HEADER.replace(f'{second}_column = "{names[second]}"', f'{second}_column = "{names[first]}"')
    refuse(tmp_path, f"dataset.toml: {first}_column and {second}_column are the same column '{names[first]}'",
           record_toml=GOOD, header=header)


def _sine_columns(n=1000, dt=1e-3, f=2.0, extra=1):
    """t, u, extra zero columns, y: a 2 Hz sine record as CSV columns."""
    t = np.arange(n) * dt
    u = np.sin(2 * np.pi * f * t)
    return np.column_stack([t, u, *[np.zeros(n)] * extra, 2 * u])


def test_refuses_a_used_column_name_twice_in_the_header(tmp_path):
    np.savetxt(tmp_path / "r.csv", _sine_columns(), delimiter=",", header="t,u,u,y", comments="")
    (tmp_path / "dataset.toml").write_text(HEADER + GOOD)
    with pytest.raises(DatasetError, match="r.csv: column name 'u' appears 2 times in the header row"):
        load_dataset(tmp_path)
    # a duplicate name the manifest does not use is harmless
    np.savetxt(tmp_path / "r.csv", _sine_columns(extra=2), delimiter=",", header="t,u,x,x,y", comments="")
    load_dataset(tmp_path)


def test_refuses_a_used_column_name_twice_in_csv_columns(tmp_path):
    np.savetxt(tmp_path / "r.csv", _sine_columns(), delimiter=",")
    (tmp_path / "dataset.toml").write_text(HEADER + 'csv_columns = ["t", "u", "u", "y"]\n' + GOOD)
    with pytest.raises(DatasetError, match="r.csv: column name 'u' appears 2 times in csv_columns"):
        load_dataset(tmp_path)


def test_refuses_whitespace_only_csv_as_empty(tmp_path):
    folder = make(tmp_path, GOOD)
    (folder / "r.csv").write_text("   \n  \n")
    with pytest.raises(DatasetError, match="r.csv: empty record .*no header row and no data"):
        load_dataset(folder)


def test_refuses_a_folder_in_place_of_a_record_file(tmp_path):
    folder = make(tmp_path, GOOD, csv=False)
    (folder / "r.csv").mkdir()
    with pytest.raises(DatasetError, match="r.csv: is a folder, not a record file"):
        load_dataset(folder)


def test_refuses_a_complex_npz_column(tmp_path):
    t = np.arange(1000) * 1e-3
    np.savez(tmp_path / "r.npz", t=t, u=np.sin(t) + 1j * np.cos(t), y=np.sin(t))
    (tmp_path / "dataset.toml").write_text(HEADER + GOOD.replace("r.csv", "r.npz"))
    with pytest.raises(DatasetError, match="r.npz: column u is complex"):
        load_dataset(tmp_path)


def test_one_file_listed_twice_gives_two_records_each_scored_in_its_own_role(tmp_path):
    """One recording, an identification and a validation window (the shared piezo dataset's layout): a record's
    file name is its key everywhere, so each window must get its own key and be scored in its own role."""
    from hysbench.identification import identify
    from hysbench.models import get_model

    toml = ('\n[[records]]\nfile = "r.csv"\nfrequency_hz = 2.0\nrole = "identification"\nwindow = [0.0, 1.0]\n'
            '\n[[records]]\nfile = "r.csv"\nfrequency_hz = 2.0\nrole = "validation"\nwindow = [1.0, 1.5]\n')
    ds = load_dataset(make(tmp_path, toml, n=2000))
    assert [r.file for r in ds.records] == ["r#1.csv", "r#2.csv"]
    assert ds.record("r#2.csv").role == "validation" and ds.record("r#2.csv").start == 1000
    fit = identify(get_model("classical-pi"), ds, method="varpro", seed=0)
    assert fit.fitted_on == ["r#1.csv"]
    assert [(s.file, s.role) for s in fit.records] == [("r#1.csv", "identification"), ("r#2.csv", "validation")]


@pytest.mark.parametrize("change", ["extra field", "missing unused field"])
def test_refuses_a_ragged_row_even_in_columns_it_does_not_use(tmp_path, change):
    """A row with a field more or fewer than the header is a malformed file, whichever column it hits."""
    t = np.arange(1000) * 1e-3
    u = np.sin(2 * np.pi * 2.0 * t)
    (tmp_path / "r.csv").write_text("t,u,y,note\n" + "\n".join(f"{a!r},{b!r},{2 * b!r},0" for a, b in zip(t, u)) + "\n")
    lines = (tmp_path / "r.csv").read_text().splitlines()
    lines[30] = lines[30] + ",7" if change == "extra field" else lines[30].rsplit(",", 1)[0]
    (tmp_path / "r.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "dataset.toml").write_text(HEADER + GOOD)
    with pytest.raises(DatasetError, match=r"unequal length \(line 31 has"):
        load_dataset(tmp_path)


def test_refuses_a_validation_window_that_overlaps_the_identification_window_of_the_same_file(tmp_path):
    toml = ('\n[[records]]\nfile = "r.csv"\nfrequency_hz = 2.0\nrole = "identification"\nwindow = [0.0, 1.0]\n'
            '\n[[records]]\nfile = "r.csv"\nfrequency_hz = 2.0\nrole = "validation"\nwindow = [0.5, 1.5]\n')
    with pytest.raises(DatasetError, match="r.csv: its validation window overlaps its identification window"):
        load_dataset(make(tmp_path, toml, n=2000))


@pytest.mark.parametrize("row", [500, 999])
def test_a_hash_in_a_column_it_does_not_use_keeps_its_row(tmp_path, row):
    """'#' starts no comment: a spreadsheet's '#N/A' in another column leaves the row's numbers read."""
    t = np.arange(1000) * 1e-3
    u = np.sin(2 * np.pi * 2.0 * t)
    rows = [f"ok,{a!r},{b!r},{2 * b!r}" for a, b in zip(t.tolist(), u.tolist())]
    rows[row] = "#N/A," + rows[row].split(",", 1)[1]
    (tmp_path / "r.csv").write_text("note,t,u,y\n" + "\n".join(rows) + "\n")
    (tmp_path / "dataset.toml").write_text(HEADER + GOOD)
    r = load_dataset(tmp_path).records[0]
    assert r.t.size == 1000 and r.u[row] == u[row]
    rows[row] = rows[row].replace("#N/A,", "ok,", 1).rsplit(",", 1)[0] + ",#N/A"  # in a column it uses
    (tmp_path / "r.csv").write_text("note,t,u,y\n" + "\n".join(rows) + "\n")
    with pytest.raises(DatasetError, match=f"non-numeric value on line {row + 2}, column y"):
        load_dataset(tmp_path)


@pytest.mark.parametrize("encode, named", [
    (lambda text: text.replace("y", "y (µm)", 1).encode("latin-1"), "is not UTF-8 text (byte 0xb5 on line 1"),
    (lambda text: text.encode("utf-16"), "is UTF-16 text"),
    (lambda text: b"PK\x03\x04\x14\x00\x06\x00\x08\x00\x00\x00!\x00\xff", "is a zip archive (an .xlsx workbook?)")])
def test_a_csv_that_is_not_utf8_is_named_as_such(tmp_path, encode, named):
    folder = make(tmp_path, GOOD)
    (folder / "r.csv").write_bytes(encode((folder / "r.csv").read_text()))
    with pytest.raises(DatasetError, match=re.escape(f"r.csv: {named}")):
        load_dataset(folder)


def test_a_decimal_comma_and_space_aligned_columns_are_named(tmp_path):
    t = np.arange(1000) * 1e-3
    u = np.sin(4 * np.pi * t)
    (tmp_path / "r.csv").write_text("t;u;y\n" + "\n".join(f"{a:.6f};{b:.6f};{2 * b:.6f}".replace(".", ",")
                                                         for a, b in zip(t, u)) + "\n")
    (tmp_path / "dataset.toml").write_text(HEADER + 'delimiter = ";"\n' + GOOD)
    with pytest.raises(DatasetError, match="line 2, column t; numbers take a decimal point, not a comma"):
        load_dataset(tmp_path)
    (tmp_path / "r.csv").write_text("t u y\n" + "\n".join(f"{a:9.6f} {b:9.6f} {2 * b:9.6f}" for a, b in zip(t, u)) + "\n")
    (tmp_path / "dataset.toml").write_text(HEADER + 'delimiter = " "\n' + GOOD)
    with pytest.raises(DatasetError, match="line 2 has .* fields are separated by runs of spaces"):
        load_dataset(tmp_path)


def test_a_record_file_given_as_the_dataset_is_named_a_file(tmp_path):
    folder = make(tmp_path, GOOD)
    with pytest.raises(DatasetError, match=r"r.csv: a file, not a dataset folder .*hysbench dataset init"):
        load_dataset(folder / "r.csv")


def test_a_quoted_field_holding_the_delimiter_shifts_no_column(tmp_path):
    """A quoted field is one field whatever it holds: '"1,234,567,890"' (a number with thousands separators)
    does not split into four, so the columns after it are read from their own fields."""
    t = np.arange(1000) * 1e-3
    u = np.sin(4 * np.pi * t)
    rows = [f"{a!r},{k},{b!r},{2 * b!r}" for k, (a, b) in enumerate(zip(t.tolist(), u.tolist()))]
    rows[10] = f'{t.tolist()[10]!r},"1,234,567,890",{u.tolist()[10]!r},{2 * u.tolist()[10]!r}'
    (tmp_path / "r.csv").write_text("t,idx,u,y\n" + "\n".join(rows) + "\n")
    (tmp_path / "dataset.toml").write_text(HEADER + GOOD)
    r = load_dataset(tmp_path).records[0]
    assert r.u[10] == u[10] and r.y[10] == 2 * u[10]
