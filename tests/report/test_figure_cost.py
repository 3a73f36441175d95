"""The report's figures drawn with less work, the same pixels.

Oracle: matplotlib's own drawing of the same figure without the shortcut (its automatic title placement), pixel
for pixel."""

import io

import numpy as np
import pytest

from dynid.report import figures


def _pixels(png: bytes) -> np.ndarray:
    from PIL import Image  # matplotlib's own PNG reader and writer

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGBA"))


def _cog() -> bytes:
    cov = np.array([[4e-6, 1e-6], [1e-6, 9e-6]])
    points = [figures.CogPoint("estimate", 1.1, 0.55, 0.004, cov, cov),
              figures.CogPoint("truth", 1.105, 0.56, 0.0, color="#d62728", marker="D")]
    return figures.centre_of_gravity_figure(2.7, 0.0, 0.75, 0.74, 0.3, points)


def _parameters() -> bytes:
    rows = [figures.ParameterRow(f"p{k}", 10.0 + k, 0.3 * (k + 1), 9.0 + k, 10.2 + k, 10.0) for k in range(5)]
    return figures.parameter_figure([("masses", rows[:3]), ("stiffnesses", rows[3:])])


@pytest.mark.parametrize("draw", [_cog, _parameters])
def test_titles_placed_as_matplotlib_places_them(draw, monkeypatch):
    """TITLE_Y given skips matplotlib's search for an offset text over the y tick labels; these axes have none, so
    the title lands where the automatic placement puts it."""
    fixed = _pixels(draw())
    monkeypatch.setattr(figures, "TITLE_Y", None)  # None: matplotlib places the title itself
    auto = _pixels(draw())
    assert fixed.shape == auto.shape
    assert np.array_equal(fixed, auto)
