"""One row per log: what a fleet engineer asks of a day's driving (tools/fleet; docs/fleet.md lists the columns).

From the sensor output run table of a log (``tools.replay.log.replay_log``) and its counters: when and how long it
ran; per published component the peak temperature and when, the time above the warning and the critical level, the
warnings raised and the shortest time to its limit; the degraded share; the rejected frames by reason; the oil
innovation (measured - modelled sump) mean and RMS.
"""

from __future__ import annotations

import datetime as dt
import math
import re

import numpy as np

from can_dbc.decoder import REJECT_REASONS
from firmware_model.components import MODE_NORMAL, MODE_OIL_MODEL, STEP_S
from firmware_model.limits import load_limits
from tools.published import ids

#: a log's frame time at or above this is taken as Unix time (after 1973): its date is the log's date ...
EPOCH_MIN_S = 1e8
#: ... below this (2100-01-01); at or above it, Unix time in milliseconds is said (tools.fleet.summary.log_date)
EPOCH_MAX_S = 4102444800.0
#: the date of EPOCH_MIN_S: an ASC header's date before it is no date either
EPOCH_MIN_DATE = dt.datetime.fromtimestamp(EPOCH_MIN_S, tz=dt.timezone.utc).date()
#: the days loggers' clocks start from when they lost their time (a real-time clock's 2000-01-01, GPS's 1980-01-06):
#: a log whose first frame lies within RESET_DAYS after one is dated by no clock (a new user's logs said "dates
#: 1980-01-06 to 2026-01-07")
RESET_EPOCHS = (dt.date(1980, 1, 6), dt.date(2000, 1, 1))
RESET_DAYS = 7
#: per component, the summary's columns (with the component id in place of {c})
COMPONENT_COLUMNS = (
    "peak_{c}_c",
    "peak_{c}_t_s",
    "above_warning_{c}_s",
    "above_critical_{c}_s",
    "warnings_{c}",
    "min_ttl_{c}_s",
    "warning_limit_{c}_c",
)


_MONTHS = {
    m: i + 1 for i, m in enumerate(("Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec"))
} | {"Mär": 3, "Mai": 5, "Okt": 10, "Dez": 12}
_ASC_DATE = re.compile(
    r"^(date|begin\s+triggerblock)\s+\w+\s+(\w{3})\s+(\d{1,2})\s+[\d:.]+(?:\s*[ap]m)?\s+(\d{4})", re.IGNORECASE
)


def asc_date(path) -> str | None:
    """The start date of a Vector ASC log from its header (python-can reads its frame times relative to the start,
    so they give none): the first 'Begin Triggerblock' with a date, else the 'date' line; None when neither parses."""
    found = {}
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            for _, line in zip(range(200), fh):
                m = _ASC_DATE.match(line.strip())
                if m and m.group(2).capitalize() in _MONTHS:
                    kind = "trigger" if m.group(1).lower() != "date" else "date"
                    try:
                        day = dt.date(int(m.group(4)), _MONTHS[m.group(2).capitalize()], int(m.group(3)))
                    except ValueError:
                        continue
                    # a writer without the start time stamps the epoch (python-can's ASCWriter: "Begin Triggerblock
                    # Thu Jan 01 00:00:00.0 1970"): no date, as a frame time before EPOCH_MIN_S is none
                    if day < EPOCH_MIN_DATE or is_reset_day(day):
                        continue
                    found.setdefault(kind, day.isoformat())
                    if kind == "trigger":
                        break
    except OSError:
        return None
    return found.get("trigger") or found.get("date")


def log_date(start_s: float) -> str | None:
    """The UTC date of a frame time that is Unix time, else None; InputError for a frame time that is Unix time in
    milliseconds (it was the raw "year 57983 is out of range", and the log's times 1000x too long)."""
    if not (math.isfinite(start_s) and start_s >= EPOCH_MIN_S):
        return None
    if start_s >= EPOCH_MAX_S:  # past 2099: no logger's clock, and no date Python can name past 9999
        if not EPOCH_MIN_S <= start_s / 1e3 < EPOCH_MAX_S:
            return None
        from firmware_model.errors import InputError

        as_ms = dt.datetime.fromtimestamp(start_s / 1e3, tz=dt.timezone.utc).date().isoformat()
        raise InputError(
            f"the log's first frame time {start_s:.0f} s is no date in seconds, but {as_ms} in milliseconds: its "
            f"time stamps look like milliseconds; give seconds (candump -L writes seconds)"
        )
    day = dt.datetime.fromtimestamp(start_s, tz=dt.timezone.utc).date()
    if is_reset_day(day):
        return None
    return day.isoformat()


def is_reset_day(day: dt.date) -> bool:
    """Whether a date lies within RESET_DAYS after a clock's reset epoch (RESET_EPOCHS): no real day of a log."""
    return any(0 <= (day - e).days < RESET_DAYS for e in RESET_EPOCHS)


def _component(row: dict, c: str, table) -> None:
    T = np.asarray(table[f"T_{c}_c"], dtype=float)
    level = np.asarray(table[f"W_{c}"], dtype=float)
    ttl = np.asarray(table[f"ttl_{c}_s"], dtype=float)
    t = np.asarray(table["time_s"], dtype=float)
    finite = np.isfinite(T)
    # the peak of the steps the sensor vouches for (level known): not an outage's held inputs nor its recovery
    # (docs/sensor.md, "Bad input"), unless no step is known
    if (finite & (level <= 2)).any():
        finite &= level <= 2
    if finite.any():
        i = int(np.nanargmax(np.where(finite, T, -np.inf)))
        row[f"peak_{c}_c"], row[f"peak_{c}_t_s"] = float(T[i]), float(t[i])
    else:
        row[f"peak_{c}_c"] = row[f"peak_{c}_t_s"] = math.nan
    known = level <= 2
    row[f"above_warning_{c}_s"] = float(np.count_nonzero(known & (level >= 1)) * STEP_S)
    row[f"above_critical_{c}_s"] = float(np.count_nonzero(known & (level >= 2)) * STEP_S)
    warn = (known & (level >= 1)).astype(np.int8)
    row[f"warnings_{c}"] = int(np.count_nonzero(np.diff(np.concatenate([[0], warn])) == 1))
    # "never" is NaN in the table; the shortest known time to limit, +inf when every refresh said never
    ok = known & (level < 3)
    row[f"min_ttl_{c}_s"] = (
        float(np.nanmin(ttl[ok])) if np.isfinite(ttl[ok]).any() else (math.inf if ok.any() else math.nan)
    )


def _degraded_share(table, oil_model: bool) -> float:
    """The share of steps not in normal mode; with the oil modelled by request, oil-model-only steps are normal."""
    if not table.n:
        return 0.0
    if oil_model and table.has("degraded_mode"):
        mode = np.asarray(table["degraded_mode"])
        return float(np.mean((mode != MODE_NORMAL) & (mode != MODE_OIL_MODEL)))
    return float(np.mean(np.asarray(table["degraded"], dtype=float) != 0))


def summarize(
    table,
    counters: dict,
    *,
    vehicle: str,
    log: str,
    key: str,
    date: str | None = None,
    oil_model: bool = False,
    gearbox=None,
) -> dict:
    """The summary row of one replayed log (``table`` from ``replay_log``, ``counters`` its ``meta["counters"]``);
    ``oil_model``: the sensor models the oil by request (``sensor.oil_mode = "model"``), so its oil-modelled steps
    are normal, not degraded (as in ``replay``'s summary); ``gearbox``: the sensor that replayed it (or its
    parameter set or description): its published components get the COMPONENT_COLUMNS, in their order (None: the
    default gearbox's)."""
    can_t = np.asarray(table["can_time_s"], dtype=float)
    start_s, end_s = float(can_t[0]), float(can_t[-1])
    innov = np.asarray(table["oil_innovation_c"], dtype=float) if table.has("oil_innovation_c") else np.zeros(0)
    innov = innov[np.isfinite(innov)]
    rejected = counters.get("decoder", {}).get("rejected", {})
    row = {
        "vehicle": vehicle,
        "log": log,
        "log_key": key,
        "date": date or log_date(start_s) or "unknown",
        "start_s": start_s,
        "end_s": end_s,
        "duration_s": float(table.n * STEP_S),
        "steps": int(table.n),
        "degraded_share": _degraded_share(table, oil_model),
        "frames": int(counters.get("decoder", {}).get("frames_seen", 0)),
        "time_jumps": int(counters.get("service", {}).get("time_jumps", 0)),
        "oil_innovation_mean_c": float(np.mean(innov)) if innov.size else math.nan,
        "oil_innovation_rms_c": float(np.sqrt(np.mean(innov**2))) if innov.size else math.nan,
        "oil_measured_share": float(innov.size / table.n) if table.n else 0.0,
    }
    for reason in REJECT_REASONS:
        row[f"rejected_{reason}"] = int(rejected.get(reason, 0))
    # the sensor's warning limits (the report ranks against them); without a gearbox, the default gearbox's
    limits = load_limits() if gearbox is None else getattr(gearbox, "limits", None)
    for c in ids(gearbox):
        _component(row, c, table)
        row[f"warning_limit_{c}_c"] = limits.of(c)[0] if limits is not None else math.nan
    return row


__all__ = ["COMPONENT_COLUMNS", "EPOCH_MIN_S", "asc_date", "log_date", "summarize"]
