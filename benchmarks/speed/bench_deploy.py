"""Speed of a deployed model: the generated C, the Python stepper, the batch kernel.

* ns per step of the generated C for MRPIM with 13 plays (Table 2), compiled -O2 (goal <= 50 ns);
* the Python stepper per ``step`` call (goal <= 2 us);
* MRPIM batch ``simulate`` over the seven protocol sines, two periods each (179,500 samples),
  against the generated C of the same maths compiled -O3 running the same records (goal: batch <=
  the C loop's time).

The C is called through ctypes once per record (a loop over the record in C), so the call
overhead (microseconds) is spread over thousands of samples. Run:
``python -m pytest benchmarks/speed/bench_deploy.py --benchmark-only -s``.
"""

import ctypes
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from hysbench.data.protocol import FREQUENCIES_HZ, SAMPLE_TIME_S, paper_voltage, protocol_time
from hysbench.models import MRPIM, FittedModel
from hysbench.models.export_c import export_c

DT = SAMPLE_TIME_S
INPUTS = [np.ascontiguousarray(paper_voltage(protocol_time(f, 2), f)) for f in FREQUENCIES_HZ]
N_SAMPLES = sum(u.size for u in INPUTS)
RANGE = (0.5, 2.5)  # the protocol's input range: every record gets the same thresholds
FIT = FittedModel(MRPIM(), MRPIM().preset("paper"), RANGE, DT, {"scale": {"y": 10.0}})
CC = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")

RUNNER = """#include "dea.h"
void run_record(const double *u, double *y, long n)
{
    dea_state s;
    long i;
    dea_init(&s);
    for (i = 0; i < n; i++) y[i] = dea_step(&s, u[i]);
}
"""


def c_library(folder: Path, opt: str):
    header, source = export_c(FIT, "dea")
    (folder / "dea.h").write_text(header)
    (folder / "dea.c").write_text(source)
    (folder / "runner.c").write_text(RUNNER)
    lib = folder / f"libdea{opt}.so"
    subprocess.run([CC, "-std=c99", "-Wall", "-Werror", opt, "-fPIC", "-shared", "-o", str(lib), str(folder / "dea.c"),
                    str(folder / "runner.c"), "-lm"], check=True)
    dll = ctypes.CDLL(str(lib))
    pointer = ctypes.POINTER(ctypes.c_double)
    dll.run_record.argtypes = [pointer, pointer, ctypes.c_long]
    dll.run_record.restype = None
    outputs = [np.empty_like(u) for u in INPUTS]

    def run_protocol():
        for u, y in zip(INPUTS, outputs):
            dll.run_record(u.ctypes.data_as(pointer), y.ctypes.data_as(pointer), u.size)
        return outputs

    return run_protocol


needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler (cc, gcc or clang) on PATH")


@needs_cc
@pytest.mark.parametrize("opt", ["-O2", "-O3"])
def test_generated_c_ns_per_step(benchmark, tmp_path, opt):
    run_protocol = c_library(tmp_path, opt)
    ys = run_protocol()
    for u, y in zip(INPUTS, ys):
        np.testing.assert_allclose(y, FIT.simulate(u), rtol=0, atol=1e-9 * np.max(np.abs(y)))
    benchmark.pedantic(run_protocol, rounds=100, iterations=1, warmup_rounds=3)
    median = benchmark.stats.stats.median
    ns = median / N_SAMPLES * 1e9
    benchmark.extra_info.update(ns_per_step=ns, protocol_ms=median * 1e3)
    print(f"\ngenerated C {opt}: {ns:.1f} ns per step, protocol {median * 1e3:.3f} ms (goal <= 50 ns per step)")


def test_python_stepper_per_call(benchmark):
    stepper = FIT.stepper()
    values = INPUTS[-1][:20000].tolist()
    step = stepper.step

    def run():
        for v in values:
            step(v)

    benchmark.pedantic(run, rounds=20, iterations=1, warmup_rounds=2)
    us = benchmark.stats.stats.median / len(values) * 1e6
    benchmark.extra_info.update(us_per_step=us)
    print(f"\nPython stepper: {us:.2f} us per step call (goal <= 2 us)")


def test_batch_simulate_protocol(benchmark):
    def run():
        return [FIT.simulate(u) for u in INPUTS]

    run()
    benchmark.pedantic(run, rounds=100, iterations=1, warmup_rounds=3)
    median = benchmark.stats.stats.median
    benchmark.extra_info.update(protocol_ms=median * 1e3, ns_per_sample=median / N_SAMPLES * 1e9)
    print(f"\nbatch simulate: protocol {median * 1e3:.3f} ms, {median / N_SAMPLES * 1e9:.1f} ns per sample "
          "(goal: <= the generated C at -O3)")
