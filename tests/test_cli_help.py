"""The ``bayesid`` command's help (issue 38): every option of every subcommand has help text and
shows its default, ``bayesid --help`` gives the order of use and where the documentation is, and
each meaning has one option name (the scoring window is ``--score-window``, the fit window
``--fit-window``; the old ``--window`` still works, hidden, with a deprecation note)."""

from __future__ import annotations

import argparse

import pytest

from bayesid import cli
from bayesid.cli import options as opt


def _subparsers(parser):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


SUBPARSERS = _subparsers(cli.build_parser())


def _options(parser):
    """(action, formatted help) of every option and positional a user can give."""
    fmt = parser._get_formatter()
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction | argparse._VersionAction):
            continue
        yield action, fmt._get_help_string(action) if action.help is not None else None


def test_every_command_is_walked():
    assert set(SUBPARSERS) == set(cli.COMMANDS) and len(SUBPARSERS) >= 7


@pytest.mark.parametrize("command", sorted(SUBPARSERS))
def test_every_option_has_help_and_shows_its_default(command):
    parser = SUBPARSERS[command]
    assert isinstance(parser._get_formatter(), opt.HelpFormatter), command
    missing, no_default, doubled = [], [], []
    for action, shown in _options(parser):
        name = "/".join(action.option_strings) or action.dest
        if action.help == argparse.SUPPRESS:
            continue  # a hidden deprecated alias: test_hidden_options_are_deprecated_aliases
        if not (action.help or "").strip():
            missing.append(name)
            continue
        if "(default:" in action.help:
            doubled.append(name)  # the formatter adds it: written by hand it would show twice
        if action.option_strings and "(default: " not in shown and not shown.endswith("(required)"):
            no_default.append(name)
    assert not missing, f"bayesid {command}: options without help: {missing}"
    assert not no_default, f"bayesid {command}: options whose help shows no default: {no_default}"
    assert not doubled, f"bayesid {command}: a default written into the help text: {doubled}"


@pytest.mark.parametrize("command", sorted(SUBPARSERS))
def test_hidden_options_are_deprecated_aliases(command):
    parser = SUBPARSERS[command]
    visible = {s for a in parser._actions if a.help != argparse.SUPPRESS for s in a.option_strings}
    for action in parser._actions:
        if action.help == argparse.SUPPRESS:
            assert isinstance(action, opt.DeprecatedAlias), (command, action.option_strings)
            assert action.new in visible, (command, action.new)
            twin = next(a for a in parser._actions if action.new in a.option_strings)
            assert twin.dest == action.dest, (command, action.new)


def test_a_window_option_has_one_meaning():
    """``--window`` is nobody's visible name; the scoring and fit windows are named for what they are."""
    for command, parser in SUBPARSERS.items():
        visible = {s for a in parser._actions if a.help != argparse.SUPPRESS for s in a.option_strings}
        assert "--window" not in visible, command
    for command in ("predict", "diagnose", "discover"):
        assert "--score-window" in SUBPARSERS[command]._option_string_actions, command
    for command in ("fit", "diagnose"):
        assert "--fit-window" in SUBPARSERS[command]._option_string_actions, command


@pytest.mark.parametrize(
    "argv, dest, new",
    [
        (["predict", "--model", "m.json", "--track", "a.csv", "--out", "o"], "window", "--score-window"),
        (
            ["diagnose", "--vehicle", "v", "--train", "a.csv", "--heldout", "b.csv", "--out", "o"],
            "window",
            "--score-window",
        ),
        (
            ["discover", "--model", "m.json", "--train", "a.csv", "--heldout", "b.csv", "--out", "o"],
            "window",
            "--score-window",
        ),
        (["fit", "--vehicle", "v", "--train", "a.csv", "--out", "o"], "window", "--fit-window"),
    ],
)
def test_the_old_window_spelling_still_works_with_a_note(argv, dest, new, capsys):
    parser = cli.build_parser()
    new_args = parser.parse_args(argv + [new, "12.5"])
    assert getattr(new_args, dest) == 12.5
    assert capsys.readouterr().err == ""
    old_args = parser.parse_args(argv + ["--window", "12.5"])
    assert vars(old_args) == vars(new_args)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--window is deprecated" in err and new in err, err


def test_the_old_spelling_is_checked_like_the_new(capsys):
    rc = cli.main(["fit", "--vehicle", "v", "--train", "a.csv", "--window", "-1", "--out", "o"])
    assert rc == 2 and "--window must be a positive number" in capsys.readouterr().err


def test_top_level_help_gives_the_order_of_use_and_the_docs(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert "fit -> predict -> sample -> diagnose" in out
    for command in cli.COMMANDS:
        assert f"\n    {command} " in out, command
    assert "docs/cli.rst" in out and "sphinx" in out
    listed = [c for c in cli.COMMANDS]
    assert listed[:4] == ["fit", "predict", "sample", "diagnose"]


@pytest.mark.parametrize("command", sorted(SUBPARSERS))
def test_every_command_help_prints(command, capsys):
    with pytest.raises(SystemExit) as e:
        cli.main([command, "--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: bayesid {command}") and "(default: " in out
