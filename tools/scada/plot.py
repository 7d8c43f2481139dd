"""The plot of the sensor over a SCADA record: the load, each measured channel with its estimate, their residuals."""

from __future__ import annotations

import numpy as np


def broken_at_gaps(stretch, *series) -> list[np.ndarray]:
    """Each of ``series`` (one value per row) with a NaN between two gap-free stretches (``stretch``: each row's,
    ScadaRecord.stretch), where matplotlib then breaks its line: a line drawn across a gap of days or months
    stands for rows that are not there."""
    starts = np.flatnonzero(np.diff(np.asarray(stretch)) != 0) + 1  # each stretch's first row but the first's
    return [np.insert(np.asarray(s, dtype=float), starts, np.nan) for s in series]


def plot_estimates(result, path) -> None:
    """Write a PNG of a :class:`tools.scada.replay.ScadaReplay`: power (input torque times speed) and the air, each
    measured channel (dots) with the sensor's estimate (line), and estimate - measured per channel; every line
    broken between the record's stretches (:func:`broken_at_gaps`)."""
    import datetime as dt

    import matplotlib.dates as mdates

    from tools.plots import outside_legend, pyplot, save_figure

    t = result.table
    # dates (UTC) on the axis, not days from the first row: a held-out month is read by its dates (a reviewer)
    days = np.asarray(t["time_utc_s"], dtype=float) / 86400.0 + mdates.date2num(dt.datetime(1970, 1, 1))

    def line(*series):  # the days and ``series`` with a break at each gap
        return broken_at_gaps(result.stretch, days, *series)

    plt = pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(13, 10), sharex=True, gridspec_kw={"height_ratios": [1, 3, 1.5]})
    power_kw = t["input_torque_nm"] * t["input_speed_rpm"] * np.pi / 30.0 / 1e3
    axes[0].plot(*line(power_kw), lw=0.6, color="tab:gray")
    axes[0].set_ylabel("input power [kW]")
    ax2 = axes[0].twinx()
    ax2.plot(*line(t["ambient_temp_c"]), lw=0.6, color="tab:cyan")
    ax2.set_ylabel("air [degC]", color="tab:cyan")
    axes[0].set_title(
        f"{t.meta.get('unit', '')}: the onboard sensor over SCADA (oil {result.oil_mode}); "
        "dots measured, lines estimated"
    )
    # the sump drawn last and thicker: with the oil modelled it is the estimate that matters, and the bearings'
    # lines hid it (a reviewer)
    sump = [n for n, column in result.estimated.items() if column == "T_oil_c"]
    order = [n for n in result.estimated if n not in sump] + sump
    for name in order:
        i = list(result.estimated).index(name)
        lw = 1.4 if name in sump else 0.8
        axes[1].plot(days, t[name], ".", ms=1.5, color=f"C{i}", alpha=0.5)
        axes[1].plot(*line(t[f"est_{name}"]), lw=lw, color=f"C{i}", label=name)
        axes[2].plot(*line(t[f"est_{name}"] - t[name]), lw=0.6 if name not in sump else 1.0, color=f"C{i}", alpha=0.8)
    axes[1].set_ylabel("temperature [degC]")
    outside_legend(axes[1])
    axes[2].axhline(0.0, color="k", lw=0.5)
    axes[2].set_ylabel("estimate - measured [K]")
    axes[2].set_xlabel("date (UTC)")
    locator = mdates.AutoDateLocator()
    axes[2].xaxis.set_major_locator(locator)
    axes[2].xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator))
    for ax in axes:
        ax.grid(alpha=0.3)
    save_figure(fig, path)
