"""Replay of a run table (CSV) through the onboard sensor at 10 Hz: the library behind `gearbox-vsensor replay RUN.csv`.

The reading is split from the stepping so that any input source plugs in: a source is an iterator of
:class:`TableRecord` (``t_s``, the sensor's ``Inputs``) on the sensor's 0.1 s grid (:func:`table_records` for run
tables); the stepping, output columns and status are :func:`replay_records`. CAN logs go through the live CAN
service instead (tools/replay/log.py), so a log replays bit-identically to a live run.

Output (a run table, tools/runtable.py): ``time_s`` (end of each 0.1 s step), the inputs the sensor read (empty
when absent), ``T_<id>_c``, ``W_<id>``, ``ttl_<id>_s`` (empty when never) for every published component, then the
status: ``degraded`` (0/1), ``degraded_mode`` (0 normal, 1 oil model only, 2 inputs missing - holding),
``speed_valid``, ``torque_valid``, ``gear_valid``, ``oil_valid``, ``oil_innovation_c`` (measured - model oil, empty
without a measurement), ``model_oil_temp_c``, for a forced oil system (a sensor whose ``oil_inlet`` is true) its oil
inlet ``oil_inlet_temp_c``, and the cumulative reject counters ``rejects_<reason>``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from firmware_model.components import STEP_S
from firmware_model.errors import InputError
from firmware_model.service.protocol import start_state  # (not options: that imports python-can)

#: a gap in the table's time longer than this is a time jump for the sensor (like the CAN service's 5 s catch-up)
MAX_HOLD_GAP_S = 5.0
#: the status columns of a table replay, in order (then rejects_<reason>)
STATUS_COLUMNS = (
    "degraded",
    "degraded_mode",
    "speed_valid",
    "torque_valid",
    "gear_valid",
    "oil_valid",
    "oil_innovation_c",
    "model_oil_temp_c",
)
#: the status column of a forced oil system's inlet, after STATUS_COLUMNS (only where the sensor has one)
INLET_COLUMN = "oil_inlet_temp_c"


class TableRecord(NamedTuple):
    """One step of a replay source: the end of the step on the run-table clock [s] and the sensor's inputs."""

    t_s: float
    inputs: Any


class CsvReplay(NamedTuple):
    """A run-table replay: the sensor output RunTable, the gearbox variant and the oil mode it ran with."""

    table: Any
    variant: str
    oil_mode: str = "measured"


class ReplaySummary(NamedTuple):
    """What a replay found, for the command line: its span, the hottest component and its peak, the highest
    warning level, the share of degraded steps and the reject counters that are not zero."""

    span_s: float
    steps: int
    hottest: str
    hottest_c: float
    max_level: int
    degraded_share: float
    rejects: dict


def _sensor_inputs():
    """(field, run-table column) of each sensor input (the CAN service's wiring)."""
    from firmware_model.service.records import SENSOR_INPUTS  # (not options: that imports python-can)

    return SENSOR_INPUTS


def read_inputs_table(path, description=None):
    """Read a run table for the sensor: the structure is checked (header, numbers, the required columns, time_s
    strictly increasing) but not the *values* of the inputs: a NaN, a gear 7.5 or a negative speed is data for
    the sensor, which holds, clamps or degrades and counts it (docs/sensor.md "Bad input"). A fixed-ratio drive's
    table is mapped onto the vehicle inputs (tools.drive_table; ``description``: the gearbox's, None: the
    GRS905)."""
    from tools import runtable as rt
    from tools.drive_table import check_drive, map_fixed_ratio

    name = os.fspath(path)
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{name}: the run table does not exist")
    names = rt.read_header(p, name)
    arr = rt.parse_numeric_csv(p, names)
    if arr is None:
        arr = rt.parse_careful(p, names, name)
    fixed = check_drive(names, description, name) == "fixed_ratio"
    for col in ("time_s",) if fixed else rt.REQUIRED:
        if col not in names:
            raise InputError(f'{name}: required column "{col}" is missing; the columns are {", ".join(names)}')
    table = rt.RunTable({c: arr[:, j] for j, c in enumerate(names)}, source=name)
    rt.validate_run_table(rt.RunTable({"time_s": table["time_s"]}, source=name), ("time_s",), name, rt.lines_of(p))
    if not fixed:
        return table
    mapped = map_fixed_ratio(table, description, name, strict=False)
    if not mapped.meta["row_period_s"] > 0:  # one row: no interval to hold it over (the plant refuses it too)
        raise InputError(
            f"{name}: one row; a fixed-ratio drive's row holds over the interval to the next row, so a table of one "
            "row has none: give at least two rows"
        )
    return mapped


class _Segment(NamedTuple):
    """A stretch of the table between time jumps: its first and last time [s]."""

    first_s: float
    last_s: float


def _segments(t_s: np.ndarray) -> list[_Segment]:
    """The stretches of the table between time jumps (gaps longer than MAX_HOLD_GAP_S)."""
    gaps = np.flatnonzero(np.diff(t_s) > MAX_HOLD_GAP_S)
    starts_s = [t_s[0]] + [t_s[g + 1] for g in gaps]
    ends_s = [t_s[g] for g in gaps] + [t_s[-1]]
    return [_Segment(a, b) for a, b in zip(starts_s, ends_s)]


def table_steps(table, dt_s: float = STEP_S) -> tuple[np.ndarray, np.ndarray]:
    """``(t_s (N,), inputs (N, 8))``: the sensor's per-step frame times and inputs (INPUT_FIELDS order) from a run
    table, vectorised: every step of the 0.1 s grid from the first row, values held from the last row at or before
    the step's start (an absent column is NaN). A gap longer than MAX_HOLD_GAP_S between rows is a time jump: no
    steps inside it, the next step carries the jump in its time. A row alone between two jumps (a table sampled
    more sparsely than MAX_HOLD_GAP_S) is one step, not dropped."""
    t_s = np.asarray(table["time_s"], dtype=float)
    if t_s.size == 0:
        return np.zeros(0), np.zeros((0, len(_sensor_inputs())))
    if not np.all(np.isfinite(t_s)) or np.any(np.diff(t_s) <= 0):
        raise InputError("column time_s must be finite and strictly increasing")
    cols = [
        np.asarray(table[col], dtype=float) if table.has(col) else np.full(t_s.size, np.nan)
        for _, col in _sensor_inputs()
    ]
    data = np.stack(cols, axis=1)
    ends, rows = [], []
    for first_s, last_s in _segments(t_s):
        n = max(1, int(math.floor((last_s - first_s) / dt_s + 1e-9)))
        starts_s = first_s + dt_s * np.arange(n)
        rows.append(np.clip(np.searchsorted(t_s, starts_s + 1e-9, side="right") - 1, 0, t_s.size - 1))
        ends.append(starts_s + dt_s)
    if not ends:
        return np.zeros(0), np.zeros((0, data.shape[1]))
    return np.concatenate(ends), data[np.concatenate(rows)]


def table_records(table, inputs_type=None, dt_s: float = STEP_S) -> Iterator[TableRecord]:
    """:func:`table_steps` as :class:`TableRecord` records (``inputs_type``: the sensor's ``Inputs``; None: the
    onboard ``SensorInputs``). This is the plug point for other sources (a CAN log decoder yields the same
    records)."""
    if inputs_type is None:
        from firmware_model.onboard.sensor import SensorInputs as inputs_type
    t_end, data = table_steps(table, dt_s)
    for end_s, row in zip(t_end.tolist(), data.tolist()):
        yield TableRecord(end_s, inputs_type(*row, t_s=end_s))


def _status_row(st) -> tuple:
    """The status columns of one step (STATUS_COLUMNS, the oil inlet, then the reject counters)."""
    return (
        int(st.degraded_mode != 0),
        int(st.degraded_mode),
        bool(st.speed_valid),
        bool(st.torque_valid),
        bool(st.gear_valid),
        bool(st.oil_valid),
        float(st.oil_innovation_c),
        float(st.model_oil_temp_c),
        float(getattr(st, INLET_COLUMN, math.nan)),
        *np.asarray(st.rejects).tolist(),
    )


def _output_table(times: list, rows_in: list, rows_out: dict, rows_st: list, sensor, state):
    """The replay's run table from its per-step rows (the sensor's published components and reject reasons)."""
    published, reject_reasons = tuple(sensor.published), sensor.reject_reasons
    from tools.runtable import RunTable

    n = len(times)
    cols = {"time_s": np.asarray(times, dtype=float)}
    inputs = _sensor_inputs()
    ins = np.asarray(rows_in, dtype=float).reshape(n, len(inputs))
    for j, (_, col) in enumerate(inputs):
        cols[col] = ins[:, j]
    for (prefix, suffix), rows in rows_out.items():
        block = np.asarray(rows, dtype=float).reshape(n, len(published))
        if prefix == "ttl_":
            block = np.where(np.isinf(block), np.nan, block)  # never = an empty cell
        for j, c in enumerate(published):
            cols[f"{prefix}{c}{suffix}"] = block[:, j]
    names = [*STATUS_COLUMNS, INLET_COLUMN, *(f"rejects_{r}" for r in reject_reasons)]
    st = np.asarray(rows_st, dtype=float).reshape(n, len(names))
    for j, nm in enumerate(names):
        if nm != INLET_COLUMN or getattr(sensor, "oil_inlet", False):  # a splash gearbox's table has no inlet
            cols[nm] = st[:, j]
    return RunTable(cols, meta={"final_state": state})


def replay_records(
    records: Iterable[TableRecord], sensor, initial_oil_c: float | None = None, t0_s: float | None = None
):
    """Step ``sensor`` through :class:`TableRecord` records; returns the output RunTable (one row per step)."""
    fields = [f for f, _ in _sensor_inputs()]
    recs = list(records)
    if not recs:
        raise InputError("the run table has no rows")
    times = np.array([r.t_s for r in recs], dtype=float)
    data = np.array([[r.inputs._asdict()[f] for f in fields] for r in recs], dtype=float)
    if hasattr(sensor, "step_table"):
        return replay_steps(times, data, sensor, initial_oil_c, [r.inputs.t_s for r in recs])
    oil0_c = recs[0].inputs.oil_temp_c if initial_oil_c is None else initial_oil_c
    state = start_state(sensor, oil0_c, recs[0].inputs.ambient_temp_c)
    rows_st = []
    rows_out: dict = {("T_", "_c"): [], ("W_", ""): [], ("ttl_", "_s"): []}
    T_rows, W_rows, ttl_rows = rows_out.values()
    for _, inputs in recs:
        state, out = sensor.step(state, inputs)
        T_rows.append(out.T_c)
        W_rows.append(out.level)
        ttl_rows.append(out.ttl_s)
        rows_st.append(_status_row(out.status))
    return _output_table(times, data, rows_out, rows_st, sensor, state)


def replay_steps(times: np.ndarray, data: np.ndarray, sensor, initial_oil_c: float | None = None, frame_t_s=None):
    """Step a sensor with ``step_table`` (VirtualSensor) through per-step inputs ``data`` (N, 8) ending at
    ``times`` (the frame times, unless ``frame_t_s`` gives others): the whole table in one call (the compiled
    core: in C). Returns the output RunTable."""
    if times.size == 0:
        raise InputError("the run table has no rows")
    oil0_c = float(data[0, 3]) if initial_oil_c is None else initial_oil_c
    state = start_state(sensor, oil0_c, float(data[0, sensor.input_fields.index("ambient_temp_c")]))
    t_frames = times if frame_t_s is None else np.asarray(frame_t_s, dtype=float)
    state, out = sensor.step_table(state, data[:, : len(sensor.input_fields)], t_frames)
    rows_out = {("T_", "_c"): out.T_c, ("W_", ""): out.level, ("ttl_", "_s"): out.ttl_s}
    return _output_table(times, data, rows_out, _status_rows(out), sensor, state)


def held_options(table) -> dict:
    """The sensor options a held table needs (none for a vehicle's table): a row held over its interval is
    bit-identical for up to GAP_PERIODS row periods by construction, so the frozen checks of speed, torque and oil
    look past that (a SCADA channel stuck over more rows is still found); its oil reading changes once a row, so
    the oil step check allows a row period's drift."""
    from firmware_model.onboard.records import SensorOptions
    from tools.drive_table import GAP_PERIODS

    meta = getattr(table, "meta", None) or {}
    if meta.get("drive") != "fixed_ratio":
        return {}
    period_s = float(meta.get("row_period_s") or 0.0)
    held_s = (GAP_PERIODS + 1.0) * period_s
    return {
        "drive_frozen_s": max(SensorOptions.drive_frozen_s, held_s),
        "oil_frozen_s": max(SensorOptions.oil_frozen_s, held_s),
        "oil_period_s": period_s,  # a row's oil reading stands for its interval: the step check looks over it
    }


#: steps of the sensor per call when a slow table is held (the outputs of one call sit in memory)
HELD_CHUNK_STEPS = 100_000
#: the reject counters that count events (one per jump), not steps: a coarse held step does not scale them
EVENT_REJECTS = ("time_jump", "time_backward")
#: a row's mean over its interval (``replay_held(row_means=True)``) from this many samples, the states at the ends
#: of the steps nearest the midpoints of its equal parts (the midpoint rule; at the MM82's 15 s step 75, 225, 375
#: and 525 s into a 10-minute row): near every step's mean for a fraction of keeping every step's outputs
#: (docs/real-data.md, "The estimate is its row's mean")
ROW_MEAN_SAMPLES = 4


def row_mean_steps(n: np.ndarray) -> np.ndarray:
    """(N, ROW_MEAN_SAMPLES) the step of each row (0-based within the row) whose end is nearest the midpoint of
    each of the row's equal parts; ``n`` (N,) the steps of each row (a row of fewer steps repeats some)."""
    mid = (2 * np.arange(ROW_MEAN_SAMPLES) + 1) / (2 * ROW_MEAN_SAMPLES)
    return np.clip(np.rint(np.outer(n, mid)).astype(np.int64), 1, np.asarray(n)[:, None]) - 1


def held_step_of(table, sensor, step_s: float | None = None) -> float:
    """The explicit step [s] a held replay of ``table`` takes with ``sensor``: ``step_s`` when given, else by the
    sensor's ``held_step`` ("auto": the largest the stability proof allows that divides the row period,
    firmware_model.onboard.stability.held_step_s; "reference": the vehicle's 0.1 s)."""
    from firmware_model.onboard.stability import held_step_s

    if step_s is not None:
        period_s, dt_s = _row_period_s(table), float(step_s)
        m = period_s / dt_s if dt_s > 0 else math.nan
        if dt_s != sensor.dt_s and not (np.isfinite(m) and m >= 1 and abs(m - round(m)) <= 1e-9 * m):
            raise InputError(f"a held step of {step_s!r} s does not divide the table's row period of {period_s:g} s")
        return dt_s
    if getattr(sensor, "held_step", "reference") != "auto":
        return sensor.dt_s
    return held_step_s(sensor.reduced.stability, _row_period_s(table), base_s=sensor.dt_s)


def _row_period_s(table) -> float:
    """A held table's row period [s]: its meta's (tools.drive_table.map_fixed_ratio), else the median spacing."""
    from tools.drive_table import row_period_s

    period_s = (getattr(table, "meta", None) or {}).get("row_period_s")
    return float(period_s) if period_s is not None else row_period_s(np.asarray(table["time_s"], dtype=float))


def replay_held(
    table,
    sensor,
    initial_oil_c: float | None = None,
    chunk_steps: int = HELD_CHUNK_STEPS,
    step_s: float | None = None,
    row_means: bool = False,
):
    """A table slower than the step (a fixed-ratio drive's SCADA averages) through a sensor with ``step_table``:
    each row held over its interval (tools.drive_table.held_plan), one output row per input row: the sensor at the
    end of that row's interval (``time_s``), with the inputs of the row. The step (:func:`held_step_of`; ``step_s``
    overrides the sensor's ``held_step``): the MM82's 10-minute rows step every 15 s (40 steps a row, a month
    172,800 steps) where the stability proof allows it, else every 0.1 s (26 million steps a month); the steps run
    ``chunk_steps`` at a time. At a coarser step the time to limit is refreshed once per row period, from the state
    one step before each regular row's end (docs/sensor.md "A coarser step for held tables"), and the reject
    counters count the 0.1 s steps each step stands for (events: one each), as at 0.1 s. ``meta["step_s"]``: the
    step taken. ``row_means``: also each row's mean over its interval of the temperatures (``T_<id>_c``) and of the
    oil inlet and the model's sump, as a SCADA row's reading is its interval's mean (:data:`ROW_MEAN_SAMPLES`), in
    ``meta["row_mean"]`` {column: (N,)}."""
    from tools.drive_table import held_plan

    base = sensor
    dt_s = held_step_of(table, sensor, step_s)
    period_s = _row_period_s(table)
    if dt_s != sensor.dt_s:
        # one time-to-limit refresh per row period (offline batches: 10 s or less often; the live service 1 s)
        sensor = sensor.with_step(dt_s, ttl_period_s=max(period_s, base.options.ttl_period_s))
    t_s = np.asarray(table["time_s"], dtype=float)
    data = np.stack(
        [np.asarray(table[c], dtype=float) if table.has(c) else np.full(t_s.size, np.nan) for _, c in _sensor_inputs()],
        axis=1,
    )
    n, ends_s = held_plan(t_s, sensor.dt_s, period_s, nearest=sensor is not base)
    first = np.concatenate([[0], np.cumsum(n)])  # the first step of each row; the last entry: the number of steps
    oil0_c = float(data[0, 3]) if initial_oil_c is None else initial_oil_c
    state = start_state(sensor, oil0_c, float(data[0, sensor.input_fields.index("ambient_temp_c")]))
    if sensor is not base and 1 < sensor.sp.ttl_every == int(np.median(n)):
        # the refresh follows the steps k = 0, every, 2 every... (step.py): k from 2 puts it after the second-last
        # step of every regular row, its time to limit published (one step counted down) at the row's last step
        state = state._replace(k=np.full(np.shape(state.k), 2 % sensor.sp.ttl_every, dtype=np.int64))
    kept: dict = {"T": [], "W": [], "ttl": [], "status": []}
    sampled = np.zeros(int(first[-1]), dtype=bool)
    if row_means:
        sampled[(first[:-1, None] + row_mean_steps(n)).ravel()] = True
    means = _RowMeans(n.size, len(sensor.published)) if row_means else None
    for k0 in range(0, int(first[-1]), chunk_steps):
        k = np.arange(k0, min(k0 + chunk_steps, int(first[-1])))
        row = np.searchsorted(first, k, side="right") - 1
        last = k == first[row + 1] - 1
        keep = last | sampled[k]  # each row's last step, and its samples for the mean
        state, out = sensor.step_table(
            state, data[row][:, : len(sensor.input_fields)], t_s[row] + sensor.dt_s * (k - first[row] + 1), keep
        )
        if means is not None:
            out = means.add(out, row[keep], sampled[k][keep], last[keep])
        for key, block in (("T", out.T_c), ("W", out.level), ("ttl", out.ttl_s), ("status", _status_rows(out))):
            kept[key].append(np.asarray(block))
    rows_out = {
        ("T_", "_c"): np.concatenate(kept["T"]),
        ("W_", ""): np.concatenate(kept["W"]),
        ("ttl_", "_s"): np.concatenate(kept["ttl"]),
    }
    status = _counted_per_base_step(np.concatenate(kept["status"]), sensor, base)
    out_table = _output_table(ends_s, data, rows_out, status, sensor, state)
    proof = base.reduced.stability or {}
    out_table.meta.update(
        drive="fixed_ratio",
        steps=int(first[-1]),
        step_s=float(sensor.dt_s),
        row_period_s=float(period_s),
        step_proof_s=float(np.min(proof["dt_max_s"])) if len(proof.get("dt_max_s", ())) else math.nan,
        step_limiting_node=str(proof.get("limiting_node", "")),
    )
    if means is not None:
        out_table.meta["row_mean"] = means.columns(sensor.published)
    return out_table


def _counted_per_base_step(status: np.ndarray, sensor, base) -> np.ndarray:
    """The status rows of a coarse step, which stands for dt / 0.1 s steps of ``base``: its reject counters count
    those steps (the events, one each)."""
    per_base = sensor.dt_s / base.dt_s
    if per_base != 1.0:
        n_st = status.shape[1] - len(sensor.reject_reasons)
        for j, reason in enumerate(sensor.reject_reasons):
            if reason not in EVENT_REJECTS:
                status[:, n_st + j] = np.rint(status[:, n_st + j] * per_base)
    return status


class _RowMeans:
    """The sums of :func:`replay_held`'s sampled steps, row by row (``row_means``)."""

    def __init__(self, n_rows: int, n_parts: int):
        self.T = np.zeros((n_rows, n_parts))
        self.inlet = np.zeros(n_rows)
        self.model_oil = np.zeros(n_rows)
        self.count = np.zeros(n_rows)

    def add(self, out, rows: np.ndarray, sampled: np.ndarray, last: np.ndarray):
        """Add the sampled steps of ``out`` (the kept steps of one call: ``rows`` their rows, ``sampled`` and
        ``last`` which they are) and return ``out`` at its rows' last steps only."""
        s = np.flatnonzero(sampled)
        np.add.at(self.T, rows[s], np.asarray(out.T_c)[s])
        np.add.at(self.inlet, rows[s], np.asarray(out.oil_inlet_temp_c)[s])
        np.add.at(self.model_oil, rows[s], np.asarray(out.model_oil_temp_c)[s])
        np.add.at(self.count, rows[s], 1.0)
        return type(out)(*(np.asarray(f)[last] for f in out))

    def columns(self, published) -> dict:
        """{column: (N,) the row's mean}: ``T_<id>_c``, the oil inlet and the model's sump."""
        c = np.maximum(self.count, 1.0)
        cols = {f"T_{p}_c": self.T[:, j] / c for j, p in enumerate(published)}
        cols[INLET_COLUMN] = self.inlet / c
        cols["model_oil_temp_c"] = self.model_oil / c
        return cols


def held_step_line(out) -> str | None:
    """The line a command prints about the step of a held replay (None for a table stepped at 0.1 s rows)."""
    from firmware_model.onboard.stability import HELD_STEP_CAP_S

    meta = getattr(out, "meta", None) or {}
    if "step_s" not in meta:
        return None
    proof = meta.get("step_proof_s", math.nan)
    return (
        f"sensor step: {meta['step_s']:g} s over rows of {meta.get('row_period_s', math.nan):g} s "
        f"({meta.get('steps', 0)} steps; the stability proof allows {proof:.3g} s, node "
        f"{meta.get('step_limiting_node', '?')}; cap {HELD_STEP_CAP_S:g} s; [sensor] held_step)"
    )


def _status_rows(out) -> np.ndarray:
    """The status columns of every step of a TableOutputs (as :func:`_status_row`)."""
    mode = out.degraded_mode.astype(float)[:, None]
    return np.hstack(
        [
            (mode != 0),
            mode,
            out.valid.astype(float),
            out.oil_innovation_c[:, None],
            out.model_oil_temp_c[:, None],
            out.oil_inlet_temp_c[:, None],
            out.rejects.astype(float),
        ]
    )


def replay_table(table, sensor, initial_oil_c: float | None = None, step_s: float | None = None):
    """Run ``sensor`` over a run table at 10 Hz (see :func:`table_records`); returns the sensor output RunTable."""
    if table.n == 0:
        raise InputError("the run table has no rows")
    if initial_oil_c is None:
        meta = getattr(table, "meta", {}) or {}
        if meta.get("initial_temp_c") is not None and not (
            table.has("oil_temp_c") and np.isfinite(table["oil_temp_c"][0])
        ):
            initial_oil_c = float(meta["initial_temp_c"])
    if hasattr(sensor, "step_table") and (getattr(table, "meta", None) or {}).get("drive") == "fixed_ratio":
        return replay_held(table, sensor, initial_oil_c, step_s=step_s)
    if hasattr(sensor, "step_table"):
        times, data = table_steps(table, sensor.dt_s)
        return replay_steps(times, data, sensor, initial_oil_c)
    return replay_records(table_records(table, sensor.Inputs, sensor.dt_s), sensor, initial_oil_c)


def replay_csv(path, config_path=None, sensor_options=None) -> CsvReplay:
    """Read a run table (CSV) and replay it through the onboard sensor of ``config_path`` (None: defaults);
    ``sensor_options``: VirtualSensor options (oil_mode, initial_temp_c)."""
    from firmware_model.config import load_config
    from firmware_model.description import description_of
    from firmware_model.onboard.sensor import VirtualSensor

    cfg = load_config(config_path)
    params = cfg.load_params()
    table = read_inputs_table(path, description_of(params))
    options = {**held_options(table), **(sensor_options or {})}
    sensor = VirtualSensor(params, config=cfg, **options)
    out = replay_table(table, sensor)
    mark_for_findings(out, sensor)
    return CsvReplay(out, params.variant, sensor.options.oil_mode)


def mark_for_findings(out, sensor) -> None:
    """What :func:`table_findings` and the summary need of the sensor, in ``out.meta``: the torque's lower clamp,
    whether the drive is a vehicle's engine (the speed-unit and kN m checks) and this gearbox's limits."""
    from firmware_model.description import description_of
    from firmware_model.service.plausibility import min_torque_nm

    description = description_of(sensor.params)
    out.meta["min_torque_nm"] = min_torque_nm(sensor)
    out.meta["engine_drive"] = description.drive.kind == "vehicle"
    out.meta["drive_limits"] = drive_limits(description)
    out.meta["limits"] = sensor.limits  # the summary's margins: this gearbox's limits, not the GRS905's
    out.meta.update(gear_meta(description))
    out.meta.update(twin_meta(sensor, description))


def twin_meta(sensor, description) -> dict:
    """The model's own sump beside the oil is judged unless a rig conditions the sump (``twin_judged``); the
    auxiliary inputs the gearbox's cooler and boundaries read (``aux_expected``: a missing one is named when the
    oil lies far from that sump). For a run table's replay and a log's alike."""
    from firmware_model.onboard.reduce import aux_inputs_expected

    expected = aux_inputs_expected(description)
    return {
        "twin_judged": not getattr(sensor, "rig", False),
        "aux_expected": tuple(c for c, e in zip(("ambient_temp_c", "coolant_temp_c"), expected) if e),
    }


#: the sensor's outputs of a vehicle's inputs that a fixed-ratio drive's est.csv leaves out: its input speed and
#: torque again under the engine's names (input_speed_rpm and input_torque_nm hold them), and the gear with its
#: validity and reject counters (the description's one gear on every row: valid, never missing, never unknown)
VEHICLE_OUTPUTS = ("engine_speed_rpm", "engine_torque_nm", "gear", "gear_valid", "rejects_gear_missing")
VEHICLE_OUTPUTS += ("rejects_gear_unknown",)


def not_written(description) -> tuple:
    """The columns a fixed-ratio drive's est.csv leaves out: :data:`VEHICLE_OUTPUTS` and each auxiliary input the
    drive has not (firmware_model.onboard.reduce.aux_inputs_expected: the vehicle speed, the retarder torque, and
    the coolant of the MM82's air cooler), which the sensor fills with its default on every row."""
    from firmware_model.onboard.records import I_AMB, INPUT_FIELDS
    from firmware_model.onboard.reduce import aux_inputs_expected

    aux = zip(INPUT_FIELDS[I_AMB:], aux_inputs_expected(description))
    return VEHICLE_OUTPUTS + tuple(c for c, has in aux if not has)


def written_table(out, description):
    """What a run table's est.csv holds: ``out`` itself for a vehicle's drive; for a fixed-ratio drive the speed and
    torque under its run table's names (input_speed_rpm, input_torque_nm) and without the columns of a vehicle it
    has not (:func:`not_written`: the gear, the vehicle speed, the retarder, an air cooler's coolant),
    as the SCADA path writes. The findings and the summary read ``out``."""
    if description.drive.kind == "vehicle":
        return out
    from tools.drive_table import FIXED_RATIO_NAMES
    from tools.runtable import RunTable

    left = set(not_written(description)) - set(FIXED_RATIO_NAMES)  # (the SCADA path has the record's own)
    cols = {FIXED_RATIO_NAMES.get(c, c): out[c] for c in out.columns if c not in left}
    return RunTable(cols, meta=out.meta, source=out.source)


def drive_limits(description) -> tuple | None:
    """A fixed-ratio drive's (max speed [rpm], max torque [N m]) for the plausibility's kN m rule; None for a
    vehicle's (the engine's own rule)."""
    d = description.drive
    return None if d.kind == "vehicle" else (d.max_speed_rad_s * 60.0 / (2.0 * math.pi), d.max_torque_nm)


def drive_knm_finding(speed_rpm, torque_nm, description, dt_s: float):
    """The kN m finding of ``description``'s fixed-ratio drive over these inputs, one every ``dt_s``
    (firmware_model.service.plausibility.fixed_torque_knm_finding), or None (also for a vehicle's drive)."""
    from firmware_model.service.plausibility import fixed_torque_knm_finding

    limits = drive_limits(description)
    return None if limits is None else fixed_torque_knm_finding(speed_rpm, torque_nm, limits, dt_s, "table")


def gear_meta(description) -> dict:
    """The gear-numbering rule's inputs (firmware_model.service.plausibility.gear_ratio_finding): the gearbox's name
    and its gears' ratios, for a vehicle's drive (none for a fixed-ratio one)."""
    if description.drive.kind != "vehicle":
        return {}
    ratios = {g.number: g.ratio for g in description.gears if g.number != 0 and math.isfinite(g.ratio)}
    return {"gearbox": description.name, "gear_ratios": ratios}


def table_findings(out, oil_model: bool = False) -> list:
    """The trust findings of a run-table replay (``firmware_model.service.trust``): columns that look like another
    unit (time in ms, engine speed in rad/s; oil in degF or kelvin, torque negated or in percent, and clamps or
    repairs on more than 5 % of the steps: ``firmware_model.service.plausibility``), the degraded share when it is
    at least DEGRADED_WARN_SHARE, with the inputs that were missing (the validity columns); ``oil_model``: the
    sensor modelled the oil by request (not degraded)."""
    from firmware_model.onboard.records import SensorOptions
    from firmware_model.service.degraded import (
        Severity,
        degraded_finding,  # (not trust: that imports python-can)
        unit_findings,
    )
    from firmware_model.service.plausibility import is_held, table_record_findings

    modes = np.asarray(out["degraded_mode"], dtype=float) if out.n else np.zeros(0)
    values, counts = np.unique(modes[np.isfinite(modes)].astype(int), return_counts=True)
    missing = {
        c: int(np.sum(np.asarray(out[c]) == 0))
        for c in ("speed_valid", "torque_valid", "gear_valid", "oil_valid")
        if out.has(c)
    }
    engine = (out.meta or {}).get("engine_drive", True)
    word = "rows" if is_held(out.meta or {}) else "steps"  # a held table's rows are its input rows
    finding = degraded_finding(
        dict(zip(values.tolist(), counts.tolist())), missing, oil_model, engine=engine, step_word=word
    )
    jumps = int(out["rejects_time_jump"][-1]) if out.n and out.has("rejects_time_jump") else 0
    units = unit_findings(
        out.n,
        jumps,
        out["time_s"] if out.n else [],
        out["engine_speed_rpm"] if out.has("engine_speed_rpm") else [],
        out["engine_torque_nm"] if out.has("engine_torque_nm") else [],
        hold_s=SensorOptions().time_jump_hold_s,
        engine=engine,
    )
    units += table_record_findings(out, (out.meta or {}).get("min_torque_nm"))
    if not engine and out.n:  # a fixed-ratio drive's rows may lie minutes apart, not hours: ms read as s
        from firmware_model.service.degraded import UnitFinding
        from tools.runtable import milliseconds_sentence

        ms = milliseconds_sentence(out["time_s"], "time_s", sparse_ok=True)
        units = ([UnitFinding(ms)] if ms else []) + units  # (first: the oil's gap to the model follows from it)
    return units + ([finding] if finding.severity >= Severity.WARNING else [])


def summarize(out) -> ReplaySummary:
    """The figures the command line prints after a table replay."""
    n = out.n
    # the published components: those with an estimate and a warning level
    published = [k[2:-2] for k in out.columns if k.startswith("T_") and k.endswith("_c") and out.has(f"W_{k[2:-2]}")]
    hottest = max(published, key=lambda c: np.nanmax(out[f"T_{c}_c"]))
    rejects = {
        k[len("rejects_") :]: int(out[k][-1]) for k in out.columns if k.startswith("rejects_") and n and out[k][-1] > 0
    }
    from firmware_model.service.plausibility import is_held

    meta = out.meta or {}
    held = is_held(meta)  # one row per input row, in steps of step_s: the last row covers its own period
    return ReplaySummary(
        span_s=(meta["steps"] * meta["step_s"] if held else out["time_s"][-1] - out["time_s"][0] + STEP_S)
        if n
        else 0.0,
        steps=int(meta["steps"]) if held else n,
        hottest=hottest,
        hottest_c=float(np.nanmax(out[f"T_{hottest}_c"])),
        max_level=max(int(np.nanmax(out[f"W_{c}"])) for c in published),
        degraded_share=float(np.mean(out["degraded"])) if n else 0.0,
        rejects=rejects,
    )
