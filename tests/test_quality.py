"""A record is judged before it is fitted (:mod:`avbench.recordings.quality`).

Simulated records with a known truth, each broken in one way -- one spike of 1e5 sigma, 5 % of the
samples clipped, int16 counts declared rad/s, a noise level that doubles halfway, samples rounded to
0.01 deg/s -- are flagged by name, and only by the names that defect explains; ``avbench estimate``
shows each flag on the screen, in the JSON, on the HTML page and in every filter file. Clean
stationary records are flagged at a stated low rate (a binomial bound over 40 records), and the
stationarity test's p-values are uniform on white noise (its level holds).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import stats

from avbench.cli import main
from avbench.noise_models import AngleRandomWalk, BiasInstability, Gyro, RateRandomWalk
from avbench.recordings.quality import (NAMES, STATIONARITY_LEVEL, judge_record, lattice_step, noise_level_change)
from avbench.recordings.sensors import SensorRecord

DT = 0.01
N = 2**15
SIGMA_DEG = 0.005  #: the gyro's white noise per sample, deg/s (0.01 deg/s rounding is then q^2/12 = 33 % of it)
G = 9.80665


def _gyro(rng, n=N, sigma_deg=SIGMA_DEG):
    """A gyro axis in deg/s: white noise of sigma_deg per sample, bias instability and a random walk."""
    terms = [AngleRandomWalk(N=sigma_deg * math.sqrt(DT)), BiasInstability(B=2e-4, tau_max=n * DT),
             RateRandomWalk(K=1e-5)]
    return Gyro(dt=DT, terms=terms).simulate(n, rng)


def _record(defect: str | None, seed: int = 7):
    """(gyro columns, unit, accel columns in m/s^2) of a record at rest with one ``defect``."""
    rng = np.random.default_rng(seed)
    g = np.column_stack([_gyro(rng) for _ in range(3)])  # deg/s
    a = rng.normal(0.0, 2e-3, (N, 3)) + np.array([0.0, 0.0, G])
    unit = "deg/s"
    if defect == "spikes":
        g[N // 3, 0] += 1e5 * SIGMA_DEG
    elif defect == "clipping":
        lo, hi = np.quantile(g[:, 0], [0.025, 0.975])
        g[:, 0] = np.clip(g[:, 0], lo, hi)
    elif defect == "raw counts":  # a 16.4 LSB per deg/s gyro read as int16 counts, declared rad/s
        g = np.round((g + 0.5) * 16.4 * 10).astype(np.int16).astype(np.float64)
        unit = "rad/s"
    elif defect == "non-stationary":
        g[N // 2:, 0] += rng.normal(0.0, SIGMA_DEG * math.sqrt(3.0), N - N // 2)  # white noise level x 2
    elif defect == "quantization":
        g = np.round(g / 0.01) * 0.01
    return g, unit, a


#: per defect: the flags it explains (counts are whole numbers, far off zero and coarse)
EXPLAINED = {"spikes": {"spikes"}, "clipping": {"clipping"}, "raw counts": {"raw counts", "implausible mean", "quantization"},
             "non-stationary": {"non-stationary"}, "quantization": {"quantization"}}


def _judge(g, unit, a):
    from avbench.noise_models.units import samples_to_si

    sensors = [SensorRecord("gyro", unit, {k: samples_to_si(g[:, i], unit) for i, k in enumerate("xyz")}, {}),
               SensorRecord("accel", "m/s^2", {k: a[:, i] for i, k in enumerate("xyz")}, {})]
    return judge_record(sensors, DT)


@pytest.mark.parametrize("defect", [None, *EXPLAINED])
def test_each_defect_is_flagged_by_its_name(defect):
    q = _judge(*_record(defect))
    names = set(q.names)
    if defect is None:
        assert not names, [f.text() for f in q.flags]
        return
    assert defect in names and names <= EXPLAINED[defect], [f.text() for f in q.flags]
    assert all(f.todo and f.finding for f in q.flags)


def test_the_noise_level_change_is_sized_with_its_interval():
    """The white noise's level doubles halfway: the short-scale level (white plus the slow terms' small share)
    of the second half over the first holds its true ratio in its interval."""
    g, unit, a = _record("non-stationary")
    r = noise_level_change(np.deg2rad(g[:, 0]))
    assert r["p"] < STATIONARITY_LEVEL
    assert r["interval"][0] <= 2.0 <= r["interval"][1] and r["interval"][1] / r["interval"][0] < 1.2, r
    flag = next(f for f in _judge(g, unit, a).flags if f.name == "non-stationary")
    assert flag.interval == r["interval"] and f"second half / first half = {r['ratio']:.3g} [" in flag.finding


def test_lattice_step():
    assert lattice_step(np.array([0.0, 0.3, 0.9, 0.3, 0.6, 1.5] * 3)) == pytest.approx(0.3)
    assert lattice_step(np.random.default_rng(0).normal(size=100)) is None


def test_false_alarms_on_clean_records_are_rare():
    """40 clean records of 6 channels, 2^14 samples each (white noise, bias instability, a random walk, the
    gyro rounded to 1/10 of its noise in every other record). The stated rate per record: per channel
    STATIONARITY_LEVEL (the other checks 1e-6 each), 6 channels -> 6e-3 plus 6 x 5e-6; flagged records
    must stay within the binomial 1 - 1e-4 quantile of it."""
    flagged = []
    for k in range(40):
        rng = np.random.default_rng(1000 + k)
        g = np.column_stack([_gyro(rng, 2**14) for _ in range(3)])
        if k % 2:
            g = np.round(g / (SIGMA_DEG / 10)) * (SIGMA_DEG / 10)
        a = rng.normal(0.0, 2e-3, (2**14, 3)) + np.array([0.0, 0.0, G])
        q = _judge(g, "deg/s", a)
        if q.flags:
            flagged.append((k, [f.text() for f in q.flags]))
    rate = 6 * (STATIONARITY_LEVEL + 5e-6)
    assert len(flagged) <= stats.binom.ppf(1 - 1e-4, 40, rate), flagged


def test_the_stationarity_test_holds_its_level():
    """On 400 white-noise records the F test's p-values are uniform: the share below 0.05 lies in the
    binomial 1 - 1e-4 interval of 0.05 (a test that ignored the blocks' own spread would be over-confident)."""
    rng = np.random.default_rng(3)
    p = np.array([noise_level_change(rng.standard_normal(2**12))["p"] for _ in range(400)])
    lo, hi = stats.binom.interval(1 - 1e-4, 400, 0.05)
    assert lo <= np.sum(p < 0.05) <= hi, np.sum(p < 0.05)


def _estimate(tmp_path, defect, capsys):
    g, unit, a = _record(defect)
    src = tmp_path / f"{(defect or 'clean').replace(' ', '_')}.npz"
    np.savez(src, data=np.column_stack([g, a]))
    out = tmp_path / "out"
    args = ["estimate", str(src), "--fs", "100", "--gyro", "0,1,2", "--accel", "3,4,5", "--units", unit,
            "--accel-units", "m/s^2", "--method", "wls", "--format", "px4,orbslam3,basalt", "--kalibr",
            str(out / f"{src.stem}_imu.yaml"), "--html", "--out", str(out), "--no-progress"]
    assert main(args) == 0
    screen = capsys.readouterr().out
    data = json.loads((out / f"{src.stem}_coefficients.json").read_text())
    page = (out / f"{src.stem}_report.html").read_text()
    files = {p.name: p.read_text() for p in out.iterdir() if p.stem.startswith(src.stem) and
             p.suffix in (".params", ".yaml", ".json") and not p.name.endswith("coefficients.json")}
    return screen, data, page, files


@pytest.mark.parametrize("defect", [None, *EXPLAINED])
def test_every_surface_names_the_flags(tmp_path, capsys, defect):
    """The screen, the JSON, the page and every filter file name each flag; a clean record's say none. On a
    broken record no filter file carries a gyro noise density that moved from the truth by more than its
    interval unflagged (a clean record's intervals are held to their coverage elsewhere)."""
    screen, data, page, files = _estimate(tmp_path, defect, capsys)
    rq = data["record_quality"]
    assert rq["ok"] == (defect is None) and len(files) == 4
    if defect is None:
        assert "RECORD FLAG" not in screen and all("RECORD FLAG" not in t for t in files.values())
        assert "no flag" in page
    else:
        assert defect in rq["flagged"]
        for name in rq["flagged"]:
            assert f"# FLAG {name} (" in screen, (name, screen[:2000])
            assert f"<td>{name}</td>" in page
            for fname, text in files.items():
                assert f"RECORD FLAG {name} (" in text, (fname, name)
    truth = math.radians(SIGMA_DEG) * math.sqrt(DT)
    for axis, ad in (data["sensors"]["gyro"]["axes"].items() if defect else ()):
        e = ad["methods"]["wls"]["coefficients"]["N"]
        lo, hi = e.get("interval_si") or (e["si"], e["si"])
        if not lo <= truth <= hi:  # moved beyond its interval: a flag must say so in every file
            assert not rq["ok"] and all("RECORD FLAG" in t for t in files.values()), (axis, e, truth)
    assert set(rq["checked"]) == set(NAMES)
