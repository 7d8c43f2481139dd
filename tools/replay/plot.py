"""The plot of a sensor replay: the hottest estimates, the highest warning level, the oil innovation."""
from __future__ import annotations

import numpy as np

from firmware_model.components import LEVEL_NA, PUBLISHED
from firmware_model.units import S_PER_MIN


#: components drawn in the temperature panel: the hottest this many
PLOT_HOTTEST = 8


def plot_replay(out, path, title: str = "") -> None:
    """Write a PNG of a sensor output run table: the PLOT_HOTTEST hottest estimates and the measured oil, the
    highest warning level per step (n/a when no level is available), the oil innovation."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t_min = out["time_s"] / S_PER_MIN
    fig, axes = plt.subplots(3, 1, figsize=(11, 9), sharex=True, gridspec_kw={"height_ratios": [3, 1, 1]})
    ax = axes[0]
    hottest = sorted(PUBLISHED, key=lambda c: -np.nanmax(out[f"T_{c}_c"]))[:PLOT_HOTTEST]
    for c in hottest:
        ax.plot(t_min, out[f"T_{c}_c"], lw=1, label=c)
    if out.has("oil_temp_c") and np.any(np.isfinite(out["oil_temp_c"])):
        ax.plot(t_min, out["oil_temp_c"], "k:", lw=1, label="oil (measured)")
    ax.set_ylabel("temperature [degC]")
    ax.legend(ncol=3, fontsize=8)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    lev = np.max(np.stack([np.where(out[f"W_{c}"] == LEVEL_NA, -1, out[f"W_{c}"]) for c in PUBLISHED]), axis=0)
    axes[1].step(t_min, lev, where="post", color="tab:red")
    axes[1].set_ylabel("max warning")
    axes[1].set_yticks([-1, 0, 1, 2], ["n/a", "0", "1", "2"])
    axes[1].grid(alpha=0.3)
    axes[2].plot(t_min, out["oil_innovation_c"], color="tab:purple", lw=1)
    axes[2].set_ylabel("oil meas - model [K]")
    axes[2].set_xlabel("time [min]")
    axes[2].grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
