"""The model-fit verdict (estimation/fit.py) against closed forms.

Oracle: a line y = a x + b fitted by least squares. With measurement errors e of standard deviation s added to
y, what the errors add to the fit's residual is s (its RMS after projection, within sqrt(2 / n) relative for n
rows); a model error m (a term the line lacks) left in the clean data must not change that figure, since the
+e / -e pair cancels the cross term m.e exactly (the fit is linear in y). The verdict then compares the
estimate's residual RMS, sqrt(s^2 + rms(m)^2) for a misfit, with s.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynid.estimation import StreamingLS
from dynid.estimation.fit import FIT_RATIO, ErrorEffect, model_fits


def _ls(W: np.ndarray, y: np.ndarray) -> StreamingLS:
    ls = StreamingLS(["a", "b"])
    ls.add(W, y, np.array(["g"] * len(y)))
    return ls


@pytest.mark.parametrize("model_error", [0.0, 5.0])
def test_the_errors_explain_their_own_size_whatever_the_model_error(model_error):
    rng = np.random.default_rng(1)
    n, s = 20000, 0.3
    x = np.linspace(-1.0, 1.0, n)
    W = np.c_[x, np.ones(n)]
    m = model_error * (x ** 2 - np.mean(x ** 2))  # what a line cannot hold
    y = 2.0 * x + 1.0 + m
    e = s * rng.standard_normal(n)
    effect = ErrorEffect(_ls(W, y), _ls(W, y + e), _ls(W, y - e))
    explained = effect.explained_rms()["g"]
    assert explained == pytest.approx(s, rel=4 * np.sqrt(2 / n))  # 4 sigma of a sample standard deviation
    # the verdict on the measured rows (clean + e): residual sqrt(s^2 + rms(m_perp)^2)
    measured = _ls(W, y + e)
    est = dict(zip(["a", "b"], np.linalg.lstsq(W, y + e, rcond=None)[0], strict=True))
    fit = model_fits(measured, effect, est)["g"]
    m_perp = m - W @ np.linalg.lstsq(W, m, rcond=None)[0]
    expected = np.sqrt(s ** 2 + np.mean(m_perp ** 2))
    assert fit.ratio == pytest.approx(expected / s, rel=0.01)
    assert fit.fits == (expected / s <= FIT_RATIO) and fit.fits == (model_error == 0.0)
    assert set(fit.parameters) == {"a", "b"}


def test_a_group_the_error_draws_do_not_hold_is_not_judged():
    n = 100
    x = np.linspace(0, 1, n)
    W = np.c_[x, np.ones(n)]
    rows = StreamingLS(["a", "b"])
    rows.add(np.r_[W, W], np.r_[x, x], np.array(["g"] * n + ["h"] * n))
    effect = ErrorEffect(_ls(W, x), _ls(W, x + 0.1), _ls(W, x - 0.1))  # only group g drawn
    fits = model_fits(rows, effect, {"a": 1.0, "b": 0.0})
    assert set(fits) == {"g"}
