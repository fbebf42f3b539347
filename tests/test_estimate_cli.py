"""``avbench estimate``: file formats, --json purity, clear failures that write nothing."""

import json
import re

import numpy as np
import pytest

from avbench.noise_models import AngleRandomWalk, Gyro, RateRandomWalk
from avbench.noise_models.units import from_si, rate_to_si
from avbench.cli import main
from avbench.recordings.readers import read_recording

FS = 100.0
N_TRUE = 2e-3  # rad/sqrt(s)


@pytest.fixture(scope="module")
def record():
    g = Gyro(dt=1 / FS, terms=[AngleRandomWalk(N=N_TRUE), RateRandomWalk(K=1e-5)])
    return g.simulate(60_000, np.random.default_rng(42))


def _coef(payload, method, coef="N", sensor="gyro", axis=None):
    axes = payload["sensors"][sensor]["axes"]
    axis = axis if axis is not None else next(iter(axes))
    return axes[axis]["methods"][method]["coefficients"][coef]


def _deg(x):
    return x / rate_to_si(1.0, "deg/s")


def test_csv_with_header_json_only(tmp_path, record, capsys):
    f = tmp_path / "rec.csv"
    np.savetxt(f, np.column_stack([np.arange(record.size) / FS, _deg(record)]), delimiter=",",
               header="t,gyro_x", comments="")
    out = tmp_path / "out"
    code = main(["estimate", str(f), "--fs", "100", "--column", "gyro_x", "--units", "deg/s",
                 "--method", "nnls_rel,slope_lines", "--json", "--out", str(out)])
    assert code == 0
    payload = json.loads(capsys.readouterr().out)  # stdout holds the JSON object and nothing else
    methods = payload["sensors"]["gyro"]["axes"]["x"]["methods"]
    assert set(methods) == {"nnls_rel", "slope_lines"}
    assert payload["timing"]["from"] == "time stamps" and payload["timing"]["rate_hz"] == pytest.approx(FS)
    n = _coef(payload, "nnls_rel")
    assert n["unit"] == "deg/sqrt(h)"
    assert n["value"] == pytest.approx(from_si("N", n["si"], "deg/sqrt(h)"))
    # the CLI reports what the estimator gives on the converted record, in both units
    from avbench import estimators
    direct = estimators.get("nnls_rel").fit(rate_to_si(_deg(record), "deg/s"), 1 / FS).coefficients_
    assert n["si"] == pytest.approx(direct["N"], rel=1e-9)
    b = _coef(payload, "nnls_rel", "B")
    assert (b["value"] is None) == (b["flag"] != "ok") and (b["value"] is None or b["value"] >= 0)
    for suffix in ("_gyro_av.png", "_av.csv", "_coefficients.csv", "_coefficients.json"):
        assert (out / f"rec_gyro_x{suffix}").is_file()
    # the poor-fit check as the estimator made it, with the reference its p-value comes from
    for m in ("nnls_rel", "slope_lines"):
        entry = methods[m]
        assert isinstance(entry["poor_fit"], bool) and 0.0 <= entry["fit_pvalue"] <= 1.0
        assert entry["fit_reference"] == "weighted chi2"


@pytest.mark.parametrize("kind", ["npy", "npz", "txt"])
def test_formats_agree(tmp_path, record, kind, capsys):
    f = tmp_path / f"rec.{kind}"
    if kind == "npy":
        np.save(f, record)
    elif kind == "npz":
        np.savez(f, data=np.column_stack([record, -record]), columns=np.array(["a", "b"]))
    else:
        np.savetxt(f, record)
    col = ["--column", "a"] if kind == "npz" else []
    assert main(["estimate", str(f), "--fs", "100", *col, "--units", "rad/s", "--method", "nnls_rel", "--json",
                 "--out", str(tmp_path)]) == 0
    si = _coef(json.loads(capsys.readouterr().out), "nnls_rel")["si"]
    np.save(tmp_path / "ref.npy", record)
    assert main(["estimate", str(tmp_path / "ref.npy"), "--fs", "100", "--units", "rad/s", "--method", "nnls_rel",
                 "--json", "--out", str(tmp_path)]) == 0
    assert si == pytest.approx(_coef(json.loads(capsys.readouterr().out), "nnls_rel")["si"], rel=1e-12)


def test_table_output_and_settings(tmp_path, record, capsys):
    f = tmp_path / "r.npy"
    np.save(f, record)
    assert main(["estimate", str(f), "--fs", "100", "--units", "rad/s", "--method", "gmwm", "--set", "gmwm.model=WN+RW",
                 "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    assert "N (deg/sqrt(h))" in text and "gmwm" in text


def _bad_files(tmp_path):
    cases = {}
    p = tmp_path / "nan.npy"
    x = np.ones(100)
    x[17] = np.nan
    np.save(p, x)
    cases["nan"] = ([str(p)], "non-finite")
    p = tmp_path / "inf.csv"
    p.write_text("1\n2\ninf\n" + "3\n" * 50)
    cases["inf"] = ([str(p)], "non-finite")
    p = tmp_path / "empty.csv"
    p.write_text("")
    cases["empty"] = ([str(p)], "empty")
    p = tmp_path / "cube.npy"
    np.save(p, np.zeros((10, 10, 3)))
    cases["shape"] = ([str(p)], "shape")
    p = tmp_path / "words.csv"
    p.write_text("rate\n" + "\n".join(["1.0"] * 20 + ["abc"] + ["2.0"] * 20) + "\n")
    cases["non-numeric"] = ([str(p)], "not numeric")
    p = tmp_path / "two.csv"
    p.write_text("a,b\n" + "1,2\n" * 40)
    cases["unknown column"] = ([str(p), "--column", "c"], "unknown column")
    cases["no column"] = ([str(p)], "(or one with --column NAME|INDEX)")
    p = tmp_path / "short.npy"
    np.save(p, np.ones(5))
    cases["short"] = ([str(p)], "at least 16")
    cases["missing"] = ([str(tmp_path / "nope.csv")], "no such file")
    p = tmp_path / "rec.xlsx"
    p.write_text("x")
    cases["type"] = ([str(p)], "unknown file type")
    return cases


@pytest.mark.parametrize("case", ["nan", "inf", "empty", "shape", "non-numeric", "unknown column",
                                  "no column", "short", "missing", "type"])
def test_bad_files_fail_clearly_and_write_nothing(tmp_path, case, capsys):
    argv, message = _bad_files(tmp_path)[case]
    out = tmp_path / "out"
    code = main(["estimate", *argv, "--fs", "100", "--units", "rad/s", "--method", "nnls_rel", "--json", "--out", str(out)])
    err = capsys.readouterr()
    assert code != 0
    assert message in err.err
    assert err.out == ""
    assert not out.exists()


@pytest.mark.parametrize(
    "extra, message",
    [(["--method", "nope"], "unknown estimator"), (["--units", "furlong/s"], "unknown rate unit"),
     (["--fs", "-3"], "--fs"), (["--set", "gmwm.colour=red", "--method", "gmwm"], "unknown setting"),
     (["--set", "wls.model=x"], "not among")],
)
def test_bad_arguments(tmp_path, record, extra, message, capsys):
    f = tmp_path / "r.npy"
    np.save(f, record)
    args = ["estimate", str(f), "--fs", "100", "--units", "rad/s", "--method", "nnls_rel", "--out", str(tmp_path / "o")]
    # later occurrences of an option override the earlier ones
    code = main(args + extra)
    assert code != 0 and message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_load_record_npz_without_data_key(tmp_path, record):
    f = tmp_path / "one.npz"
    np.savez(f, rate=record)
    rec = read_recording(f)
    assert [c.sensor for c in rec.channels] == ["gyro"] and np.array_equal(rec.channels[0].values, record)


def test_combine_pools_recordings_and_tests_agreement(tmp_path, capsys):
    """Two runs of one white-noise gyro agree; a third with three times the noise does not. The pooled
    fit sees the file boundary as a gap."""
    rng = np.random.default_rng(5)
    for name, s in (("a", 1e-3), ("b", 1e-3), ("c", 3e-3)):
        np.savez(tmp_path / f"{name}.npz", data=s * rng.standard_normal(20_000))
    common = ["--combine", "--fs", "100", "--units", "rad/s", "--method", "nnls_rel", "--json", "--out", str(tmp_path / "o")]
    assert main(["estimate", str(tmp_path / "a.npz"), str(tmp_path / "b.npz"), *common]) == 0
    same = json.loads(capsys.readouterr().out)
    assert same["combine"]["gyro"]["x"]["agree"] is True
    assert [g["before_sample"] for g in same["timing"]["gaps"]] == [20_000]
    assert (tmp_path / "o" / "a_combined_coefficients.json").is_file()
    assert main(["estimate", str(tmp_path / "a.npz"), str(tmp_path / "c.npz"), *common]) == 0
    assert json.loads(capsys.readouterr().out)["combine"]["gyro"]["x"]["agree"] is False
    assert main(["estimate", str(tmp_path / "a.npz"), str(tmp_path / "b.npz"), "--fs", "100", "--units", "rad/s"]) == 2
    assert "expected one recording, or --combine" in capsys.readouterr().err


def test_no_coefficient_is_a_bare_zero(tmp_path, record, capsys):
    """Every term reported 0 (or not resolved) carries its upper bound and, where the method gives
    it, its evidence, on screen and in JSON."""
    f = tmp_path / "r.npy"
    np.save(f, record[:30_000])
    assert main(["estimate", str(f), "--fs", "100", "--units", "rad/s", "--method", "whittle_debiased,whittle",
                 "--json", "--out", str(tmp_path)]) == 0
    payload = json.loads(capsys.readouterr().out)
    ev = {c: _coef(payload, "whittle_debiased", c)["evidence"] for c in "QNBKR"}
    assert ev["N"]["present"] and ev["N"]["reading"].startswith("present, p < 1e-6")
    for c, e in ev.items():
        assert e["upper"] is not None and 0 <= e["p_value"] <= 1
        if not e["present"]:
            assert "upper 95 % bound" in e["reading"]
    import pandas as pd

    table = pd.read_csv(tmp_path / "r_coefficients.csv", index_col=[0, 1, 2, 3], keep_default_na=False)
    for method in ("whittle_debiased", "whittle"):
        for c in "QNBKR":
            e = _coef(payload, method, c)
            assert e["value"] != 0.0  # a zero is "not resolved", with its bound
            absent = e.get("evidence") is not None and not e["evidence"]["present"]
            if e.get("fitted_si") == 0.0 or absent:
                assert e["flag"] == "not resolved" and e["interval_si"][0] == 0.0 < e["interval_si"][1]
                assert table.loc[("gyro", "x", method, c), "shown"].startswith("< ")



def test_model_choice_is_reported(tmp_path, capsys):
    """gmwm_filtered's model choice reaches the JSON (``model_choice``: the line test, the resonance test,
    the Gauss-Markov-vs-flicker evidence with its B in SI, the same in deg/s and rad/s) and the screen
    (a "bias instability:" note naming the favoured model)."""
    from avbench.noise_models import GaussMarkov

    g = Gyro(dt=1 / FS, terms=[AngleRandomWalk(N=N_TRUE), GaussMarkov(sigma=1e-3, tc=5.0)])  # a visible GM hump
    x = g.simulate(100_000, np.random.default_rng(4))
    f = tmp_path / "r.npy"
    np.save(f, x)
    assert main(["estimate", str(f), "--fs", "100", "--units", "rad/s", "--method", "gmwm_filtered",
                 "--out", str(tmp_path / "rad")]) == 0
    screen = " ".join(capsys.readouterr().out.replace("#", " ").split())  # the notes wrapped over lines, joined
    assert re.search(r"(clearly favours|does not clearly favour) the Gauss-Markov model these values come from", screen)
    payload = json.loads(next((tmp_path / "rad").glob("*_coefficients.json")).read_text())
    rad = payload["sensors"]["gyro"]["axes"]["x"]["methods"]["gmwm_filtered"]["model_choice"]
    f = tmp_path / "d.npy"
    np.save(f, _deg(x))
    assert main(["estimate", str(f), "--fs", "100", "--units", "deg/s", "--method", "gmwm_filtered", "--json",
                 "--out", str(tmp_path / "deg")]) == 0
    deg = json.loads(capsys.readouterr().out)["sensors"]["gyro"]["axes"]["x"]["methods"]["gmwm_filtered"]["model_choice"]
    ev = rad["bias_evidence"]
    assert ev["preferred"] == "GM" and ev["GM"]["weight"] + ev["FL"]["weight"] == pytest.approx(1.0)
    b_fl = ev["FL"]["B"]
    assert 0 < b_fl < 1e-3 and deg["bias_evidence"]["FL"]["B"] == pytest.approx(b_fl, rel=1e-6)
    assert rad["resonance_test"]["included"] is False and "line_test" in rad
