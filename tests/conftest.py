import numpy as np
import pytest
from scipy import stats


def mc_tolerance(samples: np.ndarray, alpha: float = 1e-4) -> np.ndarray:
    """Two-sided Student-t half-width for the mean of ``samples`` along axis 0 at level ``alpha``.

    The tolerance of every statistical test comes from the replicates themselves: the standard
    error of their mean times the t quantile for len(samples) - 1 degrees of freedom.
    """
    R = samples.shape[0]
    se = samples.std(axis=0, ddof=1) / np.sqrt(R)
    return stats.t.ppf(1 - alpha / 2, R - 1) * se


@pytest.fixture
def tol():
    return mc_tolerance
