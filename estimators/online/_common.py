"""What the online filters share: settings, scaling, initial values, streaming and results.

The filters (:mod:`avbench.estimators.online.shakf`, :mod:`avbench.estimators.online.nekf`) differ only in the compiled
recursion they run and in the state they carry; this base class does everything else.

Scaled units
------------
In SI the coefficients are tiny (N ~ 1e-4 rad/s^0.5, K ~ 1e-7 rad/s^1.5) and the measurement,
an Allan variance, is ~1e-6 rad^2/s^2: a covariance matrix in those units spans twenty decades.
The kernels therefore work with the dimensionless state ``s_c = c / c_ref`` (``c_ref`` = the initial
coefficient ``x0``) and the measurement ``z_j / h_j(c_ref)``. A Kalman filter, and the Sage-Husa
adaptation rules, are covariant under such fixed linear rescalings of state and measurement, so
this is the papers' filter exactly, with the tuning (``P0``, ``Q0``, ``R0``) expressed in the
scaled units: ``P0 = 0.25`` means an initial standard deviation of 50 % of each initial
coefficient, ``R0 = 1`` a measurement standard deviation equal to the initial model AV.

Initial values
--------------
Both papers start from a prior Allan-variance analysis. With ``x0=None`` the filters do the same
on the first ``x0_samples`` samples only (so that the method stays online): the overlapping
octave AV of that window, a relative non-negative least-squares fit of the AV model
(``scipy.optimize.nnls`` on rows divided by the AV value, clusters with J >= 8), and a floor for
the terms the window cannot see: ``beta_c >= 0.05 * min_tau(AV(tau) / tau^p_c)``, i.e. an undetected
term starts where it would contribute 5 % of the measured AV at the tau where it is most visible
(a zero start would never move: the Jacobian of ``c^2`` vanishes at 0). The filter then starts at
sample 0 of the buffered window; until the window is full (streaming use), the current
coefficients are NaN. Given ``x0``, the filter starts at once.

Streaming
---------
``partial_fit(chunk, dt)`` feeds a chunk; all recursions carry their state across chunks, so
``fit(record)`` equals feeding the same record chunk by chunk bit for bit. Memory is constant in
the record length except for the trajectory (``trajectory_every`` samples per row, default 1000;
1 = every sample, the full trajectory; 0 = none).

Divergence
----------
A non-finite state, a non-positive innovation variance, a non-positive adaptive measurement
variance, a covariance ``P`` that is not positive definite (diagonal every sample, Cholesky every
``pd_check_every`` samples), or an adaptive ``Q`` with a negative diagonal stops the filter at
that sample. The coefficients are NaN; the result's ``failure`` names the reason and the sample
index, ``extras_["last_good"]`` holds the estimate before the failing sample, and a
:class:`~avbench.estimators.base.DivergenceWarning` is emitted. Later chunks are ignored.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from avbench.estimators.online._kernels import FAILURES
from avbench.estimators.results import FitParts
from avbench.estimators.settings import Check, Coefficients, Interval, NoneValue, Relation, Terms, validate_settings
from avbench.estimators.allan.model import BETA_SCALE, TAU_POWER, design_matrix
from avbench.estimators.validation import check_terms
from avbench.estimators.base import (
    DivergenceWarning,
    Estimator,
    IdentifiabilityWarning,
    coefficient_series,
)
from avbench.noise_models.units import as_si

__all__ = ["OnlineAVFilter", "initial_guess", "octave_m"]

#: the floor of an undetected term's initial AV share (see the module docstring)
_FLOOR_SHARE = 0.05


def octave_m(n_octaves: int) -> np.ndarray:
    """Cluster sizes ``1, 2, 4, ..., 2**(n_octaves-1)``."""
    return 2 ** np.arange(int(n_octaves), dtype=np.int64)


def initial_guess(rate, dt, terms) -> dict[str, float]:
    """Initial coefficients (SI) from an AV analysis of ``rate`` (see the module docstring).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> c = initial_guess(1e-3 * rng.standard_normal(2**14), 0.01, "N")
    >>> bool(abs(c["N"] / (1e-3 * 0.1) - 1) < 0.05)
    True
    """
    from scipy.optimize import nnls

    from avbench.estimators.allan.variance import allan_variance

    terms = check_terms(terms)
    res = allan_variance(rate, dt, taus="octave", overlapping=True)
    keep = (res.J >= 8) & (res.avar > 0)
    if not keep.any():
        keep = res.avar > 0
    tau, av = res.tau[keep], res.avar[keep]
    X = design_matrix(tau, terms) / av[:, None]
    beta, _ = nnls(X, np.ones(len(tau)))
    out = {}
    for c, b in zip(terms, beta):
        floor = _FLOOR_SHARE * float(np.min(av / tau ** TAU_POWER[c]))
        out[c] = math.sqrt(max(b, floor) / BETA_SCALE[c])
    return out


def _numbers(value) -> np.ndarray:
    """``value`` (a number or nested lists of numbers; no strings, no booleans) as a float array."""
    if isinstance(value, str | bool | np.bool_) or any(isinstance(v, str | bool | np.bool_) for v in np.ravel(
            np.asarray(value, dtype=object))):
        raise ValueError(f"expected numbers, got {value!r}")
    return np.asarray(value, dtype=float)


def check_covariance(value) -> None:
    """A covariance setting on its own: a number >= 0 (times I), a non-empty list of diagonal values
    >= 0, or a square, finite, symmetric, positive semi-definite matrix (its size is checked against
    the modelled terms by :func:`_matrix`)."""
    a = _numbers(value)
    if a.ndim > 2 or a.size == 0 or (a.ndim == 2 and a.shape[0] != a.shape[1]):
        raise ValueError(f"expected a number, a list of diagonal values or a square matrix, got shape {a.shape}")
    full = np.diag(a) if a.ndim == 1 else a.reshape(1, 1) if a.ndim == 0 else a
    if not np.all(np.isfinite(full)) or not np.allclose(full, full.T) or np.any(np.linalg.eigvalsh(full) < 0):
        raise ValueError("expected a finite, symmetric, positive semi-definite covariance")


#: the declared constraint of the covariance settings P0, Q0
COVARIANCE = Check(check_covariance, "a number >= 0, a list of diagonal values >= 0 or a symmetric positive "
                                     "semi-definite matrix (scaled units)", explain=True)


def check_cluster_sizes(value) -> None:
    """A list of distinct cluster sizes, each an integer >= 1."""
    arr = np.asarray(value) if isinstance(value, list | tuple | np.ndarray) else None
    if arr is None or arr.ndim != 1 or arr.size == 0 or arr.dtype.kind not in "iu" or np.any(arr < 1):
        raise ValueError(f"expected a non-empty list of positive integer cluster sizes, got {value!r}")
    if len(np.unique(arr)) != arr.size:
        raise ValueError(f"cluster sizes must be distinct, got {value!r}")


#: the declared constraints of ``m``, the cluster sizes of the filters with several (``_multitau``): a
#: number of octaves or a list of cluster sizes
CLUSTER_SIZES = [Interval(int, 1, None),
                 Check(check_cluster_sizes, "a list of distinct positive integer cluster sizes", explain=True)]


def _matrix(name, value, n) -> np.ndarray:
    """A covariance setting (declared :data:`COVARIANCE`) for ``n`` states: a number times I, a
    length-n diagonal or an n x n matrix."""
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        a = np.eye(n) * float(a)
    elif a.ndim == 1 and a.shape == (n,):
        a = np.diag(a)
    elif a.shape != (n, n):
        raise ValueError(f"{name}: expected a number, a length-{n} diagonal or an {n}x{n} matrix, got shape {a.shape}")
    return np.ascontiguousarray(a)


def _positive(name, value, *, integer=False, allow_zero=False):
    """``value`` if it is a finite number (an integer with ``integer=True``) > 0 (>= 0 with
    ``allow_zero=True``), as a float (int); else a ValueError naming ``name``."""
    ok = isinstance(value, int | np.integer) if integer else isinstance(value, int | float | np.number)
    if isinstance(value, bool) or not ok or not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        kind = "integer" if integer else "number"
        sign = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name}: expected a finite {kind} {sign}, got {value!r}")
    return int(value) if integer else float(value)


def x0_gives_the_terms(x0, terms) -> None:
    """``x0`` (None, or a mapping) names exactly the modelled ``terms``; a ValueError naming x0 otherwise."""
    if x0 is None:
        return
    missing = [c for c in terms if c not in x0]
    extra = [c for c in x0 if c not in terms]
    if missing or extra:
        raise ValueError(f"x0: expected exactly the modelled terms {''.join(terms)}, "
                         f"missing {missing or 'none'}, extra {extra or 'none'}")


def _published(name: str) -> property:
    """A result attribute of an online filter, built from the filter's state when first read after
    a ``partial_fit`` (its pandas Series and diagnostics are not rebuilt for every chunk: a stream
    that never reads them between chunks does not even import pandas)."""

    def get(self):
        if self.__dict__.get("_stale"):
            self._stale = False
            self._publish()
        try:
            return self.__dict__["_published_" + name]
        except KeyError:
            raise AttributeError(name) from None

    def set(self, value):
        self.__dict__["_published_" + name] = value

    return property(get, set, doc=f"``{name}`` (see :class:`avbench.estimators.base.Estimator`)")


class OnlineAVFilter(Estimator):
    """Base of the online filters: subclasses set ``_multitau`` and implement the kernel hooks."""

    online = True
    _multitau = False

    #: the settings every filter has (a subclass adds its own)
    parameter_constraints = {
        "terms": [Terms()],
        "x0": [NoneValue(), Coefficients(positive=True)],
        "P0": [COVARIANCE],
        "Q0": [COVARIANCE],
        "x0_samples": [Interval(int, 1, None)],
        "trajectory_every": [Interval(int, 0, None)],
        "pd_check_every": [Interval(int, 0, None)],
    }
    #: the relations between settings: ``x0`` gives exactly the modelled ``terms``, and ``P0``, ``Q0`` have
    #: their sizes (a filter adds its own per-state or per-cluster-size settings)
    setting_relations = (
        Relation(("x0", "terms"), lambda est: x0_gives_the_terms(est.x0, check_terms(est.terms)),
                 "x0 gives exactly the modelled terms"),
        Relation(("P0", "Q0", "terms"), lambda est: [_matrix(k, getattr(est, k), len(check_terms(est.terms)))
                                                     for k in ("P0", "Q0")],
                 "P0 and Q0 have one row per modelled term"),
    )
    coefficients_ = _published("coefficients_")
    nonphysical_ = _published("nonphysical_")
    std_err_ = _published("std_err_")
    extras_ = _published("extras_")
    parts_ = _published("parts_")

    # -- hooks for subclasses ------------------------------------------------------------------
    def _filter_settings(self, nq: int) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError

    def _init_state(self, nq: int, nm: int, cfg: dict) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError

    def _run_kernel(self, chunk, traj) -> int:  # pragma: no cover - abstract
        raise NotImplementedError

    def _filter_diagnostics(self) -> dict:
        return {}

    # -- settings ------------------------------------------------------------------------------
    def _cluster_sizes(self) -> np.ndarray:
        if not self._multitau:
            return np.array([1], dtype=np.int64)
        m = self.m
        if isinstance(m, int | np.integer):
            return octave_m(int(m))
        return np.sort(np.asarray(m)).astype(np.int64)

    def _validate(self, dt: float) -> dict:
        # partial_fit starts here without Estimator.fit: the declared settings are checked here too
        validate_settings(type(self), self.get_params())
        terms = check_terms(self.terms)
        nq = len(terms)
        x0 = None if self.x0 is None else {c: as_si(c, self.x0[c]) for c in terms}
        m = self._cluster_sizes()
        cfg = dict(
            terms=terms,
            x0=x0,
            m=m,
            x0_samples=int(self.x0_samples),
            every=int(self.trajectory_every),
            pd_every=int(self.pd_check_every),
        )
        cfg.update(self._filter_settings(nq))
        if nq > len(m):
            what = "the single tau0 recursive AV" if len(m) == 1 else f"{len(m)} recursive AVs"
            warnings.warn(
                f"{self.name}: {nq} coefficients ({''.join(terms)}) from {what}: the data cannot "
                "determine them separately; the estimates depend on the initial values x0",
                IdentifiabilityWarning,
                stacklevel=4,
            )
        return cfg

    # -- streaming -----------------------------------------------------------------------------
    def _reset(self, dt: float) -> None:
        self._cfg = self._validate(dt)
        self._dt = dt
        self._buffer: list[np.ndarray] = []
        self._buffered = 0
        self._started = False
        self._traj: list[np.ndarray] = []
        self._x0_si = None
        self._n_seen = 0
        self._warned = False

    def _start(self, x0: dict) -> None:
        cfg = self._cfg
        terms, m = cfg["terms"], cfg["m"]
        c_ref = np.array([x0[c] for c in terms])
        tau = m * self._dt
        contrib = np.column_stack(
            [BETA_SCALE[c] * x0[c] ** 2 * tau ** TAU_POWER[c] for c in terms]
        )  # (nm, nq) SI AV contributions at c_ref
        href = contrib.sum(axis=1)
        if not np.all(np.isfinite(href) & (href > 0)):
            raise ValueError(
                f"x0: the initial coefficients {dict(x0)} give a model Allan variance of {href.tolist()} at "
                "the measured tau, not a positive float64 number (x0 far outside the scale of the data?); "
                "expected starting values of the order of the data's coefficients"
            )
        self._x0_si = dict(x0)
        self._c_ref = c_ref
        self._zinv = 1.0 / href
        self._A = np.ascontiguousarray(contrib / href[:, None])
        nm = len(m)
        self._av = dict(
            m=m,
            acc=np.zeros(nm),
            cnt=np.zeros(nm, dtype=np.int64),
            prev=np.zeros(nm),
            kc=np.zeros(nm, dtype=np.int64),
            av=np.zeros(nm),
        )
        every = cfg["every"]
        self._istate = np.array([0, every if every > 0 else 1, 0, -1], dtype=np.int64)
        self._state = self._init_state(len(terms), nm, cfg)
        self._started = True

    def _process(self, chunk: np.ndarray) -> None:
        if self._istate[2] != 0 or chunk.size == 0:
            return
        every = self._cfg["every"]
        rows = (chunk.size // every + 2) if every > 0 else 1
        traj = np.empty((rows, len(self._cfg["terms"]) + 1))
        nt = self._run_kernel(np.ascontiguousarray(chunk, dtype=np.float64), traj)
        if every > 0 and nt:
            self._traj.append(traj[:nt].copy())

    def _feed(self, chunk: np.ndarray) -> None:
        self._n_seen += chunk.size
        if self._started:
            self._process(chunk)
            return
        if self._cfg["x0"] is not None:
            self._start(self._cfg["x0"])
            self._process(chunk)
            return
        self._buffer.append(chunk.copy())
        self._buffered += chunk.size
        if self._buffered >= self._cfg["x0_samples"]:
            self.flush()

    def flush(self) -> "OnlineAVFilter":
        """Start the filter on the buffered samples if it is still waiting for its x0 window.

        Only needed in streaming use with ``x0=None`` when the record ends before
        ``x0_samples`` samples; ``fit`` calls it.
        """
        if not self._started and self._buffer:
            data = np.concatenate(self._buffer)
            self._buffer, self._buffered = [], 0
            head = data[: self._cfg["x0_samples"]]
            if head.size < 16:
                return self
            self._start(initial_guess(head, self._dt, self._cfg["terms"]))
            self._process(data)
        self._stale = False
        self._publish()
        return self

    def partial_fit(self, chunk, dt) -> "OnlineAVFilter":
        """Feed the next ``chunk`` of a record (rad/s, sample interval ``dt``); returns ``self``.

        The first call (re)starts the filter with the current settings; later calls must use the
        same ``dt``. After each call ``coefficients_`` holds the current estimate.
        """
        dt = _positive("dt", dt)
        arr = np.asarray(chunk)
        if arr.dtype.kind not in "iuf" or arr.ndim != 1:
            raise ValueError(f"chunk: expected a 1-D numeric array of rate samples, got {arr.dtype} {arr.shape}")
        arr = arr.astype(np.float64, copy=False)
        if not np.all(np.isfinite(arr)):
            first = int(np.flatnonzero(~np.isfinite(arr))[0])
            raise ValueError(f"chunk: non-finite sample(s), the first at index {first} of the chunk")
        if not getattr(self, "_streaming", False):
            self._reset(dt)
            self._streaming = True
        elif dt != self._dt:
            raise ValueError(f"dt: expected the dt of the earlier chunks, {self._dt!r}, got {dt!r}")
        self._feed(arr)
        self._stale = True  # results are built when read (_published)
        self._warn_if_diverged(stacklevel=3)
        return self

    def current_coefficients(self) -> pd.Series:
        """The current estimate (SI, Series indexed Q..R; NaN before the filter has started)."""
        return self._estimate()[0]

    # -- results -------------------------------------------------------------------------------
    def _estimate(self):
        terms = self._cfg["terms"]
        if not self._started:
            return coefficient_series(), ""
        s = np.abs(self._scales())
        vals = {c: float(v) for c, v in zip(terms, s * self._c_ref)}
        code = int(self._istate[2])
        if code:
            msg = f"sample {int(self._istate[3])}: {FAILURES[code]}"
            return coefficient_series(), msg
        return coefficient_series(vals), ""

    def _trajectory(self) -> pd.DataFrame:
        import pandas as pd

        terms = list(self._cfg["terms"])
        if not self._traj:
            return pd.DataFrame(columns=terms, index=pd.Index([], name="sample", dtype=np.int64))
        t = np.concatenate(self._traj)
        df = pd.DataFrame(t[:, :-1] * self._c_ref, columns=terms)
        df.index = pd.Index(t[:, -1].astype(np.int64), name="sample")
        return df

    def _publish(self) -> None:
        coefs, failure = self._estimate()
        traj = self._trajectory() if self._cfg["every"] > 0 else None
        diag = {
            "n_samples": self._n_seen,
            "x0": None if self._x0_si is None else coefficient_series(self._x0_si),
            "cluster_sizes": self._cfg["m"].tolist(),
        }
        if self._started:
            if failure:
                last = np.abs(self._scales()) * self._c_ref
                diag["last_good"] = coefficient_series(dict(zip(self._cfg["terms"], last)))
            diag.update(self._filter_diagnostics())
        self._set_results(coefs.to_dict(), None, diag, FitParts(failure=failure, trajectory=traj))
        self._warn_if_diverged(stacklevel=5)

    def _warn_if_diverged(self, stacklevel=4) -> None:
        """One DivergenceWarning, at the chunk where the kernel reported a failure."""
        if not getattr(self, "_started", False) or getattr(self, "_warned", False):
            return
        code = int(self._istate[2])
        if code:
            self._warned = True
            failure = f"sample {int(self._istate[3])}: {FAILURES[code]}"
            warnings.warn(f"{self.name}: diverged at {failure}", DivergenceWarning, stacklevel=stacklevel)

    def _fit(self, rate, dt):
        self._streaming = False
        self._reset(dt)
        self._feed(rate)
        self.flush()
        return self.coefficients_.to_dict(), None, self.extras_, self.parts_
