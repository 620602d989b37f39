"""The ``hysbench`` command line.

Each subcommand lives in its own module with ``EXAMPLE`` (shown by ``--help``),
``add_arguments(parser)`` and ``main(args) -> int``; shared argument types are in
``common``. Bad input (an unknown model, a refused dataset, bad
options, an unwritable output folder) is printed as one line on stderr with
exit status 2, never as a traceback.
"""

from __future__ import annotations

import argparse
from importlib.metadata import PackageNotFoundError, version as _dist_version
import importlib
import os
import sys

from hysbench.data.files import CREATED_FOLDERS, remove_created_empty_folders
from hysbench.models.errors import HysbenchError

from .common import OneLineParser

# subcommand -> (module, one-line help); None: the module's SUMMARY, built from what it registers
COMMANDS = {
    "check": ("hysbench.benchmarks.cli.check", "check a dataset folder and summarise its records"),
    "data": ("hysbench.benchmarks.cli.data", "generate a dataset: virtual-dea (the default dataset)"),
    "dataset": ("hysbench.benchmarks.cli.dataset", "describe a bare CSV file: dataset init writes its dataset.toml"),
    "run": ("hysbench.benchmarks.cli.run", "score every model x identifier on every dataset (writes results/)"),
    "posterior": ("hysbench.benchmarks.cli.posterior",
                  "posterior of a model's parameters with emcee (AR(1) noise; writes results/posterior.md)"),
    "reproduce": ("hysbench.benchmarks.cli.reproduce", "simulate the paper's Table 2 MRPIM over the seven frequencies"),
    "ablate": ("hysbench.benchmarks.cli.ablate", "which parts of MRPIM earn their parameters (order, q, envelopes, N)"),
    "fit": ("hysbench.benchmarks.cli.fit", "identify one model on a dataset with one identifier"),
    "export": ("hysbench.benchmarks.cli.export", "C99 code for a fitted model and its inverse (from fit --save)"),
    "report": ("hysbench.benchmarks.cli.report", None),
    "diagnose": ("hysbench.benchmarks.cli.diagnose",
                 "find what a model gets wrong: show it, name the cause, extend the model, measure the gain"),
    "accuracy": ("hysbench.benchmarks.cli.accuracy",
                 "the diagnosis's accuracy on planted effects: run plans, pool them, state the detection limits"),
    "compensate": ("hysbench.benchmarks.cli.compensate",
                   "invert models and score how well the virtual DEA tracks references (writes compensation.md)"),
}


def _version() -> str:
    try:
        return _dist_version("hysbench")
    except PackageNotFoundError:  # running from a source tree
        return "0+unknown"


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="hysbench", description="Benchmark suite for rate-dependent hysteresis models.")
    parser.add_argument("--version", action="version", version=f"hysbench {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OneLineParser)
    sub.required = True
    for name, (module, help_text) in COMMANDS.items():
        mod = importlib.import_module(module)
        help_text = help_text or mod.SUMMARY
        p = sub.add_parser(name, help=help_text, description=help_text, epilog=f"example:\n  {mod.EXAMPLE}",
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        p.set_defaults(_module=module)
        mod.add_arguments(p)
    return parser


def main(argv=None) -> int:
    for stream in (sys.stdout, sys.stderr):  # a path is printed as the OS gave it, whatever its bytes
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="surrogateescape" if stream is sys.stdout else "backslashreplace")
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error already printed in one line (2)
        return int(exc.code or 0)
    CREATED_FOLDERS.clear()  # only this command's folders are removed on a refusal
    try:
        return int(importlib.import_module(args._module).main(args) or 0)
    except HysbenchError as exc:
        remove_created_empty_folders()
        print(f"hysbench {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        remove_created_empty_folders()
        print(f"hysbench {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader of standard output went away (``| head``): stop without a traceback
        remove_created_empty_folders()
        try:  # what is still buffered has nowhere to go; so Python's exit does not report it either
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):  # a standard output with no file descriptor
            pass
        return 1

