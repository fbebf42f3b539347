"""The avbench command: simulate, presets, estimators, table (run is covered by the study tests)."""

import numpy as np
import pytest

from avbench.cli import main


def test_help_lists_commands(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    for cmd in ("simulate", "run", "table", "presets", "estimators"):
        assert cmd in out


def test_simulate_prints_table_and_writes_samples(tmp_path, capsys):
    out = tmp_path / "srs.npy"
    assert main(["simulate", "SRS2000", "--hours", "0.25", "--seed", "1", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    rows = [line.split() for line in text.splitlines() if not line.startswith("#") and line.strip()][1:]
    assert len(rows) == 13  # octave m = 1 .. 4096 for 9000 samples
    J = np.array([int(r[2]) for r in rows])
    ratio = np.array([float(r[-1]) for r in rows])
    assert np.all((ratio[J >= 64] > 0.8) & (ratio[J >= 64] < 1.25))
    lo, hi, exact = (np.array([float(r[i]) for r in rows]) for i in (4, 5, 6))
    assert np.all(lo <= hi)
    x = np.load(out)
    assert x.shape == (9000,)
    # the same seed gives the same record
    out2 = tmp_path / "srs.csv"
    assert main(["simulate", "SRS2000", "--hours", "0.25", "--seed", "1", "--out", str(out2)]) == 0
    np.testing.assert_allclose(np.loadtxt(out2), x, rtol=1e-15)


@pytest.mark.parametrize(
    "argv, msg",
    [
        (["simulate", "SRS3000"], "unknown preset"),
        (["simulate", "SRS2000", "--hours", "-1"], "positive"),
        (["simulate", "SRS2000", "--samples", "4"], "too short"),
        (["simulate", "SRS2000", "--hours", "1", "--samples", "100"], "at most one"),
        (["simulate", "SRS2000", "--hours", "0.1", "--out", "x.txt"], ".npy or .csv"),
        (["table", "/nonexistent/folder"], "not a folder"),
    ],
)
def test_errors_are_messages_not_tracebacks(argv, msg, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("avbench: error:") and msg in err
    assert not (tmp_path / "x.txt").exists()


def test_presets_and_estimators_list(capsys):
    assert main(["presets", "-v"]) == 0
    out = capsys.readouterr().out
    assert "SRS2000" in out and "Lv" in out and "arcsec" in out
    assert main(["estimators"]) == 0
    out = capsys.readouterr().out
    assert "wls" in out and "shakf" in out


def test_help_is_plain_text_and_every_estimator_is_described(capsys):
    """No reST markup in any help text; 'avbench estimators' gives every estimator a description."""
    import re

    from avbench.cli import build_parser

    parser = build_parser()
    texts = [parser.format_help()]
    for action in parser._actions:
        if hasattr(action, "choices") and isinstance(action.choices, dict):
            texts += [sub.format_help() for sub in action.choices.values()]
    for t in texts:
        assert not re.search(r"``|:[a-z]+:`|^\.\. ", t, re.M), t
    assert main(["estimators"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    from avbench import estimators
    assert len(lines) == len(estimators.names())
    for line in lines:
        name, _, desc = line.partition(" ")
        assert len(desc.strip()) > 20, f"{name} has no description"


def test_preset_notes_quote_their_own_preset(capsys):
    from avbench.noise_models import presets
    from avbench.noise_models.units import from_si

    for name in ("FOG1", "FOG2"):
        info = presets.info(name)
        q_deg = from_si("Q", info.gyro().coefficients["Q"], "arcsec")
        assert f"{q_deg:g} deg" in info.units_note, (name, q_deg, info.units_note[:120])
