"""The ``bayesid`` command.

    bayesid simulate --vehicle nps_auv2 --manoeuvre zigzag --angle 20 --mode horizontal --out track.csv
    bayesid simulate --vehicle kvlcc2_7m --manoeuvre zigzag --angle -10 --check 10 --out z10.csv
    bayesid convert --format esso-osaka ../shared/data/real/esso-osaka-frt --out tracks/esso

    bayesid diagnose --vehicle nps_auv2 --free Yv,Yr,Nv,Nr,Ydr,Ndr --train A.csv B.csv \\
        --heldout C.csv --window 60 --out diag

    bayesid fit --vehicle esso_osaka_3m --train A.csv B.csv --effects wind --out fitdir
    bayesid predict --model fitdir/model.json --track C.csv --window 60 --out pred

    bayesid discover --model fitdir/model.json --train A.csv B.csv --heldout C.csv --out disc \\
        --write-vehicle myship_discovered.toml

Each subcommand is a module with ``add_parser(sub)`` (its options) and ``run(args)`` (exit
code): :mod:`~bayesid.cli.simulate`, :mod:`~bayesid.cli.convert`, :mod:`~bayesid.cli.diagnose`,
:mod:`~bayesid.cli.discover`, :mod:`~bayesid.cli.fit`, :mod:`~bayesid.cli.predict`, :mod:`~bayesid.cli.sample`. Shared options
and the checks of numbers are in :mod:`~bayesid.cli.options`, the track files in
:mod:`~bayesid.cli.inputs`, the output folders in :mod:`~bayesid.cli.outputs` and what produced a
model in :mod:`~bayesid.cli.provenance`; the reports are written by :mod:`bayesid.report`.
"""

from __future__ import annotations

import argparse
import sys

from . import convert, diagnose, discover, fit, predict, sample, simulate
from .options import OptionError

#: The subcommands in the order of ``bayesid --help``.
COMMANDS = {
    "simulate": simulate,
    "convert": convert,
    "diagnose": diagnose,
    "discover": discover,
    "fit": fit,
    "predict": predict,
    "sample": sample,
}


def build_parser() -> argparse.ArgumentParser:
    """The parser of the ``bayesid`` command and its subcommands.

    Returns
    -------
    argparse.ArgumentParser
        The parser; ``args.command`` names the subcommand.
    """
    from .. import __version__

    ap = argparse.ArgumentParser(
        prog="bayesid",
        description="hydrodynamic coefficient identification",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--version", action="version", version=f"bayesid {__version__}")
    sub = ap.add_subparsers(dest="command", required=True)
    for module in COMMANDS.values():
        module.add_parser(sub)
    return ap


def main(argv=None) -> int:
    """Run the ``bayesid`` command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default: the command line's).

    Returns
    -------
    int
        The exit code: 0, or 2 after an error message on stderr (``error: ...``) for a bad
        input. argparse's own usage errors, ``--help`` and ``--version`` exit through SystemExit.
    """
    try:
        args = build_parser().parse_args(argv)
    except OptionError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    try:
        return COMMANDS[args.command].run(args)
    except (ValueError, KeyError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
