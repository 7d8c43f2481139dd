"""Plots people would rather look at than read: temperatures by component group and the heat budget; the panels
`simulate --plot` and `replay --plot` share (the inputs, temperatures with their warning limits); and the two
helpers every plotting module of the tools uses (:func:`pyplot` without a display, :func:`save_figure`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tools.published import description, ids, label_of
from tools.published import limits as gearbox_limits


def panels(gearbox=None) -> dict:
    """The component groups a figure draws one panel each of, from the gearbox's description (a parameter set, a
    description or a sensor; None: the default gearbox's): {title: ids}. The idle wheels' teeth, the other wheels
    (named after their shaft when they share one), the planetary members, the shaft bearings, the wheel bearings,
    the housings, and any other published component; a group the gearbox does not have is left out."""
    d = description(gearbox)
    pub = ids(d)
    idle = [w.id for w in d.wheels if w.mount == "idle"]
    wheels = [w for w in d.wheels if w.mount != "idle" and w.id in pub]
    shafts = {w.shaft for w in wheels}
    shaft_name = d.names.get(next(iter(shafts), None)) if len(shafts) == 1 else None
    out = {
        "Idle wheel teeth": [c for c in pub if c.partition(".")[0] in idle],
        (f"{shaft_name[0].upper()}{shaft_name[1:]} wheels" if shaft_name else "Wheels"): [w.id for w in wheels],
        "Planetary": [m for ps in d.planetary for m in (ps.sun, ps.planet, ps.ring)],
        "Shaft bearings": [b.id for b in d.bearings if b.wheel is None],
        "Wheel bearings": [b.id for b in d.bearings if b.wheel is not None],
        "Housings": [h.id for h in d.housings],
    }
    shown = {c for cs in out.values() for c in cs} | {"oil"}
    out["Other published components"] = [c for c in pub if c not in shown]
    return {k: v for k, v in out.items() if v}


def pyplot():
    """matplotlib.pyplot on the Agg backend (files only, no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: the time axis of every plot: minutes for drives up to TIME_IN_HOURS_FROM_S, hours beyond
TIME_IN_HOURS_FROM_S = 2 * 3600.0
#: warning levels as words on every plot's level axis
LEVEL_WORDS = {-1: "n/a", 0: "normal", 1: "warning", 2: "critical"}


def time_axis(time_s) -> tuple[np.ndarray, str]:
    """(time values, axis label) for a plot: minutes up to 2 h of drive, hours beyond (the same rule everywhere)."""
    t = np.asarray(time_s, dtype=float)
    span = float(np.nanmax(t) - np.nanmin(t)) if t.size else 0.0
    if span > TIME_IN_HOURS_FROM_S:
        return t / 3600.0, "time [h]"
    return t / 60.0, "time [min]"


def level_axis(ax) -> None:
    """Warning levels as words on a y axis (n/a below normal)."""
    ax.set_yticks(list(LEVEL_WORDS), list(LEVEL_WORDS.values()))
    ax.set_ylim(-1.4, 2.4)


def outside_legend(ax, **kw) -> None:
    """A legend to the right of the panel, where it hides no curve."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=7, **kw)


def save_figure(fig, path, dpi: int = 110) -> Path:
    """Lay out, write and close a figure; returns the path."""
    fig.tight_layout()
    fig.savefig(path, dpi=dpi, bbox_inches="tight")  # the legends outside the panels too (tight_layout leaves them)
    pyplot().close(fig)
    return Path(path)


def input_panel(ax, t, table, fixed_ratio: bool | None = None) -> None:
    """Engine speed and torque, and the gear on a second axis, with one legend outside the panel; a fixed-ratio
    drive's (``fixed_ratio``; None: from the table, its meta or its input_* columns) input shaft's speed and torque
    and no gear (a reducer's plot said "engine speed" and drew its one gear)."""
    meta = getattr(table, "meta", None) or {}
    if fixed_ratio is None:
        fixed_ratio = meta.get("drive") == "fixed_ratio" or table.has("input_speed_rpm")
    what = "input shaft" if fixed_ratio else "engine"
    for names, color, unit in (
        (("input_speed_rpm", "engine_speed_rpm"), "tab:blue", "speed [rpm]"),
        (("input_torque_nm", "engine_torque_nm"), "tab:red", "torque [N m]"),
    ):
        col = next((c for c in names if table.has(c)), None)
        if col is not None:
            ax.plot(t, table[col], lw=0.7, color=color, label=f"{what} {unit}")
    ax.set_ylabel("speed, torque")
    ax.grid(alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    if table.has("gear") and not fixed_ratio:
        g = ax.twinx()
        g.step(t, table["gear"], where="post", lw=0.7, color="tab:green", label="gear (right axis)")
        g.set_ylabel("gear", color="tab:green")
        from matplotlib.ticker import MaxNLocator

        g.yaxis.set_major_locator(MaxNLocator(integer=True, min_n_ticks=1))  # whole gears (9, not 8.6 .. 9.4)
        h2, l2 = g.get_legend_handles_labels()
        handles, labels = handles + h2, labels + l2
    ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.06, 1.0), borderaxespad=0.0, fontsize=7)


#: the temperatures among a drive's inputs: column -> legend label
INPUT_TEMPERATURES = {
    "oil_temp_c": "oil (sensor reading)",
    "ambient_temp_c": "ambient air",
    "coolant_temp_c": "engine coolant",
}


def input_temperature_panel(ax, t, table) -> None:
    """The temperatures among the inputs (oil sensor, ambient, coolant), those the table has with a value."""
    for i, (col, label) in enumerate(INPUT_TEMPERATURES.items()):
        if table.has(col) and np.any(np.isfinite(np.asarray(table[col], dtype=float))):
            ax.plot(t, table[col], lw=0.9, color=("k", "tab:cyan", "tab:orange")[i], label=label)
    ax.set_ylabel("input\ntemperatures [degC]")
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        outside_legend(ax)


def temperature_panel(ax, t, table, components, limits, gearbox, prefix: str = "T_") -> list[str]:
    """Each component's temperature labelled with its name spelled out (tools.published.label: the description's
    words for its parts), and the warning limit of each component the gearbox (a parameter set, a description or a
    sensor) publishes as a dashed line in its colour, named at the right end; one grey line where several share a
    limit. Returns the components drawn (those the table has)."""
    d = description(gearbox)
    pub = set(ids(gearbox))
    drawn = [c for c in components if table.has(f"{prefix}{c}_c")]
    at_limit: dict[float, list] = {}
    for i, c in enumerate(drawn):
        ax.plot(t, table[f"{prefix}{c}_c"], lw=1.1, color=f"C{i % 10}", label=label_of(c, d))
        if c in pub and c in limits.components:  # a derived temperature (a forced oil inlet) has no limit
            at_limit.setdefault(limits.of(c)[0], []).append((c, f"C{i % 10}"))
    for limit_c, comps in at_limit.items():
        color = comps[0][1] if len(comps) == 1 else "0.35"
        ax.axhline(limit_c, color=color, lw=0.8, ls="--")
        who = "" if len(comps) == len(drawn) > 1 else ", ".join(c for c, _ in comps) + ": "
        ax.annotate(
            f"{who}warning {limit_c:.0f} degC",
            xy=(1.0, limit_c),
            xycoords=("axes fraction", "data"),
            xytext=(-3, 2),
            textcoords="offset points",
            ha="right",
            va="bottom",
            fontsize=7,
            color=color,
        )
    return drawn


def plot_simulation(table, path, title="", limits=None, gearbox=None):
    """The figure of `simulate --plot`: the inputs (speed, torque, gear; the input temperatures), then one panel per
    component group (:func:`panels` of ``gearbox``, a parameter set or description; None: the default gearbox) with
    names spelled out, the warning limits dashed (``limits``; None: the gearbox's own, tools.published.limits) and
    the plant's oil sump for reference."""
    limits = limits or gearbox_limits(gearbox)
    gearbox = description(gearbox)
    groups = panels(gearbox)
    rows = (len(groups) + 1) // 2
    plt = pyplot()
    t, t_label = time_axis(table["time_s"])
    fig = plt.figure(figsize=(20, 5 + 4 * rows))
    grid = fig.add_gridspec(2 + rows, 2, height_ratios=[1.2, 0.9] + [2] * rows)
    inputs = fig.add_subplot(grid[0, :])
    input_panel(inputs, t, table, fixed_ratio=getattr(getattr(gearbox, "drive", None), "kind", None) == "fixed_ratio")
    inputs.set_title(title)
    input_temperature_panel(fig.add_subplot(grid[1, :], sharex=inputs), t, table)
    oil = table["T_oil_c"] if table.has("T_oil_c") else None
    for k, (group, members) in enumerate(groups.items()):
        ax = fig.add_subplot(grid[2 + k // 2, k % 2], sharex=inputs)
        temperature_panel(ax, t, table, members, limits, gearbox)
        if oil is not None:
            ax.plot(t, oil, "k:", lw=1.2, label="oil sump (plant)")
        ax.set_title(group, fontsize=10)
        ax.set_ylabel("degC (dashed:\nwarning limits)" if k % 2 == 0 else "degC")
        ax.grid(alpha=0.3)
        outside_legend(ax)
        if k >= len(groups) - 2:
            ax.set_xlabel(t_label)
    return save_figure(fig, path)


def plot_temperatures(table, path, title="", prefix="T_", gearbox=None):
    """One panel per component group (:func:`panels` of ``gearbox``; None: the default gearbox), the oil in every
    panel for reference (the validation figures, benchmarks/validate_plant.py; `simulate --plot` draws
    :func:`plot_simulation`)."""
    plt = pyplot()
    t_h, t_label = time_axis(table["time_s"])
    groups = panels(gearbox)
    rows = (len(groups) + 1) // 2
    fig, axes = plt.subplots(rows, 2, figsize=(15, 10 * rows / 3), sharex=True, squeeze=False)
    oil = table[f"{prefix}oil_c"] if table.has(f"{prefix}oil_c") else None
    for ax in axes.flat[len(groups) :]:
        ax.set_visible(False)
    for ax, (grp, members) in zip(axes.flat, groups.items()):
        for c in members:
            col = f"{prefix}{c}_c"
            if table.has(col):
                ax.plot(t_h, table[col], lw=1, label=c)
        if oil is not None:
            ax.plot(t_h, oil, "k--", lw=1.2, label="oil")
        ax.set_title(grp, fontsize=10)
        ax.set_ylabel("degC")
        ax.grid(alpha=0.3)
        outside_legend(ax, ncol=1)
    for ax in axes[-1]:
        ax.set_xlabel(t_label)
    fig.suptitle(title)
    return save_figure(fig, path)


def plot_heat_budget(table, path, title=""):
    """Heat generated by mechanism (stacked) and heat rejected to the outside, 60 s averages."""
    plt = pyplot()
    t = np.asarray(table["time_s"])
    win = max(1, int(round(60.0 / max(np.median(np.diff(t)), 1e-9)))) if t.size > 1 else 1

    def smooth(x):
        x = np.asarray(x, dtype=float)
        if win <= 1 or x.size < win:
            return x
        return np.convolve(x, np.ones(win) / win, mode="same")

    gen_groups = {
        "gear contact": [c for c in table.columns if c.startswith("Q_heat_mesh_")],
        "planetary": ["Q_heat_planetary_w"],
        "shaft bearings": [c for c in table.columns if c.startswith("Q_heat_bearing_")],
        "churning": ["Q_heat_churning_w"],
        "wheel bearings + syncs + pump": ["Q_heat_wheel_bearings_w", "Q_heat_synchronizers_w", "Q_heat_pump_w"],
        "retarder (effect)": ["Q_heat_retarder_w"],
    }
    out_cols = {
        "cooler": "Q_out_cooler_w",
        "housing convection": "Q_out_housing_convection_w",
        "housing radiation": "Q_out_housing_radiation_w",
        "supports": "Q_out_supports_conduction_w",
        "shafts": "Q_out_shafts_conduction_w",
        "held/measured sump": "Q_out_oil_boundary_w",
    }
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(14, 8), sharex=True)
    th, t_label = time_axis(t)
    stack = [
        smooth(sum(np.asarray(table[c]) for c in cols if table.has(c)))
        if any(table.has(c) for c in cols)
        else np.zeros_like(t)
        for cols in gen_groups.values()
    ]
    a1.stackplot(th, np.maximum(np.array(stack), 0) / 1e3, labels=list(gen_groups), alpha=0.85)
    a1.set_ylabel("heat generated [kW]")
    outside_legend(a1)
    a1.grid(alpha=0.3)
    for lab, c in out_cols.items():
        if table.has(c) and np.any(np.asarray(table[c]) != 0):
            a2.plot(th, smooth(table[c]) / 1e3, label=lab)
    a2.axhline(0, color="k", lw=0.5)
    a2.set_ylabel("heat rejected [kW]")
    a2.set_xlabel(t_label)
    outside_legend(a2)
    a2.grid(alpha=0.3)
    fig.suptitle(title)
    return save_figure(fig, path)
