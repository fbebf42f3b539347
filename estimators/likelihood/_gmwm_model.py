"""The latent model as GMWM fits it: its exact AV and Jacobian in the log-parameters, the box and the starting
values of those parameters, and the coefficients read from a fit.

Each is a loop over the model's noise terms (:mod:`avbench.noise_models.latents`): a term states its
parameters, their box and its starts (:class:`avbench.noise_models.term_base.NoiseTerm`); GMWM keeps no
table of its own.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from avbench.noise_models.latents import LATENT_TERMS, build_gyro, n_parameters

__all__ = ["LatentAV", "LatentAVReference", "log_bounds", "log_starts", "report"]


class LatentAVReference:
    r"""The exact discrete AV of a latent model at ``tau`` as a function of the log-parameters ``u``
    (``__call__``), and its Jacobian d AV / d u (:meth:`jacobian`), for GMWM's solver.

    Every latent's AV is its first parameter (its amplitude) squared times the AV of the same latent at
    unit amplitude, a curve set by its other parameter if it has one (``build_gyro``'s terms: their
    spectrum is amplitude^2 times a shape, ``NoiseTerm.psd_factor``). So

    .. math:: \mathrm{AV}(u) = \sum_l e^{2u_l}\,U_l(\tau; e^{v_l}),\qquad
        \partial_{u_l}\mathrm{AV} = 2e^{2u_l}U_l,\quad \partial_{v_l}\mathrm{AV} = e^{2u_l}\,\partial_{\ln p} U_l

    with :math:`U_l` computed once for a latent without a shape parameter (white, quantization,
    flicker with its fixed memory ``tau_fl``, random walk, ramp) and, for one with a shape parameter
    (Gauss-Markov Tc, the filter's tf, the sinusoid's f0), with its derivative in one call of the
    unit term's ``avar_shape_derivative`` (analytic for the Gauss-Markov term and the sinusoid; the resonance's
    central differences take steps its oscillation at long taus allows), kept for the last value (least_squares
    asks for the residuals and then the Jacobian at the same point). ``extra``: None or ``(j, e)``, a term
    :math:`e^{2u_j} e(\tau)` added (the white gain of a robust AV,
    :class:`avbench.estimators.likelihood.gmwm.WaveletVariance`)."""

    def __init__(self, latents, tau, dt, tau_fl, extra=None):
        self.m = build_gyro(latents, np.ones(n_parameters(latents)), dt, tau_fl).m_of(tau)
        self.dt, self.tau_fl, self.latents, self.extra = dt, tau_fl, latents, extra
        # (index of the amplitude, indices of the shape parameters (empty for none), unit AV or the unit term)
        self.blocks = []
        i = 0
        for lat in latents:
            k = len(LATENT_TERMS[lat].fit_parameters)
            if k == 1:
                term = build_gyro((lat,), [1.0], dt, tau_fl).terms[0]
                self.blocks.append((i, (), term.avar(self.m, dt)))
            else:  # the unit term at any shape values: type(unit)(**{**params, shape_parameters: values})
                self.blocks.append((i, tuple(range(i + 1, i + k)), build_gyro((lat,), [1.0] * k, dt, tau_fl).terms[0]))
            i += k
        self._shape = {}  # block -> (shape values, unit AV, [d unit AV / d ln p])

    def _unit(self, b, unit, p):
        kept = self._shape.get(b)
        if kept is None or kept[0] != p:
            term = type(unit)(**{**unit._params(), **dict(zip(unit.shape_parameters(), p))})
            kept = (p, *term.avar_shape_gradient(self.m, self.dt))
            self._shape[b] = kept
        return kept[1], kept[2]

    def __call__(self, u):
        out = np.zeros(self.m.size)
        for b, (i, j, unit) in enumerate(self.blocks):
            if j:
                unit = self._unit(b, unit, tuple(math.exp(u[k]) for k in j))[0]
            out += math.exp(2.0 * u[i]) * unit
        if self.extra is not None:
            out += math.exp(2.0 * u[self.extra[0]]) * self.extra[1]
        return out

    def jacobian(self, u):
        jac = np.zeros((self.m.size, len(u)))
        for b, (i, j, unit) in enumerate(self.blocks):
            scale = math.exp(2.0 * u[i])
            if j:
                unit, d_unit = self._unit(b, unit, tuple(math.exp(u[k]) for k in j))
                for k, d in zip(j, d_unit):
                    jac[:, k] = scale * d
            jac[:, i] = 2.0 * scale * unit
        if self.extra is not None:
            jac[:, self.extra[0]] += 2.0 * math.exp(2.0 * u[self.extra[0]]) * self.extra[1]
        return jac


class LatentAV(LatentAVReference):
    """:class:`LatentAVReference`'s AV and Jacobian, both from one compiled call
    (:func:`avbench.estimators.likelihood._gmwm_kernels.latent_av`, the same arithmetic; equal to round-off,
    tests), the Jacobian kept for the last point (a least-squares solver asks for the residuals, then for the
    Jacobian at the same point). Where the kernel cannot answer (a resonance's shortest clusters, where the
    reference sums the autocovariance in extended precision; a parameter outside a term's values, where the
    reference raises; a term the kernel does not know) the reference answers."""

    def __init__(self, latents, tau, dt, tau_fl, extra=None):
        from avbench.estimators.likelihood import _gmwm_kernels as kernels
        from avbench.noise_models.markov_terms import _series_powers
        from avbench.noise_models.sensor_terms import _numpy_complex_product

        super().__init__(latents, tau, dt, tau_fl, extra)
        kinds = {"GM": kernels.GAUSS_MARKOV, "FW": kernels.FILTER, "SN": kernels.SINUSOID, "RS": kernels.RESONANCE}
        fused = _numpy_complex_product()
        self._kind = np.array([kernels.FIXED if not j else kinds.get(lat, -1)
                               for lat, (_, j, _) in zip(latents, self.blocks)], dtype=np.int64)
        self._compiled = bool(np.all(self._kind >= 0)) and (fused is not None or kernels.RESONANCE not in self._kind)
        self._first = np.array([i for i, _, _ in self.blocks], dtype=np.int64)
        self._fixed = np.zeros((len(self.blocks), self.m.size))
        for b, (_, j, unit) in enumerate(self.blocks):
            if not j:
                self._fixed[b] = unit
        mf = self.m.astype(float)
        neg_m12, p1, p2, q, pow2 = _series_powers(mf)
        self._args = (np.ascontiguousarray(self.m), float(dt), self._fixed, p1, p2, q, pow2, neg_m12,
                      -1 if extra is None else int(extra[0]),
                      np.zeros(self.m.size) if extra is None else np.ascontiguousarray(extra[1], dtype=float),
                      bool(fused))
        self._kernel = kernels.latent_av
        self._kept = None  # (u, Jacobian) of the last point evaluated

    def _both(self, u):
        u = np.ascontiguousarray(u, dtype=float)
        value, jac = np.empty(self.m.size), np.empty((self.m.size, u.size))
        mi, dt, fixed, p1, p2, q, pow2, neg_m12, ej, ee, fused = self._args
        if self._kernel(self._kind, self._first, u, mi, dt, fixed, p1, p2, q, pow2, neg_m12, ej, ee, fused,
                        value, jac):
            return LatentAVReference.__call__(self, u), LatentAVReference.jacobian(self, u)
        return value, jac

    def __call__(self, u):
        if not self._compiled:
            return super().__call__(u)
        value, jac = self._both(u)
        self._kept = (np.array(u, dtype=float), jac)
        return value

    def jacobian(self, u):
        if not self._compiled:
            return super().jacobian(u)
        kept, self._kept = self._kept, None
        if kept is not None and np.array_equal(kept[0], u):
            return kept[1]
        return self._both(u)[1]


def log_bounds(latents, tau, avar, dt, T, hints=None) -> tuple[np.ndarray, np.ndarray]:
    """The box of the log-parameters of ``latents`` for a fit of the AV curve ``avar`` at ``tau`` of a record
    of ``T`` seconds sampled every ``dt``: each term's :meth:`~avbench.noise_models.term_base.NoiseTerm.fit_bounds`
    (its scale at most the value explaining the whole AV curve alone, times 10, at least 1e-8 of that; its
    shape parameters in the range the taus see), with ``hints`` (latent -> :class:`FitHint`: a spectral line
    or band found in the record) where given."""
    hints = hints or {}
    lo, hi = [], []
    for lat in latents:
        a, b = LATENT_TERMS[lat].fit_bounds(tau, avar, dt, T, hints.get(lat))
        lo += a
        hi += b
    return np.array(lo), np.array(hi)


def log_starts(latents, tau, avar, n_starts, lo, hi, hints=None) -> list[np.ndarray]:
    """Starting log-parameters read off the AV curve: every combination of the terms' starts
    (:meth:`~avbench.noise_models.term_base.NoiseTerm.fit_starts`; a Gauss-Markov Tc at ``n_starts``
    log-spaced values, a sinusoid at a spectral line or the eight strongest bumps of the curve, a resonance
    at each start read off the spectrum), in the order of the terms (the last varies fastest); ``lo``,
    ``hi``: the box (:func:`log_bounds`)."""
    hints = hints or {}
    parts, i = [], 0
    for lat in latents:
        cls = LATENT_TERMS[lat]
        k = len(cls.fit_parameters)
        parts.append(cls.fit_starts(tau, avar, lo[i:i + k], hi[i:i + k], n_starts=n_starts, hint=hints.get(lat)))
        i += k
    return [np.log(np.array([v for part in combo for v in part], dtype=float)) for combo in itertools.product(*parts)]


#: a parameter whose Jacobian column is below this fraction of the largest is taken as unidentified
#: (held fixed for the covariance of the others)
FREE_COLUMN = 1e-6


def report(latents, values, jac, at_floor):
    """Coefficients (SI), their standard errors (delta method), and the named latent parameters of a fit:
    ``values`` the parameters, ``jac`` the whitened residuals' Jacobian in the log-parameters at them,
    ``at_floor`` which parameters lie on their lower bound."""
    import pandas as pd

    # a term on its lower bound, or at round-off level where the curve cannot see it (e.g. K on a gyro
    # without rate random walk: its Jacobian column is ~0), is held fixed: the covariance is that of
    # the other parameters (inverse Gauss-Newton information of the free ones), and the fixed ones have
    # no standard error
    col = np.linalg.norm(jac, axis=0)
    free = ~np.asarray(at_floor) & (col > FREE_COLUMN * (col.max() if col.size else 0.0))
    cov_u = np.full((values.size, values.size), np.nan)
    if free.any():
        jf = jac[:, free]
        try:
            cov_u[np.ix_(free, free)] = np.linalg.inv(jf.T @ jf)
        except np.linalg.LinAlgError:
            pass
    var_u = np.diag(cov_u)
    se_u = np.sqrt(np.where(var_u > 0, var_u, np.nan))  # no curvature: no standard error
    coefs, std, params = {}, {}, {}
    i = 0
    for lat in latents:
        cls = LATENT_TERMS[lat]
        names, coef = cls.fit_parameters, cls.coefficient
        for k, name in enumerate(names):
            params[f"{lat}.{name}"] = float(values[i + k])
        v, s = values[i], se_u[i]
        if at_floor[i]:
            v = 0.0  # the term is not needed: its scale ran to the lower bound
        scale = cls.coefficient_per_amplitude
        if coef is not None:  # the sinusoid reports no IEEE coefficient (its params do)
            coefs[coef] = scale * v
            std[coef] = scale * v * s
        i += len(names)
    return coefs, pd.Series(std, dtype=float).reindex(["Q", "N", "B", "K", "R"]), params
