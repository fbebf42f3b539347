"""Rules every ``avbench`` command holds, each tested over every command (or every one that reads or
writes files), not case by case: empty option values refused alike; no output equal to an input;
one writer per output folder."""

from __future__ import annotations

import argparse
import os

import pytest

from avbench.cli import build_parser, main
from avbench.text import empty_is_none


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


CASES = [(c, a.option_strings[-1]) for c in _commands() for a in _value_options(c)[0] if a.type is not empty_is_none]
TITLED = [c for c in _commands() if any("--title" in a.option_strings for a in _value_options(c)[0])]


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


def test_every_command_taking_a_title_reads_an_empty_one_as_none():
    """``--title`` is typed alike wherever it is taken: an empty value means no title."""
    assert TITLED == ["deviations", "estimate"]
    for command in TITLED:
        (title,) = [a for a in _value_options(command)[0] if "--title" in a.option_strings]
        assert title.type is empty_is_none, command


@pytest.mark.parametrize("blank", ["", "  "])
@pytest.mark.parametrize("command", TITLED)
def test_an_empty_title_draws_no_title(command, blank, tmp_path, monkeypatch):
    """``--title ''`` (or blank): the command runs and its figures' titles name the sensor and axis
    only: neither the file name (the default title) nor a dangling separator."""
    import matplotlib.axes
    import numpy as np

    f = tmp_path / "imu_rec.csv"
    np.savetxt(f, np.random.default_rng(2).standard_normal((4000, 1)) * 1e-3, header="gx [rad/s]", comments="")
    titles = []
    real = matplotlib.axes.Axes.set_title
    monkeypatch.setattr(matplotlib.axes.Axes, "set_title",
                        lambda self, label, *a, **kw: (titles.append(str(label)), real(self, label, *a, **kw))[1])
    argv = [command, str(f), "--fs", "100", "--out", str(tmp_path / "out"), "--title", blank, "--no-progress"]
    assert main(argv + (["--method", "wls"] if command == "estimate" else [])) == 0
    drawn = [t for t in titles if t]
    assert drawn and all("imu_rec" not in t and not t.startswith((" ", "—")) for t in drawn), drawn


@pytest.mark.parametrize("command", TITLED)
def test_every_command_refuses_a_title_matplotlib_cannot_draw_before_reading(command, tmp_path, capsys):
    assert main([command, str(tmp_path / "missing.csv"), "--fs", "100", "--title", r"$\frac{$"]) == 2
    assert "--title" in capsys.readouterr().err
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


# -- studies: inputs, labels, one writer, the printed table -------------------------------------------------------


def _study(tmp_path, extra_study="", replicates=2, name="s.toml", **kw):
    from conftest import study_toml

    p = tmp_path / name
    p.write_text(study_toml(replicates=replicates, block_size=2, extra_study=extra_study, **kw))
    return p


PAPER_CSV = "gyro,method,coefficient,unit,mean,std\ng1,ols,N,deg/sqrt(h),0.5,0.1\n"


@pytest.mark.parametrize("output", ["table.csv", "table.md", "tidy.csv", "leaderboard.md", "av_g1.png"])
def test_a_study_never_writes_over_its_paper_table_or_its_own_file(output, tmp_path, capsys):
    """A study's inputs (its TOML, its paper_table) named like one of its outputs, with ``--out`` their
    folder: refused before any work, naming both, every input unchanged."""
    (tmp_path / output).write_text(PAPER_CSV)
    cfg = _study(tmp_path, extra_study=f'paper_table = "{output}"')
    before = (tmp_path / output).read_bytes()
    assert main(["run", str(cfg), "--out", str(tmp_path), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "paper_table" in err and output in err, err
    assert (tmp_path / output).read_bytes() == before
    assert not (tmp_path / "_shards").exists()
    cfg2 = tmp_path / "sub" / output
    cfg2.parent.mkdir()
    cfg2.write_text(cfg.read_text().replace(f'paper_table = "{output}"', ""))
    before = cfg2.read_bytes()
    assert main(["run", str(cfg2), "--out", str(cfg2.parent), "--no-progress"]) == 2
    assert "the study file" in capsys.readouterr().err
    assert cfg2.read_bytes() == before


@pytest.mark.parametrize(("a", "b"), [("a b", "a_b"), ("x/y", "x?y"), ("é" * 100, "é" * 100 + "!")])
def test_gyro_labels_giving_one_figure_name_or_too_long_a_name_are_refused_before_any_work(a, b, tmp_path, capsys):
    """Two gyro labels whose figures would be one file (or a label whose file name no file system takes)
    are refused when the study is read, naming the labels: nothing computed, nothing written."""
    text = _study(tmp_path).read_text().replace('name = "g1"', f'name = "g1"\nlabel = "{a}"').replace(
        'name = "g2"', f'name = "g2"\nlabel = "{b}"')
    (tmp_path / "s.toml").write_text(text)
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert ("give one figure file name" in err and repr(a) in err) or "bytes" in err, err
    assert not (tmp_path / "out").exists()


def test_a_markdown_table_keeps_its_columns_whatever_the_labels(tmp_path, capsys):
    """Estimator and gyro labels with ``|`` (``wls|NK``): every row of every Markdown table of the report
    has as many cells as its header (escaped pipes are no separators)."""
    import re

    text = _study(tmp_path).read_text().replace('name = "wls"', 'name = "wls"\nlabel = "wls|NK"').replace(
        'name = "g2"', 'name = "g2"\nlabel = "g|2"')
    (tmp_path / "s.toml").write_text(text)
    out = tmp_path / "out"
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(out), "--no-progress"]) == 0
    split = re.compile(r"(?<!\\)\|")
    for md in out.glob("*.md"):
        width = None
        for line in md.read_text().splitlines():
            if not line.startswith("|"):
                width = None
                continue
            cells = len(split.split(line))
            width = cells if width is None else width
            assert cells == width, (md.name, line)
    assert r"wls\|NK" in (out / "table.md").read_text()


def test_two_runs_into_one_folder_the_second_is_refused_naming_the_first(tmp_path, capsys):
    """A folder a live avbench run writes into (its lock names a live process): a second run is refused
    naming that process, and writes nothing; a lock left by a process that is gone is taken over."""
    import subprocess
    import sys

    cfg = _study(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (out / ".avbench.lock").write_text(f"{live.pid}\navbench run other.toml\n")
        assert main(["run", str(cfg), "--out", str(out), "--no-progress"]) == 2
        err = capsys.readouterr().err
        assert f"another avbench run (process {live.pid}: avbench run other.toml)" in err
        assert sorted(p.name for p in out.iterdir()) == [".avbench.lock"]
    finally:
        live.kill()
        live.wait()
    assert main(["run", str(cfg), "--out", str(out), "--no-progress"]) == 0  # its process is gone: taken over
    assert not (out / ".avbench.lock").exists()


def test_run_prints_its_own_table_not_the_folders(tmp_path, capsys, monkeypatch):
    """The table ``avbench run`` prints is this run's result: table.md is never read back (another run's
    could be there by then)."""
    from pathlib import Path

    cfg = _study(tmp_path)
    read = Path.read_text

    def guarded(self, *a, **k):
        assert self.name != "table.md", "table.md read back from disk"
        return read(self, *a, **k)

    monkeypatch.setattr(Path, "read_text", guarded)
    assert main(["run", str(cfg), "--out", str(tmp_path / "out"), "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert printed.strip() == read(tmp_path / "out" / "table.md").strip()


# -- text inputs with a byte-order mark -------------------------------------------------------------------------


def _text_inputs():
    """Every kind of text a command reads, as (kind, file name, text, how it is read)."""
    import functools

    import numpy as np
    from conftest import study_toml

    from avbench.recordings.load import load_recording
    from avbench.studies.config import load_config
    from avbench.studies.papers import load_paper_table

    rng = np.random.default_rng(3)
    rows = [(i / 100, *rng.standard_normal(2) * 1e-3) for i in range(400)]

    def table(sep, header=True):
        head = f"t [s]{sep}gx [rad/s]{sep}gy [rad/s]\n" if header else ""
        return head + "".join(sep.join(f"{v:.6g}" for v in r) + "\n" for r in rows)

    def recording(p, **options):
        rec, timing, sensors = load_recording(p, units="rad/s", **options)
        return [c.name for c in rec.channels], timing.dt, [s.axes[a].tolist() for s in sensors for a in s.axes]

    return [
        ("study", "s.toml", study_toml(replicates=2, block_size=2), lambda p: load_config(p).result_key()),
        ("paper table", "p.csv", "# source: a paper\n" + PAPER_CSV, lambda p: load_paper_table(p).to_dict()),
        ("csv", "r.csv", table(","), recording),
        ("tsv", "r.tsv", table("\t"), recording),
        ("dat", "r.dat", table(" ", header=False), functools.partial(recording, fs=100.0, time="none", gyro="1,2")),
    ]


@pytest.mark.parametrize("kind", ["study", "paper table", "csv", "tsv", "dat"])
def test_every_text_input_reads_the_same_with_a_byte_order_mark(kind, tmp_path):
    """A study TOML, a paper table and a recording's text table, saved with a UTF-8 BOM (as some editors
    do), read as the same file without one."""
    (name, text, read), = [(n, t, r) for k, n, t, r in _text_inputs() if k == kind]
    plain, marked = tmp_path / "plain" / name, tmp_path / "bom" / name
    for p, enc in ((plain, "utf-8"), (marked, "utf-8-sig")):
        p.parent.mkdir()
        p.write_text(text, encoding=enc)
        if kind == "study":
            (p.parent / "table.csv").write_text(PAPER_CSV)
    assert marked.read_bytes()[:3] == b"\xef\xbb\xbf"
    assert read(marked) == read(plain)


# -- a skipped axis is said ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("command", ["estimate", "deviations", "three-cornered-hat"])
def test_every_command_reading_a_recording_says_the_constant_axis_it_skips(command, tmp_path, capsys):
    """A recording whose gyro x is constant: every command that reads it says, on the screen, that it
    skipped that axis because it is constant; ``deviations`` says it in its CSV too (a row of its own)."""
    import numpy as np

    rng = np.random.default_rng(4)
    files = []
    for k in range(3 if command == "three-cornered-hat" else 1):
        x = np.column_stack([np.full(3000, 0.5), rng.standard_normal((3000, 2)) * 1e-3])
        p = tmp_path / f"u{k}.csv"
        np.savetxt(p, x, delimiter=",", comments="", header="gx [rad/s],gy [rad/s],gz [rad/s]")
        files.append(str(p))
    extra = ["--method", "wls"] if command == "estimate" else ["--deviation", "oadev"] if command == "deviations" else []
    assert main([command, *files, "--fs", "100", *extra, "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "gx" in out and "constant" in out and "skipped" in out, out
    if command == "deviations":
        import pandas as pd

        t = pd.read_csv(tmp_path / "out" / "u0_deviations.csv")
        said = t[t["statistic"].isna()]
        assert len(said) == 1 and said["note"].str.contains("constant").all() and (said["axis"] == "x").all()


# -- no output is an input ----------------------------------------------------------------------------------------


def _input_at_an_output(command, tmp_path):
    """``(argv, the input file)`` of ``command`` with one of its inputs where one of its outputs goes."""
    import numpy as np

    rng = np.random.default_rng(6)

    def recording(name):
        p = tmp_path / name
        np.savetxt(p, rng.standard_normal((2000, 1)) * 1e-3, header="gx [rad/s]", comments="")
        return p

    if command == "run":
        (tmp_path / "table.md").write_text(PAPER_CSV)
        return ["run", str(_study(tmp_path, extra_study='paper_table = "table.md"')), "--out", str(tmp_path),
                "--no-progress"], tmp_path / "table.md"
    if command == "three-cornered-hat":
        files = [recording(n) for n in ("a.csv", "b.csv", "a_hat.csv")]
        return [command, *map(str, files), "--fs", "100", "--out", str(tmp_path)], files[2]
    if command == "estimate":
        f = tmp_path / "imu.csv"  # six axes at rest, for the Kalibr yaml
        x = rng.standard_normal((4000, 6)) * 1e-3 + [0, 0, 0, 0, 0, 9.80665]
        np.savetxt(f, x, delimiter=",", comments="",
                   header="gx [rad/s],gy [rad/s],gz [rad/s],ax [m/s^2],ay [m/s^2],az [m/s^2]")
        return [command, str(f), "--fs", "100", "--method", "wls", "--kalibr", str(f), "--out", str(tmp_path)], f
    if command == "bench":
        notes = tmp_path / "README.md"
        notes.write_text("my notes\n")
        return [command, "--report-only", "--notes", str(notes), "--out", str(tmp_path)], notes
    raise AssertionError(command)


#: every command that reads a file a user gives and writes files: (deviations names its outputs after its input
#: with a suffix, so that none can be it; simulate reads no file)
READ_AND_WRITE = ["run", "three-cornered-hat", "estimate", "bench"]


@pytest.mark.parametrize("command", READ_AND_WRITE)
def test_no_command_writes_over_one_of_its_inputs(command, tmp_path, capsys):
    """Each command, given an input where one of its outputs goes: refused before any work, exit 2, with a
    line saying which input; the input's bytes unchanged."""
    argv, victim = _input_at_an_output(command, tmp_path)
    before = victim.read_bytes()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "is the" in err and str(victim.name) in err, err
    assert victim.read_bytes() == before


# -- one writer per output folder ---------------------------------------------------------------------------------


def _writing_argv(command, tmp_path):
    """The command line of ``command`` writing a set of files, on small records made in ``tmp_path``."""
    import numpy as np

    rng = np.random.default_rng(8)
    files = []
    for k in range(3 if command == "three-cornered-hat" else 1):
        files.append(str(tmp_path / f"u{k}.csv"))
        np.savetxt(files[-1], rng.standard_normal((2000, 1)) * 1e-3, header="gx [rad/s]", comments="")
    return {"run": ["run", str(_study(tmp_path)), "--no-progress"],
            "estimate": ["estimate", *files, "--fs", "100", "--method", "wls"],
            "deviations": ["deviations", *files, "--fs", "100", "--deviation", "oadev"],
            "three-cornered-hat": ["three-cornered-hat", *files, "--fs", "100"]}[command]


@pytest.mark.parametrize("command", ["run", "estimate", "deviations", "three-cornered-hat"])
def test_every_command_refuses_a_folder_another_run_writes_into(command, tmp_path, capsys):
    """An output folder locked by a live process: every command that writes a set of files into ``--out``
    is refused, naming that process, and writes nothing there; the lock is left to its holder."""
    import subprocess
    import sys

    out = tmp_path / "out"
    out.mkdir()
    argv = _writing_argv(command, tmp_path)
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    (out / ".avbench.lock").write_text(f"{live.pid}\navbench other\n")
    _assert_refused_by(live, argv, out, capsys)


def _assert_refused_by(live, argv, out, capsys):
    """``argv`` into ``out``, which the live process ``live`` holds locked: refused, naming that process,
    nothing written beside the lock; ``live`` stopped afterwards."""
    try:
        assert main([*argv, "--out", str(out)]) == 2
        assert f"another avbench run (process {live.pid}: avbench other)" in capsys.readouterr().err
        assert sorted(p.name for p in out.iterdir()) == [".avbench.lock"]
    finally:
        live.kill()
        live.wait()


@pytest.mark.parametrize("command", ["run", "estimate", "deviations", "three-cornered-hat"])
def test_a_new_output_folder_is_locked_from_its_creation(command, tmp_path, capsys, monkeypatch):
    """Two runs into one ``--out`` that does not exist yet: the other run takes the folder's lock the
    moment it exists (simulated: a live process's lock appears as the folder is made). Every command
    that writes a set of files into ``--out`` is then refused naming that process and writes nothing
    there, exactly as for a folder that existed before."""
    import pathlib
    import subprocess
    import sys

    argv = _writing_argv(command, tmp_path)
    out = tmp_path / "new" / "out"
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    real_mkdir = pathlib.Path.mkdir

    def mkdir(self, *a, **kw):
        existed = self.exists()
        real_mkdir(self, *a, **kw)
        if self == out and not existed:  # the other run wins the race for the new folder
            (out / ".avbench.lock").write_text(f"{live.pid}\navbench other\n")

    monkeypatch.setattr(pathlib.Path, "mkdir", mkdir)
    _assert_refused_by(live, argv, out, capsys)


@pytest.mark.parametrize("command", ["estimate", "deviations", "three-cornered-hat"])
def test_a_refused_command_leaves_no_new_output_folder(command, tmp_path, capsys):
    """A command refused for its input (here a sample rate of 0) into an ``--out`` that did not exist:
    exit 2, and neither that folder nor its missing parents are left behind."""
    argv = [a if a != "100" else "0" for a in _writing_argv(command, tmp_path)]
    out = tmp_path / "new" / "out"
    assert main([*argv, "--out", str(out)]) == 2
    assert not (tmp_path / "new").exists()


# -- the same file twice ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("command", ["estimate", "three-cornered-hat"])
def test_every_command_reading_several_recordings_refuses_one_file_twice(command, tmp_path, capsys):
    """The same recording given twice (by its path, or by a link to it) where several are read together
    (``estimate --combine``, ``three-cornered-hat``): refused naming both places (pooled, it would count
    every sample twice; in the hat it gives 'negative' at every tau)."""
    import numpy as np

    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    rng = np.random.default_rng(9)
    for p in (a, b):
        np.savetxt(p, rng.standard_normal((2000, 1)) * 1e-3, header="gx [rad/s]", comments="")
    link = tmp_path / "link.csv"
    link.symlink_to(a)
    extra = ["--combine", "--method", "wls"] if command == "estimate" else []
    for files in ([a, b, a], [a, link, b]):
        files = files if command == "three-cornered-hat" else files[:2] if files[1] == link else [a, a]
        assert main([command, *map(str, files), "--fs", "100", *extra, "--out", str(tmp_path / "out")]) == 2
        err = capsys.readouterr().err
        assert "is the same file as" in err and str(files[0]) in err, err
