"""False alarms and power of the poor-fit flag (:mod:`avbench.estimators.allan.fit_check`), by Monte Carlo.

``python -m avbench.studies.fit_check_calibration [--replicates 200]``

For each case (a simulated gyro, the term set fitted, the record length) and estimator: the
fraction of replicates the flag fires at p < 0.01 with the reference the estimator uses, and
with the plain chi^2_{k-p} reference (same statistic, same replicates). Cases with the
correct term set measure false alarms (nominal 1 %); the wrong-model cases measure power. Fixed
seeds: the table is a function of the arguments. Prints a markdown table.
"""

from __future__ import annotations

import argparse

import numpy as np

#: name -> (gyro factory, five-term terms fitted, GMWM model or None, samples, correct model?)
CASES = {
    "white": (lambda: _gyro("white"), "N", "WN", 50_000, True),
    "ADIS16405_X": (lambda: _gyro("ADIS16405_X"), "NBK", None, 180_000, True),
    "CRG20": (lambda: _gyro("CRG20"), "QNB", None, 36_000, True),
    "white+GM (fitted: N only)": (lambda: _gyro("gm"), "N", "WN", 50_000, False),
    # a real sensor's curve: the ADIS16405 gyro's filter and coefficients (results/real) with a line
    "filtered+line": (lambda: _gyro("filtered+line"), "NBK", None, 65_536, True),
}
METHODS = ("slope_lines", "log_fit", "nnls_rel", "ols", "wls", "wls_edf", "gmwm")


def _gyro(name):
    from avbench.noise_models import AngleRandomWalk, GaussMarkov, Gyro, presets

    if name == "white":
        return Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3)])
    if name == "gm":  # a Gauss-Markov bump (Tc = 5 s) the white-noise model misses
        return Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=2e-3, tc=5.0)])
    if name == "filtered+line":  # white noise through a first-order filter (tf = dt / 2), flicker, random walk, a
        # 5 Hz line (on 65,536 samples at 100 Hz the line test searches from 3.9 Hz)
        from avbench.noise_models import BiasInstability, FilteredWhiteNoise, RateRandomWalk, Sinusoidal

        return Gyro(dt=0.01, terms=[FilteredWhiteNoise(N=7e-4, tf=0.005), BiasInstability(B=1.8e-4),
                                    RateRandomWalk(K=1.2e-5), Sinusoidal(A=2e-3, f0=5.0)])
    return presets.get(name)


def flag_rates(case: str, method: str, replicates: int, n_samples: int | None = None, seed: int = 12345,
               settings: dict | None = None) -> dict:
    """Flags over ``replicates`` simulated records of ``case`` fitted by ``method`` (module docstring)."""
    from scipy import stats

    from avbench import estimators
    from avbench.estimators.allan.fit_check import ALPHA

    factory, terms, gm_model, n_default, _ = CASES[case]
    g = factory()
    n = int(n_samples or n_default)
    if method == "gmwm":
        if gm_model is None:
            raise ValueError(f"{case}: no GMWM model is the correct one (flicker bias instability)")
        kw = {"model": gm_model}
    else:
        kw = {"terms": terms}
    kw.update(settings or {})
    flags = plain = 0
    p_values, reference = [], None
    included = {"filter": 0, "line": 0}  # terms entered on evidence (nnls_rel_filtered)
    for ss in np.random.SeedSequence(seed).spawn(replicates):
        r = estimators.get(method, **kw).fit(g.simulate(n, np.random.default_rng(ss)), g.dt).result()
        check = r.fit_check
        included["filter"] += bool((r.model_choice.get("filter_test") or {}).get("included"))
        included["line"] += bool((r.model_choice.get("line_test") or {}).get("included"))
        flags += bool(check.poor_fit)
        plain += bool(stats.chi2.sf(check.stat, check.dof) < ALPHA)
        p_values.append(check.pvalue)
        reference = check.reference
    return {"case": case, "method": method, "replicates": replicates, "n_samples": n, "flagged": flags,
            "rate": flags / replicates, "plain_chi2_rate": plain / replicates, "reference": reference,
            "p_values": np.array(p_values), "included": included}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--replicates", type=int, default=200)
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--methods", default=",".join(METHODS))
    args = ap.parse_args(argv)
    print("| case | correct model | method | samples | replicates | flagged (rate) | plain chi^2 rate | reference "
          "| filter / line entered |")
    print("|---|---|---|---|---|---|---|---|---|")
    for case in args.cases.split(","):
        for method in args.methods.split(","):
            if method == "gmwm" and CASES[case][2] is None:
                continue
            r = flag_rates(case, method, args.replicates)
            print(f"| {case} | {'yes' if CASES[case][4] else 'no'} | {method} | {r['n_samples']} | {r['replicates']} | "
                  f"{r['flagged']} ({r['rate']:.3f}) | {r['plain_chi2_rate']:.3f} | {r['reference']} | "
                  f"{r['included']['filter']} / {r['included']['line']} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
