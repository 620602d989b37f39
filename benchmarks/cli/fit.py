"""``hysbench fit DATASET --model NAME --method NAME [--seed N] [--json FILE]``: one identification.

Prints a short table (fitness in the output unit squared, evaluations, time,
e_m / e_rms per record, parameters). ``--json`` writes the Fit (keys ``model``,
``method``, ``params``, ``fitness``, ``output_unit``, ``fit_seconds``,
``n_evaluations``, ``records`` and more; see ``Fit.to_dict``). ``--hyper key=value`` sets model
hyperparameters, ``--option key=value`` identifier options (values are read
as JSON, e.g. ``--option n_starts=4 --option 'bounds={"gamma": [0, 0.1]}'``,
falling back to a plain string). ``--save MODEL.json`` writes the model file
(models/model_file.py): what ``hysbench.models.load_model`` and ``hysbench export`` read.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hysbench.data.dataset import load_dataset
from hysbench.data.files import STDOUT, check_output_file, ensure_dir, write_json
from hysbench.models import get_model

from hysbench.identification.api import identify, list_methods

from .common import CommandError, add_dataset_argument, add_seed_argument, dataset_paths, parse_key_values

EXAMPLE = "hysbench fit data/virtual_dea --model mrpim --method varpro --json fit.json"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_dataset_argument(parser)
    parser.add_argument("--model", required=True, help="registered model name, e.g. mrpim")
    parser.add_argument("--method", default="auto",
                        help=f"identifier: {', '.join(list_methods())} (default: auto = varpro when the model has a "
                             "linear part, else lsq)")
    add_seed_argument(parser, what="the identifier")
    parser.add_argument("--json", metavar="FILE",
                        help="write the fit as JSON to FILE ('-': standard output, the table then goes to stderr); "
                             "a symbolic link is followed (its target is replaced), an existing folder, device, "
                             "FIFO or socket is refused")
    parser.add_argument("--save", metavar="MODEL.json",
                        help="write the fitted model as a model file (load with hysbench.load_model); "
                             "refused like --json, '-' is not accepted")
    parser.add_argument("--hyper", metavar="KEY=VALUE", action="append", default=[],
                        help="model hyperparameter, e.g. --hyper offset=false (repeatable)")
    parser.add_argument("--option", metavar="KEY=VALUE", action="append", default=[],
                        help="identifier option, e.g. --option n_starts=4 or --option lsq.max_nfev=50 (repeatable)")


def main(args) -> int:
    hyper = parse_key_values(args.hyper, "--hyper")
    options = parse_key_values(args.option, "--option")
    dataset = dataset_paths(args.dataset)[0]
    model = get_model(args.model, **hyper)
    if args.save == STDOUT:
        raise CommandError("--save needs a file name ('-' is for --json only)")
    for out in (args.json, args.save):  # refuse an unwritable destination before spending time on the fit
        if out:
            check_output_file(out)
    data = load_dataset(dataset) if args.save else dataset
    fit = identify(model, data, method=args.method, seed=args.seed, **options)
    # the files first: what the fit computed is kept even if printing fails (a reader closing the pipe)
    to_stdout = args.json == STDOUT
    if args.json and not to_stdout:
        ensure_dir(Path(args.json).resolve().parent)
        write_json(args.json, fit.to_dict())
    dts = [r.dt for r in data.identification] if args.save else []
    if args.save and fit.success:
        fitted = fit.fitted_model(dts[0], data.input_unit, data.output_unit)
        ensure_dir(Path(args.save).resolve().parent)
        write_json(args.save, fitted.to_dict())
    print(fit.summary(), file=sys.stderr if to_stdout else sys.stdout)
    if to_stdout:
        write_json(STDOUT, fit.to_dict())
    elif args.json:
        print(f"\nwrote {args.json}")
    if not fit.success:
        print(f"hysbench fit: {fit.message}", file=sys.stderr)
        if args.save:
            print(f"hysbench fit: no model file written ({args.save})", file=sys.stderr)
        return 1
    if args.save:
        if max(dts) - min(dts) > 1e-9 * max(dts):
            print(f"hysbench fit: note: the identification records' sample times differ ({min(dts):g} to "
                  f"{max(dts):g} s); the model file records the first, {dts[0]:g} s", file=sys.stderr)
        print(f"wrote {args.save}")
    return 0
