"""Rules every ``avbench`` command holds, each tested over every command (or every one that reads or
writes files), not case by case: empty option values refused alike; no output equal to an input;
one writer per output folder."""

from __future__ import annotations

import argparse
import os

import pytest

from avbench.cli import build_parser, main


def _commands():
    p = build_parser([])
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return sorted(sub.choices)


def _value_options(command):
    """(parser of ``command``, its options that take one value, its positionals)."""
    p = build_parser([command])
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    cp = sub.choices[command]
    opts = [a for a in cp._actions if a.option_strings and a.nargs is None and a.const is None
            and not isinstance(a, argparse._HelpAction | argparse._StoreTrueAction)]
    pos = [a for a in cp._actions if not a.option_strings]
    return opts, pos


def _positionals(pos):
    argv = []
    for a in pos:
        n = a.nargs if isinstance(a.nargs, int) else 1
        argv += [f"in{i}.csv" for i in range(n)]
    return argv


CASES = [(c, a.option_strings[-1]) for c in _commands() for a in _value_options(c)[0]]


@pytest.mark.parametrize("blank", ["", "  "])
@pytest.mark.parametrize(("command", "option"), CASES)
def test_an_empty_option_value_is_refused_by_every_command(command, option, blank, tmp_path, monkeypatch, capsys):
    """``--format ''`` is refused as ``--deviation ''`` is: every option of every command that takes a
    value, given an empty or blank one, exits 2 with a line naming the option (or argparse's usage error
    for a number or a choice), before any work: nothing is written."""
    monkeypatch.chdir(tmp_path)
    _, pos = _value_options(command)
    argv = [command, *_positionals(pos), option, blank]
    try:
        code = main(argv)
    except SystemExit as e:  # argparse: not a number / not a choice
        code = e.code
        assert option in capsys.readouterr().err
    else:
        assert option in capsys.readouterr().err
    assert code == 2
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("command", [c for c in _commands() if _value_options(c)[1]])
def test_an_empty_positional_is_refused_by_every_command(command, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    _, pos = _value_options(command)
    argv = [command, *_positionals(pos)]
    argv[1] = ""
    assert main(argv) == 2
    assert "expected a value, got an empty string" in capsys.readouterr().err
    assert os.listdir(tmp_path) == []
