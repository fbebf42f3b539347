"""Gyros from the source papers, at the papers' sample rates.

Every preset lists its source table, how its units were read, the sample rate and the paper's record
length. Bias instability is simulated as flicker noise (:class:`~avbench.noise_models.BiasInstability`)
with its filter memory ``tau_max`` twice the record length T, so the exact AV stays within about 1 %
of the plateau (2 ln2/pi) B^2 from tau = 8 dt to T/15 and rises by about 7 % at the longest octave
tau = T/2 (the truth every estimator is scored against is that exact curve, not the constant);
rate ramp as the deterministic ramp (exact R^2 tau^2 / 2).

========================  ======  ======  ===================================================
name                      rate    record  source
========================  ======  ======  ===================================================
SRS2000, VG951, CRG20     10 Hz   4 h     Lv et al. 2015, Tables 1, 3, 5 (Q, N, B)
ADIS16405_X, _Y, _Z       100 Hz  5 h     Miao et al. 2015, Table 2, Allan-variance column (N, B, K)
ADIS16405_X_50HZ          50 Hz   5 h     Miao et al. 2014, Table 2, 50 Hz column (N, B)
ADIS16405_Y_2014          100 Hz  5 h     Miao et al. 2014, Table 2, 100 Hz column (N, B, K)
FOG1, FOG2                100 Hz  3 h     Miao et al. 2015, Table 3, Allan-variance column (Q..R)
========================  ======  ======  ===================================================

>>> from avbench.noise_models import presets
>>> "SRS2000" in presets.names()
True
>>> presets.get("ADIS16405_Y").dt
0.01
"""

from __future__ import annotations

from dataclasses import dataclass, field

from avbench.noise_models.gyro import Gyro
from avbench.noise_models.terms import AngleRandomWalk, BiasInstability, Quantization, RateRamp, RateRandomWalk

__all__ = ["Preset", "get", "names", "info", "record_seconds"]


@dataclass(frozen=True)
class Preset:
    name: str
    dt: float
    duration_s: float
    coefficients: dict  # coefficient -> (value, unit) as printed by the paper (after unit reading)
    source: str
    units_note: str = ""
    extra: dict = field(default_factory=dict)

    def gyro(self) -> Gyro:
        terms = []
        c = self.coefficients
        if "Q" in c:
            terms.append(Quantization(Q=c["Q"]))
        if "N" in c:
            terms.append(AngleRandomWalk(N=c["N"]))
        if "B" in c:
            terms.append(BiasInstability(B=c["B"], tau_max=2 * self.duration_s))
        if "K" in c:
            terms.append(RateRandomWalk(K=c["K"]))
        if "R" in c:
            terms.append(RateRamp(R=c["R"]))
        return Gyro(dt=self.dt, terms=terms, name=self.name)

    @property
    def n_samples(self) -> int:
        return int(round(self.duration_s / self.dt))


_LV = (
    "Lv, Liu, Lai, Huang (2015), Optik, Table {t}. Q in microrad, N in deg/sqrt(h), B in deg/h "
    "(as the paper's headers say); sample time 0.1 s, 4 h records (its section 4)."
)
_MIAO15 = (
    "Miao, Shen, Xu, He, Tian (2015), Sensors 15, Table 2 (ADIS16405 gyro {axis}, 5 h static at "
    "100 Hz), Allan-variance column: N deg/sqrt(h), B deg/h, K deg/h^(3/2)."
)
_FOG_NOTE = (
    "Q is labelled '(deg)' in Table 3. Read literally, {q} deg of angle quantization at 100 Hz "
    "gives a rate noise (Allan deviation at 0.01 s, sqrt(3) Q / tau) of ~{rate:.1f} deg/s, absurd beside N = {n} deg/sqrt(h). We read it as arcsec "
    "(the IEEE Std 952 unit for Q; '\u00b0' for '\u2033' is a plausible typesetting slip): then "
    "quantization dominates the AV only below tau ~ 0.02 s, and ARW above it, as a FOG's AV curve "
    "looks. R (deg/h^2) is simulated as the deterministic ramp, not the paper's second-order "
    "Gauss-Markov stand-in (eq. 8), so that R^2 tau^2 / 2 holds exactly."
)


def _fog_note(q: float, n: float) -> str:
    """The unit-reading note of a Miao et al. 2015 FOG, quoting that FOG's own Q and N."""
    return _FOG_NOTE.format(q=q, n=n, rate=3**0.5 * q / 0.01)


_PRESETS: dict[str, Preset] = {
    p.name: p
    for p in [
        Preset(
            "SRS2000",
            0.1,
            4 * 3600.0,
            {"Q": (6.870e-3, "urad"), "N": (8.587e-5, "deg/sqrt(h)"), "B": (6.773e-3, "deg/h")},
            _LV.format(t=1) + " Navigation-grade FOG.",
        ),
        Preset(
            "VG951",
            0.1,
            4 * 3600.0,
            {"Q": (7.555e-2, "urad"), "N": (7.636e-3, "deg/sqrt(h)"), "B": (1.246e-1, "deg/h")},
            _LV.format(t=3) + " Tactical-grade FOG.",
        ),
        Preset(
            "CRG20",
            0.1,
            4 * 3600.0,
            {"Q": (1.868e1, "urad"), "N": (1.492, "deg/sqrt(h)"), "B": (2.079e1, "deg/h")},
            _LV.format(t=5) + " MEMS gyro.",
        ),
        Preset(
            "ADIS16405_X",
            0.01,
            5 * 3600.0,
            {"N": (2.2378, "deg/sqrt(h)"), "B": (28.3271, "deg/h"), "K": (68.5726, "deg/h^1.5")},
            _MIAO15.format(axis="X"),
        ),
        Preset(
            "ADIS16405_Y",
            0.01,
            5 * 3600.0,
            {"N": (2.2437, "deg/sqrt(h)"), "B": (29.4976, "deg/h"), "K": (62.6242, "deg/h^1.5")},
            _MIAO15.format(axis="Y"),
            "Miao et al. 2014 (Table 2) gives slightly different AV values for the same gyro Y "
            "(B 28.3976, K 62.1752): see ADIS16405_Y_2014.",
        ),
        Preset(
            "ADIS16405_Z",
            0.01,
            5 * 3600.0,
            {"N": (2.5248, "deg/sqrt(h)"), "B": (30.2804, "deg/h"), "K": (60.3588, "deg/h^1.5")},
            _MIAO15.format(axis="Z"),
        ),
        Preset(
            "ADIS16405_Y_2014",
            0.01,
            5 * 3600.0,
            {"N": (2.2437, "deg/sqrt(h)"), "B": (28.3976, "deg/h"), "K": (62.1752, "deg/h^1.5")},
            "Miao, Shen, Xu, Tian, He (2014), JINST 9 P09001, Table 2, 100 Hz column (ADIS16405 "
            "gyro Y, 5 h static at 100 Hz), Allan-variance values: N deg/sqrt(h), B deg/h, K deg/h^(3/2).",
        ),
        Preset(
            "ADIS16405_X_50HZ",
            0.02,
            5 * 3600.0,
            {"N": (3.1178, "deg/sqrt(h)"), "B": (25.5637, "deg/h")},
            "Miao, Shen, Xu, Tian, He (2014), JINST 9 P09001, Table 2, 50 Hz column (ADIS16405 gyro "
            "X, 5 h static at 50 Hz), Allan-variance values: N deg/sqrt(h), B deg/h; K not modelled.",
        ),
        Preset(
            "FOG1",
            0.01,
            3 * 3600.0,
            {
                "Q": (0.0224, "arcsec"),
                "N": (0.0050, "deg/sqrt(h)"),
                "B": (0.2771, "deg/h"),
                "K": (0.5530, "deg/h^1.5"),
                "R": (0.3499, "deg/h^2"),
            },
            "Miao et al. (2015), Sensors 15, Table 3, #1 FOG (3 h static at 100 Hz), Allan-variance column.",
            _fog_note(q=0.0224, n=0.0050),
        ),
        Preset(
            "FOG2",
            0.01,
            3 * 3600.0,
            {
                "Q": (0.0260, "arcsec"),
                "N": (0.0051, "deg/sqrt(h)"),
                "B": (0.2667, "deg/h"),
                "K": (0.2994, "deg/h^1.5"),
                "R": (0.1382, "deg/h^2"),
            },
            "Miao et al. (2015), Sensors 15, Table 3, #2 FOG (3 h static at 100 Hz), Allan-variance column.",
            _fog_note(q=0.0260, n=0.0051),
        ),
    ]
}


def names() -> list[str]:
    """Names of the presets."""
    return list(_PRESETS)


def info(name: str) -> Preset:
    """The :class:`Preset` record (source, units reading, sample rate, record length)."""
    try:
        return _PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown preset {name!r}: expected one of {', '.join(_PRESETS)}") from None


def get(name: str) -> Gyro:
    """A :class:`~avbench.noise_models.Gyro` for preset ``name`` at the paper's sample rate."""
    return info(name).gyro()


def record_seconds(name: str) -> float:
    """The record length (s) the paper used for this gyro."""
    return info(name).duration_s
