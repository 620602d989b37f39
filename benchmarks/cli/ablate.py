"""``hysbench ablate DATASET``: which parts of MRPIM earn their parameters (see ``ablation``)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from hysbench.data.dataset import load_dataset

from hysbench.benchmarks.ablation import N_OPERATORS, ORDERS, AblationError, run_ablation
from hysbench.benchmarks.reports.ablation import write_outputs
from hysbench.data.files import ensure_dir

from .common import add_dataset_argument, add_jobs_argument, add_seed_argument, check_outputs, dataset_paths

EXAMPLE = "hysbench ablate data/virtual_dea --orders 1,2,4 --operators 7,13 --no-grid"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_dataset_argument(parser)
    parser.add_argument("--out", default="results", help="folder for ablation.md, ablation.json, ablation.png "
                                                          "(default: results/)")
    parser.add_argument("--json", metavar="FILE", help="also write the JSON here")
    add_jobs_argument(parser)
    add_seed_argument(parser, what="the varpro candidates")
    parser.add_argument("--orders", default=",".join(map(str, ORDERS)),
                        help=f"polynomial orders (default {','.join(map(str, ORDERS))})")
    parser.add_argument("--operators", default=",".join(map(str, N_OPERATORS)),
                        help=f"numbers of play operators (default {','.join(map(str, N_OPERATORS))})")
    parser.add_argument("--no-grid", action="store_true", help="skip the full grid order x q x envelopes")
    parser.add_argument("--full-records", action="store_true",
                        help="fit the records whole (no trimming of periodic history before the windows)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")


def _integers(text: str, what: str, minimum: int) -> list[int]:
    try:
        values = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise AblationError(f"--{what} must be comma-separated integers, got {text!r}") from None
    if not values or any(v < minimum for v in values):
        raise AblationError(f"--{what} needs integers >= {minimum}, got {text!r}")
    return sorted(set(values))


def main(args: argparse.Namespace) -> int:
    jobs = (os.cpu_count() or 1) if args.jobs is None else args.jobs
    orders = _integers(args.orders, "orders", 0)
    if max(orders) > 12:
        raise AblationError(f"--orders: the model allows orders up to 12, got {max(orders)}")
    n_ops = _integers(args.operators, "operators", 1)
    dataset = load_dataset(dataset_paths(args.dataset)[0])
    check_outputs(args)

    def progress(variant, row):
        if not args.quiet:
            cv = row.get("cv_folds") or []
            cv_mean = sum(f["e_rms"] for f in cv) / len(cv) if cv else float("nan")
            print(f"  {variant.name:<16} {row['n_params']:>3} params  fit {row['fit_seconds']:6.2f} s  "
                  f"cv {row.get('cv_seconds', 0.0):6.2f} s  cv e_rms {cv_mean:7.3f} %", file=sys.stderr)

    result = run_ablation(dataset, orders=orders, n_operators=n_ops, grid=not args.no_grid, seed=args.seed,
                          jobs=jobs, trim=not args.full_records, progress=progress)
    out = ensure_dir(args.out)
    if args.json:
        ensure_dir(Path(args.json).resolve().parent)
    paths = write_outputs(result, out, args.json)
    if not args.quiet:
        for line in result["conclusions"]:
            print(line)
        t = result["timing"]
        print(f"{t['n_variants']} variants, {t['n_fits']} fits in {t['total_seconds']:.1f} s; wrote "
              f"{', '.join(str(p) for p in paths)}")
    return 0
