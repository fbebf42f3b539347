"""Sage-Husa adaptive Kalman filter of the Allan-variance coefficients (Miao et al. 2014).

State (Miao et al. 2014, eq 3.5): the modelled coefficients, a random walk
:math:`x_{k+1} = x_k + \\zeta_k`. Measurement (eqs 3.4, 3.7): the recursive Allan variance at the
sample time :math:`\\tau_0`,

.. math::

    z_k = \\frac{k-2}{k-1}\\delta_{k-1}^2 + \\frac{(\\bar w_k - \\bar w_{k-1})^2}{2(k-1)}
        = h(x_k) = \\frac{3Q^2}{\\tau_0^2} + \\frac{N^2}{\\tau_0} + \\frac{2\\ln2}{\\pi}B^2
          + \\frac{K^2\\tau_0}{3} + \\frac{R^2\\tau_0^2}{2},

with Jacobian :math:`H_k = \\partial h/\\partial x = [6Q/\\tau_0^2, 2N/\\tau_0, (4\\ln2/\\pi)B,
2K\\tau_0/3, R\\tau_0^2]` (all entries >= 0 for non-negative coefficients). Filter: eqs 3.8-3.19.

Reading of the paper (where it is ambiguous or wrong, and what is done here)
------------------------------------------------------------------------------
* eq 3.11 writes the innovation with :math:`H_k x_{k|k-1}`; for this non-linear ``h`` that is
  ``2 h(x)``, not the prediction. We use the extended-KF form :math:`h(x_{k|k-1})`; likewise
  :math:`h(x_k)` in eq 3.18. The innovation uses :math:`r_{k-1}` (``r_k`` is computed after it).
* eq 3.14 uses :math:`R_k`, which eq 3.19 only computes later: we use :math:`R_{k-1}`, so that
  :math:`D_k = H_k^T S_k^{-1}` with the innovation variance ``S_k`` of eq 3.10.
* eq 3.16 reads :math:`q_k = q_{k-1} + \\gamma_k Q_{k-1}\\varepsilon_k`, a matrix where a vector
  is needed; we read it as :math:`Q_{k-1} D_k \\varepsilon_k`, the form eq 3.17 implies.
* eqs 3.18-3.19 use :math:`\\gamma` without index: :math:`\\gamma_k` of eq 3.15, with ``k`` the
  cluster index of the AV recursion (the first measurement has ``k = 2``).
* The paper gives no values for ``b``, ``P0``, ``Q0``, ``R0``; the defaults here are ours.
* Identifiability. One scalar measurement cannot determine several coefficients: the filter moves
  the state only along ``H`` and ends near its initial value in the other directions (SPEC,
  "Identifiability"); an :class:`~avbench.estimators.base.IdentifiabilityWarning` is emitted when more
  than one coefficient is modelled. Worse, the measurement-noise mean ``r`` of eq 3.18 enters the
  measurement exactly as the bias-instability term does (a constant): once the gain is
  established, ``h(x) + r`` tracks the AV and the split between ``h(x)`` and ``r`` set in the
  first few samples is never corrected. Even a single-coefficient gyro is then biased (see the
  tests); ``adapt="qQR"`` (no ``r``) removes this. The default is the paper's ``"qQrR"``.
* Coefficients are reported as ``|x|`` (``h`` depends on ``x**2`` only).

The state is scaled internally (``s = x / x0``, measurement divided by ``h(x0)``), which leaves the
filter unchanged; ``P0``, ``Q0`` and ``R0`` are given in these scaled units (see
:mod:`avbench.estimators.online._common`).
"""

from __future__ import annotations

import numpy as np

from avbench.estimators.online._common import CLUSTER_SIZES, OnlineAVFilter, _matrix, _numbers
from avbench.estimators.settings import Check, Interval, Relation
from avbench.estimators.online._kernels import shakf_run
from avbench.estimators.base import register

__all__ = ["Shakf", "ShakfMultitau"]

_ADAPT_BITS = {"q": 1, "Q": 2, "r": 4, "R": 8}


def _adapt_flags(adapt) -> int:
    if not isinstance(adapt, str) or any(ch not in _ADAPT_BITS for ch in adapt) or len(set(adapt)) != len(adapt):
        raise ValueError(
            f"adapt: expected a string of distinct letters from 'qQrR' (the noise statistics the "
            f"Sage-Husa rules adapt, eqs 3.16-3.19), got {adapt!r}"
        )
    return sum(_ADAPT_BITS[ch] for ch in adapt)


def _check_r0(value) -> None:
    """R0 on its own: a finite number > 0, or a non-empty list of them (its length is checked against the
    cluster sizes by a relation of :class:`_ShakfBase`)."""
    r0 = _numbers(value)
    if r0.ndim > 1 or r0.size == 0 or not np.all(np.isfinite(r0)) or not np.all(r0 > 0):
        raise ValueError(f"expected a positive number or a list of them, got {value!r}")


class _ShakfBase(OnlineAVFilter):
    #: an adaptive filter's end point: last-bit differences of the kernels move it by ~1e-5 relative
    #: (Estimator.round_off_amplified)
    round_off_amplified = True

    parameter_constraints = {
        **OnlineAVFilter.parameter_constraints,
        "b": [Interval(float, 0, 1)],
        "R0": [Check(_check_r0, "a finite number > 0 or a list of them, one per cluster size (scaled units)")],
        "adapt": [Check(_adapt_flags, "a string of distinct letters from 'qQrR' (the noise statistics the "
                                      "Sage-Husa rules adapt, Miao et al. 2014, eqs 3.16-3.19)")],
    }

    def _r0_per_cluster_size(self) -> None:
        """A list ``R0`` has one value per cluster size."""
        nm = len(self._cluster_sizes())
        r0 = np.asarray(self.R0, dtype=float)
        if r0.ndim == 1 and r0.shape != (nm,):
            raise ValueError(f"R0: expected a positive number or {nm} positive numbers (one per cluster size), "
                             f"got {self.R0!r}")

    setting_relations = OnlineAVFilter.setting_relations + (
        Relation(("R0", "m"), _r0_per_cluster_size, "a list R0 has one value per cluster size"),)

    def _filter_settings(self, nq):
        return dict(
            b=float(self.b),
            adapt_flags=_adapt_flags(self.adapt),
            P0=_matrix("P0", self.P0, nq),
            Q0=_matrix("Q0", self.Q0, nq),
            R0=self.R0,
        )

    def _init_state(self, nq, nm, cfg):
        R0 = np.asarray(cfg["R0"], dtype=float)
        st = dict(
            s=np.ones(nq),
            P=cfg["P0"].copy(),
            q=np.zeros(nq),
            Q=cfg["Q0"].copy(),
            r=np.zeros(nm),
            R=np.broadcast_to(R0, (nm,)).astype(float).copy(),
        )
        return st

    def _scales(self):
        """The state's coefficient scales (a method, not a stored lambda: a fitted filter pickles)."""
        return self._state["s"]

    def _run_kernel(self, chunk, traj):
        st, av, cfg = self._state, self._av, self._cfg
        return shakf_run(
            chunk, self._zinv, self._A, av["m"], av["acc"], av["cnt"], av["prev"], av["kc"], av["av"],
            st["s"], st["P"], st["q"], st["Q"], st["r"], st["R"], cfg["b"], cfg["adapt_flags"],
            self._istate, cfg["every"], traj, cfg["pd_every"],
        )

    def _filter_diagnostics(self):
        st = self._state
        return {
            "q": st["q"].copy(),
            "Q_diag": np.diag(st["Q"]).copy(),
            "r": st["r"].copy(),
            "R": st["R"].copy(),
            "P_diag": np.diag(st["P"]).copy(),
            "avar": self._av["av"].copy(),
        }


@register("shakf")
class Shakf(_ShakfBase):
    """SHAKF estimator of Miao et al. 2014 (eqs 3.5-3.19) on the recursive AV at tau0.

    Parameters
    ----------
    terms : str
        Modelled coefficients (the state), a subset of ``"QNBKR"``.
    x0 : dict or None
        Initial coefficients, ``{coef: SI float or [value, "unit"]}`` for every modelled term;
        ``None``: from an AV fit on the first ``x0_samples`` samples (:mod:`avbench.estimators.online._common`).
    b : float
        Forgetting factor of eq 3.15, ``0 <= b <= 1`` (``b = 1``: ``gamma_k = 1/(k+1)``).
    P0, Q0 : float, sequence or matrix
        Initial state covariance and process-noise covariance in scaled units (relative to x0**2).
    R0 : float
        Initial measurement-noise variance, relative to ``h(x0)**2``.
    adapt : str
        Which noise statistics adapt: ``q`` (eq 3.16), ``Q`` (3.17), ``r`` (3.18), ``R`` (3.19).
    x0_samples : int
        Window of the default initial AV analysis.
    trajectory_every : int
        Keep the estimate every this many samples in the result's ``trajectory`` (default 1000:
        a decimated trajectory, so that the default run goes at the kernel's speed; 1: every
        sample, the full trajectory; 0: none).
    pd_check_every : int
        Cholesky test of ``P`` every this many samples (0: diagonal test only).

    Examples
    --------
    >>> import numpy as np
    >>> from avbench import estimators
    >>> rate = 1e-3 * np.random.default_rng(1).standard_normal(200_000)
    >>> est = estimators.get("shakf", terms="N", x0={"N": 5e-5}, adapt="qQR").fit(rate, 0.01)
    >>> bool(abs(est.coefficients_["N"] / 1e-4 - 1) < 0.01)
    True
    """

    def __init__(self, *, terms="QNBKR", x0=None, b=0.99, P0=0.25, Q0=1e-8, R0=1.0, adapt="qQrR",
                 x0_samples=65536, trajectory_every=1000, pd_check_every=1024):
        self.terms = terms
        self.x0 = x0
        self.b = b
        self.P0 = P0
        self.Q0 = Q0
        self.R0 = R0
        self.adapt = adapt
        self.x0_samples = x0_samples
        self.trajectory_every = trajectory_every
        self.pd_check_every = pd_check_every


@register("shakf_multitau")
class ShakfMultitau(_ShakfBase):
    """Extension: SHAKF with a vector measurement, the recursive AVs at cluster sizes ``m``.

    Not in Miao et al. 2014. Each cluster size contributes a measurement
    :math:`z_j = \\delta_k^2(m_j)` whenever a cluster of ``m_j`` samples completes, with
    :math:`h_j(x) = \\sum_c \\beta_c(x)\\,(m_j\\tau_0)^{p_c}`; the components are processed as
    sequential scalar updates (diagonal measurement noise, one ``r_j``, ``R_j`` each), so that
    ``m = [1]`` is exactly :class:`Shakf`. With several cluster sizes the coefficients become
    identifiable. ``m``: number of octaves (``1, 2, ..., 2**(m-1)``) or a list of cluster sizes.
    The default ``adapt="qQR"`` drops the measurement-mean estimate ``r`` (eq 3.18), which would
    give every component its own free offset and make the coefficients unidentifiable again.
    Other settings as :class:`Shakf`.
    """

    _multitau = True

    parameter_constraints = {**_ShakfBase.parameter_constraints, "m": CLUSTER_SIZES}

    def __init__(self, *, terms="QNBKR", x0=None, m=17, b=0.99, P0=0.25, Q0=1e-8, R0=1.0, adapt="qQR",
                 x0_samples=65536, trajectory_every=1000, pd_check_every=1024):
        self.terms = terms
        self.x0 = x0
        self.m = m
        self.b = b
        self.P0 = P0
        self.Q0 = Q0
        self.R0 = R0
        self.adapt = adapt
        self.x0_samples = x0_samples
        self.trajectory_every = trajectory_every
        self.pd_check_every = pd_check_every
