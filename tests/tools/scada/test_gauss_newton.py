"""The bounded Gauss-Newton step of tools/scada/gauss_newton.py: with a parameter whose unconstrained step leaves its
range, the others are solved again with it at its bound (clipping the unconstrained step moves them as if it had not
been stopped)."""

from __future__ import annotations

import numpy as np

from tools.scada.gauss_newton import bounded_step, fit


def _two_correlated():
    """Residual r + J d of two correlated parameters (two heat terms seen through one temperature): the data want
    the first far below its lower bound and the second up to make up for it."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=200)
    jac = np.c_[a, 0.9 * a + 0.1 * rng.normal(size=200)]
    d_true = np.array([-2.0, 2.5])
    r = -(jac @ d_true)
    return jac, r


def test_a_parameter_at_its_bound_lets_the_others_make_up():
    jac, r = _two_correlated()
    x, lo, hi = np.zeros(2), np.array([-0.5, -10.0]), np.array([10.0, 10.0])
    d = bounded_step(jac, r, x, lo, hi)
    assert d[0] == -0.5  # held at the bound it would cross
    # the second is the least-squares value given the first there (checked on a fine grid)
    grid = np.linspace(-10, 10, 200001)
    cost = [np.sum((r + jac[:, 0] * -0.5 + jac[:, 1] * g) ** 2) for g in grid[::100]]
    assert abs(d[1] - grid[::100][int(np.argmin(cost))]) < 0.02
    # the clipped unconstrained step is worse than no step here; the bounded one is better than both
    clipped = np.clip(np.linalg.lstsq(jac, -r, rcond=None)[0], lo - x, hi - x)

    def cost_of(step):
        return float(np.sum((r + jac @ step) ** 2))

    assert cost_of(d) < cost_of(np.zeros(2)) < cost_of(clipped)


def test_inside_the_bounds_it_is_the_plain_least_squares_step():
    jac, r = _two_correlated()
    d = bounded_step(jac, r, np.zeros(2), np.full(2, -10.0), np.full(2, 10.0))
    np.testing.assert_allclose(d, np.linalg.lstsq(jac, -r, rcond=None)[0])


def test_the_fit_moves_from_a_start_at_a_bound():
    """A linear model whose best fit lies beyond one bound: the fit ends at that bound with the other moved, where
    clipping the unconstrained step left both where they started."""
    jac, r0 = _two_correlated()

    def residual(x):
        return r0 + jac @ x

    out = fit(residual, np.zeros(2), np.array([0.0, -10.0]), np.array([10.0, 10.0]), np.full(2, 0.1))
    x1_best = -float(jac[:, 1] @ r0) / float(jac[:, 1] @ jac[:, 1])  # the second's optimum with the first at 0
    assert out["x"][0] == 0.0
    assert abs(out["x"][1] - x1_best) < 1e-9 and x1_best > 0.2
    assert np.sum(out["r"] ** 2) < np.sum(r0**2)
