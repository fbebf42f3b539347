"""Outputs are planned before the work and written as one set (avbench/outputs.py, recordings/plan.py).

* A run interrupted before its renames -- a writer that raises, a rename that fails, a real SIGTERM
  sent to a real ``avbench estimate`` between two writes -- leaves the previous set byte for byte and no
  temporary file; a SIGTERM during the renames is held back until the new set is whole.
* Output names made of any text are file names in ``--out`` (property test over generated strings).
* Every refusal of the plan comes before the first fit and writes nothing.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from avbench import outputs
from avbench.outputs import NAME_BYTES, safe_name, tmp_name, write_set
from avbench.recordings.plan import OutputPlan, output_stem

ENV = {**os.environ, "MPLBACKEND": "Agg"}


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


# -- write_set ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("fail_at", [0, 1, 2])
def test_a_writer_that_raises_leaves_the_previous_set(tmp_path, fail_at):
    names = ["a.png", "b.csv", "c.json"]
    write_set([(tmp_path / n, (lambda n=n: f"old {n}".encode())) for n in names])
    before = _snapshot(tmp_path)

    def render(i, n):
        if i == fail_at:
            raise RuntimeError("midway")
        return f"new {n}".encode()

    with pytest.raises(RuntimeError, match="midway"):
        write_set([(tmp_path / n, (lambda i=i, n=n: render(i, n))) for i, n in enumerate(names)])
    assert _snapshot(tmp_path) == before  # no new file, no temporary file


@pytest.mark.parametrize("fail_at", [0, 1, 2])
def test_a_rename_that_fails_puts_every_replaced_file_back(tmp_path, monkeypatch, fail_at):
    names = ["a.png", "b.csv", "c.json"]
    write_set([(tmp_path / n, (lambda n=n: f"old {n}".encode())) for n in names[:2]])  # c.json is new
    before = _snapshot(tmp_path)
    real, calls = os.replace, []

    def replace(src, dst):
        if Path(dst).name in names:
            calls.append(dst)
            if len(calls) == fail_at + 1:
                raise OSError(28, "No space left on device")
        return real(src, dst)

    monkeypatch.setattr(outputs.os, "replace", replace)
    with pytest.raises(OSError):
        write_set([(tmp_path / n, (lambda n=n: f"new {n}".encode())) for n in names])
    monkeypatch.undo()
    assert _snapshot(tmp_path) == before


def test_a_complete_set_replaces_the_previous_one(tmp_path):
    write_set([(tmp_path / "a", lambda: b"1"), (tmp_path / "b", lambda: b"2")])
    write_set([(tmp_path / "a", lambda: b"3"), (tmp_path / "b", lambda: b"4")])
    assert _snapshot(tmp_path) == {"a": b"3", "b": b"4"}


# -- a real avbench estimate, sent SIGTERM between writes ----------------------------------------------

_KILLER = r"""
import os, signal, sys
import avbench.recordings.plan as plan
import avbench.outputs as outputs
from avbench.cli import main

when = sys.argv[1]
if when == "between writes":  # the second file is rendered, then SIGTERM arrives
    real_write_set = plan.write_set
    def write_set(items):
        items = list(items)
        def late(render, k):
            def r():
                if k == 2:
                    os.kill(os.getpid(), signal.SIGTERM)
                return render()
            return r
        return real_write_set([(p, late(render, k)) for k, (p, render) in enumerate(items)])
    plan.write_set = write_set
else:  # SIGTERM while the files are renamed into place
    real_commit = outputs._commit
    def commit(temps):
        os.kill(os.getpid(), signal.SIGTERM)
        real_commit(temps)
    outputs._commit = commit
sys.exit(main(sys.argv[2:]))
"""


def _estimate(args, when=None):
    cmd = [sys.executable, "-c", _KILLER, when] if when else [sys.executable, "-m", "avbench.cli"]
    return subprocess.run([*cmd, "estimate", *map(str, args)], capture_output=True, text=True, env=ENV, timeout=600)


@pytest.fixture
def imu(tmp_path):
    rng = np.random.default_rng(3)
    n = 3000
    f = tmp_path / "imu.npz"
    np.savez(f, gyro=1e-3 * rng.standard_normal((n, 3)), accel=np.array([0, 0, 9.8]) + 1e-2 * rng.standard_normal((n, 3)),
             t=np.arange(n) / 100.0)
    return f


def test_sigterm_between_writes_leaves_the_previous_set(tmp_path, imu):
    out = tmp_path / "out"
    base = [imu, "--units", "rad/s", "--method", "wls", "--no-progress", "--out", out, "--kalibr", out / "imu.yaml"]
    first = _estimate([*base, "--title", "first"])
    assert first.returncode == 0, first.stderr
    before = _snapshot(out)
    assert len(before) == 6  # two figures, the AV table, the two coefficient files, the yaml
    r = _estimate([*base, "--title", "second"], "between writes")
    assert r.returncode == 143, r.stderr
    assert "interrupted by SIGTERM" in r.stderr and "Traceback" not in r.stderr
    assert _snapshot(out) == before


def test_sigterm_during_the_renames_waits_for_the_new_set(tmp_path, imu):
    out = tmp_path / "out"
    base = [imu, "--units", "rad/s", "--method", "wls", "--no-progress", "--out", out]
    assert _estimate([*base, "--title", "first"]).returncode == 0
    before = _snapshot(out)
    r = _estimate([*base, "--title", "second", "--method", "wls,ols"], "during renames")
    assert r.returncode == -signal.SIGTERM, r.stderr  # ended by the signal, once the set was in place
    after = _snapshot(out)
    assert sorted(after) == sorted(before)  # no temporary file left
    changed = sorted(k for k in after if after[k] != before[k])  # the AV table depends on neither title nor method
    assert changed == sorted(k for k in after if not k.endswith("_av.csv")), changed
    assert b'"ols"' in after["imu_coefficients.json"]


# -- names --------------------------------------------------------------------------------------------

@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.text(min_size=0, max_size=400))
def test_any_text_makes_a_file_name_in_the_folder(tmp_path, text):
    """Whatever a column or a file is called, its output names are files in --out: no separator, no
    hidden or parent name, no ``$``, short enough for a temporary name beside them."""
    name = safe_name(text)
    assert name and "/" not in name and "\x00" not in name and "$" not in name
    assert not name.startswith(".") and name not in (".", "..")
    assert len(name.encode("utf-8", "surrogateescape")) <= NAME_BYTES
    assert len(tmp_name(tmp_path / f"{name}_coefficients.json").name.encode("utf-8", "surrogateescape")) <= 255
    stem = output_stem(Path("rec") / f"{text or 'x'}.csv", text)
    target = tmp_path / f"{stem}_coefficients.json"
    target.write_bytes(b"{}")
    assert target.parent == tmp_path
    target.unlink()


LETTERS = st.characters(whitelist_categories=("Ll", "Lu", "Nd"))


@given(a=st.text(LETTERS, min_size=NAME_BYTES + 1, max_size=300), b=st.text(LETTERS, min_size=NAME_BYTES + 1, max_size=300))
def test_distinct_long_texts_keep_distinct_names(a, b):
    """A name cut to length ends with a digest of the whole text: two long texts differing anywhere
    (even after the cut) keep two names."""
    assert (safe_name(a) == safe_name(b)) == (a == b)


def test_plan_refusals_name_the_option_and_write_nothing(tmp_path):
    rec = tmp_path / "r.npz"
    rec.write_bytes(b"x")
    plan = OutputPlan(tmp_path / "out")
    plan.add("r_av.csv", lambda r: b"")
    plan.add_path(rec, "--kalibr", lambda r: b"")
    with pytest.raises(ValueError, match=r"--kalibr .*is the input recording"):
        plan.check([rec])
    twice = OutputPlan(tmp_path / "out")
    twice.add("r_imu.yaml", lambda r: b"")
    twice.add_path(tmp_path / "out" / "r_imu.yaml", "--kalibr", lambda r: b"")
    with pytest.raises(ValueError, match=r"--kalibr .*is also the output 'r_imu.yaml'"):
        twice.check([rec])
    assert not (tmp_path / "out").exists()


def test_estimate_refusals_come_before_the_fits(tmp_path, imu):
    """--kalibr on the input, --kalibr where nothing can be written, a --set relation, a bad --title: one
    line, exit 2, nothing written, the input intact."""
    before = imu.read_bytes()
    out = tmp_path / "out"
    cases = [(["--kalibr", imu], "is the input recording"),
             (["--kalibr", "/proc/avbench-nope/imu.yaml"], "--kalibr '/proc/avbench-nope/imu.yaml'"),
             (["--method", "gmwm", "--set", "gmwm.filter_tf=0.01"], "--set: estimator 'gmwm': filter_tf"),
             (["--title", "$\\frac{1}{$"], "--title")]
    for extra, words in cases:
        r = _estimate([imu, "--units", "rad/s", "--method", "wls", "--out", out, *extra])
        assert r.returncode == 2 and words in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert not out.exists() or not any(out.iterdir())
    assert imu.read_bytes() == before


def test_names_from_columns_and_stems_are_safe(tmp_path):
    """--column values with brackets and slashes, ``..`` and ``$`` in them, and a 250-byte stem make
    outputs inside --out, and the figure's title keeps a file name's ``$`` as a character."""
    x = np.random.default_rng(4).standard_normal((2000, 3)) * 1e-3
    f = tmp_path / ("r$x$" + "L" * 240 + ".csv")
    np.savetxt(f, np.column_stack([np.arange(2000) / 100, x]), delimiter=",", header="t,gx [deg/s],../x,$y$",
               comments="")
    out = tmp_path / "out"
    for column in ("gx [deg/s]", "../x", "$y$"):
        r = _estimate([f, "--column", column, "--units", "deg/s", "--method", "wls", "--out", out, "--no-progress"])
        assert r.returncode == 0, r.stderr
    names = sorted(p.name for p in out.iterdir())
    assert len(names) == 12 and all(len(n.encode()) <= 255 and "$" not in n for n in names)
    assert not any(tmp_path.glob("x_*")) and not any(p.name.startswith(".") for p in out.iterdir())
