"""``hysbench run``: every model x identifier on every dataset, resumable and parallel."""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from hysbench.data.files import ensure_dir
from hysbench.data.dataset import load_dataset
from hysbench.models.errors import HysbenchError

from hysbench.benchmarks.matrix.cells import (DEFAULT_METHODS, code_fingerprint, method_options, package_version,
                                              plan_cells)
from hysbench.benchmarks.matrix.execute import run_matrix
from hysbench.benchmarks.matrix.report import write_matrix_csv, write_report
from hysbench.benchmarks.matrix.store import CellStore


def default_dataset() -> Path:
    import hysbench.data

    return Path(hysbench.data.__file__).resolve().parent / "virtual_dea"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--dataset", action="append", metavar="DIR",
                        help="dataset folder; repeat for several (default: the virtual DEA in data/virtual_dea)")
    parser.add_argument("--models", help="comma-separated model names (default: every registered model)")
    parser.add_argument("--methods", help="comma-separated identifiers (default: every one that applies)")
    parser.add_argument("--out", default="results", help="output folder (default: results/)")
    parser.add_argument("--jobs", type=int, default=None, help="local worker processes (default: all cores)")
    parser.add_argument("--seed", type=int, default=0, help="seed of every identifier (default 0)")
    parser.add_argument("--dask", metavar="ADDRESS", help="run the cells on this Dask scheduler instead")
    parser.add_argument("--option", action="append", default=[], metavar="METHOD.KEY=VALUE",
                        help="an identifier option, e.g. mpso.iterations=50 (repeatable)")
    parser.add_argument("--full-budget", action="store_true",
                        help="the identifiers' own default budgets instead of the matrix's (much slower)")
    parser.add_argument("--force", action="store_true", help="recompute cells that are already finished")
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")


def _names(text: str | None, what: str) -> list[str] | None:
    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise HysbenchError(f"--{what} needs at least one name")
    return names


def parse_options(items: list[str]) -> dict[str, dict]:
    """['mpso.iterations=50'] -> {'mpso': {'iterations': 50}}."""
    out: dict[str, dict] = {}
    for item in items:
        head, sep, raw = item.partition("=")
        method, dot, key = head.partition(".")
        if not (sep and dot and method and key):
            raise HysbenchError(f"--option {item!r}: expected METHOD.KEY=VALUE")
        try:
            value = json.loads(raw)
        except json.JSONDecodeError:
            value = raw
        out.setdefault(method, {})[key] = value
    return out


def _shown(path: Path) -> str:
    """A dataset folder as the report shows it: relative to the working folder when inside it."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def main(args) -> int:
    started = time.perf_counter()
    if args.jobs is not None and args.jobs < 1:
        raise HysbenchError(f"--jobs must be at least 1, got {args.jobs}")
    if args.seed < 0:
        raise HysbenchError(f"--seed must not be negative, got {args.seed}")
    models = _names(args.models, "models")
    methods = _names(args.methods, "methods")
    user_options = parse_options(args.option)
    paths = [Path(p) for p in (args.dataset or [default_dataset()])]
    datasets = [(p, load_dataset(p)) for p in paths]
    names = [ds.name for _, ds in datasets]
    if len(set(names)) != len(names):
        raise HysbenchError(f"two datasets share a name ({', '.join(names)}); names label the results")
    for method in user_options:
        if method not in (methods or DEFAULT_METHODS):
            raise HysbenchError(f"--option names method {method!r}, which is not being run")
    options = method_options(methods, user_options, args.full_budget)
    cells = plan_cells(datasets, models, methods, args.seed, options)
    if not cells:
        raise HysbenchError("no model/method combination applies; check --models and --methods")
    out = ensure_dir(args.out)
    store = CellStore(out)
    reused = sum(1 for c in cells if not args.force and store.get(c.key) is not None)

    results: dict[str, dict] = {}

    def on_result(res):
        results[res["key"]] = res
        write_matrix_csv(out, list(results.values()))

    all_results = run_matrix(cells, store, jobs=args.jobs, dask_address=args.dask, force=args.force,
                             on_result=on_result, quiet=args.quiet)
    ordered = [all_results[c.key] for c in cells]
    write_matrix_csv(out, ordered)
    elapsed = time.perf_counter() - started
    header = [
        f"Generated by `hysbench run` (hysbench {package_version()}, code {code_fingerprint()}), seed {args.seed}. "
        f"{len(cells)} cells: {len(cells) - reused} computed, {reused} reused from an earlier run.",
        "",
        "| dataset | folder | records (identification / validation) | content hash |",
        "|---|---|---|---|",
    ] + [f"| {ds.name} | `{_shown(p)}` | {len(ds.identification)} / {len(ds.validation)} | "
         f"`{ds.content_hash()[:12]}` |" for p, ds in datasets]
    budget = "the identifiers' own defaults" if args.full_budget else "the matrix's default budget"
    header += ["", f"Identifier options ({budget} and any `--option`): "
               + (", ".join(f"{m}.{k}={v}" for m, o in options.items() for k, v in o.items()) or "none")
               + ". Budgets are part of each cell's key: a rerun with other options recomputes."]
    write_report(out, ordered, [ds for _, ds in datasets], header)
    failed = [r for r in ordered if r["status"] != "ok"]
    if not args.quiet:
        print(f"{len(cells)} cells ({len(cells) - reused} computed, {reused} reused, {len(failed)} failed or "
              f"non-finite) in {elapsed:.1f} s; wrote {out}/matrix.csv and {out}/report.md")
    for r in failed:  # printed even with --quiet: never silent
        print(f"{r['status']}: {r['model']}/{r['method']} on {r['dataset']}: {r['error']}", file=sys.stderr)
    return 1 if failed and len(failed) == len(ordered) else 0
