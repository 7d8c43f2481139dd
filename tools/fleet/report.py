"""The fleet report: DIR/report.md with its plots (DIR/report_*.png), from the Parquet tables of a fleet run.

Hottest vehicles and components, the distribution of the per-log peaks, the time above the warning level by
component and by vehicle, the degraded share and rejected frames, the logs that could not be read, and (after
``--diagnose``) the drifting vehicles with their fitted cooler effectiveness and oil volume per period.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from tools.fleet.store import ERRORS, HEALTH, read_table


def _save(fig, path: Path) -> None:
    """A figure written under a temporary name and renamed: complete or absent."""
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=100)
    os.replace(tmp, path)


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _cols(table) -> dict:
    return {n: table.column(n).to_pylist() for n in table.column_names}


def _nanmedian(x: list) -> float:
    """The median of the finite values (NaN when none: a period in which no truck sends its level)."""
    a = np.asarray(x, dtype=float)
    a = a[np.isfinite(a)]
    return float(np.median(a)) if a.size else math.nan


def _fmt_s(s: float) -> str:
    return f"{s / 3600:.2f} h" if s >= 3600 else f"{s / 60:.1f} min" if s >= 60 else f"{s:.0f} s"


def published_in(c: dict) -> tuple:
    """The published components a summary table covers, in its column order: the ids with a ``peak_<id>_c``
    column (tools.fleet.summary wrote them from the sensor's gearbox, in its published order)."""
    return tuple(k[len("peak_") : -len("_c")] for k in c if k.startswith("peak_") and k.endswith("_c"))


def _limits(c: dict, pub: tuple, n: int) -> np.ndarray:
    """Each log's warning limit per component [degC] (NaN: a row of an earlier version, which does not record it)."""
    cols = [c.get(f"warning_limit_{k}_c") or [None] * n for k in pub]
    return np.array(cols, dtype=float).reshape(len(pub), n).T


def _margin_key(margin: float, peak: float) -> tuple:
    """Sort key: the largest margin over the warning limit first (the closest below it next); without a known
    limit, after those with one, by peak."""
    return (0, -margin) if np.isfinite(margin) else (1, -peak)


def _hottest(c: dict, lines: list) -> None:
    """The vehicles and components ranked by their peak's margin to the component's own warning limit (peak -
    limit: parts have different limits, so the hottest in degC need not be the nearest to its limit)."""
    n = len(c["log"])
    pub = published_in(c)
    peaks = np.array([[c[f"peak_{k}_c"][i] for k in pub] for i in range(n)], dtype=float).reshape(n, -1)
    limits = _limits(c, pub, n)
    margin = peaks - limits
    # per log the component with the largest margin, else (no limit recorded) the hottest
    score = np.where(np.isfinite(margin), margin + 1e6, np.where(np.isfinite(peaks), peaks, -np.inf))
    best = np.argmax(score, axis=1)
    per_vehicle: dict = {}
    for i in range(n):
        j, v = best[i], c["vehicle"][i]
        T, lim, m = peaks[i, j], limits[i, j], margin[i, j]
        if np.isfinite(T) and (v not in per_vehicle or _margin_key(m, T) < _margin_key(*per_vehicle[v][:2])):
            per_vehicle[v] = (m, T, lim, pub[j], c["date"][i], os.path.basename(c["log"][i]))
    lines += [
        "## Hottest vehicles (nearest to, or furthest over, a component's warning limit)",
        "",
        "| vehicle | peak | component | warning limit | peak - limit | date | log |",
        "|---|---|---|---|---|---|---|",
    ]
    for v, (m, T, lim, comp, date, log) in sorted(per_vehicle.items(), key=lambda kv: _margin_key(*kv[1][:2]))[:10]:
        lim_txt, m_txt = (f"{lim:.1f} degC", f"{m:+.1f} K") if np.isfinite(m) else ("-", "-")
        lines.append(f"| {_cell(v)} | {T:.1f} degC | {comp} | {lim_txt} | {m_txt} | {date} | {_cell(log)} |")
    lines += [
        "",
        "## Hottest components (fleet peak against the warning limit, median of the per-log peaks)",
        "",
        "| component | fleet peak | warning limit | peak - limit | median peak | time above warning | "
        "time above critical |",
        "|---|---|---|---|---|---|---|",
    ]
    fleet_peak = np.nanmax(np.where(np.isfinite(peaks), peaks, -np.inf), axis=0)
    fleet_margin = np.where(np.isfinite(margin), margin, -np.inf)
    top = np.argmax(fleet_margin, axis=0)  # per component the log furthest over (or nearest to) its limit
    for j in sorted(range(len(pub)), key=lambda j: _margin_key(fleet_margin[top[j], j], fleet_peak[j]))[:10]:
        k, m, lim = pub[j], fleet_margin[top[j], j], limits[top[j], j]
        lim_txt, m_txt = (f"{lim:.1f} degC", f"{m:+.1f} K") if np.isfinite(m) else ("-", "-")
        lines.append(
            f"| {k} | {np.nanmax(peaks[:, j]):.1f} degC | {lim_txt} | {m_txt} | {np.nanmedian(peaks[:, j]):.1f} degC | "
            f"{_fmt_s(float(np.sum(c[f'above_warning_{k}_s'])))} | "
            f"{_fmt_s(float(np.sum(c[f'above_critical_{k}_s'])))} |"
        )
    lines.append("")


def _not_written(path: Path, why: str, lines: list) -> None:
    """A plot with nothing to show: not written (an earlier run's copy removed, it would show another fleet), and
    the report says why."""
    path.unlink(missing_ok=True)
    lines += [f"{why}: {path.name} not written.", ""]


def _plots(c: dict, out: Path, lines: list) -> None:
    plt = _plt()
    n = len(c["log"])
    lines += ["## Peaks and time above the warning level", ""]
    pub = published_in(c)
    peaks = {k: np.array(c[f"peak_{k}_c"], dtype=float) for k in pub}
    shown = [k for k in pub if np.isfinite(peaks[k]).any()]
    if shown:
        top = sorted(shown, key=lambda k: -np.nanmax(peaks[k]))[:6]
        fig, ax = plt.subplots(figsize=(8, 4.5))
        ax.boxplot([peaks[k][np.isfinite(peaks[k])] for k in top])
        ax.set_xticks(range(1, len(top) + 1), top)
        ax.set_ylabel("peak per log [degC]")
        ax.set_title(f"Distribution of the per-log peaks, the {len(top)} hottest components ({n} logs)")
        fig.tight_layout()
        _save(fig, out / "report_peaks.png")
        plt.close(fig)
        lines += ["![peaks](report_peaks.png)", ""]
    else:
        _not_written(out / "report_peaks.png", "No log has a temperature (the sensor never ran initialised)", lines)
    above = {k: float(np.sum(c[f"above_warning_{k}_s"])) for k in pub}
    ks = [k for k in pub if above[k] > 0]
    if not ks:
        _not_written(out / "report_above_warning.png", "No log reached a warning limit", lines)
        return
    per_v: dict = {}
    for i in range(n):
        per_v[c["vehicle"][i]] = per_v.get(c["vehicle"][i], 0.0) + max(c[f"above_warning_{k}_s"][i] for k in pub)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.5))
    a1.barh(ks, [above[k] / 60 for k in ks])
    a1.set_xlabel("time above warning, all logs [min]")
    a1.set_title("By component")
    vs = sorted((v for v in per_v if per_v[v] > 0), key=lambda v: -per_v[v])[:15]
    a2.barh(vs, [per_v[v] / 60 for v in vs])
    a2.set_xlabel("time with any component above warning [min]")
    a2.set_title(f"By vehicle ({len(vs)} of {len(per_v)} reached it)" if len(vs) < 15 else "By vehicle (15 most)")
    fig.tight_layout()
    _save(fig, out / "report_above_warning.png")
    plt.close(fig)
    lines += ["![time above warning](report_above_warning.png)", ""]


def _cell(text) -> str:
    """Text for a Markdown table cell: a '|' (the warnings' separator) would split it."""
    return str(text or "").replace("|", "\\|")


def _gone(c: dict, lines: list) -> None:
    """The logs summarised here that are no longer at their path (their rows still count above)."""
    gone = sorted({x for x in c["log"] if not os.path.exists(x)})
    if not gone:
        return
    lines += [
        f"## Logs no longer at their path ({len(gone)})",
        "",
        "Moved, renamed or deleted since they were summarised: their rows still count above, and a moved log "
        "is counted again under its new path. `gearbox-vsensor fleet ... --prune` removes their rows.",
        "",
        "| log |",
        "|---|",
    ]
    lines += [f"| {_cell(x)} |" for x in gone[:50]] + [""]


def _malformed(c: dict, lines: list) -> None:
    """The logs whose malformed lines were skipped (tools/replay/lines.py): how many and the first line numbers."""
    counts = [int(n or 0) for n in c.get("malformed_lines", [0] * len(c["log"]))]
    hit = [i for i, n in enumerate(counts) if n]
    if not hit:
        return
    lines += [
        f"## Logs with malformed lines skipped ({len(hit)})",
        "",
        "Lines no reader could read (garbage, a last line cut by a logger unplugged): skipped and counted; more "
        "than 1 % of a log's lines, or one that broke a frame sequence the step needs, makes it untrusted.",
        "",
        "| vehicle | log | lines skipped | first lines |",
        "|---|---|---|---|",
    ]
    lines += [
        f"| {_cell(c['vehicle'][i])} | {_cell(os.path.basename(c['log'][i]))} | {counts[i]} | "
        f"{_cell(c['malformed_first_lines'][i])} |"
        for i in hit[:50]
    ]
    if len(hit) > 50:
        lines.append(f"\n... and {len(hit) - 50} more (the summary's column malformed_lines)")
    lines.append("")


def _trusted_only(c: dict, lines: list) -> dict:
    """The summary's columns without the logs `replay` would call untrusted (exit status 3), which are listed
    instead: their peaks are no gearbox's (a log without gearbox messages peaks at its start temperature)."""
    trusted = [t is not False for t in c.get("trusted", [None] * len(c["log"]))]
    bad = [i for i, t in enumerate(trusted) if not t]
    if not bad:
        return c
    _warnings_table(
        c,
        bad,
        lines,
        f"## Logs whose outputs should not be trusted ({len(bad)}, left out of the peaks and times below)",
        "What `gearbox-vsensor replay` would warn about (exit status 3) for each:",
        "trusted is false",
    )
    return {k: [v[i] for i in range(len(v)) if trusted[i]] for k, v in c.items()}


def warned_section(c: dict, lines: list) -> None:
    """The trusted logs with warnings (`replay` exits 0 and says them: gear numbers of another gearbox, an oil far
    from the model's own sump), listed: they stay in the peaks below, which rest on them (the report showed such a
    log among the hottest vehicles without a word)."""
    warned = [i for i, w in enumerate(c.get("trust_warnings", [])) if w]
    if warned:
        _warnings_table(
            c,
            warned,
            lines,
            f"## Logs with warnings ({len(warned)}, kept in the peaks and times below)",
            "What `gearbox-vsensor replay` would warn about (exit status 0) for each: its estimates rest on what it "
            "says.",
            "trust_warnings",
        )


def _warnings_table(c: dict, rows: list, lines: list, heading: str, intro: str, column: str) -> None:
    """A section listing the logs ``rows`` of the summary's columns ``c`` with their warnings (at most 50)."""
    lines += [heading, "", intro, "", "| vehicle | log | warnings |", "|---|---|---|"]
    lines += [
        f"| {_cell(c['vehicle'][i])} | {_cell(os.path.basename(c['log'][i]))} | {_cell(c['trust_warnings'][i])} |"
        for i in rows[:50]
    ]
    if len(rows) > 50:
        lines.append(f"\n... and {len(rows) - 50} more (the summary's column {column})")
    lines.append("")


def duplicate_logs(c: dict) -> list[list[str]]:
    """Groups of logs that look like copies of each other: the same first and last frame time and the same number
    of frames (a log copied under another name is summarised twice and its hours counted twice). Within a vehicle
    any such logs; across vehicles only logs whose frame times are Unix time (a logger's relative times all start
    near 0, so two trucks' equally long logs could match)."""
    from tools.fleet.summary import EPOCH_MIN_S

    groups: dict = {}
    for i, log in enumerate(c["log"]):
        if not c["frames"][i]:
            continue
        start = c["start_s"][i]
        owner = None if start is not None and start >= EPOCH_MIN_S else c["vehicle"][i]
        key = (owner, start, c["end_s"][i], c["frames"][i])
        groups.setdefault(key, []).append(log)
    return [sorted(logs) for logs in groups.values() if len(logs) > 1]


def copy_vehicles(c: dict, group: list) -> list:
    """The vehicles a group of copies (:func:`duplicate_logs`) is summarised under, in order."""
    of = dict(zip(c["log"], c["vehicle"]))
    return sorted({str(of[log]) for log in group})


#: a log dated this many days or more from the day its Unix frame times say is misdated (one day: the UTC date of a
#: drive past midnight is a local one's neighbour)
MISDATED_DAYS = 2


def misdated_logs(c: dict) -> list[tuple[str, str, str]]:
    """(log, its date, the date of its frame times) of each log dated (by a manifest or --vehicle-from) MISDATED_DAYS
    or more from the day its Unix frame times say: one of the two is wrong, and the date decides its health period
    (a manifest's date overrode the frames' without a word)."""
    import datetime as dt

    from firmware_model.errors import InputError
    from tools.fleet.summary import log_date

    found = []
    for log, date, start in zip(c["log"], c["date"], c["start_s"]):
        try:
            framed = log_date(float(start)) if start is not None else None
        except InputError:  # (milliseconds: said apart)
            framed = None
        if framed and date not in (None, "unknown"):
            if abs((dt.date.fromisoformat(date) - dt.date.fromisoformat(framed)).days) >= MISDATED_DAYS:
                found.append((log, date, framed))
    return found


#: logs of one vehicle overlapping by more than this are reported (a logger that rotates its files may repeat a
#: frame or two at the seam) [s]
OVERLAP_MIN_S = 1.0


def overlapping_logs(c: dict) -> list[tuple[str, str, str, float]]:
    """(vehicle, log, other log, overlap [s]) for every two logs of one vehicle whose frame times overlap by more
    than OVERLAP_MIN_S: one truck drives one log at a time, so two overlapping logs are two trucks' (or one drive
    logged twice) under one vehicle. Only logs whose frame times are Unix time (a logger's relative times all start
    near 0); copies (:func:`duplicate_logs`, reported as such) are left out."""
    from tools.fleet.summary import EPOCH_MIN_S

    per_vehicle: dict = {}
    for i, log in enumerate(c["log"]):
        start, end = c["start_s"][i], c["end_s"][i]
        if c["frames"][i] and start is not None and end is not None and start >= EPOCH_MIN_S:
            per_vehicle.setdefault(c["vehicle"][i], []).append((start, end, c["frames"][i], log))
    found = []
    for vehicle, logs in sorted(per_vehicle.items()):
        logs.sort()
        for j, (s1, e1, n1, a) in enumerate(logs):
            for s2, e2, n2, b in logs[j + 1 :]:
                if s2 >= e1 - OVERLAP_MIN_S:  # sorted by start: no later log overlaps this one
                    break
                overlap_s = min(e1, e2) - s2
                if overlap_s > OVERLAP_MIN_S and (s1, e1, n1) != (s2, e2, n2):
                    found.append((vehicle, a, b, overlap_s))
    return found


def _overlaps(c: dict, lines: list) -> None:
    found = overlapping_logs(c)
    if not found:
        return
    lines += [
        f"## Logs of one vehicle that overlap in time ({len(found)} pairs)",
        "",
        "One truck drives one log at a time: these logs are two trucks' under one vehicle name (or one drive logged "
        "twice), and the vehicle's peaks, hours and health fit mix them. Put each truck's logs under its own "
        "vehicle (a folder per truck, --vehicle-from or a --manifest), then run again.",
        "",
        "| vehicle | log | overlaps | by |",
        "|---|---|---|---|",
    ]
    lines += [
        f"| {_cell(v)} | {_cell(os.path.basename(a))} | {_cell(os.path.basename(b))} | {_fmt_s(s)} |"
        for v, a, b, s in found[:50]
    ]
    if len(found) > 50:
        lines.append(f"\n... and {len(found) - 50} more pairs")
    lines.append("")


def _duplicates(c: dict, lines: list) -> None:
    dups = duplicate_logs(c)
    if not dups:
        return
    lines += [
        f"## Logs that look like copies ({len(dups)} groups)",
        "",
        "Same first and last frame time, same number of frames: each copy is summarised and its hours counted again "
        "above; copies under two vehicles (Unix frame times only) also give one truck's drive to another. Remove "
        "the copies, then run again with --prune (it removes the rows of logs no longer at their path; a re-run "
        "skips what is done).",
        "",
        "| logs | vehicles |",
        "|---|---|",
    ]
    lines += [
        "| " + _cell(", ".join(os.path.basename(x) for x in g)) + " | " + _cell(", ".join(copy_vehicles(c, g))) + " |"
        for g in dups[:50]
    ]
    lines.append("")


def _flag_table(fl: dict, rows: list) -> list:
    lines = ["| vehicle | effect | in the period from | value | own baseline | why |", "|---|---|---|---|---|---|"]
    for i in rows:
        lines.append(
            f"| {_cell(fl['vehicle'][i])} | {fl['effect'][i]} | {fl['start'][i]} | {fl['value'][i]:.2f} | "
            f"{fl['baseline'][i]:.2f} | {fl['reason'][i]} |"
        )
    return lines + [""]


def _read_flags(path: Path) -> dict:
    if not path.is_file():
        return {"vehicle": []}
    import pyarrow.parquet as pq

    return _cols(pq.read_table(path))


def period_axis(ax, periods: dict) -> None:
    """Whole periods only, at most 8 ticks, each labelled with its period's first day when the table has it."""
    from matplotlib.ticker import FuncFormatter, MaxNLocator

    first = {}
    for q, d in zip(periods["period"], periods.get("start", [None] * len(periods["period"]))):
        if d is not None and q not in first:
            first[q] = str(d)[:10]
    ax.xaxis.set_major_locator(MaxNLocator(nbins=8, integer=True))
    if first:
        ax.xaxis.set_major_formatter(
            FuncFormatter(lambda x, _pos: first.get(int(round(x)), "") if abs(x - round(x)) < 1e-9 else "")
        )
        ax.tick_params(axis="x", labelrotation=30)
        ax.set_xlabel("period, labelled by its first day")
    else:
        ax.set_xlabel("period")


def _health(out: Path, lines: list) -> bool:
    """The fleet health section from DIR/health; False when there is none."""
    p = out / HEALTH / "periods.parquet"
    if not p.is_file():
        return False
    import pyarrow.parquet as pq

    periods = _cols(pq.read_table(p))
    fl = _read_flags(out / HEALTH / "flags.parquet")
    wt = _read_flags(out / HEALTH / "watch.parquet")
    from tools.fleet.health import JUDGED_PERIODS, level_short, level_short_sentence

    counts: dict = {}
    for v in periods["vehicle"]:
        counts[v] = counts.get(v, 0) + 1
    judged = sum(n >= JUDGED_PERIODS for n in counts.values())
    lines += [
        "## Fleet health (--diagnose)",
        "",
        f"{len(counts)} vehicles, {len(periods['vehicle'])} vehicle-periods fitted; {judged} of the "
        f"{len(counts)} vehicles have the {JUDGED_PERIODS} periods a drift needs before it can be flagged "
        f"(a baseline, then a run of drifting periods): the others cannot be flagged yet. "
        f"Flagged: {len(fl['vehicle'])}. To watch (oil level from the oil temperature): {len(wt['vehicle'])}. "
        f"(From the health tables of the last --diagnose run into this folder.)",
        "",
    ]
    short = level_short(
        {"vehicle": v, "level_logs": n}
        for v, n in zip(periods["vehicle"], periods.get("level_logs", [0] * len(periods["vehicle"])))
    )
    if short:
        text = level_short_sentence(short)
        lines += [text[0].upper() + text[1:] + ".", ""]
    if fl["vehicle"]:
        lines += _flag_table(fl, range(len(fl["vehicle"])))
    order = _vehicle_order(periods, sorted(set(fl["vehicle"])), sorted(set(wt["vehicle"])))
    _fitted_tables(periods, order, lines)
    if wt["vehicle"]:
        lines += [
            "### To watch: check the oil level",
            "",
            "These trucks are not judged on a measured oil level (J1939 SPN 124: not sent, sent in too few "
            "periods, or below a plausible fill), and the oil volume estimated from their oil temperature "
            "drifted down. That estimate is not identifiable: a 4 L leak moves the "
            "oil temperature by a few tenths of a kelvin, less than the onboard model's own error in 8 of the "
            "9 drives and starts measured, and on the synthetic validation fleets such drifts were right 2 "
            "times in 7 (see 'Measured' in the fleet documentation, docs/fleet.md). A dipstick check, not a "
            "diagnosis.",
            "",
        ]
        lines += _flag_table(wt, range(len(wt["vehicle"])))
    _health_plot(periods, order, set(fl["vehicle"]) | set(wt["vehicle"]), out, lines)
    return True


#: the fitted values the report shows per vehicle and period: (column, its standard error, heading, format)
FITTED = (
    (
        "cooler_scale",
        "cooler_se",
        "Cooler effectiveness scale [-] (1: the parameters' cooler; lower: fouled, bypassed)",
        "{:.2f}",
    ),
    (
        "oil_volume_l",
        "oil_volume_se",
        "Oil volume from the oil temperature [L] (not identifiable from it: a dipstick check, not a diagnosis)",
        "{:.1f}",
    ),
    ("oil_level_pct", "oil_level_se", "Measured oil level, SPN 124 [%]", "{:.1f}"),
)
#: the vehicles and the (latest) periods the tables show at most
TABLE_VEHICLES, TABLE_PERIODS = 30, 8
#: a period's fleet spread needs at least this many vehicles to mark one outside it
SPREAD_MIN_VEHICLES = 3


def _period_spread(periods: dict, attr: str) -> dict:
    """Per period: (the fleet's median, its spread, how many vehicles have a value) of column ``attr``."""
    from tools.fleet.health import at_grid_edge, fleet_spread

    out = {}
    for q in sorted(set(periods["period"])):
        vals = [
            x
            for x, p in zip(periods[attr], periods["period"])
            if p == q and math.isfinite(x) and not at_grid_edge(attr, x)
        ]
        out[q] = (*fleet_spread(vals), len(vals))
    return out


def _below(attr: str, x: float, se: float, spread: tuple) -> bool:
    """A value below the fleet's spread in its period (where a fouled cooler or a low oil volume goes): more than
    SPREAD_OUTSIDE spreads, 3 of its standard errors and the smallest drop a flag counts below the median (trucks
    that fit alike, as simulated ones do, have a spread near 0: a hundredth is no finding)."""
    from tools.fleet.health import DRIFT_MIN, LEVEL_DRIFT_MIN_SHARE, SPREAD_OUTSIDE

    med, sp, n = spread
    least = {
        "cooler_scale": DRIFT_MIN["cooler_effectiveness_scale"],
        "oil_volume_l": DRIFT_MIN["oil_level_low"],
        "oil_level_pct": LEVEL_DRIFT_MIN_SHARE * med,
    }[attr]
    drop = med - x
    return (
        n >= SPREAD_MIN_VEHICLES and math.isfinite(x) and drop > max(SPREAD_OUTSIDE * sp, least) and not drop <= 3 * se
    )


def _vehicle_order(periods: dict, flagged: list, watched: list) -> list:
    """The flagged vehicles, the watched ones, then the others by how far their fitted cooler sits below the fleet's
    median (in spreads, their worst period), the farthest first."""
    spread = _period_spread(periods, "cooler_scale")
    depth: dict = {}
    for v, q, x in zip(periods["vehicle"], periods["period"], periods["cooler_scale"]):
        med, sp, _ = spread[q]
        z = (med - x) / sp if math.isfinite(x) and math.isfinite(sp) else -math.inf
        depth[v] = max(depth.get(v, -math.inf), z)
    first = flagged + [v for v in watched if v not in flagged]
    return first + sorted((v for v in depth if v not in first), key=lambda v: (-depth[v], v))


def _fitted_tables(periods: dict, order: list, lines: list) -> None:
    """Per fitted value a table vehicle x period, with the fleet's median and spread of each period."""
    from tools.fleet.health import COOLER_GRID, DRIFT_MIN, SPREAD_OUTSIDE, VOLUME_GRID_L, at_grid_edge

    per = sorted(set(periods["period"]))[-TABLE_PERIODS:]
    start = {}
    for q, d in zip(periods["period"], periods["start"]):
        start.setdefault(q, str(d)[:10])
    at = {(v, q): i for i, (v, q) in enumerate(zip(periods["vehicle"], periods["period"]))}
    shown = order[:TABLE_VEHICLES]
    lines += [
        "### Fitted values per vehicle and period",
        "",
        f"Each vehicle's fitted value per period (columns: the period's first day) +/- its standard error, "
        f"beside the fleet's median and spread (1.4826 x the median absolute deviation) in that period. "
        f"**below**: "
        f"below the median by more than {SPREAD_OUTSIDE:g} spreads, 3 standard errors and the drop a flag "
        f"needs ({DRIFT_MIN['cooler_effectiveness_scale']:g} cooler, {DRIFT_MIN['oil_level_low']:g} L oil; "
        f"with at least {SPREAD_MIN_VEHICLES} vehicles in the period), where a "
        f"fouled cooler or a low oil level goes (a weak cooler also pulls the oil volume's estimate down); a "
        f"flag needs a drift from the vehicle's own baseline as well. Flagged and watched vehicles first, "
        f"then the farthest below the fleet's cooler median. (grid edge): the fit ran to the end of what it tries "
        f"(cooler {COOLER_GRID[0]:g}-{COOLER_GRID[-1]:g}, oil {VOLUME_GRID_L[0]:g}-{VOLUME_GRID_L[-1]:g} L): a bound, "
        "not an estimate, left out of the fleet's median and spread; at the top, the log is likely another "
        "gearbox's (check --gearbox) or one the model misses.",
        "",
    ]
    n_periods = len(set(periods["period"]))
    if len(order) > len(shown) or n_periods > len(per):
        lines[-2] += (
            f" Shown: {len(shown)} of {len(order)} vehicles, the last {len(per)} of {n_periods} periods; "
            f"all in health/periods.parquet."
        )
    for attr, se, heading, fmt in FITTED:
        if not np.isfinite(np.asarray(periods.get(attr, []), dtype=float)).any():
            continue
        spread = _period_spread(periods, attr)
        lines += [
            f"{heading}:",
            "",
            "| vehicle | " + " | ".join(start[q] for q in per) + " |",
            "|---|" + "---|" * len(per),
        ]
        for v in shown:
            cells = []
            for q in per:
                i = at.get((v, q))
                x = periods[attr][i] if i is not None else math.nan
                if not math.isfinite(x):
                    cells.append("-")
                    continue
                e = periods[se][i]
                txt = fmt.format(x) + (f" +/- {fmt.format(e)}" if math.isfinite(e) else "")
                txt += " (grid edge)" if at_grid_edge(attr, x) else ""
                cells.append(f"**{txt} below**" if _below(attr, x, e, spread[q]) else txt)
            lines.append(f"| {_cell(v)} | " + " | ".join(cells) + " |")
        lines.append(
            "| fleet median | " + " | ".join(fmt.format(spread[q][0]) if spread[q][2] else "-" for q in per) + " |"
        )
        lines.append(
            "| fleet spread | " + " | ".join(fmt.format(spread[q][1]) if spread[q][2] >= 2 else "-" for q in per) + " |"
        )
        lines.append("")


def _health_plot(periods: dict, order: list, marked: set, out: Path, lines: list) -> None:
    """The fitted values per period of at most 8 vehicles (the flagged and watched first, then the farthest below
    the fleet's cooler median) over the fleet's median and spread."""
    from tools.fleet.health import SPREAD_OUTSIDE

    plotted = order[:8]
    plt = _plt()
    panels = [
        (a, e, h.split(" (")[0])
        for a, e, h, _ in FITTED
        if np.isfinite(np.asarray(periods.get(a, []), dtype=float)).any()
    ]
    fig, axes = plt.subplots(1, len(panels), figsize=(6 * len(panels), 4.5), squeeze=False)
    for ax, (attr, se, label) in zip(axes[0], panels):
        spread = _period_spread(periods, attr)
        per = [q for q in sorted(spread) if spread[q][2]]
        med = np.array([spread[q][0] for q in per])
        band = np.array([spread[q][1] if spread[q][2] >= SPREAD_MIN_VEHICLES else 0.0 for q in per])
        ax.fill_between(
            per,
            med - SPREAD_OUTSIDE * band,
            med + SPREAD_OUTSIDE * band,
            color="0.85",
            label=f"fleet median +/- {SPREAD_OUTSIDE:g} spreads",
        )
        ax.plot(per, med, "k--", marker="." if len(per) == 1 else None, label="fleet median")
        for v in plotted:
            idx = [i for i in range(len(periods["vehicle"])) if periods["vehicle"][i] == v]
            ax.errorbar(
                [periods["period"][i] for i in idx],
                [periods[attr][i] for i in idx],
                yerr=[
                    min(periods[se][i], 1.0 if attr != "oil_level_pct" else 10.0)
                    if math.isfinite(periods[se][i])
                    else 0
                    for i in idx
                ],
                marker="o",
                capsize=2,
                label=v + (" (flagged or watched)" if v in marked else ""),
            )
        period_axis(ax, periods)
        ax.set_ylabel(label)
        ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.suptitle(
        f"Fitted values per period (1 standard error) of {len(plotted)} of {len(order)} vehicles: "
        f"flagged and watched first, then the farthest below the fleet's cooler median"
    )
    fig.tight_layout()
    _save(fig, out / "report_health.png")
    plt.close(fig)
    lines += ["![health](report_health.png)", ""]


def truck_hours(c: dict) -> str:
    """The trusted logs' hours, and those of the untrusted ones apart: a log whose time stamps are milliseconds read as
    seconds (untrusted) added 3.0 h for 3 minutes of driving."""
    duration = np.asarray(c["duration_s"], dtype=float)
    trusted = np.array([t is not False for t in c.get("trusted", [None] * duration.size)], dtype=bool)
    text = f"{float(np.nansum(duration[trusted])) / 3600:.1f} truck-hours"
    if (~trusted).any():
        text += (
            f" ({float(np.nansum(duration[~trusted])) / 3600:.1f} h more in {int(np.sum(~trusted))} untrusted "
            "logs, not counted: their time base or inputs are suspect)"
        )
    return text


def _undated(c: dict, lines: list) -> None:
    """The logs without a date, and why: they are left out of --diagnose's periods."""
    from tools.fleet.summary import EPOCH_MIN_S

    bad = [i for i, d in enumerate(c["date"]) if d == "unknown"]
    if not bad:
        return
    lines += [
        f"## Logs without a date ({len(bad)}, left out of the fleet health)",
        "",
        f"A log's date is the UTC day of its first frame when its frame times are Unix time (at least "
        f"{EPOCH_MIN_S:.0e} s: candump -L, and .blf, .mf4 and .trc logs that record their start), the date in "
        f"a Vector .asc header, or the manifest's date column. These logs have none of them: their frame times "
        f"count from the logger's start, or lie within a week after a clock's reset day (a real-time clock's "
        f"2000-01-01, GPS's 1980-01-06: a logger that lost its time). Give their dates in a --manifest (column "
        f"date) or by --vehicle-from's (?P<date>...) in the file name.",
        "",
        "| vehicle | log | first frame time |",
        "|---|---|---|",
    ]
    lines += [
        f"| {_cell(c['vehicle'][i])} | {_cell(os.path.basename(c['log'][i]))} | {c['start_s'][i]:.3f} s |"
        for i in bad[:50]
    ]
    if len(bad) > 50:
        lines.append(f"\n... and {len(bad) - 50} more (the summary's date is 'unknown')")
    lines.append("")


def write_report(out: str | os.PathLike, health_why_none: str = "") -> Path:
    """Write DIR/report.md (and its plots) from the tables in DIR; returns its path. ``health_why_none``: why a
    --diagnose run just now fitted nothing (said in the report when no earlier run left health tables)."""
    out = Path(out)
    summary = read_table(out)
    errors = read_table(out, ERRORS)
    lines = ["# Fleet report", ""]
    if summary is None:
        lines += ["No log was summarised."]
    else:
        c = _cols(summary)
        dated = sorted(d for d in c["date"] if d != "unknown")
        undated = len(c["date"]) - len(dated)
        span = (f"dates {dated[0]} to {dated[-1]}" if dated else "no dates") + (
            f" ({undated} logs without a date: their frame times are not Unix time, or a clock's reset day, and "
            f"the manifest gives none; listed below)"
            if undated
            else ""
        )
        lines += [
            f"{len(c['log'])} logs, {len(set(c['vehicle']))} vehicles, {truck_hours(c)}; "
            f"{span}. Mean degraded share "
            f"{100 * float(np.mean(c['degraded_share'])):.1f} %; frames rejected: "
            f"{sum(sum(c[k]) for k in c if k.startswith('rejected_'))} of {sum(c['frames'])}.",
            "",
        ]
        _undated(c, lines)
        _duplicates(c, lines)
        _overlaps(c, lines)
        _gone(c, lines)
        _malformed(c, lines)
        c = _trusted_only(c, lines)
        warned_section(c, lines)
        if c["log"]:
            _hottest(c, lines)
            _plots(c, out, lines)
        else:
            for png in ("report_peaks.png", "report_above_warning.png"):
                (out / png).unlink(missing_ok=True)
            lines += [
                "No log is trusted, so no peak or time above a warning is shown: report_peaks.png and "
                "report_above_warning.png not written.",
                "",
            ]
    if not _health(out, lines) and health_why_none:
        (out / "report_health.png").unlink(missing_ok=True)
        lines += [
            "## Fleet health (--diagnose)",
            "",
            f"Nothing fitted: {health_why_none}; report_health.png not written.",
            "",
        ]
    if errors is not None and errors.num_rows:
        e = _cols(errors)
        lines += ["## Logs that could not be read", "", "| log | stage | reason |", "|---|---|---|"]
        lines += [
            f"| {_cell(os.path.basename(e['log'][i]))} | {e['stage'][i]} | {_cell(e['reason'][i])} |"
            for i in range(min(len(e["log"]), 50))
        ]
        if len(e["log"]) > 50:
            lines.append(f"\n... and {len(e['log']) - 50} more in the errors table (errors/*.parquet)")
        lines.append("")
    path = out / "report.md"
    tmp = path.with_name(".report.md.tmp")
    tmp.write_text("\n".join(lines))
    os.replace(tmp, path)
    return path


__all__ = ["OVERLAP_MIN_S", "duplicate_logs", "overlapping_logs", "period_axis", "write_report"]
