"""The `avbench estimate` figure: an ADEV panel per axis, and under it the fit check's z per tau."""

import numpy as np
import pytest

from avbench.noise_models import AngleRandomWalk, Gyro, RateRandomWalk, Sinusoidal
from avbench.recordings import figure
from avbench.recordings.fit import fit_axis, scaled_allan
from avbench.recordings.sensors import SensorRecord


def test_residual_panels_show_each_methods_z():
    dt = 0.01
    g = Gyro(dt=dt, terms=[AngleRandomWalk(N=1e-4), Sinusoidal(3e-3, 0.6), RateRandomWalk(K=2e-6)])
    x = g.simulate(100_000, np.random.default_rng(0))
    starts = np.empty(0, dtype=np.int64)
    fits = fit_axis(x, dt, starts, ["gmwm"], {"gmwm": {"model": "WN+RW"}})
    fits_sn = fit_axis(x, dt, starts, ["gmwm"], {"gmwm": {"model": "WN+RW+SN", "min_m": 1}})
    tau, z = figure.residuals(fits["gmwm"])
    tau_sn, z_sn = figure.residuals(fits_sn["gmwm"])
    assert tau.size >= 5 and np.max(np.abs(z)) > 4  # the bump the model lacks shows in z ...
    assert np.max(np.abs(z_sn)) < 4  # ... and is gone with the sinusoid
    rec = SensorRecord("gyro", "rad/s", {"x": x}, {"x": "x"})
    fig = figure.figure(rec, {"x": fits}, {"x": scaled_allan(x, dt, starts)}, dt, "t", {"x": {"gmwm": True}})
    top, bottom = fig.axes[0], fig.axes[1]
    assert top.get_yscale() == "log" and bottom.get_ylabel() == "fit check z"
    assert len(bottom.lines) >= 1 and np.allclose(bottom.lines[0].get_ydata(), z)


def test_a_model_curve_is_drawn_only_over_the_scales_its_method_fitted():
    """GMWM told to start at the 8th sample (``min_m=8``): its curve starts at 8 dt, the AV's points at dt;
    a method without that choice (wls) is drawn from the first tau; every text at TEXT_PT points or more."""
    from matplotlib.text import Text

    dt = 0.01
    x = Gyro(dt=dt, terms=[AngleRandomWalk(N=1e-4), RateRandomWalk(K=2e-6)]).simulate(40_000, np.random.default_rng(1))
    starts = np.empty(0, dtype=np.int64)
    fits = fit_axis(x, dt, starts, ["gmwm", "wls"], {"gmwm": {"min_m": 8}})
    assert fits["gmwm"].result.model_choice["min_m"] == 8
    rec = SensorRecord("gyro", "rad/s", {"x": x}, {"x": "x"})
    fig = figure.figure(rec, {"x": fits}, {"x": scaled_allan(x, dt, starts)}, dt, "t", {"x": {}})
    curves = {line.get_label(): line.get_xdata() for line in fig.axes[0].lines}
    assert np.isclose(curves["gmwm"].min(), 8 * dt) and np.isclose(curves["wls"].min(), dt)
    fig.canvas.draw()
    sizes = [t.get_fontsize() for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()]
    assert min(sizes) >= figure.TEXT_PT


def test_log_axes_are_labelled_in_plain_text_at_their_ticks():
    """Every tick label of a log axis is plain text (no mathtext "$"), names its tick's value
    (:func:`figure.power_label` read back), and the drawing parses no mathtext."""
    import re
    from unittest import mock

    from matplotlib import mathtext

    dt = 0.01
    x = Gyro(dt=dt, terms=[AngleRandomWalk(N=1e-4), RateRandomWalk(K=2e-6)]).simulate(40_000, np.random.default_rng(2))
    starts = np.empty(0, dtype=np.int64)
    rec = SensorRecord("gyro", "rad/s", {"x": x}, {"x": "x"})
    fig = figure.figure(rec, {"x": fit_axis(x, dt, starts, ["gmwm"])}, {"x": scaled_allan(x, dt, starts)}, dt, "t",
                        {"x": {}})
    with mock.patch.object(mathtext.MathTextParser, "parse", side_effect=AssertionError("mathtext parsed")):
        fig.canvas.draw()
    sup = str.maketrans("⁻⁰¹²³⁴⁵⁶⁷⁸⁹", "-0123456789")
    checked = 0
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            if axis.get_scale() != "log":
                continue
            lo, hi = sorted(axis.get_view_interval())
            for tick in axis.get_major_ticks():
                text, value = tick.label1.get_text(), tick.get_loc()
                if not lo <= value <= hi:
                    continue
                assert "$" not in text
                m = re.fullmatch(r"(?:([0-9.]+)×)?10([-0-9]+)", text.translate(sup))
                assert m, text
                assert float(m.group(1) or 1) * 10.0 ** int(m.group(2)) == pytest.approx(value, rel=1e-9)
                checked += 1
    assert checked >= 6
