"""Speed of ``hysbench diagnose`` (issue 9): a seven-record dataset in <= 60 s on this 2-core machine.

Two seven-record datasets, each diagnosed once by the command (report and
figures included, numba caches warm):

* the paper's protocol (0.02 ... 1 Hz, two periods each: 179,500 samples)
  simulated from the Table 2 MRPIM with a planted relaxation and noise
  (``planted.planted_dataset("relaxation", 0)``);
* the virtual DEA, the default dataset (data/virtual_dea: each record runs
  through the creep transition, 2.9 million samples), when present.
"""

from pathlib import Path

import pytest

from hysbench.benchmarks.cli import main as hysbench
from hysbench.benchmarks.diagnosis.planted import planted_dataset
from hysbench.data import save_dataset

TARGET_S = 60.0
VIRTUAL_DEA = Path(__file__).resolve().parents[2] / "data" / "virtual_dea"


def _diagnose(folder, out):
    assert hysbench(["diagnose", str(folder), "--out", str(out), "--quiet"]) == 0


@pytest.fixture(scope="module")
def protocol_dataset(tmp_path_factory):
    folder = tmp_path_factory.mktemp("planted") / "ds"
    save_dataset(planted_dataset("relaxation", 0)[0], folder)
    return folder


def test_diagnose_protocol_dataset(benchmark, protocol_dataset, tmp_path):
    _diagnose(protocol_dataset, tmp_path / "warm")  # numba caches, imports
    benchmark.pedantic(_diagnose, args=(protocol_dataset, tmp_path / "out"), rounds=1, iterations=1)
    seconds = benchmark.stats.stats.median
    print(f"\nhysbench diagnose, protocol dataset (7 records, 179,500 samples): {seconds:.1f} s")
    assert seconds <= TARGET_S


def test_diagnose_virtual_dea(benchmark, tmp_path):
    if not (VIRTUAL_DEA / "dataset.toml").is_file():
        pytest.skip(f"the default dataset is not at {VIRTUAL_DEA}")
    benchmark.pedantic(_diagnose, args=(VIRTUAL_DEA, tmp_path / "out"), rounds=1, iterations=1)
    seconds = benchmark.stats.stats.median
    print(f"\nhysbench diagnose, virtual DEA (7 records, 2.9 million samples): {seconds:.1f} s")
    assert seconds <= TARGET_S
