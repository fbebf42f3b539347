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


# -- worker counts ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("cores", [1, 2, 8])
def test_worker_count_is_capped_at_the_cores_and_the_work_and_says_so(cores, monkeypatch):
    """Every ``--jobs`` (1..100, and -1..-cores) and every amount of work (1..20 blocks): at least one
    process, never more than the cores or the blocks, all of them when that allows; a note exactly
    when fewer run than were asked for."""
    from avbench.studies import workers

    monkeypatch.setattr(workers.os, "cpu_count", lambda: cores)
    for jobs in [*range(1, 101), *range(-cores, 0)]:
        asked = jobs if jobs > 0 else cores + 1 + jobs
        for work in range(1, 21):
            n = workers.worker_count(jobs, work)
            assert n == max(1, min(asked, cores, work)), (jobs, work, n)
            note = workers.workers_note(jobs, work)
            assert (note is not None) == (jobs > 0 and n < jobs), (jobs, work, note)
            if note:
                assert f"--jobs {jobs}: {n} worker" in note


def test_a_study_asked_for_64_jobs_runs_as_many_as_cores_and_blocks_and_says_so(tmp_path, capsys):
    """``--jobs 64`` on two blocks of work: min(cores, 2) workers, said on stderr, the same rows as
    ``--jobs 1``."""
    from conftest import study_toml

    from avbench.studies.config import load_config
    from avbench.studies.runner import run_study

    (tmp_path / "s.toml").write_text(study_toml(replicates=2, block_size=2))
    cfg = load_config(tmp_path / "s.toml")
    one = run_study(cfg, tmp_path / "one", n_jobs=1, progress=False, make_report=False)
    capsys.readouterr()
    many = run_study(cfg, tmp_path / "many", n_jobs=64, progress=False, make_report=False)
    assert f"--jobs 64: {min(os.cpu_count() or 1, 2)} worker process(es)" in capsys.readouterr().err
    cols = ["gyro", "replicate", "estimator", "coefficient", "estimate"]
    assert one[cols].equals(many[cols])
