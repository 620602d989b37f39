"""``hysbench diagnose DATASET``: show where a model departs from the data, name the cause, extend, measure.

Writes diagnosis.md, its PNG figures and diagnosis.json into ``--out``
(default results/), or the JSON where ``--json`` says. The verdict is
printed: the cause (none, unexplained, or one of relaxation, delay,
resonance, creep, interference, saturation), its parameters with their
uncertainty, causes it cannot be told apart from and the drive that would
separate them, each candidate's held-out score and the validation gain of
the extended model.
"""

from __future__ import annotations

import argparse
import math
import sys

from hysbench.data.dataset import load_dataset, output_scale, scaled_output
from hysbench.data.files import STDOUT
from hysbench.benchmarks.cli.common import (add_dataset_argument, add_seed_argument, check_outputs, dataset_paths,
                                            integer_at_least, positive_int, timed_progress)
from hysbench.benchmarks.diagnosis.candidates import MAX_ROWS
from hysbench.benchmarks.diagnosis.diagnose import diagnose
from hysbench.benchmarks.diagnosis.policy import Policy
from hysbench.benchmarks.diagnosis.report import verdict_lines, write_report
from hysbench.models import get_model

EXAMPLE = "hysbench diagnose data/virtual_dea --model mrpim --out results"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_dataset_argument(parser)
    parser.add_argument("--model", default="mrpim", help="base model (registry name, default mrpim)")
    parser.add_argument("--out", default="results", help="folder for diagnosis.md, figures and JSON (default results/)")
    parser.add_argument("--json", default=None, metavar="FILE",
                        help="write the JSON here (default OUT/diagnosis.json; - for standard output, the verdict "
                             "then on stderr)")
    add_seed_argument(parser, what="the identifiers and the row subset")
    parser.add_argument("--max-rows", type=positive_int, default=None,
                        help="samples per record in the candidate screen (default 10000)")
    parser.add_argument("--segments", type=integer_at_least(2), metavar="K",
                        help="cut each identification record into K consecutive records of whole periods "
                             "(leave-one-record-out on one long recording)")
    parser.add_argument("--thorough", action="store_true",
                        help="try every cause afresh on top of the named one also on long records (a delay or a "
                             "mode under the plant's own relaxation; about three times slower on the default dataset)")
    parser.add_argument("--policy", action="append", default=[], metavar="KEY=VALUE",
                        help="change one threshold of the decision rule (repeat for several; fields and defaults: "
                             "docs/diagnosis.md, e.g. --policy z_pass=2.5); the report prints the policy used")
    parser.add_argument("--note", default="", help="a line put at the top of diagnosis.md")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")


def main(args) -> int:
    # an unknown model, a bad policy or an unwritable destination fails here, before any work
    model = get_model(args.model)
    policy = Policy().with_overrides(args.policy)
    check_outputs(args)
    say = timed_progress(args.quiet)

    dataset = load_dataset(dataset_paths(args.dataset)[0])
    scale = output_scale(dataset)  # 1 at ordinary scales; else diagnosed at order one (exact power of two)
    note = args.note
    if scale != 1.0:
        dataset = scaled_output(dataset, scale)
        note = " ".join(filter(None, [note, f"The output was divided by 2^{math.frexp(scale)[1] - 1} (exact) to be "
                                            "diagnosed at order one: amounts in the output's unit below are in units "
                                            f"of 2^{math.frexp(scale)[1] - 1} {dataset.output_unit or 'output units'}; "
                                            "percentages and verdicts are unchanged by it."]))
    diag = diagnose(dataset, model=model, seed=args.seed, max_rows=args.max_rows or MAX_ROWS,
                    segments=args.segments, progress=say, thorough=args.thorough, policy=policy)
    say("writing the report")
    write_report(diag, args.out, args.json, note=note)
    print(verdict(diag), file=sys.stderr if args.json == STDOUT else sys.stdout)  # stdout: the JSON alone
    return 0


def verdict(diag) -> str:
    """The report's verdict lines, then each candidate's held-out score."""
    lines = verdict_lines(diag)
    lines.append(diag.policy.summary())
    lines.append("evidence (leave-one-identification-record-out prediction against the base model refitted the same "
                 "way; validation records untouched):")
    for c in sorted(diag.candidates, key=lambda c: -c.heldout_gain):
        h = c.heldout
        lines.append(f"  {c.cause:<13} held-out gain {100 * c.heldout_gain:9.3f} %   z {h.get('z', 0.0):6.2f}   "
                     f"folds {h.get('folds_improved')}/{h.get('n_folds')}")
    return "\n".join(lines)
