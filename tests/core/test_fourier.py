import numpy as np
import pytest
from pdeface.surface.fourier import evaluate_fourier, fit_fourier


def test_recovers_a_cosine_series_exactly(rng):
    v = np.linspace(0, np.pi, 37)
    coef = rng.normal(size=(4, 6, 3))
    P = evaluate_fourier(coef, v)
    c, r = fit_fourier(P, 5)
    np.testing.assert_allclose(c, coef, atol=1e-12)
    np.testing.assert_allclose(r, 0, atol=1e-12)


def test_residual_closes_the_curve_and_is_orthogonal(rng):
    P = rng.normal(size=(3, 37, 3))
    c, r = fit_fourier(P, 5)
    v = np.linspace(0, np.pi, 37)
    np.testing.assert_allclose(evaluate_fourier(c, v) + r, P, atol=1e-12)
    # least squares on the even-reflected closed curve: residual ⟂ every mode there
    w = np.full(37, 2.0)
    w[[0, -1]] = 1
    B = np.cos(np.outer(v, np.arange(6)))
    np.testing.assert_allclose(np.einsum("jn,j,kjc->knc", B, w, r), 0, atol=1e-10)


def test_full_modes_leave_no_residual(rng):
    P = rng.normal(size=(2, 9, 3))
    _, r = fit_fourier(P, 8)
    np.testing.assert_allclose(r, 0, atol=1e-10)
    with pytest.raises(ValueError):
        fit_fourier(P, 9)
