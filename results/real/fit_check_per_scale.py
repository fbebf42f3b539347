"""Measurement: the per-scale reading of the fit check (``fit_covariance="record"``) on simulated records of the
models ``gmwm_filtered`` fitted to real gyro axes, where the model is true and the record stationary.

For each model (the fitted parameters of an axis whose default fit the per-scale reading flagged), ``R`` records
of the real run's length are simulated and fitted by ``gmwm_filtered``; on each the per-scale test is made on the
fit's own scales as :func:`avbench.estimators.allan.fit_check.assess_fit` makes it (the batches' variances
against the record's AV level, Student's t where a batch variance is used, Bonferroni over the scales at
``alpha / 2``) whether or not the record shows an excess (which on a stationary record it rarely does, so the
default check seldom reads it), with the linearised residual variance alone (``pinned=1``) and with the floor of
:data:`~avbench.estimators.allan.fit_check.PINNED_LEVERAGE`. Prints per model the records flagged by each and
the Clopper-Pearson 95 % interval of the rate; the nominal rate is at most ``alpha / 2`` = 0.005.

``python results/real/fit_check_per_scale.py [R]`` (~6 CPU-s a record). With R = 30 (seeds [20261207, r]): the
linearised residual alone flags 30/30 records of each model (largest |z| / limit, median: 218, 171, 12,839: the
first octave, which the fit pins); with the floor 0/30 of each, 0/90 in all (95 % interval of the rate
[0, 0.040]; median largest |z| / limit 0.48-0.51)."""
import sys
import warnings

import numpy as np

from avbench import estimators
from avbench.estimators.allan import fit_check as F
from avbench.estimators.allan.covariance import av_covariance
from avbench.estimators.allan.variance import allan_variance
from avbench.estimators.likelihood import gmwm as G
from avbench.noise_models.latents import build_gyro
from avbench.studies.scoring import _clopper_pearson

warnings.simplefilter("ignore")
DT, N = 0.01, 1_000_000
#: gmwm_filtered's fits (FW+GM+RW, SI, rad/s) of ADIS16405 run 3 y and run 5 y, and of the MTi-G's x (FW+GM):
#: their FW tf is 5.1, 6.1 and 1.8 ms (the last far below dt: the first octave pinned by N and tf)
MODELS = {
    "adis run 3 y": ("FW+GM+RW", [7.58e-4, 0.005142, 2.11e-4, 39.5, 9e-06]),
    "adis run 5 y": ("FW+GM+RW", [8.16e-4, 0.006095, 1.88e-4, 41.0, 1.2e-05]),
    "mtig x": ("FW+GM", [5.64e-4, 0.001767, 3.0e-4, 3.17]),
}


def per_scale(captured, pinned):
    """(flagged, largest |z| / limit): the per-scale test of the captured check
    (:func:`~avbench.estimators.allan.fit_check.scale_residuals` on the fit's own scales, forced)."""
    a, k = captured
    rate, dt, model_avar, gyro = a[0], a[1], a[2], a[3]
    tau_j, jac = k["jacobian"]
    av = allan_variance(rate, dt, taus="octave")
    keep = ((av.n_samples // av.m >= F.MIN_CLUSTERS) & (av.tau >= tau_j[0] * (1 - 1e-9))
            & (av.tau <= tau_j[-1] * (1 + 1e-9)))
    tau, avar, m = av.tau[keep], av.avar[keep], av.m[keep]
    z, lim = F.scale_residuals(rate, m, avar, model_avar(tau), av_covariance(gyro, m, av.n_samples),
                               jac[np.searchsorted(tau_j, tau)], av.n_samples, F.ALPHA / 2, pinned=pinned)
    return bool(np.any(np.abs(z) > lim)), float(np.max(np.abs(z) / lim))


def main(R):
    captured = []
    orig = G.assess_fit

    def spy(*a, **k):
        if k.get("record_covariance") and k.get("jacobian") is not None:
            captured.append((a, k))
        return orig(*a, **k)

    G.assess_fit = spy
    for name, (model, values) in MODELS.items():
        gyro = build_gyro(G.parse_model(model), np.asarray(values, float), DT, 2 * N * DT)
        flags = {1.0: 0, F.PINNED_LEVERAGE: 0}
        worst = {1.0: [], F.PINNED_LEVERAGE: []}
        for r in range(R):
            x = gyro.simulate(N, np.random.default_rng([20261207, r]))
            captured.clear()
            estimators.get("gmwm_filtered").fit(x * 1e3, DT)  # at unit magnitude, as avbench estimate fits
            for pinned in flags:
                f, w = per_scale(captured[-1], pinned)
                flags[pinned] += f
                worst[pinned].append(w)
        for pinned, k in flags.items():
            lo, hi = _clopper_pearson(k, R)
            print(f"{name}: pinned={pinned}: {k}/{R} records flagged by the per-scale test (rate {k / R:.3f}, "
                  f"95 % [{lo:.3f}, {hi:.3f}]); largest |z|/limit median {np.median(worst[pinned]):.2f}", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 40)
