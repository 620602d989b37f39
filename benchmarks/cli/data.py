"""``hysbench data virtual-dea --out DIR [--seed N] [--excitation NAME[,NAME...]|all]``: write the virtual DEA dataset.

The dataset is the paper's seven-frequency protocol applied to the virtual DEA
(hysbench.data.virtual_dea): one record per frequency from t = 0 through the
creep transition to two stable periods, measured by the virtual laser sensor with
the given seed. The default dataset shipped in data/virtual_dea/ is this command's
output with the default seed.

With ``--excitation`` the records are the same actuator and sensor under other
drives (data/excitations.py: triangle, multisine, random, decaying-sine,
reversal-curves, or ``all``), each after a sine run-in through most of the creep
transition and scored on the drive only: the unseen-waveform dataset shipped in
data/virtual_dea_waveforms/ is ``--excitation all`` with the default seed.

DIR is replaced as a whole (written beside it, then moved into place). To protect
other files, DIR must be absent, empty, or a dataset folder (holding dataset.toml).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from hysbench.data.files import OutputError
from hysbench.models.errors import HysbenchError

from hysbench.data.excitations import EXCITATIONS, ExcitationError
from hysbench.data.virtual_dea import DEFAULT_SEED, WAVEFORM_DRIVES, write_dataset, write_waveform_dataset

from .common import comma_list, nonnegative_int

EXAMPLE = ("hysbench data virtual-dea --out /tmp/virtual_dea --seed 7\n"
           "  hysbench data virtual-dea --excitation all --out /tmp/virtual_dea_waveforms")

SEED_MAX = 2**63 - 1


class DataCommandError(HysbenchError):
    """A bad option of ``hysbench data``."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="data_command", metavar="DATASET")
    sub.required = True
    p = sub.add_parser("virtual-dea", help="the virtual DEA's seven records (the default dataset)",
                       description=__doc__.split("\n\n")[1], epilog=f"example:\n  {EXAMPLE}",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True,
                   help="output folder (replaced if it holds a virtual DEA made by this command, else only with --force)")
    p.add_argument("--force", action="store_true", help="replace any dataset folder at --out")
    p.add_argument("--seed", type=nonnegative_int, default=DEFAULT_SEED,
                   help=f"seed of the sensor noise (default {DEFAULT_SEED}, the shipped dataset's)")
    p.add_argument("--excitation", metavar="NAME[,NAME...]",
                   help=f"unseen drives instead of the seven sines: {', '.join(EXCITATIONS)}, or all")


def check_output_folder(out: Path, force: bool = False) -> None:
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out} exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not (out / "dataset.toml").is_file():
        raise OutputError(f"--out {out} is a non-empty folder without dataset.toml; refusing to replace it")
    if (out / "dataset.toml").is_file() and not (out / "truth.json").is_file() and not force:
        raise OutputError(f"--out {out} holds a dataset not made by this command (no truth.json); "
                          "refusing to replace it without --force")
    parent = out.parent if str(out.parent) else Path(".")
    if parent.exists() and not parent.is_dir():
        raise OutputError(f"cannot write {out}: {parent} is not a folder")


def main(args) -> int:
    if args.data_command != "virtual-dea":  # argparse allows only the listed choices
        raise DataCommandError(f"unknown dataset {args.data_command!r}")
    if not 0 <= args.seed <= SEED_MAX:
        raise DataCommandError(f"--seed must be an integer in 0..{SEED_MAX}, got {args.seed}")
    out = Path(args.out)
    names = excitation_names(args.excitation)
    check_output_folder(out, args.force)
    t0 = time.perf_counter()
    try:
        if names:
            write_waveform_dataset(out, names, seed=args.seed)
        else:
            write_dataset(out, seed=args.seed)
    except OSError as exc:
        raise OutputError(f"cannot write {out}: {exc.strerror or exc}") from None
    what = f"the virtual DEA under {', '.join(names)}" if names else "the virtual DEA dataset"
    print(f"wrote {what} (seed {args.seed}) to {out} in {time.perf_counter() - t0:.1f} s")
    return 0


def excitation_names(text: str | None) -> list[str]:
    names = comma_list(text, "--excitation")
    if names is None:
        return []
    if names == ["all"]:
        return list(WAVEFORM_DRIVES)
    unknown = [n for n in names if n not in EXCITATIONS]
    if unknown:
        raise ExcitationError(f"--excitation: unknown drive {unknown[0]!r}; known: {', '.join(EXCITATIONS)}, all")
    return names
