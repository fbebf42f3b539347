"""Step 5c: the Allan deviation of each axis with every method's fitted curve and each fitted term.

One figure per sensor, one panel per axis (or one figure per axis: ``axes``): the overlapping octave
ADEV (gap-aware) with its 68 % chi^2 bars, each method's model curve (dashed; "poor fit" in its label
when flagged) over the scales the method fitted (:func:`fitted_scales`), and for the first method that
fitted the terms' own lines -- Q: sqrt(3) Q / tau, N: N / sqrt(tau),
B: sqrt(2 ln2 / pi) B, K: K sqrt(tau / 3), R: R tau / sqrt(2) (IEEE Std 952 Annex C) -- each
labelled with its value in the display units (resolved values only). Under each panel, the residuals of every method's
fit check (:mod:`avbench.estimators.allan.fit_check`): z per tau, the decorrelated standardised
residual of the AV against the method's model (the result's ``fit_check.residuals``; about N(0, 1)
where the model holds), with the +-2 band: where a flagged fit misses the curve, and by how much.

Every text is drawn at :data:`TEXT_PT` points or more: at the 110 dpi of the files and the page, and a
panel shown at its own width, no smaller than a page's body text (15 px). Drawn at a cost that does
not dominate the command: a matplotlib ``Figure`` on the Agg canvas without pyplot, margins set in
inches (no tight-layout pass, which draws every tick label once more to measure it), grid lines at the
decades, no minor ticks, and the decades labelled in plain text with Unicode superscripts (:func:`power_label`:
matplotlib's default log labels are mathtext, whose parser costs ~20 ms per distinct label).
"""

from __future__ import annotations

import math

import numpy as np

from avbench.noise_models.units import DISPLAY_UNITS, SI_SAMPLE_UNIT, from_si

__all__ = ["figure", "residuals", "deviations_figure", "fitted_scales", "power_label", "TEXT_PT"]

#: the smallest text of a figure, in points (10 pt at 110 dpi: 15.3 px)
TEXT_PT = 10.0

_TERM = {
    "Q": lambda c, t: math.sqrt(3.0) * c / t,
    "N": lambda c, t: c / np.sqrt(t),
    "B": lambda c, t: math.sqrt(2 * math.log(2) / math.pi) * c * np.ones_like(t),
    "K": lambda c, t: c * np.sqrt(t / 3.0),
    "R": lambda c, t: c * t / math.sqrt(2.0),
}


_SUPERSCRIPT = str.maketrans("-0123456789", "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075\u2076\u2077\u2078\u2079")


def power_label(value, _pos=None) -> str:
    """A log axis's tick label in plain text: ``10⁻³`` at a decade, ``2×10⁻³`` between (a mantissa of at
    most two significant digits), "" for a value that is not positive and finite.

    >>> power_label(1e-3), power_label(100.0), power_label(1.0), power_label(2e-3), power_label(0.0)
    ('10⁻³', '10²', '10⁰', '2×10⁻³', '')
    """
    if not (math.isfinite(value) and value > 0):
        return ""
    e = math.floor(math.log10(value) + 1e-9)
    m = value / 10.0**e
    sup = "10" + str(e).translate(_SUPERSCRIPT)
    return sup if abs(m - 1.0) < 1e-9 else f"{m:.2g}×{sup}"


def _plain_log_labels(axs):
    """Each log axis of ``axs`` labelled by :func:`power_label` (no mathtext)."""
    from matplotlib.ticker import FuncFormatter

    for ax in np.ravel(axs):
        for axis in (ax.xaxis, ax.yaxis):
            if axis.get_scale() == "log":
                axis.set_major_formatter(FuncFormatter(power_label))


def fitted_scales(fit, tau, dt) -> np.ndarray:
    """The taus of ``tau`` (s) a method's model holds for: from the first AV scale it fitted (its model
    choice ``min_m``, in samples, where it makes one) up."""
    first = fit.result.model_choice.get("min_m")
    tau = np.asarray(tau, dtype=float)
    if isinstance(first, (int, float)) and not isinstance(first, bool) and first > 0:
        return tau[tau >= first * dt * (1 - 1e-9)]
    return tau


def figure(sensor_record, axis_fits, avs, dt, title, flags, deviations=None, axes=None):
    """A matplotlib Figure for one sensor (``axis_fits``: axis -> method -> MethodFit; ``avs``: axis ->
    (AllanResult of the record times ``scale``, ``scale``), see :func:`~avbench.recordings.fit.scaled_allan`;
    ``flags``: axis -> method -> poor-fit flag; ``deviations``: axis -> name -> AllanResult of the
    deviation family, drawn as lines with their 68 % chi^2 band, TDEV excepted, which is an angle;
    ``axes``: the axes drawn, default all). Deviations are drawn in SI units."""
    import matplotlib

    axes_names = list(sensor_record.axes) if axes is None else list(axes)
    with matplotlib.rc_context({"font.size": TEXT_PT, "legend.fontsize": TEXT_PT, "axes.titlesize": TEXT_PT,
                                "axes.labelsize": TEXT_PT, "xtick.labelsize": TEXT_PT,
                                "ytick.labelsize": TEXT_PT}):
        fig, axs = _new_figure(2, len(axes_names), (6.2 * len(axes_names), 7.4), sharex="col",
                               gridspec_kw={"height_ratios": [3.0, 1.1]})
        _draw_panels(axs, axes_names, sensor_record, axis_fits, avs, dt, title, flags, deviations)
        _no_minor_ticks(axs)
        _plain_log_labels(axs)
    return fig


def _draw_panels(axs, axes_names, sensor_record, axis_fits, avs, dt, title, flags, deviations):
    from avbench.recordings.fit import fitted_avar

    sensor = sensor_record.sensor
    units = DISPLAY_UNITS[sensor]
    si = SI_SAMPLE_UNIT[sensor]
    for ax, rax, name in zip(axs[0], axs[1], axes_names):
        av, scale = avs[name]
        with np.errstate(invalid="ignore", over="ignore"):
            lo, hi, adev = np.sqrt(av.ci_low) / scale, np.sqrt(av.ci_high) / scale, av.adev / scale
        ax.errorbar(av.tau, adev, yerr=[adev - lo, hi - adev], fmt="o", ms=3, color="k",
                    label="overlapping ADEV (68 % χ²)")
        tau = np.unique(np.rint(np.logspace(0, np.log10(max(av.m.max(), 1)), 80)).astype(int)) * dt
        terms_drawn = False
        for i, (method, fit) in enumerate(axis_fits[name].items()):
            if fit.error is not None:
                continue
            held = fitted_scales(fit, tau, dt)
            with np.errstate(invalid="ignore", over="ignore"):
                curve = fitted_avar(fit, held, scaled=True) * (scale / fit.scale) ** 2
            label = method + ("  (POOR FIT)" if flags.get(name, {}).get(method) else "")
            if np.any(curve > 0):
                ax.plot(held, np.sqrt(np.where(curve > 0, curve, np.nan)) / scale, "--", color=f"C{i}", label=label)
            if not terms_drawn:
                for j, (c, f) in enumerate(_TERM.items()):
                    v = fit.result.coefficients[c].value  # resolved values only
                    if math.isfinite(v) and v > 0:
                        shown = from_si(c, v, units[c], sensor)
                        ax.plot(tau, f(v, tau), ":", lw=1.2, color=f"C{j + 5}", label=f"{c} = {shown:.3g} {units[c]}")
                terms_drawn = True
        _draw_deviations(ax, (deviations or {}).get(name, {}), skip=("tvar", "avar"))  # OADEV: the points above
        for i, (method, fit) in enumerate(axis_fits[name].items()):
            r = residuals(fit)
            if r is not None:
                rax.plot(r[0], r[1], "o-", ms=3, lw=0.8, color=f"C{i}", label=method)
        rax.axhspan(-2, 2, color="0.9", zorder=0)
        rax.axhline(0, color="0.5", lw=0.8)
        rax.set_xscale("log")
        rax.set_xlabel("τ (s)")
        rax.set_ylabel("fit check z")
        rax.grid(True, alpha=0.3)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylabel(f"Allan deviation ({si})")
        ax.set_title(f"{title + ' — ' if title else ''}{sensor} {name}")
        ax.grid(True, alpha=0.3)
        ymin, ymax = np.nanmin(lo[lo > 0]) if np.any(lo > 0) else None, np.nanmax(hi) if np.any(np.isfinite(hi)) else None
        if ymin and ymax and math.isfinite(ymin) and math.isfinite(ymax):
            ax.set_ylim(ymin / 3, ymax * 3)
        ax.legend(loc="lower left", framealpha=0.8)


#: the margins around the panels (inches): left (the y label and tick labels), right, bottom (the x
#: label), top (the titles), and between panels across (a y label) and down
_MARGINS_IN = {"left": 1.0, "right": 0.2, "bottom": 0.65, "top": 0.4, "across": 1.1, "down": 0.15}


def _new_figure(rows, cols, size, **kw):
    """(Figure, axes array rows x cols) on the Agg canvas, without pyplot, with the margins of
    :data:`_MARGINS_IN` (no tight-layout pass)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    w, h = size
    m = _MARGINS_IN
    fig = Figure(figsize=size)
    FigureCanvasAgg(fig)
    axs = fig.subplots(rows, cols, squeeze=False, **kw)
    panel_w = (w - m["left"] - m["right"] - m["across"] * (cols - 1)) / cols
    panel_h = (h - m["bottom"] - m["top"] - m["down"] * (rows - 1)) / rows
    fig.subplots_adjust(left=m["left"] / w, right=1 - m["right"] / w, bottom=m["bottom"] / h, top=1 - m["top"] / h,
                        wspace=m["across"] / panel_w, hspace=m["down"] / panel_h)
    return fig, axs


def _no_minor_ticks(axs):
    """Log axes without their minor ticks (each a line and a text object, most of the drawing's cost
    over several decades); the decades keep their ticks, labels and grid lines."""
    for ax in np.ravel(axs):
        ax.minorticks_off()


def residuals(fit):
    """(tau, z) of a fitted method's fit check, or None when it has none (failed, a method without the
    check, or a check that is not made per tau: whittle's bins frequencies)."""
    return fit.result.fit_check.residuals


def _draw_deviations(ax, devs, skip=("tvar",)):
    """Each deviation of ``devs`` (name -> AllanResult) as a line with its chi^2 band (TDEV, an angle, skipped)."""
    for k, (dname, r) in enumerate(devs.items()):
        if r.kind in skip:
            continue
        with np.errstate(invalid="ignore"):
            ax.plot(r.tau, r.deviation, "-", marker=".", lw=1, color=f"C{(k + 3) % 10}", label=dname.upper())
            ax.fill_between(r.tau, np.sqrt(r.ci_low), np.sqrt(r.ci_high), color=f"C{(k + 3) % 10}", alpha=0.12)


def deviations_figure(sensor, si_unit, deviations, title, confidence):
    """``avbench deviations``: one panel per axis, each deviation of ``deviations`` (axis -> name ->
    AllanResult, SI units) with its chi^2 band at ``confidence``; TDEV (an angle) on a second y axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(deviations)
    fig, axs = plt.subplots(1, len(names), figsize=(6.2 * len(names), 4.6), squeeze=False)
    for ax, name in zip(axs[0], names):
        _draw_deviations(ax, deviations[name])
        t = {k: r for k, r in deviations[name].items() if r.kind == "tvar"}
        if t:
            ax2 = ax.twinx()
            for dname, r in t.items():
                ax2.plot(r.tau, r.deviation, "--", color="0.4", lw=1, label=f"{dname.upper()} (right axis)")
            ax2.set_yscale("log")
            ax2.set_ylabel(f"time deviation ({si_unit.split('/')[0]})")
            ax2.legend(fontsize=7, loc="upper right")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("τ (s)")
        ax.set_ylabel(f"deviation ({si_unit})")
        ax.set_title(f"{title + ' — ' if title else ''}{sensor} {name} (bands: {confidence:.0%} χ²)", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    return fig
