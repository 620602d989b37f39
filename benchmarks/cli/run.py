"""``hysbench run``: every model x identifier on every dataset, resumable and parallel.

Two suites. ``default``: the given datasets (the virtual DEA by default), written to
matrix.csv and report.md; cells identified on the virtual DEA's seven sines are also
scored, from their stored Fits, on the unseen waveforms (``--unseen``), a second table
in report.md and matrix_unseen.csv. ``measured``: every dataset folder holding a
dataset.toml under ``--datasets-root`` (default ../shared/datasets beside the
repository), written to matrix_measured.csv and report_measured.md with its own cells
cache; a folder without a manifest gets a one-line hint naming ``hysbench dataset init``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from pathlib import Path

from hysbench.data.files import ensure_dir, shown
from hysbench.data.dataset import DatasetError, fitting_problems, load_dataset, shared_datasets_root
from hysbench.data.virtual_dea import default_waveforms_path
from hysbench.models.errors import HysbenchError

from hysbench.benchmarks.matrix.cells import (DEFAULT_METHODS, code_fingerprint, method_options, package_version,
                                              plan_cells)
from hysbench.benchmarks.matrix.execute import run_matrix
from hysbench.benchmarks.matrix.report import seconds_per_cell, write_matrix_csv, write_report
from hysbench.benchmarks.matrix.store import CellStore
from hysbench.benchmarks.matrix import measured, unseen

from .common import (CommandError, add_dataset_argument, add_jobs_argument, add_seed_argument, comma_list,
                     dataset_paths, parse_method_options)

EXAMPLE = ("hysbench run data/virtual_dea --models mrpim,classical-pi --methods varpro,lsq --option lsq.max_nfev=60\n"
           "  hysbench run --suite measured --datasets-root ../shared/datasets")


def budget_lines(options: dict, cells, full_budget: bool) -> list[str]:
    """The report's statement of every cell's budget: the identifiers' options, and for the learners
    (``native``, which no identifier option bounds) the hyperparameters that set their training."""
    budget = "the identifiers' own defaults" if full_budget else "the matrix's default budget"
    lines = ["", f"Identifier options ({budget} and any `--option`): "
             + (", ".join(f"{m}.{k}={v}" for m, o in options.items() for k, v in o.items()) or "none")
             + ". Budgets are part of each cell's key: a rerun with other options recomputes."]
    learners = sorted({(c.model, c.hyperparameters) for c in cells if c.method == "native"})
    if learners:
        lines += ["", "Learners (`native`) train by their own library, bounded by their hyperparameters, not by an "
                  "identifier option: " + "; ".join(f"{m} {h}" for m, h in learners) + "."]
    return lines


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_dataset_argument(parser, many=True)
    parser.add_argument("--models", help="comma-separated model names (default: the registry's matrix models)")
    parser.add_argument("--methods", help="comma-separated identifiers (default: every one that applies)")
    parser.add_argument("--out", default="results", help="output folder (default: results/)")
    add_jobs_argument(parser)
    add_seed_argument(parser)
    parser.add_argument("--dask", metavar="ADDRESS", help="run the cells on this Dask scheduler instead")
    parser.add_argument("--option", action="append", default=[], metavar="METHOD.KEY=VALUE",
                        help="an identifier option, e.g. mpso.iterations=50 (repeatable)")
    parser.add_argument("--full-budget", action="store_true",
                        help="the identifiers' own default budgets instead of the matrix's (much slower)")
    parser.add_argument("--force", action="store_true", help="recompute cells that are already finished")
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    parser.add_argument("--suite", choices=("default", "measured"), default="default",
                        help="default: the DATASET folders; measured: every dataset under --datasets-root")
    parser.add_argument("--datasets-root", metavar="DIR", help="folder of dataset folders for --suite measured "
                        "(default: ../shared/datasets beside the repository)")
    parser.add_argument("--unseen", metavar="DIR", help="unseen-waveform dataset scored with the Fits of the cells "
                        f"identified on {unseen.IDENTIFIED_ON} (default: data/virtual_dea_waveforms; 'none': skip)")


def _shown(path: Path) -> str:
    """A dataset folder as the report shows it: relative to the working folder when inside it."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def _suite_datasets(args) -> tuple[list, list[str]]:
    """(path, dataset) pairs of the chosen suite and the lines naming folders it skipped."""
    if args.suite == "default":
        if args.datasets_root:
            raise CommandError("--datasets-root applies to --suite measured only")
        paths = dataset_paths(args.dataset)
        for p in paths:
            if p.is_dir() and not (p / "dataset.toml").is_file():
                raise CommandError(measured.init_hint(p))  # a bare folder of CSV files: name the next command
        return [(p, load_dataset(p)) for p in paths], []
    if args.dataset:
        raise CommandError("--suite measured takes no DATASET; it scores every dataset under --datasets-root")
    root = Path(args.datasets_root) if args.datasets_root else shared_datasets_root()
    if not root.is_dir():
        raise CommandError(f"--datasets-root {root} is not a folder")
    found, skipped = measured.discover(root)
    if not found:
        raise CommandError(f"no folder under {root} holds a dataset.toml" + (f" ({skipped[0]})" if skipped else ""))
    return found, skipped


def _unseen_dataset(args, datasets):
    if args.suite != "default" or (args.unseen or "").lower() == "none":
        return None
    if args.unseen and not Path(args.unseen).exists():
        raise CommandError(f"--unseen {args.unseen}: no such dataset folder")
    if not any(ds.name == unseen.IDENTIFIED_ON for _, ds in datasets):
        if args.unseen:
            raise CommandError(f"--unseen needs cells identified on {unseen.IDENTIFIED_ON!r}; no such dataset is run")
        return None
    try:
        waveforms = load_dataset(args.unseen or default_waveforms_path())
    except DatasetError as exc:
        raise CommandError(f"--unseen: {exc}") from None
    units = (waveforms.input_unit, waveforms.output_unit)
    for path, ds in datasets:  # the name alone does not make a dataset the actuator the waveforms drive
        if ds.name == unseen.IDENTIFIED_ON and (ds.input_unit, ds.output_unit) != units:
            why = (f"{shown(path)} is named {ds.name!r} but in {ds.input_unit or '?'} -> {ds.output_unit or '?'}, "
                   f"the unseen waveforms in {units[0] or '?'} -> {units[1] or '?'}")
            if args.unseen:
                raise CommandError(f"--unseen: {why}: its fits cannot be scored on them")
            print(f"hysbench run: {why}: its fits are not scored on them", file=sys.stderr)
            return None
    return waveforms


def main(args) -> int:
    started = time.perf_counter()
    models = comma_list(args.models, "--models")
    methods = comma_list(args.methods, "--methods")
    user_options = parse_method_options(args.option)
    datasets, skipped = _suite_datasets(args)
    for path, ds in datasets:  # refused before any work: a matrix of cells that cannot fit says nothing
        for problem in fitting_problems(ds):
            raise CommandError(f"{shown(path)}: {problem}")
    if args.suite == "measured" and models is None:
        models = measured.suite_models()
    for line in skipped:  # never silent: each folder not scored is named
        print(f"hysbench run: {line}", file=sys.stderr)
    unseen_ds = _unseen_dataset(args, datasets)
    names = [ds.name for _, ds in datasets]
    if len(set(names)) != len(names):
        twice = next(name for name in names if names.count(name) > 1)
        folders = " and ".join(shown(path) for path, ds in datasets if ds.name == twice)
        raise HysbenchError(f"datasets {folders} share the name {twice!r}, which labels the results: "
                            "give one of them another name (name = ... in its dataset.toml)")
    for method in user_options:
        if method not in (methods or DEFAULT_METHODS):
            raise HysbenchError(f"--option names method {method!r}, which is not being run")
    options = method_options(methods, user_options, args.full_budget)
    cells = plan_cells(datasets, models, methods, args.seed, options)
    if not cells:
        raise HysbenchError("no model/method combination applies; check --models and --methods")
    is_measured = args.suite == "measured"
    csv_name, report_name = ((measured.MEASURED_CSV, measured.MEASURED_REPORT) if is_measured
                             else ("matrix.csv", "report.md"))
    out_existed = Path(args.out).exists()
    out = ensure_dir(args.out)
    store = CellStore(out, measured.MEASURED_CELLS if is_measured else "cells")
    reused = sum(1 for c in cells if not args.force and store.get(c.key) is not None)

    results: dict[str, dict] = {}

    def on_result(res):
        results[res["key"]] = res
        write_matrix_csv(out, list(results.values()), csv_name)

    expected = seconds_per_cell(out / csv_name)  # read before this run rewrites it
    try:
        all_results = run_matrix(cells, store, jobs=args.jobs, dask_address=args.dask, force=args.force,
                                 on_result=on_result, quiet=args.quiet, expected_seconds=expected)
    except BaseException:
        if not out_existed and not any(p.is_file() for p in out.rglob("*")):  # no empty folders left behind
            shutil.rmtree(out, ignore_errors=True)
        raise
    ordered = [all_results[c.key] for c in cells]
    write_matrix_csv(out, ordered, csv_name)
    extra = []
    if unseen_ds is not None:
        scored = unseen.score_cells(ordered, unseen_ds, cache=store.folder / unseen.CACHE_FILE)
        unseen.write_unseen_csv(out, scored)
        extra = unseen.unseen_section([r for r in ordered if r["status"] == "ok"], scored, unseen_ds)
    elapsed = time.perf_counter() - started
    header = [
        f"Generated by `hysbench run{' --suite measured' if is_measured else ''}` (hysbench {package_version()}, "
        f"code {code_fingerprint()}), seed {args.seed}. "
        f"{len(cells)} cells: {len(cells) - reused} computed, {reused} reused from an earlier run; "
        f"wall time {elapsed:.0f} s with {args.jobs or os.cpu_count()} worker processes.",
        "",
        "| dataset | folder | records (identification / validation) | content hash |",
        "|---|---|---|---|",
    ] + [f"| {ds.name} | `{_shown(p)}` | {len(ds.identification)} / {len(ds.validation)} | "
         f"`{ds.content_hash()[:12]}` |" for p, ds in datasets]
    if skipped:
        header += ["", "Folders not scored:", ""] + [f"- {line}" for line in skipped]
    header += budget_lines(options, cells, args.full_budget)
    write_report(out, ordered, [ds for _, ds in datasets], header, extra, report_name)
    failed = [r for r in ordered if r["status"] != "ok"]
    if not args.quiet:
        print(f"{len(cells)} cells ({len(cells) - reused} computed, {reused} reused, {len(failed)} failed or "
              f"non-finite) in {elapsed:.1f} s; wrote {out}/{csv_name} and {out}/{report_name}"
              + (f" (with the unseen-waveform table, {out}/{unseen.UNSEEN_CSV})" if unseen_ds is not None else ""))
    for r in failed:  # printed even with --quiet: never silent
        print(f"{r['status']}: {r['model']}/{r['method']} on {r['dataset']}: {r['error']}", file=sys.stderr)
    return 1 if failed and len(failed) == len(ordered) else 0
