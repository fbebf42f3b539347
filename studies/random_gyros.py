"""Gyros drawn at random outside the presets, for ``studies/random_gyros.toml``.

``python -m avbench.studies.random_gyros > studies/random_gyros.toml`` writes the config; the draw
depends only on ``SEED`` (the config is committed, so the study's tables depend only on it).

Each gyro (10 Hz, 2 h records): angle random walk N log-uniform over the presets' range
(2.5e-8 .. 9e-4 rad/s/sqrt(Hz)); each of quantization, flicker bias instability and rate random walk
present with probability 0.7, its size relative to N log-uniform over the presets' ratios
(Q/N in 0.03 .. 0.3 sqrt(s), B/N in 0.15 .. 1.5 sqrt(Hz), K/N in 0.005 .. 0.05 /s); the flicker's
memory ``tau_max`` log-uniform in 0.2 .. 5 record lengths (below and above the record).
:data:`REPLICATES` records per gyro give each gyro's RMSE / CRLB (the leaderboard's median over the
gyros); coverage is pooled over gyros and replicates
(:func:`avbench.studies.summaries.random_gyros.pooled`).
"""

from __future__ import annotations

import numpy as np

SEED = 2323
N_GYROS = 200
DT = 0.1
RECORD_S = 7200.0
#: records per gyro: enough for each gyro's own RMSE (relative standard error ~0.3) and a median over
#: the gyros
REPLICATES = 6

#: (low, high) of the log-uniform draws
N_RANGE = (2.5e-8, 9e-4)
RATIOS = {"Q": (0.03, 0.3), "B": (0.15, 1.5), "K": (0.005, 0.05)}
P_PRESENT = 0.7
TAU_MAX = (0.2, 5.0)

HEADER = """# Gyros drawn at random outside the presets: written by
# `python -m avbench.studies.random_gyros` (seed {seed}); do not edit by hand.
#
# {n} gyros x {reps} replicates of 2 h at 10 Hz: N always; Q, flicker B (tau_max 0.2-5 record lengths), K
# each present with probability 0.7, sized relative to N within the presets' ratios. Estimators: the
# recommended default (de-biased Whittle, every candidate term kept, profile-likelihood intervals),
# the reference (the same likelihood told each gyro's true terms), its estimates averaged over the
# submodels by BIC weight with each coefficient's own term kept, by Akaike and BIC weight with dropped
# terms counted 0 and by Akaike weight with own terms kept, the plain Whittle likelihood, and Whittle
# with BIC term selection (`whittle`). Per gyro:
# RMSE / CRLB over its replicates (scores.md, leaderboard.md: the median over gyros). Pooled coverage
# per coefficient:
# avbench.studies.summaries.random_gyros (results/random_gyros/pooled.md).

[study]
name = "random_gyros"
description = "{n} gyros drawn at random (seed {seed}) outside the presets, 2 h at 10 Hz, {reps} replicates each."
seed = {seed}
replicates = {reps}
duration_s = {record}
block_size = 1
figure_gyros = ["g000", "g001"]

[[estimators]]
name = "whittle_debiased"
label = "Whittle debiased (profile)"
settings = {{ terms = "QNBKR" }}

[[estimators]]
name = "whittle_debiased"
label = "Whittle debiased, true terms"
settings = {{ terms = "true", averaging = "none" }}

[[estimators]]
name = "whittle_debiased"
label = "Whittle debiased, BIC-averaged, own term kept"
settings = {{ terms = "QNBKR", averaging = "bic_kept" }}

[[estimators]]
name = "whittle_debiased"
label = "Whittle debiased, Akaike-averaged"
settings = {{ terms = "QNBKR", averaging = "akaike" }}

[[estimators]]
name = "whittle_debiased"
label = "Whittle debiased, BIC-averaged"
settings = {{ terms = "QNBKR", averaging = "bic" }}

[[estimators]]
name = "whittle_debiased"
label = "Whittle debiased, Akaike-averaged, own term kept"
settings = {{ terms = "QNBKR", averaging = "akaike_kept" }}

[[estimators]]
name = "whittle_debiased"
label = "Whittle plain (profile)"
settings = {{ terms = "QNBKR", spectrum = "plain" }}

[[estimators]]
name = "whittle"
label = "Whittle (BIC)"
settings = {{ terms = "QNBKR" }}
"""


def draw(seed: int = SEED, n_gyros: int = N_GYROS) -> list[dict]:
    """The gyros' terms (SI) as dicts ``{coef: value, "tau_max": s}``."""
    rng = np.random.default_rng(seed)

    def logu(lo, hi):
        return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))

    out = []
    for _ in range(n_gyros):
        N = logu(*N_RANGE)
        g = {"N": N}
        for c in ("Q", "B", "K"):
            present = rng.uniform() < P_PRESENT
            val = N * logu(*RATIOS[c])
            tau = logu(*TAU_MAX) * RECORD_S
            if present:
                g[c] = val
                if c == "B":
                    g["tau_max"] = tau
        out.append(g)
    return out


def config_text(seed: int = SEED, n_gyros: int = N_GYROS) -> str:
    lines = [HEADER.format(seed=seed, n=n_gyros, reps=REPLICATES, record=RECORD_S)]
    for i, g in enumerate(draw(seed, n_gyros)):
        terms = []
        if "Q" in g:
            terms.append(f'{{type = "Quantization", Q = {g["Q"]:.6g}}}')
        terms.append(f'{{type = "AngleRandomWalk", N = {g["N"]:.6g}}}')
        if "B" in g:
            terms.append(f'{{type = "BiasInstability", B = {g["B"]:.6g}, tau_max = {g["tau_max"]:.6g}}}')
        if "K" in g:
            terms.append(f'{{type = "RateRandomWalk", K = {g["K"]:.6g}}}')
        lines.append(f'[[gyros]]\nname = "g{i:03d}"\ndt = {DT}\nterms = [\n    ' + ",\n    ".join(terms) + ",\n]\n")
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover
    print(config_text(), end="")
