"""The CAN service over a whole log at once: the same run table, bit for bit, as feeding its frames one by one.

:func:`run_columns` takes a service built for an offline replay (``record=True``, ``emit_frames=False``) and the
frames of a log as columns (``can_dbc.columnar.FrameColumns``) and does what :meth:`SensorService.feed` does frame
by frame, with numpy over the columns:

1. the decoder's half: ``can_dbc.columnar.decode_columns`` (every value, time and counter of ``feed_into``);
2. the frame half of every step: the step grid on frame time (anchored at the first frame of a wanted PGN, one
   step per 0.1 s boundary a frame passes, a catch-up of up to ``max_catchup_steps``, a forward or backward time
   jump restarting the grid and forgetting every input), which inputs are fresh at each boundary (the latest value
   of the frames *before* the one that passes it, not older than ``stale_factor`` periods), the gear map, the
   reference torque, initialisation, the time-base check;
3. the sensor half: the sensor's ``step_table`` over every initialised step (the compiled core: in C, its time to
   limit refreshed between kernel calls), the status and the recorded columns.

The counters (``service.counters``, ``service.decoder.counters``) end as the frame path leaves them; what only a
live run does (frames sent, DM1, logging every minute) is not done.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np

from can_dbc.columnar import (
    FLAG_ERROR,
    FLAG_EXTENDED,
    FLAG_FD,
    FLAG_REMOTE,
    DecodedColumns,
    FrameColumns,
    decode_columns,
    pgn_keys,
)
from can_dbc.decoder import signal_messages
from can_dbc.j1939 import ID_MAX
from firmware_model.components import MODE_NOT_INITIALISED, STEP_S
from firmware_model.physics.oil import T_MAX_C as OIL_T_MAX_C
from firmware_model.physics.oil import T_MIN_C as OIL_T_MIN_C
from firmware_model.service.degraded import recorded_mode_counters, recorded_reject_counters
from firmware_model.service.options import GEAR_RANGE, NOMINAL_PERIOD_S, SENSOR_INPUTS, wanted_pgns
from firmware_model.service.protocol import start_state
from firmware_model.service.recorder import StepRecorder
from firmware_model.service.records import RecordedOutputs, StepKind
from firmware_model.service.trust import TIME_EVENT, TimeBaseCheck, log_time_glitch

#: timing frames examined per vectorised pass of the step grid (fewer right after a time jump)
_GRID_CHUNK_MAX = 65536
_GRID_CHUNK_MIN = 256


class Grid(NamedTuple):
    """The steps of a log: the frame that triggered each (its index), its boundary time, its run-table time; the
    anchors (frame index, frame time; the first, then one per time jump) and which of them were time jumps."""

    trigger: np.ndarray
    t_step_s: np.ndarray
    t_s: np.ndarray
    anchor_frame: np.ndarray
    anchor_t_s: np.ndarray
    jump_frames: np.ndarray
    catchup_steps: int
    #: (frame index, its time, the grid's last step time, the next timing frame's time or None) of each timing
    #: frame whose time stamp alone lay far ahead (a glitch: no jump)
    glitches: tuple = ()


def _boundaries(t_s: np.ndarray, t0_s: float) -> np.ndarray:
    """Per frame the largest n with ``t0 + n x STEP_S <= t`` in the same float sums as the service."""
    n = np.floor((t_s - t0_s) / STEP_S).astype(np.int64)
    while True:
        over = t0_s + n * STEP_S > t_s
        if not over.any():
            break
        n -= over
    while True:
        under = t0_s + (n + 1) * STEP_S <= t_s
        if not under.any():
            break
        n += under
    return n


def step_grid(t_frame_s: np.ndarray, timing: np.ndarray, max_catchup: int, backward_tol_s: float) -> Grid:
    """The service's step grid over the timing frames ``timing`` (indices, file order) of frame times
    ``t_frame_s`` (``SensorService.feed``: anchor, due steps, forward and backward time jumps)."""
    ts = t_frame_s[timing]
    trig, tstep, toff = [], [], []
    anchors, anchor_t, jumps, glitches = [], [], [], []
    t0 = first = None
    k, offset, catchup, pos, size = 0, 0.0, 0, 0, _GRID_CHUNK_MIN
    while pos < ts.size:
        if t0 is None:
            t0 = first = float(ts[pos])
            anchors.append(int(timing[pos]))
            anchor_t.append(t0)
            pos += 1
            continue
        c = ts[pos : pos + size]
        n = _boundaries(c, t0)
        cm = np.maximum.accumulate(np.maximum(n, k))
        kprev = np.concatenate([[k], cm[:-1]])
        nb = t0 + (kprev + 1) * STEP_S
        stepping = c >= nb
        fwd = stepping & (n - kprev > max_catchup)
        bwd = ~stepping & (c < nb - STEP_S - backward_tol_s)
        events = np.flatnonzero(fwd | bwd)
        stop = int(events[0]) if events.size else c.size
        s = np.flatnonzero(stepping[:stop])
        due = n[s] - kprev[s]
        total = int(due.sum())
        if total:
            rep = np.repeat(s, due)
            within = np.arange(total) - np.repeat(np.cumsum(due) - due, due)
            kk = np.repeat(kprev[s], due) + within + 1
            trig.append(timing[pos + rep])
            tstep.append(t0 + kk * STEP_S)
            toff.append(np.full(total, offset))
            catchup += total - s.size
        if events.size:
            j = stop
            t_j = float(c[j])
            nxt = pos + j + 1
            if fwd[j] and (nxt == ts.size or ts[nxt] < t_j - STEP_S - backward_tol_s):
                # the next timing frame is back near the grid (or there is none): this one frame's time stamp is a
                # glitch, not a jump (SensorService._settle_ahead): the grid goes on from the frame after it
                glitches.append(
                    (int(timing[pos + j]), t_j, t0 + int(kprev[j]) * STEP_S, float(ts[nxt]) if nxt < ts.size else None)
                )
                k, pos, size = int(kprev[j]), nxt, _GRID_CHUNK_MIN
                continue
            if bwd[j]:
                offset += t0 + int(kprev[j]) * STEP_S - t_j  # as SensorService._time_jump
            jumps.append(int(timing[pos + j]))
            anchors.append(int(timing[pos + j]))
            anchor_t.append(t_j)
            t0, k = t_j, 0
            pos += j + 1
            size = _GRID_CHUNK_MIN
        else:
            k = int(cm[-1])
            pos += c.size
            size = min(2 * size, _GRID_CHUNK_MAX)

    def cat(parts, dt):
        return np.concatenate(parts) if parts else np.zeros(0, dtype=dt)

    t_step_s = cat(tstep, float)
    t_s = t_step_s - (first if first is not None else 0.0) + cat(toff, float)
    return Grid(
        cat(trig, np.int64),
        t_step_s,
        t_s,
        np.array(anchors, dtype=np.int64),
        np.array(anchor_t),
        np.array(jumps, dtype=np.int64),
        catchup,
        tuple(glitches),
    )


class _Fresh:
    """Which value of each signal is fresh at each step: the latest from a frame before the step's trigger, not
    forgotten by a time jump since, not older than its limit."""

    def __init__(self, decoded: DecodedColumns, grid: Grid) -> None:
        self.tracks, self.grid = decoded.tracks, grid
        jumps = grid.jump_frames
        at = np.searchsorted(jumps, grid.trigger, side="right") - 1
        self.forgot = np.where(at >= 0, jumps[np.maximum(at, 0)] if jumps.size else -1, -1)

    def values(self, name: str, max_age_s: float) -> np.ndarray:
        """The fresh value of ``name`` at every step, NaN where there is none."""
        n = self.grid.trigger.size
        track = self.tracks.get(name)
        if track is None or not track.frame.size:
            return np.full(n, np.nan)
        j = np.searchsorted(track.frame, self.grid.trigger, side="left") - 1
        jj = np.maximum(j, 0)
        fresh = (j >= 0) & (track.frame[jj] >= self.forgot) & (self.grid.t_step_s - track.time_s[jj] <= max_age_s)
        return np.where(fresh, track.value[jj], np.nan)


def _model_gear(gear: np.ndarray, gear_map) -> np.ndarray:
    """The service's gear mapping (``gear_map``, then the model's range) over an array; NaN = not available."""
    out = gear.copy()
    if gear_map is not None:
        known = np.isfinite(gear)
        mapped = np.full(gear.shape, np.nan)
        for g in np.unique(gear[known]).tolist():
            m = gear_map.get(int(g))
            if m is not None:
                mapped[gear == g] = m
        out = mapped
    return np.where((out >= GEAR_RANGE[0]) & (out <= GEAR_RANGE[1]), out, np.nan)


def _time_base(service, grid: Grid, decoded: DecodedColumns) -> np.ndarray:
    """The time-base check at every step (``TimeBaseCheck`` at each window close and anchor); the suspect flag each
    step's request carries; ``service.counters["time_base"]`` as the frame path leaves it."""
    opts = service.options
    check = TimeBaseCheck(opts.time_base_window_s, opts.time_base_windows)
    keys = tuple(service.decoder.counters["arrivals"])

    def arrivals(frame: int) -> dict:
        return {k: int(np.searchsorted(decoded.arrivals[k], frame)) if k in decoded.arrivals else 0 for k in keys}

    n = grid.t_step_s.size
    suspect = np.zeros(n, dtype=bool)
    tb = service.counters["time_base"]
    epoch = np.searchsorted(grid.anchor_frame, grid.trigger, side="right") - 1
    starts = np.searchsorted(epoch, np.arange(grid.anchor_frame.size))
    ends = np.append(starts[1:], n)
    for a in range(grid.anchor_frame.size):
        check.restart(float(grid.anchor_t_s[a]), arrivals(int(grid.anchor_frame[a])))
        i, end = int(starts[a]), int(ends[a])
        while i < end:
            suspect[i:end] = check.suspect
            span = grid.t_step_s[i:end] - check.window_start_s
            due = np.flatnonzero(span >= check.window_s)
            if not due.size:
                break
            i += int(due[0])
            suspect[i] = check.suspect
            event = check.update(float(grid.t_step_s[i]), arrivals(int(grid.trigger[i])))
            if event is not None and event != "cleared" and tb["finding"] is None:
                tb["finding"] = dataclasses.asdict(event)
            i += 1
    if n:
        tb.update(windows_checked=check.windows_checked, windows_suspect=check.windows_suspect, suspect=check.suspect)
    return suspect


class FrameHalf(NamedTuple):
    """Every step's frame half: kind, the inputs (steps x 8, NaN = not available), percent and reference torque,
    the rig thermocouples (NaN where none is fresh) and which thermocouples were ever received."""

    grid: Grid
    kind: np.ndarray
    inputs: np.ndarray
    pct: np.ndarray
    ref_nm: np.ndarray
    meas_c: np.ndarray
    meas_seen: tuple


#: the whole-log path logs this many time jumps one by one, then how many more there were
JUMPS_LOGGED = 20
#: ... in this line
JUMPS_MORE = "%d more frame time jumps (not logged one by one)"


def _count_out_of_order(counters: dict, t_frame_s: np.ndarray, max_back_s: float) -> None:
    """Frames earlier than the (finite) frame before them by at most ``max_back_s``, as
    SensorService._check_order counts them."""
    t = t_frame_s[np.isfinite(t_frame_s)]
    back = -np.diff(t) if t.size > 1 else np.zeros(0)
    late = back[(back > 0.0) & (back <= max_back_s)]
    counters["frames_out_of_order"] += int(late.size)
    if late.size:
        counters["out_of_order_max_s"] = max(counters["out_of_order_max_s"], float(late.max()))


def _log_jumps(log, grid: Grid, t_frame_s: np.ndarray) -> None:
    """Log the grid's time jumps as the frame path does, one warning each (the summary counts them and points to
    these messages)."""
    for _i, f in enumerate(grid.jump_frames[:JUMPS_LOGGED]):
        before = int(np.searchsorted(grid.trigger, f, side="left")) - 1
        epoch = int(np.searchsorted(grid.anchor_frame, f, side="left")) - 1
        last_s = (
            float(grid.t_step_s[before])
            if before >= 0 and grid.trigger[before] > grid.anchor_frame[epoch]
            else float(grid.anchor_t_s[epoch])
        )
        t_s = float(t_frame_s[f])
        log.warning(
            "frame time jumped %s by %.3f s (from %.6f to %.6f): restarting the step grid, inputs dropped, "
            "the sensor resumes from its state",
            "backward" if t_s < last_s else "forward",
            abs(t_s - last_s),
            last_s,
            t_s,
            extra={TIME_EVENT: "jump"},
        )
    if grid.jump_frames.size > JUMPS_LOGGED:
        log.warning(JUMPS_MORE, grid.jump_frames.size - JUMPS_LOGGED, extra={TIME_EVENT: "jumps_more"})


def frame_half(service, cols: FrameColumns, decoded: DecodedColumns, meas_names: tuple) -> FrameHalf:
    """The service's frame half over a decoded log; updates ``service.counters`` as the frame path does."""
    opts = service.options
    flags = cols.flags
    ext_ok = (
        ((flags & FLAG_EXTENDED) != 0)
        & ((flags & (FLAG_ERROR | FLAG_REMOTE | FLAG_FD)) == 0)
        & (cols.can_id >= 0)
        & (cols.can_id <= ID_MAX)
        & np.isfinite(cols.timestamp_s)
    )
    timing = np.flatnonzero(
        ext_ok & np.isin(np.where(ext_ok, pgn_keys(np.where(ext_ok, cols.can_id, 0)), -1), list(wanted_pgns().values()))
    )
    grid = step_grid(cols.timestamp_s, timing, opts.max_catchup_steps, opts.backward_tolerance_s)
    counters = service.counters
    counters["frames_not_timing"] += len(cols) - timing.size
    counters["steps"] += grid.t_step_s.size
    counters["catchup_steps"] += grid.catchup_steps
    counters["time_jumps"] += grid.jump_frames.size
    for i, (_, glitch_s, grid_s, next_s) in enumerate(grid.glitches):
        counters["frames_time_glitch"] += 1
        log_time_glitch(service.log, glitch_s, grid_s, next_s, i + 1)
    _count_out_of_order(counters, cols.timestamp_s, STEP_S + opts.backward_tolerance_s)
    _log_jumps(service.log, grid, cols.timestamp_s)
    fresh = _Fresh(decoded, grid)
    max_age = {m: opts.stale_factor * p for m, p in NOMINAL_PERIOD_S.items()}
    messages = signal_messages()
    n = grid.t_step_s.size
    inputs = np.empty((n, len(SENSOR_INPUTS)))
    stale = counters["stale_steps"]
    for j, (_, signal) in enumerate(SENSOR_INPUTS):
        inputs[:, j] = fresh.values(signal, max_age[messages[signal]])
        missing = int(np.count_nonzero(np.isnan(inputs[:, j])))
        if missing:
            stale[signal] = stale.get(signal, 0) + missing
    j1939_gear = inputs[:, 2].copy()
    inputs[:, 2] = _model_gear(j1939_gear, opts.gear_map)
    counters["gear_unmapped_steps"] += int(np.count_nonzero(~np.isnan(j1939_gear) & np.isnan(inputs[:, 2])))
    inputs[:, 7] = np.abs(inputs[:, 7])  # J1939 reports retarder braking negative
    pct = fresh.values("engine_torque_pct", max_age[messages["engine_torque_pct"]])
    k = np.searchsorted(decoded.ec1_frame, grid.trigger, side="left") - 1
    configured = np.nan if opts.configured_ref_torque_nm is None else opts.configured_ref_torque_nm
    ref_nm = np.where(
        k >= 0, decoded.ec1_ref_torque_nm[np.maximum(k, 0)] if decoded.ec1_frame.size else configured, configured
    )
    meas_c = (
        np.stack([fresh.values(m, max_age["RIG"]) for m in meas_names], axis=1) if n else np.zeros((0, len(meas_names)))
    )
    first_s = grid.anchor_t_s[0] if grid.anchor_t_s.size else 0.0
    oil = inputs[:, 3]
    plausible = (oil >= OIL_T_MIN_C) & (oil <= OIL_T_MAX_C)  # (as SensorService._initialisation; NaN: not)
    waiting = ~plausible & (grid.t_step_s - first_s < opts.init_wait_s - 1e-9)
    ready = np.flatnonzero(~waiting)
    kind = np.full(n, int(StepKind.NOT_INITIALISED), dtype=np.int8)
    if ready.size:
        kind[ready[0]] = int(StepKind.INITIALISE)
        kind[ready[0] + 1 :] = int(StepKind.STEP)
        counters["started_without_oil"] = bool(not plausible[ready[0]]) and getattr(service, "restore", None) is None
    counters["uninitialised_steps"] += int(ready[0]) if ready.size else n
    return FrameHalf(grid, kind, inputs, pct, ref_nm, meas_c, tuple(m in decoded.tracks for m in meas_names))


def _opt(x: np.ndarray) -> np.ndarray:
    return np.where(np.isfinite(x), x, np.nan)


def sensor_half(service, half: FrameHalf) -> RecordedOutputs:
    """The sensor's step over every initialised step (``step_table``); the not-initialised steps as the service
    records them. Updates ``service.state`` and the steps per degraded mode."""
    n = half.kind.size
    n_pub, sensor = len(service.published), service.sensor
    n_rej = len(sensor.reject_reasons)
    T = np.full((n, n_pub), np.nan)
    level = np.full((n, n_pub), 3.0)
    ttl = np.full((n, n_pub), np.nan)
    tail = np.zeros((n, 9 + n_rej))
    ready = np.flatnonzero(half.kind != int(StepKind.NOT_INITIALISED))
    i0 = int(ready[0]) if ready.size else n
    ins, ref_ok = half.inputs, np.isfinite(half.ref_nm).astype(float)
    nan = math.nan
    tail[:i0, 0] = float(MODE_NOT_INITIALISED != 0)
    tail[:i0, 1] = MODE_NOT_INITIALISED
    tail[:i0, 2:5] = np.isfinite(ins[:i0, :3])
    tail[:i0, 5] = 0.0
    tail[:i0, 6] = ref_ok[:i0]
    tail[:i0, 7:9] = nan
    base = None
    if i0 < n:
        oil0 = ins[i0, 3]
        state = start_state(sensor, float(oil0), float(ins[i0, sensor.input_fields.index("ambient_temp_c")]))
        base = getattr(state, "rejects", None)
        state, out = sensor.step_table(state, np.ascontiguousarray(ins[i0:]), half.grid.t_s[i0:])
        service.state = state
        T[i0:], level[i0:], ttl[i0:] = out.T_c, out.level, out.ttl_s
        mode = out.degraded_mode.astype(float)
        tail[i0:, 0] = mode != 0
        tail[i0:, 1] = mode
        tail[i0:, 2:6] = out.valid
        tail[i0:, 6] = ref_ok[i0:]
        tail[i0:, 7] = _opt(out.oil_innovation_c)
        tail[i0:, 8] = _opt(out.model_oil_temp_c)
        tail[i0:, 9:] = out.rejects[:, :n_rej]
    service.counters.update(recorded_mode_counters(tail[:, 1]))
    if n_rej:
        service.counters.update(
            recorded_reject_counters(
                tail[i0:, 9:], sensor.reject_reasons[:n_rej], ins[i0:, sensor.input_fields.index("oil_temp_c")], base
            )
        )
    return RecordedOutputs(T, level, ttl, tail)


def run_columns(service, cols: FrameColumns) -> dict[str, np.ndarray]:
    """A whole log through ``service`` (fresh, ``record=True``, ``emit_frames=False``): the run-table columns of
    ``service.recorded()`` after feeding the frames one by one, bit for bit, and the same counters."""
    if not service.record or service.emit_frames:
        raise ValueError("run_columns needs a fresh SensorService built with record=True, emit_frames=False")
    if service.counters["steps"] or service.decoder.counters["frames_seen"]:
        raise ValueError("run_columns needs a fresh SensorService (no frame fed yet)")
    meas_names = tuple(f"meas_T_{c}_c" for c in service.published)
    decoded = decode_columns(cols, service.decoder)
    half = frame_half(service, cols, decoded, meas_names)
    _time_base(service, half.grid, decoded)
    outputs = sensor_half(service, half)
    recorder = StepRecorder(service.published, meas_names, service.sensor.reject_reasons)
    g = half.grid
    head = np.column_stack([g.t_s, g.t_step_s, half.inputs, half.pct, half.ref_nm]) if g.t_s.size else np.zeros((0, 12))
    recorder.adopt_heads(head, half.meas_c)
    recorder.adopt(outputs)
    return recorder.columns(half.meas_seen)


__all__ = ["FrameHalf", "Grid", "frame_half", "run_columns", "sensor_half", "step_grid"]
