"""Validation figures like the paper's Figures 4-8: Y and W X stacked per equation group."""

from __future__ import annotations

import io
import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

NOT_EXCITED = "not excited"  # a panel's corner when the test barely moves its equation (estimation.not_excited)


def _pyplot():
    import matplotlib  # start-up: matplotlib 0.3 s, pyplot 1 s

    matplotlib.use("Agg")  # files only, never a window
    import matplotlib.pyplot as plt  # start-up: matplotlib 0.3 s, pyplot 1 s

    return plt


def preload() -> None:
    """Import pyplot now: a process forked after this has it (report.apart)."""
    _pyplot()


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


CSS_DPI = 96.0
"""CSS pixels per inch: the HTML report shows a figure at its drawn size (`html.figure_html` reads the PNG's
resolution), so a font of p points is p × 96 / 72 CSS pixels on any screen; the report's figures use 7 points
and more (9.3 px and more)."""
REPORT_DPI = CSS_DPI  # one pixel per CSS pixel: 1.25 was 0.1 s slower and 30 % larger for a little sharpness


TITLE_Y = 1.0
"""An axes title's height (axes fraction), given rather than left to matplotlib: to place it, matplotlib measures
every y tick label of the axes for an offset text (x 1e3) above them, once more than it draws them (5-7 % of the
centre of gravity and parameter figures' CPU); the report's titled axes (ratios, %, metres, mm) show none: the
same pixels (tests/report/test_figure_cost.py)."""


def _png(fig, plt, dpi: float = 90) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)  # the resolution is kept in the PNG (pHYs)
    plt.close(fig)
    return buf.getvalue()


# ------------------------------------------------------------------ the report's figures

@dataclass(frozen=True)
class ParameterRow:
    """One parameter of the interval plot: its label, estimate, 95 % half-width, a priori, truth (None when
    unknown) and the scale that normalises them."""

    label: str
    value: float
    half95: float
    a_priori: float | None
    truth: float | None
    scale: float


def parameter_figure(groups: Sequence[tuple[str, Sequence[ParameterRow]]], limit: float = 50.0) -> bytes:
    """PNG, one panel per parameter group: each estimate's 95 % interval, the a priori and the truth, as a
    difference from the estimate in % of the parameter's engineering scale, so that groups of any unit share
    one readable axis; the shaded band is the flag's ±5 %. Points beyond ±limit % sit on the edge as arrows."""
    plt = _pyplot()
    groups = [(t, rows) for t, rows in groups if rows]
    heights = [max(len(rows), 2) * 0.2 + 0.15 for _, rows in groups]
    fig, axes = plt.subplots(len(groups), 1, figsize=(8.6, sum(heights) + 0.45 * len(groups) + 0.7), squeeze=False,
                             gridspec_kw={"height_ratios": heights})
    for ax, (title, rows) in zip(axes[:, 0], groups, strict=True):
        y = np.arange(len(rows))[::-1]
        pct = lambda v, r: 100 * (v - r.value) / r.scale if r.scale > 0 else np.nan  # noqa: E731
        half = np.array([100 * r.half95 / r.scale if r.scale > 0 else np.nan for r in rows])
        shown = np.clip(np.nan_to_num(half, nan=0.0), 0, limit)
        ax.axvspan(-5, 5, color="#e6f0e6", zorder=0)
        ax.axvline(0, color="0.6", lw=0.6, zorder=1)
        ax.errorbar(np.zeros(len(rows)), y, xerr=shown, fmt="o", ms=3.5, color="#1f4e99", ecolor="#1f4e99",
                    elinewidth=1.6, capsize=2.5, zorder=3, label="estimate, 95 % interval")
        for key, marker, color, name in (("a_priori", "s", "#999999", "a priori"), ("truth", "D", "#d62728", "truth")):
            xs = np.array([pct(getattr(r, key), r) if getattr(r, key) is not None else np.nan for r in rows])
            if np.all(np.isnan(xs)):
                continue
            inside = np.abs(xs) <= limit
            ax.scatter(xs[inside], y[inside], marker=marker, s=18, color=color, zorder=4, label=name,
                       facecolors="none" if key == "a_priori" else color)
            for sign, arrow in ((1, ">"), (-1, "<")):  # off the axis: an arrow on its edge
                out = ~inside & (np.sign(xs) == sign)
                if out.any():
                    ax.scatter(np.full(out.sum(), sign * limit), y[out], marker=arrow, s=24, color=color, zorder=4)
        ax.set_yticks(y, [r.label for r in rows], fontsize=7.5)
        ax.set_xlim(-limit * 1.04, limit * 1.04)
        ax.set_ylim(-0.7, len(rows) - 0.3)
        ax.set_title(title, fontsize=9, loc="left", y=TITLE_Y)
        ax.tick_params(axis="x", labelsize=7.5)
        ax.grid(axis="x", color="0.9", lw=0.5)
    axes[-1, 0].set_xlabel("difference from the estimate, % of the parameter's engineering scale "
                           "(green: the flag's ±5 %)", fontsize=8)
    axes[0, 0].legend(fontsize=7, loc="lower right", bbox_to_anchor=(1.0, 1.0), ncols=3, frameon=False)
    total = sum(heights) + 0.45 * len(groups) + 0.7
    # hspace is a fraction of the mean panel height: 0.45 inch between panels, for the group's title
    fig.subplots_adjust(left=0.12, right=0.98, top=1 - 0.3 / total, bottom=0.55 / total,
                        hspace=0.45 / (sum(heights) / len(heights)))
    return _png(fig, plt, REPORT_DPI)


def _with_holes(t: np.ndarray, *ys: np.ndarray) -> tuple[np.ndarray, ...]:
    """NaN inserted where the time step exceeds 3 x its median (rows left out), so lines do not bridge it."""
    if len(t) < 3:
        return (t, *ys)
    dt = np.diff(t)
    cut = np.nonzero(dt > 3 * np.median(dt))[0] + 1
    if not len(cut):
        return (t, *ys)
    return tuple(np.insert(np.asarray(a, dtype=float), cut, np.nan) for a in (t, *ys))


def _nice_step(span: float, n: int = 3) -> float:
    raw = max(span, 1e-9) / n
    mag = 10 ** np.floor(np.log10(raw))
    return float(mag * min((1, 2, 2.5, 5, 10), key=lambda m: abs(m * mag - raw)))


def validation_grid(title: str, rows: Sequence[tuple[str, str]], tests: Sequence[str],
                    data: dict[tuple[str, str], tuple[np.ndarray, np.ndarray, np.ndarray]],
                    max_points: int = 600, kinds: Sequence[str] = (),
                    spans: dict[str, tuple[float, float]] | None = None,
                    corners: Mapping[tuple[str, str], str] | None = None) -> bytes:
    """PNG like the paper's Figures 4-8: one row per equation (name, unit of its force), one panel per test
    side by side (each with its own time axis, s, from the test's first sample shown); measured Y and
    predicted W X, in each panel's corner corners[(group, test)] (default: the relative error; grey when it is
    "not excited"). data[(group, test)] = (t, Y, WX); long signals
    are thinned to max_points per line (a picture: the CSV has every sample). kinds: per test, "direct" or
    "cross" (a heavier line where they change, the kind over the test's name); spans: each test's time range
    (default: its rows' in this figure). A hole in a signal (rows left out) is left blank. The panels of a row share one
    matplotlib Axes, offset in time: drawing an Axes' ticks is most of a figure's cost (84 panels for the car)."""
    plt = _pyplot()
    # start-up: matplotlib 0.3 s, pyplot 1 s
    from matplotlib.ticker import FixedFormatter, FixedLocator, MaxNLocator, NullLocator
    from matplotlib.transforms import blended_transform_factory

    tests = list(tests) or [""]
    spans = dict(spans or {})
    for test in tests:
        if test not in spans:
            ts = [data[(g, test)][0] for g, _ in rows if (g, test) in data and len(data[(g, test)][0])]
            spans[test] = (min(float(t[0]) for t in ts), max(float(t[-1]) for t in ts)) if ts else (0.0, 1.0)
    width_s = max(b - a for a, b in spans.values()) or 1.0
    gap = 0.06 * width_s
    offset = {test: k * (width_s + gap) - spans[test][0] for k, test in enumerate(tests)}
    ticks, labels = [], []
    for test in tests:
        a, b = spans[test]
        step = _nice_step(b - a)
        for v in np.arange(np.ceil(a / step) * step, b + 1e-9, step):
            ticks.append(v + offset[test])
            labels.append(f"{v:g}")
    fig_w = min(11.5, max(8.0, 2.0 + 2.4 * len(tests)))  # at most 1104 CSS px: a laptop's page shows it whole
    height = 0.75 + 1.0 * len(rows)
    fig, axes = plt.subplots(len(rows), 1, figsize=(fig_w, height), squeeze=False)
    for (g, unit), ax in zip(rows, axes[:, 0], strict=True):
        trans = blended_transform_factory(ax.transData, ax.transAxes)
        for k, test in enumerate(tests):
            got = data.get((g, test))
            if k:
                change = len(kinds) > k and kinds[k] != kinds[k - 1]
                ax.axvline(k * (width_s + gap) - gap / 2, color="0.1" if change else "0.5", lw=1.6 if change else 0.6)
            if got is None or not len(got[0]):
                ax.text(k * (width_s + gap) + width_s / 2, 0.5, "no rows", transform=trans, ha="center",
                        va="center", fontsize=7, color="0.5")
                continue
            t, Y, WX = got
            step = max(1, len(t) // max_points)
            x, y1, y2 = _with_holes(t[::step] + offset[test], Y[::step], WX[::step])
            ax.plot(x, y1, lw=0.8, color="#1f4e99", label="measured Y" if k == 0 else None)
            ax.plot(x, y2, lw=0.8, ls="--", color="#d62728", label="model W X" if k == 0 else None)
            note = (corners or {}).get((g, test))
            if note is None:
                note = f"{100 * np.linalg.norm(Y - WX) / max(np.linalg.norm(Y), 1e-300):.1f} %"
            ax.text(k * (width_s + gap) + width_s, 0.95, note, transform=trans, ha="right", va="top", fontsize=7,
                    color="0.45" if note == NOT_EXCITED else "0.0", style="italic" if note == NOT_EXCITED else "normal",
                    bbox={"boxstyle": "square,pad=0.1", "fc": "white", "ec": "none",
                                                "alpha": 0.7})
        ax.set_ylabel(f"{g}\n[{unit}]", fontsize=7.5)  # two lines: a name as long as "pitch moment" fits a row
        ax.yaxis.set_major_locator(MaxNLocator(3))
        ax.tick_params(labelsize=7, length=2)
        ax.set_xlim(-gap / 4, len(tests) * (width_s + gap) - gap * 0.75)
        ax.xaxis.set_major_locator(NullLocator())  # time ticks on the bottom row only: each tick is artists
    top = axes[0, 0]
    trans = blended_transform_factory(top.transData, top.transAxes)

    for k, test in enumerate(tests):
        head = (f"{kinds[k]}: " if len(kinds) > k else "") + test
        top.text(k * (width_s + gap) + width_s / 2, 1.04, "\n".join(textwrap.wrap(head, 26)), transform=trans,
                 ha="center", va="bottom", fontsize=7)
    bottom = axes[-1, 0]
    bottom.xaxis.set_major_locator(FixedLocator(ticks))
    bottom.xaxis.set_major_formatter(FixedFormatter(labels))
    bottom.set_xlabel("time in each test [s]", fontsize=7.5)
    top.legend(fontsize=7, loc="lower left", framealpha=0.8, ncols=2)
    fig.suptitle(title, fontsize=9.5, x=0.01, y=0.995, ha="left", va="top")
    fig.subplots_adjust(left=0.85 / fig_w + 0.03, right=0.99, top=1 - 0.75 / height, bottom=0.45 / height,
                        hspace=0.15)
    return _png(fig, plt, REPORT_DPI)


@dataclass(frozen=True)
class CogPoint:
    """A centre of gravity to draw: ahead of the rear axle, height above the ground, lateral (left +), m; the
    covariances of (ahead, height) and (ahead, lateral) for its 95 % ellipse (None: a point)."""

    label: str
    ahead: float
    height: float
    lateral: float
    cov_side: np.ndarray | None = None
    cov_top: np.ndarray | None = None
    color: str = "#1f4e99"
    marker: str = "o"


def _ellipse(ax, centre, cov, color, scale=1.0):
    """The 95 % ellipse of a 2-D normal (chi-square, 2 degrees of freedom: 2.448 σ), drawn scaled by `scale`."""
    from matplotlib.patches import Ellipse  # start-up: matplotlib 0.3 s, pyplot 1 s

    w, v = np.linalg.eigh(np.asarray(cov, dtype=float))
    w = np.sqrt(np.clip(w, 0.0, None)) * 2.448 * scale
    angle = float(np.degrees(np.arctan2(v[1, 1], v[0, 1])))
    ax.add_patch(Ellipse(centre, 2 * w[1], 2 * w[0], angle=angle, fill=False, color=color, lw=1.2))


def centre_of_gravity_figure(front: float, rear: float, half_track_front: float, half_track_rear: float,
                             wheel_radius: float, points: Sequence[CogPoint], zoom_mm: float = 30.0) -> bytes:
    """PNG: the car's side and top views (axles, wheels from the geometry) with the centres of gravity, and a
    zoom around the first point showing the 95 % uncertainty ellipses (in mm about it)."""
    from matplotlib.patches import Circle, Rectangle  # start-up: matplotlib 0.3 s, pyplot 1 s

    plt = _pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(9.6, 5.4), gridspec_kw={"width_ratios": [2.6, 1]})
    L, R = front - rear, wheel_radius
    width = 0.7 * R  # a tire's width, for the drawing only
    side, top = axes[0, 0], axes[1, 0]
    side.axhline(0, color="0.3", lw=1)
    for z in (rear, front):
        side.add_patch(Circle((z - rear, R), R, fill=False, color="0.2", lw=1.2))
        side.plot([z - rear], [R], "+", color="0.2")
    side.plot([rear - rear - 0.6 * R, front - rear + 0.6 * R], [R] * 2, color="0.75", lw=0.8, ls=":")
    for z, t in ((rear, half_track_rear), (front, half_track_front)):
        top.plot([z - rear] * 2, [-t, t], color="0.3", lw=1)
        for s in (-1, 1):
            top.add_patch(Rectangle((z - rear - R, s * t - width / 2), 2 * R, width, fill=False, color="0.2"))
    top.axhline(0, color="0.75", lw=0.8, ls=":")
    for p in points:
        side.plot(p.ahead, p.height, p.marker, color=p.color, ms=6, label=p.label)
        top.plot(p.ahead, p.lateral, p.marker, color=p.color, ms=6)
    ref = points[0]
    for ax, coord, cov_key, ylabel in ((axes[0, 1], "height", "cov_side", "height − estimate [mm]"),
                                       (axes[1, 1], "lateral", "cov_top", "lateral − estimate [mm]")):
        ax.axhline(0, color="0.85", lw=0.6)
        ax.axvline(0, color="0.85", lw=0.6)
        for p in points:
            xy = (1e3 * (p.ahead - ref.ahead), 1e3 * (getattr(p, coord) - getattr(ref, coord)))
            ax.plot(*xy, p.marker, color=p.color, ms=5)
            cov = getattr(p, cov_key)
            if cov is not None:
                _ellipse(ax, xy, cov, p.color, scale=1e3)
        ax.set_xlim(-zoom_mm, zoom_mm)
        ax.set_ylim(-zoom_mm, zoom_mm)
        ax.set_aspect("equal")
        ax.set_xlabel("ahead − estimate [mm]", fontsize=7.5)
        ax.set_ylabel(ylabel, fontsize=7.5)
        ax.tick_params(labelsize=7)
    axes[0, 1].set_title(f"zoom ±{zoom_mm:g} mm: 95 % ellipses", fontsize=8.5, y=TITLE_Y)
    for ax, ylabel, title in ((side, "height above the ground [m]", "side view (front to the right)"),
                              (top, "lateral, left + [m]", "top view")):
        ax.set_aspect("equal")
        ax.set_xlim(-R - 0.4, L + R + 0.4)
        ax.set_ylabel(ylabel, fontsize=7.5)
        ax.set_title(title, fontsize=8.5, loc="left", y=TITLE_Y)
        ax.tick_params(labelsize=7)
    side.set_ylim(-0.1, max(2 * R, max(p.height for p in points)) + 0.35)
    t = max(half_track_front, half_track_rear) + width
    top.set_ylim(-t - 0.1, t + 0.1)
    top.set_xlabel("ahead of the rear axle [m]", fontsize=7.5)
    handles, names = side.get_legend_handles_labels()
    fig.legend(handles, names, fontsize=7.5, loc="lower center", ncols=len(names), frameon=False)
    fig.subplots_adjust(left=0.07, right=0.98, top=0.94, bottom=0.15, wspace=0.25, hspace=0.4)
    return _png(fig, plt, REPORT_DPI)


# ------------------------------------------------------------------ damper curves

@dataclass(frozen=True)
class DamperCurve:
    """One damper's identified force against its clearance rate (bump > 0), m/s and N: the estimate, its σ, the
    truth's curve (None when unknown) and the knees (v-, v+; infinite: none)."""

    title: str
    velocity: np.ndarray
    force: np.ndarray
    std: np.ndarray
    truth: np.ndarray | None
    knees: tuple[float, float]


def damper_curve_figure(curves: Sequence[DamperCurve]) -> bytes:
    """PNG: one panel per damper, the estimated curve with its 95 % band, the truth dashed, the knees dotted."""
    plt = _pyplot()
    cols = min(2, len(curves))
    rows = -(-len(curves) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.6 * cols, 3.0 * rows), squeeze=False)
    for ax in axes.ravel()[len(curves):]:
        ax.axis("off")
    for ax, c in zip(axes.ravel(), curves, strict=False):
        ax.fill_between(c.velocity, c.force - 1.96 * c.std, c.force + 1.96 * c.std, color="C0", alpha=0.25,
                        lw=0, label="95 % band")
        ax.plot(c.velocity, c.force, color="C0", lw=1.2, label="estimate")
        if c.truth is not None:
            ax.plot(c.velocity, c.truth, color="k", lw=0.9, ls="--", label="truth")
        for k in c.knees:
            if np.isfinite(k):
                ax.axvline(k, color="0.5", lw=0.7, ls=":")
        ax.axhline(0.0, color="0.8", lw=0.6)
        ax.axvline(0.0, color="0.8", lw=0.6)
        ax.set_title(c.title, fontsize=9)
        ax.set_xlabel("clearance rate (m/s), bump > 0", fontsize=8)
        ax.set_ylabel("force (N)", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0, 0].legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    return _png(fig, plt)
