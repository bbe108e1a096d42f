"""The options of the ``bayesid`` subcommands that several of them take, each declared once, and
the argparse types that check numeric options while the command line is parsed.

A subcommand adds a shared option with its ``add_*`` function, passing its own default or help
text where it differs from the others'. A numeric option's type (:func:`number`) converts the
text and checks the value: text that is no number is argparse's usage error; a value out of range
raises :class:`OptionError`, which :func:`bayesid.cli.main` prints as ``error: ...`` with exit
code 2.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from .. import protocol, tasks
from ..models.context import INPUT_RECONSTRUCTIONS

#: The window start rules' help text (``--start``).
START_HELP = (
    "window start states: measured (causal 1 s estimate), fitted (with the model, over a lead-in), "
    "auto (fitted when a track does not log u, v and r and its positions are too noisy for a 1 s "
    "slope estimate of the velocity)"
)
#: The help text of ``--inputs``.
INPUTS_HELP = (
    "logged inputs between samples: hold (each sample kept until the next), linear (interpolated "
    "between samples, as a rate-limited rudder moves; for coarse logs, 1-5 Hz, of a moving rudder), rate "
    "(the rudder and planes move at the steering gear's rate between samples: --rudder-rate or the ship "
    "file's [service] rudder_rate_deg_s)"
)
#: The choices of ``--weighting`` ("": the model's default).
WEIGHTINGS = ("", "noise", "residual")
#: The help text of ``--weighting``.
WEIGHTING_HELP = (
    "channel weights of the fits: noise sds, or the residual RMS of a first fit (two-step "
    "feasible GLS); empty: residual for ships, noise for submarines"
)
#: The help text of ``--score-window``.
SCORE_WINDOW_HELP = (
    "scoring window, s: the tracks are predicted and scored over non-overlapping windows of this "
    "length, each started by the --start rule (<= 0: the whole run)"
)


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """The subcommands' help: each option's text followed by its default.

    As argparse's :class:`~argparse.ArgumentDefaultsHelpFormatter`, but a required option says
    ``(required)`` instead of ``(default: None)``, a flag ``(default: off)``, an option whose default
    is ``None`` or empty ``(default: none)`` / ``(default: empty)`` (its help text says what that
    means), and a text that already places ``%(default)s`` is left as it is.

    Parameters
    ----------
    prog : str
        The program name, as for :class:`argparse.HelpFormatter`.
    indent_increment : int, default 2
        As for :class:`argparse.HelpFormatter`.
    max_help_position : int, default 24
        As for :class:`argparse.HelpFormatter`.
    width : int, optional
        As for :class:`argparse.HelpFormatter` (default: the terminal's).
    """

    def _get_help_string(self, action):
        text = action.help or ""
        if "%(default)" in text or not action.option_strings or action.default is argparse.SUPPRESS:
            return text
        if action.required:
            return f"{text} (required)"
        if action.nargs == 0:
            return f"{text} (default: {'on' if action.default else 'off'})"
        if action.default is None or action.default == "":
            return f"{text} (default: {'none' if action.default is None else 'empty'})"
        return f"{text} (default: %(default)s)"


class DeprecatedAlias(argparse.Action):
    """An option's old spelling, hidden from the help: it stores its value under the new option's
    ``dest`` and prints a one-line deprecation note on stderr.

    Declared with ``help=argparse.SUPPRESS`` and ``new="--new-name"`` (see :func:`add_score_window`).

    Parameters
    ----------
    option_strings : list of str
        The old spelling (``["--window"]``).
    dest : str
        The new option's ``dest``.
    new : str
        The new option, named in the note (``"--score-window"``).
    **kwargs
        Other arguments of :class:`argparse.Action` (``type``, ``default``, ``help``).
    """

    def __init__(self, option_strings, dest, new: str, **kwargs):
        super().__init__(option_strings, dest, **kwargs)
        self.new = new

    def __call__(self, parser, namespace, values, option_string=None):
        print(
            f"note: {parser.prog} {option_string} is deprecated, use {self.new} (same meaning)",
            file=sys.stderr,
        )
        setattr(namespace, self.dest, values)


def add_subcommand(sub, name: str, help: str) -> argparse.ArgumentParser:
    """A subcommand's parser, its help showing each option's default (:class:`HelpFormatter`).

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers of the ``bayesid`` parser.
    name : str
        The subcommand.
    help : str
        Its line in ``bayesid --help``.

    Returns
    -------
    argparse.ArgumentParser
        The subcommand's parser.
    """
    return sub.add_parser(name, formatter_class=HelpFormatter, help=help, description=help)


class OptionError(Exception):
    """A numeric option's value out of its range, raised by a :func:`number` type while parsing.

    Not a ValueError, so that argparse passes it on instead of turning it into its generic
    "invalid float value" usage error; the message names the option.
    """


#: A check of :func:`number`: the value is positive.
POSITIVE = (lambda v: v > 0, "{option} must be positive, not {value}")
#: A check of :func:`number`: the value is zero or positive.
NON_NEGATIVE = (lambda v: v >= 0, "{option} must be >= 0, not {value}")


def at_least(least, message: str = "{option} must be at least {least}, not {value}") -> tuple:
    """A check of :func:`number`: the value is ``least`` or more.

    Parameters
    ----------
    least : int or float
        The smallest value allowed.
    message : str
        The error message, formatted with ``option``, ``least`` and ``value``.

    Returns
    -------
    tuple
        ``(predicate, message)``.
    """
    return (lambda v: v >= least, message.replace("{least}", str(least)))


def number(option: str, kind=float, *checks):
    """The argparse type of a numeric option.

    Parameters
    ----------
    option : str
        The option, named in the error messages (``"--dt"``).
    kind : type
        ``float`` or ``int``: converts the text; text that is no such number is argparse's usage
        error ("invalid float value").
    *checks : tuple
        ``(predicate, message)`` pairs, in order: the first predicate that is false raises
        :class:`OptionError` with its message, formatted with ``option`` and ``value``
        (:data:`POSITIVE`, :data:`NON_NEGATIVE`, :func:`at_least`). A float must be finite
        before any check.

    Returns
    -------
    callable
        The type, named like ``kind`` for argparse's messages.
    """

    def parse(text: str):
        value = kind(text)
        if kind is float and not math.isfinite(value):
            raise OptionError(f"{option} must be a finite number, not {value}")
        for ok, message in checks:
            if not ok(value):
                raise OptionError(message.format(option=option, value=value))
        return value

    parse.__name__ = kind.__name__
    return parse


def add_number(parser, option: str, *checks, kind=float, **kwargs) -> None:
    """Add a numeric option whose type is :func:`number`.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    option : str
        The option (``"--dt"``).
    *checks : tuple
        The checks of :func:`number`.
    kind : type
        ``float`` or ``int``.
    **kwargs
        ``default``, ``help`` and other arguments of ``add_argument``.
    """
    parser.add_argument(option, type=number(option, kind, *checks), **kwargs)


def split_names(text, option: str = "") -> list:
    """The comma-separated names of an option.

    Parameters
    ----------
    text : str or None
        The option's value.
    option : str
        The option, named in the error message.

    Returns
    -------
    list of str
        The names, blanks dropped.

    Raises
    ------
    ValueError
        A name given twice, naming the option.
    """
    names = [n.strip() for n in text.split(",") if n.strip()] if text else []
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ValueError(f"{option or 'option'}: {', '.join(twice)} given twice")
    return names


# --- options shared by several subcommands ------------------------------------------------------


def add_vehicle(parser, help: str, **kwargs) -> None:
    """``--vehicle``: a packaged vehicle id or a vehicle file (``required`` or ``default`` in kwargs).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    help : str
        The option's help text.
    **kwargs
        ``required=True`` or a ``default`` (and any other arguments of ``add_argument``).
    """
    parser.add_argument("--vehicle", help=help, **kwargs)


def add_free(parser, help: str) -> None:
    """``--free``: comma-separated free coefficients (empty: the vehicle's).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    help : str
        The option's help text.
    """
    parser.add_argument("--free", default="", help=help)


def add_effects(parser, help: str) -> None:
    """``--effects``: comma-separated effects in the model.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    help : str
        The option's help text.
    """
    parser.add_argument("--effects", default="", help=help)


def add_tracks(parser, option: str, help: str) -> None:
    """A list of Track CSVs (``--train``, ``--heldout``, ``--track``), at least one.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    option : str
        The option (``"--train"``, ``"--heldout"`` or ``"--track"``); required, it takes one or
        more CSV paths.
    help : str
        The option's help text.
    """
    parser.add_argument(option, nargs="+", required=True, metavar="CSV", help=help)


def add_score_window(parser) -> None:
    """``--score-window``: the protocol's scoring window, s (finite; <= 0: the whole run; default 60).

    Stored as ``args.window``. The old spelling ``--window`` still works, hidden, with a
    deprecation note (:class:`DeprecatedAlias`): it meant the fit window in ``bayesid fit``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    """
    add_number(parser, "--score-window", dest="window", default=60.0, metavar="SECONDS", help=SCORE_WINDOW_HELP)
    _add_alias(parser, "--window", "--score-window", "window")


def add_floor(parser) -> None:
    """``--floor``: what the noise floor of a diagnosis holds (``DiagnoseOptions.floor``):
    ``coefficients`` (default), the measured noise and the base fit's coefficient uncertainty, or
    ``noise``, a perfect model's error.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    """
    parser.add_argument(
        "--floor",
        choices=("coefficients", "noise"),
        default="coefficients",
        help="what the noise floor holds: coefficients (default): the measured noise and the base fit's coefficient "
        "uncertainty at it (draws from the inverse Fisher information), so that held-out runs the training runs do "
        "not determine (turns after zigzags) are not read as a missing effect; noise: the measured noise alone (a "
        "perfect model's error, the rule before issue 67's controls)",
    )


def add_fit_window(parser, *checks, default, help: str, dest: str = "fit_window", alias: bool = False) -> None:
    """``--fit-window``: the window of the training fits (multiple shooting), s.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    *checks : tuple
        ``(predicate, message)`` pairs the window must pass, as in :func:`number`.
    default : float or None
        The option's default, s.
    help : str
        The option's help text.
    dest : str, default "fit_window"
        The attribute of the parsed arguments that holds it.
    alias : bool, default False
        Also take the old spelling ``--window``, hidden, with a deprecation note
        (:class:`DeprecatedAlias`; ``bayesid fit`` called its fit window so).
    """
    add_number(parser, "--fit-window", *checks, dest=dest, default=default, metavar="SECONDS", help=help)
    if alias:
        _add_alias(parser, "--window", "--fit-window", dest, *checks)


def _add_alias(parser, old: str, new: str, dest: str, *checks) -> None:
    parser.add_argument(
        old,
        type=number(old, float, *checks),
        dest=dest,
        action=DeprecatedAlias,
        new=new,
        default=argparse.SUPPRESS,
        help=argparse.SUPPRESS,
    )


def add_dt(parser, default, help: str, auto: bool = False) -> None:
    """``--dt``: the model's integration step, s (positive), or ``auto``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    default : float or None
        The option's default, s; ``None`` when the command picks the step itself (its help text
        says how).
    help : str
        The option's help text.
    auto : bool, default False
        Accept ``--dt auto`` as well (the string ``"auto"``: the command refines the step itself,
        :mod:`bayesid.estimation.stepcheck`).
    """
    parse = number("--dt", float, POSITIVE)
    if not auto:
        parser.add_argument("--dt", type=parse, default=default, help=help)
        return

    def parse_auto(text: str):
        return "auto" if text.strip().lower() == "auto" else parse(text)

    parse_auto.__name__ = "float"
    parser.add_argument("--dt", type=parse_auto, default=default, help=help)


def add_max_nfev(parser, help: str) -> None:
    """``--max-nfev``: least-squares iterations (positive; default 60).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    help : str
        The option's help text.
    """
    add_number(parser, "--max-nfev", POSITIVE, kind=int, default=60, help=help)


def add_weighting(parser) -> None:
    """``--weighting``: the channel weights of the fits.

    The choices are :data:`WEIGHTINGS` (default ``""``: the model's), the help text
    :data:`WEIGHTING_HELP`.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    """
    parser.add_argument("--weighting", choices=WEIGHTINGS, default="", help=WEIGHTING_HELP)


def add_start(parser) -> None:
    """``--start``: the window start rule.

    The choices are :data:`bayesid.protocol.START_RULES` (default ``auto``), the help text
    :data:`START_HELP`.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    """
    parser.add_argument("--start", choices=protocol.START_RULES, default="auto", help=START_HELP)


def add_inputs(parser) -> None:
    """``--inputs``: how the logged inputs are reconstructed between samples, and
    ``--rudder-rate``: the gear's rate of ``--inputs rate`` (deg/s, positive).

    The choices are :data:`bayesid.models.context.INPUT_RECONSTRUCTIONS` (default ``hold``),
    the help text :data:`INPUTS_HELP`.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    """
    parser.add_argument("--inputs", choices=INPUT_RECONSTRUCTIONS, default="hold", help=INPUTS_HELP)
    add_number(
        parser,
        "--rudder-rate",
        POSITIVE,
        default=None,
        metavar="DEG_S",
        help="the steering gear's rate of --inputs rate, deg/s; none: the ship file's [service] rudder_rate_deg_s",
    )


def add_leadin(parser) -> None:
    """``--leadin``: the lead-in of the fitted start rule, s (>= 0; 0: the protocol's).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    """
    add_number(
        parser,
        "--leadin",
        NON_NEGATIVE,
        default=0.0,
        help=f"lead-in of the fitted start rule, s (0: {protocol.LEADIN_S:g} s or "
        f"{protocol.LEADIN_SAMPLES} samples of the slowest log, at most the scoring window)",
    )


def add_seed(parser, help: str) -> None:
    """``--seed``: a random seed (>= 0; default 0).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    help : str
        The option's help text.
    """
    add_number(parser, "--seed", NON_NEGATIVE, kind=int, default=0, help=help)


def add_prior(parser, help: str) -> None:
    """``--prior``: file (the vehicle file's ``[prior]``) or none.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    help : str
        The option's help text.
    """
    parser.add_argument("--prior", choices=("file", "none"), default="file", help=help)


def add_jobs(parser) -> None:
    """``--jobs`` and ``--scheduler`` (:func:`bayesid.tasks.add_arguments`).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    """
    tasks.add_arguments(parser)


def add_out(parser, help: str | None = None) -> None:
    """``--out``: the output folder (or file), required.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    help : str, optional
        The option's help text (none by default).
    """
    parser.add_argument("--out", required=True, help=help)


def add_overwrite(parser) -> None:
    """``--overwrite``: replace this command's earlier output in ``--out``.

    The command's :func:`bayesid.cli.outputs.check_out` acts on it.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    """
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace what this command wrote before in --out (a non-empty --out is refused otherwise)",
    )


def discovery_options(args):
    """The discovery and design options of ``--max-order``, ``--alternatives``, ``--compare``,
    ``--no-design`` and ``--seed``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options.

    Returns
    -------
    tuple
        ``(DiscoveryOptions, DiscriminationOptions or None)``: no design without alternatives.
    """
    from ..analysis.gap.design import DiscriminationOptions
    from ..analysis.gap.discovery import DiscoveryOptions

    found = DiscoveryOptions(
        max_order=args.max_order, n_alternatives=args.alternatives, compare=compare_terms(args.compare)
    )
    off = args.no_design or args.alternatives == 0
    return found, None if off else DiscriminationOptions(seed=args.seed)


def compare_terms(value: str) -> tuple:
    """The terms of ``--compare``: comma-separated names, or the kept terms and their
    alternatives read from an earlier round's ``diagnosis.json`` (a value ending in ``.json``).

    Parameters
    ----------
    value : str
        The option's value ("" for none).

    Returns
    -------
    tuple of str
        The term names, in order, each once.

    Raises
    ------
    ValueError
        The file is missing, not JSON or lists no discovered term (named with ``--compare``);
        an empty name in the list.
    """
    value = (value or "").strip()
    if not value:
        return ()
    if not value.lower().endswith(".json"):
        names = [n.strip() for n in value.split(",")]
        if not all(names):
            raise ValueError(f"--compare: an empty term name in {value!r}")
        return tuple(dict.fromkeys(names))
    import json

    path = Path(value)
    if not path.is_file():
        raise ValueError(f"--compare: {path}: no such file (an earlier round's diagnosis.json)")
    try:
        items = json.loads(path.read_text()).get("discovered") or []
        kept = [r for r in items if r.get("kept")]
        names = [r["term"] for r in kept] + [a["term"] for r in kept for a in r.get("alternatives") or []]
    except (ValueError, AttributeError, KeyError, TypeError) as exc:
        raise ValueError(f"--compare: {path}: not a diagnosis.json with a 'discovered' list ({exc})") from None
    if not names:
        raise ValueError(f"--compare: {path}: the earlier round kept no term; nothing to compare")
    return tuple(dict.fromkeys(names))


def add_discovery(parser, default_on: bool) -> None:
    """Structure discovery's options: ``--max-order``, ``--alternatives``, ``--compare``, ``--no-design``,
    ``--write-vehicle`` (and ``--no-discover`` where discovery is a stage that may be skipped).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    default_on : bool
        Discovery is a stage of the subcommand (``--no-discover`` skips it).
    """
    if default_on:
        parser.add_argument(
            "--no-discover",
            action="store_true",
            help="skip structure discovery (the terms the model lacks) when the remainder is significant",
        )
    add_number(
        parser,
        "--max-order",
        at_least(1),
        (lambda v: v <= 3, "{option} must be at most 3, not {value}"),
        kind=int,
        default=3,
        help="highest number of factors of a candidate term (1-3)",
    )
    add_number(
        parser,
        "--alternatives",
        at_least(0),
        kind=int,
        default=2,
        help="refit this many further candidates per degree of freedom (score test), those a selected term's "
        "collinear group stood for and this many set aside as mimicked, and name every one the held-out runs "
        "cannot separate from a kept term (0: name the selected terms alone)",
    )
    parser.add_argument(
        "--compare",
        default="",
        metavar="TERMS|DIAGNOSIS.json",
        help="terms refitted and judged whatever the selection says: comma-separated names, or the kept terms and "
        "their alternatives from an earlier round's diagnosis.json (after adding the designed run)",
    )
    parser.add_argument(
        "--no-design",
        action="store_true",
        help="do not rank the standard runs that would separate a kept term from its alternatives",
    )
    parser.add_argument(
        "--write-vehicle",
        default="",
        metavar="PATH",
        help="write the vehicle file with the kept terms added, and a named ship effect's coefficients (the wake "
        "in a turn's C1, C2, C2m; a shifted tR, tP, wP or Xuu) set (ready for bayesid fit); empty: not written",
    )
