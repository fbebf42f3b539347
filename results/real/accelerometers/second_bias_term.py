"""Measurement (not the default): a second, slow Gauss-Markov bias term on the full ADIS16405 accelerometer runs.

``GS``: a Gauss-Markov term with tc >= 30 s that reports no coefficient (B stays the first term's), added to
``FW+GM+RW`` (the line test adds ``SN``); ``gmwm_filtered`` without the bias-evidence and resonance steps, both
models on the same record. Prints per axis K, B, N of the two-term fit over the one-term fit, Hansen's J / dof /
shortest cluster size, and the fit check's p-value. The term is registered in the latent table at run time only.

``AVBENCH_REAL_DATA=... python results/real/accelerometers/second_bias_term.py`` (~3 CPU-min)."""
import math
import warnings

import numpy as np
import avbench.noise_models.latents as L
from avbench.noise_models.markov_terms import GaussMarkov
warnings.simplefilter("ignore")

class SlowGaussMarkov(GaussMarkov):
    coefficient = None
    latent = "GS"
    @classmethod
    def fit_shape_bounds(cls, tau, dt, T, hint=None):
        return [math.log(max(30.0, tau[0]))], [math.log(10 * T)]
    @classmethod
    def fit_starts(cls, tau, avar, lo, hi, *, n_starts=1, hint=None):
        out = []
        for tc in (100.0, 400.0):
            peak = np.interp(math.log(1.89 * tc), np.log(tau), avar)
            out.append((math.sqrt(peak / 0.38) / 2, tc))
        return out

new = {}
for k, v in L.LATENT_TERMS.items():
    new[k] = v
    if k == "FL":
        new["GS"] = SlowGaussMarkov
L.LATENT_TERMS.clear(); L.LATENT_TERMS.update(new)
L.LATENTS.clear(); L.LATENTS.update({c: (cls.fit_parameters, cls.coefficient) for c, cls in new.items()})
import os
from pathlib import Path

from avbench import estimators
from avbench.recordings.fit import _scale_of
from avbench.studies.real_runs import _records

for rec, sensor, axis, x, timing in _records(Path(os.environ["AVBENCH_REAL_DATA"])):
    if sensor != "accel":
        continue
    k, x = (rec, axis), np.asarray(x)
    v = {"x": x * _scale_of(x), "dt": timing.dt}
    res = {}
    for model in ("FW+GM+RW", "FW+GM+GS+RW"):
        e = estimators.get("gmwm_filtered", model=model, bias_evidence=False, resonance="model").fit(v["x"], v["dt"])
        g = e.diagnostics_
        res[model] = (e.coefficients_["N"], e.coefficients_["B"], e.coefficients_["K"], g["J_stat"], g["dof"], g["min_m"], g["fit_pvalue"])
    a, b = res["FW+GM+RW"], res["FW+GM+GS+RW"]
    print(k, "K ratio GS/plain %.2f" % (b[2] / a[2] if a[2] else float('nan')), "B ratio %.2f" % (b[1] / a[1]), "N ratio %.3f" % (b[0] / a[0]),
          "J %.1f/%d m%d -> %.1f/%d m%d" % (a[3], a[4], a[5], b[3], b[4], b[5]), "p %.3g -> %.3g" % (a[6], b[6]), flush=True)
