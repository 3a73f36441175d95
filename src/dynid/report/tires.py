"""The tire characteristics in the report: the fitted curves over the measured points (figure_tires.png), a table
in the sheet's units (N/deg, N per unit slip), which test reached which slips, and tires.csv."""

from __future__ import annotations

import math

import numpy as np

from ..vehicle.tire_curves import ALPHA_PURE, AXLES, KAPPA_PURE, free_rolling_slip
from .figures import TITLE_Y, _png, _pyplot
from .html import Section, Table

DEG = math.pi / 180.0
# measured points drawn per panel at most: Agg draws a coloured marker at ~8 µs, and an hour's 290k wheel samples
# took 1.9 of the figure's 2.2 s CPU; 10,000 evenly spaced points of a cloud show its shape as all of them do
SCATTER_MAX = 10_000


def shown(mask: np.ndarray) -> tuple[np.ndarray, str]:
    """The samples of a panel's mask drawn (indices: all, or every k-th when over SCATTER_MAX) and what the legend
    says of them ("" when all are drawn)."""
    idx = np.flatnonzero(mask)
    k = -(-len(idx) // SCATTER_MAX)
    return (idx, "") if k <= 1 else (idx[::k], f", 1 in {k} of {len(idx):,}")


def tire_figure(tires) -> bytes:
    """Lateral force over load against slip angle per axle (measured points coloured by load, the fitted curve at
    0.5, 1 and 1.5 times the axle's nominal load, dashed beyond the slips measured), and longitudinal force over
    load against slip ratio with the fitted law. Up to SCATTER_MAX measured points a panel are drawn, evenly
    spaced ones beyond (the legend says how many)."""
    plt = _pyplot()

    fig, axes = plt.subplots(2, 2, figsize=(10, 7), squeeze=False)
    s = tires.samples
    kappa0 = free_rolling_slip(s) if s is not None else None
    for col, (axle, corners) in enumerate(AXLES.items()):
        ax = axes[0, col]
        if s is not None and len(s):
            m, some = shown(np.isin(s.corner, corners) & (np.abs(s.kappa - kappa0) <= KAPPA_PURE))
            sc = ax.scatter(np.degrees(s.alpha[m]), s.fy[m] / s.fz[m], c=s.fz[m], s=4, cmap="viridis", alpha=0.6,
                            label=f"measured (pure slip{some})")
            fig.colorbar(sc, ax=ax, label="Fz (N)")
        c = tires.lateral.get(axle)
        if c is not None:
            lo, hi = c.alpha_range
            span = max(abs(lo), abs(hi))
            grid = np.linspace(-1.5 * span, 1.5 * span, 301)
            inside = (grid >= lo) & (grid <= hi)
            for f, style in zip((0.5 * c.fz0, c.fz0, 1.5 * c.fz0), ("C1", "C3", "C4"), strict=True):
                fy = c.force(grid, np.full_like(grid, f)) / f
                ax.plot(np.degrees(grid[inside]), fy[inside], color=style, lw=1.6, label=f"fit at {f:.0f} N")
                ax.plot(np.degrees(grid), np.where(inside, np.nan, fy), color=style, lw=1.0, ls="--")
        ax.set_title(f"{axle} axle: lateral" + (" (Magic Formula)" if c is not None and c.magic else ""), y=TITLE_Y)
        ax.set_xlabel("slip angle α (deg)")
        ax.set_ylabel("Fy / Fz")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
        ax = axes[1, col]
        if s is not None and len(s):
            m, some = shown(np.isin(s.corner, corners) & (np.abs(s.alpha) <= ALPHA_PURE))
            ax.scatter(s.kappa[m], s.fx[m] / s.fz[m], c=s.fz[m], s=4, cmap="viridis", alpha=0.6,
                       label="measured" + (f" ({some[2:]})" if some else ""))
        law = tires.longitudinal.get(axle)
        if law is not None:
            k = np.linspace(min(law.kappa_range[0], 0.0), law.kappa_range[1], 50)
            k0 = law.free_rolling_slip(law.fz0)[0]
            kx = law.stiffness(law.fz0)[0] / law.fz0 / (1 - k0)  # per unit of the slip counted with R, as plotted
            ax.plot(k, -kx * (k - k0), color="C3", lw=1.6, label=f"fit at {law.fz0:.0f} N")
        ax.set_title(f"{axle} axle: longitudinal", y=TITLE_Y)
        ax.set_xlabel("slip ratio κ (> 0 braking)")
        ax.set_ylabel("Fx / Fz")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    # fixed margins, tight_layout's for the demo's car: it measured every tick label for 40 % of the figure's time
    # (0.6 of 1.6 s CPU); the axes are ratios (Fy/Fz, Fx/Fz, degrees, slip) of a few digits whatever the car, the
    # colour bars' loads four or five
    fig.subplots_adjust(left=0.0872, right=0.96, top=0.9481, bottom=0.0836, wspace=0.295, hspace=0.304)
    return _png(fig, plt)


def tire_table(tires) -> Table:
    """Per axle and tire: the stiffnesses at the nominal load in the sheet's units, with σ."""
    rows = []
    for name, c in {**tires.lateral, **{f"tire {k}": v for k, v in tires.per_tire.items()}}.items():
        v, s = c.stiffness(c.fz_mean)
        a0, a1 = c.alpha_range
        co = c.coefficients(c.fz_mean) if c.magic else {}
        mf = (" ".join(f"{k} {co[k][0]:.3g}±{co[k][1]:.2g}" for k in "BCDE") if co else "linear")
        rows.append([name, "cornering stiffness", f"{c.fz_mean:.0f}", f"{v * DEG:.1f}", f"{s * DEG:.1f}", "N/deg",
                     f"{math.degrees(a0):+.1f} .. {math.degrees(a1):+.1f}°", mf])
    for name, law in {**tires.longitudinal, **{f"tire {k}": v for k, v in tires.longitudinal_per_tire.items()}}.items():
        v, s = law.stiffness(law.fz0)
        rows.append([name, "slip stiffness (secant)", f"{law.fz0:.0f}", f"{v:.0f}", f"{s:.0f}", "N per unit slip",
                     f"κ {law.kappa_range[0]:.3f} .. {law.kappa_range[1]:.3f}",
                     f"rolling radius {tires.wheel_radius / (1 - law.free_rolling_slip(law.fz0)[0]):.4f} m"])
    return Table(["axle / tire", "quantity", "load (N)", "value", "σ", "unit", "slips used", "curve"], rows,
                 caption="Tire characteristics (ISO wheel axes, pure slip)")


def reach_table(tires) -> Table:
    rows = [[r["test"], r["wheel"], f"{r['alpha_deg'][0]:+.2f} .. {r['alpha_deg'][1]:+.2f}",
             f"{r['kappa'][0]:+.4f} .. {r['kappa'][1]:+.4f}", f"{r['fz_N'][0]:.0f} .. {r['fz_N'][1]:.0f}",
             f"{r['inclination_deg']:.1f}", r.get("lateral_regime", ""),
             f"{100 * r['peak_force_used']:.0f} %" if "peak_force_used" in r else ""] for r in tires.reach]
    return Table(["test", "wheel", "slip angle (deg)", "slip ratio", "Fz (N)", "|inclination| (deg)",
                  "lateral curve reached", "share of peak force"], rows,
                 caption="Which test reaches which part of the curves (speed above 10 m/s)")


def tire_section(tires) -> tuple[Section, dict[str, str | bytes]]:
    """The report's section and its files (tires.csv, figure_tires.png)."""
    text = ("Tire characteristics from the wheel force transducers and the wheels' slips, in ISO wheel axes (x the "
            "wheel plane's line on the road, z the road's normal): a tire machine's axes, not the wheel's own, which "
            "the body roll tilts. Pure slip only: lateral samples within 0.01 of the wheel's free-rolling slip "
            "ratio, longitudinal with |α| ≤ 0.5°, speed above 10 m/s. σ from the Jacobian and the residual, widened "
            "by the residual's autocorrelation; it assumes the model right (combined slip, camber thrust and "
            "relaxation are not modelled). Beyond the "
            "slips measured (dashed) the curve is an extrapolation.")
    if tires.missing:
        text += "\nNot fitted: " + "; ".join(f"{k} ({v})" for k, v in tires.missing.items())
    png = tire_figure(tires)
    caption = "Tire curves: fitted laws over the measured pure-slip points (coloured by load)"
    return (Section("Tire characteristics", text, figures=[(caption, png)], tables=[tire_table(tires),
                                                                                     reach_table(tires)],
                    anchor="tires"),
            {"tires.csv": tires.csv(), "figure_tires.png": png})


__all__ = ["reach_table", "tire_figure", "tire_section", "tire_table"]
