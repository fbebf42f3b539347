"""Measurement: do ``gmwm_filtered``'s intervals of N, B and K keep their coverage on simulated accelerometer-like
records (outside the presets), with the two widenings of the record mode -- the Birge ratio of a misfit
(``GMWM._dispersion``) and the bounds' edf taken from the record's variance factors (``GMWM._bound_edf``) --
and without them ("before": both turned off on the same records)?

The record: an ADIS16405 accelerometer axis as ``gmwm_filtered`` reads the real ones (``coefficients.csv``, run 5
x and its neighbours: filtered white N 0.29 m/s/sqrt(h), tf 11 ms; a Gauss-Markov bias B ~ 300 ug, tc 10 s; a
random walk K 0.04 m/s^2/sqrt(h); the 0.47 Hz line of 8.5 mg), 30 minutes at 100 Hz (the slices' length), in two
kinds: "stationary" (the model itself) and "moving" (the white noise's level moves by +-20 % between the record's
eighths, as the real accelerometers' short scales do between half-hours; its N the mean level's). Prints, per kind
and coefficient, the records whose 95 % interval (the one ``avbench estimate`` shows: [0, upper] where not resolved) holds the truth,
before and after, with the Clopper-Pearson 95 % interval, and the median interval width over the truth.

``python results/real/accelerometers/simulated_coverage.py [R]`` (~12 CPU-s a record: two fits)."""
import sys
import warnings

import numpy as np

from avbench import estimators
from avbench.estimators.likelihood.gmwm import GMWM
from avbench.noise_models import FilteredWhiteNoise, GaussMarkov, Gyro, RateRandomWalk, Sinusoidal
from avbench.noise_models.markov_terms import B_EQUIV_OVER_SIGMA
from avbench.studies.scoring import _clopper_pearson

warnings.simplefilter("ignore")
DT, N = 0.01, 180_000
TRUTH = {"N": 0.29 / 60, "B": 3.0e-3, "K": 0.04 / 60}
#: the white level's moves between eighths of a "moving" record; its N is the record's mean white level
MOVES = (1, -1, 1, -1, -1, 1, -1, 1)
N_MOVING = TRUTH["N"] * float(np.sqrt(np.mean((1.0 + 0.2 * np.array(MOVES)) ** 2)))
GYRO = Gyro(dt=DT, terms=[FilteredWhiteNoise(N=TRUTH["N"], tf=0.011), GaussMarkov(sigma=TRUTH["B"] / B_EQUIV_OVER_SIGMA,
                                                                                  tc=10.0),
                          RateRandomWalk(K=TRUTH["K"]), Sinusoidal(8.5e-3, 0.47)])


def record(kind, r):
    rng = np.random.default_rng([20261207, r])
    if kind == "stationary":
        return GYRO.simulate(N, rng)
    level = np.repeat(1.0 + 0.2 * np.array(MOVES), N // 8)
    white = Gyro(dt=DT, terms=[FilteredWhiteNoise(N=TRUTH["N"], tf=0.011)])
    rest = Gyro(dt=DT, terms=GYRO.terms[1:])
    return white.simulate(N, rng) * level + rest.simulate(N, rng)


def shown(fit, c):
    e = fit.result().coefficients[c]
    return e.interval


def main(R):
    plain = (GMWM._dispersion, GMWM._bound_edf)
    for kind in ("stationary", "moving"):
        hold = {(w, c): 0 for w in ("before", "after") for c in TRUTH}
        width = {(w, c): [] for w in ("before", "after") for c in TRUTH}
        count = {c: 0 for c in TRUTH}
        for r in range(R):
            x = record(kind, r) * 100.0  # at unit magnitude, as avbench estimate fits
            for which in ("before", "after"):
                if which == "before":
                    GMWM._dispersion = staticmethod(lambda check: 1.0)
                    GMWM._bound_edf = staticmethod(lambda wv, check, factor, dispersion=1.0: wv.edf)
                else:
                    GMWM._dispersion, GMWM._bound_edf = staticmethod(plain[0]), staticmethod(plain[1])
                fit = estimators.get("gmwm_filtered").fit(x, DT)
                for c, t in TRUTH.items():
                    t = N_MOVING if (kind, c) == ("moving", "N") else t
                    iv = shown(fit, c)
                    if iv is None or not np.all(np.isfinite(iv)):
                        continue
                    count[c] += which == "after"
                    lo, hi = iv[0] / 100.0, iv[1] / 100.0
                    hold[(which, c)] += bool(lo <= t <= hi)
                    width[(which, c)].append((hi - lo) / t)
        for c in TRUTH:
            for which in ("before", "after"):
                k, n = hold[(which, c)], count[c]
                lo, hi = _clopper_pearson(k, n)
                print(f"{kind} {c} {which}: {k}/{n} hold the truth ({k / max(n, 1):.3f}, 95 % [{lo:.3f}, {hi:.3f}]); "
                      f"median width / truth {np.median(width[(which, c)]):.3f}", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 30)
