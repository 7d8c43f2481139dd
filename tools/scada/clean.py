"""The rules a SCADA record's values pass, each rejection counted (docs/real-data.md, "Bad rows").

Per channel of the column map, in this order: an empty cell is ``missing``; a value that is no number or lies
outside the channel's ``range`` is ``implausible``; a value further than ``jump_k`` from both neighbours of its
stretch, on the same side (a one-row spike), is a ``jump``, and so is a measured temperature's run of up to
SPIKE_RUN_S off the readings around it (:func:`glitch_runs`); a measured temperature the same to the bit for
STUCK_MIN_S or more while the load or the air moved is ``stuck`` after its first row. Each of these leaves NaN in
the channel, the row stays. A derived input torque is 0 where the rotor stands still (speed below the map's
``standstill_rpm``: ``standstill``) and where the power (or the converter torque) is negative, the turbine drawing
from the grid (``negative_power``): those rows stay, counted, with no load on the gearbox. The reader's own reasons
(lines, time stamps, gaps) are counted in the same dictionary.
"""

from __future__ import annotations

import numpy as np

from firmware_model.units import RAD_S_PER_RPM
from tools.scada.columns import Channel, ColumnMap

#: every reason a row or value is dropped, repaired or flagged, in report order
REASONS = (
    "bad_bytes",
    "bad_line",
    "bad_time",
    "out_of_order",
    "duplicate_time",
    "conflicting_time",
    "gap",
    "missing",
    "implausible",
    "jump",
    "stuck",
    "standstill",
    "negative_power",
)
#: each reason in words, for reports
REASON_WORDS = {
    "bad_bytes": "lines with bytes that are not UTF-8 (read as U+FFFD: a cell with one is dropped)",
    "bad_line": "lines with the wrong number of fields (dropped)",
    "bad_time": "time stamps that do not parse or carry no UTC offset (row dropped)",
    "out_of_order": "rows earlier than a row before them in their file (sorted into place)",
    "duplicate_time": "repeated time stamps with the same values (one row kept)",
    "conflicting_time": "rows repeating a time stamp with other values (none of them kept)",
    "gap": "gaps (a step over 1.5 periods): a new stretch starts, models reset",
    "missing": "empty cells (NaN)",
    "implausible": "values outside the channel's range or not numbers (NaN)",
    "jump": "spikes beyond the channel's jump_k (NaN; an input's one row, a gearbox temperature's up to an hour)",
    "stuck": "measured temperatures stuck at one value for a day or more while the load or the air moved (NaN after "
    "the run's first)",
    "standstill": "rows with the rotor standing still (input torque 0)",
    "negative_power": "rows drawing power from the grid (input torque 0)",
}
#: the reasons counted per channel
CHANNEL_REASONS = ("missing", "implausible", "jump", "stuck")
#: a temperature reading the same to the bit for this long is a stuck sensor or logger [s] (the shared turbines'
#: longest such runs: 14-33 rows of 10 min, 5.5 h, a cold bearing at standstill; a stuck channel read as the
#: gearbox's put a bearing 6.8 K RMS off and fitted a fleet month's bearing loss at 0.58: a new user's review)
STUCK_MIN_S = 86400.0
#: ... while the turbine's load or air moved: the input torque over this share of its record's largest, or the air
#: around the gearbox over this many kelvin (a steady run, a plant's or a rig's, settles to the bit: not stuck)
STUCK_LOAD_SHARE, STUCK_AIR_K = 0.2, 5.0


def spikes(x: np.ndarray, stretch: np.ndarray, jump: float) -> np.ndarray:
    """Rows further than ``jump`` from both neighbours in their stretch, on the same side; and a stretch's first row
    further than ``jump`` from the next one where that one and its own next agree within ``jump``: a glitch is not
    taken as where a model starts (NaN neighbours never make a spike; a last row, with one neighbour, never is)."""
    prev = np.r_[np.nan, x[:-1]]
    nxt = np.r_[x[1:], np.nan]
    with_prev = np.r_[False, stretch[1:] == stretch[:-1]]
    with_next = np.r_[stretch[:-1] == stretch[1:], False]
    up, down = x - prev, x - nxt
    with np.errstate(invalid="ignore"):
        inner = with_prev & with_next & (np.abs(up) > jump) & (np.abs(down) > jump) & (np.sign(up) == np.sign(down))
        nxt2 = np.r_[x[2:], np.full(min(2, x.size), np.nan)]
        with_next2 = with_next & np.r_[with_next[1:], False]
        first = ~with_prev & with_next2 & (np.abs(down) > jump) & (np.abs(nxt - nxt2) <= jump)
    return inner | first


#: a measured gearbox temperature off its readings before and after by more than its ``jump_k``, on one side, for at
#: most this long is a glitch too (a sensor's dropout to -40 or 0 degC: a part's thermal mass does not leave and come
#: back by 20 K within an hour), and its neighbours may lie across a gap up to this long [s]; the air around the
#: gearbox can move so (a door, a heater): its spikes stay one row
SPIKE_RUN_S = 3600.0


def glitch_runs(x: np.ndarray, linked: np.ndarray, jump: float, max_rows: int) -> np.ndarray:
    """Runs of 1..``max_rows`` rows further than ``jump`` from both the value before the run and the value after
    it, all on one side, the three in one ``linked`` stretch (stretches joined across gaps of up to SPIKE_RUN_S);
    and a linked stretch's last row off the two before it, which agree."""
    out = np.zeros(x.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        step = np.abs(np.diff(x)) > jump
    for a in np.flatnonzero(step & (linked[1:] == linked[:-1])) + 1:  # a run's first row: a step from the row before
        if out[a - 1]:
            continue  # the step back from a glitch run (its good rows are no run of their own)
        p, sign = x[a - 1], 1.0 if x[a] > x[a - 1] else -1.0
        b = a
        while b < x.size and b - a < max_rows and linked[b] == linked[a - 1] and sign * (x[b] - p) > jump:
            b += 1
        if b == a or b >= x.size or linked[b] != linked[a - 1] or not np.isfinite(x[b]):
            continue
        if np.min(sign * (x[a:b] - x[b])) > jump:
            out[a:b] = True
    # a linked stretch's last row further than jump from the one before, where that one and its own previous agree
    # (the mirror of spikes' first row: a sump read at -40 degC on a turbine's last row before a day's gap)
    last = np.flatnonzero(np.r_[linked[1:] != linked[:-1], True])
    last = last[last >= 2]
    with np.errstate(invalid="ignore"):
        same = (linked[last - 2] == linked[last]) & (np.abs(x[last - 1] - x[last - 2]) <= jump)
        same &= ~out[last - 1] & ~out[last - 2]  # (not the row a glitch run came back on)
        out[last[same & (np.abs(x[last] - x[last - 1]) > jump)]] = True
    return out


def stuck_runs(x: np.ndarray, stretch: np.ndarray, min_rows: int) -> list[tuple[int, int]]:
    """[start, stop) of each run of at least ``min_rows`` rows of one stretch whose finite values are the same to
    the bit (NaN ends a run)."""
    if x.size < 2:
        return []
    same = (x[1:] == x[:-1]) & (stretch[1:] == stretch[:-1])
    edges = np.flatnonzero(np.diff(np.r_[0, same.astype(np.int8), 0]))
    return [(int(a), int(b) + 1) for a, b in zip(edges[::2], edges[1::2]) if b + 1 - a >= min_rows]


def _moved(values: dict, a: int, b: int) -> bool:
    """Whether the load or the air around the gearbox moved over rows [a, b) (STUCK_LOAD_SHARE, STUCK_AIR_K)."""

    def span(x):
        x = x[a:b][np.isfinite(x[a:b])]
        return float(x.max() - x.min()) if x.size else 0.0

    torque, air = values.get("input_torque_nm"), values.get("ambient_temp_c")
    if torque is not None and np.isfinite(torque).any():
        if span(torque) > STUCK_LOAD_SHARE * float(np.nanmax(np.abs(torque))):
            return True
    return air is not None and span(air) > STUCK_AIR_K


def _checked(
    name: str,
    x: np.ndarray,
    ch: Channel,
    stretch: np.ndarray,
    by: dict,
    stuck: dict,
    stuck_rows: int = 0,
    inputs: dict | None = None,
    glitch: tuple | None = None,
) -> np.ndarray:
    """``x`` with its missing, implausible, spike (``glitch``: (linked stretches, rows) of :func:`glitch_runs` as
    well) and (``stuck_rows``: runs that long while ``inputs`` moved, see :func:`_moved`) stuck values NaN, each
    counted in ``by[name]``; each stuck run in ``stuck[name]``: (start, stop, value)."""
    x = x.copy()
    miss = np.isnan(x)
    bad = ~miss & ~np.isfinite(x)
    if ch.range is not None:
        with np.errstate(invalid="ignore"):
            bad |= ~miss & ((x < ch.range[0]) | (x > ch.range[1]))
    x[bad] = np.nan
    jump = spikes(x, stretch, ch.jump_k) if ch.jump_k else np.zeros(x.shape, bool)
    if ch.jump_k and glitch is not None:  # a measured temperature: runs of up to an hour, across short gaps
        jump |= glitch_runs(np.where(jump, np.nan, x), glitch[0], ch.jump_k, glitch[1])
    x[jump] = np.nan
    # across gaps of up to SPIKE_RUN_S too (a logger that drops a row now and then breaks no stuck run)
    runs_in = stretch if glitch is None else glitch[0]
    runs = [r for r in stuck_runs(x, runs_in, stuck_rows) if _moved(inputs or {}, *r)] if stuck_rows else []
    values = [float(x[a]) for a, _ in runs]
    for a, b in runs:
        x[a + 1 : b] = np.nan  # the first is a reading; the rest repeat it
    by[name] = {"missing": int(miss.sum()), "implausible": int(bad.sum()), "jump": int(jump.sum())}
    by[name]["stuck"] = sum(b - a - 1 for a, b in runs)
    if runs:
        stuck[name] = [(a, b, v) for (a, b), v in zip(runs, values)]
    return x


#: a load over this share of the record's large loads (the 99th percentile while turning) while the rotor's speed
#: reads standstill is no standstill: a generator makes no power standing still, so the speed reading is implausible
LOAD_AT_STANDSTILL_SHARE = 0.05


def _derived(ch: Channel, raw: dict, cmap: ColumnMap, counts: dict, implausible_speed: dict) -> np.ndarray:
    """A derived input torque [N m]: P / omega_rotor or Cm * fast / slow, 0 at standstill and under negative load;
    NaN where the speed reads standstill under a load (LOAD_AT_STANDSTILL_SHARE), those rows' mask kept in
    ``implausible_speed`` under the speed's column."""
    src = ch.sources
    speed_col = src["speed"] if ch.derive == "power_over_speed" else src["slow_speed"]
    speed = raw[speed_col] * ch.speed_scale  # rpm
    load = raw[src["power"] if ch.derive == "power_over_speed" else src["torque"]] * ch.source_scale
    # the record's large loads while the rotor turns: a high percentile, so that one stray value does not set it
    with np.errstate(invalid="ignore"):
        turning = np.isfinite(load) & (speed >= cmap.standstill_rpm)
    top = float(np.percentile(load[turning], 99.0)) if turning.any() else np.nan
    with np.errstate(invalid="ignore"):
        loaded_still = (speed < cmap.standstill_rpm) & (load > LOAD_AT_STANDSTILL_SHARE * top) & (top > 0.0)
        still = (speed < cmap.standstill_rpm) & ~loaded_still
        negative = load < 0.0
    implausible_speed[speed_col] = loaded_still
    moving = ~still & ~negative
    # a source cell that is no number (inf: the reader's mark) is no reading either: no torque, not 0
    unread = ~np.isfinite(load) | ~np.isfinite(speed) | loaded_still
    if ch.derive != "power_over_speed":
        unread |= ~np.isfinite(raw[src["fast_speed"]])
    moving &= ~unread
    out = np.where(unread, np.nan, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        if ch.derive == "power_over_speed":
            val = load / (speed * RAD_S_PER_RPM)
        else:
            val = load * raw[src["fast_speed"]] * ch.speed_scale / speed  # the ratio fast / slow
    out[moving] = val[moving]
    counts["standstill"] += int(np.sum(still))
    counts["negative_power"] += int(np.sum(negative))
    return out * ch.scale + ch.offset


def clean_values(
    raw: dict, stretch: np.ndarray, cmap: ColumnMap, counts: dict, time_s: np.ndarray | None = None
) -> tuple[dict, dict, dict]:
    """(channel -> values, channel -> reason -> count, channel -> its stuck runs [(start, stop, value)]) of every
    input and measured channel of ``cmap``; the totals are added to ``counts``. ``time_s``: the rows' times, for
    the measured channels' glitch runs (SPIKE_RUN_S; None: one-row spikes only)."""
    values, by, stuck, implausible_speed = {}, {}, {}, {}
    stuck_rows = int(np.ceil(STUCK_MIN_S / cmap.period_s))
    glitch = None
    if time_s is not None and len(time_s):
        # stretches joined across gaps of up to SPIKE_RUN_S (never split where a stretch is not: hourly rows)
        apart = np.diff(np.asarray(time_s, dtype=float)) > SPIKE_RUN_S
        linked = np.cumsum(np.r_[False, apart & (np.diff(stretch) != 0)])
        glitch = (linked, max(1, int(SPIKE_RUN_S // cmap.period_s)))
    for name, ch in cmap.channels.items():
        if ch.derive:
            x = _derived(ch, raw, cmap, counts, implausible_speed)
        else:
            x = raw[ch.column]
            x = np.where(np.isfinite(x), x * ch.scale + ch.offset, x)
        measured = name in cmap.measured  # (the map's inputs come first: the load and the air are read by then)
        values[name] = _checked(
            name, x, ch, stretch, by, stuck, stuck_rows if measured else 0, values, glitch if measured else None
        )
    for name, ch in cmap.channels.items():  # a speed read as standstill under a load: implausible, NaN
        bad = implausible_speed.get(ch.column) if not ch.derive else None
        if bad is not None and bad.any():
            bad = bad & np.isfinite(values[name])
            values[name] = np.where(bad, np.nan, values[name])
            by[name]["implausible"] += int(bad.sum())
    for reason in CHANNEL_REASONS:
        counts[reason] += sum(c[reason] for c in by.values())
    return values, by, stuck
