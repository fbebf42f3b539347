"""``avbench three-cornered-hat A B C``: each of three sensors' own noise from three recordings made together.

Three units recorded side by side on one table (three gyros, three clocks) see the same common
motion; the differences of pairs cancel it, and with independent noises
``AV(a - b) = AV(a) + AV(b)``, so each unit's own variance follows from the three pairwise ones
(Gray & Allan 1974; the estimates and their error bars:
:func:`avbench.estimators.allan.deviations_tf.three_cornered_hat`). A negative estimate -- the noise
of one unit too small to be seen beside the others' at that tau -- is kept as it is and reported as
an upper bound, not set to 0.

The three recordings are read as ``avbench estimate`` reads one (the same reader options, which
apply to all three); they must have the same rate and are cut to the shortest; the sensor and axis
are chosen with ``--sensor`` and ``--axis`` (the first of each by default).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

__all__ = ["hat_of_recordings", "hat_table"]


def _channel(loaded, sensor, axis, label):
    rec, timing, sensors = loaded
    chosen = [s for s in sensors if sensor in (None, s.sensor)]
    if not chosen:
        raise ValueError(f"--sensor {sensor}: {label} ({rec.path}) has no {sensor} channels")
    s = chosen[0]
    names = list(s.axes)
    name = axis if axis is not None else names[0]
    if name not in s.axes:
        raise ValueError(f"--axis {axis}: {label} ({rec.path}) has {s.sensor} axes {', '.join(names)}")
    return s, name, np.asarray(s.axes[name], dtype=float), timing


def hat_of_recordings(paths, *, sensor=None, axis=None, kind="oadev", taus="octave", confidence=0.683,
                      **reader_options):
    """``(ThreeCorneredHat, sensor record, axis, dt)`` of three recordings (module docstring)."""
    from avbench.estimators.allan.deviations_tf import three_cornered_hat
    from avbench.recordings.load import load_recording

    if len(paths) != 3:
        raise ValueError(f"expected three recordings made together, got {len(paths)}")
    picked = [_channel(load_recording(p, **reader_options), sensor, axis, label)
              for p, label in zip(paths, ("A", "B", "C"))]
    dts = [t.dt for *_, t in picked]
    if max(dts) > min(dts) * (1 + 1e-6):
        raise ValueError(f"the three recordings have different sample intervals {dts} s: expected one rate "
                         "(resample them, or give --fs)")
    kinds = {s.sensor for s, *_ in picked}
    if len(kinds) != 1:
        raise ValueError(f"the three recordings give different sensors {sorted(kinds)}: choose one with --sensor")
    n = min(x.size for _, _, x, _ in picked)
    if any(t.starts.size for *_, t in picked):
        raise ValueError("a recording has gaps: the three-cornered hat needs three gap-free records of the same "
                         "instants")
    a, b, c = (x[:n] for _, _, x, _ in picked)
    hat = three_cornered_hat(a, b, c, dts[0], kind, taus, confidence=confidence)
    return hat, picked[0][0], picked[0][1], dts[0]


def hat_table(hat, sensor_record, labels) -> pd.DataFrame:
    """One row per unit and tau: the unit's own variance and deviation (SI), its standard error,
    Satterthwaite's edf, the deviation's interval at the hat's confidence (``ThreeCorneredHat.ci_low``
    / ``ci_high``), and whether the estimate is negative (then the deviation is empty and the
    interval ``[0, upper]`` a bound)."""
    lo, hi = hat.ci_low, hat.ci_high
    rows = []
    for i, label in enumerate(labels):
        for j, tau in enumerate(hat.tau):
            v = float(hat.avar[i, j])
            rows.append({"unit": label, "tau": float(tau), "m": int(hat.m[j]), "avar": v,
                         "deviation": math.sqrt(v) if v > 0 else math.nan, "std_err": float(hat.std_err[i, j]),
                         "edf": float(hat.sensor_edf[i, j]), "lower_dev": math.sqrt(max(float(lo[i, j]), 0.0)),
                         "upper_dev": math.sqrt(max(float(hi[i, j]), 0.0)), "negative": not v > 0,
                         "si_unit": sensor_record.si_unit})
    return pd.DataFrame(rows)
