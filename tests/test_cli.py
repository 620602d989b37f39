"""The command line as one package: every command shows an example, shares its argument types,
and refuses bad input in one line with exit status 2."""

import json
import os

import pytest

from hysbench.benchmarks.cli import COMMANDS, main
from hysbench.benchmarks.cli.common import CommandError, parse_key_values, parse_method_options
from hysbench.benchmarks.cli.report import REPORTS
from hysbench.data.virtual_dea import default_dataset_path


@pytest.mark.parametrize("command", list(COMMANDS))
def test_every_command_shows_an_example(command, capsys):
    assert main([command, "--help"]) == 0
    out = capsys.readouterr().out
    assert "example:\n  hysbench " + command in out


@pytest.mark.parametrize("command", [["dataset", "init"], ["data", "virtual-dea"]])
def test_a_command_with_an_action_shows_its_example_on_the_actions_help_too(command, capsys):
    assert main([*command, "--help"]) == 0
    assert "example:\n  hysbench " + " ".join(command) in capsys.readouterr().out


@pytest.mark.parametrize("report", list(REPORTS))
def test_every_report_shows_an_example(report, capsys):
    assert main(["report", report, "--help"]) == 0
    assert f"example (every argument at its default):\n  hysbench report {report}" in capsys.readouterr().out


@pytest.mark.parametrize("argv", [["--help"], ["report", "--help"]])
def test_the_help_lists_every_report(argv, capsys):
    assert main(argv) == 0
    words = capsys.readouterr().out.split("regenerate a report: ", 1)[1].split()  # argparse wraps the line
    listed = [words[0]]
    while listed[-1].endswith(","):  # the list ends at its first word without a comma
        listed.append(words[len(listed)])
    assert [name.rstrip(",") for name in listed] == list(REPORTS)


BAD = {
    "check": (["check", "/no/such/folder"], "no/such/folder"),
    "data": (["data", "virtual-dea", "--out", "x", "--seed", "-3"], "--seed"),
    "run": (["run", "--models", "no-such-model", "--out", "{tmp}"], "no-such-model"),
    "dataset": (["dataset", "init", "{tmp}/file", "--time", "5", "--input", "1", "--output", "2"], "--time 5"),
    "posterior": (["posterior", "--model", "no-such-model", "--out", "{tmp}"], "no-such-model"),
    "reproduce": (["reproduce", "--out", "{tmp}/file/sub"], "{tmp}/file"),
    "ablate": (["ablate", "--orders", "1,x", "--out", "{tmp}"], "--orders"),
    "fit": (["fit", "--model", "mrpim", "--method", "no-such-method"], "no-such-method"),
    "export": (["export", "{tmp}/no-such-model.json", "--out", "{tmp}/c", "--prefix", "dea"], "no-such-model.json"),
    "diagnose": (["diagnose", "--model", "no-such-model", "--out", "{tmp}"], "no-such-model"),
    "compensate": (["compensate", "--models", "no-such-model", "--out", "{tmp}"], "no-such-model"),
    "report": (["report", "baselines", "--models", "no-such-model", "--out", "{tmp}/b.md"], "no-such-model"),
    "accuracy": (["accuracy", "report", "no-such-plan", "--rows", "{tmp}/rows.jsonl.gz"], "no-such-plan"),
}


@pytest.mark.parametrize("command", list(COMMANDS))
def test_bad_input_is_one_line_and_status_2(command, tmp_path, capsys):
    assert command in BAD, f"add a bad-input case for the new command {command!r}"
    (tmp_path / "file").write_text("not a folder")
    argv, named = BAD[command]
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert named.replace("{tmp}", str(tmp_path)) in err


def test_key_values_are_json_or_text():
    assert parse_key_values(["a=1", "b=[1, 2]", "c=TRUE", "d=none", "e=word", "f={\"x\": 1}"], "--option") == {
        "a": 1, "b": [1, 2], "c": True, "d": None, "e": "word", "f": {"x": 1}}
    assert parse_method_options(["mpso.iterations=5", "lsq.max_nfev=3"]) == {
        "mpso": {"iterations": 5}, "lsq": {"max_nfev": 3}}
    with pytest.raises(CommandError, match="KEY=VALUE"):
        parse_key_values(["novalue"], "--hyper")
    with pytest.raises(CommandError, match="METHOD.KEY=VALUE"):
        parse_method_options(["iterations=5"])


def test_the_default_dataset_is_the_shipped_virtual_dea():
    assert (default_dataset_path() / "dataset.toml").is_file()


DESTINATION_IS_A_FOLDER = {
    "fit": ["fit", "--model", "classical-pi", "--json", "{tmp}"],
    "fit --save": ["fit", "--model", "classical-pi", "--save", "{tmp}"],
    "diagnose": ["diagnose", "--out", "{tmp}/new", "--json", "{tmp}"],
    "posterior": ["posterior", "--model", "classical-pi", "--out", "{tmp}/new", "--json", "{tmp}"],
    "ablate": ["ablate", "--out", "{tmp}/new", "--json", "{tmp}"],
    "compensate": ["compensate", "--models", "classical-pi", "--out", "{tmp}/new", "--json", "{tmp}"],
}


@pytest.mark.parametrize("command", list(DESTINATION_IS_A_FOLDER))
def test_a_destination_that_is_a_folder_is_refused_before_any_work(command, tmp_path, capsys):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in DESTINATION_IS_A_FOLDER[command]]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"cannot write {tmp_path}: it is a folder" in err
    assert not (tmp_path / "new").exists()  # nothing created, no empty output folder left


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs a /proc file system")
def test_an_output_folder_the_system_refuses_is_named_before_any_work(capsys):
    # os.access says root may write /proc; the check writes a probe file instead
    assert main(["ablate", "--out", "/proc/hysbench-out"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "/proc is not writable" in err, err


def test_report_baselines_refuses_an_unknown_method_before_fitting_and_takes_a_folder(tmp_path, capsys):
    code = main(["report", "baselines", "--models", "classical-pi", "--methods", "nosuch", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "unknown method(s) nosuch" in err and "Traceback" not in err
    assert not (tmp_path / "baselines.md").exists()


def test_data_virtual_dea_does_not_replace_a_measured_dataset_without_force(tmp_path, capsys):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "dataset.toml").write_text('name = "mine"\n')
    (mine / "notes.md").write_text("my notes\n")
    code = main(["data", "virtual-dea", "--out", str(mine), "--excitation", "triangle"])
    err = capsys.readouterr().err
    assert code == 2 and "--force" in err
    assert (mine / "notes.md").read_text() == "my notes\n"


def test_version_is_printed(capsys):
    with pytest.raises(SystemExit) as exit_info:
        from hysbench.benchmarks.cli import build_parser
        build_parser().parse_args(["--version"])
    assert exit_info.value.code == 0 and capsys.readouterr().out.startswith("hysbench ")


@pytest.mark.parametrize("argv, named", [
    (["posterior", "--burn", "50", "--steps", "20", "--fixed-steps", "--out", "{tmp}/new"], "--burn 50"),
    (["compensate", "--references", ",", "--out", "{tmp}/new"], "--references names no reference"),
    (["run", "--unseen", "{tmp}/nosuch", "--out", "{tmp}/new"], "--unseen {tmp}/nosuch: no such dataset folder"),
])
def test_options_refused_before_any_work(argv, named, tmp_path, capsys):
    code = main([a.replace("{tmp}", str(tmp_path)) for a in argv])
    err = capsys.readouterr().err
    assert code == 2 and named.replace("{tmp}", str(tmp_path)) in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "new").exists()


def test_a_fit_keeps_its_model_file_when_its_reader_goes_away(tmp_path):
    """`hysbench fit ... --save m.json | head -1`: the model file is written before anything is printed."""
    import subprocess
    import sys

    from tiny_dataset import write_tiny_dataset

    folder = write_tiny_dataset(tmp_path / "tiny")
    saved, report = tmp_path / "m.json", tmp_path / "fit.json"
    proc = subprocess.Popen([sys.executable, "-m", "hysbench.benchmarks.cli", "fit", str(folder), "--model",
                             "classical-pi", "--method", "varpro", "--save", str(saved), "--json", str(report)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 1 and "Traceback" not in err, err
    assert json.loads(saved.read_text())["model"] == "classical-pi"
    assert json.loads(report.read_text())["model"] == "classical-pi"


@pytest.mark.parametrize("low", ["-1e3", "-1000", "-.5e1", "-2.5"])
def test_a_negative_number_in_any_form_is_read_as_a_number_not_an_option(low):
    from hysbench.benchmarks.cli import build_parser

    args = build_parser().parse_args(["export", "m.json", "--out", "c", "--prefix", "x", "--input-limits", low, "1"])
    assert args.input_limits == [float(low), 1.0]


def test_a_reader_that_goes_away_stops_the_command_without_a_traceback():
    """`hysbench check | head -1`: standard output closed by its reader is no traceback on stderr."""
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "hysbench.benchmarks.cli", "check"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # before the command writes anything: its first line meets a closed pipe
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 1
    assert "Traceback" not in err and "BrokenPipeError" not in err and "Exception ignored" not in err, err


def test_a_dataset_named_virtual_dea_in_other_units_is_not_scored_on_the_unseen_waveforms(tmp_path, capsys):
    """The waveforms drive the virtual DEA (kV -> mm); a fit of another actuator that shares its name is not
    simulated on them: --unseen is refused, the default skips them and says so."""
    from types import SimpleNamespace

    from tiny_dataset import write_tiny_dataset

    from hysbench.benchmarks.cli.run import _unseen_dataset
    from hysbench.data.dataset import load_dataset

    def dataset(name, units):
        folder = write_tiny_dataset(tmp_path / name)
        toml = folder / "dataset.toml"
        toml.write_text(toml.read_text().replace('name = "tiny"', f'name = "{name}"\ninput_unit = "{units[0]}"\n'
                                                                  f'output_unit = "{units[1]}"'))
        return folder

    mine = dataset("virtual-dea", ("V", "um"))
    drives = str(dataset("drives", ("kV", "mm")))
    datasets = [(mine, load_dataset(mine))]
    with pytest.raises(CommandError, match="is named 'virtual-dea' but in V -> um, the unseen waveforms in kV -> mm"):
        _unseen_dataset(SimpleNamespace(suite="default", unseen=drives), datasets)
    assert _unseen_dataset(SimpleNamespace(suite="default", unseen=None), datasets) is None
    assert "its fits are not scored on them" in capsys.readouterr().err
    datasets[0][1].input_unit, datasets[0][1].output_unit = "kV", "mm"
    assert _unseen_dataset(SimpleNamespace(suite="default", unseen=drives), datasets).name == "drives"
