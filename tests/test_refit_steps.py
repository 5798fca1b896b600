"""The steps that move a fit's coordinates back to the prior and start a refit, on objectives whose
answer is known in closed form (pure numpy stand-ins for the free-run objective)."""
from types import SimpleNamespace

import numpy as np

from twin.fit import simfit


def _linear(A: np.ndarray, b: np.ndarray, x_prior: np.ndarray):
    """r(x) = A x − b; its vessel is the coordinates themselves."""
    return SimpleNamespace(residuals=lambda x: A @ x - b, x_prior=x_prior,
                           bounds=lambda: (np.full(len(x_prior), -np.inf), np.full(len(x_prior), np.inf)),
                           vessel=lambda x: np.asarray(x, float))


def test_the_return_to_the_prior_is_shortened_where_the_full_step_diverges():
    # a cost that is finite only within 0.6 of the origin along the step: the full step (and its half,
    # which lands at 0.5 but costs more than the quarter) are passed over for the lowest finite one
    def residuals(x):
        return np.array([np.nan if abs(x[0]) > 0.6 else (x[0] - 0.2) * 10.0])

    obj = SimpleNamespace(residuals=residuals, bounds=lambda: (np.array([-5.0]), np.array([5.0])))
    got = simfit._lowest_on_line(obj, np.array([0.0]), np.array([1.0]))
    assert got[0] == 0.25  # |0.25 − 0.2| < |0.5 − 0.2| < |0 − 0.2|; the step of 1 diverged
    assert simfit.STEP_FRACTIONS[-1] == 0.0  # staying put is always among the candidates


def test_a_refit_starts_from_the_candidate_the_objective_finds_lowest():
    coords = [SimpleNamespace(quantity=SimpleNamespace(get=lambda v, i=i: v[i])) for i in range(2)]
    obj = SimpleNamespace(residuals=lambda x: np.array([np.inf if x[0] > 3 else x[0] - 1.0, x[1]]),
                          scale=np.array([1.0, 2.0]), bounds=lambda: (np.full(2, -10.0), np.full(2, 10.0)))
    diverging, near, far = [4.0, 0.0], [1.5, 0.2], [-2.0, 0.0]
    np.testing.assert_allclose(simfit._lowest_start(obj, coords, [diverging, far, near]), [1.5, 0.1])
    np.testing.assert_allclose(simfit._lowest_start(obj, coords, [far]), [-2.0, 0.0])  # one start: taken as it is
