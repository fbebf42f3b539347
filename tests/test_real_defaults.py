"""The default methods on the real recordings (optional: skipped when the licensed recordings are
not next to the repository, in ../shared/data/real/, read in place)."""

from pathlib import Path

import numpy as np
import pytest

import estimators
from estimators.base import DEFAULT_METHODS
from noise_models.units import from_si

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
ADIS = DATA / "adis16405-calgary" / "adis_16405_imu1.npz"
MTIG = DATA / "mtig-cont-imu1" / "cont_imu1.npz"
needs = pytest.mark.skipif(not (ADIS.exists() and MTIG.exists()),
                           reason="real recordings not found in ../shared/data/real (optional, licensed data)")


def _records():
    x = np.deg2rad(np.load(ADIS)["data"][:, :3])
    for k in range(3):
        yield f"ADIS X{'XYZ'[k]}", x[:, k]
    yield "MTi-G", np.asarray(np.load(MTIG)["data"], dtype=float).ravel()


@pytest.mark.slow
@needs
@pytest.mark.parametrize("name", DEFAULT_METHODS)
def test_defaults_are_physically_plausible_on_real_records(name):
    # plausibility bounds (DEFAULT_METHODS gave N 1.4-2.8, B 8-58 on all 19 axes; results/real): N within a factor 1.5 of the 2-3 deg/sqrt(h) every method and the
    # datasheet's noise density agree on (MTi-G: 1.3-2.2), B between a fifth and twice the ADEV
    # minimum read as a plateau (B = min ADEV / 0.664: 38-46 deg/h on ADIS, 7-60 on the MTi-G)
    for label, rate in _records():
        est = estimators.get(name).fit(rate, 0.01)
        n = from_si("N", est.coefficients_["N"], "deg/sqrt(h)")
        b = from_si("B", est.coefficients_["B"], "deg/h")
        assert 1.0 < n < 4.0, (label, n)
        assert 5.0 < b < 100.0, (label, b)
        assert isinstance(est.diagnostics_["poor_fit"], bool)
