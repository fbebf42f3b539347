"""The likelihoods keep no table of terms: Whittle's spectra and MLE's model are read from the terms'
own declarations (fit parameters, spectrum, autocovariance), so a term registered at run time is
fitted by the Whittle likelihood without a line of it changed, and the modules hold no list of term
names."""

import ast
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import solve_discrete_lyapunov

from avbench.estimators.likelihood import whittle_spectra
from avbench.estimators.likelihood._mle_kernels import BlockMeanSystem
from avbench.estimators.likelihood.whittle_likelihood import WhittleFit, whittle_fit
from avbench.noise_models import AngleRandomWalk, Gyro, NoiseTerm
from avbench.noise_models.exact_avar import avar_from_autocovariance
from avbench.noise_models.latents import LATENT_TERMS
from avbench.noise_models.term_base import StateBlock, TermStream, _check_dt, _omega_dt
from avbench.noise_models.units import COEFFICIENTS

LIKELIHOOD = Path(__file__).resolve().parents[1] / "estimators" / "likelihood"


class _PairStream(TermStream):
    def __init__(self, dt, rng, S):
        super().__init__(dt, rng)
        self.S = S
        self.last = rng.standard_normal()

    def next(self, n):
        e = np.concatenate(([self.last], self.rng.standard_normal(n)))
        self.last = e[-1]
        return self.S * (e[1:] + e[:-1]) / math.sqrt(2.0)


class PairNoise(NoiseTerm):
    """A term no module of the likelihoods knows: w_k = S (e_k + e_{k-1}) / sqrt 2, a moving average of two
    white samples (autocovariance S^2, S^2 / 2 at lags 0, 1; spectrum 2 dt S^2 (1 + cos w))."""

    latent = "PN"
    fit_parameters = ("S",)

    def __init__(self, S):
        self.S = float(S)

    @classmethod
    def from_fit(cls, values, *, tau_max=None):
        return cls(S=values[0])

    def _params(self):
        return {"S": self.S}

    def autocovariance(self, lags, dt):
        _check_dt(dt)
        d = np.abs(np.asarray(lags))
        return np.where(d == 0, self.S**2, np.where(d == 1, self.S**2 / 2, 0.0))

    def avar(self, m, dt):
        m = np.asarray(m)
        return avar_from_autocovariance(self.autocovariance(np.arange(2 * m.max() + 1), dt), m)

    def psd(self, f, dt):
        f, w = _omega_dt(f, dt)
        return 2 * dt * self.S**2 * (1 + np.cos(w))

    def stream(self, dt, rng):
        return _PairStream(dt, rng, self.S)


@pytest.mark.parametrize("debiased", [False, True])
def test_a_term_registered_at_run_time_is_fitted_by_the_whittle_likelihood(monkeypatch, debiased):
    """Registered as a latent, the new term is a component of the likelihood: its unit spectrum is its psd,
    its expected periodogram the transform of its autocovariance, and the fit of white noise plus it
    recovers both variances within 4 standard errors of the Whittle information."""
    monkeypatch.setitem(LATENT_TERMS, PairNoise.latent, PairNoise)
    assert whittle_spectra.components()["PN"] is PairNoise
    dt, n, S, N = 0.1, 2**15, 3e-3, 1e-3
    f = np.arange(1, n // 2 + 1) / (n * dt)
    np.testing.assert_array_equal(whittle_spectra.unit_spectrum("PN", f, dt), PairNoise(1.0).psd(f, dt) / (2 * dt))
    # E[I_k] of an MA(1): c(0) + 2 (1 - 1/n) c(1) cos w_k
    expected = 1.0 + (1 - 1 / n) * np.cos(2 * np.pi * np.arange(1, n // 2 + 1) / n)
    np.testing.assert_allclose(whittle_spectra.expected_periodogram("PN", n, dt), expected, rtol=1e-12, atol=1e-15)
    x = Gyro(dt=dt, terms=[AngleRandomWalk(N=N), PairNoise(S)]).simulate(n, np.random.default_rng(4))
    wf = WhittleFit(x, dt, debiased=debiased)
    fit = whittle_fit(wf, ["PN", "N"])
    assert fit["comps"] == ["N", "PN"] and fit["converged"]
    truth = np.array([N**2, S**2]) / wf.scale**2  # each term is its amplitude squared times its unit spectrum
    se = np.sqrt(np.diag(np.linalg.inv(fit["detail"]["info"])))  # of the log-variances
    z = (np.log(fit["a"]) - np.log(truth)) / se
    assert np.all(np.abs(z) < 4), z


class PairNoiseBlocks(PairNoise):
    """:class:`PairNoise` with its part of the MLE's block-mean state space: over block j (samples jm ..
    jm + m - 1) the sum of w is S / sqrt 2 (u_j + l_{j-1}), u_j = 2 sum e - e_last and l_j = e_last of
    block j; states (u_j, l_j, l_{j-1}), var u = (4m - 3) S^2, cov(u, l) = S^2, var l = S^2."""

    block_mean_states = 3

    @classmethod
    def block_mean_block(cls, values, m, dt):
        S2 = values[0] ** 2
        Q = S2 * np.array([[4.0 * m - 3, 1, 0], [1, 1, 0], [0, 0, 0]])
        P0 = Q + S2 * np.diag([0.0, 0.0, 1.0])
        z = 1 / (m * math.sqrt(2))
        return StateBlock(np.array([[0.0, 0, 0], [0, 0, 0], [0, 1, 0]]), Q, np.array([z, 0, z]), P0)


@pytest.mark.parametrize("code", [code for code, cls in LATENT_TERMS.items()
                                  if cls.block_mean_states is not None and cls.stationary
                                  and not cls.deterministic] + ["PN"])
@pytest.mark.parametrize("m", [1, 6])
def test_the_mle_state_space_of_a_term_has_its_block_means_autocovariance(monkeypatch, code, m):
    """The MLE's state space of one term, built from its declarations alone (a term registered at run time
    too), gives its block means the autocovariance of the term's own: the double sum of
    :meth:`autocovariance` over two blocks; and the analytic derivatives are those of the matrices."""
    monkeypatch.setitem(LATENT_TERMS, PairNoiseBlocks.latent, PairNoiseBlocks)
    cls, dt = LATENT_TERMS[code], 0.1
    values = [3e-3, 2.0, 0.7][: len(cls.fit_parameters)]
    term = cls.from_fit(values)
    system = BlockMeanSystem((code,), m, dt)
    p = np.log(values)
    T, Qc, H, P0, _ = system.matrices(p)
    s = slice(0, system.lev)  # the term's own (stationary) states
    P = solve_discrete_lyapunov(T[s, s], Qc[s, s]) if system.lev else np.zeros((0, 0))
    np.testing.assert_allclose(P, P0[s, s], rtol=1e-12, atol=1e-12 * np.abs(P0).max(initial=0))
    z = system.Z[s]
    i = np.arange(m)
    for h in range(4):
        exact = np.mean(term.autocovariance(np.abs(h * m + i[:, None] - i[None, :]), dt))
        model = z @ np.linalg.matrix_power(T[s, s], h) @ P @ z + (H if h == 0 else 0.0)
        assert model == pytest.approx(exact, rel=1e-10), h
    derivatives = system.derivatives(p)
    for k in range(p.size):
        step = np.zeros(p.size)
        step[k] = 1e-6
        up, down = system.matrices(p + step), system.matrices(p - step)
        for d, a, b in zip(derivatives, up, down):
            np.testing.assert_allclose(d[k], (np.asarray(a) - np.asarray(b)) / 2e-6, rtol=1e-6, atol=1e-9)


def _catalogue_literals(path: Path):
    """String constants of ``path`` (docstrings aside) that name terms as a catalogue: any latent code, and
    any container display of two or more coefficient names."""
    tree = ast.parse(path.read_text())
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, (ast.Module, ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef))
                  and node.body and isinstance(node.body[0], ast.Expr) and isinstance(node.body[0].value, ast.Constant)}
    codes = set(LATENT_TERMS)
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            if node.value in codes or any(part in codes for part in node.value.split(".")[:1] if "." in node.value):
                found.append((node.lineno, node.value))
        if isinstance(node, (ast.Tuple, ast.List, ast.Set, ast.Dict)):
            elts = node.keys if isinstance(node, ast.Dict) else node.elts
            names = [e.value for e in elts if isinstance(e, ast.Constant) and e.value in COEFFICIENTS]
            if len(names) >= 2:
                found.append((node.lineno, tuple(names)))
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and len(node.value) > 1 \
                and set(node.value) <= set(COEFFICIENTS) and id(node) not in docstrings and node.value.isupper() \
                and len(set(node.value)) == len(node.value) and node.value not in codes:
            found.append((node.lineno, node.value))  # "QNBK"-like strings listing coefficients
    return found


@pytest.mark.parametrize("name", ["whittle.py", "whittle_likelihood.py", "whittle_spectra.py", "whittle_intervals.py",
                                  "mle.py", "_mle_kernels.py", "_mle_model.py"])
def test_the_likelihood_modules_hold_no_list_of_term_names(name):
    assert _catalogue_literals(LIKELIHOOD / name) == []


def test_the_catalogue_check_finds_a_list_of_term_names(tmp_path):
    """The check above can fail: it finds the kinds of catalogue the modules held."""
    src = tmp_path / "m.py"
    src.write_text('A = ("N", "Q", "K", "B", "GM")\nif c == "GM":\n    pass\nd = {"QN": ("Q",)}\ns = "QNBKR"\n'
                   't = sp["GM.tc"] if "RW" in latents else None\n')
    assert {v for _, v in _catalogue_literals(src)} >= {"GM", ("N", "Q", "K", "B"), "QN", "QNBKR", "GM.tc", "RW"}
