"""``avbench three-cornered-hat A B C``: each of three sensors' own noise from three recordings made together.

Three units recorded side by side on one table (three gyros, three clocks) see the same common
motion; the differences of pairs cancel it, and with independent noises
``AV(a - b) = AV(a) + AV(b)``, so each unit's own variance follows from the three pairwise ones
(Gray & Allan 1974; the estimates and their error bars:
:func:`avbench.estimators.allan.deviations_tf.three_cornered_hat`). A negative estimate -- the noise
of one unit too small to be seen beside the others' at that tau -- is kept as it is and reported as
an upper bound, not set to 0.

The three recordings are read as ``avbench estimate`` reads one (the same reader options, which
apply to all three), and are checked and aligned before any statistic (:func:`hat_of_recordings`):

* **three units**: the same file given twice is refused, naming both places;
* **one channel**: the same sensor and axis in each (``--sensor``, ``--axis``; by default the first
  sensor of A and the first of its axes that all three have), never one unit's y beside another's x;
  an axis a recording skipped (constant) is said;
* **one rate**, and **common instants**: with time stamps (in all three, or in none) each record is
  cut to the span the three have in common, its first sample the one nearest the span's start, so
  that the i-th samples of the three are one instant (a record starting 50 s later, or one sample
  later, is aligned; a record sharing no instant with the others is refused, naming it). Without
  stamps the first samples are taken as one instant (said). A recording with a gap within the
  common span is refused, naming it.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["HatRun", "hat_of_recordings", "hat_table", "unit_labels"]

LETTERS = ("A", "B", "C")


@dataclass
class HatRun:
    """The three-cornered hat of three recordings: the estimates, the channel, the aligned span."""

    hat: object  # avbench.estimators.allan.deviations_tf.ThreeCorneredHat
    sensor_record: object  # A's SensorRecord (its sensor and SI unit)
    axis: str
    dt: float
    labels: list[str]
    notes: list[str] = field(default_factory=list)


def unit_labels(paths) -> list[str]:
    """The names the three units go by: each file's name, or, where two share it (``imu.csv`` in three
    folders), the fewest trailing parts of its path that tell them apart.

    >>> unit_labels(["a/imu.csv", "b/imu.csv", "c/x.csv"])
    ['a/imu.csv', 'b/imu.csv', 'x.csv']
    """
    parts = [Path(os.path.abspath(p)).parts for p in paths]
    labels = []
    for i, p in enumerate(parts):
        k = 1
        while k < len(p) and any(q[-k:] == p[-k:] for j, q in enumerate(parts) if j != i):
            k += 1
        labels.append("/".join(p[-k:]))
    return labels


def _sensor_of(loaded, sensor, who):
    rec, _, sensors = loaded
    chosen = [s for s in sensors if sensor in (None, s.sensor)]
    if not chosen:
        raise ValueError(f"--sensor {sensor}: {who} has no {sensor} channels")
    return chosen[0]


def _choose_axis(records, axis, whos, notes):
    """The one axis name all three sensor records have (``axis``, else the first of A's)."""
    names = [list(s.axes) for s in records]
    if axis is not None:
        for s, n, who in zip(records, names, whos):
            if axis not in s.axes:
                raise ValueError(f"--axis {axis}: {who} has {s.sensor} axes {', '.join(n) or 'none'}; expected an "
                                 "axis of all three")
        return axis
    common = [a for a in names[0] if all(a in n for n in names[1:])]
    if not common:
        raise ValueError(f"no {records[0].sensor} axis is in all three recordings ("
                         + "; ".join(f"{who}: {', '.join(n)}" for who, n in zip(whos, names))
                         + "); expected --axis naming one of each, or recordings of the same axes")
    if common[0] != names[0][0] or any(n[0] != common[0] for n in names):
        notes.append(f"{records[0].sensor} {common[0]}: the first axis all three recordings have ("
                     + "; ".join(f"{who}: {', '.join(n)}" for who, n in zip(whos, names)) + ")")
    return common[0]


def _align(loaded, dt, whos, notes) -> list[tuple[int, int]]:
    """``(first sample, n)`` of each record on the instants the three have in common (module docstring)."""
    times = [rec.time for rec, _, _ in loaded]
    stamped = [t is not None for t in times]
    if any(stamped) and not all(stamped):
        have = ", ".join(w for w, s in zip(whos, stamped) if s)
        lack = ", ".join(w for w, s in zip(whos, stamped) if not s)
        raise ValueError(f"{have} have time stamps and {lack} none: the records cannot be put on common instants; "
                         "expected stamps in all three (or --time none to take their first samples as one instant)")
    if not any(stamped):
        n = min(timing.n_samples for _, timing, _ in loaded)
        notes.append("no time stamps: the three records' first samples are taken as one instant")
        return [(0, n)] * 3
    origins = [rec.time_origin or 0.0 for rec, _, _ in loaded]
    times = [t + (o - min(origins)) for t, o in zip(times, origins)]  # one clock, its origin the earliest start
    spans = [(float(t[0]), float(t[-1])) for t in times]
    start, stop = max(s[0] for s in spans), min(s[1] for s in spans)
    if stop < start - dt / 2:  # the one whose removal leaves the other two a common span is at fault
        rest = [i for i in range(3) if min(spans[j][1] for j in range(3) if j != i)
                >= max(spans[j][0] for j in range(3) if j != i) - dt / 2]
        where = "; ".join(f"{w}: {lo:.9g} to {hi:.9g} s" for w, (lo, hi) in zip(whos, spans))
        if len(rest) == 1:
            raise ValueError(f"{whos[rest[0]]} shares no instant with the other two ({where}); expected three "
                             "recordings made together")
        raise ValueError(f"the three recordings share no instant ({where}); expected recordings made together")
    cuts = []
    for (rec, timing, _), t, who in zip(loaded, times, whos):
        first = int(np.searchsorted(t, start - dt / 2))
        last = int(np.searchsorted(t, stop + dt / 2))
        inside = timing.starts[(timing.starts > first) & (timing.starts < last)]
        if inside.size:
            raise ValueError(f"{who} has {inside.size} gap(s) within the span the three share (the first at "
                             f"{float(t[inside[0]]):.9g} s); the three-cornered hat needs three gap-free records of the "
                             "same instants")
        cuts.append((first, last - first))
        if first or last < t.size:
            notes.append(f"{who}: samples {first} to {last - 1} of {t.size}, the instants all three have")
    n = min(c[1] for c in cuts)
    return [(first, n) for first, _ in cuts]


def hat_of_recordings(paths, *, sensor=None, axis=None, kind="oadev", taus="octave", confidence=0.683,
                      **reader_options) -> HatRun:
    """The three-cornered hat of three recordings made together (module docstring)."""
    from avbench.estimators.allan.deviations_tf import three_cornered_hat
    from avbench.recordings.files import check_distinct
    from avbench.recordings.load import load_recording

    if len(paths) != 3:
        raise ValueError(f"expected three recordings made together, got {len(paths)}")
    labels = unit_labels(paths)
    whos = [f"{letter} ({p})" for letter, p in zip(LETTERS, paths)]
    check_distinct(paths, whos, "three recordings of three units")
    loaded = [load_recording(p, **reader_options) for p in paths]
    notes = [f"{who}: {note}" for who, (rec, _, _) in zip(whos, loaded) for note in rec.notes]
    records = [_sensor_of(x, sensor, who) for x, who in zip(loaded, whos)]
    kinds = {s.sensor for s in records}
    if len(kinds) != 1:
        raise ValueError(f"the three recordings give different sensors ("
                         + "; ".join(f"{w}: {s.sensor}" for w, s in zip(whos, records)) + "); choose one with --sensor")
    dts = [t.dt for _, t, _ in loaded]
    if max(dts) > min(dts) * (1 + 1e-6):
        raise ValueError("the three recordings have different sample intervals ("
                         + "; ".join(f"{w}: {d:.9g} s" for w, d in zip(whos, dts))
                         + "); expected one rate (resample them, or give --fs)")
    name = _choose_axis(records, axis, whos, notes)
    cuts = _align(loaded, dts[0], whos, notes)
    a, b, c = (np.asarray(s.axes[name], dtype=float)[first:first + n] for s, (first, n) in zip(records, cuts))
    hat = three_cornered_hat(a, b, c, dts[0], kind, taus, confidence=confidence)
    return HatRun(hat, records[0], name, dts[0], labels, notes)


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
