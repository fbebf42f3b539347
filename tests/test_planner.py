"""`avbench plan`: the planned record length meets its target on simulated records, its efficiency is the
measured one, and its precision at 2 h agrees with the spread grand_comparison_2h measured."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from avbench.cli import main
from avbench.noise_models import presets
from avbench.studies import planner

RESULTS = Path(__file__).resolve().parents[1] / "results"


def test_efficiency_is_the_committed_measurement():
    eff = pd.read_csv(RESULTS / "random_gyros" / "efficiency.csv")
    row = eff[eff.estimator == "Whittle debiased (profile)"].set_index("coefficient")["median_hi"]
    assert set(planner.EFFICIENCY) == set(row.index)
    for c, v in planner.EFFICIENCY.items():
        assert v == pytest.approx(row[c], rel=1e-5), c


@pytest.mark.parametrize("name", ["SRS2000", "FOG1", "CRG20", "ADIS16405_X"])
def test_planned_length_is_the_shortest_meeting_the_target(name):
    g = presets.get(name)
    p = planner.plan(g, 0.2)
    for c in p.coefficients:
        if p.extrapolated[c] or p.samples[c] <= planner.N_MIN:
            continue
        n = p.samples[c]
        assert planner.precision_at(g, int(n), [c])[c] <= 0.2
        assert planner.precision_at(g, int(n / 1.02), [c])[c] > 0.2


def test_precision_falls_with_length_and_target_orders_lengths():
    g = presets.get("CRG20")
    loose, tight = planner.plan(g, 0.2), planner.plan(g, 0.05)
    for c in loose.coefficients:
        assert tight.samples[c] >= loose.samples[c]
    h = loose.curve.to_numpy()
    assert np.all(np.diff(h, axis=0) < 0)


def _meets(p, records=40, seed=3):
    """The check's share, judged by its Clopper-Pearson interval: the plan promises ~95 % of records within the
    target; it fails where the interval's upper end lies below the 90 % the plan must at least give."""
    res = planner.check_plan(p, records=records, seed=seed)
    for c in p.coefficients:
        assert res.interval[c][1] >= 0.90, (c, res.met[c], res.records, res.failed[c])
    return res


@pytest.mark.parametrize("coef,target", [("N", 0.05), ("B", 0.10)])
def test_planned_length_meets_target_on_simulated_records(coef, target):
    _meets(planner.plan(presets.get("SRS2000"), target, [coef]))


@pytest.mark.slow
@pytest.mark.parametrize("name,coef,target", [("FOG1", "B", 0.10), ("CRG20", "Q", 0.20), ("CRG20", "B", 0.10),
                                              ("VG951", "B", 0.10), ("ADIS16405_X", "N", 0.01)])
def test_planned_length_meets_target_on_three_presets(name, coef, target):
    _meets(planner.plan(presets.get(name), target, [coef]), records=60)


@pytest.mark.slow
def test_plan_from_a_pilot_record(tmp_path):
    """A 20-minute pilot of a preset: the plan made from its fitted coefficients meets the target on records of
    the true gyro (the pilot's own estimate is noisy; the plan holds where the pilot resolved the coefficient)."""
    g = presets.get("FOG1")
    x = g.simulate(int(1200 / g.dt), np.random.default_rng(11))
    path = tmp_path / "pilot.csv"
    pd.DataFrame({"t": np.arange(x.size) * g.dt, "gx": x}).to_csv(path, index=False)
    (axis,) = planner.gyros_from_pilot(path, units="rad/s", gyro="gx")
    p_pilot = planner.plan(axis.gyro, 0.10, ["B"])
    p_true = planner.plan(g, 0.10, ["B"])
    # the pilot's plan is the true plan up to the pilot's own precision on B (its 20 minutes give ±~15 %)
    assert 0.5 < p_pilot.samples["B"] / p_true.samples["B"] < 2.0
    truth_plan = planner.Plan(gyro=g, target=0.10, samples=p_pilot.samples, extrapolated=p_pilot.extrapolated,
                              curve=p_pilot.curve)
    res = planner.check_plan(truth_plan, records=60, seed=5)
    assert res.interval["B"][1] >= 0.80


def test_precision_at_two_hours_agrees_with_grand_comparison_2h():
    """The planner's spread at 2 h (CRLB x efficiency) against the RMSE the full-model Whittle fit measured over
    30 records of each preset: the median ratio lies inside the 99 % chi-square interval of a 30-record RMSE."""
    scores = pd.read_csv(RESULTS / "grand_comparison_2h" / "scores.csv")
    rows = scores[(scores.estimator == "Whittle (full)") & scores.gyro.isin(presets.names())]
    ratios = []
    for (gyro, c), r in rows.set_index(["gyro", "coefficient"]).iterrows():
        if c not in planner.EFFICIENCY or not np.isfinite(r.rmse) or not r.true > 0:
            continue
        g = presets.get(gyro)
        h = planner.precision_at(g, int(round(7200 / g.dt)), [c])[c]
        predicted_rmse = h * r.true / stats.norm.ppf(0.975)
        ratios.append(r.rmse / predicted_rmse)
    assert len(ratios) >= 20
    lo, hi = (np.sqrt(stats.chi2.ppf(q, 30) / 30) for q in (0.005, 0.995))
    assert lo <= np.median(ratios) <= hi, (np.median(ratios), lo, hi)


def test_cli_prints_a_plan_and_its_figure(tmp_path, capsys):
    fig = tmp_path / "plan.png"
    assert main(["plan", "--preset", "SRS2000", "--target", "10", "--duration", "1h", "--figure", str(fig)]) == 0
    out = capsys.readouterr().out
    for c in ("Q", "N", "B"):
        assert f"\n  {c} " in out
    assert "record at least" in out and fig.stat().st_size > 0


def test_cli_datasheet_units(capsys):
    assert main(["plan", "--N", "0.15 deg/sqrt(h)", "--B", "5 deg/h", "--rate", "200", "--target", "20"]) == 0
    out = capsys.readouterr().out
    assert "0.15 deg/sqrt(h)" in out and "5 deg/h" in out


@pytest.mark.parametrize("argv,words", [
    (["plan"], "give --preset"),
    (["plan", "--N", "0.1 deg/sqrt(h)"], "--rate"),
    (["plan", "--N", "0.1 furlongs", "--rate", "100"], "unknown unit"),
    (["plan", "--preset", "SRS2000", "--N", "0.1"], "not both"),
    (["plan", "--preset", "SRS2000", "--target", "0"], "--target"),
    (["plan", "--preset", "SRS2000", "--duration", "soon"], "duration"),
    (["plan", "--preset", "SRS2000", "--coefficients", "K"], "no K"),
])
def test_cli_refuses_bad_input_in_one_line(argv, words, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and "\n" not in err
