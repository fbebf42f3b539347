r"""The "existing method" of Miao et al. 2015: equivalent-ARMA state-space model + recursive EM.

Miao et al. 2015 (§3, §5.1; after Ford & Evans 1999 and Saini & Rana 2010) write the gyro's
white-noise-driven stochastic errors as an equivalent ARMA model, turn it into a linear Gaussian
state-space model, and estimate its matrices on line with the finite-dimensional filters for EM of
Elliott & Krishnamurthy (1999) (Miao et al. 2015, eqs 16-33). The noise coefficients are then read
back from the estimated matrices.

Model (N, B, K; Miao et al. 2015, eqs 58-63)
---------------------------------------------
Rate = white (ARW, :math:`N v_1`) + first-order Gauss-Markov standing for the bias instability
(:math:`y_f = \beta B_p v_2/(D+\beta)`, eq. 6) + rate random walk (:math:`y_{rrw} = K v_3/D`,
eq. 4), :math:`v_i` unit-intensity white noises. Checking each step:

* eq. 59, :math:`D(D+\beta)Y = D\beta B_p v_2 + (D+\beta)K v_3`: correct (for the coloured part).
* eqs 60-61: the right-hand side has spectrum
  :math:`\omega^2(K^2+\beta^2B_p^2) + \beta^2K^2`, so a single white noise :math:`r` with
  :math:`\sigma_2\dot r + \sigma_3 r`, :math:`\sigma_2 = \sqrt{K^2+\beta^2B_p^2}`,
  :math:`\sigma_3 = K\beta`, is spectrally equivalent: correct (eq. 61 prints the square root over
  :math:`\dot r` too, a typesetting slip).
* eq. 62: controllable canonical form, :math:`\dot X = [[0,1],[0,-\beta]]X + [0,1]^T\xi`,
  :math:`Y = [K\beta,\ \sigma_2]X + Nv`: correct; its output spectrum is
  :math:`K^2/\omega^2 + \beta^2B_p^2/(\omega^2+\beta^2) + N^2`.
* eq. 63 (Euler discretisation, :math:`\tau` = sample interval): :math:`\Phi = [[1,\tau],
  [0,1-\beta\tau]]`, :math:`G = [0,\tau]^T`. The driving noise of the discrete model must have
  variance :math:`1/\tau` (a unit-intensity white noise averaged over :math:`\tau`), i.e. discrete
  process covariance :math:`Q = GG^T/\tau = [[0,0],[0,\tau]]`; the paper leaves it implicit.
* **eq. 63's measurement noise** :math:`(N/\tau)v_k` **is wrong**: a white rate of intensity
  :math:`N^2` sampled every :math:`\tau` has standard deviation :math:`N/\sqrt\tau` (SPEC: white rate
  :math:`\omega_k = (N/\sqrt{dt})n_k` has AV :math:`N^2/\tau`). Read back as :math:`N = \tau\sqrt R`,
  eq. 63 would underestimate N by a factor :math:`\sqrt{\tau}` (x 0.1 at 100 Hz). We use
  :math:`R = N^2/\tau`, :math:`N = \sqrt{R\,\tau}`.
* The paper's :math:`B` (here :math:`B_p`) is a Gauss-Markov amplitude, not the Allan bias
  instability: the GM stationary variance is :math:`\sigma^2 = \beta B_p^2/2`. We report
  :math:`B` through SPEC's convention for a GM term,
  :math:`B = B_{equiv} = 0.6174\sigma/0.6643 = 0.9294\sigma`, and the initial value ``x0["B"]`` is
  read the same way (:math:`\sigma = B/0.9294`, :math:`B_p = \sigma\sqrt{2/\beta}`).

Estimation (Miao et al. 2015, eqs 16-33)
-----------------------------------------
EM updates the full matrices :math:`A` (m x m), :math:`C` (1 x m), :math:`Q` (m x m),
:math:`R` (eq. 16). These are defined only up to a change of state coordinates, so the canonical
entries of eq. 63 (:math:`K\beta` etc.) cannot be read off the estimated :math:`C` once EM has moved
the coordinates. We read the coefficients from similarity invariants instead (they are what the
likelihood determines): :math:`N^2 = R\,dt`; the eigenvalues :math:`\lambda_1` (nearest 1: rate
random walk) and :math:`\lambda_2 = \phi = e^{-dt/T_c}` (Gauss-Markov) of :math:`A`; and the
numerator of the state part of the output spectrum,
:math:`C\,\mathrm{adj}(zI-A)\,Q\,\mathrm{adj}(z^{-1}I-A)^TC^T = \mu_0 + \mu_1(z+z^{-1})`, which is
matched to independent drivings :math:`q_K|z-\lambda_2|^2 + q_G|z-\lambda_1|^2` (solved in the
well-conditioned variables :math:`\varepsilon_i = 1-\lambda_i`). Then :math:`K^2 = q_K/dt`,
:math:`\sigma^2 = q_G/(1-\phi^2)`, :math:`B = 0.9294\sigma`, :math:`T_c = -dt/\ln\phi`. A negative
:math:`q_K` or :math:`q_G`, complex eigenvalues or :math:`\phi\notin(0,1)` make the coefficient
non-physical (NaN, flagged). :math:`K` treats :math:`\lambda_1` as 1 (eq. 63 has exactly 1; EM does
not constrain it), :math:`\lambda_1` is reported in ``extras_``.

Supported coefficient sets (``terms``): ``"NK"`` (Ford & Evans: 1 state, random walk),
``"NB"`` (1 state, Gauss-Markov), ``"NBK"`` (2 states, eqs 58-63). The model is driven by white
noise only, so quantization (Q) and rate ramp (R) are not supported (Miao et al. 2015, §3: "the
quantization noise cannot be directly incorporated"); N is required (it is the measurement noise).

Other corrections to the printed equations, all needed for the method to work: eq. 17 has the
sign of the gain term reversed (:math:`\hat x^+ = A\hat x + K(y - CA\hat x)`); eq. 19 mixes time
indices (:math:`Z_k^{-1} = P_k^+ - P_k^+A^T(P_{k+1}^-)^{-1}AP_k^+`, the covariance of
:math:`x_k` given :math:`x_{k+1}`; we use its positive semi-definite Joseph-like form); eq. 29
prints :math:`-AU^{(2)}A^T` for :math:`+AU^{(2)}A^T` (with the minus Q is negative); eq. 30 uses
:math:`E_k` for its transpose. Eq. 29 divides :math:`U^{(0)}` (which includes :math:`x_0x_0^T`) by
k: an O(1/k) bias we keep as printed.

Choices the paper leaves open (settings): the initial A, C, Q, R are eq. 63 (corrected) at
``x0`` and ``tc0`` (``init_form="eq63"``), or the equivalent diagonal form (``"diagonal"``:
:math:`A = \mathrm{diag}(1,\phi)`, :math:`C = [1, 1]`); the state prior is
:math:`\hat x_0 = 0`, :math:`P_0 = \sum_{j<h}A^jQA^{jT}` (:func:`prior_covariance`, :math:`h` the
length of the first chunk: the spread of the state about that chunk's mean under the current
model; see "Numerics" for why not a diffuse prior); the record's
first-chunk mean is removed and the data are divided by a fixed scale (the white-noise level of
the first chunk) for conditioning; with ``recursive=True`` (the paper) parameters are updated after
every ``update_every`` samples once ``warmup`` samples are in; an update that would be singular or
give an indefinite Q is skipped and counted (the paper does not say). ``passes > 1`` repeats the
pass over the record from the last estimate: with ``recursive=False`` each pass is one exact batch
EM iteration (Shumway & Stoffer 1982; the E-K filters give the smoothed sufficient statistics).
An M-step whose :math:`A` has an eigenvalue outside the closed unit disk has that eigenvalue moved
onto it (real eigenvalues clipped to :math:`\pm1` with the eigenvectors kept, a complex pair
scaled to modulus 1) before :math:`Q` is formed from it (Q's update is the maximiser for any given
A, so this is a conditional-maximisation step); eq. 63's model has eigenvalues 1 and
:math:`1-\beta\tau`, none explosive. The count is ``extras_["n_clipped"]``.

Numerics: what keeps the filter stable
--------------------------------------
The measurement update is the Joseph form and stays symmetric positive semi-definite. Two links
would otherwise make the recursion diverge on a record started far from the truth: (1) eq. 29's
:math:`U^{(0)}` contains :math:`E[x_0x_0^T|Y_k]`, which under a diffuse, isotropic prior
(:math:`P_0 = I s^2/(CC^T)`, ~1e8 where the model's state variance is ~1-20) stays ~:math:`P_0` in
the directions the first samples do not resolve, so the first M-steps put ~:math:`P_0/k` into Q;
(2) the next M-steps give an :math:`A` with an explosive eigenvalue whose eigenvector is almost in
the null space of C. EM cannot correct an unobservable mode (its statistics reproduce the model's
own dynamics) and :math:`C = E^T(U^{(0)})^{-1}` shrinks along it as its variance grows, so P and the
E-K statistics grow like :math:`\lambda^{2k}` until rounding makes P indefinite. No covariance
factorisation survives that, so both links are cut at the source: the prior is the model's own
accumulated covariance (the x_0 term of eq. 29 is then the documented O(1/k) bias), and an
explosive M-step is clipped onto the unit disk (a random-walk or Gauss-Markov state then grows at
most linearly in an unobservable direction). Rejecting such steps instead would freeze the
recursion: with a unit root the unconstrained estimate is > 1 about half the time. The tests run 60
short records per mode (starts up to 100x off) and long records.

Examples
--------
>>> import numpy as np
>>> from avbench.estimators.online.arma_em import ArmaEM
>>> rng = np.random.default_rng(1)
>>> dt, n, N, K = 0.1, 20000, 1e-3, 1e-5
>>> y = N / np.sqrt(dt) * rng.standard_normal(n) + np.cumsum(K * np.sqrt(dt) * rng.standard_normal(n))
>>> est = ArmaEM(terms="NK", x0={"N": 2e-3, "K": 3e-5}).fit(y, dt)
>>> bool(abs(est.coefficients_["N"] / N - 1) < 0.05)
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from avbench.estimators.online import _arma_em_kernels as _k
from avbench.estimators.results import FitParts
from avbench.estimators.online._common import x0_gives_the_terms
from avbench.estimators.settings import (Boolean, Check, Coefficients, Interval, NoneValue, Options, Relation,
                                         validate_settings)
from avbench.estimators.validation import check_terms
from avbench.estimators.base import DivergenceWarning, Estimator, register, warn
from avbench.noise_models.terms import B_EQUIV_OVER_SIGMA, GM_PEAK_TAU_OVER_TC
from avbench.noise_models.units import as_si

__all__ = ["ArmaEM", "SUPPORTED_TERMS", "initial_model", "coefficients_from_model", "prior_covariance",
           "EKFilter"]

#: coefficient sets the equivalent-ARMA model can represent, and their state dimension
SUPPORTED_TERMS = {("N", "K"): 1, ("N", "B"): 1, ("N", "B", "K"): 2}
_INIT_FORMS = ("eq63", "diagonal")
_ENGINES = ("numba", "reference")


def _check_supported(terms) -> tuple[str, ...]:
    if isinstance(terms, str) and any(c in terms for c in "QR"):
        raise ValueError(
            f"terms={terms!r}: arma_em cannot model quantization (Q) or rate ramp (R): the equivalent "
            "ARMA model is driven by white noise only (Miao et al. 2015, §3); expected one of "
            "'NK', 'NB', 'NBK'"
        )
    t = check_terms(terms)
    if t not in SUPPORTED_TERMS:
        raise ValueError(
            f"terms={terms!r}: arma_em supports the coefficient sets 'NK', 'NB', 'NBK' "
            "(white-noise-driven models with N as measurement noise; Q and R are not supported)"
        )
    return t


def initial_model(coefs: dict, tc: float, dt: float, terms, form: str = "eq63"):
    r"""State-space matrices (A, C, Q, R), in SI, of the equivalent-ARMA model at given coefficients.

    For ``terms = "NBK"`` and ``form="eq63"`` this is Miao et al. 2015, eq. 63 with the corrections
    of the module docstring:

    .. math::

        A = \begin{bmatrix}1 & dt\\ 0 & 1-\beta dt\end{bmatrix},\quad
        Q = \begin{bmatrix}0 & 0\\ 0 & dt\end{bmatrix},\quad
        C = [K\beta,\ \sqrt{K^2+\beta^2B_p^2}],\quad R = N^2/dt,

    :math:`\beta = 1/T_c`, :math:`B_p = \sigma\sqrt{2/\beta}`, :math:`\sigma = B/0.9294`.
    ``form="diagonal"``: :math:`A = \mathrm{diag}(1, \phi)`, :math:`C = [1, 1]`,
    :math:`Q = \mathrm{diag}(K^2dt,\ \sigma^2(1-\phi^2))` (same output spectrum up to the Euler
    step). ``"NK"``: :math:`A = 1, C = 1, Q = K^2 dt`; ``"NB"``: :math:`A = \phi, C = 1,
    Q = \sigma^2(1-\phi^2)`.
    """
    terms = _check_supported(terms)
    R = np.array([coefs["N"] ** 2 / dt])
    if terms == ("N", "K"):
        return np.eye(1), np.ones(1), np.array([[coefs["K"] ** 2 * dt]]), R
    sigma = coefs["B"] / B_EQUIV_OVER_SIGMA
    phi = math.exp(-dt / tc)
    qg = sigma**2 * -math.expm1(-2.0 * dt / tc)
    if terms == ("N", "B"):
        return np.array([[phi]]), np.ones(1), np.array([[qg]]), R
    K = coefs["K"]
    if form == "diagonal":
        return np.diag([1.0, phi]), np.ones(2), np.diag([K**2 * dt, qg]), R
    beta = 1.0 / tc
    Bp = sigma * math.sqrt(2.0 / beta)
    A = np.array([[1.0, dt], [0.0, 1.0 - beta * dt]])
    C = np.array([K * beta, math.sqrt(K**2 + beta**2 * Bp**2)])
    Q = np.array([[0.0, 0.0], [0.0, dt]])
    return A, C, Q, R


def coefficients_from_model(A, C, Q, R, dt: float, terms) -> tuple[dict, dict, dict]:
    r"""N, B, K (SI) from estimated (A, C, Q, R) through similarity invariants (module docstring).

    Returns ``(coefficients, nonphysical, extra)``; ``extra`` holds ``tc`` (s), ``lambda_rrw``
    (the eigenvalue of A taken as the random walk's, ideally 1) and ``sigma_gm``.

    Examples
    --------
    >>> A, C, Q, R = initial_model({"N": 1e-3, "B": 2e-4, "K": 3e-6}, 50.0, 0.01, "NBK")
    >>> c, bad, extra = coefficients_from_model(A, C, Q, R, 0.01, "NBK")
    >>> [round(c[k] / v, 3) for k, v in (("N", 1e-3), ("B", 2e-4), ("K", 3e-6))]
    [1.0, 1.0, 1.0]
    """
    terms = _check_supported(terms)
    A = np.asarray(A, float)
    C = np.asarray(C, float).ravel()
    Q = np.asarray(Q, float)
    R = float(np.ravel(R)[0])
    coefs = {c: math.nan for c in terms}
    bad = {c: True for c in terms}
    extra = {"tc": math.nan, "lambda_rrw": math.nan, "sigma_gm": math.nan}
    if R > 0 and math.isfinite(R):
        coefs["N"], bad["N"] = math.sqrt(R * dt), False
    if terms != ("N", "B", "K"):
        lam, q = A[0, 0], C[0] ** 2 * Q[0, 0]
        if terms == ("N", "K"):
            extra["lambda_rrw"] = lam
            if q >= 0 and math.isfinite(q):
                coefs["K"], bad["K"] = math.sqrt(q / dt), False
        else:
            _set_gm(coefs, bad, extra, 1.0 - lam, q, dt)
        return coefs, bad, extra
    # eigenvalues of M = I - A: eps = 1 - lambda, computed without cancellation
    M = np.eye(2) - A
    tr, det = M[0, 0] + M[1, 1], M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]
    disc = tr * tr - 4.0 * det
    if not (disc >= 0 and math.isfinite(disc)):
        return coefs, bad, extra
    big = 0.5 * (tr + math.copysign(math.sqrt(disc), tr))
    small = det / big if big != 0 else 0.0
    e1, e2 = (small, big) if abs(small) <= abs(big) else (big, small)  # e1: random walk
    extra["lambda_rrw"] = 1.0 - e1
    # numerator of the state part of the spectrum: (z u + v) Q (u/z + v)'
    u = C
    v = C @ (A - np.trace(A) * np.eye(2))
    w = C @ np.array([[M[1, 1], -M[0, 1]], [-M[1, 0], M[0, 0]]])  # C adj(I - A) = u + v
    alpha = float(w @ Q @ w)  # numerator at z = 1
    gamma = -float(u @ Q @ v)  # minus the coefficient of z
    sysm = np.array([[e2 * e2, e1 * e1], [1.0 - e2, 1.0 - e1]])
    if abs(np.linalg.det(sysm)) == 0 or not np.all(np.isfinite(sysm)):
        return coefs, bad, extra
    qk, qg = np.linalg.solve(sysm, [alpha, gamma])
    if qk >= 0 and math.isfinite(qk):
        coefs["K"], bad["K"] = math.sqrt(qk / dt), False
    _set_gm(coefs, bad, extra, e2, qg, dt)
    return coefs, bad, extra


def _set_gm(coefs, bad, extra, eps, qg, dt):
    """B (and tc, sigma) of a Gauss-Markov term with phi = 1 - eps and driving variance qg."""
    if 0 < eps < 1 and qg >= 0 and math.isfinite(qg):
        sigma = math.sqrt(qg / (eps * (2.0 - eps)))
        extra["sigma_gm"] = sigma
        extra["tc"] = -dt / math.log1p(-eps)
        coefs["B"], bad["B"] = B_EQUIV_OVER_SIGMA * sigma, False


def prior_covariance(A, Q, h: int) -> np.ndarray:
    r"""Prior covariance of the state at the start of a pass: :math:`\sum_{j=0}^{h-1} A^jQA^{jT}`.

    The covariance the model accumulates over ``h`` steps from a known state: for a stable mode
    (Gauss-Markov) the stationary covariance once ``h`` exceeds its correlation time, for the
    random walk the spread of its level over ``h`` samples. Computed by doubling,
    :math:`S_{2h} = S_h + A^hS_hA^{hT}`, in :math:`O(\log h)` products.
    """
    A = np.asarray(A, float)
    S = np.asarray(Q, float).copy()  # S_1
    Ah = A.copy()  # A^1
    todo, S_out, A_out = int(h), np.zeros_like(S), np.eye(A.shape[0])
    while todo:  # binary expansion of h: S_out = S_a, A_out = A^a for the bits done so far
        if todo & 1:
            S_out = S_out + A_out @ S @ A_out.T
            A_out = A_out @ Ah
        todo >>= 1
        if todo:
            S = S + Ah @ S @ Ah.T
            Ah = Ah @ Ah
    return 0.5 * (S_out + S_out.T)


@dataclass
class EKFilter:
    """State of one E-K recursive-EM pass (all arrays; constant memory in the record length).

    Parameters A, C, Q, R are in the scaled units of the data fed in.
    """

    A: np.ndarray
    C: np.ndarray
    Q: np.ndarray
    R: np.ndarray

    def start(self, y0: float, P0: np.ndarray) -> None:
        """Begin a pass: prior N(0, P0) for x_0, measurement update with y_0, E-K initialisation
        (Miao et al. 2015, eq. 33: a = 0, b = 0, d^(0) = sym(e_i e_j'), d^(1) = d^(2) = 0,
        b^T_i = e_i y_0)."""
        m = self.A.shape[0]
        P0 = np.array(P0, dtype=float)
        s = float(self.C @ P0 @ self.C + self.R[0])
        K = P0 @ self.C / s
        self.x = K * y0
        IKC = np.eye(m) - np.outer(K, self.C)
        P = IKC @ P0 @ IKC.T + np.outer(K, K) * self.R[0]
        self.P = 0.5 * (P + P.T)
        self.a = np.zeros((4, m, m))
        self.b = np.zeros((4, m, m, m))
        self.d = np.zeros((4, m, m, m, m))
        for i in range(m):
            for j in range(m):
                self.d[0, i, j, i, j] += 0.5
                self.d[0, i, j, j, i] += 0.5
        self.aT = np.zeros(m)
        self.bT = np.eye(m) * y0
        self.sc = np.array([y0 * y0, -0.5 * (math.log(2 * math.pi * s) + y0 * y0 / s)])
        self.ic = np.zeros(_k.N_IC, dtype=np.int64)
        self.tracks_h3 = True  # the E-K filter of H^(3) ran on every sample (exact_q)

    @property
    def m(self) -> int:
        return self.A.shape[0]

    @property
    def status(self) -> int:
        return int(self.ic[_k.I_STATUS])

    def run(self, y, *, recursive, warmup, update_every, trace_every, exact_q=False,
            engine="numba") -> np.ndarray:
        """Feed samples ``y`` (after the first); returns the trace rows written."""
        m = self.m
        start = int(self.ic[_k.I_K])
        n_rows = 0 if trace_every <= 0 else (start + len(y)) // trace_every - start // trace_every
        trace = np.empty((max(n_rows, 0), 2 + 2 * m * m + m))
        if self.status != _k.OK or len(y) == 0:
            return trace[:0]
        self.tracks_h3 = self.tracks_h3 and bool(exact_q)
        run = _k.ek_run
        if engine == "reference":
            from avbench.estimators.online._arma_em_reference import ek_run_reference as run
        ntr = run(np.ascontiguousarray(y, dtype=float), self.A, self.C, self.Q, self.R, self.x, self.P,
                  self.a, self.b, self.d, self.aT, self.bT, self.sc, self.ic, bool(recursive),
                  int(warmup), int(update_every), int(trace_every), trace, bool(exact_q))
        return trace[:ntr]

    def statistics(self) -> dict:
        """E[H^(0)], E[H^(1)], E[H^(2)], E[H^(3)], E[T] given the data so far (eqs 32-33).

        ``U3`` (:math:`H^{(3)}`) is NaN unless every :meth:`run` of the pass had ``exact_q``.
        """
        m = self.m
        U = np.empty((4, m, m))
        E = np.empty(m)
        _k.evaluate_stats(self.a, self.b, self.d, self.aT, self.bT, self.x, self.P, U, E)
        U3 = U[3] if self.tracks_h3 else np.full((m, m), np.nan)
        return {"U0": U[0], "U1": U[1], "U2": U[2], "U3": U3, "T": E, "syy": self.sc[_k.S_SYY],
                "k": int(self.ic[_k.I_K])}

    def m_step(self, exact_q=False) -> bool:
        """Batch M-step from the statistics of the pass; False (parameters kept) if invalid."""
        if exact_q and not self.tracks_h3:
            raise ValueError("exact_q: the pass did not track H^(3); run it with exact_q=True")
        k = int(self.ic[_k.I_K])
        return bool(k > 0 and _k.m_step(self.a, self.b, self.d, self.aT, self.bT, self.x, self.P,
                                        self.sc, k, self.A, self.C, self.Q, self.R, bool(exact_q)))

    @property
    def loglik(self) -> float:
        return float(self.sc[_k.S_LOGLIK])


@register("arma_em")
class ArmaEM(Estimator):
    r"""Equivalent-ARMA state-space model with Elliott-Krishnamurthy recursive EM (Miao et al. 2015, §3).

    See the module docstring for the model, the corrections to the printed equations and the
    mapping back to N, B, K.

    Parameters
    ----------
    terms : {"NBK", "NK", "NB"}
        Coefficients modelled (Q and R are not supported: ValueError).
    x0 : mapping or None
        Initial coefficient values (SI float or ``[value, "unit"]``) for every modelled term; Miao
        et al. 2015 use N 1.5 deg/sqrt(h), B 20 deg/h, K 50 deg/h^1.5. None: from an octave
        Allan-variance fit of the first chunk (N, B, K by non-negative least squares).
    tc0 : float or None
        Initial Gauss-Markov correlation time (s). None: :math:`\sqrt3 N_0/(1.8926 K_0)` (the AV
        minimum of N + K, read as the GM peak) when K is modelled, else 1000 dt.
    init_form : {"eq63", "diagonal"}
        Coordinates of the initial model (see :func:`initial_model`).
    passes : int
        Passes over the record in :meth:`fit`; each pass restarts the filters from the previous
        pass's parameters.
    recursive : bool
        True (the paper): parameters updated on line within a pass (recursive EM). False: fixed
        within a pass, one batch EM M-step at its end.
    warmup, update_every : int
        On-line M-steps start after ``warmup`` samples and happen every ``update_every`` samples.
    exact_q : bool
        False (the paper, eq. 29): Q from :math:`U^{(0)} = \sum_{l=0}^k x_lx_l^T`. True
        (improvement): from :math:`\sum_{l=1}^k x_lx_l^T`, the exact EM update. The difference
        is one term, but Q is a small difference of large sums (Q is tiny beside the state
        variance), so the extra :math:`x_0x_0^T/k` biases Q and hence K and B noticeably.
    trace_every : int
        Record the coefficient trajectory every so many samples (0: never), in the result's
        ``trajectory``.
    engine : {"numba", "reference"}
        Compiled kernel or the plain NumPy reference (slow; for tests).

    Attributes
    ----------
    coefficients_, nonphysical_, parts_, extras_
        See :class:`avbench.estimators.base.Estimator`. ``extras_`` holds ``A, C, Q, R`` (scaled
        units, see ``scale``), ``scale``, ``offset``, ``tc``, ``lambda_rrw``, ``loglik`` (per pass),
        ``n_updates``, ``n_rejected``, ``n_clipped``; the result its ``failure`` (None or a message
        with the sample index) and ``trajectory`` (DataFrame: sample, N, B, K in SI).
    """

    round_off_amplified = True  # an iterative EM's end point (last digits of K move between kernels) (Estimator.round_off_amplified)

    #: the record's offset and scale (the first chunk's mean and noise level) and the Gauss-Markov
    #: sigma carry the rate's unit; A, C, Q, R are in the filter's own scaled units
    diagnostic_units = {"offset": 1, "scale": 1, "sigma_gm": 1}

    online = True

    parameter_constraints = {
        "terms": [Check(_check_supported, "'NK', 'NB' or 'NBK', the coefficient sets arma_em supports (a subset of "
                                          "N, B, K with N; the equivalent ARMA model is driven by white noise only: "
                                          "no quantization Q, no rate ramp R)", explain=True)],
        "x0": [NoneValue(), Coefficients(positive=True)],
        "tc0": [NoneValue(), Interval(float, 0, None, closed="neither")],
        "init_form": [Options(*_INIT_FORMS)],
        "passes": [Interval(int, 1, None)],
        "recursive": [Boolean()],
        "warmup": [Interval(int, 1, None)],
        "update_every": [Interval(int, 1, None)],
        "exact_q": [Boolean()],
        "trace_every": [Interval(int, 0, None)],
        "engine": [Options(*_ENGINES)],
    }
    setting_relations = (Relation(("x0", "terms"), lambda est: x0_gives_the_terms(est.x0, _check_supported(est.terms)),
                                  "x0 gives exactly the modelled terms"),)

    def __init__(self, *, terms="NBK", x0=None, tc0=None, init_form="eq63", passes=1, recursive=True,
                 warmup=100, update_every=1, exact_q=False, trace_every=1000, engine="numba"):
        self.terms = terms
        self.x0 = x0
        self.tc0 = tc0
        self.init_form = init_form
        self.passes = passes
        self.recursive = recursive
        self.warmup = warmup
        self.update_every = update_every
        self.exact_q = exact_q
        self.trace_every = trace_every
        self.engine = engine

    # -- settings ---------------------------------------------------------------------------------
    def _settings(self) -> dict:
        # partial_fit starts here without Estimator.fit: the declared settings are checked here too
        validate_settings(type(self), self.get_params())
        terms = _check_supported(self.terms)
        return {
            "terms": terms,
            "x0": None if self.x0 is None else {c: as_si(c, self.x0[c]) for c in terms},
            "tc0": None if self.tc0 is None else float(self.tc0),
            "passes": int(self.passes),
            "warmup": int(self.warmup),
            "update_every": int(self.update_every),
            "trace_every": int(self.trace_every),
        }

    # -- initialisation -----------------------------------------------------------------------------
    @staticmethod
    def _data_x0(y, dt, terms) -> dict:
        """Initial N, B, K from a non-negative least-squares fit of the octave AV of ``y``."""
        from scipy.optimize import nnls

        from avbench.estimators.allan.variance import allan_variance
        from avbench.estimators.allan.model import BETA_SCALE, design_matrix

        from avbench.estimators.validation import check_variance_seen

        av = allan_variance(y, dt, taus="octave", overlapping=False)
        keep = av.J >= 3
        check_variance_seen(av.tau[keep], av.avar[keep], len(terms))
        keep &= av.avar > 0
        X = design_matrix(av.tau[keep], terms)
        w = 1.0 / av.avar[keep]
        beta, _ = nnls(X * w[:, None], av.avar[keep] * w)
        x0 = {c: math.sqrt(max(b, 0.0) / BETA_SCALE[c]) for c, b in zip(terms, beta)}
        floor = 1e-3 * math.sqrt(np.var(np.diff(y)) / 2 * dt)  # keep every term alive
        fallback = {"N": floor, "B": floor / math.sqrt(dt), "K": floor / math.sqrt(dt) / (len(y) * dt)}
        return {c: v if v > 0 else fallback[c] for c, v in x0.items()}

    def _start(self, y: np.ndarray, dt: float) -> None:
        cfg = self._settings()
        terms = cfg["terms"]
        x0 = cfg["x0"] or self._data_x0(y, dt, terms)
        tc0 = cfg["tc0"]
        if tc0 is None:
            if "K" in terms:
                tc0 = math.sqrt(3.0) * x0["N"] / x0["K"] / GM_PEAK_TAU_OVER_TC
            else:
                tc0 = 1000.0 * dt
        tc0 = max(tc0, 2.0 * dt)
        A, C, Q, R = initial_model(x0, tc0, dt, terms, self.init_form)
        # fixed offset and scale (first chunk) for conditioning: y_s = (y - offset) / scale
        offset = float(np.mean(y))
        scale = math.sqrt(0.5 * float(np.var(np.diff(y)))) if len(y) > 1 else 0.0
        if not scale > 0:
            scale = max(abs(offset), 1.0)
        self._cfg = cfg
        self._dt = dt
        self._n_first = len(y)
        self._offset, self._scale = offset, scale
        self._x0_si, self._tc0 = x0, tc0
        self._filter = EKFilter(A=A.copy(), C=C / scale, Q=Q.copy(), R=R / scale**2)
        self._pass = 0
        self._stopped = None
        self._loglik: list[float] = []
        self._trace: list[np.ndarray] = []
        self._begin_pass(float((y[0] - offset) / scale))

    def _begin_pass(self, y0_scaled: float) -> None:
        f = self._filter
        f.start(y0_scaled, prior_covariance(f.A, f.Q, self._n_first))
        self._pass += 1

    # -- fitting -------------------------------------------------------------------------------
    def _feed(self, y: np.ndarray) -> None:
        cfg = self._cfg
        ys = (y - self._offset) / self._scale
        rows = self._filter.run(ys, recursive=self.recursive, warmup=cfg["warmup"],
                                update_every=cfg["update_every"], trace_every=cfg["trace_every"],
                                exact_q=self.exact_q, engine=self.engine)
        if len(rows) and self._pass == 1:  # converted once, as they arrive
            self._trace.append(self._trace_coefficients(rows))

    def partial_fit(self, chunk, dt) -> "ArmaEM":
        """Feed the next chunk of a record (on-line, one pass, constant memory).

        The first call fixes ``dt``, the offset (the chunk's mean) and the scale; later chunks must
        have the same ``dt``. After every call ``coefficients_`` holds the current estimates.
        """
        if getattr(self, "_filter", None) is None or getattr(self, "_pass", 0) == 0:
            rate, dt = _check_record(chunk, dt, minimum=16)
            self._start(rate, dt)
            self._feed(rate[1:])
        else:
            rate, dt = _check_record(chunk, dt, minimum=0)
            if dt != self._dt:
                raise ValueError(f"dt: expected the same sample interval as the first chunk ({self._dt}), got {dt}")
            self._feed(rate)
        self._set_results(*self._results())
        return self

    def reset(self) -> "ArmaEM":
        """Forget the data seen by :meth:`partial_fit`."""
        self._filter = None
        self._pass = 0
        return self

    def _fit(self, rate, dt):
        self.reset()
        self._start(rate, dt)
        f = self._filter
        for p in range(self._cfg["passes"]):
            if p > 0:
                self._begin_pass(float((rate[0] - self._offset) / self._scale))
            self._feed(rate[1:])
            if f.status != _k.OK:
                break
            self._loglik.append(f.loglik)
            if not self.recursive and not f.m_step(self.exact_q):
                if p == 0:
                    f.ic[_k.I_STATUS] = _k.FAIL_MSTEP
                    f.ic[_k.I_FAIL_INDEX] = f.ic[_k.I_K]
                else:  # EM walked to the boundary (a variance -> 0): keep the last valid estimate
                    self._stopped = f"M-step invalid after pass {p + 1}; kept the parameters of pass {p + 1}"
                break
        return self._results()

    def _results(self):
        f, dt, s = self._filter, self._dt, self._scale
        terms = self._cfg["terms"]
        failure = None
        if f.status != _k.OK:
            failure = (f"{_k.FAILURE_MESSAGES[f.status]} at sample {int(f.ic[_k.I_FAIL_INDEX])}"
                       f" of pass {self._pass}")
            warn(DivergenceWarning, f"arma_em: {failure}")
            coefs, bad = {c: math.nan for c in terms}, {c: False for c in terms}
            extra = {"tc": math.nan, "lambda_rrw": math.nan, "sigma_gm": math.nan}
        else:
            coefs, bad, extra = coefficients_from_model(f.A, f.C * s, f.Q, f.R * s**2, dt, terms)
        traj = self._trajectory()
        diag = {
            "stopped": self._stopped,
            "A": f.A.copy(), "C": f.C.copy(), "Q": f.Q.copy(), "R": float(f.R[0]),
            "scale": s, "offset": self._offset, "passes": self._pass,
            "x0": dict(self._x0_si), "tc0": self._tc0,
            "loglik": list(self._loglik) or [f.loglik],
            "n_samples": int(f.ic[_k.I_K]) + 1,
            "n_updates": int(f.ic[_k.I_UPDATES]), "n_rejected": int(f.ic[_k.I_REJECTED]),
            "n_clipped": int(f.ic[_k.I_CLIPPED]),
            "first_rejected": int(f.ic[_k.I_FIRST_REJECT]) if f.ic[_k.I_REJECTED] else None,
            **extra,
        }
        loglik = diag["loglik"]
        parts = FitParts(failure=failure, trajectory=traj, llf=float(loglik[-1]) if loglik else math.nan,
                         n_iter=int(self._pass))
        return coefs, bad, diag, parts

    def _trace_coefficients(self, rows: np.ndarray) -> np.ndarray:
        """Rows [sample, coefficients (SI)...] from traced kernel rows [k, A, C, Q, R]."""
        terms = self._cfg["terms"]
        m, s, dt = self._filter.m, self._scale, self._dt
        out = np.empty((len(rows), 1 + len(terms)))
        for i, r in enumerate(rows):
            A = r[1 : 1 + m * m].reshape(m, m)
            C = r[1 + m * m : 1 + m * m + m] * s
            Q = r[1 + m * m + m : 1 + 2 * m * m + m].reshape(m, m)
            c, _, _ = coefficients_from_model(A, C, Q, r[-1] * s**2, dt, terms)
            out[i] = [r[0] + 1, *(c[t] for t in terms)]
        return out

    def _trajectory(self) -> pd.DataFrame:
        """Coefficient estimates (SI) along the first pass, every ``trace_every`` samples."""
        cols = ["sample", *self._cfg["terms"]]
        if not self._trace:
            return pd.DataFrame(columns=cols)
        df = pd.DataFrame(np.concatenate(self._trace), columns=cols)
        df["sample"] = df["sample"].astype(np.int64)
        return df


def _check_record(chunk, dt, minimum):
    from avbench.estimators.validation import check_record

    if minimum >= 16:
        return check_record(chunk, dt)
    arr = np.asarray(chunk)
    if arr.ndim != 1 or arr.dtype.kind not in "iuf" or not np.all(np.isfinite(arr)):
        raise ValueError("chunk: expected a 1-D array of finite numeric rate samples")
    _, dt = check_record(np.zeros(16), dt)
    return arr.astype(np.float64, copy=False), dt
