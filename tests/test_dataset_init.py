"""`hysbench dataset init`: a bare CSV to a loadable dataset in one command; bad columns refused."""

import os

import numpy as np
import pytest

from hysbench.benchmarks.cli import main
from hysbench.data.dataset import load_dataset


def _series(n=400, dt=0.01):
    t = np.arange(n) * dt
    u = np.sin(2 * np.pi * 1.0 * t)
    y = 0.8 * u + 0.1 * np.sign(np.cos(2 * np.pi * t))
    return t, u, y


def test_a_headerless_csv_by_index(tmp_path, capsys):
    t, u, y = _series()
    csv = tmp_path / "run1.csv"
    np.savetxt(csv, np.column_stack([np.arange(t.size), y, t, u]), delimiter=",", fmt="%.10g")  # index, y, t, u
    assert main(["dataset", "init", str(csv), "--time", "2", "--input", "3", "--output", "1", "--frequency", "1"]) == 0
    out = capsys.readouterr().out
    assert "hysbench run" in out and "scored 100 samples (3-3.99 s)" in out  # the last period, as check shows
    ds = load_dataset(tmp_path)
    rec = ds.records[0]
    assert ds.name == "run1" and rec.role == "identification" and rec.frequency_hz == 1.0
    assert np.allclose(rec.t, t) and np.allclose(rec.u, u) and np.allclose(rec.y, y)
    assert rec.n_scored == 100  # the last period of 1 Hz at 10 ms
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dataset.toml", "run1.csv"]


def test_a_csv_with_names_by_name_and_index(tmp_path):
    t, u, y = _series()
    csv = tmp_path / "sweep.csv"
    np.savetxt(csv, np.column_stack([t, u, y]), delimiter=",", header="time_s,volts,um", comments="", fmt="%.10g")
    assert main(["dataset", "init", str(csv), "--time", "time_s", "--input", "1", "--output", "um",
                 "--role", "validation", "--window", "1,3", "--name", "my-piezo", "--output-unit", "um"]) == 0
    ds = load_dataset(tmp_path)
    rec = ds.records[0]
    assert (ds.name, ds.input_column, ds.output_unit, rec.role) == ("my-piezo", "volts", "um", "validation")
    assert np.allclose(rec.y, y) and rec.n_scored == 200


@pytest.mark.parametrize("columns, named", [
    (["--time", "0", "--input", "1", "--output", "9"], "--output 9"),       # index out of range
    (["--time", "t", "--input", "1", "--output", "2"], "no header row"),    # name on a headerless CSV
    (["--time", "0", "--input", "1", "--output", "1"], "three different"),  # the same column twice
    (["--time", "1", "--input", "0", "--output", "2"], "time is not increasing"),  # the loader refuses it
])
def test_bad_columns_are_refused_in_one_line_and_nothing_is_written(tmp_path, capsys, columns, named):
    t, u, y = _series()
    csv = tmp_path / "bare.csv"
    np.savetxt(csv, np.column_stack([t, u, y]), delimiter=",", fmt="%.10g")
    assert main(["dataset", "init", str(csv), *columns]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and named in err and "Traceback" not in err
    assert [p.name for p in tmp_path.iterdir()] == ["bare.csv"]


def test_an_unknown_name_lists_the_columns_and_an_existing_manifest_is_kept(tmp_path, capsys):
    t, u, y = _series()
    csv = tmp_path / "named.csv"
    np.savetxt(csv, np.column_stack([t, u, y]), delimiter=",", header="t,u,y", comments="", fmt="%.10g")
    assert main(["dataset", "init", str(csv), "--time", "t", "--input", "volts", "--output", "y"]) == 2
    assert "no such column (has t, u, y)" in capsys.readouterr().err
    (tmp_path / "dataset.toml").write_text("keep me")
    assert main(["dataset", "init", str(csv), "--time", "t", "--input", "u", "--output", "y"]) == 2
    assert "--force" in capsys.readouterr().err and (tmp_path / "dataset.toml").read_text() == "keep me"


def test_a_frequency_at_or_above_nyquist_is_refused_and_nothing_is_written(tmp_path, capsys):
    t, u, y = _series()  # 10 ms: Nyquist 50 Hz
    csv = tmp_path / "bare.csv"
    np.savetxt(csv, np.column_stack([t, u, y]), delimiter=",", fmt="%.10g")
    assert main(["dataset", "init", str(csv), "--time", "0", "--input", "1", "--output", "2",
                 "--frequency", "1e6"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Nyquist frequency 50 Hz" in err
    assert [p.name for p in tmp_path.iterdir()] == ["bare.csv"]


@pytest.mark.parametrize("input_column", ["volt", "1"])  # by name or by index
def test_a_column_name_twice_in_the_header_is_refused(tmp_path, capsys, input_column):
    t, u, y = _series()
    csv = tmp_path / "dup.csv"
    np.savetxt(csv, np.column_stack([t, u, y]), delimiter=",", header="time,volt,volt", comments="", fmt="%.10g")
    assert main(["dataset", "init", str(csv), "--time", "time", "--input", input_column, "--output", "2"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "2 columns 'volt'" in err
    assert [p.name for p in tmp_path.iterdir()] == ["dup.csv"]


def test_a_loader_refusal_names_the_file_once(tmp_path, capsys):
    csv = tmp_path / "ragged.csv"
    csv.write_text("t,u,y\n0,1,2\n0.001,1.1\n")
    assert main(["dataset", "init", str(csv), "--time", "t", "--input", "u", "--output", "y"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "unequal length" in err
    assert err.count("ragged.csv") == 1, err  # the file is named once, not once per layer


@pytest.mark.parametrize("file_name, extra, named", [
    (b"run-\xff.csv", [], "the CSV's file name run-"),
    (b"run.csv", ["--name", os.fsdecode(b"x\xff")], "--name is not valid UTF-8"),
    (b"run.csv", ["--output-unit", os.fsdecode(b"\xb5m")], "--output-unit is not valid UTF-8"),
])
def test_a_name_a_utf8_manifest_cannot_hold_is_named_and_nothing_is_written(tmp_path, capsys, file_name, extra, named):
    t, u, y = _series()
    csv = tmp_path / os.fsdecode(file_name)
    np.savetxt(csv, np.column_stack([t, u, y]), delimiter=",", header="t,u,y", comments="")
    assert main(["dataset", "init", str(csv), "--time", "t", "--input", "u", "--output", "y", *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and named in err and "is not valid UTF-8" in err, err
    assert [p.name for p in tmp_path.iterdir()] == [csv.name]


def test_check_keeps_its_columns_aligned_for_a_long_file_name(tmp_path, capsys):
    t, u, y = _series()
    csv = tmp_path / ("a_long_measurement_file_name_" * 2 + ".csv")
    np.savetxt(csv, np.column_stack([t, u, y]), delimiter=",", header="t,u,y", comments="", fmt="%.10g")
    assert main(["dataset", "init", str(csv), "--time", "t", "--input", "u", "--output", "y", "--frequency", "1"]) == 0
    capsys.readouterr()
    assert main(["check", str(tmp_path)]) == 0
    header, row = capsys.readouterr().out.splitlines()[1:3]
    assert header.index("role") == row.index("identification")
    assert len(header) == len(row)


def test_two_datasets_with_one_name_are_refused_naming_both_folders_and_the_fix(tmp_path, capsys):
    """Two CSV files called run1.csv in two folders get the same dataset name from dataset init."""
    t, u, y = _series()
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        csv = tmp_path / folder / "run1.csv"
        np.savetxt(csv, np.column_stack([t, u, y]), delimiter=",", header="t,u,y", comments="", fmt="%.10g")
        assert main(["dataset", "init", str(csv), "--time", "t", "--input", "u", "--output", "y"]) == 0
    capsys.readouterr()
    status = main(["run", str(tmp_path / "a"), str(tmp_path / "b"), "--models", "classical-pi",
                   "--methods", "varpro", "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert status == 2 and len(err.strip().splitlines()) == 1
    assert "share the name 'run1'" in err and "dataset.toml" in err
    assert str(tmp_path / "a") in err and str(tmp_path / "b") in err
    assert not (tmp_path / "out").exists()


def test_a_csv_that_is_not_utf8_is_named_as_such_and_nothing_is_written(tmp_path, capsys):
    t, u, y = _series()
    csv = tmp_path / "run.csv"
    csv.write_bytes(("t,u,y (µm)\n" + "".join(f"{a},{b},{c}\n" for a, b, c in zip(t, u, y))).encode("latin-1"))
    assert main(["dataset", "init", str(csv), "--time", "0", "--input", "1", "--output", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "run.csv: is not UTF-8 text (byte 0xb5 on line 1" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv"]


def test_a_tab_separated_csv_is_named_and_read_with_a_typed_tab(tmp_path, capsys):
    t, u, y = _series()
    csv = tmp_path / "run.csv"
    np.savetxt(csv, np.column_stack([t, u, y]), delimiter="\t", header="t\tu\ty", comments="", fmt="%.10g")
    args = ["dataset", "init", str(csv), "--time", "t", "--input", "u", "--output", "y"]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--time 't': no such column" in err[0]
    assert "looks separated by '\\t': pass --delimiter 'tab'" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv"]
    for typed in ("\\t", "tab"):
        assert main(args + ["--delimiter", typed, "--force"]) == 0
        assert np.allclose(load_dataset(tmp_path).records[0].y, y)


def test_check_shows_each_records_ranges_so_a_record_in_another_unit_stands_out(tmp_path, capsys):
    t, u, y = _series()
    lines = ['name = "two"', 'time_column = "t"', 'input_column = "u"', 'output_column = "y"']
    for name, scale in (("um.csv", 1.0), ("m.csv", 1e-6)):
        np.savetxt(tmp_path / name, np.column_stack([t, u, y * scale]), delimiter=",", header="t,u,y", comments="")
        lines += ["[[records]]", f'file = "{name}"', 'role = "identification"']
    (tmp_path / "dataset.toml").write_text("\n".join(lines) + "\n")
    assert main(["check", str(tmp_path)]) == 0
    header, first, second = capsys.readouterr().out.splitlines()[1:4]
    assert header.endswith("output range, scored") and len(header) == len(first) == len(second)
    assert first.endswith(f"{y.min():.4g} to {y.max():.4g}") and second.endswith(f"{y.min() * 1e-6:.4g} to "
                                                                              f"{y.max() * 1e-6:.4g}")


@pytest.mark.parametrize("name", ["piezo \U0001F600", "\U0001D707-stage", "del\x7fchar", "tab\tand \"quote\""])
def test_any_unicode_name_is_written_as_valid_toml(tmp_path, capsys, name):
    """A character beyond U+FFFF (JSON would write it as a surrogate pair, which TOML refuses) or a DEL (which
    TOML must see escaped) in --name or the file name."""
    t, u, y = _series()
    csv = tmp_path / f"run{name[0]}{name[-1]}.csv"
    np.savetxt(csv, np.column_stack([t, u, y]), delimiter=",", header="t,u,y", comments="")
    assert main(["dataset", "init", str(csv), "--time", "t", "--input", "u", "--output", "y", "--name", name]) == 0
    ds = load_dataset(tmp_path)
    assert ds.name == name and ds.records[0].file == csv.name
