"""Edges by rule: the text-table sniffer and the magnitude check, tested by property.

* Any numeric table written with any of the separators the reader accepts (decimal commas where
  ``,`` is not the separator), with or without a header whose names hold spaces, brackets and
  slashes, reads back as the same columns (values equal to the text written), whatever the
  header's own characters.
* A record of absurd magnitude for its declared unit gets a note that names the unit and the
  expected range; any plausible record gets none, in every unit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from avbench.noise_models.units import SAMPLE_UNITS, samples_to_si
from avbench.recordings.readers import header_unit, read_recording
from avbench.recordings.sensors import PLAUSIBLE_SI, plausibility, to_si

SEPARATORS = {",": ",", ";": ";", "tab": "\t", "blank": " "}
# names: letters, digits, spaces, brackets, slashes, dots, underscores; never a number, never a time name
NAME_CHARS = st.sampled_from(list("abcdefgxyzGXYZ_ []/.-^0123456789"))
finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)


def _name(s: str) -> bool:
    s = s.strip()
    if not s or s.lower() in {"t", "time", "timestamp", "time_s", "times", "t_s", "nan", "inf", "infinity"}:
        return False
    if header_unit(s)[1] not in (None, "gyro"):  # its header declares another kind ("[G]": gauss), which the
        return False  # reader rightly refuses for a gyro column (test_a_declared_unit_of_another_kind_is_refused)
    try:
        float(s)
        return False
    except ValueError:
        return True


@st.composite
def tables(draw):
    sep = draw(st.sampled_from(list(SEPARATORS)))
    k = draw(st.integers(1, 4))
    n = draw(st.integers(3, 30))
    values = np.array(draw(st.lists(st.lists(finite, min_size=k, max_size=k), min_size=n, max_size=n)))
    header = draw(st.booleans())
    names = None
    if header:
        chars = NAME_CHARS if sep != "blank" else NAME_CHARS.filter(lambda c: c != " ")
        # a blank-separated header cannot hold a name with a space (the character filter alone has let one through)
        names = draw(st.lists(st.text(chars, min_size=1, max_size=14).map(str.strip).filter(_name)
                              .filter(lambda s: sep != "blank" or " " not in s), min_size=k, max_size=k, unique=True))
    decimal = draw(st.sampled_from([".", ","])) if sep != "," else "."
    return sep, values, names, decimal


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(table=tables())
def test_any_table_reads_back_as_written(tmp_path_factory, table):
    sep_name, values, names, decimal = table
    # one unnamed column of decimal-comma numbers ("0,5") is a comma table of integers: ambiguous by
    # nature (read as two columns, as any sniffer would); with a header or more columns it is not
    assume(not (decimal == "," and values.shape[1] == 1 and names is None))
    sep = SEPARATORS[sep_name]
    path = tmp_path_factory.mktemp("t") / "rec.csv"
    cell = (lambda v: repr(float(v)).replace(".", decimal))
    lines = ([sep.join(names)] if names else []) + [sep.join(cell(v) for v in row) for row in values]
    path.write_text("\n".join(lines) + "\n")
    cols = names if names else [str(i) for i in range(values.shape[1])]
    rec = read_recording(path, gyro=",".join(cols) if values.shape[1] > 1 or names else None, time_column="none")
    assert len(rec.channels) == values.shape[1]
    for j, c in enumerate(rec.channels):
        if names:
            assert c.name == names[j]
        np.testing.assert_array_equal(np.asarray(c.values, float), values[:, j])


@pytest.mark.parametrize("name,kind", [("[G]", "magnetic"), ("x [g]", "accel"), ("x [m/s^2]", "accel"),
                                       ("t0 [ms]", "time"), ("temp [degC]", "temperature")])
def test_a_declared_unit_of_another_kind_is_refused(tmp_path, name, kind):
    """A column chosen as gyro whose header declares an acceleration or a time unit is an error naming both."""
    p = tmp_path / "rec.csv"
    p.write_text(name + "\n" + "\n".join(["0.0", "1.0", "2.0"]) + "\n")
    assert header_unit(name)[1] == kind
    with pytest.raises(ValueError, match="chosen as gyro but its header says"):
        read_recording(p, gyro=name, time_column="none")


@pytest.mark.parametrize("header", ["gyro x [deg/s]", "rate (deg/s) z", "w x / deg s^-1"])
def test_one_column_with_a_spaced_header_is_one_column(tmp_path, header):
    x = np.random.default_rng(1).normal(size=40)
    p = tmp_path / "one.csv"
    p.write_text(header + "\n" + "\n".join(repr(float(v)) for v in x) + "\n")
    rec = read_recording(p)
    assert [c.name for c in rec.channels] == [header]
    np.testing.assert_array_equal(rec.channels[0].values, x)


def test_a_header_with_spaces_in_a_comma_table(tmp_path):
    x = np.random.default_rng(2).normal(size=(30, 2))
    p = tmp_path / "two.csv"
    p.write_text("gyro x [deg/s], gyro y [deg/s]\n" + "\n".join(f"{float(a)!r}, {float(b)!r}" for a, b in x) + "\n")
    rec = read_recording(p, gyro="gyro x [deg/s],gyro y [deg/s]")
    np.testing.assert_array_equal(np.column_stack([c.values for c in rec.channels]), x)


@settings(max_examples=80, deadline=None)
@given(sensor=st.sampled_from(["gyro", "accel"]), data=st.data(),
       log_peak=st.floats(min_value=-300, max_value=300))
def test_magnitude_note_by_rule(sensor, data, log_peak):
    """A note exactly when the largest magnitude, in SI, is outside the plausible range; it names the
    unit and the range expected in that unit."""
    unit = data.draw(st.sampled_from(list(SAMPLE_UNITS[sensor])))
    per_unit = float(samples_to_si(1.0, unit, sensor))
    x = np.random.default_rng(0).uniform(-1, 1, 64)
    x *= 10.0**log_peak / np.max(np.abs(x))
    assume(np.all(np.isfinite(x)) and np.max(np.abs(x)) > 0)
    peak_si = float(np.max(np.abs(x))) * per_unit
    lo, hi = PLAUSIBLE_SI[sensor]
    assume(not math.isclose(peak_si, lo, rel_tol=1e-9) and not math.isclose(peak_si, hi, rel_tol=1e-9))
    note = plausibility(x, unit, sensor, "col")
    assert (note is not None) == (not lo <= peak_si <= hi)
    if note:
        assert unit in note and "expected" in note and ("above" in note) == (peak_si > hi)


def test_absurd_magnitude_is_noted_with_what_was_expected(tmp_path):
    p = tmp_path / "absurd.csv"
    p.write_text("\n".join(repr(float(1e297 * v)) for v in np.random.default_rng(3).normal(size=64)) + "\n")
    rec = read_recording(p)
    to_si(rec, "rad/s")
    assert len(rec.notes) == 1 and "1e+03 rad/s" in rec.notes[0] and "--units" in rec.notes[0]
    rec = read_recording(p)
    to_si(rec, "deg/s")  # still absurd in deg/s, and the range is given in deg/s
    assert "5.73e+04 deg/s" in rec.notes[0]


def test_constant_axes_are_skipped_and_said_and_all_constant_is_refused(tmp_path):
    """A constant (or all-zero) axis has no noise to fit: skipped with a note naming it; a record whose
    every chosen axis is constant is refused before any fit."""
    p = tmp_path / "zeros.csv"
    p.write_text("0.0\n" * 64)
    with pytest.raises(ValueError, match=r"every chosen axis is constant \(gyro column 0\)"):
        to_si(read_recording(p), "deg/s")
    x = np.random.default_rng(4).normal(size=64)
    q = tmp_path / "mixed.csv"
    q.write_text("gx,gy,gz\n" + "".join(f"{float(v)!r},3.5,0\n" for v in x))
    rec = read_recording(q)
    (s,) = to_si(rec, "deg/s")
    assert list(s.axes) == ["x"]
    assert sum("constant" in n and "skipped" in n for n in rec.notes) == 2
