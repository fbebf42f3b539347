"""GMWM's trust-region reflective solver (``estimators/likelihood/_trf.py``) is scipy's ``least_squares``
(method "trf", bounds, ``x_scale`` 1) step for step: the same operations on the same operands, so every field
of the result -- end point, cost, residuals, Jacobian, evaluation counts, stopping rule -- must equal scipy's bit
for bit, on any problem, on the kernels this process runs on and (in a fresh process) on the kernels the
committed studies were computed with (``test_regeneration.REFERENCE_KERNELS``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import least_squares

from scipy.linalg import cho_factor, solve_triangular

from avbench.estimators.likelihood._trf import TERMINATION_MESSAGES, lower_triangular_solver, resume_trf, trf_bounds

TOLERANCES = dict(xtol=1e-15, ftol=1e-15, gtol=1e-15)


def problem(seed: int):
    """A bounded problem shaped like GMWM's: a curve on 17 log-spaced scales fitted by a sum of
    ``exp(2 u_i)`` times per-term shapes, one of them with a shape parameter (a Gauss-Markov-like bump
    whose position is ``exp(u)``), noisy data, a box on the log-parameters, a start inside it."""
    rng = np.random.default_rng(seed)
    tau = np.geomspace(0.1, 1e4, 17)
    k = int(rng.integers(1, 4))  # power-law terms
    slopes = rng.choice([-2.0, -1.0, 0.0, 1.0, 2.0], size=k, replace=False)
    truth = np.r_[rng.normal(0, 2, k), rng.normal(0, 1), rng.uniform(0, 6)]

    def model(u):
        amp = np.exp(2 * u[:k])[None, :] * tau[:, None] ** slopes[None, :]
        tc = np.exp(u[k + 1])
        bump = np.exp(2 * u[k]) * (tau / tc) ** 2 / (1 + (tau / tc) ** 2) ** 1.5
        return amp.sum(axis=1) + bump

    def jac(u):
        J = np.empty((tau.size, u.size))
        J[:, :k] = 2 * np.exp(2 * u[:k])[None, :] * tau[:, None] ** slopes[None, :]
        tc = np.exp(u[k + 1])
        r = (tau / tc) ** 2
        shape = r / (1 + r) ** 1.5
        J[:, k] = 2 * np.exp(2 * u[k]) * shape
        d_shape_d_lnr = shape * (1 - 1.5 * r / (1 + r))
        J[:, k + 1] = np.exp(2 * u[k]) * d_shape_d_lnr * -2.0
        return J / y[:, None]

    y = model(truth) * np.exp(rng.normal(0, 0.05 * rng.uniform(0.1, 3), tau.size))
    n = truth.size
    lo = truth - rng.uniform(0.5, 8, n)
    hi = truth + rng.uniform(0.5, 8, n)
    x0 = np.clip(truth + rng.normal(0, 3, n), lo + 1e-9, hi - 1e-9)
    return (lambda u: model(u) / y - 1.0), jac, x0, lo, hi


def both(seed: int, max_nfev: int = 2000):
    fun, jac, x0, lo, hi = problem(seed)
    ours = trf_bounds(fun, jac, x0, lo, hi, max_nfev=max_nfev, **TOLERANCES)
    theirs = least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf", x_scale=1.0, max_nfev=max_nfev,
                           **TOLERANCES)
    return ours, theirs


FIELDS = ("x", "cost", "fun", "jac", "grad", "optimality", "active_mask", "nfev", "njev", "status", "message",
          "success")


def _differing(ours, theirs) -> list[str]:
    return [f for f in FIELDS if not np.array_equal(np.asarray(ours[f]), np.asarray(theirs[f]))]


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_every_field_is_scipys(seed):
    ours, theirs = both(seed)
    assert set(ours) >= set(FIELDS)
    assert not _differing(ours, theirs), f"fields differing from scipy's least_squares: {_differing(ours, theirs)}"
    assert ours.message == TERMINATION_MESSAGES[ours.status]


def test_a_short_budget_stops_as_scipys():
    ours, theirs = both(3, max_nfev=5)
    assert ours.status == theirs.status == 0 and ours.nfev == theirs.nfev == 5
    assert ours.message == theirs.message and not ours.success


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), short=st.integers(2, 60))
def test_a_resumed_run_is_the_long_run_bit_for_bit(seed, short):
    """A run stopped by a short budget and resumed to a longer one ends where the one long run ends, every field
    equal (and the stopped run is left as it was)."""
    fun, jac, x0, lo, hi = problem(seed)
    long = trf_bounds(fun, jac, x0, lo, hi, max_nfev=400, **TOLERANCES)
    first = trf_bounds(fun, jac, x0, lo, hi, max_nfev=short, **TOLERANCES)
    if first.status != 0:
        assert not _differing(first, long)
        return
    x_first = first.x.copy()
    resumed = resume_trf(first, 400)
    assert not _differing(resumed, long), _differing(resumed, long)
    assert np.array_equal(first.x, x_first) and first.nfev == short


def test_only_a_run_stopped_by_its_budget_resumes():
    fun, jac, x0, lo, hi = problem(1)
    done = trf_bounds(fun, jac, x0, lo, hi, max_nfev=2000, **TOLERANCES)
    assert done.status != 0
    with pytest.raises(ValueError, match="status 0"):
        resume_trf(done, 4000)


def test_bit_for_bit_on_the_reference_kernels():
    """A fresh process on the committed studies' kernels: scipy's result, every field, on 200 problems."""
    from tests.test_regeneration import REFERENCE_KERNELS, _reference_kernels_run_here

    if not _reference_kernels_run_here():
        pytest.skip("the reference kernels (x86-64 with AVX2) do not run on this machine")
    code = ("import json, sys; from tests.test_trf import both, _differing; "
            "print(json.dumps({s: _differing(*both(s)) for s in range(200)}))")
    done = subprocess.run([sys.executable, "-c", code], env={**os.environ, **REFERENCE_KERNELS},
                          capture_output=True, text=True, cwd=os.path.dirname(os.path.dirname(__file__)))
    assert done.returncode == 0, done.stderr[-3000:]
    differ = {s: f for s, f in json.loads(done.stdout.strip().splitlines()[-1]).items() if f}
    assert not differ, f"fields differing from scipy's least_squares (seed: fields): {differ}"


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), size=st.integers(1, 24), columns=st.integers(0, 6),
       fortran=st.booleans())
def test_the_whitening_is_solve_triangulars(seed, size, columns, fortran):
    """GMWM's whitening: the Cholesky factor of a covariance (as the second step builds it), a vector or a
    Jacobian on the right: solve_triangular's bits."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(size, size + 3))
    L = np.tril(cho_factor(a @ a.T + 1e-3 * np.eye(size), lower=True)[0])
    L = np.asfortranarray(L) if fortran else L
    b = rng.normal(size=(size, columns) if columns else size) * np.exp(rng.normal(0, 5))
    assert np.array_equal(lower_triangular_solver(L)(b), solve_triangular(L, b, lower=True))


@pytest.mark.parametrize("bad, match", [
    (dict(x0=np.array([5.0, 0.0])), "x0 is infeasible"),
    (dict(lo=np.array([0.0, -1.0, 2.0])), "three vectors of one length"),
    (dict(hi=np.array([-2.0, 1.0])), "finite bounds with lb < ub"),
    (dict(lo=np.array([-np.inf, -1.0])), "finite bounds with lb < ub"),
])
def test_bad_input_is_named(bad, match):
    args = {**dict(x0=np.zeros(2), lo=np.array([-1.0, -1.0]), hi=np.array([1.0, 1.0])), **bad}
    with pytest.raises(ValueError, match=match):
        trf_bounds(lambda u: u - 0.5, lambda u: np.eye(2), args["x0"], args["lo"], args["hi"])


def test_residuals_not_finite_at_the_start_are_refused():
    with pytest.raises(ValueError, match="not finite in the initial point"), np.errstate(divide="ignore"):
        trf_bounds(lambda u: np.log(u), lambda u: np.diag(1 / u), np.array([0.0, 1.0]), np.array([-1.0, -1.0]),
                   np.array([2.0, 2.0]))
