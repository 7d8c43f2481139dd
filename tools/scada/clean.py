"""The rules a SCADA record's values pass, each rejection counted (docs/real-data.md, "Bad rows").

Per channel of the column map, in this order: an empty cell is ``missing``; a value that is no number or lies
outside the channel's ``range`` is ``implausible``; a value further than ``jump_k`` from both neighbours of its
stretch, on the same side (a one-row spike), is a ``jump``. Each of these leaves NaN in the channel, the row stays.
A derived input torque is 0 where the rotor stands still (speed below the map's ``standstill_rpm``: ``standstill``)
and where the power (or the converter torque) is negative, the turbine drawing from the grid (``negative_power``):
those rows stay, counted, with no load on the gearbox. The reader's own reasons (lines, time stamps, gaps) are
counted in the same dictionary.
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
    "gap",
    "missing",
    "implausible",
    "jump",
    "standstill",
    "negative_power",
)
#: each reason in words, for reports
REASON_WORDS = {
    "bad_bytes": "lines with bytes that are not UTF-8 (read as U+FFFD: a cell with one is dropped)",
    "bad_line": "lines with the wrong number of fields (dropped)",
    "bad_time": "time stamps that do not parse or carry no UTC offset (row dropped)",
    "out_of_order": "rows earlier than a row before them in their file (sorted into place)",
    "duplicate_time": "repeated time stamps (the first row kept)",
    "gap": "gaps (a step over 1.5 periods): a new stretch starts, models reset",
    "missing": "empty cells (NaN)",
    "implausible": "values outside the channel's range or not numbers (NaN)",
    "jump": "one-row spikes beyond the channel's jump_k (NaN)",
    "standstill": "rows with the rotor standing still (input torque 0)",
    "negative_power": "rows drawing power from the grid (input torque 0)",
}
#: the reasons counted per channel
CHANNEL_REASONS = ("missing", "implausible", "jump")


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


def _checked(name: str, x: np.ndarray, ch: Channel, stretch: np.ndarray, by: dict) -> np.ndarray:
    """``x`` with its missing, implausible and spike values NaN, each counted in ``by[name]``."""
    x = x.copy()
    miss = np.isnan(x)
    bad = ~miss & ~np.isfinite(x)
    if ch.range is not None:
        with np.errstate(invalid="ignore"):
            bad |= ~miss & ((x < ch.range[0]) | (x > ch.range[1]))
    x[bad] = np.nan
    jump = spikes(x, stretch, ch.jump_k) if ch.jump_k else np.zeros(x.shape, bool)
    x[jump] = np.nan
    by[name] = {"missing": int(miss.sum()), "implausible": int(bad.sum()), "jump": int(jump.sum())}
    return x


def _derived(ch: Channel, raw: dict, cmap: ColumnMap, counts: dict) -> np.ndarray:
    """A derived input torque [N m]: P / omega_rotor or Cm * fast / slow, 0 at standstill and under negative load."""
    src = ch.sources
    speed = raw[src["speed"] if ch.derive == "power_over_speed" else src["slow_speed"]] * ch.speed_scale  # rpm
    load = raw[src["power"] if ch.derive == "power_over_speed" else src["torque"]] * ch.source_scale
    with np.errstate(invalid="ignore"):
        still = speed < cmap.standstill_rpm
        negative = load < 0.0
    moving = ~still & ~negative
    out = np.where(np.isnan(load) | np.isnan(speed), np.nan, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        if ch.derive == "power_over_speed":
            val = load / (speed * RAD_S_PER_RPM)
        else:
            val = load * raw[src["fast_speed"]] * ch.speed_scale / speed  # the ratio fast / slow
    out[moving] = val[moving]
    counts["standstill"] += int(np.sum(still))
    counts["negative_power"] += int(np.sum(negative))
    return out * ch.scale + ch.offset


def clean_values(raw: dict, stretch: np.ndarray, cmap: ColumnMap, counts: dict) -> tuple[dict, dict]:
    """(channel -> values, channel -> reason -> count) of every input and measured channel of ``cmap``; the totals
    are added to ``counts``."""
    values, by = {}, {}
    for name, ch in cmap.channels.items():
        if ch.derive:
            x = _derived(ch, raw, cmap, counts)
        else:
            x = raw[ch.column]
            x = np.where(np.isfinite(x), x * ch.scale + ch.offset, x)
        values[name] = _checked(name, x, ch, stretch, by)
    for reason in CHANNEL_REASONS:
        counts[reason] += sum(c[reason] for c in by.values())
    return values, by
