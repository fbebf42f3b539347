"""The block-mean state-space model of :mod:`avbench.estimators.likelihood.mle` and its compiled Kalman likelihood.

:class:`BlockMeanSystem` builds the system matrices (transition ``T``, disturbance covariance
``Qc``, design ``Z``, observation variance ``H``, initial covariances) of the exact block-mean
model derived in the :mod:`avbench.estimators.likelihood.mle` docstring; :func:`diffuse_loglike` evaluates its exact
Gaussian log-likelihood by the Kalman filter with the exact initial treatment of the diffuse
states (level, drift) of Durbin & Koopman (2012, Sec. 5.2, univariate form of Sec. 6.4; Koopman &
Durbin 2000): while the diffuse covariance :math:`P_\\infty` is non-zero, an observation with
:math:`F_\\infty = Z P_\\infty Z' > 0` contributes :math:`-\\tfrac12\\log(2\\pi F_\\infty)` and
updates with the gains :math:`K_0 = P_\\infty Z'/F_\\infty`,
:math:`K_1 = (P_* Z' - F_* K_0)/F_\\infty`; afterwards the ordinary prediction-error decomposition
:math:`-\\tfrac12\\sum_t(\\log 2\\pi F_t + v_t^2/F_t)` (Durbin & Koopman 2012, eq. 7.2).

The recursion is the one statsmodels runs for ``BlockMeanModel`` (univariate diffuse filter,
diffuse tolerance 1e-10, predicted covariance forced symmetric, and the covariance frozen once
the squared Frobenius norm of its change is below 1e-19 -- a time-invariant filter has then
reached its steady state, so later steps update the state only). That model
(:mod:`avbench.estimators.likelihood._mle_model`) is kept as the reference the tests hold this one to. Everything
here is NumPy + numba: no statsmodels import.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["BlockMeanSystem", "diffuse_loglike", "diffuse_filter", "augmented_loglike", "augmented_filter"]

#: statsmodels' thresholds (``KalmanFilter``): diffuse F_inf, and the steady-state test on P
TOL_DIFFUSE = 1e-10
TOL_CONVERGED = 1e-19


class BlockMeanSystem:
    """Layout and system matrices of the block-mean model (see :mod:`avbench.estimators.likelihood.mle`),
    assembled from the terms' own parts (:meth:`avbench.noise_models.NoiseTerm.block_mean_block`).

    State: the states of each stochastic term, from the last of the model to the first (``(s, xbar)`` of
    a Gauss-Markov term, ``(theta_j, theta_{j-1})`` of quantization), then the shared level
    ``(L, Lbar)``, then the deterministic terms' states (the drift's slope); the level and those are
    diffuse. Parameters are the natural logarithms of each stochastic term's fit parameters, in the
    model's order. The observation row depends on m and dt only (the terms' rows at unit parameters).
    """

    def __init__(self, latents, m: int, dt: float):
        from avbench.noise_models.latents import LATENT_TERMS

        self.latents = tuple(latents)
        self.m, self.dt = int(m), float(dt)
        terms = [LATENT_TERMS[lat] for lat in self.latents]
        stochastic = [cls for cls in terms if not cls.deterministic]
        # the stochastic terms' states in the reverse of the model's order: the layout whose summation
        # order the filters' round-off is fixed with (another order moves the likelihood by ~1e-16
        # relative, which the Hessian's differences carry into the standard errors at ~1e-7)
        states, i = {}, 0
        for cls in reversed(stochastic):
            states[cls] = slice(i, i + cls.block_mean_states)
            i += cls.block_mean_states
        #: (term class, its states, indices of its log-parameters) per term: stochastic ones, then the others
        self.parts, n = [], 0
        for cls in stochastic:
            self.parts.append((cls, states[cls], list(range(n, n + len(cls.fit_parameters)))))
            n += len(cls.fit_parameters)
        self.lev = i
        i += 2
        for cls in terms:
            if cls.deterministic:
                self.parts.append((cls, slice(i, i + cls.block_mean_states), []))
                i += cls.block_mean_states
        self.k = i
        #: each stochastic term's parameter indices, its amplitude first
        self.groups = [idx for _, _, idx in self.parts if idx]
        #: a diffuse state beside the level (a drift): the augmented filter's case
        self.drift = self.k > self.lev + 2
        #: the states that start from their stationary distribution, one (start, stop) per term
        self.stationary = [(sl.start, sl.stop) for cls, sl, _ in self.parts if sl.stop > sl.start
                           and not cls.deterministic]
        # the log of each stochastic term's fit parameters, in the model's order (the drift is a state)
        self.names = [f"log_{p}" for cls in stochastic for p in cls.fit_parameters]
        Z = np.zeros(self.k)
        Z[self.lev + 1] = 1.0
        for cls, sl, idx in self.parts:
            Z[sl] = cls.block_mean_block(np.ones(len(idx)), self.m, self.dt).Z
        self.Z = Z

    def values(self, params) -> dict:
        return dict(zip(self.names, np.exp(np.asarray(params, dtype=float))))

    def _blocks(self, params, scale):
        """Each term's ``(class, states, parameter indices, values, StateBlock)``: the amplitude (the first
        fit parameter) in the unit of the scaled data, the shape parameters as they are."""
        v = np.exp(np.asarray(params, dtype=float))
        out = []
        for cls, sl, idx in self.parts:
            vals = [v[i] * scale if k == 0 else v[i] for k, i in enumerate(idx)]
            out.append((cls, sl, idx, vals, cls.block_mean_block(vals, self.m, self.dt)))
        return out

    def matrices(self, params, scale: float = 1.0):
        """``(T, Qc, H, P0, Pinf0)`` for log-parameters ``params``, data multiplied by ``scale``.

        ``P0`` is the covariance of the first state from its stationary distribution (GM,
        quantization); ``Pinf0`` is the identity on the diffuse block (level, drift).
        """
        return self._matrices(self._blocks(params, scale))

    def _matrices(self, blocks):
        k, lev = self.k, self.lev
        T, Qc, P0, Pinf0 = np.zeros((k, k)), np.zeros((k, k)), np.zeros((k, k)), np.zeros((k, k))
        H = 0.0
        T[lev, lev] = T[lev + 1, lev] = 1.0
        for _, sl, _, _, b in blocks:
            T[sl, sl], Qc[sl, sl], P0[sl, sl] = b.T, b.Q, b.P0
            H += b.H
            if b.level is not None:
                Qc[lev : lev + 2, lev : lev + 2] += b.level
            if b.level_input is not None:
                T[lev : lev + 2, sl] = b.level_input
        for i in range(lev, k):
            Pinf0[i, i] = 1.0
        return T, Qc, H, P0, Pinf0

    def derivatives(self, params, scale: float = 1.0):
        """Derivatives of :meth:`matrices`' ``(T, Qc, H, P0)`` with respect to each log-parameter:
        arrays ``(dT, dQc, dH, dP0)`` of shapes (p, k, k), (p, k, k), (p,), (p, k, k), in the order
        of :attr:`names` (each term's :meth:`~avbench.noise_models.NoiseTerm.block_mean_derivatives`)."""
        p, k, lev = len(self.names), self.k, self.lev
        dT, dQc, dH, dP0 = np.zeros((p, k, k)), np.zeros((p, k, k)), np.zeros(p), np.zeros((p, k, k))
        for cls, sl, idx, vals, b in self._blocks(params, scale):
            for i, d in zip(idx, cls.block_mean_derivatives(vals, self.m, self.dt, b)):
                dT[i, sl, sl], dQc[i, sl, sl], dP0[i, sl, sl], dH[i] = d.T, d.Q, d.P0, d.H
                if d.level is not None:
                    dQc[i, lev : lev + 2, lev : lev + 2] = d.level
                if d.level_input is not None:
                    dT[i, lev : lev + 2, sl] = d.level_input
        return dT, dQc, dH, dP0

    def score(self, y, params, scale: float = 1.0, method: str = "auto") -> tuple:
        """``(loglike, gradient)``: the exact diffuse log-likelihood of ``y * scale`` (as
        :meth:`loglike` with the same ``method``, to the bit) and its analytic derivatives in the
        log-parameters (the derivative recursions of :func:`diffuse_filter` or :func:`augmented_filter`)."""
        if method not in ("auto", "exact_initial", "augmented"):
            raise ValueError(f"method: expected 'auto', 'exact_initial' or 'augmented', got {method!r}")
        T, Qc, H, P0, Pinf0 = self.matrices(params, scale)
        dT, dQc, dH, dP0 = self.derivatives(params, scale)
        grad = np.empty(len(self.names))
        a, P = np.empty(self.k), np.empty((self.k, self.k))
        if method == "augmented" or (method == "auto" and self.drift):
            ll = augmented_filter(y, scale, T, Qc, self.Z, H, P0, self.lev, dT, dQc, dH, dP0, a, P, grad)
            if not math.isnan(ll):
                return ll, grad
        ll = diffuse_filter(y, scale, T, Qc, self.Z, H, P0, Pinf0, dT, dQc, dH, dP0, a, P, grad)
        return ll, grad

    def loglike(self, y, params, scale: float = 1.0, final=None, method: str = "auto") -> float:
        """Exact diffuse log-likelihood of ``y * scale`` (scaled units); ``final``: optional
        ``(a, P)`` arrays that receive the last filtered state and its covariance.

        ``method``: "exact_initial" (:func:`diffuse_loglike`), "augmented"
        (:func:`augmented_loglike`, falling back to the former where it returns NaN) or "auto":
        augmented with a drift (whose shrinking variance keeps the exact initial filter's
        covariance from ever reaching its steady state), exact initial otherwise (where its
        steady state comes first).
        """
        if method not in ("auto", "exact_initial", "augmented"):
            raise ValueError(f"method: expected 'auto', 'exact_initial' or 'augmented', got {method!r}")
        T, Qc, H, P0, Pinf0 = self.matrices(params, scale)
        a_out = np.empty(self.k) if final is None else final[0]
        P_out = np.empty((self.k, self.k)) if final is None else final[1]
        if method == "augmented" or (method == "auto" and self.drift):
            ll = augmented_loglike(y, scale, T, Qc, self.Z, H, P0, self.lev, a_out, P_out)
            if not math.isnan(ll):
                return ll
        return diffuse_loglike(y, scale, T, Qc, self.Z, H, P0, Pinf0, a_out, P_out)


@njit(cache=True)
def _sparse_rows(T):
    """T's non-zero entries row by row (CSR): row pointers, rows, columns, values."""
    k = T.shape[0]
    tp = np.zeros(k + 1, dtype=np.int64)
    for i in range(k):
        tp[i + 1] = tp[i] + _nonzeros(T[i])[0]
    ti = np.empty(tp[k], dtype=np.int64)
    tl = np.empty(tp[k], dtype=np.int64)
    tv = np.empty(tp[k])
    for i in range(k):
        _, cols, vals = _nonzeros(T[i])
        for e in range(cols.shape[0]):
            ti[tp[i] + e], tl[tp[i] + e], tv[tp[i] + e] = i, cols[e], vals[e]
    return tp, ti, tl, tv


@njit(cache=True)
def _nonzeros(z):
    """Count, positions and values of the non-zero entries of the vector ``z``."""
    nnz = 0
    for i in range(z.shape[0]):
        if z[i] != 0.0:
            nnz += 1
    idx = np.empty(nnz, dtype=np.int64)
    val = np.empty(nnz)
    e = 0
    for i in range(z.shape[0]):
        if z[i] != 0.0:
            idx[e], val[e] = i, z[i]
            e += 1
    return nnz, idx, val


@njit(cache=True, inline="always")
def _csr_left(tp, tl, tv, X, out):
    """out = T X, T given by its non-zero entries row by row (``tp``: row pointers, ``tl``: columns,
    ``tv``: values); the sums run over the same terms in the same order as the dense product, less
    the zeros."""
    for i in range(out.shape[0]):
        for j in range(X.shape[1]):
            acc = 0.0
            for e in range(tp[i], tp[i + 1]):
                acc += tv[e] * X[tl[e], j]
            out[i, j] = acc


@njit(cache=True)
def _predict(tp, ti, tl, tv, Pf, Qc, P, tmp):
    """P = T Pf T' + Qc, then forced symmetric (statsmodels' STABILITY_FORCE_SYMMETRY).

    T is given by its non-zero entries, row by row (``tp``: row pointers, ``tl``: columns, ``tv``:
    values, ``ti`` unused): the block-mean transition has at most 8 of its 49 entries non-zero.
    The sums run over the same terms in the same order as the dense product, less the zeros.
    """
    k = P.shape[0]
    _csr_left(tp, tl, tv, Pf, tmp)
    for i in range(k):
        for j in range(k):
            acc = 0.0
            for e in range(tp[j], tp[j + 1]):
                acc += tmp[i, tl[e]] * tv[e]
            P[i, j] = acc + Qc[i, j]
    for i in range(k):
        for j in range(i + 1, k):
            s = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = s
            P[j, i] = s


@njit(cache=True)
def _sq_change(P, Pprev):
    """Squared Frobenius norm of P - Pprev (the steady-state test)."""
    k = P.shape[0]
    ss = 0.0
    for i in range(k):
        for j in range(k):
            d = P[i, j] - Pprev[i, j]
            ss += d * d
    return ss


@njit(cache=True)
def _steady_gain(P, Z, H, M, K, Pf):
    """Freeze the filter at the predicted covariance P: returns F, fills the gain K = P Z / F and the
    filtered covariance Pf = P - P Z K'."""
    k = P.shape[0]
    F = _forecast(P, Z, H, M)
    for i in range(k):
        K[i] = M[i] / F
    for i in range(k):
        for j in range(k):
            Pf[i, j] = P[i, j] - M[i] * K[j]
    return F


@njit(cache=True)
def _forecast(P, Z, H, M):
    """M = P Z and the forecast variance Z' P Z + H."""
    k = P.shape[0]
    F = H
    for i in range(k):
        acc = 0.0
        for j in range(k):
            acc += P[i, j] * Z[j]
        M[i] = acc
        F += Z[i] * acc
    return F


@njit(cache=True)
def diffuse_loglike(y, scale, T, Qc, Z, H, P0, Pinf0, a_out, P_out):
    """Log-likelihood of ``y * scale`` under the state-space model (module docstring).

    Returns the log-likelihood in the scaled units; ``a_out``/``P_out`` receive the last filtered
    state and covariance. A non-positive forecast variance outside the diffuse period gives -inf.
    (:func:`diffuse_filter` without derivatives.)
    """
    k = T.shape[0]
    return diffuse_filter(y, scale, T, Qc, Z, H, P0, Pinf0, np.zeros((0, k, k)), np.zeros((0, k, k)),
                          np.zeros(0), np.zeros((0, k, k)), a_out, P_out, np.zeros(0))


@njit(cache=True, inline="always")
def _dstate(tp, tl, tv, dnz, drow, dcol, dval, af, daf, da, r, k):
    """The predicted state's derivative in parameter r: T daf + dT af (T, dT in sparse rows)."""
    for i in range(k):
        acc = 0.0
        for e in range(tp[i], tp[i + 1]):
            acc += tv[e] * daf[r, tl[e]]
        da[r, i] = acc
    for e in range(dnz[r]):
        da[r, drow[r, e]] += dval[r, e] * af[dcol[r, e]]


@njit(cache=True, inline="always")
def _dpredict(tp, tl, tv, dnz, drow, dcol, dval, Pf, dPf, dQc, dP, r, tmp, tmp2):
    """dP[r] = T dPf[r] T' + dT Pf T' + T Pf dT' + dQc[r], forced symmetric: the derivative of
    :func:`_predict` in parameter r (T by its non-zero entries, dT by its ``dnz[r]`` non-zero entries
    ``dval[r]`` at ``drow[r], dcol[r]``; the last two terms are each other's transpose, Pf being
    symmetric). Indexes the parameter's slices in place (no views: this runs p times per step)."""
    k = Pf.shape[0]
    for i in range(k):  # tmp = T dPf[r]
        for j in range(k):
            acc = 0.0
            for e in range(tp[i], tp[i + 1]):
                acc += tv[e] * dPf[r, tl[e], j]
            tmp[i, j] = acc
    nz = dnz[r]
    if nz > 0:
        for i in range(k):
            for j in range(k):
                tmp2[i, j] = 0.0
        for e in range(nz):  # tmp2 = dT Pf
            for j in range(k):
                tmp2[drow[r, e], j] += dval[r, e] * Pf[dcol[r, e], j]
        for i in range(k):
            for j in range(k):
                tmp[i, j] += tmp2[i, j]
    for i in range(k):
        for j in range(i, k):
            acc = 0.0
            for e in range(tp[j], tp[j + 1]):
                acc += tmp[i, tl[e]] * tv[e]
            acc2 = 0.0
            for e in range(tp[i], tp[i + 1]):
                acc2 += tmp[j, tl[e]] * tv[e]
            if nz > 0:
                for e in range(tp[i], tp[i + 1]):
                    acc += tv[e] * tmp2[j, tl[e]]
                for e in range(tp[j], tp[j + 1]):
                    acc2 += tv[e] * tmp2[i, tl[e]]
            sym = 0.5 * ((acc + dQc[r, i, j]) + (acc2 + dQc[r, j, i]))
            dP[r, i, j] = sym
            dP[r, j, i] = sym


@njit(cache=True, inline="always")
def _dforecast(dP, r, Z, dHr, dM):
    """dM[r] = dP[r] Z and the forecast variance's derivative Z' dP[r] Z + dH[r]."""
    k = Z.shape[0]
    F = dHr
    for i in range(k):
        acc = 0.0
        for j in range(k):
            acc += dP[r, i, j] * Z[j]
        dM[r, i] = acc
        F += Z[i] * acc
    return F


@njit(cache=True, inline="always")
def _dsq_change(dP, r, prev):
    """Squared Frobenius norm of dP[r] - prev."""
    k = prev.shape[0]
    ss = 0.0
    for i in range(k):
        for j in range(k):
            d = dP[r, i, j] - prev[i, j]
            ss += d * d
    return ss


@njit(cache=True)
def _entries(dT):
    """The non-zero entries of each matrix ``dT[r]``: counts, rows, columns, values."""
    p, k = dT.shape[0], dT.shape[1]
    dnz = np.zeros(p, dtype=np.int64)
    drow = np.zeros((p, k * k), dtype=np.int64)
    dcol = np.zeros((p, k * k), dtype=np.int64)
    dval = np.zeros((p, k * k))
    for r in range(p):
        for i in range(k):
            for j in range(k):
                if dT[r, i, j] != 0.0:
                    e = dnz[r]
                    drow[r, e], dcol[r, e], dval[r, e] = i, j, dT[r, i, j]
                    dnz[r] = e + 1
    return dnz, drow, dcol, dval


@njit(cache=True)
def diffuse_filter(y, scale, T, Qc, Z, H, P0, Pinf0, dT, dQc, dH, dP0, a_out, P_out, grad):
    r""":func:`diffuse_loglike` and, for each of the ``p = dT.shape[0]`` parameters whose system
    matrices have derivatives ``dT[i], dQc[i], dH[i], dP0[i]``, the derivative of the same
    log-likelihood in ``grad[i]`` (the score; ``p`` may be 0).

    The score runs the derivative (tangent) recursions of the filter beside it -- the Kalman
    filter's derivative recursions of Harvey (1989, Sec. 3.4.6; Durbin & Koopman 2012, Sec. 7.3.3
    give the same score by the smoother): with :math:`\\dot x` the derivative of x in one parameter,
    :math:`\\dot v = -Z'\\dot a`, :math:`\\dot F = Z'\\dot PZ + \\dot H`, :math:`\\dot K =
    (\\dot PZ - K\\dot F)/F`, :math:`\\dot a_{t+1} = \\dot T a_{t|t} + T(\\dot a + \\dot Kv + K\\dot v)`,
    :math:`\\dot P_{t+1} = \\dot T P_{t|t}T' + T\\dot P_{t|t}T' + TP_{t|t}\\dot T' + \\dot Q` and
    :math:`\\dot\\ell = -\\tfrac12\\sum_t(\\dot F/F + 2v\\dot v/F - v^2\\dot F/F^2)`. The diffuse
    covariance does not depend on the parameters (the diffuse block of T is fixed).

    The likelihood freezes the covariance at its steady state (module docstring): the derivative
    of that function would jump wherever the freezing step moves, by the change of the still
    settling :math:`\dot P` times the number of frozen steps. Instead the derivative recursions
    run on, with the covariance frozen, until :math:`\dot P` settles by the same test
    (:math:`\|\Delta\dot P\|_F^2 < 10^{-19}` for every parameter): the score is then the
    derivative of the exact (never frozen) likelihood to the precision of the freeze, smooth in
    the parameters, so that its central differences give a stable observed information. The
    log-likelihood returned is :func:`diffuse_loglike`'s, to the bit.
    """
    n = y.shape[0]
    k = T.shape[0]
    p = dT.shape[0]
    a = np.zeros(k)
    af = np.empty(k)
    P = P0.copy()
    Pi = Pinf0.copy()
    Pf = np.empty((k, k))
    Pif = np.empty((k, k))
    Pprev = np.empty((k, k))
    tmp = np.empty((k, k))
    tmp2 = np.empty((k, k))
    M = np.empty(k)
    Mi = np.empty(k)
    K0 = np.empty(k)
    K1 = np.empty(k)
    # derivatives, one row per parameter
    da = np.zeros((p, k))
    daf = np.empty((p, k))
    dP = dP0.copy()
    dPf = np.empty((p, k, k))
    dM = np.empty((p, k))
    dK0 = np.empty((p, k))
    dF = np.empty(p)
    dv = np.empty(p)
    dssq2 = np.zeros(p)  # sum of 2 v dv over the steps after the derivatives settle
    dll = np.zeros(p)
    ssq2 = 0.0
    n_post = 0
    dconverged = False
    tp, ti, tl, tv = _sparse_rows(T)  # T's non-zero entries by rows, for the covariance prediction
    dnz, drow, dcol, dval = _entries(dT)
    zero = np.zeros((k, k))
    log2pi = math.log(2.0 * math.pi)
    ll = 0.0
    nobs_diffuse = 0
    converged = False
    Fc = 1.0
    ssq = 0.0
    t_conv = n
    for t in range(n):
        diffuse = False
        if t == nobs_diffuse:
            ss = 0.0
            for i in range(k):
                for j in range(k):
                    ss += Pi[i, j] * Pi[i, j]
            if ss > TOL_DIFFUSE:
                nobs_diffuse += 1
                diffuse = True
        v = y[t] * scale
        for i in range(k):
            v -= Z[i] * a[i]
        for r in range(p):
            acc = 0.0
            for i in range(k):
                acc -= Z[i] * da[r, i]
            dv[r] = acc
        if converged:
            # steady state: fixed gain K0 and forecast variance Fc (the log-determinant term
            # -0.5 log(2 pi Fc) per step is added once at the end)
            for i in range(k):
                af[i] = a[i] + K0[i] * v
            ssq += v * v
            if dconverged:
                ssq2 += v * v
                n_post += 1
                for r in range(p):
                    for i in range(k):
                        daf[r, i] = da[r, i] + dK0[r, i] * v + K0[i] * dv[r]
                    dssq2[r] += 2.0 * v * dv[r]
            else:
                # the covariance is frozen, its derivatives still settle (their own test below)
                for r in range(p):
                    dF[r] = _dforecast(dP, r, Z, dH[r], dM)
                    for i in range(k):
                        dK0[r, i] = (dM[r, i] - K0[i] * dF[r]) / Fc
                    for i in range(k):
                        daf[r, i] = da[r, i] + dK0[r, i] * v + K0[i] * dv[r]
                    dll[r] -= 0.5 * (dF[r] / Fc + 2.0 * v * dv[r] / Fc - v * v * dF[r] / (Fc * Fc))
                dchange = _dsettle_step(tp, tl, tv, dnz, drow, dcol, dval, Pf, dPf, dQc, dP, M, K0, dM, dK0,
                                        Pprev, tmp, tmp2)
                if dchange < TOL_CONVERGED:
                    dconverged = True
                    for r in range(p):
                        dF[r] = _dforecast(dP, r, Z, dH[r], dM)
                        for i in range(k):
                            dK0[r, i] = (dM[r, i] - K0[i] * dF[r]) / Fc
            for i in range(k):
                acc = 0.0
                for e in range(tp[i], tp[i + 1]):
                    acc += tv[e] * af[tl[e]]
                a[i] = acc
            for r in range(p):
                _dstate(tp, tl, tv, dnz, drow, dcol, dval, af, daf, da, r, k)
            continue
        F = max(_forecast(P, Z, H, M), 0.0)
        for r in range(p):
            dF[r] = _dforecast(dP, r, Z, dH[r], dM)
        Fi = max(_forecast(Pi, Z, 0.0, Mi), 0.0) if diffuse else 0.0
        if diffuse and Fi > TOL_DIFFUSE:
            for i in range(k):
                K0[i] = Mi[i] / Fi
            for i in range(k):
                K1[i] = M[i] / Fi + (-F / Fi) * K0[i]
            for i in range(k):
                af[i] = a[i] + K0[i] * v
            # Pf = P L0' + Pi L1', Pif = Pi L0' with L0 = I - K0 Z', L1 = -K1 Z'
            for i in range(k):
                for j in range(k):
                    Pf[i, j] = P[i, j] - M[i] * K0[j] - Mi[i] * K1[j]
                    Pif[i, j] = Pi[i, j] - Mi[i] * K0[j]
            ll -= 0.5 * math.log(2.0 * math.pi * Fi)
            for r in range(p):  # K0 does not depend on the parameters; dK1 = (dM - dF K0) / Fi
                for i in range(k):
                    daf[r, i] = da[r, i] + K0[i] * dv[r]
                for i in range(k):
                    for j in range(k):
                        dPf[r, i, j] = (dP[r, i, j] - dM[r, i] * K0[j]
                                        - Mi[i] * (dM[r, j] - dF[r] * K0[j]) / Fi)
        elif F > TOL_DIFFUSE:
            for i in range(k):
                K0[i] = M[i] / F
            for i in range(k):
                af[i] = a[i] + K0[i] * v
            for i in range(k):
                for j in range(k):
                    Pf[i, j] = P[i, j] - M[i] * K0[j]
                    Pif[i, j] = Pi[i, j]
            ll -= 0.5 * (log2pi + math.log(F) + v * v / F)
            for r in range(p):
                for i in range(k):
                    dK0[r, i] = (dM[r, i] - K0[i] * dF[r]) / F
                for i in range(k):
                    daf[r, i] = da[r, i] + dK0[r, i] * v + K0[i] * dv[r]
                for i in range(k):
                    for j in range(k):
                        dPf[r, i, j] = dP[r, i, j] - dM[r, i] * K0[j] - M[i] * dK0[r, j]
                dll[r] -= 0.5 * (dF[r] / F + 2.0 * v * dv[r] / F - v * v * dF[r] / (F * F))
        else:
            if not diffuse:
                for r in range(p):
                    grad[r] = np.nan
                return -np.inf
            for i in range(k):
                af[i] = a[i]
                for j in range(k):
                    Pf[i, j] = P[i, j]
                    Pif[i, j] = Pi[i, j]
            for r in range(p):
                for i in range(k):
                    daf[r, i] = da[r, i]
                    for j in range(k):
                        dPf[r, i, j] = dP[r, i, j]
        # prediction
        for i in range(k):
            acc = 0.0
            for j in range(k):
                acc += T[i, j] * af[j]
            a[i] = acc
        for r in range(p):
            _dstate(tp, tl, tv, dnz, drow, dcol, dval, af, daf, da, r, k)
            _dpredict(tp, tl, tv, dnz, drow, dcol, dval, Pf, dPf, dQc, dP, r, tmp, tmp2)
        for i in range(k):
            for j in range(k):
                Pprev[i, j] = P[i, j]
        _predict(tp, ti, tl, tv, Pf, Qc, P, tmp)
        if diffuse or t < nobs_diffuse + 1:
            _predict(tp, ti, tl, tv, Pif, zero, Pi, tmp)
        elif t + 1 < n:
            if _sq_change(P, Pprev) < TOL_CONVERGED:
                # the next forecast's F and gain are those of this step's covariance
                converged = True
                t_conv = t + 1
                Fc = _steady_gain(P, Z, H, M, K0, Pf)
                dconverged = p == 0
    if converged:
        ll -= 0.5 * ((n - t_conv) * (log2pi + math.log(Fc)) + ssq / Fc)
    if dconverged:
        for r in range(p):
            dll[r] -= 0.5 * (n_post * dF[r] / Fc + dssq2[r] / Fc - ssq2 * dF[r] / (Fc * Fc))
    for r in range(p):
        grad[r] = dll[r]
    for i in range(k):
        a_out[i] = af[i]
        for j in range(k):
            P_out[i, j] = Pf[i, j]
    return ll


#: smallest forecast variance (units of the scaled data, whose variance is 1) the augmented filter
#: accepts; below it the Schur complement q - s' S^-1 s would cancel too many digits and the
#: likelihood falls back to the exact initial filter
TOL_AUGMENTED = 1e-8
#: squared relative change of the diffuse columns per step below which they are at their fixed
#: point (a relative change of 1e-14 per step, geometrically decaying: ~1e-12 on the likelihood)
TOL_COLUMNS = 1e-28
#: the augmented filter's steady-state test on P (squared Frobenius norm of the change per step);
#: tighter than statsmodels' 1e-19, so that it equals the (never frozen, with a drift) exact
#: initial filter to ~1e-14 relative
TOL_CONVERGED_AUGMENTED = 1e-28


@njit(cache=True)
def _augmented_step(yt, A, Af, Kf, w, zi, zv, tp, tl, tv):
    """One filtering and prediction step of every column: w = (y, 0) - Z'A, Af = A + Kf w, A = T Af."""
    k, c = A.shape
    for col in range(c):
        acc = yt if col == 0 else 0.0
        for e in range(zi.shape[0]):
            acc -= zv[e] * A[zi[e], col]
        w[col] = acc
    for i in range(k):
        for col in range(c):
            Af[i, col] = A[i, col] + Kf[i] * w[col]
    _csr_left(tp, tl, tv, Af, A)


@njit(cache=True, inline="always")
def _dsettle_gain(dP, dH, Z, dM, Kf, dKf, dF, Fc):
    """With the covariance frozen: the forecast variance's and gain's derivatives from dP."""
    p, k = dM.shape[0], dM.shape[1]
    for r in range(p):
        dF[r] = _dforecast(dP, r, Z, dH[r], dM)
        for i in range(k):
            dKf[r, i] = (dM[r, i] - Kf[i] * dF[r]) / Fc


@njit(cache=True, inline="always")
def _dsettle_step(tp, tl, tv, dnz, drow, dcol, dval, Pf, dPf, dQc, dP, M, Kf, dM, dKf, prev, tmp, tmp2):
    """One step of the covariance derivatives with the covariance frozen; their largest squared
    Frobenius change over the parameters (the caller compares it with its tolerance)."""
    p, k = dM.shape[0], dM.shape[1]
    change = 0.0
    for r in range(p):
        for i in range(k):
            for j in range(k):
                dPf[r, i, j] = dP[r, i, j] - dM[r, i] * Kf[j] - M[i] * dKf[r, j]
                prev[i, j] = dP[r, i, j]
        _dpredict(tp, tl, tv, dnz, drow, dcol, dval, Pf, dPf, dQc, dP, r, tmp, tmp2)
        change = max(change, _dsq_change(dP, r, prev))
    return change


@njit(cache=True)
def augmented_loglike(y, scale, T, Qc, Z, H, P0, lev, a_out, P_out):
    """Diffuse log-likelihood of ``y * scale`` by the augmented Kalman filter
    (:func:`augmented_filter` without derivatives)."""
    k = T.shape[0]
    return augmented_filter(y, scale, T, Qc, Z, H, P0, lev, np.zeros((0, k, k)), np.zeros((0, k, k)),
                            np.zeros(0), np.zeros((0, k, k)), a_out, P_out, np.zeros(0))


@njit(cache=True, inline="always")
def _dcolumns(r, dA, dAf, Af, w, dw, Kf, dKf, c0, c1, tp, tl, tv, dnz, drow, dcol, dval):
    """Derivative of one filtering and prediction step of the columns c0..c1-1 in parameter r:
    dAf = dA + dKf w' + Kf dw', dA = T dAf + dT Af."""
    k = Kf.shape[0]
    for i in range(k):
        for col in range(c0, c1):
            dAf[r, i, col] = dA[r, i, col] + dKf[r, i] * w[col] + Kf[i] * dw[r, col]
    for i in range(k):
        for col in range(c0, c1):
            acc = 0.0
            for e in range(tp[i], tp[i + 1]):
                acc += tv[e] * dAf[r, tl[e], col]
            dA[r, i, col] = acc
    for e in range(dnz[r]):
        for col in range(c0, c1):
            dA[r, drow[r, e], col] += dval[r, e] * Af[dcol[r, e], col]


@njit(cache=True, inline="always")
def _dinnovations(r, dA, dw, zi, zv, c0, c1):
    """dw[r, col] = -Z' dA[r][:, col] for the columns c0..c1-1."""
    for col in range(c0, c1):
        acc = 0.0
        for e in range(zi.shape[0]):
            acc -= zv[e] * dA[r, zi[e], col]
        dw[r, col] = acc


@njit(cache=True, inline="always")
def _dgram(r, dG, w, dw, dFr, F, c):
    """dG[r] += d(w w' / F) (lower triangle)."""
    for i in range(c):
        for j in range(i + 1):
            dG[r, i, j] += (dw[r, i] * w[j] + w[i] * dw[r, j]) / F - w[i] * w[j] * dFr / (F * F)


@njit(cache=True)
def augmented_filter(y, scale, T, Qc, Z, H, P0, lev, dT, dQc, dH, dP0, a_out, P_out, grad):
    r"""Diffuse log-likelihood of ``y * scale`` by the augmented Kalman filter.

    The states ``lev, ..., k-1`` (level, block-mean level, slope) are diffuse: the state is
    :math:`\\alpha_t = \\alpha^*_t + A_t\\delta`, :math:`\\delta` the diffuse initial values, and one
    ordinary Kalman filter (initial covariance ``P0``, zero on the diffuse block) runs on the data
    column and the d columns of :math:`A_t` together (de Jong 1991; Durbin & Koopman 2012,
    Sec. 5.7): with the innovation row :math:`w_t = (y_t, 0) - Z'A_t` and
    :math:`G = \\sum_t w_t' w_t/F_t = \\begin{pmatrix} q & s'\\\\ s & S\\end{pmatrix}`,

    .. math::

        \\log L_d = -\\tfrac12\\Big[n\\log 2\\pi + \\sum_t \\log F_t + q - s'S^{-1}s + \\log|S|\\Big],

    the same exact diffuse likelihood as :func:`diffuse_loglike` (Durbin & Koopman 2012, Sec. 5.7.4),
    but with a covariance that reaches its steady state also with a drift in the model (the
    slope's shrinking variance lives in :math:`S^{-1}`, not in :math:`P_t`). Same symmetry and
    steady-state rules as :func:`diffuse_loglike`. ``a_out``/``P_out`` receive the last filtered
    state :math:`a + A\\hat\\delta` and covariance :math:`P + A S^{-1} A'`. Returns NaN when a
    forecast variance falls below ``TOL_AUGMENTED`` (the caller then uses :func:`diffuse_loglike`).

    With ``p = dT.shape[0] > 0`` parameters (system-matrix derivatives ``dT, dQc, dH, dP0``) it
    also returns the score in ``grad``: the derivative recursions of :func:`diffuse_filter` for the
    covariance, gain and forecast variance, and for every column :math:`\dot A_{t+1} = \dot T A_{t|t}
    + T(\dot A + \dot K w' + K\dot w')`, :math:`\dot w = -Z'\dot A`,
    :math:`\dot G = \sum_t (\dot w w' + w\dot w')/F_t - ww'\dot F_t/F_t^2`; then
    :math:`\dot{(q - s'S^{-1}s)} = \dot q - 2x'\dot s + x'\dot Sx` (:math:`x = S^{-1}s`) and
    :math:`\dot{\log|S|} = \mathrm{tr}(S^{-1}\dot S)`. As in :func:`diffuse_filter` the
    derivatives run on after the covariance (and the diffuse columns) settle, until they settle
    themselves (same tests); from then on their sums are kept in closed form, as the likelihood's.
    """
    n = y.shape[0]
    k = T.shape[0]
    d = k - lev
    c = d + 1
    A = np.zeros((k, c))
    for j in range(d):
        A[lev + j, j + 1] = 1.0
    Af = np.empty((k, c))
    P = P0.copy()
    Pf = np.empty((k, k))
    Pprev = np.empty((k, k))
    tmp = np.empty((k, k))
    M = np.empty(k)
    Kf = np.empty(k)
    w = np.empty(c)
    G = np.zeros((c, c))
    Gss = np.zeros((c, c))  # sum of w w' over the steady-state steps (divided by Fc at the end)
    tp, ti, tl, tv = _sparse_rows(T)
    _, zi, zv = _nonzeros(Z)
    zn = zi.shape[0]
    p = dT.shape[0]
    dnz, drow, dcol, dval = _entries(dT)
    dA = np.zeros((p, k, c))
    dAf = np.empty((p, k, c))
    dP = dP0.copy()
    dPf = np.empty((p, k, k))
    dM = np.empty((p, k))
    dKf = np.empty((p, k))
    dF = np.empty(p)
    dw = np.empty((p, c))
    dG = np.zeros((p, c, c))
    dlogdet = np.zeros(p)
    tmp2 = np.empty((k, k))
    dsettled = p == 0  # the covariance derivatives (after the covariance itself)
    csettled = p == 0  # the diffuse columns' derivatives (after the columns themselves)
    logdet = 0.0
    converged = False
    Fc = 1.0
    t_conv = n
    t = 0
    while t < n and not converged:
        # phase 1: the covariance is still moving
        F = _forecast(P, Z, H, M)
        if not F > TOL_AUGMENTED:
            for r in range(p):
                grad[r] = np.nan
            return np.nan
        for i in range(k):
            Kf[i] = M[i] / F
        for r in range(p):
            dF[r] = _dforecast(dP, r, Z, dH[r], dM)
            for i in range(k):
                dKf[r, i] = (dM[r, i] - Kf[i] * dF[r]) / F
            _dinnovations(r, dA, dw, zi, zv, 0, c)
        _augmented_step(y[t] * scale, A, Af, Kf, w, zi, zv, tp, tl, tv)
        logdet += math.log(F)
        for i in range(c):
            for j in range(i + 1):
                G[i, j] += w[i] * w[j] / F
        for r in range(p):
            _dcolumns(r, dA, dAf, Af, w, dw, Kf, dKf, 0, c, tp, tl, tv, dnz, drow, dcol, dval)
            dlogdet[r] += dF[r] / F
            _dgram(r, dG, w, dw, dF[r], F, c)
        for i in range(k):
            for j in range(k):
                Pf[i, j] = P[i, j] - M[i] * Kf[j]
                Pprev[i, j] = P[i, j]
        for r in range(p):
            for i in range(k):
                for j in range(k):
                    dPf[r, i, j] = dP[r, i, j] - dM[r, i] * Kf[j] - M[i] * dKf[r, j]
        _predict(tp, ti, tl, tv, Pf, Qc, P, tmp)
        for r in range(p):
            _dpredict(tp, tl, tv, dnz, drow, dcol, dval, Pf, dPf, dQc, dP, r, tmp, tmp2)
        t += 1
        if t < n:
            if _sq_change(P, Pprev) < TOL_CONVERGED_AUGMENTED:
                # steady state: the next forecast's F and gain are those of this covariance
                converged = True
                t_conv = t
                Fc = _steady_gain(P, Z, H, M, Kf, Pf)
    Aprev = np.empty((k, c))
    fixed = False
    while t < n and not fixed:
        # phase 2: fixed gain; the diffuse columns still move (to their fixed point A = T (A - Kf Z'A))
        for i in range(k):
            for col in range(1, c):
                Aprev[i, col] = A[i, col]
        if not dsettled:
            _dsettle_gain(dP, dH, Z, dM, Kf, dKf, dF, Fc)
        for r in range(p):
            _dinnovations(r, dA, dw, zi, zv, 0, c)
        _augmented_step(y[t] * scale, A, Af, Kf, w, zi, zv, tp, tl, tv)
        for i in range(c):
            for j in range(i + 1):
                Gss[i, j] += w[i] * w[j]
        for r in range(p):
            _dcolumns(r, dA, dAf, Af, w, dw, Kf, dKf, 0, c, tp, tl, tv, dnz, drow, dcol, dval)
            dlogdet[r] += dF[r] / Fc
            _dgram(r, dG, w, dw, dF[r], Fc, c)
        if not dsettled:
            dsettled = _dsettle_step(tp, tl, tv, dnz, drow, dcol, dval, Pf, dPf, dQc, dP, M, Kf, dM, dKf,
                                     Pprev, tmp, tmp2) < TOL_CONVERGED_AUGMENTED
        t += 1
        ss = 0.0
        nn = 0.0
        for i in range(k):
            for col in range(1, c):
                dd = A[i, col] - Aprev[i, col]
                ss += dd * dd
                nn += A[i, col] * A[i, col]
        fixed = ss <= TOL_COLUMNS * nn
    # phase 3: the diffuse columns at their fixed point (their innovations w[1:] constant): only the
    # data column moves
    n_fixed = n - t
    w1 = np.empty(c)
    for col in range(1, c):
        acc = 0.0
        for e in range(zn):
            acc -= zv[e] * A[zi[e], col]
        w1[col] = acc
        if n_fixed > 0:  # (else Af already holds the last filtered columns)
            for i in range(k):
                Af[i, col] = A[i, col] + Kf[i] * acc
    a0 = A[:, :1].copy()  # the data column
    sw = 0.0
    sww = 0.0
    # derivatives in phase 3: per step while they settle, then sums over the remaining steps
    n_agg = 0
    s_v = 0.0
    s_vv = 0.0
    s_dv = np.zeros(p)
    s_vdv = np.zeros(p)
    wcur = w1.copy()
    dAprev = np.empty((k, c))
    while t < n:
        v = y[t] * scale
        for e in range(zn):
            v -= zv[e] * a0[zi[e], 0]
        sw += v
        sww += v * v
        for i in range(k):
            Af[i, 0] = a0[i, 0] + Kf[i] * v
        if p > 0:
            if dsettled and csettled:
                n_agg += 1
                s_v += v
                s_vv += v * v
                wcur[0] = v
                for r in range(p):
                    _dinnovations(r, dA, dw, zi, zv, 0, 1)
                    s_dv[r] += dw[r, 0]
                    s_vdv[r] += v * dw[r, 0]
                    _dcolumns(r, dA, dAf, Af, wcur, dw, Kf, dKf, 0, 1, tp, tl, tv, dnz, drow, dcol, dval)
            else:
                if not dsettled:
                    _dsettle_gain(dP, dH, Z, dM, Kf, dKf, dF, Fc)
                wcur[0] = v
                ss = 0.0
                nn = 0.0
                for r in range(p):
                    _dinnovations(r, dA, dw, zi, zv, 0, c)
                    for i in range(k):
                        for col in range(1, c):
                            dAprev[i, col] = dA[r, i, col]
                    _dcolumns(r, dA, dAf, Af, wcur, dw, Kf, dKf, 0, c, tp, tl, tv, dnz, drow, dcol, dval)
                    dlogdet[r] += dF[r] / Fc
                    _dgram(r, dG, wcur, dw, dF[r], Fc, c)
                    for i in range(k):
                        for col in range(1, c):
                            dd = dA[r, i, col] - dAprev[i, col]
                            ss += dd * dd
                            nn += dA[r, i, col] * dA[r, i, col]
                csettled = ss <= TOL_COLUMNS * nn
                if not dsettled:
                    dsettled = _dsettle_step(tp, tl, tv, dnz, drow, dcol, dval, Pf, dPf, dQc, dP, M, Kf, dM, dKf,
                                             Pprev, tmp, tmp2) < TOL_CONVERGED_AUGMENTED
        _csr_left(tp, tl, tv, Af[:, :1], a0)
        t += 1
    if n_agg > 0:
        # the derivatives' sums over the settled steps: only the data column's innovation moves
        for r in range(p):
            dlogdet[r] += n_agg * dF[r] / Fc
            dG[r, 0, 0] += 2.0 * s_vdv[r] / Fc - s_vv * dF[r] / (Fc * Fc)
            for i in range(1, c):
                dG[r, i, 0] += (dw[r, i] * s_v + w1[i] * s_dv[r]) / Fc - w1[i] * s_v * dF[r] / (Fc * Fc)
                for j in range(1, i + 1):
                    dG[r, i, j] += n_agg * ((dw[r, i] * w1[j] + w1[i] * dw[r, j]) / Fc
                                            - w1[i] * w1[j] * dF[r] / (Fc * Fc))
    if converged:
        logdet += (n - t_conv) * math.log(Fc)
        Gss[0, 0] += sww
        for i in range(1, c):
            Gss[i, 0] += w1[i] * sw
            for j in range(1, i + 1):
                Gss[i, j] += w1[i] * w1[j] * n_fixed
        for i in range(c):
            for j in range(i + 1):
                G[i, j] += Gss[i, j] / Fc
    for i in range(c):
        for j in range(i):
            G[j, i] = G[i, j]
    # Cholesky S = R R' of the d x d block, then q - s' S^-1 s = q - |R^-1 s|^2, log|S| = 2 sum log R_ii
    R = np.zeros((d, d))
    for i in range(d):
        for j in range(i + 1):
            acc = G[i + 1, j + 1]
            for l in range(j):
                acc -= R[i, l] * R[j, l]
            if i == j:
                if not acc > 0.0:
                    for r in range(p):
                        grad[r] = np.nan
                    return -np.inf
                R[i, i] = math.sqrt(acc)
            else:
                R[i, j] = acc / R[j, j]
    u = np.empty(d)
    for i in range(d):
        acc = G[i + 1, 0]
        for l in range(i):
            acc -= R[i, l] * u[l]
        u[i] = acc / R[i, i]
    quad = G[0, 0]
    logS = 0.0
    for i in range(d):
        quad -= u[i] * u[i]
        logS += 2.0 * math.log(R[i, i])
    # delta_hat = -S^-1 s (back substitution R' delta = -u); Sinv = R'^-1 R^-1
    dh = np.empty(d)
    for i in range(d - 1, -1, -1):
        acc = -u[i]
        for l in range(i + 1, d):
            acc -= R[l, i] * dh[l]
        dh[i] = acc / R[i, i]
    Rinv = np.zeros((d, d))
    for j in range(d):
        for i in range(j, d):
            acc = 1.0 if i == j else 0.0
            for l in range(j, i):
                acc -= R[i, l] * Rinv[l, j]
            Rinv[i, j] = acc / R[i, i]
    # the last filtered state: Af (before the final prediction) of every column
    for i in range(k):
        acc = Af[i, 0]
        for j in range(d):
            acc += Af[i, j + 1] * dh[j]
        a_out[i] = acc
    B = np.zeros((k, d))  # A S^-1 A' = B B' with B = A R'^-1 (A = Af[:, 1:])
    for i in range(k):
        for j in range(d):
            acc = 0.0
            for l in range(j + 1):
                acc += Af[i, l + 1] * Rinv[j, l]
            B[i, j] = acc
    for i in range(k):
        for j in range(k):
            acc = Pf[i, j]
            for l in range(d):
                acc += B[i, l] * B[j, l]
            P_out[i, j] = acc
    if p > 0:
        # x = S^-1 s = -delta_hat; S^-1 = Rinv' Rinv
        Sinv = np.zeros((d, d))
        for i in range(d):
            for j in range(d):
                acc = 0.0
                for l in range(d):
                    acc += Rinv[l, i] * Rinv[l, j]
                Sinv[i, j] = acc
        for r in range(p):
            for i in range(c):
                for j in range(i):
                    dG[r, j, i] = dG[r, i, j]
            dq = dG[r, 0, 0]
            for i in range(d):
                dq -= 2.0 * (-dh[i]) * dG[r, i + 1, 0]
                for j in range(d):
                    dq += dh[i] * dG[r, i + 1, j + 1] * dh[j]
            dls = 0.0
            for i in range(d):
                for j in range(d):
                    dls += Sinv[i, j] * dG[r, j + 1, i + 1]
            grad[r] = -0.5 * (dlogdet[r] + dq + dls)
    return -0.5 * (n * math.log(2.0 * math.pi) + logdet + quad + logS)


def augmented_loglike_py(y, scale, T, Qc, Z, H, P0, lev):
    """Plain-NumPy reference of :func:`augmented_loglike` (tests only): the same augmented filter
    without the steady-state shortcuts. Returns ``(loglike, a, P)`` (last filtered state and
    covariance, as ``a_out``/``P_out``)."""
    k = T.shape[0]
    d = k - lev
    A = np.zeros((k, d + 1))
    A[lev:, 1:] = np.eye(d)
    P = P0.copy()
    G = np.zeros((d + 1, d + 1))
    logdet = 0.0
    for yt in np.asarray(y, dtype=float) * scale:
        F = Z @ P @ Z + H
        Kf = P @ Z / F
        w = np.concatenate([[yt], np.zeros(d)]) - Z @ A
        G += np.outer(w, w) / F
        logdet += math.log(F)
        Af = A + np.outer(Kf, w)
        Pf = P - np.outer(Kf, P @ Z)
        A = T @ Af
        P = T @ Pf @ T.T + Qc
        P = (P + P.T) / 2
    q, s, S = G[0, 0], G[1:, 0], G[1:, 1:]
    dh = -np.linalg.solve(S, s)
    ll = -0.5 * (y.size * math.log(2 * math.pi) + logdet + q - s @ np.linalg.solve(S, s) + np.linalg.slogdet(S)[1])
    return ll, Af[:, 0] + Af[:, 1:] @ dh, Pf + Af[:, 1:] @ np.linalg.solve(S, Af[:, 1:].T)
