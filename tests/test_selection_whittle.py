"""The model-choice components the Whittle estimators use (avbench.estimators.selection): the
chi-bar-squared evidence, the boundary-aware profile-likelihood interval, the domain switch,
backward elimination and the choice between non-nested models; each against a closed form."""

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy import special, stats

from avbench.estimators.selection.elimination import (PENALTY, SLOPE_PENALTY, backward_elimination,
                                                      choose_by_criterion, penalised, wald_drop_candidates)
from avbench.estimators.selection.evidence import (CHI2_CRITICAL_5, CHIBAR2_CRITICAL_5, chibar2_pvalue, present,
                                                   two_sided_pvalue)
from avbench.estimators.selection.profile import (NEGATIVE_Z, RunningMax, likelihood_root, profile_interval,
                                                  profile_start, steeper_negative_neighbours)

Q95 = float(stats.chi2.ppf(0.95, 1))


# -- evidence ------------------------------------------------------------------------------------
@pytest.mark.parametrize("t", [1e-6, 0.1, 1.0, 2.705543454095404, 3.84, 10.0, 50.0])
def test_chibar2_pvalue_is_the_tail_of_the_boundary_mixture(t):
    """P(T >= t) for T ~ 1/2 chi2_0 + 1/2 chi2_1: the LR of a normal mean constrained to >= 0,
    T = max(Z, 0)^2, whose tail is P(Z >= sqrt t) (Self & Liang 1987, Case 5)."""
    assert chibar2_pvalue(t) == pytest.approx(stats.norm.sf(math.sqrt(t)), rel=1e-10)
    mixture_cdf = 0.5 + 0.5 * stats.chi2.cdf(t, 1)  # the chi2_0 half is a point mass at 0
    assert chibar2_pvalue(t) == pytest.approx(1 - mixture_cdf, rel=1e-9)


@given(st.floats(min_value=0.0, max_value=200.0))
@settings(max_examples=50, deadline=None)
def test_chibar2_pvalue_is_half_the_chi2_tail(lr):
    p = chibar2_pvalue(lr)
    if lr == 0:
        assert p == 1.0
    else:
        assert p == pytest.approx(0.5 * stats.chi2.sf(lr, 1), rel=1e-12, abs=1e-300)
        assert 0 <= p <= 0.5


def test_chibar2_pvalue_at_and_below_zero_and_not_finite():
    assert chibar2_pvalue(0.0) == 1.0 and chibar2_pvalue(-1e-12) == 1.0
    assert math.isnan(chibar2_pvalue(math.nan)) and math.isnan(chibar2_pvalue(math.inf))


def test_chibar2_pvalues_are_uniform_under_the_boundary_null():
    """200 000 boundary LR statistics under the null: p <= alpha with probability alpha (within 4
    binomial standard errors) for alpha < 1/2, and p = 1 in half of them. The plain chi2_1 p-value
    would reject at half the level."""
    rng = np.random.default_rng(0)
    R = 200_000
    lr = np.maximum(rng.standard_normal(R), 0.0) ** 2
    p = np.array([chibar2_pvalue(v) for v in lr])
    for alpha in (0.01, 0.05, 0.2):
        assert abs(np.mean(p <= alpha) - alpha) < 4 * math.sqrt(alpha * (1 - alpha) / R), alpha
    assert abs(np.mean(p == 1.0) - 0.5) < 4 * math.sqrt(0.25 / R)


def test_critical_values_and_presence():
    assert chibar2_pvalue(CHIBAR2_CRITICAL_5) == pytest.approx(0.05, rel=1e-12)
    assert CHIBAR2_CRITICAL_5 == pytest.approx(stats.chi2.ppf(0.90, 1), rel=1e-14)
    assert two_sided_pvalue(CHI2_CRITICAL_5) == pytest.approx(0.05, rel=1e-12)
    assert list(present(np.array([0.01, 0.05, 0.2]))) == [True, False, False]


# -- the profile interval ------------------------------------------------------------------------
def _variance_component(m, mean_square):
    """x_i ~ N(0, 1 + a), a >= 0 (a variance above a known unit noise), m samples: the
    log-likelihood in u = log a, its maximum over a >= 0 and the log-likelihood at a = 0."""
    S = m * mean_square

    def ll(a):
        return -0.5 * m * math.log1p(a) - 0.5 * S / (1.0 + a)

    return ll, max(mean_square - 1.0, 0.0)


def _closed_form_bounds(m, v_hat, q):
    """The likelihood interval of v = 1 + a without the constraint: 2(l(v_hat) - l(v)) = m (r - 1 - log r)
    with r = v_hat / v, so r = -W_k(-exp(-(1 + q/m))) (Lambert W, branch 0: upper end, -1: lower)."""
    c = -math.exp(-(1.0 + q / m))
    r_up, r_lo = -special.lambertw(c, 0).real, -special.lambertw(c, -1).real
    return v_hat / r_lo - 1.0, v_hat / r_up - 1.0


def _run(m, mean_square, absent=False, at_zero=False, best=None, floor=1e-6):
    ll, a_hat = _variance_component(m, mean_square)
    u_hat = math.log(max(a_hat, floor))
    su = math.sqrt(2.0 / m) * (1.0 + a_hat) / max(a_hat, floor)  # Wald se of log a
    su = min(max(su, 0.05), 5.0)
    best = RunningMax(ll(a_hat) if best is None else best)
    iv = profile_interval(lambda u: ll(math.exp(u)), u_hat, su, ll(0.0), best, Q95, absent=absent, at_zero=at_zero)
    return iv, ll, a_hat


def _root_at(ll, top, bound):
    """The signed likelihood root at a bound, relative to the maximum ``top``."""
    return math.sqrt(max(2 * (top - ll(bound)), 0.0))


def test_profile_interval_of_a_resolved_variance_is_the_likelihood_interval():
    m, ms = 200, 1.5
    iv, ll, a_hat = _run(m, ms)
    lo, hi = _closed_form_bounds(m, ms, Q95)
    assert iv.lr == pytest.approx(2 * (ll(a_hat) - ll(0.0)), rel=1e-12) and iv.lr > Q95
    assert iv.p_value == chibar2_pvalue(iv.lr) and iv.lower_reason is None
    for got, want in ((iv.lower, lo), (iv.upper, hi)):
        assert abs(_root_at(ll, ll(a_hat), got) - math.sqrt(Q95)) < 0.0101  # the search's tolerance
        assert got == pytest.approx(want, rel=0.03)
    assert iv.lower < a_hat < iv.upper


def test_profile_interval_of_a_weak_variance_reaches_zero():
    """The likelihood ratio of dropping the term is within chi2_1(0.95): the interval is [0, upper]
    and the evidence that ratio, with its chi-bar-squared p-value."""
    m, ms = 200, 1.05
    iv, ll, a_hat = _run(m, ms)
    lr = 2 * (ll(a_hat) - ll(0.0))
    assert 0 < lr < Q95
    assert iv.lower == 0.0 and iv.lower_reason == "not significant"
    assert iv.lr == pytest.approx(lr, rel=1e-12) and iv.p_value == pytest.approx(0.5 * stats.chi2.sf(lr, 1))
    assert iv.upper == pytest.approx(_closed_form_bounds(m, ms, Q95)[1], rel=0.03)


def _boundary_upper(m, ms):
    """The upper end at an estimate on the boundary: 2(l(0) - l(a)) = chi2_1(0.95), by bisection."""
    from scipy.optimize import brentq

    ll, _ = _variance_component(m, ms)
    return brentq(lambda a: 2 * (ll(0.0) - ll(a)) - Q95, 1e-9, 100.0, xtol=1e-14)


def test_profile_interval_at_the_boundary():
    """Estimate on the boundary 0 (mean square below the known noise): [0, upper] with upper where
    the likelihood falls chi2_1(0.95)/2 below its value at 0, no evidence (LR 0, p = 1)."""
    m, ms = 200, 0.9
    iv, ll, a_hat = _run(m, ms, absent=True)
    assert a_hat == 0.0
    assert (iv.lower, iv.lr, iv.p_value, iv.lower_reason) == (0.0, 0.0, 1.0, "estimate at 0")
    assert abs(_root_at(ll, ll(0.0), iv.upper) - math.sqrt(Q95)) < 0.0101
    assert iv.upper == pytest.approx(_boundary_upper(m, ms), rel=0.03)


def test_profile_interval_below_zero_in_a_larger_domain_is_measured_from_zero():
    """``at_zero``: the maximum is over a domain where the variance may go below 0 (here 1 + a > 0)
    and lies below 0; the interval on a >= 0 is measured from the best profile value over a >= 0
    (at 0), not from that maximum: the same upper end as on the boundary, and no evidence."""
    m, ms = 200, 0.9
    ll, _ = _variance_component(m, ms)
    signed_max = ll(ms - 1.0)  # a = -0.1
    assert signed_max > ll(0.0)
    iv, _, _ = _run(m, ms, absent=True, at_zero=True, best=signed_max)
    assert (iv.lower, iv.lr, iv.p_value) == (0.0, 0.0, 1.0)
    assert iv.upper == pytest.approx(_boundary_upper(m, ms), rel=0.03)
    # measured from the signed maximum instead, the upper end would be nearer 0
    wrong, _, _ = _run(m, ms, absent=True, at_zero=False, best=signed_max)
    assert wrong.upper < 0.9 * iv.upper


def test_running_max_keeps_the_highest_value():
    best = RunningMax(-5.0)
    for v in (-7.0, -4.0, -4.5):
        best.update(v)
    assert best.value == -4.0


def test_likelihood_root_on_a_linear_root():
    """r(u) - sqrt q linear in u: the root is found (to 0.01 in r) on either side; no sign change in
    30 steps: the interval is unbounded on that side."""
    sq, su = math.sqrt(Q95), 0.3
    for direction, u0 in ((+1, 2.0), (-1, -1.5)):
        u = likelihood_root(lambda u: abs(u - 0.0) / abs(u0) * sq - sq, 0.0, direction, sq, su, 0.01)
        assert abs(abs(u) / abs(u0) * sq - sq) < 0.01 and np.sign(u) == direction
    assert likelihood_root(lambda u: -1.0, 0.0, +1, sq, su, 0.01) == math.inf
    assert likelihood_root(lambda u: -1.0, 0.0, -1, sq, su, 0.01) == -math.inf


def test_profile_start_follows_the_path_and_keeps_floored_terms():
    lo = np.array([-10.0, -10.0])
    # two visited points: on the line through them
    visited = [(0.0, np.array([1.0, 2.0])), (1.0, np.array([1.5, 1.0]))]
    np.testing.assert_allclose(profile_start(visited, 0.5, None, lo), [1.25, 1.5])
    # one point: along the regression slope, at most one log unit from it
    one = [(0.0, np.array([1.0, 2.0]))]
    np.testing.assert_allclose(profile_start(one, 0.5, np.array([0.4, -4.0]), lo), [1.2, 1.0])
    # a parameter at its floor at the nearest point stays there (just above it); without log units
    # nothing is clipped
    floored = [(0.0, np.array([1.0, -10.0]))]
    np.testing.assert_allclose(profile_start(floored, 0.5, np.array([0.0, 2.0]), lo), [1.0, -10.0 + math.log(1.01)])
    np.testing.assert_allclose(profile_start(one, 0.5, np.array([0.4, -4.0]), lo, log_units=False), [1.2, 0.0])


# -- the domain switch ---------------------------------------------------------------------------
def test_steeper_negative_neighbours():
    """A term switches to the non-negative domain's interval exactly when its next term in Q N B K
    (the steeper spectrum) has a variance below -1.96 of its Wald standard errors."""
    comps = ["Q", "N", "B", "K"]
    info = np.diag([1.0, 4.0, 1.0, 0.25])  # Wald std 1, 0.5, 1, 2
    for aK, expected in [(-2 * NEGATIVE_Z * 1.01, {"B": "K"}), (-2 * NEGATIVE_Z * 0.99, {}), (1.0, {})]:
        assert steeper_negative_neighbours(comps, [0.5, 1.0, 1.0, aK], info) == expected
    # B below 0 sends N (its shallower neighbour), not K; Q below 0 sends nothing
    a = [-NEGATIVE_Z * 1.01, 1.0, -1.01 * NEGATIVE_Z, 1.0]
    assert steeper_negative_neighbours(comps, a, info) == {"N": "B"}
    assert steeper_negative_neighbours(comps, [0.5, 1.0, 1.0, -10.0], np.zeros((4, 4))) == {}  # singular


# -- elimination and the choice between models ---------------------------------------------------
def test_penalties():
    assert PENALTY["bic"](1000) == math.log(1000) and SLOPE_PENALTY["bic"](1000) == math.log(1000)
    assert PENALTY["lr"](1000) == pytest.approx(stats.chi2.ppf(0.90, 1), rel=1e-14)
    assert SLOPE_PENALTY["lr"](1000) == pytest.approx(stats.chi2.ppf(0.95, 1), rel=1e-14)
    assert penalised(-10.0, 3, 2.0) == 26.0


def test_wald_drop_candidates():
    """Terms at their boundary, and those whose 1/se(log a)^2 is below 4 x the penalty."""
    info = np.diag([1e4, 10.0, 1.0])  # Wald statistics 1e4, 10, 1
    pen = math.log(1e4)  # threshold 36.8
    assert wald_drop_candidates(["N", "B", "K"], info, [], pen) == ["B", "K"]
    assert wald_drop_candidates(["N", "B", "K"], info, ["N"], pen) == ["N", "B", "K"]
    assert wald_drop_candidates(["N", "B", "K"], info, [], 3000.0) == ["N", "B", "K"]
    assert wald_drop_candidates(["N", "B"], np.zeros((2, 2)), [], pen) == ["N", "B"]  # singular: all


#: log-likelihood of each model (its tuple of terms); criterion -2 l + 2 p
_LL = {("A", "B", "C"): 0.0, ("B", "C"): -0.2, ("A", "C"): -3.0, ("A", "B"): -0.5,
       ("C",): -6.0, ("B",): -1.5, ("A",): -4.0}


def _eliminate(candidates=lambda f: list(f), admissible=lambda sub: True, ll=_LL):
    calls = []

    def refit(cur, sub):
        calls.append((cur, tuple(sub)))
        return tuple(sub)

    out = backward_elimination(("A", "B", "C"), terms=lambda f: f, criterion=lambda f: penalised(ll[f], len(f), 2.0),
                               candidates=candidates, refit=refit, admissible=admissible)
    return out, calls


def test_backward_elimination_takes_the_best_drop_until_none_improves():
    """ABC (criterion 6) -> BC (4.4, the best of BC 4.4, AC 10, AB 5) -> stop (C 14, B 5 are worse)."""
    out, calls = _eliminate()
    assert out.chosen == ("B", "C") and out.dropped == ["A"] and out.stop == "no improvement"
    assert list(out.visited) == [("A", "B", "C"), ("B", "C"), ("A", "C"), ("A", "B"), ("C",), ("B",)]
    assert [c[1] for c in calls] == list(out.visited)[1:]  # each model fitted once, warm from its parent
    assert calls[-1][0] == ("B", "C")


def test_backward_elimination_stops():
    ll = {**_LL, ("B",): 0.5, ("C",): 1.0}  # a single term beats every pair
    out, _ = _eliminate(ll=ll)
    assert out.chosen == ("C",) and out.dropped == ["A", "B"] and out.stop == "one term left"
    out, _ = _eliminate(candidates=lambda f: [])
    assert out.chosen == ("A", "B", "C") and out.stop == "no candidate" and list(out.visited) == [("A", "B", "C")]
    out, calls = _eliminate(admissible=lambda sub: "B" in sub)  # a model needs B
    assert out.chosen == ("B", "C") and ("A", "C") not in out.visited and ("C",) not in out.visited


def test_choose_by_criterion_weights():
    """The lowest criterion wins (ties: the first); weights exp(-delta/2), normalised."""
    out = choose_by_criterion({"flicker": 10.0, "gauss_markov": 12.0}, lambda c: c)
    assert out.chosen == "flicker" and out.criteria == {"flicker": 10.0, "gauss_markov": 12.0}
    w = 1 / (1 + math.exp(-1))
    assert out.weights["flicker"] == pytest.approx(w, rel=1e-14)
    assert out.weights["gauss_markov"] == pytest.approx(1 - w, rel=1e-14)
    assert choose_by_criterion({"x": 1.0, "y": 1.0}, lambda c: c).chosen == "x"
    assert choose_by_criterion({"flicker": 3.0}, lambda c: c).weights is None


# -- the Whittle profile intervals against a closed form -----------------------------------------
def test_whittle_profile_interval_of_white_noise_is_the_closed_form():
    """White noise alone: S = a / dt at every ordinate, so the trend slope does not depend on a and
    the Whittle log-likelihood is -W log a - (sum_k w_k I_k dt) / a + const (W = sum_k w_k): its
    maximum is a_hat = sum_k w_k I_k dt / W and its 95 % interval solves 2W(r - 1 - log r) = chi2_1(0.95),
    r = a_hat / a, in closed form by Lambert W."""
    from avbench.estimators.likelihood.whittle_intervals import profile_evidence
    from avbench.estimators.likelihood.whittle_likelihood import WhittleFit, whittle_fit

    dt = 0.1
    x = np.random.default_rng(3).standard_normal(4_001) + 0.01 * np.arange(4_001)
    wf = WhittleFit(x, dt)
    beta = np.sum(wf.w * wf.GX) / np.sum(wf.w * wf.G2)
    I = (wf.X2 - 2 * beta * wf.GX + beta**2 * wf.G2) / wf.n
    W = wf.w.sum()
    a_hat = np.sum(wf.w * I) * dt / W
    full = whittle_fit(wf, ["N"], 1)
    assert full["a"][0] == pytest.approx(a_hat, rel=1e-4)  # scoring stops at a Newton decrement of 1e-6
    ev, _ = profile_evidence(wf, full)
    c = -math.exp(-(1.0 + Q95 / (2 * W)))
    lo, hi = a_hat / -special.lambertw(c, -1).real, a_hat / -special.lambertw(c, 0).real
    # the search stops within 0.01 of sqrt(q) on the likelihood root: ~0.01 / sqrt(W / 2) in log a
    assert ev["N"]["lower"] == pytest.approx(lo, rel=0.01 / math.sqrt(W / 2) * 2)
    assert ev["N"]["upper"] == pytest.approx(hi, rel=0.01 / math.sqrt(W / 2) * 2)
