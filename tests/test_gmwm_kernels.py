"""GMWM's latent model compiled (``LatentAV``, one numba call for the AV and its Jacobian) held to its Python
reference (``LatentAVReference``, the terms' own ``avar_shape_gradient``) on random parameters over every
kind of term."""

import math

import numpy as np
import pytest

from avbench.estimators.likelihood import _gmwm_kernels as kernels
from avbench.estimators.likelihood._gmwm_model import LatentAV, LatentAVReference, log_bounds
from avbench.noise_models.latents import LATENT_TERMS, param_index
from avbench.noise_models.sensor_terms import RESONANCE_MAX_FREQUENCY
from avbench.noise_models.term_base import FitHint

EPS = np.finfo(float).eps

#: models that hold every latent between them (at most one term per coefficient, as parse_model allows)
MODELS = [("QN", "WN", "GM", "RW", "DR"), ("FW", "GM", "RW", "SN", "RS"), ("WN", "FL", "RW", "RS"),
          ("QN", "FW", "FL", "DR", "SN"), ("WN", "GM", "RS"), ("FW", "RS")]


def _draw(rng, latents, tau, dt, T):
    """Log-parameters uniform in the fit's box (an AV curve of white noise and a plateau sets the amplitudes'
    range); a sinusoid's and a resonance's frequency, at every other draw, within the window of a line or band
    found where the band search looks (1/24 of the sampling rate to :data:`RESONANCE_MAX_FREQUENCY` of it), as
    the fits hold them; anywhere the box allows otherwise."""
    avar = 1e-6 / tau + 1e-9
    hints = None
    if rng.uniform() < 0.5:
        f = math.exp(rng.uniform(math.log(1 / (24 * dt)), math.log(RESONANCE_MAX_FREQUENCY / dt)))
        hints = {lat: FitHint(window=(f / 1.5, f * 1.5)) for lat in ("SN", "RS")}
    lo, hi = log_bounds(latents, tau, avar, dt, T, hints)
    return rng.uniform(lo + 1e-9, hi - 1e-9)


def _column_tolerance(latents, u, ref, jac_ref, m):
    """What round-off leaves in each Jacobian column: a few ulps of the AV and of the column itself for a column
    computed from one evaluation (a sinusoid's d/d ln f0 is ~m omega times its AV); for a central-difference column (the filter's tf, the resonance's f0 and tc) a few ulps of the
    term's AV over the step (the reference's steps: 1e-4, a resonance's smaller at long taus)."""
    scale = np.abs(ref)
    tol = 64 * EPS * (scale[:, None] + np.abs(jac_ref))
    for lat in latents:
        i = param_index(latents, lat)
        term_av = np.abs(jac_ref[:, i]) / 2  # e^{2u} U: the term's own AV
        if lat == "FW":
            tol[:, i + 1] = 64 * EPS * term_av / 1e-4 + 64 * EPS * scale
        if lat == "RS":
            f0, tc = math.exp(u[i + 1]), math.exp(u[i + 2])
            unit = LATENT_TERMS["RS"](sigma=1.0, f0=f0, tc=tc)
            for k, h in zip((1, 2), unit.gradient_steps(m, 0.01)):
                tol[:, i + k] = 64 * EPS * term_av / h + 64 * EPS * scale
    return tol


@pytest.mark.parametrize("latents", MODELS)
def test_the_compiled_model_equals_its_reference(latents):
    """Value and Jacobian of the kernel against the reference at 200 random points of the box each: the
    value to 1e-12 (the same formulas; NumPy's vectorised expm1 and exp differ from libm's by an ulp), every
    Jacobian column within round-off (:func:`_column_tolerance`); the kernel answers at
    least 90 of the 200 draws itself (with a resonance, those whose shortest clusters its closed form covers;
    the others fall back to the reference)."""
    rng = np.random.default_rng(abs(hash(latents)) % 2**32)
    dt, n = 0.01, 2_000_000
    T = n * dt
    tau = dt * 2.0 ** np.arange(0, 17)
    model = LatentAV(latents, tau, dt, 2 * T)
    ref = LatentAVReference(latents, tau, dt, 2 * T)
    assert model._compiled
    own = 0
    for _ in range(200):
        u = _draw(rng, latents, tau, dt, T)
        v, j = model(u), model.jacobian(u)
        v_ref, j_ref = ref(u), ref.jacobian(u)
        np.testing.assert_allclose(v, v_ref, rtol=1e-12, atol=0)
        assert np.all(np.abs(j - j_ref) <= _column_tolerance(latents, u, v_ref, j_ref, model.m)), latents
        value, jac = np.empty(tau.size), np.empty((tau.size, u.size))
        own += model._kernel(model._kind, model._first, u, *model._args, value, jac) == 0
    assert own >= 90


def test_the_robust_white_gain_term_is_added():
    """``extra``: the white gain of a robust AV, e^{2u_j} e(tau) in the value and its derivative in column j."""
    dt = 0.01
    tau = dt * 2.0 ** np.arange(0, 12)
    latents = ("WN", "GM", "RW")
    extra = (0, np.linspace(0.01, 0.2, tau.size) / tau)
    u = np.log([2e-3, 1e-4, 12.0, 3e-5])
    model, ref = LatentAV(latents, tau, dt, 1e4, extra), LatentAVReference(latents, tau, dt, 1e4, extra)
    np.testing.assert_allclose(model(u), ref(u), rtol=1e-13, atol=0)
    np.testing.assert_allclose(model.jacobian(u), ref.jacobian(u), rtol=1e-13, atol=1e-300)
    assert not np.array_equal(model(u), LatentAV(latents, tau, dt, 1e4)(u))


def test_where_the_kernel_cannot_answer_the_reference_does():
    """A resonance whose shortest clusters need the autocovariance route (low f0, long tc: (2m+1)|alpha| < 1),
    and a sinusoid above the Nyquist frequency (the reference's ValueError): the kernel says so, the model
    answers as the reference."""
    dt = 0.01
    tau = dt * 2.0 ** np.arange(0, 12)
    latents = ("WN", "RS")
    u = np.log([2e-3, 1e-3, 0.05, 100.0])  # |alpha| ~ 3e-3: m < 150 below the closed form's range
    model, ref = LatentAV(latents, tau, dt, 1e4), LatentAVReference(latents, tau, dt, 1e4)
    value, jac = np.empty(tau.size), np.empty((tau.size, u.size))
    assert model._kernel(model._kind, model._first, u, *model._args, value, jac) == 1
    np.testing.assert_array_equal(model(u), ref(u))
    np.testing.assert_array_equal(model.jacobian(u), ref.jacobian(u))
    sn = LatentAV(("WN", "SN"), tau, dt, 1e4)
    with pytest.raises(ValueError, match="Nyquist"):
        sn(np.log([2e-3, 1e-3, 60.0]))


def test_the_jacobian_is_that_of_the_point_asked():
    """The Jacobian kept from the last evaluation is handed out only for that point."""
    dt = 0.01
    tau = dt * 2.0 ** np.arange(0, 12)
    latents = ("FW", "GM", "RW")
    model, ref = LatentAV(latents, tau, dt, 1e4), LatentAVReference(latents, tau, dt, 1e4)
    u, w = np.log([2e-3, 0.02, 1e-4, 12.0, 3e-5]), np.log([1e-3, 0.05, 2e-4, 3.0, 1e-5])
    model(u)
    j = model.jacobian(w)
    assert np.allclose(j, ref.jacobian(w), rtol=1e-10, atol=0)
    assert not np.allclose(j, ref.jacobian(u), rtol=1e-3, atol=0)
    assert kernels.latent_av is not kernels.latent_av_py  # compiled
