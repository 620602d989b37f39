"""The Python snippets of README.md's "In Python" section and of docs/api.md run as written; the Python
blocks of the other docs pages are compiled (syntax-checked) only, because they are fragments that use
names a reader supplies (``u``, ``dt``, a saved ``m.json``) or take minutes (a posterior, a diagnosis of
the default dataset)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
PYTHON = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
RUN = {"README.md": "## In Python", "docs/api.md": None}  # page -> the section whose snippets run (None: all)


def python_blocks(page: str, section: str | None = None) -> list[str]:
    text = (ROOT / page).read_text(encoding="utf-8")
    if section is not None:
        text = text.split(section + "\n", 1)[1].split("\n## ", 1)[0]
    return PYTHON.findall(text)


def write_csv_records(folder: Path, files: list[str]) -> None:
    """Short 1 Hz records with a header row ``t,u,y``: three periods of a sine drive and a lagging response."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    t = np.arange(300) * 0.01
    u = 1.5 + np.sin(2 * np.pi * t - np.pi / 2)
    for file in files:
        y = 0.45 * u + 0.05 * u**2 + 0.12 * np.sin(2 * np.pi * t - 0.6) + 0.004 * rng.standard_normal(t.size)
        np.savetxt(folder / file, np.c_[t, u, y], delimiter=",", header="t,u,y", comments="")


def run_blocks(blocks: list[str], where: str) -> None:
    namespace: dict = {"__name__": "__snippet__"}
    for i, block in enumerate(blocks):
        exec(compile(block, f"{where} block {i + 1}", "exec"), namespace)


def test_the_api_page_runs_as_written(tmp_path, monkeypatch, capsys):
    """docs/api.md: the script from a CSV file (``my-actuator`` holds run1.csv and run2.csv, as it says), then
    the matrix on the folder it wrote."""
    blocks = python_blocks("docs/api.md")
    assert len(blocks) == 2
    monkeypatch.chdir(tmp_path)
    write_csv_records(tmp_path / "my-actuator", ["run1.csv", "run2.csv"])
    run_blocks(blocks, "docs/api.md")
    out = capsys.readouterr().out
    assert "run2.csv: validation, e_m" in out and "mrpim varpro ok" in out and "classical-pi varpro ok" in out
    assert (tmp_path / "fit.json").is_file() and (tmp_path / "my-results" / "cells").is_dir()


def test_the_readme_python_section_runs_as_written(tmp_path, monkeypatch, capsys):
    """README.md: on a folder with the two identification records and the validation record that
    ``hb.diagnose`` needs (the README says so below the snippet)."""
    blocks = python_blocks("README.md", RUN["README.md"])
    assert len(blocks) == 1
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "my-actuator"
    write_csv_records(folder, ["run1.csv", "run2.csv", "run3.csv"])
    roles = {"run1.csv": "identification", "run3.csv": "identification", "run2.csv": "validation"}
    (folder / "dataset.toml").write_text('name = "my-actuator"\ntime_column = "t"\ninput_column = "u"\n'
                                         'output_column = "y"\n' + "".join(
                                             f'\n[[records]]\nfile = "{f}"\nfrequency_hz = 1.0\nrole = "{r}"\n'
                                             for f, r in roles.items()))
    namespace: dict = {}
    exec(compile(blocks[0], "README.md", "exec"), namespace)
    assert "run2.csv validation" in capsys.readouterr().out
    assert isinstance(namespace["diag"].cause, str)
    assert {r["model"] for r in namespace["rows"]} == {"mrpim", "classical-pi"}
    assert namespace["y"].shape == namespace["ds"].records[0].u.shape


SYNTAX_ONLY = [(page.relative_to(ROOT).as_posix(), i, block)
               for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
               for i, block in enumerate(python_blocks(page.relative_to(ROOT).as_posix()))]


@pytest.mark.parametrize("page,index,block", SYNTAX_ONLY, ids=[f"{p}-{i + 1}" for p, i, _ in SYNTAX_ONLY])
def test_every_python_block_of_the_docs_compiles(page, index, block):
    compile(block, f"{page} block {index + 1}", "exec")
