"""Gauss-Markov rate noise: the first-order process (exponentially correlated, a bias instability's model
in the fits) and the second-order one (the rate-ramp stand-in of Miao et al. 2015).

=====================  ==========================================  =======================================
term                   generator                                   exact AV at tau = m dt
=====================  ==========================================  =======================================
GaussMarkov(sigma,tc)  x_k = phi x_{k-1} + sigma sqrt(1-phi^2) n_k   closed form (:class:`GaussMarkov`)
SecondOrderGaussMarkov exact discretisation of Miao et al. 2015,    from the exact autocovariance
                       eq. 8
=====================  ==========================================  =======================================

(SPEC, "Discrete generators and their exact Allan variance"; the interface:
:mod:`avbench.noise_models.term_base`.)
"""

from __future__ import annotations

import math

import numpy as np

from avbench.noise_models._term_kernels import (_ar1_kernel, _gm_central_kernel, _gm_rows_kernel, _gm_shape_kernel,
                                                _sogm_kernel)
from avbench.noise_models.exact_avar import avar_from_autocovariance, check_m
from avbench.noise_models.term_base import (PLATEAU, NoiseTerm, StateBlock, TermStream, _check_dt, _grid_value,
                                            _omega_dt, _positive)
from avbench.noise_models.units import as_si

__all__ = ["GaussMarkov", "SecondOrderGaussMarkov", "GM_PEAK_TAU_OVER_TC", "GM_PEAK_ADEV_OVER_SIGMA",
           "B_EQUIV_OVER_SIGMA"]

#: continuous first-order GM: the AV peaks at tau = 1.8926 Tc ...
GM_PEAK_TAU_OVER_TC = 1.8926
#: ... with Allan deviation 0.6174 sigma
GM_PEAK_ADEV_OVER_SIGMA = 0.6174
#: SPEC's convention: the bias instability a GM term stands for, B_equiv = 0.6174 sigma / 0.6643
B_EQUIV_OVER_SIGMA = GM_PEAK_ADEV_OVER_SIGMA / math.sqrt(PLATEAU)


# --- first-order Gauss-Markov ----------------------------------------------------------------


def block_mean_ar1(phi_log, sigma, m):
    """Transition and disturbance covariance of ``(s, xbar)``, the AR(1) value at the end of a block of
    ``m`` samples and the block's mean, for log(phi) = ``phi_log`` and stationary std ``sigma``: with
    :math:`c_i = (1-\\phi^i)/(1-\\phi)`, :math:`s_{j+1} = \\phi^m s_j + \\sum_i \\phi^{i-1} e_{(i)}`,
    :math:`\\bar x_{j+1} = a s_j + \\tfrac1m\\sum_i c_i e_{(i)}`, :math:`a = \\tfrac1m\\sum_i \\phi^i`
    (var e = sigma^2 (1 - phi^2); (i) counts innovations from the end of the block)."""
    j = np.arange(1, m + 1, dtype=float)
    phi = math.exp(phi_log)
    c = np.expm1(j * phi_log) / math.expm1(phi_log)  # (1 - phi^j) / (1 - phi), stable as phi -> 1
    pw = np.exp((j - 1) * phi_log)  # phi^(j-1)
    q = sigma**2 * -math.expm1(2 * phi_log)  # sigma^2 (1 - phi^2)
    a = float(np.exp(j * phi_log).sum()) / m
    cov = q * np.array([[pw @ pw, pw @ c / m], [pw @ c / m, c @ c / m**2]])
    T = np.array([[phi**m, 0.0], [a, 0.0]])
    return T, cov


def block_mean_ar1_dphi(phi_log, sigma, m):
    r"""Derivatives of :func:`block_mean_ar1`'s ``(T, cov)`` with respect to ``phi_log`` (analytic:
    :math:`c_j = \\sum_{i<j}\\phi^i`, so :math:`dc_j/d\\log\\phi = \\sum_{i<j} i\\phi^i`)."""
    j = np.arange(1, m + 1, dtype=float)
    c = np.expm1(j * phi_log) / math.expm1(phi_log)
    pw = np.exp((j - 1) * phi_log)
    dpw = (j - 1) * pw
    dc = np.cumsum(dpw)
    q = sigma**2 * -math.expm1(2 * phi_log)
    dq = -2.0 * sigma**2 * math.exp(2 * phi_log)
    S = np.array([[pw @ pw, pw @ c / m], [pw @ c / m, c @ c / m**2]])
    dS = np.array([[2 * (pw @ dpw), (dpw @ c + pw @ dc) / m], [(dpw @ c + pw @ dc) / m, 2 * (c @ dc) / m**2]])
    dT = np.array([[m * math.exp(m * phi_log), 0.0], [float((j * np.exp(j * phi_log)).sum()) / m, 0.0]])
    return dT, dq * S + q * dS


class _AR1Stream(TermStream):
    def __init__(self, dt, rng, sigma, phi):
        super().__init__(dt, rng)
        self.phi = phi
        self.scale = sigma * math.sqrt(1.0 - phi * phi)
        # stationary start: x_{-1} ~ N(0, sigma^2)
        self.zi = np.array([phi * rng.standard_normal() * sigma])

    def next(self, n):
        out = self.rng.standard_normal(n)
        out *= self.scale
        if n:  # x_k = e_k + phi x_{k-1}, in place (the recursion of lfilter([1], [1, -phi]))
            self.zi[0] = _ar1_kernel(out, self.phi, self.zi[0])
        return out


def _gm_f_over_c2_numpy(m: np.ndarray, a: float) -> np.ndarray:
    """f(m) / (1 - phi)^2 with phi = exp(-a), f = m(1-phi^2) - 3phi + 4phi^(m+1) - phi^(2m+1).

    Evaluated without catastrophic cancellation: a Taylor series in a (whose first three
    coefficients vanish identically) where (2m+1) a < 1, the expm1 form elsewhere. The NumPy
    reference of :func:`_gm_f_over_c2` (which returns its values bit for bit, compiled).
    """
    m = m.astype(float)
    c = -math.expm1(-a)
    out = np.empty_like(m)
    x = (2 * m + 1) * a
    small = x < 1.0
    if np.any(small):
        ms = m[small]
        total = np.zeros_like(ms)
        term_a = a**3 / 6.0  # a^k / k!, starting at k = 3
        for k in range(3, 60):
            ck = -ms * 2.0**k - 3.0 + 4.0 * (ms + 1.0) ** k - (2.0 * ms + 1.0) ** k
            total += (-1) ** k * term_a * ck
            term_a *= a / (k + 1)
            if term_a * (2 * ms.max() + 1) ** (k + 1) < 1e-18 * np.abs(total).min():
                break
        out[small] = total / c**2
    big = ~small
    if np.any(big):
        mb = m[big]
        f = mb * (-math.expm1(-2 * a)) - math.exp(-a) * (
            -4 * np.expm1(-mb * a) + np.expm1(-2 * mb * a)
        )
        out[big] = f / c**2
    return out

#: the Taylor series of :func:`_gm_f_over_c2_numpy` runs over k = 3 .. 59
_SERIES_K = np.arange(3, 60, dtype=float)
#: cluster sizes (bytes) -> (-m then -2m, (m + 1)^k, (2m + 1)^k, (2m + 1)^(k+1), 2^k): the values of the
#: series that depend on the cluster sizes only, kept for the few size vectors a fit evaluates
_POWERS: dict = {}


def _series_powers(mf: np.ndarray) -> tuple:
    """The cluster-size factors of :func:`_gm_rows_kernel` for float cluster sizes ``mf``, computed as
    :func:`_gm_f_over_c2_numpy` computes them (vectorised powers for the series' c_k, scalar ``pow`` for its
    stopping bound), kept per ``mf``."""
    key = mf.tobytes()
    kept = _POWERS.get(key)
    if kept is None:
        k = _SERIES_K[:, None]
        with np.errstate(over="ignore", invalid="ignore"):
            p1 = (mf + 1.0) ** k
            p2 = (2.0 * mf + 1.0) ** k
            q = np.array([[float(np.float64(2 * v + 1) ** (int(kk) + 1)) for v in mf] for kk in _SERIES_K])
        pow2 = np.array([2.0 ** int(kk) for kk in _SERIES_K])
        kept = (np.concatenate((-mf, -2 * mf)), p1, p2, q, pow2)
        while len(_POWERS) >= 64:
            try:
                _POWERS.pop(next(iter(_POWERS)))
            except (KeyError, RuntimeError, StopIteration):  # emptied meanwhile by another thread
                break
        _POWERS[key] = kept
    return kept


def _gm_inputs(mf: np.ndarray, a_values) -> tuple:
    """The arguments of :func:`avbench.noise_models._term_kernels._gm_rows_py` before ``out``: per row the
    scalars as :func:`_gm_f_over_c2_numpy` computes them (Python's ``expm1``, ``exp``, ``**``), NumPy's
    vectorised ``expm1(-m a)``, ``expm1(-2 m a)`` of all rows in one call, the powers kept per ``mf``."""
    neg_m12, p1, p2, q, pow2 = _series_powers(mf)
    a = np.array(a_values, dtype=float)
    scal = np.array([((-math.expm1(-x)) ** 2, -math.expm1(-2 * x), math.exp(-x), x**3 / 6.0) for x in a_values]).T
    return mf, a, scal[0], scal[1], scal[2], scal[3], np.expm1(np.multiply.outer(a, neg_m12)), p1, p2, q, pow2


def _gm_f_over_c2_rows(m: np.ndarray, a_values) -> np.ndarray:
    """``[_gm_f_over_c2_numpy(m, a) for a in a_values]`` as one (len(a_values), len(m)) array, bit for bit
    (compiled :func:`avbench.noise_models._term_kernels._gm_rows_py`; NumPy's vectorised expm1 once for all
    rows, the series' powers kept per ``m``)."""
    mf = m.astype(float)
    out = np.empty((len(a_values), mf.size))
    _gm_rows_kernel(*_gm_inputs(mf, a_values), out)
    return out


def _gm_central(m: np.ndarray, a_values, variances, step) -> tuple[np.ndarray, np.ndarray]:
    """``(v[0], (v[1] - v[2]) / step)`` with ``v[r] = variances[r] * _gm_f_over_c2_numpy(m, a_values[r]) / m^2``
    (three rows: a Gauss-Markov AV and its central difference), bit for bit those NumPy expressions
    (compiled :func:`avbench.noise_models._term_kernels._gm_central_py`)."""
    mf = m.astype(float)
    value, deriv = np.empty(mf.size), np.empty(mf.size)
    _gm_central_kernel(*_gm_inputs(mf, a_values), np.array(variances, dtype=float), float(step), value, deriv)
    return value, deriv


def _gm_f_over_c2(m: np.ndarray, a: float) -> np.ndarray:
    """f(m) / (1 - phi)^2 with phi = exp(-a), f = m(1-phi^2) - 3phi + 4phi^(m+1) - phi^(2m+1), without
    catastrophic cancellation: :func:`_gm_f_over_c2_numpy`'s values, compiled (:func:`_gm_f_over_c2_rows`)."""
    return _gm_f_over_c2_rows(m, (a,))[0]


class GaussMarkov(NoiseTerm):
    """First-order Gauss-Markov rate noise (Miao et al. 2015, eq. 6), stationary std sigma.

    .. math:: x_k = \\phi x_{k-1} + \\sigma\\sqrt{1-\\phi^2}\\,n_k,\\qquad \\phi = e^{-dt/T_c}

    Exact discrete AV (SPEC): sigma^2 [m(1-phi^2) - 3phi + 4phi^(m+1) - phi^(2m+1)] / [m^2 (1-phi)^2],
    evaluated without cancellation. It reports the bias instability it stands for as SPEC's
    ``B_equiv = 0.6174 sigma / 0.6643 = 0.9294 sigma`` (AV peak matched to the flicker plateau).

    Parameters
    ----------
    sigma : float or (value, unit)
        Stationary standard deviation of the rate (rad/s, or e.g. ``(20, "deg/h")``).
    tc : float
        Correlation time Tc in seconds.
    """

    coefficient = "B"
    shape_parameter = "tc"
    latent = "GM"
    fit_parameters = ("sigma", "tc")
    coefficient_per_amplitude = B_EQUIV_OVER_SIGMA
    block_mean_states = 2

    @classmethod
    def block_mean_block(cls, values, m, dt):
        """States ``(s, xbar)`` (:func:`block_mean_ar1`), observed through xbar; the first from a stationary
        s_0."""
        sigma, tc = values
        T, Q = block_mean_ar1(-dt / tc, sigma, m)
        P0 = sigma**2 * np.outer(T[:, 0], T[:, 0]) + Q
        return StateBlock(T, Q, np.array([0.0, 1.0]), P0)

    @classmethod
    def block_mean_derivatives(cls, values, m, dt, block):
        """In log sigma twice the covariances; in log Tc by :func:`block_mean_ar1_dphi`, with
        :math:`d\\log\\phi/d\\log T_c = -\\log\\phi`."""
        sigma, tc = values
        phi_log = -dt / tc
        dT, dQ = block_mean_ar1_dphi(phi_log, sigma, m)
        dT, dQ = -phi_log * dT, -phi_log * dQ
        t0, dt0 = block.T[:, 0], dT[:, 0]
        dP0 = sigma**2 * (np.outer(dt0, t0) + np.outer(t0, dt0)) + dQ
        return [*super().block_mean_derivatives(values, m, dt, block), StateBlock(dT, dQ, np.zeros(2), dP0)]

    @classmethod
    def block_mean_memory(cls, values):
        """The correlation time Tc."""
        return values[1]

    @classmethod
    def from_fit(cls, values, *, tau_max=None):
        return cls(sigma=values[0], tc=values[1])

    @classmethod
    def fit_amplitude_top(cls, tau, avar):
        """The sigma whose AV peak (0.38 sigma^2) is the curve's highest AV."""
        return math.sqrt(np.max(avar) / 0.38)

    @classmethod
    def fit_shape_bounds(cls, tau, dt, T, hint=None):
        """Tc between the shortest tau fitted (at least dt) and 10 T: a Gauss-Markov term faster than every
        scale fitted looks like white noise plus a 1/tau^2 term there, i.e. like a sensor filter, and says
        nothing about bias instability."""
        return [math.log(max(dt, tau[0]))], [math.log(10 * T)]

    @classmethod
    def fit_starts(cls, tau, avar, lo, hi, *, n_starts=1, hint=None):
        """``n_starts`` values of Tc, log-spaced from the shortest tau (at least twice Tc's lower bound) to half
        the longest; sigma at each is half the one whose AV peak (0.38 sigma^2 at 1.89 Tc) is the curve there."""
        out = []
        for tc in np.geomspace(max(tau[0], 2 * math.exp(lo[1])), tau[-1] / 2, n_starts):
            peak = np.interp(math.log(1.89 * tc), np.log(tau), avar)
            out.append((math.sqrt(peak / 0.38) / 2, tc))
        return out

    def __init__(self, sigma, tc):
        self.sigma = as_si("B", sigma)
        if self.sigma == 0:
            raise ValueError("sigma: expected a positive standard deviation, got 0")
        self.tc = _positive("tc", tc)

    @classmethod
    def from_bias_instability(cls, B, tau_peak) -> "GaussMarkov":
        """The GM whose AV peak equals the plateau (2 ln2/pi) B^2 at ``tau_peak`` seconds."""
        return cls(sigma=as_si("B", B) / B_EQUIV_OVER_SIGMA, tc=_positive("tau_peak", tau_peak) / GM_PEAK_TAU_OVER_TC)

    def psd_factor(self):
        return self.sigma**2, GaussMarkov(sigma=1.0, tc=self.tc)

    def _params(self):
        return {"sigma": self.sigma, "tc": self.tc}

    def coefficients(self):
        return {"B": B_EQUIV_OVER_SIGMA * self.sigma}

    def phi(self, dt) -> float:
        return math.exp(-_check_dt(dt) / self.tc)

    def avar(self, m, dt):
        m = check_m(m)
        a = _check_dt(dt) / self.tc
        return self.sigma**2 * _gm_f_over_c2(m, a) / m.astype(float) ** 2

    def avar_shape_derivative(self, m, dt):
        """``(avar, d avar / d ln tc)``, analytic (compiled
        :func:`avbench.noise_models._term_kernels._gm_shape_py`): with a = dt / tc, d/d ln tc = -a d/da.
        The AV agrees with :meth:`avar` to round-off (a compiled series whose stopping rule is per cluster
        size; :meth:`avar` stays the exact truth of the studies)."""
        mf = check_m(m).astype(float)
        a = _check_dt(dt) / self.tc
        g, dg = np.empty_like(mf), np.empty_like(mf)
        _gm_shape_kernel(mf, a, g, dg)
        scale = self.sigma**2 / (mf * mf)
        return scale * g, scale * (-a) * dg

    def autocovariance(self, lags, dt) -> np.ndarray:
        """sigma^2 phi^|k| = sigma^2 exp(-|k| dt / Tc) (the exponential of each lag: no error growing with
        the lag, as a power of the rounded phi would have)."""
        dt = _check_dt(dt)
        k = np.abs(np.asarray(lags, dtype=float))
        return self.sigma**2 * np.exp(-k * dt / self.tc)

    def psd(self, f, dt):
        grid = f
        f, w = _omega_dt(f, dt)
        phi = self.phi(dt)
        return 2 * dt * self.sigma**2 * (1 - phi**2) / (1 - 2 * phi * _grid_value(grid, dt, "cos(w)", w) + phi**2)

    def stream(self, dt, rng):
        return _AR1Stream(_check_dt(dt), rng, self.sigma, self.phi(dt))


# --- second-order Gauss-Markov ---------------------------------------------------------------


class _SOGMStream(TermStream):
    def __init__(self, dt, rng, A, chol, P):
        super().__init__(dt, rng)
        self.A = A
        self.chol = chol
        self.x = np.linalg.cholesky(P) @ rng.standard_normal(2)  # stationary start

    def next(self, n):
        e = self.rng.standard_normal((n, 2))
        out = np.empty(n)
        if n:
            _sogm_kernel(self.A, self.chol, e, self.x, out)
        return out


class SecondOrderGaussMarkov(NoiseTerm):
    """Second-order Gauss-Markov process, the rate-ramp stand-in of Miao et al. 2015 (eq. 8).

    .. math:: y = \\frac{q\\,v(t)}{D^2 + \\sqrt2\\,w_0 D + w_0^2}

    discretised exactly (matrix exponential and Van Loan process-noise covariance), started from its
    stationary state. The paper writes the numerator as ``R v``; read literally, that R is not the
    ramp coefficient (the AV for tau << 1/w0 would be R^2 tau^2 / (4 sqrt2 w0)). Here ``R`` is the
    rate-ramp coefficient the process imitates: the driving intensity is chosen so that the
    stationary variance of dy/dt is R^2, which makes AV ~ R^2 tau^2 / 2 for dt << tau << 1/w0.
    Beyond tau ~ 1/w0 the AV peaks and then falls like white noise, N_equiv^2 / tau with
    N_equiv = q / w0^2. :meth:`avar` is exact for the discrete sequence (from its autocovariance).

    Parameters
    ----------
    R : float or (value, unit)
        Ramp coefficient imitated (rad/s^2, or e.g. ``(0.35, "deg/h^2")``).
    w0 : float
        Natural angular frequency (rad/s); the ramp-like band is tau << 1/w0.
    """

    coefficient = "R"
    shape_parameter = "w0"

    def __init__(self, R, w0):
        self.R = as_si("R", R)
        if self.R == 0:
            raise ValueError("R: expected a positive ramp coefficient, got 0")
        self.w0 = _positive("w0", w0)

    def _params(self):
        return {"R": self.R, "w0": self.w0}

    def coefficients(self):
        return {"R": self.R}

    @property
    def q(self) -> float:
        """Driving intensity q of eq. 8: Var(dy/dt) = q^2 / (2 sqrt2 w0) = R^2."""
        return self.R * math.sqrt(2 * math.sqrt(2) * self.w0)

    def _continuous(self):
        w0 = self.w0
        F = np.array([[0.0, 1.0], [-(w0**2), -math.sqrt(2) * w0]])
        G = np.array([[0.0], [self.q]])
        return F, G

    def discretise(self, dt):
        """(A, Qd, P): transition, process-noise covariance, stationary covariance."""
        dt = _check_dt(dt)
        F, G = self._continuous()
        n = 2
        M = np.zeros((2 * n, 2 * n))
        M[:n, :n] = -F
        M[:n, n:] = G @ G.T
        M[n:, n:] = F.T
        from scipy.linalg import expm

        E = expm(M * dt)
        A = E[n:, n:].T
        Qd = A @ E[:n, n:]
        Qd = (Qd + Qd.T) / 2
        from scipy.linalg import solve_continuous_lyapunov

        P = solve_continuous_lyapunov(F, -G @ G.T)
        return A, Qd, (P + P.T) / 2

    def autocovariance(self, lags, dt) -> np.ndarray:
        """r(k) = e1^T A^|k| P e1 through the eigen-decomposition of the transition A."""
        A, _, P = self.discretise(dt)
        mu, V = np.linalg.eig(A)
        left = V[0, :]  # e1^T V
        right = np.linalg.solve(V, P[:, 0])  # V^-1 P e1
        k = np.abs(np.asarray(lags, dtype=np.int64))
        r = np.real((left * right) * mu ** k.reshape(-1)[:, None]).sum(axis=1)
        return r.reshape(k.shape)

    def avar(self, m, dt):
        m = check_m(m)
        return avar_from_autocovariance(self.autocovariance(np.arange(int(2 * m.max()) + 1), dt), m)

    def psd(self, f, dt):
        f, w = _omega_dt(f, dt)
        A, _, P = self.discretise(dt)
        mu, V = np.linalg.eig(A)
        a = V[0, :] * np.linalg.solve(V, P[:, 0])
        z = np.exp(-1j * w)[:, None] * mu[None, :]
        s = np.real(a[None, :] * z / (1 - z)).sum(axis=1)
        return 2 * dt * (P[0, 0] + 2 * s)

    def stream(self, dt, rng):
        dt = _check_dt(dt)
        A, Qd, P = self.discretise(dt)
        chol = np.linalg.cholesky(Qd + 1e-300 * np.eye(2))
        return _SOGMStream(dt, rng, np.ascontiguousarray(A), chol, P)
