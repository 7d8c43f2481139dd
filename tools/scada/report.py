"""OUT/report.md of `fleet --columns` (docs/real-data.md, "The fleet on SCADA"): what a reliability engineer reads
first, the flags with their reasons, then each unit's fitted values period by period, the units or periods not
judged and why, and what was left out (files, channels, stuck readings). The Parquet tables under OUT/health hold the
same and more; this is their summary in words (the trucks' fleet writes its own, tools.fleet.report)."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from tools.scada.fleet import EFFECTS, PeriodFit, identified, in_range

#: the effects in a reader's words (columns of the per-unit tables)
EFFECT_WORDS = {"bearing_loss_scale": "bearing losses [x nominal]", "cooler_effectiveness_scale": "cooler [x nominal]"}
#: the plot's file beside report.md, and the most units it draws (the flagged first; the median is of all)
PLOT_NAME, PLOT_UNITS = "report_fitted.png", 8
#: error bars longer than this [x nominal] are drawn at this length (a period that barely identifies an effect)
PLOT_SE_CAP = 0.5


def _cell(text) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _value(f: PeriodFit, eid: str) -> str:
    """A fitted value with its standard error, '-' where the period fits none, a value with an error wider than its
    plausible range or outside that range marked."""
    v, se = f.values.get(eid, math.nan), f.se.get(eid, math.inf)
    if not (math.isfinite(v) and math.isfinite(se)):
        return "-"
    if not identified(f, eid):
        mark = " (not identified: its error is wider than its plausible range)"
    else:
        mark = "" if in_range(f, eid) else " (outside its plausible range)"
    return f"{v:.2f} +- {se:.2f}{mark}"


def report_lines(
    fits: Sequence[PeriodFit],
    flags: Sequence,
    not_judged: dict,
    left_out: Sequence[tuple[str, str]],
    kind: str,
    max_rows: int = 60,
    plot: str | None = None,
) -> list[str]:
    """The report's lines: ``flags`` (tools.fleet.health.Flag), ``not_judged`` (unit -> why it or some of its periods
    were not judged, '' when judged throughout), ``left_out`` ((files, sentence) of files, units or channels not
    used in whole or in part), ``kind`` ("unit-months" or "unit-periods"); ``plot``: the sentence of the fitted
    values' plot (:func:`plot_lines`), after the flags."""
    units = sorted({f.unit for f in fits} | set(not_judged))
    lines = [
        "# Fleet report (SCADA)",
        "",
        f"{len({f.unit for f in fits})} units fitted, {len(fits)} {kind}; {len(flags)} flagged. Each unit's effects "
        "are fitted per period with the onboard model and judged against its siblings' median (docs/real-data.md, "
        '"The fleet on SCADA"): a unit is flagged when it drifts from its own baseline against them for two '
        "periods.",
        "",
        f"## Flags ({len(flags)})",
        "",
    ]
    if flags:
        lines += ["| unit | effect | from the period of | what it means, the figures |", "|---|---|---|---|"]
        lines += [f"| {_cell(f.vehicle)} | {f.effect} | {f.start} | {_cell(f.reason)} |" for f in flags]
    else:
        lines.append("None: no unit drifted from its siblings beyond its intervals for two periods.")
    lines.append("")
    if plot:
        lines += [plot, ""]
    said = {u: w for u, w in not_judged.items() if w}
    if said:
        lines += [f"## Not judged, in whole or in part ({len(said)})", ""]
        lines += [f"- {_cell(u)}: {_cell(w)}" for u, w in sorted(said.items())]
        lines.append("")
    if left_out:
        lines += [f"## Left out, in whole or in part ({len(left_out)})", "", "| files | why |", "|---|---|"]
        lines += [
            f"| {_cell(', '.join(os.path.basename(p) for p in str(files).split(', '))[:120])} | {_cell(why)} |"
            for files, why in left_out
        ]
        lines.append("")
    lines += ["## Fitted values per unit", ""]
    for u in units:
        mine = sorted((f for f in fits if f.unit == u), key=lambda f: f.period)
        lines += [f"### {u} ({len(mine)} periods fitted)", ""]
        if not mine:
            lines += ["No period fitted.", ""]
            continue
        lines += [
            "| period from | rows | " + " | ".join(EFFECT_WORDS.get(e, e) for e in EFFECTS) + " | residual RMS [K] |",
            "|---|---:|" + "---:|" * len(EFFECTS) + "---:|",
        ]
        lines += [
            f"| {f.start} | {f.rows} | " + " | ".join(_value(f, e) for e in EFFECTS) + f" | {f.rms_c:.2f} |"
            for f in mine[-max_rows:]
        ]
        if len(mine) > max_rows:
            lines.append(f"\n(the last {max_rows} of {len(mine)}; all in health/effects.parquet)")
        lines.append("")
    return lines


def plotted_units(fits: Sequence[PeriodFit], flags: Sequence) -> list[str]:
    """The units the plot draws, at most PLOT_UNITS: the flagged ones first, then the others by name."""
    flagged = list(dict.fromkeys(f.vehicle for f in flags))
    rest = sorted({f.unit for f in fits} - set(flagged))
    return (flagged + rest)[:PLOT_UNITS]


def period_medians(fits: Sequence[PeriodFit], eid: str) -> dict:
    """{period start: the median of the units' identified values within the effect's plausible range} (the line
    the plot draws the units against; the flags' own baseline is each unit's, tools.scada.fleet)."""
    by: dict = {}
    for f in fits:
        if in_range(f, eid):
            by.setdefault(f.start, []).append(f.values[eid])
    return {k: float(np.median(v)) for k, v in sorted(by.items())}


def plot_fitted(fits: Sequence[PeriodFit], flags: Sequence, path: str | os.PathLike) -> Path:
    """Write the fitted values' plot: one panel per effect, each drawn unit's value per period with its standard
    error (at most PLOT_SE_CAP), the median of all units' values per period, a flag's first period circled.
    A value outside the effect's plausible range is drawn at the panel's edge as a cross, one not identified (an
    error wider than the range) as a cross without its error bar."""
    import datetime as dt

    from firmware_model.effects import CATALOG
    from tools.plots import outside_legend, pyplot, save_figure

    plt = pyplot()
    units = plotted_units(fits, flags)
    fig, axes = plt.subplots(len(EFFECTS), 1, figsize=(12, 3.6 * len(EFFECTS)), sharex=True, squeeze=False)
    day = dt.date.fromisoformat
    for ax, eid in zip(axes[:, 0], EFFECTS):
        e = CATALOG[eid]
        pad = 0.1 * (e.high - e.low)
        lo, hi = e.low - pad, e.high + pad
        med = period_medians(fits, eid)
        if med:
            ax.plot([day(k) for k in med], list(med.values()), "k--", lw=1.0, label="median of all units")
        for i, u in enumerate(units):
            mine = sorted((f for f in fits if f.unit == u and np.isfinite(f.se[eid])), key=lambda f: f.period)
            if not mine:
                continue
            x = [day(f.start) for f in mine]
            v = np.array([f.values[eid] for f in mine])
            se = np.minimum([f.se[eid] for f in mine], PLOT_SE_CAP)
            inside = np.array([in_range(f, eid) for f in mine])
            shown = np.clip(v, lo, hi)
            flagged = {fl.start for fl in flags if fl.vehicle == u and fl.effect == eid}
            color = f"C{i % 10}"
            label = u + (" (flagged)" if any(fl.vehicle == u for fl in flags) else "")
            ax.errorbar(x, shown, yerr=np.where(inside, se, 0.0), fmt="o", ms=3, capsize=2, color=color, label=label)
            # a line through consecutive periods only: one across missing periods would draw values never fitted
            cuts = np.flatnonzero(np.diff([f.period for f in mine]) > 1) + 1
            for a, b in zip([0, *cuts], [*cuts, len(mine)]):
                ax.plot(x[a:b], shown[a:b], "-", lw=0.8, color=color)
            out = ~inside
            if out.any():
                ax.plot(np.array(x, dtype=object)[out], shown[out], "x", ms=8, color=color)
            for f in mine:
                if f.start in flagged:
                    ax.plot([day(f.start)], [np.clip(f.values[eid], lo, hi)], "o", ms=14, mfc="none", mec="red")
        ax.axhline(e.neutral, color="0.6", lw=0.6)
        ax.set_ylim(lo, hi)
        ax.set_ylabel(EFFECT_WORDS.get(eid, eid))
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:  # (a panel with no identified period: no legend, no warning)
            outside_legend(ax)
    n = len({f.unit for f in fits})
    axes[0, 0].set_title(
        f"Fitted values per period of {len(units)} of {n} units (1 standard error, at most {PLOT_SE_CAP:g}); red "
        "circle: a flag's first period; x: outside the plausible range (drawn at the edge) or not identified"
    )
    axes[-1, 0].set_xlabel("period start (UTC)")
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    save_figure(fig, tmp)
    os.replace(tmp, path)
    return path


def write_report(path: str | os.PathLike, fits, flags, *args, **kwargs) -> Path:
    """Write :func:`report_lines` to ``path`` and the fitted values' plot beside it (:func:`plot_fitted`; none
    when nothing was fitted: an earlier run's removed), each atomically; returns the report's path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    png = path.with_name(PLOT_NAME)
    if any(np.isfinite(f.se[e]) for f in fits for e in EFFECTS):
        plot_fitted(fits, flags, png)
        plot = f"![fitted values per period]({PLOT_NAME})"
    else:
        png.unlink(missing_ok=True)
        plot = f"No effect was identified in any period: {PLOT_NAME} not written."
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text("\n".join(report_lines(fits, flags, *args, plot=plot, **kwargs)) + "\n")
    os.replace(tmp, path)
    return path
