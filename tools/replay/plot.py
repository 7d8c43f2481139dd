"""The plot of a sensor replay: inputs, the estimates closest to their limits with the limits drawn, the warning
level of every component that left normal (as words), the oil innovation."""

from __future__ import annotations

import numpy as np

from firmware_model.components import LEVEL_NA
from tools.plots import input_panel  # the replay's input panel, shared with simulate's and the demo's figures
from tools.published import description, ids, label_of
from tools.published import limits as gearbox_limits

#: components drawn in the temperature panel: the closest to their own warning limits, this many
PLOT_CLOSEST = 6


def closest_to_limits(out, limits, published) -> list[str]:
    """The ``published`` components (ids) ordered by their smallest margin to their own warning limit over the
    drive, the PLOT_CLOSEST closest."""
    margin = {
        c: float(np.nanmin(limits.of(c)[0] - np.asarray(out[f"T_{c}_c"], dtype=float)))
        for c in published
        if c in limits.components  # a derived temperature (a forced oil inlet) has no limit of its own
        and out.has(f"T_{c}_c")
        and np.any(np.isfinite(out[f"T_{c}_c"]))
    }
    return sorted(margin, key=margin.get)[:PLOT_CLOSEST]


def raised_components(out, published) -> list[str]:
    """The ``published`` components (ids, in their order) whose warning level left normal in ``out``."""
    return [c for c in published if out.has(f"W_{c}") and np.any(np.isin(out[f"W_{c}"], (1, 2)))]


def plot_replay(out, path, title: str = "", limits=None, gearbox=None) -> None:
    """Write a PNG of a sensor output run table: the inputs; the PLOT_CLOSEST estimates closest to their own warning
    limits, each with its limit dashed, and the measured oil; the level of every component that left normal, as
    words; the oil innovation (measured - model). ``gearbox``: the sensor, its parameter set or description (the
    published components and their words; None: the default gearbox). ``limits``: None for the sensor's that ran
    (the table's meta), else the gearbox's own (tools.published.limits), never the GRS905's file for another one."""
    from tools.plots import level_axis, outside_legend, pyplot, save_figure, temperature_panel, time_axis

    limits = limits or (getattr(out, "meta", None) or {}).get("limits") or gearbox_limits(gearbox)
    d, pub = description(gearbox), ids(gearbox)
    plt = pyplot()
    t, t_label = time_axis(out["time_s"])
    fig, axes = plt.subplots(4, 1, figsize=(13, 11), sharex=True, gridspec_kw={"height_ratios": [1.2, 3, 1.3, 1]})
    input_panel(axes[0], t, out)
    axes[0].set_title(title)
    ax = axes[1]
    temperature_panel(ax, t, out, closest_to_limits(out, limits, pub), limits, gearbox)
    if out.has("oil_temp_c") and np.any(np.isfinite(out["oil_temp_c"])):
        ax.plot(t, out["oil_temp_c"], "k:", lw=1, label="oil (measured)")
    ax.set_ylabel("temperature [degC]\n(dashed: warning limits)")
    outside_legend(ax)
    ax.grid(alpha=0.3)
    ax = axes[2]
    raised = raised_components(out, pub)
    for i, c in enumerate(raised[:8]):
        lv = np.where(np.asarray(out[f"W_{c}"]) == LEVEL_NA, -1, out[f"W_{c}"])
        ax.step(t, lv, where="post", lw=1.2, color=f"C{i}", label=label_of(c, d))
    if not raised:
        ax.text(0.5, 0.5, "no warning on this drive", transform=ax.transAxes, ha="center", va="center")
    level_axis(ax)
    ax.set_ylabel("warning level")
    if raised:
        outside_legend(ax)
    ax.grid(alpha=0.3)
    axes[3].plot(t, out["oil_innovation_c"], color="tab:purple", lw=1)
    axes[3].set_ylabel("oil measured -\nmodel [K]")
    axes[3].set_xlabel(t_label)
    axes[3].grid(alpha=0.3)
    save_figure(fig, path)
