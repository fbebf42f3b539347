"""Measurement: a second, slow Gauss-Markov bias term (GS) on the full accel runs."""
import math, pickle, sys, warnings, numpy as np
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
import avbench.estimators.likelihood.gmwm as G
from avbench import estimators
d = pickle.load(open("/work/accel_out/diag_accel.pkl", "rb"))
for k, v in d.items():
    res = {}
    for model in ("FW+GM+RW", "FW+GM+GS+RW"):
        e = estimators.get("gmwm_filtered", model=model, bias_evidence=False, resonance="model").fit(v["x"], v["dt"])
        g = e.diagnostics_
        res[model] = (e.coefficients_["N"], e.coefficients_["B"], e.coefficients_["K"], g["J_stat"], g["dof"], g["min_m"], g["fit_pvalue"])
    a, b = res["FW+GM+RW"], res["FW+GM+GS+RW"]
    print(k, "K ratio GS/plain %.2f" % (b[2] / a[2] if a[2] else float('nan')), "B ratio %.2f" % (b[1] / a[1]), "N ratio %.3f" % (b[0] / a[0]),
          "J %.1f/%d m%d -> %.1f/%d m%d" % (a[3], a[4], a[5], b[3], b[4], b[5]), "p %.3g -> %.3g" % (a[6], b[6]), flush=True)
