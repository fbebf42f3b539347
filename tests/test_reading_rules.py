"""The reading rules of ``avbench estimate``, tested by property over generated inputs.

* **Time** (recordings/time_units.py, recordings/timing.py): stamps generated in any unit, from any
  origin (zero, boot, the epoch, a wrapping uint32 counter), at any IMU rate, rounded or not, in any
  dtype, are read in their own unit with the rate of their span -- or refused, naming --time-units,
  exactly where another unit also gives an IMU's rate and neither the epoch nor --fs decides. No gap is
  invented by the stamps' resolution; two or more missing samples are always a gap.
* **Tables** (recordings/text_tables.py): any dialect (separator, quoting, byte-order mark, line
  ends) reads back as written; a header whose names do not match the fields, and decimal commas
  under comma separators whatever the exponent, are refused.
* **Units** (recordings/channels.py, recordings/sensors.py): case decides where it carries meaning
  (g vs G); a static accelerometer's unit follows from gravity.
* **Named arrays** (recordings/arrays.py): one rule for .npz and .mat, top level or struct, any
  orientation.
"""

from __future__ import annotations

import csv
import io
import math
import time

import numpy as np
import pytest
import scipy.io
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

from avbench.noise_models.units import SAMPLE_UNITS, STANDARD_GRAVITY, samples_to_si
from avbench.recordings.channels import header_unit
from avbench.recordings.readers import read_recording
from avbench.recordings.sensors import GRAVITY_TOLERANCE, accel_unit_from_gravity, to_si
from avbench.recordings.time_units import EPOCH_START, PLAUSIBLE_RATE, TIME_SCALE, Stamps, stamps_in_seconds
from avbench.recordings.timing import timing_of

FIXTURES = [HealthCheck.function_scoped_fixture, HealthCheck.too_slow]


# -- time ---------------------------------------------------------------------------------------------

@st.composite
def stamp_records(draw):
    """(raw stamps, true unit, true rate, quantum in raw units, relative jitter, n)."""
    unit = draw(st.sampled_from(list(TIME_SCALE)))
    rate = 10 ** draw(st.floats(math.log10(1.1), math.log10(30_000)))
    n = draw(st.integers(40, 1500))
    origin = draw(st.sampled_from(["zero", "boot", "epoch", "uint32"]))
    rounding = draw(st.sampled_from(["exact", "integer", "decimals"]))
    dtype = draw(st.sampled_from(["float64", "float32", "int64"]))
    jitter = draw(st.sampled_from([0.0, 0.02]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    scale = TIME_SCALE[unit]
    step = 1.0 / (rate * scale)  # raw units per sample
    t0 = {"zero": 0.0, "boot": draw(st.floats(1.0, 6e5)), "epoch": 1.7e9, "uint32": draw(st.floats(1.0, 6e5))}[origin]
    start = int(round(t0 / scale))  # a whole number of units: the origin adds no digits
    rel = (np.arange(n) + jitter * rng.uniform(-0.5, 0.5, n)) * step
    if origin == "uint32" or dtype == "int64":
        rounding = "integer"
    if rounding == "integer":
        ints, q = start + np.floor(rel).astype(np.int64), 1.0  # integer arithmetic: 1.7e18 ns keep every ns
        raw = ints.astype(np.float64)
    elif rounding == "decimals":
        d = draw(st.integers(0, 6))
        raw, q = start + np.round(rel, d), 10.0 ** -d
    else:
        raw, q = start + rel, 0.0
    if origin == "uint32":
        raw = (ints % 2**32).astype(np.uint32)
    elif rounding == "integer" and dtype != "float32":
        raw = ints
    else:  # float stamps are resolved to their spacing, too (float64 epoch seconds: 0.24 us)
        raw = raw.astype(np.float32 if dtype == "float32" else np.float64)
        q = max(q, float(np.spacing(raw.dtype.type(np.max(np.abs(raw))))))
    assume(q <= 0.5 * step)  # stamps resolved finer than half the interval (coarser ones are the next test's)
    return raw, unit, rate, q, jitter, n


def _plausible(rate, unit):
    """The units in which stamps of ``unit`` at ``rate`` give an IMU's rate."""
    lo, hi = PLAUSIBLE_RATE
    rates = {u: rate * TIME_SCALE[unit] / TIME_SCALE[u] for u in TIME_SCALE}
    return [u for u, r in rates.items() if lo <= r <= hi], rates


@settings(max_examples=400, deadline=None)
@given(case=stamp_records(), with_fs=st.booleans())
def test_time_unit_and_rate_by_plausibility(case, with_fs):
    raw, unit, rate, q, jitter, n = case
    plausible, rates = _plausible(rate, unit)
    lo, hi = PLAUSIBLE_RATE
    assume(all(not (0.97 * lo < r < 1.03 * lo or 0.97 * hi < r < 1.03 * hi) for r in rates.values()))
    step = 1.0 / (rate * TIME_SCALE[unit])
    error = (2 * q + jitter * step) / ((n - 1) * step)  # the span's error, relative
    hint = (rate, "--fs") if with_fs else None
    first = float(raw[0])
    dated = [u for u in plausible if EPOCH_START <= first * TIME_SCALE[u] <= time.time()]
    decided = len(plausible) == 1 or len(dated) == 1 or (with_fs and error < 0.005)
    try:
        seconds, got, how, _, _ = stamps_in_seconds("f", Stamps(raw, "column 't'"), None, hint)
    except ValueError as e:
        assert not decided, (unit, rate, plausible, str(e))
        assert "--time-units" in str(e) and len(str(e).splitlines()) == 1
        event("refused: two plausible units")
        return
    assert got == unit, (unit, rate, plausible, how)
    event("read: " + ("the only plausible unit" if len(plausible) == 1 else "decided by the epoch or --fs"))
    timing = timing_of(seconds, None, n, "f", q * TIME_SCALE[unit] or None)
    assert timing.n_gaps == 0
    assert abs(timing.fs / rate - 1) <= error * 1.01 + 1e-9


@settings(max_examples=200, deadline=None)
@given(per_q=st.floats(1.05, 40.0), n=st.integers(200, 3000), at=st.floats(0.1, 0.9), missing=st.integers(0, 5),
       seed=st.integers(0, 2**32 - 1))
def test_resolution_invents_no_gap_and_misses_none(per_q, n, at, missing, seed):
    """ms-integer stamps of any rate up to 1 kHz (dt = per_q ms, rounded down to 1 ms, 2 % jitter):
    the rate is right to the stamps' resolution, no rounding makes a gap, and ``missing`` >= 2 samples
    dropped at one place are one gap there (one missing sample may hide in the rounding)."""
    rng = np.random.default_rng(seed)
    k = np.arange(n + missing)
    k = np.delete(k, np.arange(int(at * n), int(at * n) + missing))
    raw = np.floor(1e7 + (k + 0.02 * rng.uniform(-0.5, 0.5, k.size)) * per_q).astype(np.int64)
    stamps = Stamps(raw, "column 't'", "ms", "the header")
    assume(PLAUSIBLE_RATE[0] < 1000 / per_q)
    seconds, _, _, resolution, _ = stamps_in_seconds("f", stamps)
    timing = timing_of(seconds, None, raw.size, "f", resolution)
    assert resolution == pytest.approx(1e-3)
    if missing != 1 or timing.n_gaps:  # a missing sample taken for two steps lengthens the span by one dt
        runs = timing.n_gaps + 1  # each run's span is off by its ends' rounding (1 ms each) and jitter (1 % each)
        assert abs(timing.dt * 1000 / per_q - 1) <= runs * (2 + 0.02 * per_q) / (per_q * (n - 2)) + 1e-9
    if missing >= 2:
        assert timing.starts.tolist() == [int(at * n)]
    elif missing == 0:
        assert timing.n_gaps == 0


def test_the_reported_examples():
    """Shapes of real files' time stamps: PX4 ulog2csv (us since boot at 250 Hz, starting past 1e8), a
    wrapping uint32 us counter, ms since boot, ms-integer stamps at 800 Hz, float32 stamps, whole
    seconds at 1 Hz (refused: 1 Hz in s or 1 kHz in ms), us at 8 kHz (refused; --fs decides)."""
    def read(raw, hint=None, declared=None):
        s, unit, _, q, notes = stamps_in_seconds("f", Stamps(np.asarray(raw), "column 't'", declared), None, hint)
        return unit, timing_of(s, None, len(raw), "f", q), notes

    i = np.arange(3000)
    unit, t, _ = read(120_000_000 + i * 4000)
    assert unit == "us" and t.fs == pytest.approx(250) and t.n_gaps == 0
    unit, t, notes = read(((2**32 - 1_000_000 + i * 4000) % 2**32).astype(np.uint32))
    assert unit == "us" and t.fs == pytest.approx(250) and t.n_gaps == 0 and "32-bit counter" in notes[0]
    unit, t, _ = read(2e8 + i * 10)
    assert unit == "ms" and t.fs == pytest.approx(100)
    unit, t, _ = read(np.floor(1e6 + i * 1.25).astype(np.int64))
    assert unit == "ms" and t.fs == pytest.approx(800, rel=1e-3) and t.n_gaps == 0
    unit, t, _ = read((1e5 + i * 0.01).astype(np.float32))
    assert unit == "s" and t.fs == pytest.approx(100, rel=1e-3) and t.n_gaps == 0
    with pytest.raises(ValueError, match=r"1 Hz as s and 1000 Hz as ms.*--time-units s or --time-units ms"):
        read(i)
    with pytest.raises(ValueError, match=r"8 Hz as ms and 8000 Hz as us.*--time-units ms or --time-units us"):
        read(3_000_000 + i * 125)
    assert read(3_000_000 + i * 125, (8000.0, "--fs"))[0] == "us"
    assert read(1_700_000_000_000_000 + i * 125)[0] == "us"  # an epoch stamp decides
    with pytest.raises(ValueError, match=r"the header says ms, which makes 0.25 Hz.*--time-units"):
        read(120_000_000 + i * 4000, declared="ms")


def test_a_files_rate_is_read_and_held_against_fs(tmp_path):
    x = np.random.default_rng(1).standard_normal((500, 3))
    f = tmp_path / "r.npz"
    np.savez(f, gyro=x, fs=np.array(200.0))
    from avbench.recordings.load import load_recording

    assert load_recording(f, units="rad/s").timing.fs == 200.0
    with pytest.raises(ValueError, match=r"--fs 100: .* states its rate as 200 Hz \(variable 'fs'\)"):
        load_recording(f, units="rad/s", fs=100)
    np.savez(f, gyro=x, t=np.arange(500) / 100.0, dt=np.array(0.005))
    with pytest.raises(ValueError, match=r"variable 'dt' says 200 Hz but its time stamps give 100 Hz"):
        load_recording(f, units="rad/s")


# -- tables -------------------------------------------------------------------------------------------

NAMES = st.text(st.characters(whitelist_categories=("Ll", "Lu")), min_size=2, max_size=8).filter(
    lambda s: s.lower() not in {"time", "times", "nan", "inf", "infinity"})
finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


@st.composite
def tables(draw, min_cols=1):
    k = draw(st.integers(min_cols, 4))
    n = draw(st.integers(3, 40))
    values = np.array(draw(st.lists(st.lists(finite, min_size=k, max_size=k), min_size=n, max_size=n)))
    names = draw(st.lists(NAMES, min_size=k, max_size=k, unique_by=str.lower))
    return values, names


@settings(max_examples=80, deadline=None, suppress_health_check=FIXTURES)
@given(table=tables(), sep=st.sampled_from([",", ";", "\t", " "]), quoting=st.sampled_from(["minimal", "header", "all"]),
       bom=st.booleans(), crlf=st.booleans())
def test_any_dialect_reads_back(tmp_path_factory, table, sep, quoting, bom, crlf):
    """RFC 4180 quoting (R's write.csv quotes every name; QUOTE_ALL quotes numbers too), a byte-order
    mark, CRLF line ends: the same columns, the same names, the same values."""
    values, names = table
    buf = io.StringIO()
    w = csv.writer(buf, delimiter=sep, lineterminator="\r\n" if crlf else "\n",
                   quoting=csv.QUOTE_ALL if quoting != "minimal" else csv.QUOTE_MINIMAL)
    w.writerow(names)
    text = buf.getvalue()
    buf = io.StringIO()
    w = csv.writer(buf, delimiter=sep, lineterminator="\r\n" if crlf else "\n",
                   quoting=csv.QUOTE_ALL if quoting == "all" else csv.QUOTE_MINIMAL)
    w.writerows([[repr(float(v)) for v in row] for row in values])
    path = tmp_path_factory.mktemp("t") / "rec.csv"
    path.write_bytes((("\ufeff" if bom else "") + text + buf.getvalue()).encode("utf-8"))
    rec = read_recording(path, gyro=",".join(names), time_column="none")
    assert [c.name for c in rec.channels] == names
    np.testing.assert_array_equal(np.column_stack([c.values for c in rec.channels]), values)


@settings(max_examples=60, deadline=None, suppress_health_check=FIXTURES)
@given(table=tables(min_cols=2), sep=st.sampled_from([",", ";", "\t", " "]), extra=st.sampled_from([-1, 1]),
       index=st.booleans())
def test_a_header_that_does_not_name_every_field_is_refused(tmp_path_factory, table, sep, extra, index):
    """One name fewer (a table written with its row index) or one more than the fields: refused, naming
    the header -- never read with the names shifted onto the next column."""
    values, names = table
    names = names[:-1] if extra < 0 else names + ["extra"]
    rows = [([str(i)] if index else []) + [repr(float(v)) for v in row] for i, row in enumerate(values)]
    if index and extra < 0:
        names = names + ["last"]  # k names over k + 1 fields
    path = tmp_path_factory.mktemp("h") / "rec.csv"
    path.write_text(sep.join(names) + "\n" + "\n".join(sep.join(r) for r in rows) + "\n")
    k = len(rows[0])
    assume(len(names) != k)
    with pytest.raises(ValueError, match=rf"the header names {len(names)} column\(s\) but line 2 has {k} fields"):
        read_recording(path, gyro=names[0], time_column="none")


@settings(max_examples=80, deadline=None, suppress_health_check=FIXTURES)
@given(table=tables(), places=st.integers(1, 6), style=st.sampled_from(["e", "E", "f"]), header=st.booleans())
def test_decimal_commas_under_comma_separators_are_refused_whatever_the_exponent(tmp_path_factory, table, places,
                                                                                   style, header):
    """Never read as two integer columns: refused -- or, where a one-name header says there is one column
    per number, read as the decimal-comma numbers they are."""
    values, names = table
    cells = [[(f"%.{places}{style}" % v).replace(".", ",") for v in row] for row in values]
    if style == "f":  # a fraction's mark: an exponent, or a leading zero after the comma
        assume(places >= 2 and any(c.split(",")[1].startswith("0") for row in cells for c in row))
    path = tmp_path_factory.mktemp("d") / "rec.csv"
    path.write_text((",".join(names) + "\n" if header else "") + "\n".join(",".join(r) for r in cells) + "\n")
    try:
        rec = read_recording(path, time_column="none", gyro=",".join(names) if header else None)
    except ValueError as e:
        assert "looks written with decimal commas" in str(e)
        return
    # read only where a header of one name per number makes the decimal commas certain: as written
    assert header and len(names) == 1
    written = [float(row[0].replace(",", ".")) for row in cells]
    np.testing.assert_array_equal(rec.channels[0].values, written)


@settings(max_examples=60, deadline=None, suppress_health_check=FIXTURES)
@given(table=tables(min_cols=2), data=st.data())
def test_a_line_with_other_fields_is_refused_naming_it(tmp_path_factory, table, data):
    values, names = table
    rows = [[repr(float(v)) for v in row] for row in values]
    bad = data.draw(st.integers(0, len(rows) - 1))
    rows[bad] = rows[bad][:-1] if data.draw(st.booleans()) else rows[bad] + ["1.0"]
    path = tmp_path_factory.mktemp("r") / "rec.csv"
    path.write_text(",".join(names) + "\n" + "\n".join(",".join(r) for r in rows) + "\n")
    with pytest.raises(ValueError) as e:
        read_recording(path, gyro=",".join(names), time_column="none")
    line = bad + 2 if bad else 3  # a bad first data line is the table's shape: the next line differs
    assert f"line {line}" in str(e.value) or (bad == 0 and "the header names" in str(e.value)), str(e.value)


def test_a_short_first_line_is_refused_naming_the_next(tmp_path):
    """A first data line with fewer fields than the header reads as the table's shape (one column, its
    numbers not split): the first line that differs from it is named."""
    path = tmp_path / "rec.csv"
    path.write_text("AA,AB\n0.0\n0.0,0.0\n0.0,0.0\n")
    with pytest.raises(ValueError, match="line 3: column 0 is not numeric"):
        read_recording(path, gyro="AA,AB", time_column="none")


# -- units --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("spelling, kind, unit", [
    ("g", "accel", "g"), ("G", "magnetic", "G"), ("mg", "accel", "mg"), ("mG", "magnetic", "mG"),
    ("ug", "accel", "ug"), ("µG", "magnetic", "uG"), ("MG", None, None), ("RAD/S", "gyro", "rad/s"),
    ("M/S^2", "accel", "m/s^2"), ("NS", "time", "ns"), ("Deg/H", "gyro", "deg/h"), ("°C", "temperature", "degC")])
def test_case_decides_where_it_carries_meaning(spelling, kind, unit):
    assert header_unit(f"x [{spelling}]")[1:] == (kind, unit)


def test_gauss_columns_are_never_accelerometer_axes(tmp_path):
    x = np.random.default_rng(2).standard_normal((100, 3))
    p = tmp_path / "mag.csv"
    p.write_text("t [s],gx [rad/s],mx [G],my [G]\n" + "".join(f"{i / 100},{a!r},{b!r},{c!r}\n"
                                                              for i, (a, b, c) in enumerate(x.tolist())))
    rec = read_recording(p)
    assert [(c.sensor, c.name) for c in rec.channels] == [("gyro", "gx [rad/s]")]
    with pytest.raises(ValueError, match=r"'mx \[G\]' is chosen as accel but its header says G \(a magnetic field\)"):
        read_recording(p, accel="mx [G]")


@settings(max_examples=100, deadline=None)
@given(unit=st.sampled_from(list(SAMPLE_UNITS["accel"])), rel=st.floats(-0.15, 0.15),
       direction=st.tuples(*[st.floats(-1, 1)] * 3), noise=st.floats(0, 0.05))
def test_accelerometer_units_from_gravity(unit, rel, direction, noise):
    """A static accelerometer, any attitude, its gravity off by up to 15 % (bias, scale, local gravity):
    its unit is found; the same record scaled into no unit's window is not."""
    d = np.array(direction)
    assume(np.linalg.norm(d) > 0.1)
    per = float(samples_to_si(1.0, unit, "accel"))
    mean = d / np.linalg.norm(d) * STANDARD_GRAVITY * (1 + rel) / per
    x = mean + noise * STANDARD_GRAVITY / per * np.random.default_rng(0).standard_normal((500, 3))
    assert accel_unit_from_gravity(list(x.T))[0] == unit
    assert accel_unit_from_gravity(list((x * 3.0).T))[0] is None  # 3 g in no unit's window
    assert GRAVITY_TOLERANCE < 0.5 * (9.80665 - 1) / 9.80665


# -- named arrays ------------------------------------------------------------------------------------

@settings(max_examples=60, deadline=None, suppress_health_check=FIXTURES)
@given(container=st.sampled_from(["npz", "mat"]), struct=st.booleans(), wide=st.booleans(), accel=st.booleans(),
       stamps=st.sampled_from(["t", "time", "fs", "none"]), gyro_name=st.sampled_from(["gyro", "omega", "Gyro"]))
def test_named_arrays_are_found_the_same_way_in_every_container(tmp_path_factory, container, struct, wide, accel,
                                                                  stamps, gyro_name):
    n = 400
    rng = np.random.default_rng(5)
    g = 1e-3 * rng.standard_normal((n, 3))
    a = np.array([0.0, 0.0, 9.81]) + 1e-2 * rng.standard_normal((n, 3))
    arrays = {gyro_name: g.T.copy() if wide else g}
    if accel:
        arrays["acc"] = a
    if stamps in ("t", "time"):
        arrays[stamps] = np.arange(n) / 100.0
    elif stamps == "fs":
        arrays["fs"] = np.array(100.0)
    if struct and container == "npz":
        arrays = {f"imu.{k}": v for k, v in arrays.items()}  # an .npz saved from a flattened struct
    path = tmp_path_factory.mktemp("a") / f"rec.{container}"
    if container == "npz":
        np.savez(path, **arrays)
    else:
        scipy.io.savemat(path, {"imu": arrays} if struct else arrays)
    rec = read_recording(path, fs=None)
    assert [c.sensor for c in rec.channels] == ["gyro"] * 3 + ["accel"] * 3 * accel
    np.testing.assert_array_equal(np.column_stack([c.values for c in rec.channels[:3]]), g)
    if stamps in ("t", "time"):
        assert rec.time is not None and rec.time[-1] == pytest.approx((n - 1) / 100)
    else:
        assert rec.time is None
    assert (rec.rate is not None) == (stamps == "fs")
    if accel:
        (_, acc) = to_si(rec, "rad/s")  # the accelerometer's unit from gravity
        assert acc.unit_in == "m/s^2" and any("gravity" in n for n in rec.notes)
