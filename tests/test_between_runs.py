"""Between-run spread (``--combine``): DerSimonian-Laird random effects and ``--inflate auto``."""

import json
import math

import numpy as np
import pytest
from scipy import stats

from avbench.cli import main
from avbench.recordings.fit import random_effects


def _binomial_ok(hits, R, p):
    """hits / R is consistent with p (two-sided binomial test at 1e-4)."""
    return stats.binomtest(hits, R, p).pvalue > 1e-4


@pytest.mark.parametrize("tau", [0.0, 0.5, 2.0])
def test_q_profile_interval_covers_the_between_run_sd(tau):
    """95 % Q-profile interval of tau covers the true tau at its nominal rate (k = 6 runs, unequal
    within-run errors); the prediction interval covers a new run's true value (mu + u_new, what a
    filter should assume; not its noisy estimate) at about 95 %."""
    rng = np.random.default_rng(int(10 * tau) + 1)
    R, k = 1000, 6
    cover = pred = 0
    for _ in range(R):
        se = rng.uniform(0.5, 1.5, k)
        y = 10 + tau * rng.standard_normal(k) + se * rng.standard_normal(k)
        r = random_effects(y, se)
        lo, hi = r["tau_ci"]
        cover += (lo <= tau <= hi) if tau > 0 else (lo == 0.0)
        new = 10 + tau * rng.standard_normal()
        pred += r["prediction"][0] <= new <= r["prediction"][1]
    # tau = 0 lies on the boundary: the interval includes it whenever Q <= chi^2_{k-1, 97.5 %}
    assert _binomial_ok(cover, R, 0.975 if tau == 0 else 0.95), cover / R
    # the prediction interval with a DL tau is approximate (Higgins et al. 2009): at least nominal - 3 %
    assert pred / R >= 0.92 - 3 * math.sqrt(0.95 * 0.05 / R), pred / R


def test_the_test_can_fail_within_run_se_alone():
    """Ignoring the between-run spread (tau = 0, the SE a single fit claims) covers far too rarely."""
    rng = np.random.default_rng(3)
    hits = 0
    for _ in range(400):
        se = np.full(6, 0.2)
        y = 10 + 2.0 * rng.standard_normal(6) + se * rng.standard_normal(6)
        new = 10 + 2.0 * rng.standard_normal()
        mu, s = np.average(y, weights=1 / se**2), 1 / math.sqrt(np.sum(1 / se**2))
        hits += abs(new - mu) <= 1.96 * math.hypot(s, 0.2)
    assert not _binomial_ok(hits, 400, 0.95)


def test_dersimonian_laird_by_hand_and_edges():
    y, se = np.array([1.0, 2.0, 4.0]), np.array([1.0, 1.0, 1.0])
    r = random_effects(y, se)
    Q = np.sum((y - y.mean()) ** 2)  # equal weights
    assert r["Q"] == pytest.approx(Q)
    assert r["tau"] ** 2 == pytest.approx((Q - 2) / (3 - 1))  # sum w - sum w^2 / sum w = 3 - 1
    assert r["mean"] == pytest.approx(y.mean())
    assert random_effects([1.0], [0.1])["tau"] is None
    sd = random_effects([1.0, 2.0, 3.0], [np.nan] * 3)  # no within-run SE: the runs' SD
    assert sd["tau"] == pytest.approx(1.0) and "SD of the runs" in sd["method"]


def test_combine_reports_between_run_spread_and_inflates_the_yaml(tmp_path, capsys):
    """Six simulated runs whose white noise differs from run to run (log-normal, SD 0.25): the
    between-run SD of N is found with an interval that holds the truth, and ``--inflate auto``
    multiplies the yaml's noise density by the prediction limit over the mean."""
    rng = np.random.default_rng(24)
    n, dt, N0, K = 40_000, 0.01, 1e-3 * math.sqrt(0.01), 2e-6
    Ns = N0 * np.exp(0.25 * rng.standard_normal(6))
    files = []
    for i, N in enumerate(Ns):
        g = N / math.sqrt(dt) * rng.standard_normal(n) + np.cumsum(K * math.sqrt(dt) * rng.standard_normal(n))
        a = N0 / math.sqrt(dt) * rng.standard_normal(n)  # the accelerometer: no spread
        files.append(tmp_path / f"run{i}.npz")
        np.savez(files[-1], data=np.column_stack([g, a]))
    args = ["estimate", *map(str, files), "--combine", "--fs", "100", "--gyro", "0", "--accel", "1",
            "--units", "rad/s", "--accel-units", "m/s^2", "--method", "gmwm", "--set", "gmwm.model=\"WN+RW\"",
            "--inflate", "auto", "--format", "kalibr", "--out", str(tmp_path / "o"), "--json"]
    assert main(args) == 0
    data = json.loads(capsys.readouterr().out)
    r = next(iter(data["between_runs"]["sensors"]["gyro"].values()))["N"]
    true_tau = float(np.std(Ns, ddof=1))
    assert r["k"] == 6 and r["tau_ci"][0] <= true_tau <= r["tau_ci"][1], (r, true_tau)
    assert r["tau"] > 5 * r["mean_se"] / math.sqrt(6)  # the spread dwarfs one run's sampling error
    f = data["between_runs"]["inflate"]["gyroscope_noise_density"]
    assert f == pytest.approx(r["prediction"][1] / r["mean"], rel=1e-12) and f > 1.2
    text = (tmp_path / "o" / "run0_combined_kalibr.yaml").read_text()
    assert "--inflate auto" in text
    val = float(text.split("gyroscope_noise_density:")[1].split()[0])
    assert val == pytest.approx(data["filter_yaml"]["values_si"]["gyroscope_noise_density"] * f, rel=1e-12)
    assert main(["estimate", *map(str, files[:2]), "--combine", "--fs", "100", "--gyro", "0", "--units", "rad/s",
                 "--inflate", "auto"]) == 2
    assert "at least 3 recordings" in capsys.readouterr().err
