"""The onboard sensor over a SCADA record: `replay --gearbox MM82 --columns engie FILE... --out est.csv`
(docs/real-data.md, "The sensor on SCADA").

The record becomes a fixed-ratio run table (:mod:`tools.scada.runtable`: each 10-minute row held over its interval,
the measured sump as ``oil_temp_c`` unless the oil is modelled), the sensor replays it with one output row per input
row (tools.replay.table.replay_held), and the estimates are written beside the measurements: for every measured
channel of the column map its cleaned reading under its own name and the sensor's estimate of the description's
part it is tied to as ``est_<name>`` (``est_Gb1t_avg``): the estimate's mean over the row's interval, as the
reading is its interval's mean (the sensor's output at the interval's end is ``T_<id>_c``). With ``oil_mode =
"model"`` the sump is read only in the first row (the model's start) and the sump channel's estimate is the
model's; with the oil measured, the estimate of the sump is the reading the sensor used (its model's own sump is
the ``model_oil_temp_c`` column). A channel tied to a forced oil system's inlet (``oil.inlet``) is estimated by the
status column ``oil_inlet_temp_c``. The sensor's full output (``T_<id>_c``, ``W_<id>``, ``ttl_<id>_s``, the
status) follows; est.csv leaves out the
columns of a vehicle the drive has not (tools.replay.table.not_written).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from firmware_model.description import OIL_INLET, description_of
from firmware_model.errors import InputError
from tools.replay.table import INLET_COLUMN, drive_knm_finding, not_written
from tools.runtable import RunTable
from tools.scada.reader import ScadaRecord
from tools.scada.runtable import INPUTS, oil_channel, run_table_of

#: the time to limit's refresh period of these offline replays at 0.1 s [s] (the live service refreshes every second;
#: at a held table's coarser step, once per row: tools.replay.table.replay_held)
OFFLINE_TTL_PERIOD_S = 10.0
#: the time-to-limit period of replays that want temperatures only (the diagnosis, the calibration's predictor)
#: [s]: refreshed once, at the first step (no temperature depends on it; the refreshes, once per row otherwise,
#: were a fifth of such a replay's time). Finite: the kernel counts the steps between refreshes in an int32
ESTIMATES_TTL_PERIOD_S = 1.0e8
#: the sensor options of such replays
ESTIMATES_ONLY = {"ttl_period_s": ESTIMATES_TTL_PERIOD_S}
#: a derived temperature of the description -> the sensor's output column that estimates it (where it has one)
DERIVED_COLUMNS = {OIL_INLET: INLET_COLUMN}


@dataclass
class ScadaReplay:
    """What :func:`replay_record` did: the output table, the sensor's oil mode and the channels it estimated."""

    table: RunTable
    oil_mode: str
    estimated: dict  # measured channel -> the output column its estimate comes from
    notes: list  # the channels left without an estimate, and why
    stretch: np.ndarray  # the record's gap-free stretch of each row (ScadaRecord.stretch): where a plot breaks
    left_out: tuple = ()  # columns of ``table`` that est.csv leaves out (tools.replay.table.not_written)

    def written(self) -> RunTable:
        """What est.csv holds: :attr:`table` without :attr:`left_out` (the findings read the whole table)."""
        t = self.table
        return RunTable({c: t[c] for c in t.columns if c not in self.left_out}, meta=t.meta, source=t.source)


#: a gap in a record this long [s] is said when the sump is modelled: the model's sump comes out of it cooled over
#: the gap, where the real one may have been kept warm (a heater) or the turbine restarted hours before its rows do
LONG_GAP_S = 86400.0
#: ... with the largest sump error in this long after the gap [s]
AFTER_GAP_S = 6 * 3600.0


def long_gap_starts(record: ScadaRecord) -> list[int]:
    """The first row of each stretch that follows a gap of LONG_GAP_S or more."""
    t = np.asarray(record.time_s, dtype=float)
    return [a for a, _ in record.stretch_bounds()[1:] if t[a] - t[a - 1] >= LONG_GAP_S]


def after_long_gaps(record: ScadaRecord) -> np.ndarray:
    """(N,) bool: the rows within AFTER_GAP_S after a gap of LONG_GAP_S or more, where a modelled sump comes out of
    the gap cooled over an assumed standstill, not from what the gearbox did."""
    t = np.asarray(record.time_s, dtype=float)
    out = np.zeros(t.size, dtype=bool)
    for a in long_gap_starts(record):
        out[a : int(np.searchsorted(t, t[a] + AFTER_GAP_S))] = True
    return out


def _long_gap_notes(record: ScadaRecord, cols: dict) -> list[str]:
    """With the sump modelled: one note on the record's gaps of LONG_GAP_S or more, the longest and the largest
    sump error in the AFTER_GAP_S after any of them (the model's sump restarts from its state cooled over the gap,
    not from a reading)."""
    oil = oil_channel(record)
    t = np.asarray(record.time_s, dtype=float)
    starts = long_gap_starts(record)
    if oil is None or not starts:
        return []
    err = np.abs(np.asarray(cols[f"est_{oil}"]) - np.asarray(cols[oil]))
    worst = max(
        (
            float(np.nanmax(err[a:b], initial=0.0))
            for a in starts
            for b in [int(np.searchsorted(t, t[a] + AFTER_GAP_S))]
        ),
        default=0.0,
    )
    longest = max(t[a] - t[a - 1] for a in starts) / 86400.0
    return [
        f"{len(starts)} gap(s) of a day or more (the longest {longest:.1f} days): the modelled sump comes out of each "
        f"cooled over it, not from a reading; in the {AFTER_GAP_S / 3600:g} h after them it is up to {worst:.1f} K off "
        f"{oil}"
    ]


def estimate_columns(record: ScadaRecord, published, parts=(), outputs=()) -> tuple[dict, list[str]]:
    """({measured channel: the sensor's output column that estimates it}, notes): ``T_<node>_c`` of the published
    part each channel is tied to; a channel tied to a derived temperature, its status column when the output
    (``outputs``: its column names) has it (the oil inlet: ``oil_inlet_temp_c``, a forced oil system's). A channel
    tied to a part of the gearbox (``parts``: its nodes and derived temperatures) the sensor does not estimate is
    left without an estimate, with a note; one tied to a part the gearbox does not have is one sentence (a wrong
    map)."""
    out, notes = {}, []
    for name, node in record.cmap.nodes.items():
        if node in published:
            out[name] = f"T_{node}_c"
        elif DERIVED_COLUMNS.get(node) in outputs:
            out[name] = DERIVED_COLUMNS[node]
        elif node in parts:
            notes.append(f"{name} is not estimated: the sensor does not publish {node!r}")
        else:
            raise InputError(
                f"column map {record.cmap.name}: measured channel {name} is tied to {node!r}, which the gearbox "
                f"does not have (it publishes {', '.join(published)})"
            )
    return out, notes


#: how far into a record its first sump reading may lie to be where a modelled sump starts [s]
START_WINDOW_S = 3600.0


def first_sump(record: ScadaRecord) -> tuple[float, int] | None:
    """The sump channel's first reading in the record's first hour and first stretch, with its row (None without
    one): where a modelled sump starts. A record begins wherever its files begin, often with the turbine producing
    and the oil at 55-60 degC; started at the nacelle air instead, the model's sump would take most of a day to be
    fair to (its slowest mode). A first row without a reading (or a glitch there: tools/scada/clean.py) leaves the
    start to the next reading."""
    oil = oil_channel(record)
    if oil is None or record.n == 0:
        return None
    t = np.asarray(record.time_s, dtype=float)
    x = np.asarray(record.values[oil], dtype=float)
    ok = np.isfinite(x) & (np.asarray(record.stretch) == record.stretch[0]) & (t - t[0] <= START_WINDOW_S)
    rows = np.flatnonzero(ok)
    return (float(x[rows[0]]), int(rows[0])) if rows.size else None


def replay_record(
    record: ScadaRecord, config, sensor_options: dict | None = None, effects: dict | None = None, params=None
) -> ScadaReplay:
    """Replay the sensor of ``config`` (a firmware_model.config.Config; its gearbox) over ``record``; ``effects``:
    {effect id: value} of the sensor's effect hooks (firmware_model.onboard.reduce.EFFECT_HOOKS); ``params``: the
    gearbox's parameters in place of the configuration's (a calibration's trial values)."""
    from firmware_model.description import description_of
    from firmware_model.onboard.sensor import VirtualSensor
    from tools.drive_table import map_fixed_ratio
    from tools.replay.table import held_options, mark_for_findings, replay_held

    params = config.load_params() if params is None else params
    # an offline batch: the time to limit refreshed every 10 s (the live service: every 1 s), a quarter less time
    options = {"ttl_period_s": OFFLINE_TTL_PERIOD_S, **(sensor_options or {})}
    oil_mode = options.get("oil_mode") or config.sensor.get("oil_mode", "measured")
    table = run_table_of(record, with_oil=oil_mode != "model")
    # the fixed-ratio inputs onto the sensor's (input speed and torque, the description's one gear)
    drive = map_fixed_ratio(table, description_of(params), table.source, strict=False)
    sensor = VirtualSensor(params, config=config, effects=effects, **{**held_options(drive), **options})
    d = description_of(params)
    start = first_sump(record) if oil_mode == "model" else None
    start_c = start[0] if start is not None else None
    out = replay_held(drive, sensor, initial_oil_c=start_c, row_means=True)
    row_mean = out.meta.pop("row_mean")
    estimated, notes = estimate_columns(record, tuple(sensor.published), (*d.nodes, *d.derived), out.columns)
    if start is not None:
        which = "the first sump reading" if start[1] == 0 else f"the first sump reading (row {start[1] + 1})"
        notes.append(
            f"the model's sump starts at {which} ({start_c:.1f} degC), reads no other and is not compared with that one"
        )
    elif oil_mode == "model":
        notes.append(unread_start_note(record, sensor, table))
    n = record.n
    if out.n != n:  # one output row per SCADA row (tools.replay.table.replay_held)
        raise RuntimeError(f"the replay gave {out.n} rows for {n} SCADA rows")
    cols: dict = {"time_s": out["time_s"], "time_utc_s": np.asarray(record.time_s, dtype=float)}
    for name in INPUTS:
        cols[name] = table[name]
    for name in record.cmap.nodes:
        cols[name] = np.asarray(record.values[name], dtype=float)
        # the estimate is the interval's mean, as the reading is (the sensor's output at the row's end: T_<id>_c)
        cols[f"est_{name}"] = np.array(row_mean[estimated[name]]) if name in estimated else np.full(n, np.nan)
        tau_s = record.cmap.measured[name].response_s
        if tau_s > 0.0 and name in estimated:
            cols[f"est_{name}"] = reading_response(
                cols[f"est_{name}"], row_mean["T_oil_c"], np.asarray(record.time_s, dtype=float), record.stretch, tau_s
            )
        if start is not None and record.cmap.nodes[name] == "oil":
            cols[f"est_{name}"][start[1]] = np.nan  # the reading the model starts from: not compared with itself
    for name in out.columns:
        if name not in cols and name not in INPUTS:
            cols[name] = out[name]
    if oil_mode == "model":
        notes += _long_gap_notes(record, cols)
    meta = {**out.meta, "unit": record.unit, "t0_utc_s": table.meta["t0_utc_s"], "drive": "fixed_ratio"}
    meta["air_default_c"] = float(sensor.sp.aux_default[0])  # what a row without its air took (air_finding)
    result = RunTable(cols, meta=meta, source=f"replay of {record.unit}")
    mark_for_findings(result, sensor)  # (a rotor's drive: no idle-speed rule; its own kN m rule)
    return ScadaReplay(result, oil_mode, estimated, notes, np.asarray(record.stretch), not_written(d))


def unread_start_note(record: ScadaRecord, sensor, table) -> str:
    """With the sump modelled and no reading to start it from (:func:`first_sump`: none in the record's first hour
    and stretch): where the model's sump starts (the sensor's own start without an oil reading: ``[sensor]
    initial_temp_c``, else the first row's air, else the gearbox's ambient boundary) and why, in words (it started
    at the air in silence, where a reading's start is said)."""
    air = np.asarray(table["ambient_temp_c"], dtype=float)[0] if table.has("ambient_temp_c") else math.nan
    start_c = float(np.ravel(sensor.initial_state(T_oil_c=None, ambient_c=float(air)).T_c)[0])
    if sensor.options.initial_temp_c is not None:
        where = f"the configuration's [sensor] initial_temp_c ({start_c:.1f} degC)"
    elif math.isfinite(air) and start_c == air:
        air_col = record.cmap.channels["ambient_temp_c"].columns[0] if "ambient_temp_c" in record.cmap.channels else ""
        where = f"the air of the record's first row ({start_c:.1f} degC{', ' + air_col if air_col else ''})"
    else:
        where = f"the gearbox's ambient boundary ({start_c:.1f} degC; the first row's air missing or out of range)"
    oil = oil_channel(record)
    read = np.flatnonzero(np.isfinite(np.asarray(record.values[oil], dtype=float))) if oil else np.array([], int)
    if oil is None:
        why = "the column map has no channel tied to the sump"
    elif not read.size:
        why = f"no sump reading in the record ({oil} empty or rejected on every row)"
    else:
        why = f"no sump reading in the record's first hour and stretch ({oil}'s first is on row {read[0] + 1})"
    return (
        f"the model's sump starts at {where}: {why}; a gearbox already warm then reads warmer than the model's sump "
        "for most of a day"
    )


def reading_response(est_c, sump_c, time_s, stretch, tau_s: float) -> np.ndarray:
    """What a reading with a response of ``tau_s`` [s] shows of its part's estimate ``est_c`` (row means): the sump
    ``sump_c`` plus the part's rise over it through a first-order lag, ``y += (1 - exp(-dt / tau)) (rise - y)`` row
    by row (``dt`` the time since the last row with a rise), started at the rise at each stretch's first row
    (``stretch``: the record's gap-free stretch of each row). A reading sitting in metal that the part warms and the
    oil's spray cools (docs/real-data.md, "The bearings' reading"). A row without a rise is NaN and leaves the lag
    where it was."""
    est_c, sump_c, time_s = (np.asarray(v, dtype=float) for v in (est_c, sump_c, time_s))
    rise_a, out = est_c - sump_c, np.full(est_c.shape, np.nan)
    # Python floats in the loop (a numpy scalar per element was two thirds of its time; the same arithmetic)
    rise, sump, t, st = rise_a.tolist(), sump_c.tolist(), time_s.tolist(), np.asarray(stretch).tolist()
    y, t_y, prev = math.nan, math.nan, None  # the lagged rise, the time it stands for, the last row's stretch
    isfinite, exp = math.isfinite, math.exp
    for i, r in enumerate(rise):
        if st[i] != prev:
            y, prev = math.nan, st[i]
        if isfinite(r):
            y = r if not isfinite(y) else r + exp(-(t[i] - t_y) / tau_s) * (y - r)
            t_y, out[i] = t[i], sump[i] + y
    return out


#: a record's findings: rows dropped by the reader beyond this share of the rows read; a channel's values rejected
#: as implausible beyond this share of its rows; a measured channel's estimate off its readings on average by more
#: than BIAS_WARN_K (a loud warning: a model gap, a hot bearing or a unit) or BIAS_UNTRUSTED_K (exit 3: no model gap
#: is that large; a sump read in degF puts the bearings 56 K over theirs) over at least BIAS_MIN_ROWS rows. The
#: shipped MM82 on the three ENGIE turbines' records: |mean| within 3.3 K on every channel, either oil mode.
DROPPED_WARN_SHARE, IMPLAUSIBLE_WARN_SHARE = 0.05, 0.05
#: the air around the gearbox missing on at least this share of the rows: a warning, on at least the second the
#: outputs are not trusted (the degraded shares of the drive inputs, firmware_model.service.degraded). The sensor
#: takes the description's default air for such rows (not held: the auxiliary inputs' documented default), and an
#: empty nacelle column put R80721's modelled sump at 2.59 against 1.32 K RMS over a week with exit 0
AIR_MISSING_WARN_SHARE, AIR_MISSING_UNTRUSTED_SHARE = 0.2, 0.5
BIAS_WARN_K, BIAS_UNTRUSTED_K, BIAS_MIN_ROWS = 10.0, 30.0, 36


#: the severities of the findings (firmware_model.service.degraded.Severity's values, compared as ints: this room
#: imports no service module; tests/tools/scada/test_replay_scada.py holds them equal)
WARNING, UNTRUSTED = 1, 2


@dataclass(frozen=True)
class RecordFinding:
    """What a SCADA replay's record says about its outputs (``firmware_model.service.degraded.Severity``)."""

    kind: str
    severity: int
    sentence: str
    channel: str | None = None  # the measured channel it is about (an estimate far off its readings), if one


def record_findings(record: ScadaRecord, result: ScadaReplay) -> list:
    """The trust findings of a SCADA replay, most severe first: the sensor's on its output table (degraded share,
    repairs: tools.replay.table.table_findings), rows the reader dropped, channels mostly rejected as implausible
    (a column in another unit than its map says), and measured channels whose estimate is far off on average (each
    file's damaged lines by number are said apart, by tools.cli.scada_notes, as fleet, diagnose and calibrate say
    them)."""
    from tools.replay.table import table_findings

    found = [
        RecordFinding("plausibility", int(f.severity), torque_unit_hint(record, f.sentence))
        if is_torque_unit_sentence(f.sentence)
        else f
        for f in table_findings(result.table, oil_model=result.oil_mode == "model")
    ]
    spacing = spacing_finding(record)
    if spacing is not None:
        # it says why the held table's time jumps forward on most rows (the run-table sentence's advice, "rows at
        # most 60 s apart; resample it", is not a SCADA record's)
        found = [f for f in found if not f.sentence.startswith("time_s jumps forward")] + [spacing]
    c = record.counts
    dropped = {k: c.get(k, 0) for k in ("bad_line", "bad_time", "duplicate_time") if c.get(k, 0)}
    read = record.n + sum(dropped.values()) + c.get("conflicting_time", 0)
    conflict = record.conflict_sentence()  # whatever its share: its own warning
    if conflict:
        found.append(RecordFinding("rows", WARNING, conflict))
    if read and sum(dropped.values()) > DROPPED_WARN_SHARE * read:
        why = ", ".join(f"{v} {k.replace('_', ' ')}" for k, v in dropped.items())
        found.append(
            RecordFinding(
                "rows",
                WARNING,
                f"{sum(dropped.values())} of {read} rows were dropped ({why}): the outputs leave them out"
                + (
                    " (bad time: a stamp without its UTC offset or that does not parse)"
                    if "bad_time" in dropped
                    else ""
                )
                + (
                    " (duplicate time: a row repeating a time stamp with the same values; one kept)"
                    if "duplicate_time" in dropped
                    else ""
                ),
            )
        )
    found += range_findings(record)
    air = air_finding(record, result.table.meta.get("air_default_c"))
    found += [air] if air is not None else []
    t = result.table
    biases = {}
    for name in result.estimated:
        e = np.asarray(t[f"est_{name}"], dtype=float) - np.asarray(t[name], dtype=float)
        f = bias_finding(name, e)
        if f is not None:
            found.append(f)
            biases[name] = float(np.nanmean(e))
    shared = shared_sump_finding(record, result.oil_mode, biases)
    held = holding_run_finding(t)
    return sorted(found + ([shared] if shared else []) + ([held] if held else []), key=lambda f: -f.severity)


#: the sensor holding its drive inputs (missing or implausible speed or torque) on every row for this long is a
#: warning whatever the whole record's degraded share [s]: a month of them can be a small share of a year
HOLDING_RUN_WARN_S = 86400.0


def holding_run_finding(table) -> RecordFinding | None:
    """The longest run of rows in which the sensor held its drive inputs (``degraded_mode`` holding), when it lasts
    HOLDING_RUN_WARN_S or more, else None."""
    from firmware_model.components import MODE_HOLDING

    if not table.has("degraded_mode") or not table.has("time_utc_s"):
        return None
    held = np.asarray(table["degraded_mode"]) == MODE_HOLDING
    edges = np.flatnonzero(np.diff(np.r_[0, held.astype(np.int8), 0]))
    if not edges.size:
        return None
    t = np.asarray(table["time_utc_s"], dtype=float)
    spans = [(t[b - 1] - t[a], a, b) for a, b in zip(edges[::2], edges[1::2])]
    span_s, a, b = max(spans)
    if not span_s >= HOLDING_RUN_WARN_S:
        return None
    start = datetime.fromtimestamp(t[a], tz=timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    return RecordFinding(
        "degraded",
        WARNING,
        f"the drive inputs (the input speed or torque: missing, or implausible) were not usable for "
        f"{span_s / 86400:.1f} days in a row from {start} ({b - a} rows): the sensor held its last inputs there, and "
        "those rows' estimates rest on them (est.csv's degraded_mode)",
    )


def shared_sump_finding(record: ScadaRecord, oil_mode: str, biases: dict) -> RecordFinding | None:
    """With the sump measured, every other channel's estimate starts from the sump reading: all of them off by more
    than BIAS_UNTRUSTED_K the same way points at that reading (a sump in degF put the bearings and the inlet 63-65 K
    over theirs, and the warnings named every channel but the sump's)."""
    sump = oil_channel(record)
    others = [n for n in record.cmap.nodes if n != sump]
    if oil_mode != "measured" or sump is None or len(others) < 2 or set(others) - set(biases):
        return None
    signs = {np.sign(biases[n]) for n in others}
    if len(signs) != 1 or min(abs(biases[n]) for n in others) <= BIAS_UNTRUSTED_K:
        return None
    lo, hi = (f"{v:+.0f}" for v in sorted((min(biases[n] for n in others), max(biases[n] for n in others))))
    return RecordFinding(
        "units",
        UNTRUSTED,
        f"the estimates of {', '.join(others)} all sit {lo}..{hi} K off their readings, and each starts from the sump "
        f"reading {sump} the sensor used: is {sump} in another unit than its map says (degF: 58 degC reads 136)?",
        sump,
    )


#: a record whose rows lie further apart than this share over its map's period_s (median spacing) has every row
#: after a gap; closer than the inverse share, its gaps are found late (GAP_PERIODS of the map's period)
SPACING_TOLERANCE = 1.1


def spacing_finding(record: ScadaRecord) -> RecordFinding | None:
    """Rows whose median spacing is not the column map's ``period_s``: further apart (hourly rows read with a
    10-minute map), every row is its own stretch after a gap and the sensor holds the inputs 60 s, then takes the
    drive as stopped (untrusted); closer (1-minute rows), each row is held until the next and the estimates stand,
    but a gap is found only past GAP_PERIODS of the map's period (a warning). Not judged where the reader dropped
    more than DROPPED_WARN_SHARE of the rows (the rows left lie further apart for that reason)."""
    from tools.scada.reader import GAP_PERIODS

    t = np.asarray(record.time_s, dtype=float)
    c = record.counts
    dropped = c.get("bad_line", 0) + c.get("bad_time", 0)
    if t.size < 3 or dropped > DROPPED_WARN_SHARE * (t.size + dropped):
        return None  # rows dropped between the others: their own warning says so, not the map's period
    spacing_s, period_s = float(np.median(np.diff(t))), float(record.cmap.period_s)
    fix = f"if the file's rows are {spacing_s:g}-s averages, set period_s = {spacing_s:g} in a copy of the column map"
    if spacing_s > SPACING_TOLERANCE * period_s:
        return RecordFinding(
            "rows",
            UNTRUSTED,
            f"the rows lie {spacing_s:g} s apart (median) where the column map's period_s is {period_s:g} s: every "
            f"row is taken for its own stretch after a gap (the sensor holds the inputs over 60 s of it, then takes "
            f"the drive as stopped); {fix}",
        )
    if spacing_s * SPACING_TOLERANCE < period_s:
        return RecordFinding(
            "rows",
            WARNING,
            f"the rows lie {spacing_s:g} s apart (median) where the column map's period_s is {period_s:g} s: each row "
            f"is held until the next (the estimates stand), but a gap is found only past {GAP_PERIODS * period_s:g} s; "
            f"{fix}",
        )
    return None


def is_torque_unit_sentence(sentence: str) -> bool:
    """Whether ``sentence`` is the fixed-ratio drive's torque-unit finding (kN m, or MN m: 10^6 too small)."""
    return "looks like kN m" in sentence or "looks like MN m" in sentence


def torque_unit_hint(record: ScadaRecord, sentence: str) -> str:
    """The kN m finding of a fixed-ratio table (firmware_model.service.plausibility) names run-table columns and
    says "give N m"; on a SCADA record the fix is the column map's unit of the column the input torque comes from."""
    ch = record.cmap.channels.get("input_torque_nm")
    if ch is None or not is_torque_unit_sentence(sentence):
        return sentence
    name = record.cmap.name
    if ch.derive == "power_over_speed":
        unit = {1.0: "W", 1e3: "kW", 1e6: "MW"}.get(ch.source_scale, f"units of {ch.source_scale:g} W")
        return (
            f"{sentence}. On this SCADA record the column map {name} derives the torque from {ch.sources['power']} "
            f'read in {unit}: a power column in MW wants power_unit = "MW" in the map (in kW, "kW")'
        )
    if ch.derive:
        unit = {1.0: "N m", 1e3: "kN m"}.get(ch.source_scale, f"units of {ch.source_scale:g} N m")
        return (
            f"{sentence}. On this SCADA record the column map {name} derives the torque from "
            f'{ch.sources["torque"]} read in {unit}: a torque column in kN m wants torque_unit = "kN m" in the map'
        )
    return (
        f"{sentence}. On this SCADA record the column map {name} reads the torque from {ch.column} in {ch.unit}: a "
        'torque column in kN m wants unit = "kN m" in the map'
    )


def range_findings(record: ScadaRecord) -> list[RecordFinding]:
    """The channels whose values the reader mostly rejected as implausible (a column in another unit than its map
    says: a nacelle air in kelvin)."""
    found = []
    for name, by in record.by_channel.items():
        bad = by.get("implausible", 0)
        if record.n and bad > IMPLAUSIBLE_WARN_SHARE * record.n:
            ch = record.cmap.channels[name]
            lo, hi = ch.range or (math.nan, math.nan)
            found.append(
                RecordFinding(
                    "units",
                    UNTRUSTED,
                    f"{name} ({', '.join(ch.columns)}): {bad} of {record.n} "
                    f"rows outside its plausible range {lo:g}..{hi:g} (in the unit its name ends with, converted "
                    f"from the map's {ch.unit}): " + (speed_unit_hint(record, name) or _unit_question(ch)),
                )
            )
    return found


def air_finding(record: ScadaRecord, default_c=None) -> RecordFinding | None:
    """The air around the gearbox (the map's ``ambient_temp_c``) missing on AIR_MISSING_WARN_SHARE of the rows or
    more (an empty or mostly empty nacelle column; one mostly out of range is range_findings'): the sensor took
    its default air there. ``default_c``: that default [degC], said when known."""
    name = "ambient_temp_c"
    ch = record.cmap.channels.get(name)
    if (
        ch is None
        or not record.n
        or record.by_channel.get(name, {}).get("implausible", 0) > (IMPLAUSIBLE_WARN_SHARE * record.n)
    ):
        return None
    missing = int(np.sum(~np.isfinite(np.asarray(record.values[name], dtype=float))))
    share = missing / record.n
    if share < AIR_MISSING_WARN_SHARE:
        return None
    default = f", {float(default_c):g} degC" if default_c is not None and math.isfinite(default_c) else ""
    return RecordFinding(
        "inputs",
        UNTRUSTED if share >= AIR_MISSING_UNTRUSTED_SHARE else WARNING,
        f"the air around the gearbox ({name} <- {', '.join(ch.columns)}) is missing on {missing} of {record.n} "
        f"rows ({share:.0%}): the sensor took the gearbox description's default air there{default}, not the "
        "nacelle's; map a column that has it (an export without a nacelle air: the outdoor air + 12.5 K, "
        'docs/real-data.md "Without a nacelle air")',
    )


def _unit_question(ch) -> str:
    """The end of a range finding's sentence: for a temperature, the two units a column of another is likely in and
    how the map says them (a file in kelvin was asked only "is the column in another unit?")."""
    if ch.unit in ("degC", "°C", "C"):
        return (
            'is the column in another unit? (in kelvin: unit = "K" for it in the column map; in Fahrenheit: '
            'unit = "degF")'
        )
    return "is the column in another unit?"


#: a derived torque P / omega out of its range because the speed is in rad/s read as rpm: the torque at the speed
#: in rad/s (the read torque times 2 pi / 60) fits its range on at least this share of the producing rows where the
#: read one does not
RAD_S_FIT_SHARE = 0.95


def speed_unit_hint(record: ScadaRecord, name: str) -> str:
    """For a torque derived as power over speed that is mostly out of its range: when the speed column read as
    rad/s would put it back in range, the end of the finding's sentence saying so (else "")."""
    ch = record.cmap.channels.get(name)
    if name != "input_torque_nm" or ch is None or ch.derive != "power_over_speed" or "power_kw" not in record.values:
        return ""
    power_bad = record.by_channel.get("power_kw", {}).get("implausible", 0) / max(record.n, 1)
    if power_bad > IMPLAUSIBLE_WARN_SHARE:
        # the power itself out of its range (in W where the map says kW): its unit first, not the speed's
        power = ch.sources["power"]
        return (
            f"the torque is {power} over {ch.sources['speed']}, and {power} itself is out of its range on "
            f"{power_bad:.0%} of the rows: set its unit first (unit of power_kw and power_unit of the torque in the "
            "column map)"
        )
    lo, hi = ch.range or (-math.inf, math.inf)
    speed_rpm = np.asarray(record.values["input_speed_rpm"], dtype=float)
    power_w = np.asarray(record.values["power_kw"], dtype=float) * 1e3
    running = (speed_rpm > record.cmap.standstill_rpm) & (power_w > 0.0)
    read_nm = power_w[running] / (speed_rpm[running] * math.pi / 30.0)
    out = (read_nm < lo) | (read_nm > hi)
    as_rad_s = read_nm[out] * math.pi / 30.0  # the same power over the column's values taken as rad/s
    if out.sum() < 3 or np.mean((as_rad_s >= lo) & (as_rad_s <= hi)) < RAD_S_FIT_SHARE:
        return ""
    speed = ch.sources["speed"]
    return (
        f"the torque is {ch.sources['power']} over {speed}, and with {speed} read as rad/s it fits its range on "
        f"{np.mean((as_rad_s >= lo) & (as_rad_s <= hi)):.0%} of those rows: if {speed} is in rad/s, set unit = "
        f'"rad/s" for the speed and speed_unit = "rad/s" for the torque in the column map'
    )


def bias_finding(name: str, est_minus_measured) -> RecordFinding | None:
    """A measured channel whose estimate is off its readings on average by more than BIAS_WARN_K, else None."""
    e = np.asarray(est_minus_measured, dtype=float)
    e = e[np.isfinite(e)]
    bias = float(np.mean(e)) if e.size >= BIAS_MIN_ROWS else 0.0
    if abs(bias) <= BIAS_WARN_K:
        return None
    return RecordFinding(
        "units",
        UNTRUSTED if abs(bias) > BIAS_UNTRUSTED_K else WARNING,
        f"{name}: the estimate is {bias:+.1f} K off its readings on average over {e.size} rows: "
        + (
            "a unit or a channel of the column map is wrong (an input in degF or kelvin, a reading tied "
            "to the wrong node)"
            if abs(bias) > BIAS_UNTRUSTED_K
            else "the model and this unit disagree (a bearing running hot, a sensor offset: "
            "gearbox-vsensor diagnose) or a unit or a channel of the column map is wrong"
        ),
        name,
    )


def untrusted_findings(record: ScadaRecord, residual: dict, params) -> list[RecordFinding]:
    """What makes `replay` exit 3 on ``record``, from what a fit already has (``residual``: {channel: measured -
    model} at the neutral effects over the record) and no replay table: channels mostly implausible, an input
    torque in kN m (firmware_model.service.plausibility) and an estimate more than BIAS_UNTRUSTED_K off its readings
    on average. ``params``: the gearbox's (its drive's limits). A fit to such a record explains a unit mistake by a
    gearbox effect: diagnose and calibrate refuse it, the fleet leaves the unit out."""
    found = [
        f
        for f in [*range_findings(record), spacing_finding(record), air_finding(record)]
        if f and f.severity >= UNTRUSTED
    ]
    v = record.values
    if "input_speed_rpm" in v and "input_torque_nm" in v:
        knm = drive_knm_finding(
            v["input_speed_rpm"], v["input_torque_nm"], description_of(params), float(record.cmap.period_s)
        )
        if knm is not None:
            found.append(RecordFinding("plausibility", UNTRUSTED, torque_unit_hint(record, knm.sentence)))
    for name, r in residual.items():
        f = bias_finding(name, -np.asarray(r, dtype=float))
        if f is not None and f.severity >= UNTRUSTED:
            found.append(f)
    return found


def screen_untrusted(records, residuals, params, role: str, sump: str | None = None) -> tuple[list, list, list]:
    """``records`` and their residuals at the neutral effects (``residuals``) screened by :func:`untrusted_findings`:
    an InputError naming the first record whose inputs or sump look wrong (a column out of range, the torque in
    kN m, the sump channel ``sump`` far off the model, or every other channel off: the sump drives their estimates);
    a measured channel far off its estimate beside others that are not (a thermocouple reading 0 degC, tied to the
    wrong node) is left out of that record instead, the rest of it kept: (records, residuals, one note per channel
    left out). ``role``: "training" or "test"."""
    kept, kept_res, notes = [], [], []
    for record, residual in zip(records, residuals):
        found = untrusted_findings(record, residual, params)
        files = ", ".join(Path(f).name for f in record.files[:3]) + (" ..." if len(record.files) > 3 else "")
        off = {f.channel for f in found if f.channel is not None}
        sound = [ch for ch, r in residual.items() if ch != sump and ch not in off and np.isfinite(r).sum()]
        # every channel off alike (or the sump, which drives them): an input's unit, not one channel's fault
        fatal = [f for f in found if f.channel is None or f.channel == sump or not sound]
        if fatal:
            raise InputError(
                f"the {role} record of {record.unit} ({files}): {fatal[0].sentence} (replay exits 3 on it; fix the "
                "file or the column map)"
            )
        drop = [f for f in found if f.channel is not None]
        if drop:
            record = record.select(np.ones(record.n, dtype=bool))
            residual = dict(residual)
            for f in drop:
                record.values[f.channel] = np.full(record.n, np.nan)
                residual[f.channel] = np.full(record.n, np.nan)
                notes.append(f"the {role} record of {record.unit} ({files}): {f.channel} left out: {f.sentence}")
        kept.append(record)
        kept_res.append(residual)
    return kept, kept_res, notes


def error_lines(result: ScadaReplay, sump: str | None = None) -> list[str]:
    """One line per measured channel: rows compared, mean, RMS and 99th percentile of |estimate - measured|; the sump
    channel ``sump`` (tools.scada.runtable.oil_channel), measured, said to be the reading the sensor used."""
    t = result.table
    lines = [f"  note: {x}" for x in result.notes]
    for name in result.estimated:
        if name == sump and result.oil_mode != "model":  # the estimate is the reading the sensor used: 0 K says nothing
            if not np.isfinite(np.asarray(t[name], dtype=float)).any():  # (every reading missing or rejected)
                lines.append(
                    f"  {name}: no reading the sensor could use (each row missing or rejected): it modelled the oil"
                )
            else:
                lines.append(f"  {name}: the reading the sensor used (the oil measured; --oil-mode model estimates it)")
            continue
        e = t[f"est_{name}"] - t[name]
        ok = np.isfinite(e)
        if not ok.any():
            lines.append(f"  {name}: no row with both a reading and an estimate")
            continue
        e = e[ok]
        lines.append(
            f"  {name}: {ok.sum()} rows, estimate - measured mean {e.mean():+.2f} K, RMS "
            f"{np.sqrt(np.mean(e**2)):.2f} K, |e| p99 {np.percentile(np.abs(e), 99):.2f} K"
        )
    return lines
