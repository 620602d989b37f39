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
    print(f"{'file':<{width}} {'role':<15} {'f (Hz)':>8} {'weight':>6} {'samples':>9} {'dt (s)':>10} {'scored':>16}")
    for r in ds.records:
        f = f"{r.frequency_hz:g}" if r.frequency_hz else "-"
        scored = f"{r.t[r.start]:.6g}-{r.t[r.stop - 1]:.6g} s"
        print(f"{r.file:<{width}} {r.role:<15} {f:>8} {r.weight:>6g} {r.t.size:>9} {r.dt:>10.4g} {scored:>16}")
    for problem in fitting_problems(ds):  # loadable, but no command can fit on it: say so
        print(f"hysbench check: warning: {problem}", file=sys.stderr)
    return 0
