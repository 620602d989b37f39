"""Speed of ``hysbench ablate`` on the default dataset (the virtual DEA).

Target: the whole command (load, 33 variants x (1 full + 7 leave-one-frequency-out)
varpro fits, outputs) <= 120 s wall with its default ``--jobs`` (all cores) on
the 2-core reference machine.

The load average before and after and the CPU time (this process and its
workers) are recorded: on a shared machine the wall time says little without
them (CPU time / cores is what the wall time would be on free cores).
"""

import os
import resource
import time

from hysbench.benchmarks.ablation import run_ablation
from hysbench.data.virtual_dea import default_dataset_path as default_dataset
from hysbench.benchmarks.cli import main as cli_main
from hysbench.data.dataset import load_dataset

TARGET_S = 120.0


def cpu_seconds() -> float:
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def test_ablate_default_dataset(benchmark, tmp_path):
    folder = default_dataset()
    # warm the numba cache and imports (not timed): one small variant
    run_ablation(load_dataset(folder), orders=(4,), factors=("order",), grid=False, jobs=1)
    load_before = os.getloadavg()
    cpu0 = cpu_seconds()
    t0 = time.perf_counter()
    code = benchmark.pedantic(cli_main, args=(["ablate", "--out", str(tmp_path / "out"), "--quiet"],),
                              rounds=1, iterations=1)
    wall = time.perf_counter() - t0
    cpu = cpu_seconds() - cpu0
    load_after = os.getloadavg()
    assert code == 0
    benchmark.extra_info.update(dataset=str(folder), wall_s=wall, cpu_s=cpu, load_before=load_before,
                                load_after=load_after, cores=os.cpu_count())
    print(f"\nhysbench ablate {folder.name}: {wall:.1f} s wall, {cpu:.1f} s CPU (load average "
          f"{load_before[0]:.1f} -> {load_after[0]:.1f}, {os.cpu_count()} cores)")
    assert wall <= TARGET_S
