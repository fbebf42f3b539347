"""The seeding rule of every study: one independent random stream per gyro x replicate.

Replicate ``r`` of gyro ``g`` draws from ``SeedSequence(seed, spawn_key=(g, r))`` -- the stream
``SeedSequence(seed).spawn`` would give its (g, r) grandchild -- so every number depends only on
the config and the seed, never on the worker count, the backend or the order tasks finish in. The
runner (simulation) and the figures (replicate 0 redrawn) both take it from here.
"""

from __future__ import annotations

import numpy as np

__all__ = ["replicate_rng"]


def replicate_rng(seed: int, gyro_index: int, replicate: int) -> np.random.Generator:
    """The generator of replicate ``replicate`` of gyro ``gyro_index`` (independent of scheduling)."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(gyro_index, replicate)))
