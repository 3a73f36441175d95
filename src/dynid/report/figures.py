"""Validation figures like the paper's Figures 4-8: Y and W X stacked per equation group."""

from __future__ import annotations

import io
from collections.abc import Sequence

import numpy as np


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")  # files only, never a window
    import matplotlib.pyplot as plt

    return plt


def validation_figure(Y: np.ndarray, WX: np.ndarray, groups: np.ndarray, title: str,
                      order: Sequence[str] | None = None) -> bytes:
    """PNG: for each group, measured Y and reconstructed W X against the stacked sample index."""
    plt = _pyplot()
    order = list(order or dict.fromkeys(groups))
    height = 1.6 * len(order) + 0.8
    fig, axes = plt.subplots(len(order), 1, figsize=(10, height), squeeze=False)
    for ax, g in zip(axes[:, 0], order, strict=True):
        sel = groups == g
        ax.plot(Y[sel], lw=0.8, label="Y (measured)")
        ax.plot(WX[sel], lw=0.8, ls="--", label="W X (model)")
        err = np.linalg.norm(Y[sel] - WX[sel]) / max(np.linalg.norm(Y[sel]), 1e-300)
        ax.set_ylabel(g, rotation=0, ha="right", fontsize=8)
        ax.text(0.99, 0.92, f"{100 * err:.1f} %", transform=ax.transAxes, ha="right", va="top", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0, 0].legend(fontsize=7, loc="upper left")
    axes[0, 0].set_title(title, fontsize=10)
    axes[-1, 0].set_xlabel("samples (stacked per equation)", fontsize=8)
    # fixed margins (inches: title and axis label 0.45, group names 0.9): tight_layout measures every
    # line's extent, about 2 s for the car's 14 panels of thousands of samples
    fig.subplots_adjust(left=0.09, right=0.99, top=1 - 0.45 / height, bottom=0.45 / height, hspace=0.45)
    return _png(fig, plt)


def residual_histograms(Y: np.ndarray, WX: np.ndarray, groups: np.ndarray, title: str) -> bytes:
    """PNG: histogram of the residual Y - W X of each group, normalised by its standard deviation."""
    plt = _pyplot()
    order = list(dict.fromkeys(groups))
    cols = min(4, len(order))
    rows = -(-len(order) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(2.6 * cols, 2.0 * rows), squeeze=False)
    for ax in axes.ravel()[len(order):]:
        ax.axis("off")
    for ax, g in zip(axes.ravel(), order, strict=False):
        r = (Y - WX)[groups == g]
        ax.hist(r, bins=40, color="0.4")
        ax.set_title(f"{g}  σ={np.std(r):.3g}", fontsize=8)
        ax.tick_params(labelsize=6)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return _png(fig, plt)


def _png(fig, plt) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return buf.getvalue()
