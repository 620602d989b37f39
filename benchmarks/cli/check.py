"""``hysbench check DATASET``: load a dataset, refuse it in one line, or summarise it."""

from __future__ import annotations

import argparse

import sys

from hysbench.data.dataset import fitting_problems, load_dataset

from .common import add_dataset_argument, dataset_paths

EXAMPLE = "hysbench check ../shared/datasets/piezo_sindy_1hz"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_dataset_argument(parser)


def main(args) -> int:
    ds = load_dataset(dataset_paths(args.dataset)[0])
    print(f"{ds.name}: {len(ds.records)} records ({len(ds.identification)} identification, "
          f"{len(ds.validation)} validation); input {ds.input_unit or '?'}, output {ds.output_unit or '?'}")
    width = max([28, *(len(r.file) for r in ds.records)])  # a long file name keeps the columns aligned
    # the ranges show a record in another unit or scale than the others (one output_unit serves them all)
    ranges = {r.file: (f"{r.u.min():.4g} to {r.u.max():.4g}", f"{r.y[r.scored].min():.4g} to {r.y[r.scored].max():.4g}")
              for r in ds.records}
    wu = max([len("input range"), *(len(u) for u, _ in ranges.values())])
    wy = max([len("output range, scored"), *(len(y) for _, y in ranges.values())])
    print(f"{'file':<{width}} {'role':<15} {'f (Hz)':>8} {'weight':>6} {'samples':>9} {'dt (s)':>10} {'scored':>16} "
          f"{'input range':>{wu}} {'output range, scored':>{wy}}")
    for r in ds.records:
        f = f"{r.frequency_hz:g}" if r.frequency_hz else "-"
        scored = f"{r.t[r.start]:.6g}-{r.t[r.stop - 1]:.6g} s"
        u_range, y_range = ranges[r.file]
        print(f"{r.file:<{width}} {r.role:<15} {f:>8} {r.weight:>6g} {r.t.size:>9} {r.dt:>10.4g} {scored:>16} "
              f"{u_range:>{wu}} {y_range:>{wy}}")
    for problem in fitting_problems(ds):  # loadable, but no command can fit on it: say so
        print(f"hysbench check: warning: {problem}", file=sys.stderr)
    return 0
