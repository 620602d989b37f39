"""``hysbench report amplitude``: the virtual DEA's best fits driven beyond their identified voltage range.

At the identified amplitude (1 kV around 1.5 kV, 0.2 Hz, 410 s from rest) the study's drive is the dataset's
0.2 Hz validation record's, and its reference the same physics without sensor noise: its e_rms must equal the
matrix cell's own score of that record up to the scoring window and the noise (5 % relative; a wrong drive,
reference or window is off by far more)."""

import json

import pytest

from hysbench.benchmarks.cli import main
from hysbench.benchmarks.matrix.cells import plan_cells, run_cell
from hysbench.benchmarks.reports import amplitude
from hysbench.data.dataset import load_dataset
from hysbench.data.virtual_dea import default_dataset_path


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    ds = load_dataset(default_dataset_path())
    folder = tmp_path_factory.mktemp("run")
    (folder / "cells").mkdir()
    cell = run_cell(plan_cells([(str(default_dataset_path()), ds)], ["classical-pi"], ["varpro"], 0)[0])
    (folder / "cells" / "classical-pi.json").write_text(json.dumps(cell))
    return folder, cell


def test_at_the_identified_amplitude_the_study_scores_the_cells_own_validation_record(results):
    folder, cell = results
    (row,) = amplitude.study(folder)
    own = next(r["e_rms"] for r in cell["records"] if r["frequency_hz"] == amplitude.FREQUENCY_HZ)
    assert row["model"] == "classical-pi" and row["kind"] == "grey-box"
    assert row["e_rms"][1.0] == pytest.approx(own, rel=0.05)
    # beyond the identified range the rate-independent fit errs more than inside it
    assert row["e_rms"][1.25] > row["e_rms"][1.0]


def test_cli_writes_the_report_and_refuses_a_folder_without_cells(results, tmp_path, capsys):
    folder, _ = results
    assert main(["report", "amplitude", "--results", str(folder)]) == 0
    md = (folder / "amplitude_extrapolation.md").read_text()
    assert "| classical-pi (varpro) | grey-box |" in md and (folder / "erms_amplitude.png").stat().st_size > 0
    assert main(["report", "amplitude", "--results", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no cells/ folder" in err[0]


def test_a_damaged_cell_file_is_named_in_one_line(tmp_path, capsys):
    (tmp_path / "cells").mkdir()
    (tmp_path / "cells" / "a.json").write_bytes(b"\xff[1]")
    assert main(["report", "amplitude", "--results", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "a.json is not a readable cell file" in err[0]
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["a.json", "cells"]


def test_cells_of_another_actuator_named_virtual_dea_are_refused(results, tmp_path, capsys):
    """The study compares against the virtual DEA's displacement (mm): fits in another output unit that share
    the dataset's name are not driven with it."""
    _, cell = results
    (tmp_path / "cells").mkdir()
    other = json.loads(json.dumps(cell))
    other["fit"]["output_unit"] = "um"
    (tmp_path / "cells" / "mine.json").write_text(json.dumps(other))
    assert main(["report", "amplitude", "--results", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "output unit um, not the virtual DEA's mm" in err[0]
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["cells", "mine.json"]
