"""Speed of ``hysbench diagnose``: a seven-record dataset in <= 60 s on this 2-core machine.

Two seven-record datasets, each diagnosed once by the command (report and
figures included, numba caches warm):

* the paper's protocol (0.02 ... 1 Hz, two periods each: 179,500 samples)
  simulated from the Table 2 MRPIM with a first-order relaxation and white
  noise (planted with ``planted.low_pass_convolution``);
* the virtual DEA, the default dataset (data/virtual_dea: each record runs
  through the creep transition, 2.9 million samples), when present.
"""


import pytest

import numpy as np

from hysbench.benchmarks.cli import main as hysbench
from hysbench.benchmarks.diagnosis_accuracy.planted import low_pass_convolution
from hysbench.data import save_dataset
from hysbench.data.dataset import Dataset, Record
from hysbench.data.virtual_dea import default_dataset_path
from hysbench.data.protocol import FREQUENCIES_HZ, SAMPLE_TIME_S, paper_voltage, protocol_time, role_of, weight_of
from hysbench.models import get_model

TARGET_S = 60.0
VIRTUAL_DEA = default_dataset_path()


def _diagnose(folder, out):
    assert hysbench(["diagnose", str(folder), "--out", str(out), "--quiet"]) == 0


@pytest.fixture(scope="module")
def protocol_dataset(tmp_path_factory):
    folder = tmp_path_factory.mktemp("planted") / "ds"
    model, rng = get_model("mrpim"), np.random.default_rng(0)
    params, records = model.preset("paper"), []
    for f in FREQUENCIES_HZ:
        t = protocol_time(f, 2, SAMPLE_TIME_S)
        u = paper_voltage(t, f)
        y = model.simulate(u, SAMPLE_TIME_S, params) + 0.3 * low_pass_convolution(u, SAMPLE_TIME_S, 2.0)
        records.append(Record(f"f{f:g}Hz.npz", t, u, y + rng.normal(0, 0.01, t.size), role=role_of(f),
                              frequency_hz=f, weight=weight_of(f)))
    save_dataset(Dataset(name="protocol-relaxation", records=records, input_unit="kV", output_unit="mm"), folder)
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
