"""Bad data files given to ``avbench estimate``: a clear message ("avbench: error: FILE: ..." on
stderr), a non-zero exit, and nothing written for rejected input. Also the shared helpers of
:mod:`avbench.recordings.files` for the cases where NumPy's own errors do not name the file."""

from __future__ import annotations

import os

import numpy as np
import pytest

from avbench.recordings import files as data_files
from avbench.cli import main

pytest.importorskip("avbench.recordings.estimate")

X = np.random.default_rng(0).standard_normal(400)
GOOD = "\n".join(f"{v:.6f}" for v in X)


def _npy(arr):
    def make(p):
        np.save(p, arr)
    return make


def _text(s):
    return lambda p: p.write_text(s)


def _bytes(b):
    return lambda p: p.write_bytes(b)


def _replace_row(i, token):
    rows = GOOD.splitlines()
    rows[i] = token
    return "\n".join(rows)


CASES = [
    # name, file name, writer, extra args, expected words in the message
    ("nan in csv", "r.csv", _text(_replace_row(10, "nan")), [], "non-finite sample(s) (NaN/inf), the first at index 10"),
    ("inf in csv", "r.csv", _text(_replace_row(7, "-inf")), [], "non-finite sample(s) (NaN/inf), the first at index 7"),
    ("overflow in csv", "r.csv", _text(_replace_row(3, "1e400")), [], "non-finite sample(s)"),
    ("nan in npy", "r.npy", _npy(np.where(np.arange(400) == 3, np.nan, X)), [], "the first at index 3"),
    ("inf in npz", "r.npz", lambda p: np.savez(p, data=np.where(np.arange(400) == 5, np.inf, X)), [], "the first at index 5"),
    ("3-D npy", "r.npy", _npy(X.reshape(10, 8, 5)), [], "expected a 1-D record or a 2-D (samples x columns) table, got shape (10, 8, 5)"),
    ("2 columns, no --column", "r.npy", _npy(X.reshape(200, 2)), [], "2 columns (column 0, column 1); choose them with --gyro"),
    ("column out of range", "r.npy", _npy(X.reshape(200, 2)), ["--column", "2"], "column index 2 out of range (--gyro/--column); expected 0..1"),
    ("unknown column name", "r.csv", _text("gx,gy\n" + "\n".join(f"{v},{v}" for v in X)), ["--column", "gz"], "unknown column 'gz' (--gyro/--column); expected one of gx, gy"),
    ("empty npy", "r.npy", _npy(np.array([])), [], "the record is empty"),
    ("empty file", "r.csv", _text(""), [], "the file is empty"),
    ("blank lines only", "r.csv", _text("\n \n\n"), [], "empty"),
    ("header only", "r.csv", _text("rate_x\n"), [], "a header but no samples"),
    ("text among numbers", "r.csv", _text(_replace_row(12, "abc")), [], "line 13: column 0 is not numeric ('abc')"),
    ("text column", "r.csv", _text("\n".join(f"{v},word" for v in X)), ["--column", "1"], "is not numeric"),
    ("strings in npy", "r.npy", _npy(np.array(["1.0"] * 100)), [], "not numeric (dtype <U3)"),
    ("complex npy", "r.npy", _npy(X.astype(complex)), [], "not numeric (dtype complex128)"),
    ("bool npy", "r.npy", _npy(X > 0), [], "not numeric (dtype bool)"),
    ("object npy", "r.npy", lambda p: np.save(p, np.array([1.0, "a"] * 20, dtype=object), allow_pickle=True), [], "not a readable .npy array"),
    ("ragged rows", "r.csv", _text("1,2\n3\n4,5,6\n" + "\n".join(f"{v},{v}" for v in X)), [], "cannot parse as a text table"),
    ("binary as csv", "r.csv", _bytes(bytes(range(256)) * 8), [], "not a text file"),
    ("latin-1 text", "r.csv", _bytes("café\n".encode("latin-1") + GOOD.encode()), [], "not a text file"),
    ("corrupt npy", "r.npy", _bytes(b"\x93NUMPY garbage" + os.urandom(200)), [], "not a readable .npy array"),
    ("npz with two arrays", "r.npz", lambda p: np.savez(p, a=X, b=X), [], "no variable named like a gyro or accelerometer; found a (400 float64), b (400 float64)"),
    ("npz without arrays", "r.npz", lambda p: np.savez(p), [], "no variable named like a gyro or accelerometer; found no variables"),
    ("too few samples", "r.csv", _text("\n".join(map(str, X[:10]))), [], "10 samples; expected at least 16"),
    ("unknown type", "r.xlsx", _text("1"), [], "unknown file type '.xlsx'"),
    ("missing file", None, None, [], "no such file"),
    ("--fs 0", "r.csv", _text(GOOD), ["--fs", "0"], "--fs: expected a positive sample rate in Hz, got 0.0"),
    ("--fs nan", "r.csv", _text(GOOD), ["--fs", "nan"], "--fs: expected a positive sample rate"),
    ("unknown unit", "r.csv", _text(GOOD), ["--units", "furlong/s"], "unknown rate unit 'furlong/s'"),
    ("unknown method", "r.csv", _text(GOOD), ["--method", "olss"], "--method: unknown estimator 'olss': expected one of"),
]


def _run(tmp_path, name, writer, extra, capsys):
    path = tmp_path / (name or "missing.csv")
    if writer is not None:
        writer(path)
    out = tmp_path / "out"
    rc = main(["estimate", str(path), "--fs", "10", "--units", "rad/s", "--method", "ols", "--out", str(out), *extra])
    captured = capsys.readouterr()
    return rc, captured, path, out


@pytest.mark.parametrize("case, fname, writer, extra, words", CASES, ids=[c[0] for c in CASES])
def test_bad_input_is_rejected_clearly_and_writes_nothing(tmp_path, capsys, case, fname, writer, extra, words):
    rc, captured, path, out = _run(tmp_path, fname, writer, extra, capsys)
    assert rc != 0
    err = captured.err.strip()
    assert err.startswith("avbench: error: "), err
    assert words in err, err
    if not extra or extra[0] == "--column":  # file problems name the file
        assert str(path) in err
    assert "Traceback" not in err
    assert not out.exists() or not any(out.iterdir())
    assert captured.out == ""


def test_good_file_still_works(tmp_path, capsys):
    rc, captured, path, out = _run(tmp_path, "r.csv", _text(GOOD), [], capsys)
    assert rc == 0, captured.err
    assert (out / "r_coefficients.json").is_file()


# -- inputs whose raw errors (NumPy's, a NaN) would not name the file or the fault: each message does --

GAPS = [
    ("corrupt npz", "r.npz", _bytes(os.urandom(300)), "r.npz: not a readable .npz archive"),
    ("a folder", "adir", lambda p: p.mkdir(), "adir: is a folder"),
    ("npy named .npz", "r.npz", lambda p: np.save(p.with_suffix(".npy"), X) or p.with_suffix(".npy").rename(p), "not a readable .npz archive"),
    ("first sample nan", "r.csv", _text("nan\n" + GOOD), "non-finite sample(s) (NaN/inf), the first at index 0"),
]


@pytest.mark.parametrize("case, fname, writer, words", GAPS, ids=[g[0] for g in GAPS])
def test_gaps_in_estimate(tmp_path, capsys, case, fname, writer, words):
    rc, captured, path, out = _run(tmp_path, fname, writer, [], capsys)
    assert rc != 0 and words in captured.err
    assert not out.exists() or not any(out.iterdir())


def test_data_files_helpers(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(os.urandom(300))
    with pytest.raises(ValueError, match=r"bad\.npz: not a readable \.npz archive \(not a NumPy file"):
        data_files.load_npz(bad)
    zipped_junk = tmp_path / "junk.npz"
    zipped_junk.write_bytes(b"PK\x03\x04" + os.urandom(100))
    with pytest.raises(ValueError, match=r"junk\.npz: not a readable \.npz archive"):
        data_files.load_npz(zipped_junk)
    np.save(tmp_path / "one.npy", X)
    assert np.array_equal(data_files.load_npy(tmp_path / "one.npy"), X)
    (tmp_path / "one.npy").rename(tmp_path / "one.npz")
    with pytest.raises(ValueError, match="a single .npy array, not an .npz archive"):
        data_files.load_npz(tmp_path / "one.npz")
    np.savez(tmp_path / "ok.npz", data=X, columns=np.array(["a"]))
    assert set(data_files.load_npz(tmp_path / "ok.npz")) == {"data", "columns"}
    with pytest.raises(ValueError, match="corrupt.npy: not a readable .npy array"):
        (tmp_path / "corrupt.npy").write_bytes(os.urandom(100))
        data_files.load_npy(tmp_path / "corrupt.npy")
    with pytest.raises(ValueError, match="is a folder"):
        data_files.check_file(tmp_path)
    with pytest.raises(ValueError, match="no such file"):
        data_files.check_file(tmp_path / "nope")
    (tmp_path / "e.csv").write_text("")
    with pytest.raises(ValueError, match="the file is empty"):
        data_files.check_file(tmp_path / "e.csv")
    assert data_files.is_header_row(["rate", "gyro x"])
    assert not data_files.is_header_row(["nan"])
    assert not data_files.is_header_row(["time", "1.5"])
    assert not data_files.is_header_row(["-Inf"])
