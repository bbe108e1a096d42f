"""The ``bayesid`` command.

    bayesid simulate --vehicle nps_auv2 --manoeuvre zigzag --angle 20 --mode horizontal --out track.csv
    bayesid simulate --vehicle kvlcc2_7m --manoeuvre zigzag --angle -10 --check 10 --out z10.csv
    bayesid convert --format esso-osaka ../shared/data/real/esso-osaka-frt --out tracks/esso

    bayesid fit --vehicle esso_osaka_3m --train A.csv B.csv --effects wind --out fitdir
    bayesid predict --model fitdir/model.json --track C.csv --score-window 60 --out pred
    bayesid sample --model fitdir/model.json --train A.csv B.csv --out post

    bayesid diagnose --vehicle nps_auv2 --free Yv,Yr,Nv,Nr,Ydr,Ndr --train A.csv B.csv \\
        --heldout C.csv --score-window 60 --out diag

    bayesid discover --model fitdir/model.json --train A.csv B.csv --heldout C.csv --out disc \\
        --write-vehicle myship_discovered.toml

    bayesid design --model fitdir/model.json --train A.csv B.csv --heldout C.csv --out des

Each subcommand is a module with ``add_parser(sub)`` (its options) and ``run(args)`` (exit
code): :mod:`~bayesid.cli.simulate`, :mod:`~bayesid.cli.convert`, :mod:`~bayesid.cli.diagnose`,
:mod:`~bayesid.cli.discover`, :mod:`~bayesid.cli.design`, :mod:`~bayesid.cli.fit`,
:mod:`~bayesid.cli.predict`, :mod:`~bayesid.cli.sample`. Shared options
and the checks of numbers are in :mod:`~bayesid.cli.options`, the track files in
:mod:`~bayesid.cli.inputs`, the output folders in :mod:`~bayesid.cli.outputs` and what produced a
model in :mod:`~bayesid.cli.provenance`; the reports are written by :mod:`bayesid.report`.
"""

from __future__ import annotations

import argparse
import sys

from . import convert, design, diagnose, discover, fit, predict, sample, simulate
from .options import HelpFormatter, OptionError

#: The subcommands in the order of ``bayesid --help``: the order of use, then the tools around it.
COMMANDS = {
    "fit": fit,
    "predict": predict,
    "sample": sample,
    "diagnose": diagnose,
    "discover": discover,
    "design": design,
    "simulate": simulate,
    "convert": convert,
}

#: ``bayesid --help``'s text above the commands.
DESCRIPTION = """\
Identify the hydrodynamic coefficients of a ship, submarine or AUV from its tracks (Track CSVs)
and say how well each one is determined.

Order of use:  fit -> predict -> sample -> diagnose
  fit       vehicle file + training tracks -> model.json (the identified coefficients)
  predict   model.json + other tracks -> errors over scoring windows, manoeuvre indices, bands
  sample    model.json + training tracks -> posterior of the coefficients, identifiability
  diagnose  vehicle file + training and held-out tracks -> what the model misses, and why
Around it: discover (model terms the data say are missing), design (the run that tells
apart the terms the runs cannot), simulate (a standard manoeuvre of a vehicle file -> a
Track CSV), convert (third-party data files -> Track CSVs).
"""

#: ``bayesid --help``'s text below the commands.
EPILOG = """\
Each command's options and defaults: bayesid COMMAND --help.
Documentation: docs/ in the source tree (quickstart, reading your report, command reference
docs/cli.rst, FAQ); build it with
  pip install -e '.[docs]' && python -m sphinx -b html docs docs/_build/html
and open docs/_build/html/index.html.
"""


class _TopFormatter(argparse.RawDescriptionHelpFormatter, HelpFormatter):
    """The description and epilog as written, the options with their defaults."""


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
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=_TopFormatter,
    )
    ap.add_argument("--version", action="version", version=f"bayesid {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND", title="commands")
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
