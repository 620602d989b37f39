"""``hysbench compensate DATASET [--model M | --models A,B] [--method X] [--option K=V] [--inverse I]``: inverse
compensation on the plant.

Identifies each model on the dataset's identification records (as ``hysbench
fit``; ``--option KEY=VALUE`` as there, for every model), inverts it (``--inverse``:
the P-I family's causal inverse, as ``hysbench export``'s), and drives the virtual DEA
(its physics and sensor, input clipped to 0.5-2.5 kV) from rest along each reference: the protocol's seven sines,
a triangle, a multisine and a band-limited random reference. Scores tracking
e_rms / e_m for the static linear gain, each model's inverse open loop, a PI loop
alone and with each inverse as feedforward. Writes compensation.md, figures and
compensation.json into ``--out`` (default results/).

Example::

    hysbench compensate data/virtual_dea --models classical-pi,mrpim --out results
"""

from __future__ import annotations

import argparse
import shlex

from hysbench.benchmarks.cli.common import (add_dataset_argument, add_seed_argument, check_outputs, comma_list,
                                            dataset_paths, parse_key_values, timed_progress)
from hysbench.benchmarks.compensation.controllers import PI_BANDWIDTH_HZ
from hysbench.benchmarks.compensation.report import write_report
from hysbench.benchmarks.compensation.run import DEFAULT_MODELS, check_models, compensate
from hysbench.data.files import shown_path
from hysbench.identification.api import list_methods
from hysbench.identification.errors import IdentificationError
from hysbench.models.inverse import INVERSES

EXAMPLE = "hysbench compensate data/virtual_dea --models classical-pi,mrpim,viscoelastic --out results"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_dataset_argument(parser)
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--model", help="one registered model to invert, e.g. mrpim")
    group.add_argument("--models", help=f"comma-separated models (default: {','.join(DEFAULT_MODELS)})")
    parser.add_argument("--method", default="auto", help=f"identifier: {', '.join(list_methods())} (default auto)")
    parser.add_argument("--option", metavar="KEY=VALUE", action="append", default=[],
                        help="identifier option for every model, as hysbench fit's, e.g. --option stable_inverse=true "
                             "(repeatable; over the budget --method auto gives bouc-wen)")
    parser.add_argument("--inverse", choices=INVERSES, default="auto",
                        help="the P-I family's causal inverse, as hysbench export's: exact, reference-driven or auto "
                             "(default: classical P-I's analytic one where it applies, else reference-driven where "
                             "the model has rate terms); other models ignore it")
    add_seed_argument(parser, what="the identifier")
    parser.add_argument("--bandwidth", type=float, default=PI_BANDWIDTH_HZ,
                        help=f"PI loop bandwidth in Hz (default {PI_BANDWIDTH_HZ:g})")
    parser.add_argument("--references", default=None,
                        help="comma-separated reference names to run (default all: sine-<f>Hz, triangle, multisine, "
                             "random)")
    parser.add_argument("--out", default="results", help="folder for compensation.md, figures, JSON (default results/)")
    parser.add_argument("--json", default=None, metavar="FILE",
                        help="write the JSON here (default OUT/compensation.json)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")


def main(args) -> int:
    names = [args.model] if args.model else (comma_list(args.models, "--models") or list(DEFAULT_MODELS))
    options = parse_key_values(args.option, "--option")
    dataset = dataset_paths(args.dataset)[0]
    if not (args.bandwidth > 0 and args.bandwidth < 100):
        raise IdentificationError(f"--bandwidth must lie in (0, 100) Hz, got {args.bandwidth!r}")
    check_models(names)  # an unknown model fails here, before any work (a bad --option or --inverse: in compensate)
    check_outputs(args)
    say = timed_progress(args.quiet)

    refs = [r.strip() for r in args.references.split(",")] if args.references else None
    result, runs = compensate(dataset, names, method=args.method, seed=args.seed, bandwidth_hz=args.bandwidth,
                              reference_names=refs, log=say, identify_options=options, inverse=args.inverse)
    parts = ["hysbench compensate", shlex.quote(shown_path(dataset)), "--models", ",".join(names)]
    if args.method != "auto":
        parts += ["--method", args.method]
    for item in args.option:
        parts += ["--option", shlex.quote(item)]
    if args.inverse != "auto":
        parts += ["--inverse", args.inverse]
    if args.seed != 0:
        parts += ["--seed", str(args.seed)]
    if args.bandwidth != PI_BANDWIDTH_HZ:
        parts += ["--bandwidth", f"{args.bandwidth:g}"]
    if refs:
        parts += ["--references", ",".join(refs)]
    command = " ".join(parts)
    write_report(result, runs, args.out, args.json, command=command)
    for name, why in result["not_invertible"].items():
        print(f"{name}: cannot be inverted: {why}")
    print(f"best open-loop inverse on the sines: {result['best_model'] or 'none (no sine reference run)'}")
    print(f"wrote {args.out}/compensation.md")
    return 0
