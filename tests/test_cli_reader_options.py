"""Every command that reads a recording takes the same reader options: one definition
(:func:`avbench.cli.reader_options_parser`), whose dests are the keywords of
:func:`avbench.recordings.load.load_recording`. Checked on the parsers themselves, attribute by attribute."""

from __future__ import annotations

import argparse
import inspect

import pytest

from avbench.cli import build_parser, reader_options_parser

#: the commands that read a recording
READING_COMMANDS = ("estimate", "deviations")
#: what an option is made of: a difference in any of these is a drift between commands
ATTRIBUTES = ("option_strings", "dest", "default", "help", "choices", "type", "nargs", "const", "metavar", "required")


def _subparsers(parser):
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices


def _options(parser) -> dict:
    """{dest: {attribute: value}} of a parser's options (its -h left out)."""
    return {a.dest: {k: getattr(a, k) for k in ATTRIBUTES} | {"action": type(a).__name__}
            for a in parser._actions if a.option_strings and not isinstance(a, argparse._HelpAction)}


@pytest.fixture(scope="module")
def commands():
    return _subparsers(build_parser())  # every command built (no argv: estimate's real parser too)


def test_the_reader_options_are_the_keywords_of_load_recording():
    from avbench.recordings.load import READER_OPTIONS, load_recording

    dests = tuple(_options(reader_options_parser()))
    assert dests == READER_OPTIONS
    keywords = [p.name for p in inspect.signature(load_recording).parameters.values() if p.kind is p.KEYWORD_ONLY]
    assert [k for k in keywords if k != "progress"] == list(READER_OPTIONS)


@pytest.mark.parametrize("command", READING_COMMANDS)
def test_each_reading_command_has_the_reader_options_exactly(commands, command):
    shared = _options(reader_options_parser())
    mine = _options(commands[command])
    missing = sorted(set(shared) - set(mine))
    assert not missing, f"avbench {command} lacks {missing}"
    for dest, attrs in shared.items():
        # help after _plain_help, which every command's help goes through (idempotent on plain text)
        assert mine[dest] == attrs, f"avbench {command} {attrs['option_strings']}: {mine[dest]} != {attrs}"


def test_estimate_and_deviations_reader_options_are_identical(commands):
    est, dev = _options(commands["estimate"]), _options(commands["deviations"])
    for dest in _options(reader_options_parser()):
        assert est[dest] == dev[dest], f"--{dest}: estimate {est[dest]} != deviations {dev[dest]}"


def test_a_drift_is_caught():
    """The comparison sees a changed default, help, choices or type (it is not vacuous)."""
    base = _options(reader_options_parser())
    for attr, value in (("default", "s"), ("help", "units"), ("choices", ["s"]), ("type", str)):
        p = reader_options_parser()
        action = next(a for a in p._actions if a.dest == "time_units")
        setattr(action, attr, value)
        assert _options(p)["time_units"] != base["time_units"], attr


def test_estimate_is_listed_without_building_its_parser_but_reads_alike_when_built():
    """``avbench deviations ...`` does not import the estimate command; ``avbench estimate ...`` builds it
    with the shared options."""
    listed = _subparsers(build_parser(["deviations", "x.csv"]))
    assert not _options(listed["estimate"])
    built = _subparsers(build_parser(["estimate", "x.csv"]))
    assert set(_options(reader_options_parser())) <= set(_options(built["estimate"]))


def test_deviations_takes_estimates_defaults(tmp_path, capsys):
    """A time column in ms without a unit: both commands infer it from the stamps (no '--time-units s')."""
    import numpy as np

    from avbench.cli import main

    rng = np.random.default_rng(0)
    n = 4000
    f = tmp_path / "r.csv"
    np.savetxt(f, np.column_stack([np.arange(n) * 10, rng.normal(0, 0.1, n)]), delimiter=",",
               header="time,gx", comments="", fmt=["%d", "%.6f"])
    assert main(["deviations", str(f), "--units", "deg/s", "--deviation", "oadev", "--out", str(tmp_path / "d"),
                 "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "samples at 100 Hz" in out
