"""Bad inputs against the real command line, in a temporary folder: each is refused with ONE line on stderr
naming the problem and exit status 2, never a traceback; nothing it was pointed at is changed, no file's
content is echoed, no empty output folder is left behind. Most cases call ``hysbench.benchmarks.cli.main``
in-process (the same code path as the ``hysbench`` script); a few run the real executable."""

from __future__ import annotations

import os
import socket
import stat
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pytest
from hysbench.benchmarks.cli import main as cli

from tiny_dataset import tiny_records, write_tiny_dataset

SECRET = "root:x:0:0:SECRET-FIRST-LINE"


@dataclass
class Case:
    name: str
    make: Callable[[Path], list[str]]  # builds the bad input in a temporary folder, returns the argv
    expect: str  # a phrase of the one-line message


def _tiny(root: Path, **kw) -> str:
    return str(write_tiny_dataset(root / "tiny", **kw))


def _fifo(path: Path) -> Path:
    os.mkfifo(path)
    return path


def _char_device(path: Path) -> Path:
    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 7))  # the numbers of /dev/full
    except (PermissionError, AttributeError):
        pytest.skip("cannot create a device node here")
    return path


def _socket(path: Path) -> Path:
    s = socket.socket(socket.AF_UNIX)
    s.bind(str(path))
    s.close()
    return path


def _manifest(root: Path, records: list[tuple[str, str]], extra: str = "") -> str:
    folder = root / "ds"
    folder.mkdir(exist_ok=True)
    lines = ['name = "bad"', 'time_column = "t"', 'input_column = "u"', 'output_column = "y"', extra]
    for file, role in records:
        lines += ["[[records]]", f'file = "{file}"', f'role = "{role}"']
    (folder / "dataset.toml").write_text("\n".join(lines) + "\n")
    return str(folder)


def _csv(path: Path, rows: list[str]) -> Path:
    path.write_text("t,u,y\n" + "\n".join(rows) + "\n")
    return path


def _good_rows(n: int = 50) -> list[str]:
    t = np.arange(n) * 0.01
    return [f"{float(a)!r},{float(1.5 + np.sin(7 * a))!r},{float(np.cos(5 * a))!r}" for a in t]


def _npz_claiming(path: Path, n: int) -> Path:
    """An .npz whose columns' headers claim n float64 samples each (the data themselves are not there)."""
    import zipfile

    with zipfile.ZipFile(path, "w") as zf:
        for c in ("t", "u", "y"):
            header = {"descr": "<f8", "fortran_order": False, "shape": (n,)}
            with zf.open(f"{c}.npy", "w") as fh:
                np.lib.format.write_array_header_1_0(fh, header)
                fh.write(b"\0" * 64)
    return path


def _export(model_file: Path) -> list[str]:
    return ["export", str(model_file), "--out", str(model_file.parent / "c"), "--prefix", "dea"]


def _written(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _nested_toml(root: Path) -> list[str]:
    folder = root / "deep"
    folder.mkdir()
    (folder / "dataset.toml").write_text("x = " + "[" * 5000 + "]" * 5000 + "\n")
    return ["check", str(folder)]


def _outside_record(root: Path) -> list[str]:
    (root / "secret.csv").write_text(SECRET + "\nmore\n")
    (root / "a" / "b").mkdir(parents=True)
    folder = root / "a" / "b"
    (folder / "dataset.toml").write_text('name = "x"\ntime_column = "t"\ninput_column = "u"\noutput_column = "y"\n'
                                         '[[records]]\nfile = "../../secret.csv"\nrole = "identification"\n')
    return ["check", str(folder)]


def _constant_input(root: Path) -> list[str]:
    records = {f: (t, np.full_like(u, 1.5), y) for f, (t, u, y) in tiny_records().items()}
    return ["run", str(write_tiny_dataset(root / "const", records=records)), "--models", "classical-pi",
            "--methods", "varpro", "--jobs", "1", "--out", str(root / "out")]


def _zero_weights(root: Path) -> list[str]:
    folder = write_tiny_dataset(root / "w0")
    toml = folder / "dataset.toml"
    toml.write_text(toml.read_text().replace('role = "identification"', 'role = "identification"\nweight = 0'))
    return ["run", str(folder), "--models", "classical-pi", "--methods", "varpro", "--jobs", "1",
            "--out", str(root / "out")]


CASES = [
    Case("json to a FIFO", lambda r: ["fit", _tiny(r), "--model", "classical-pi", "--json", str(_fifo(r / "p"))],
         "it is a FIFO, not a regular file"),
    Case("json to a device", lambda r: ["fit", _tiny(r), "--model", "classical-pi", "--json",
                                        str(_char_device(r / "full"))], "it is a device, not a regular file"),
    Case("json to a socket", lambda r: ["fit", _tiny(r), "--model", "classical-pi", "--json",
                                        str(_socket(r / "s"))], "it is a socket, not a regular file"),
    Case("json to a folder", lambda r: ["fit", _tiny(r), "--model", "classical-pi", "--json", str(r)],
         "it is a folder"),
    Case("TOML nested 5000 deep", _nested_toml, "nested too deeply"),
    Case("--option nested 25000 deep", lambda r: ["fit", _tiny(r), "--model", "classical-pi", "--option",
                                                  "n_starts=" + "[" * 25000 + "]" * 25000], "nested too deeply"),
    Case("--hyper nested 25000 deep", lambda r: ["fit", _tiny(r), "--model", "classical-pi", "--hyper",
                                                 "offset=" + "{\"a\":" * 25000 + "1" + "}" * 25000],
         "nested too deeply"),
    Case("no identification records", lambda r: ["run", _tiny(r, roles={"f1Hz.npz": "validation",
                                                                        "f2Hz.npz": "validation"}),
                                                 "--jobs", "1", "--out", str(r / "out")], "no identification records"),
    Case("constant input", _constant_input, "the input is constant"),
    Case("every identification record of weight 0", _zero_weights, "has weight 0"),
    Case("record outside its dataset folder", _outside_record, "must stay inside the dataset folder"),
    Case("FIFO as a record file", lambda r: ["check", _manifest(r, [(str(_fifo(r / "rec.csv")), "identification")])],
         "not a regular file"),
    Case("/dev/zero as a record file", lambda r: ["check", _manifest(r, [("/dev/zero", "identification")])],
         "not a regular file"),
    Case("an .npz expanding beyond the limit",
         lambda r: ["check", _manifest(r, [(str(_npz_claiming(r / "big.npz", 2**27)), "identification")])],
         "above the limit"),
    Case("CSV number with an underscore",
         lambda r: ["check", _manifest(r, [(str(_csv(r / "u.csv", _good_rows()[:10] + ["0.1,1_0,0.5"]
                                                     + _good_rows()[11:])), "identification")])],
         "non-numeric value on line 12, column u"),
    Case("output beyond the loader's limit", lambda r: ["check", _tiny(r, output_factor=1e200)], "beyond 1e+100"),
    Case("subnormal output", lambda r: ["check", _tiny(r, output_factor=2.0**-1070)], "subnormal"),
    Case("dataset init on a folder", lambda r: ["dataset", "init", str(r), "--time", "t", "--input", "u",
                                                "--output", "y"], "is a folder"),
    Case("posterior with no identification records",
         lambda r: ["posterior", _tiny(r, roles={"f1Hz.npz": "validation", "f2Hz.npz": "validation"}),
                    "--out", str(r / "new" / "out"), "--quiet"], "no identification records"),
    Case("report identification with no identification records",
         lambda r: ["report", "identification", _tiny(r, roles={"f1Hz.npz": "validation", "f2Hz.npz": "validation"}),
                    "--out", str(r / "new" / "out")], "no identification records"),
    Case("model file nested 100000 deep", lambda r: _export(_written(r / "m.json", "[" * 100000 + "]" * 100000)),
         "nested too deeply"),
    Case("FIFO as a model file", lambda r: _export(_fifo(r / "m.json")), "not a regular file"),
]


def _snapshot(root: Path) -> dict:
    return {p: (stat.S_IFMT(p.lstat().st_mode), p.lstat().st_size) for p in root.rglob("*")}


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_bad_input_is_one_line_and_exit_2(case, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    argv = case.make(tmp_path)
    capsys.readouterr()
    before = _snapshot(tmp_path)
    code = cli(argv)
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, f"exit {code}, stderr:\n{err}"
    assert case.expect in lines[0] and lines[0].startswith("hysbench ")
    assert "SECRET" not in err and "root:x" not in err
    assert _snapshot(tmp_path) == before  # nothing replaced, nothing written, no empty folder left


def test_check_warns_about_a_dataset_nothing_can_be_fitted_on(tmp_path, capsys):
    assert cli(["check", _tiny(tmp_path, roles={"f1Hz.npz": "validation", "f2Hz.npz": "validation"})]) == 0
    assert "warning: no identification records" in capsys.readouterr().err
    records = {f: (t, np.full_like(u, 1.5), y) for f, (t, u, y) in tiny_records().items()}
    assert cli(["check", str(write_tiny_dataset(tmp_path / "const", records=records))]) == 0
    assert "warning: the input is constant in every identification record" in capsys.readouterr().err
    folder = write_tiny_dataset(tmp_path / "w0")
    toml = folder / "dataset.toml"
    toml.write_text(toml.read_text().replace('role = "identification"', 'role = "identification"\nweight = 0'))
    assert cli(["check", str(folder)]) == 0
    assert "warning: every identification record has weight 0" in capsys.readouterr().err


def test_an_absolute_record_path_is_allowed(tmp_path, capsys):
    assert cli(["check", _manifest(tmp_path, [(str(_csv(tmp_path / "elsewhere.csv", _good_rows())),
                                               "identification")])]) == 0


def test_json_through_a_symlink_replaces_its_target_and_keeps_the_link(tmp_path, capsys):
    target = tmp_path / "target.json"
    target.write_text("old")
    link = tmp_path / "link.json"
    link.symlink_to(target)
    assert cli(["fit", _tiny(tmp_path), "--model", "classical-pi", "--json", str(link)]) == 0
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert target.read_text().startswith("{")


def test_json_dash_is_standard_output(tmp_path, capsys, monkeypatch):
    import json

    monkeypatch.chdir(tmp_path)
    assert cli(["fit", _tiny(tmp_path), "--model", "classical-pi", "--json", "-"]) == 0
    out = capsys.readouterr()
    assert json.loads(out.out)["model"] == "classical-pi" and "fitness" in out.err
    assert not (tmp_path / "-").exists()


def test_a_dataset_folder_whose_name_is_not_utf8_is_run_and_reported(tmp_path, capsys):
    name = os.fsdecode(b"tiny-\xff\xfe")
    dataset = write_tiny_dataset(tmp_path / name)
    out = tmp_path / "out"
    assert cli(["run", str(dataset), "--models", "classical-pi", "--methods", "varpro", "--jobs", "1", "--quiet",
                "--out", str(out)]) == 0
    assert b"tiny-\xff\xfe" in (out / "report.md").read_bytes()  # the path as the OS gave it


def test_real_executable_refuses_in_one_line(tmp_path):
    """The installed entry point itself, on two of the cases above (a fresh process each: no state shared)."""
    for case in (CASES[0], CASES[9]):
        root = tmp_path / case.name.replace(" ", "-")
        root.mkdir()
        argv = case.make(root)
        before = _snapshot(root)
        proc = subprocess.run([sys.executable, "-m", "hysbench.benchmarks.cli", *argv], capture_output=True,
                              text=True, timeout=120, cwd=root)
        lines = proc.stderr.strip().splitlines()
        assert proc.returncode == 2 and len(lines) == 1, proc.stderr
        assert case.expect in lines[0] and "SECRET" not in proc.stderr
        assert _snapshot(root) == before
