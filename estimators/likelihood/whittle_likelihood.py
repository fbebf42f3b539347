"""The Whittle likelihood of a gyro record and its maximisation: :class:`WhittleFit` (the record's
periodogram, the likelihood, Fisher scoring, the trend slope, starting values, the sandwich
information), :func:`whittle_fit` (the best fit of a set of terms) and :func:`spectral_fit_check`
(the goodness of fit of the fitted spectrum).

The likelihood
--------------
For a Gaussian record :math:`x_0..x_{n-1}` with discrete-time spectral density
:math:`S(\\omega;\\theta) = \\sum_j a_j S_j(\\omega)` (the terms' spectra with unit coefficient,
:mod:`avbench.estimators.likelihood.whittle_spectra`, linear in the variances :math:`a_j`), the
Whittle approximation of the log-likelihood (Whittle 1953; Percival & Walden 1993, Sec. 6.6;
Brockwell & Davis 1991, Sec. 10.8) is

.. math::

    \\ell(\\theta) = -\\sum_{k=1}^{\\lfloor n/2\\rfloor} w_k\\left[\\log S(\\omega_k;\\theta)
        + \\frac{I_k}{S(\\omega_k;\\theta)}\\right],\\qquad
    I_k = \\frac1n\\Big|\\sum_t x_t e^{-i\\omega_k t} - \\beta\\,G_k\\Big|^2,
    \\quad \\omega_k = 2\\pi k/n,

with :math:`w_k = 1` except :math:`w_{n/2} = 1/2` (the Nyquist ordinate is real). With
``debiased=True`` :math:`S(\\omega_k)` is replaced by the expected periodogram of a record of n
samples (Sykulski et al. 2019); the model stays linear in the variances.

Trend regression. :math:`G_k = \\sum_t t\\,e^{-i\\omega_k t} = -n/(1-e^{-i\\omega_k})` is the DFT
of a linear trend. For a random walk :math:`x_t = x_{t-1} + v_t` (:math:`x_{-1} = 0`) the DFT at a
Fourier frequency is exactly :math:`(V_k - V_0)/(1-e^{-i\\omega_k})`: the pseudo-spectrum holds for
:math:`V_k`, and :math:`V_0` (the sum of all increments) enters exactly like a linear trend of
slope :math:`V_0/n`. The slope is profiled out at every step by frequency-domain generalised least
squares (Hannan 1963), :math:`\\hat\\beta = \\sum w_k\\mathrm{Re}(\\bar G_kX_k)/S_k \\big/ \\sum
w_k|G_k|^2/S_k`: one regression removes a deterministic ramp and makes the random-walk periodogram
exact. Its variance is computed exactly in the time domain (:meth:`WhittleFit.trend_variance`).
``reml=True``: the restricted likelihood, :math:`\\ell - \\tfrac12\\log\\sum_k w_k|G_k|^2/S_k`
(Patterson & Thompson 1971; Harville 1977).

Maximisation
------------
Fisher scoring (Newton steps with the expected information :math:`\\sum_k w_k\\,\\nabla\\log
S\\,\\nabla\\log S^T`, backtracking on :math:`\\ell`) in the log of every variance and of a
Gauss-Markov Tc; a variance that runs to its floor (:data:`FLOOR` of the level at which the term
alone would reach the binned periodogram somewhere) is absent. One FFT, then O(n) per iteration
(compiled, :mod:`avbench.estimators.likelihood._whittle_kernels`). Profile fits (a parameter held)
score in the variances themselves, projected on their floors; ``signed`` fits score in the
variances with no floor, over the domain where the model spectrum is positive at every Fourier
frequency. Starting values: non-negative least squares of log-binned periodogram means on the
basis spectra; a fit that does not converge from them is retried from the weighted least-squares
start (``reweight``) and the better of the two kept.
"""

from __future__ import annotations

import math

import numpy as np

from avbench.estimators.likelihood.whittle_spectra import (autocovariance, components, expected_periodogram,
                                                           is_shaped, low_dft_covariance, unit_spectrum, walk)

__all__ = ["WhittleFit", "whittle_fit", "spectral_fit_check", "FLOOR", "SANDWICH_ORDINATES"]

#: a term whose variance is below this fraction of the smallest "alone" level (the variance at which
#: the term alone reaches the binned periodogram somewhere) is absent: it contributes < 1e-6 everywhere
FLOOR = 1e-6
#: passes of the weighted least-squares start (WhittleFit.start) used to retry a fit that did not converge
REWEIGHT = 3

#: the lowest Fourier ordinates whose exact covariance enters the sandwich information
#: (:meth:`WhittleFit.godambe_ratio`); above them the ordinates are taken as independent
SANDWICH_ORDINATES = 512


class WhittleFit:
    """The record's periodogram and the model fitted to it (one set of terms).

    ``debiased=True``: the model's ordinates are the expected periodogram of the record
    (:func:`~avbench.estimators.likelihood.whittle_spectra.expected_periodogram`, Sykulski et al. 2019)
    instead of the spectrum."""

    def __init__(self, x: np.ndarray, dt: float, reml: bool = False, debiased: bool = False):
        n = x.size
        self.n, self.dt = n, dt
        self.reml = bool(reml)
        self.debiased = bool(debiased)
        self.scale = float(np.std(np.diff(x))) or 1.0
        X = np.fft.rfft(x / self.scale)[1:]
        k = np.arange(1, n // 2 + 1, dtype=float)
        self.f = k / (n * dt)
        z = np.exp(-2j * np.pi * k / n)
        self.G = -n / (1.0 - z)  # DFT of the trend t = 0..n-1
        self.X = X
        self.w = np.ones(k.size)
        if n % 2 == 0:
            self.w[-1] = 0.5
        self.G2 = np.ascontiguousarray(np.abs(self.G) ** 2)
        self.GX = np.ascontiguousarray((np.conj(self.G) * X).real)
        self.X2 = np.ascontiguousarray(np.abs(X) ** 2)
        self._check_resolved()
        self._basis = {}
        self._cov = {}  # low ordinates' DFT covariance of each term (godambe_ratio)
        self._acf = {}  # each unit stationary term's autocovariance at lags 0..n-1 (trend_variance)

    def _check_resolved(self):
        """Refuse a record whose noise float64 cannot resolve beside its straight line.

        The likelihood profiles the trend out of each ordinate as
        :math:`|X_k|^2 - 2\\beta\\,\\mathrm{Re}(\\bar G_k X_k) + \\beta^2|G_k|^2`, whose rounding error is
        about :math:`\\epsilon(|X_k|^2 + \\beta^2|G_k|^2)`. Where the trend-removed ordinate is not above
        that (a ramp with no or almost no noise on it) the fit has nothing to fit there: one error naming
        the line, instead of a fit on rounding errors."""
        beta = float(np.sum(self.GX)) / float(np.sum(self.G2))
        resid = self.X2 - 2 * beta * self.GX + beta**2 * self.G2
        floor = 64 * np.finfo(float).eps * (self.X2 + beta**2 * self.G2)
        lost = int(np.count_nonzero(resid <= floor))
        if lost:
            raise ValueError(
                f"rate: a straight line with no noise float64 can resolve around it (at "
                f"{lost} of {resid.size} frequencies): the spectral fit removes the line and fits the noise left; "
                "expected a sensor's record (noise on every sample, resolvable beside its drift)")

    def basis(self, c, tc=None):
        """Ordinates k = 1..n//2 of term ``c`` with unit coefficient: its spectrum, or (``debiased``)
        its expected periodogram; cached per record."""
        key = (c, tc)
        if key not in self._basis:
            if len(self._basis) > 12:  # Gauss-Markov bases of earlier Tc values
                self._basis = {k: v for k, v in self._basis.items() if not is_shaped(k[0])}
            self._basis[key] = (expected_periodogram(c, self.n, self.dt, tc) if self.debiased
                                else unit_spectrum(c, self.f, self.dt, tc))
        return self._basis[key]

    # -- likelihood ------------------------------------------------------------------------------
    def basis_matrix(self, comps, tc):
        """The bases of ``comps`` as rows: the model's ordinates are ``a @ basis_matrix(comps, tc)``."""
        rows = [self.basis(c, tc if is_shaped(c) else None) for c in comps]
        return np.ascontiguousarray(np.vstack(rows))

    def evaluate(self, comps, a, tc=None, grad=False, Bm=None, linear=False):
        """``(loglik, beta, sgg, score, info)`` at variances ``a`` (normalised units), compiled; the
        score and information in the log-variances, or (``linear``) in the variances themselves."""
        from avbench.estimators.likelihood._whittle_kernels import whittle_pass

        Bm = self.basis_matrix(comps, tc) if Bm is None else Bm
        D = np.zeros(0)
        c_tc = 0.0
        shaped = _shaped(comps)
        if shaped is not None and grad:
            h = 1e-4
            D = (self.basis(shaped, tc * math.exp(h)) - self.basis(shaped, tc * math.exp(-h))) / (2 * h)
            c_tc = float(a[list(comps).index(shaped)])
        a = np.asarray(a, dtype=float)
        out = whittle_pass(a, Bm, D, c_tc, self.X2, self.GX, self.G2, self.w, float(self.n), grad, linear)
        if not self.reml or not np.isfinite(out[0]):
            return out
        # restricted likelihood: - 1/2 log of the slope's information, sum_k w_k |G_k|^2 / S_k
        ll, beta, sgg, score, info = out
        ll = ll - 0.5 * math.log(sgg)
        if grad:
            S = a @ Bm
            t = self.w * self.G2 / (S * S)
            adj = 0.5 / sgg * ((Bm @ t) if linear else a * (Bm @ t))
            if D.size:
                adj = np.append(adj, 0.5 / sgg * c_tc * float(D @ t))
            score = score + adj
        return ll, beta, sgg, score, info

    def loglik(self, comps, a, tc=None):
        """Profile Whittle log-likelihood at variances ``a`` (normalised units) for ``comps``."""
        return self.evaluate(comps, a, tc)[0]

    def fit(self, comps, a0, tc0=None, lo=None, max_iter=200, fixed=None, tol=1e-6, hold_floor=None,
            signed=False):
        """Fisher scoring in u = log a (and log Tc); returns (a, tc, loglik, n_iter, converged, detail).
        ``fixed``: index of a parameter held at its start value (a profile likelihood).
        ``hold_floor`` (default: True when ``fixed`` is given, the profile fits):
        scoring steps in the variances themselves (projected onto their floors; a Tc still in log
        Tc, capped at 3), not in their logs. The model spectrum is linear in the variances, so
        these steps do not slow down near 0, where the log-scale score and information of a term
        both vanish: in log a, a term at its floor that the profile needs to rise (K as B is pushed
        down) takes a huge Newton step that, once the step vector is capped, leaves every parameter
        crawling. The point fits take log-scale steps.
        ``signed``: steps in the variances themselves with no floor: a variance of Q, N, B or K may
        go below 0 as long as the model spectrum stays positive at every Fourier frequency (a step
        that leaves that domain is halved; a Gauss-Markov variance keeps its floor, its Tc being
        undefined at 0). ``detail["info"]`` is then the information in the variances."""
        linear_scale = signed or (fixed is not None if hold_floor is None else bool(hold_floor))
        comps = list(comps)
        has_gm = _shaped(comps) is not None
        p = len(comps)
        lo = np.full(p + has_gm, -np.inf) if lo is None else np.asarray(lo, dtype=float)
        if linear_scale:
            # x = (variances, log Tc); a variance's floor in the variance itself (none if signed)
            x = np.asarray(a0, dtype=float).copy()
            xlo = np.exp(lo[:p])
            if signed:
                xlo[[not is_shaped(c) for c in comps]] = -np.inf
            if has_gm:
                x = np.append(x, math.log(tc0))
            xlo = np.append(xlo, lo[p:])
            above_tol = np.where(np.isfinite(xlo), 1e-9 * np.maximum(np.abs(xlo), 1.0), 0.0)
        else:
            x = np.log(np.asarray(a0, dtype=float))
            if has_gm:
                x = np.append(x, math.log(tc0))
            xlo = lo
            above_tol = 1e-9

        def unpack(xx):
            return (xx[:p] if linear_scale else np.exp(xx[:p])), (math.exp(xx[p]) if has_gm else None)

        a, tc = unpack(x)
        Bm = self.basis_matrix(comps, tc)
        ll, beta, sgg, score, info = self.evaluate(comps, a, tc, grad=True, Bm=Bm, linear=linear_scale)
        converged = False
        it = 0
        for it in range(1, max_iter + 1):
            above = x > xlo + above_tol
            free = above | (score > 0)  # at the floor, only a step upwards frees it
            if fixed is not None:
                free[fixed] = False
            idx = np.flatnonzero(free)
            if idx.size == 0:
                converged = True
                break
            try:
                step_f = _newton_step(info, score, idx)
            except np.linalg.LinAlgError:
                break
            decrement = float(score[idx] @ step_f)  # Newton decrement: twice the expected gain
            if not np.isfinite(decrement):
                break
            if decrement < tol:
                converged = True
                break
            step = np.zeros_like(x)
            step[idx] = step_f
            if not linear_scale:
                big = np.max(np.abs(step))
                if big > 3.0:
                    step *= 3.0 / big
            elif has_gm:
                step[p] = max(min(step[p], 3.0), -3.0)
            t = 1.0
            if linear_scale and not signed:
                # a variance falls at most tenfold per step (on towards its floor over the next ones)
                down = (step[:p] < -0.9 * a) & above[:p]
                if np.any(down):
                    t = float(np.min(-0.9 * a[down] / step[:p][down]))
            t0 = t
            for _ in range(40):
                xn = np.maximum(x + t * step, xlo)
                an, tcn = unpack(xn)
                Bn = self.basis_matrix(comps, tcn) if has_gm else Bm
                # the full step is usually taken: evaluate the score with it
                trial = self.evaluate(comps, an, tcn, grad=(t == t0), Bm=Bn, linear=linear_scale)
                if np.isfinite(trial[0]) and trial[0] > ll:
                    break
                t *= 0.5
            else:
                converged = decrement < 1e-4  # no ascent left at machine precision
                break
            x, Bm = xn, Bn
            a, tc = unpack(x)
            if t != t0:
                trial = self.evaluate(comps, a, tc, grad=True, Bm=Bm, linear=linear_scale)
            ll, beta, sgg, score, info = trial
        a, tc = unpack(x)
        return np.array(a, dtype=float), tc, ll, it, converged, {"beta": beta, "sgg": sgg, "info": info}

    # -- the sandwich (Godambe) information -----------------------------------------------------
    def _low_cov(self, c, tc, m):
        """``(acf, A, P, acf_fft)`` of one unit term (:func:`_low_dft_covariance`), cached; None for
        the random walk."""
        key = (c, tc, m)
        if key not in self._cov:
            if len(self._cov) > 12:  # Gauss-Markov terms of earlier Tc values
                self._cov = {k: v for k, v in self._cov.items() if not is_shaped(k[0])}
            acf = autocovariance(c, self.n, self.dt, tc)
            if acf is None:
                self._cov[key] = None
            else:
                from scipy import fft as sfft

                L = sfft.next_fast_len(2 * self.n, real=True)
                col = np.zeros(L)
                col[: self.n] = acf
                col[L - self.n + 1:] = acf[1:][::-1]  # the circulant embedding of the Toeplitz matrix
                self._cov[key] = (acf, *low_dft_covariance(acf, m), sfft.rfft(col), L)
        return self._cov[key]

    def godambe_ratio(self, comps, a, tc=None, m=SANDWICH_ORDINATES) -> np.ndarray:
        """Per variance :math:`a_j`: the ratio :math:`(H^{-1}JH^{-1})_{jj}/(H^{-1})_{jj}` of the
        estimator's sandwich variance to the inverse Whittle information at the model ``(comps, a,
        tc)``, in the variances (a Gauss-Markov Tc's row: not modelled, the variances' only).

        The Whittle score :math:`s_j = \\sum_k w_k B_{jk}(I_k - S_k)/S_k^2` has variance
        :math:`J = H` (the information :math:`\\sum_k w_kB_{jk}B_{lk}/S_k^2`) only if the ordinates
        are independent with variance :math:`S_k^2`. Neither holds at the lowest frequencies of a
        short record: a 1/f term is not circulant, and the trend slope profiled out of every ordinate
        (:math:`Y_k = X_k - \\hat\\beta G_k`, :math:`\\hat\\beta = c^Tx`, :meth:`trend_weights`)
        ties them together. The estimator's variance is :math:`H^{-1}JH^{-1}` (Sykulski et al. 2019,
        Biometrika 106(2), Theorem 2, J from the covariance of the periodogram; Dahlhaus & Wefelmeyer
        1996). For a Gaussian record :math:`\\mathrm{cov}(I_k, I_l) = (|E[Y_k\\bar Y_l]|^2 +
        |E[Y_kY_l]|^2)/n^2`, computed exactly under the model for the lowest ``m`` ordinates:

        .. math:: E[Y_k\\bar Y_l] = A_{kl} - u_k\\bar G_l - G_k\\bar u_l + G_k\\bar G_l\\,v,\\quad
            E[Y_kY_l] = P_{kl} - u_kG_l - G_ku_l + G_kG_l\\,v,

        with A, P the DFT covariances of the record (:func:`.whittle_spectra.low_dft_covariance` for
        the stationary terms; the random walk :math:`x_t = \\sum_{s\\le t}v_s` in closed form, :math:`A_{kl} =
        \\sigma^2n(\\delta_{kl}+1)/((1-z_k)(1-\\bar z_l))`, :math:`P_{kl} = \\sigma^2n/((1-z_k)(1-z_l))`,
        :math:`z_k = e^{-i\\omega_k}`), :math:`u_k = E[X_k\\hat\\beta]` the DFT of :math:`\\Sigma c`
        (Toeplitz products by FFT) and :math:`v = c^T\\Sigma c`. Variances below 0 (the signed domain)
        enter as they are. Above the lowest m ordinates: independent, J = H there. O(n log n + m^2)
        per call, the unit terms' A and P cached per record (~0.1 s on 20 min at 100 Hz).

        Not used by the intervals or the standard errors: a diagnostic of how far the Whittle
        information is from the estimator's variance at the lowest ordinates of a short record."""
        from scipy import fft as sfft

        comps = list(comps)
        a = np.asarray(a, dtype=float)
        n, dt = self.n, self.dt
        Bm = self.basis_matrix(comps, tc)
        S = a @ Bm
        H = (Bm * (self.w / S**2)) @ Bm.T
        m = int(min(m, (n - 1) // 2))
        c = self.trend_weights(comps, a, tc)
        A = np.zeros((m, m), dtype=complex)
        P = np.zeros((m, m), dtype=complex)
        Sc = np.zeros(n)  # Sigma c
        C = None
        for j, name in enumerate(comps):
            low = self._low_cov(name, tc if is_shaped(name) else None, m)
            if low is None:  # the random walk, increments of variance a dt
                s2 = a[j] * dt
                z1 = 1.0 - np.exp(-2j * np.pi * np.arange(1, m + 1) / n)
                A += s2 * n * (np.eye(m) + 1.0) / np.outer(z1, np.conj(z1))
                P += s2 * n / np.outer(z1, z1)
                if C is None:
                    C = (np.cumsum(np.arange(n) * c), np.cumsum(c))
                Sc += s2 * (C[0] - np.arange(n) * C[1])  # sum_t min(s, t) c_t (sum c = 0)
                continue
            acf, Aj, Pj, col_f, L = low
            A += a[j] * Aj
            P += a[j] * Pj
            Sc += a[j] * sfft.irfft(col_f * sfft.rfft(c, L), L)[:n]
        u = sfft.rfft(Sc)[1:m + 1]
        v = float(c @ Sc)
        G = self.G[:m]
        EY = A - np.outer(u, np.conj(G)) - np.outer(G, np.conj(u)) + np.outer(G, np.conj(G)) * v
        PY = P - np.outer(u, G) - np.outer(G, u) + np.outer(G, G) * v
        cov = (np.abs(EY) ** 2 + np.abs(PY) ** 2) / float(n) ** 2
        cov[np.diag_indices(m)] -= S[:m] ** 2
        b = Bm[:, :m] * (self.w[:m] / S[:m] ** 2)
        J = H + b @ cov @ b.T
        try:
            Hi = np.linalg.inv(H)
        except np.linalg.LinAlgError:
            return np.ones(len(comps))
        ratio = np.diag(Hi @ J @ Hi) / np.diag(Hi)
        return np.where(np.isfinite(ratio) & (ratio > 0), ratio, 1.0)

    # -- the trend slope -------------------------------------------------------------------------
    def _unit_acf(self, c, tc):
        """:func:`~.whittle_spectra.autocovariance` of unit term ``c`` at lags 0..n-1, cached per record."""
        key = (c, tc)
        if key not in self._acf:
            if len(self._acf) > 12:  # Gauss-Markov terms of earlier Tc values
                self._acf = {k: v for k, v in self._acf.items() if not is_shaped(k[0])}
            self._acf[key] = autocovariance(c, self.n, self.dt, tc)
        return self._acf[key]

    def trend_weights(self, comps, a, tc=None) -> np.ndarray:
        """Weights c with :math:`\\hat\\beta = \\sum_t c_t x_t / s` (s the normalising scale): the
        frequency-domain GLS slope at the spectrum ``a`` written in the time domain (one FFT).
        :math:`\\sum_t c_t = 0`: the slope ignores the mean."""
        from scipy import fft as sfft

        S = np.asarray(a, dtype=float) @ self.basis_matrix(comps, tc)
        A = self.w * np.conj(self.G) / S
        n = self.n
        Y = np.zeros(n // 2 + 1, dtype=complex)
        Y[1:] = np.conj(A)
        if n % 2 == 0:
            Y[-1] = 2.0 * Y[-1].real  # irfft does not double the Nyquist ordinate
        c = sfft.irfft(Y, n) * (n / 2.0)
        return c / float(np.sum(self.w * self.G2 / S))

    def trend_variance(self, comps, a, tc=None, a_walk=None) -> float:
        """Exact variance of the slope :math:`\\hat\\beta` (normalised units) under the model
        ``(comps, a, tc)``: the quadratic form :math:`c^T\\Sigma c` of :meth:`trend_weights` with the
        model's time-domain covariance, O(n log n) through the autocorrelation of c.

        The frequency-domain GLS variance :math:`(n/2)/\\sum_k w_k|G_k|^2/S_k` treats the few lowest
        ordinates, where the trend's DFT lives, as independent with mean S: with flicker noise it is
        several times too small. Here every term enters exactly:
        white :math:`a_N/\\Delta t` at lag 0; quantization :math:`(a_Q/\\Delta t^2)(2, -1)` at lags 0, 1;
        Gauss-Markov :math:`a\\,\\phi^{|\\tau|}`; ideal flicker (the likelihood's 1/f spectrum) through
        its variogram :math:`\\gamma(\\tau) = (a_B/\\pi)\\sum_{j<\\tau} 1/(j+\\tfrac12) =
        (a_B/\\pi)(\\psi(\\tau+\\tfrac12) - \\psi(\\tfrac12))`, valid because :math:`\\sum c_t = 0`
        (:math:`c^T\\Sigma c = -\\sum_{s,t} c_s c_t\\gamma(|s-t|)`); the random walk (increments of
        variance :math:`a_K\\Delta t`) through the reverse cumulative sums of c, which also holds its
        end-point drift. ``a_walk`` sets the random walk's variance, also where ``comps`` has none (the
        ramp test uses the full model's: a random walk too weak to be kept still drifts). Variances below 0 (``domain="spectrum"``) count as 0 in the covariance (the weights
        keep the fitted spectrum)."""
        from scipy import fft as sfft

        c = self.trend_weights(comps, a, tc)
        n, dt = self.n, self.dt
        # the covariance of the record under the reported model: a variance below 0 (a fit in the
        # domain of a positive spectrum, which the weights c keep) is the term's absence
        var = {x: max(float(v), 0.0) for x, v in zip(comps, a)}
        walker = walk(comps)
        if a_walk is not None:  # the random walk drifts whether or not the reported model holds it
            walker = walker or walk(components())
            var[walker] = float(a_walk)
        m = sfft.next_fast_len(2 * n, real=True)
        F = sfft.rfft(c, m)
        acf = sfft.irfft(F.real**2 + F.imag**2, m)[:n]  # sum_t c_t c_{t+tau}
        out = 0.0
        for x, v in var.items():
            if x == walker:  # increments of variance v dt: through the reverse cumulative sums of c
                C = np.cumsum(c[::-1])
                out += v * dt * float(C @ C)
                continue
            r = self._unit_acf(x, tc if is_shaped(x) else None)  # c^T Sigma c = r(0) acf(0) + 2 sum r(t) acf(t)
            out += v * (r[0] * acf[0] + 2 * float(r[1:] @ acf[1:]))
        return max(out, 0.0)

    # -- starting values -------------------------------------------------------------------------
    def start(self, comps, tc=None, reweight=0):
        """Start variances from NNLS of log-binned periodogram means (relative residuals), and the
        'alone' level of each term (largest variance that alone stays under the binned periodogram).

        ``reweight=0``: residuals relative to the binned periodogram itself. A bin of one or two
        ordinates that happens to be small (an exponential variable often is) then gets a huge weight
        and can pull the start far off (e.g. white noise read as quantization). ``reweight > 0``:
        that many further passes with the residuals relative to the previous pass's model, weighted
        by the square root of the bin's count (a bin mean of k ordinates has relative std 1/sqrt(k)):
        the weighted least squares of the binned periodogram, the robust start used when scoring from
        the first one does not converge (:func:`whittle_fit`)."""
        from scipy.optimize import nnls

        nb = 64
        edges = np.unique(np.geomspace(1, self.f.size + 1, nb + 1).astype(int)) - 1
        counts = np.diff(edges).astype(float)
        # a rough trend removal for the start: least squares with a white spectrum
        beta = float(np.sum(self.GX)) / float(np.sum(self.G2))
        I = (self.X2 - 2 * beta * self.GX + beta**2 * self.G2) / self.n
        Ib = np.add.reduceat(I, edges[:-1]) / counts
        B = np.array([np.add.reduceat(self.basis(c, tc if is_shaped(c) else None), edges[:-1]) / counts
                      for c in comps]).T
        top = np.array([np.max(Ib / B[:, j]) for j in range(B.shape[1])])
        under = np.array([np.min(Ib / B[:, j]) for j in range(B.shape[1])])
        wts = 1.0 / Ib
        a, _ = nnls(B * wts[:, None], Ib * wts)
        a = np.maximum(a, 1e-2 * under)
        for _ in range(reweight):
            model = B @ a
            wts = np.sqrt(counts) / np.maximum(model, 1e-300)
            a, _ = nnls(B * wts[:, None], Ib * wts)
            a = np.maximum(a, 1e-2 * under)
        return a, under


def _newton_step(info, score, idx):
    """Fisher-scoring step of the parameters ``idx`` (the information lightly regularised)."""
    sub = info[np.ix_(idx, idx)]
    return np.linalg.solve(sub + 1e-12 * np.trace(sub) * np.eye(idx.size), score[idx])


def _shaped(comps) -> str | None:
    """The component of ``comps`` a shape parameter shapes (a Gauss-Markov term; at most one), or None."""
    return next((c for c in comps if is_shaped(c)), None)


def _gm_starts(T, dt, n_starts):
    return np.geomspace(max(20 * dt, T / 2000), T / 4, n_starts)


def _fit_result(comps, a, tc, loglik, n_iter, converged, detail, floor, signed) -> dict:
    """One maximum of :func:`whittle_fit` as it returns it: the terms at or below their floor are
    ``absent``."""
    return dict(comps=comps, a=a, tc=tc, loglik=loglik, n_iter=n_iter, converged=converged, detail=detail,
                absent=[c for i, c in enumerate(comps) if a[i] <= floor[i]], signed=signed)


def whittle_fit(wf: WhittleFit, comps, n_starts=4, warm=None, hold_floor=False, signed=False):
    """Best fit of the spectral terms ``comps`` (names from Q, N, B, K, GM); dict of results
    (``hold_floor``: :meth:`WhittleFit.fit`'s). ``signed``: the maximum over the domain where the
    model spectrum is positive (variances of Q, N, B, K may be negative), scored from the maximum
    over non-negative variances (which is found first, as without ``signed``); a term whose variance
    ends at or below 0 is ``absent``."""
    comps = [c for c in components() if c in comps]
    shaped = _shaped(comps)
    T = wf.n * wf.dt
    tcs = _gm_starts(T, wf.dt, n_starts) if shaped is not None else [None]
    best = best_nn = None
    for tc in tcs:
        a0, top = wf.start(comps, tc)
        if warm is not None:
            a0 = np.array([max(warm.get(c, a0[i]), 1e-3 * top[i]) for i, c in enumerate(comps)])
            if shaped is not None and warm.get("tc"):
                tc = warm["tc"]
        lo = np.log(FLOOR * top)
        if shaped is not None:
            lo = np.append(lo, math.log(wf.dt))
        tc_start = tc
        a, tc_hat, ll, it, conv, d = wf.fit(comps, a0, tc, lo, hold_floor=hold_floor)
        if not conv:
            # a poor start can leave scoring crawling far from the optimum: retry from the weighted
            # least-squares start and keep the better (fits that converge are never refitted)
            a1, _ = wf.start(comps, tc_start, reweight=REWEIGHT)
            retry = wf.fit(comps, a1, tc_start, lo, hold_floor=hold_floor)
            if retry[2] > ll:
                a, tc_hat, ll, it, conv, d = retry
        floor = FLOOR * top * 1.0001
        nonneg = None
        if signed:
            # the maximum over non-negative variances, kept for intervals over that domain
            nonneg = _fit_result(comps, a, tc_hat, ll, it, conv, d, floor, False)
            s_fit = wf.fit(comps, a, tc_hat, lo, signed=True)
            if np.isfinite(s_fit[2]) and s_fit[2] >= ll:
                a, tc_hat, ll, it2, conv, d = s_fit
                it += it2
            else:  # no ascent into negative variances: the non-negative maximum, information in a
                d = dict(d, info=wf.evaluate(comps, a, tc_hat, grad=True, linear=True)[4])
            floor = np.where([is_shaped(c) for c in comps], floor, 0.0)
        if best is None or ll > best["loglik"]:
            best = _fit_result(comps, a, tc_hat, ll, it, conv, d, floor, bool(signed))
        if nonneg is not None and (best_nn is None or nonneg["loglik"] > best_nn["loglik"]):
            best_nn = nonneg
        if warm is not None:
            break
    if best_nn is not None:
        best["nonneg"] = best_nn
    return best


#: poor-fit level of the spectral fit check (as :data:`avbench.estimators.allan.fit_check.ALPHA`)
FIT_ALPHA = 0.01
#: log-spaced frequency bins of the spectral fit check
FIT_BINS = 32


def spectral_fit_check(wf: WhittleFit, fit: dict, n_params: int, alpha: float = FIT_ALPHA, n_bins: int = FIT_BINS):
    """Goodness of fit of a Whittle fit: the periodogram normalised by the fitted model.

    Under the model the ordinates :math:`r_k = I_k / \\bar S_k` (``\\bar S`` the spectrum, or the
    expected periodogram with ``spectrum="debiased"``; ``I`` after the trend regression) are
    approximately independent Exp(1) (Brockwell & Davis 1991, Thm 10.3.2). In each of ``n_bins``
    log-spaced bins of :math:`m_b` ordinates (k < n/2), :math:`2\\sum r_k \\sim \\chi^2_{2m_b}`;
    its probability transform to a normal score :math:`z_b` makes the bins comparable whatever their
    size (a one-ordinate bin is as skewed as an exponential), and
    :math:`T = \\sum_b z_b^2 \\approx \\chi^2_{B - p}` with p the fitted parameters (the variances,
    a Gauss-Markov Tc, the trend slope). A model that misses a bump, a missing term or the wrong
    shape leaves a run of bins off 1: ``poor_fit`` is ``p < alpha``. The false-alarm rate and power
    are measured in ``tests/test_whittle_debiased.py`` (the binomial tolerance of the level).

    Returns the fit check's entries (:func:`~avbench.estimators.allan.fit_check.as_fit_check`) ``poor_fit``, ``fit_stat``, ``fit_dof``, ``fit_pvalue``,
    ``fit_reference`` and ``fit_check`` (``f`` bin centres (Hz), ``ratio`` the binned means of
    :math:`r_k`, ``z``, ``alpha``)."""
    from scipy import stats

    S = np.asarray(fit["a"], dtype=float) @ wf.basis_matrix(fit["comps"], fit["tc"])
    beta = fit["detail"]["beta"]
    r = (wf.X2 - 2 * beta * wf.GX + beta**2 * wf.G2) / wf.n / S
    K = r.size - (1 if wf.n % 2 == 0 else 0)  # the Nyquist ordinate (chi^2_1 / 2) is left out
    r = r[:K]
    edges = np.unique(np.geomspace(1, K + 1, n_bins + 1).astype(int)) - 1
    m = np.diff(edges).astype(float)
    sums = np.add.reduceat(r, edges[:-1])
    cdf = stats.chi2.cdf(2 * sums, 2 * m)
    sf = stats.chi2.sf(2 * sums, 2 * m)
    z = np.where(cdf < 0.5, stats.norm.ppf(np.maximum(cdf, 1e-300)), -stats.norm.ppf(np.maximum(sf, 1e-300)))
    stat = float(np.sum(z**2))
    dof = max(int(m.size - n_params), 1)
    pval = float(stats.chi2.sf(stat, dof))
    f = np.sqrt(wf.f[edges[:-1]] * wf.f[edges[1:] - 1])
    return {"poor_fit": bool(pval < alpha), "fit_stat": stat, "fit_dof": dof, "fit_pvalue": pval,
            "fit_reference": "chi2 of binned normalised periodogram",
            "fit_check": {"f": f, "ratio": sums / m, "z": z, "alpha": alpha}}
