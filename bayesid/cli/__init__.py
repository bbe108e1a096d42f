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

What the package says goes through the ``bayesid`` logger; :func:`main` puts the one handler on
it, on stderr, for the command's run: progress (INFO) by default, ``-q`` warnings and errors only
(no progress bars either), ``-v`` debug records too.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
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
    talk = ap.add_mutually_exclusive_group()
    talk.add_argument("-q", "--quiet", action="store_true", help="warnings and errors only: no progress lines or bars")
    talk.add_argument("-v", "--verbose", action="store_true", help="debug messages too (each finished task)")
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
    import matplotlib

    matplotlib.use("Agg")  # the commands write their figures, they never show them
    try:
        args = build_parser().parse_args(argv)
    except OptionError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    level = logging.WARNING if args.quiet else logging.DEBUG if args.verbose else logging.INFO
    with _messages(level):
        try:
            return COMMANDS[args.command].run(args)
        except (ValueError, KeyError, FileNotFoundError) as e:
            print(f"error: {e}", file=sys.stderr)
            return 2


class _Stderr(logging.StreamHandler):
    """A handler on the ``sys.stderr`` of the moment (one replaced after it was made, as by
    pytest's capture, included) that clears a running tqdm bar for its line and redraws it after
    (a line written into a bar garbles both)."""

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value):
        pass

    def emit(self, record):
        from tqdm import tqdm

        with tqdm.external_write_mode(file=sys.stderr):
            super().emit(record)


class _Lines(logging.Formatter):
    """The package's records as the command's lines: progress (INFO) indented under the command's
    own, ``warning: ...`` and ``error: ...`` as the command writes them, ``debug: [logger] ...``."""

    def format(self, record):
        text = super().format(record)
        if record.levelno == logging.INFO:
            return f"  {text}"
        if record.levelno < logging.INFO:
            return f"debug: [{record.name}] {text}"
        return f"{record.levelname.lower()}: {text}"


@contextlib.contextmanager
def _messages(level: int):
    """The ``bayesid`` logger at ``level`` with the command's stderr handler, for one run (the
    logger is left as it was: ``main`` may be called again in the same process)."""
    logger = logging.getLogger("bayesid")
    handler = _Stderr()
    handler.setFormatter(_Lines())
    old = logger.level
    logger.setLevel(level)
    logger.addHandler(handler)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(old)
