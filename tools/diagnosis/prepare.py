"""Stage 1 of the diagnosis: load the measured runs, validate them and put their channels on the analysis grid.

Input: measured run tables (CSV) or CAN logs with the oil sensor ``oil_temp_c`` and/or rig thermocouples
``meas_T_<id>_c``. Every problem is an InputError of one sentence naming the file and the column.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from firmware_model.errors import InputError
from firmware_model.physics.oil import check_temperature_c
from tools.diagnosis.options import INPUT_COLUMNS, J1939_RES_C, LOG_SUFFIXES, OIL, OIL_RIG, Options
from tools.diagnosis.overlap import check_held_out
from tools.runtable import REQUIRED, RunTable, read_run_table, validate_run_table


class ChannelColumns(NamedTuple):
    """The measured column of a channel and the model column that predicts it."""

    column: str
    model_column: str


@dataclass(frozen=True, eq=False)
class Channel:
    """One measured channel of one file: its valid raw samples and their averages on the analysis grid."""

    id: str  # 'oil' or component id
    column: str  # measured column
    model_column: str  # model column predicting it
    t_s: np.ndarray  # raw valid sample times
    y_c: np.ndarray  # raw valid values
    cell_t_s: np.ndarray  # mean sample time per grid cell
    cell_y_c: np.ndarray  # mean value per grid cell
    cell_n: np.ndarray  # samples per grid cell


@dataclass(frozen=True, eq=False)
class Dataset:
    """One measured file, ready for the diagnosis."""

    name: str
    role: str  # 'train' or 'test'
    inputs: RunTable  # the drive inputs (and the oil when it is an input), meta['initial_temp_c']
    channels: dict  # channel id -> Channel
    initial_temp_c: float
    t_start_s: float
    t_end_s: float
    warnings: tuple = ()
    start: str = "rest"  # 'rest', or 'running': scored from scored_from_s (tools/diagnosis/start.py)
    scored_from_s: float | None = None


class Runs(NamedTuple):
    """The prepared training and test files."""

    train: list
    test: list


def channel_columns(table: RunTable) -> dict:
    """Channel id -> ChannelColumns of every measured channel in `table`."""
    out = {}
    if table.has("oil_temp_c"):
        out[OIL] = ChannelColumns("oil_temp_c", "oil_temp_c")
    for c in table.columns:
        if c.startswith("meas_T_") and c.endswith("_c"):
            cid = c[len("meas_T_") : -2]
            # a rig thermocouple in the sump is not the vehicle's oil sensor (no sensor lag effect on it)
            out[cid if cid != OIL else OIL_RIG] = ChannelColumns(c, f"T_{cid}_c")
    return out


# ----------------------------------------------------------------------------------------------------------------
# loading


def _table_from_can_log(p: Path, path, config_path) -> RunTable:
    """The measured run table of a CAN log, decoded through the sensor's own CAN service."""
    try:
        from firmware_model.service import build_service
        from firmware_model.service.trust import Severity
        from tools.replay.formats import is_can_log
        from tools.replay.log import replay_log
    except ImportError:
        raise InputError(
            f"{path}: CAN logs need the log decoder (tools/replay/log.py), which is not installed; "
            f"convert the log to a CSV run table first"
        ) from None
    if not is_can_log(p):
        raise InputError(f"{path}: {p.suffix} logs are not supported; use .log, .asc, .blf, .mf4 or .trc")
    service = build_service(config_path, record=True, emit_frames=False, log_findings=False)
    rec = replay_log(p, service)
    # what the sensor's service found untrustworthy (firmware_model.service.trust): a wrong clock makes every rate
    # and lag of the diagnosis wrong; inputs from unexpected source addresses explain missing channels
    untrusted = [f for f in service.findings() if f.kind != "degraded" and f.severity >= Severity.UNTRUSTED]
    for f in untrusted:
        if f.kind == "time_base":
            raise InputError(f"{path}: {f.sentence}")
    hint = "".join(f"; {f.sentence}" for f in untrusted)
    keep = [c for c in INPUT_COLUMNS + ("oil_temp_c",) if rec.has(c)] + [
        c for c in rec.columns if c.startswith("meas_T_") and c.endswith("_c")
    ]
    cols = {c: np.asarray(rec[c], dtype=float) for c in keep}
    foreign = [f for f in service.findings() if f.kind == "foreign_source" and f.message == "TRF1"]
    if foreign and not np.any(np.isfinite(cols.get("oil_temp_c", np.zeros(0)))):
        # the oil sensor is there, on another source address: not a dead sensor (what the column check would say)
        raise InputError(
            f"{path}: the log carries no oil temperature from the expected source address; {foreign[0].sentence}"
        )
    # the first steps before every drive signal has arrived carry no input: drop them
    ok = np.ones(rec.n, dtype=bool)
    for c in REQUIRED:
        if c not in cols:
            raise InputError(
                f"{path}: the log never carries {c} (its J1939 message is missing or from another "
                f"source address); check the [can] section of the configuration{hint}"
            )
        ok &= np.isfinite(cols[c])
    if not ok.any():
        raise InputError(f"{path}: no step of the log has engine speed, torque and gear together{hint}")
    first = int(np.argmax(ok))
    t = RunTable({c: v[first:] for c, v in cols.items()}, meta={"source": "can"}, source=os.fspath(path))
    # a drive signal that drops out later is held (the sensor does the same)
    for c in REQUIRED[1:]:
        v = t[c]
        bad = ~np.isfinite(v)
        if bad.any():
            idx = np.maximum.accumulate(np.where(bad, 0, np.arange(v.size)))
            t[c] = v[idx]
    return t


def load_table(path, config_path=None) -> RunTable:
    """A measured run table from a CSV file, or from a CAN log (candump -L .log, .asc, .blf, .mf4, .trc) decoded through
    the sensor's own CAN service (tools.replay.log): the decoded inputs, the oil sensor (TRF1) and the rig
    thermocouple frames (meas_T_<id>_c); the sensor's own estimates are dropped."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{path}: no such file")
    if p.suffix.lower() in LOG_SUFFIXES:
        return _table_from_can_log(p, path, config_path)
    t = read_run_table(p)
    t.source = os.fspath(path)
    return t


def fingerprint(table: RunTable) -> str:
    """A hash of the drive and the measured channels: the same run given twice has the same fingerprint."""
    h = hashlib.sha1()
    for c in ("time_s", "engine_speed_rpm", "engine_torque_nm", "gear"):
        h.update(np.ascontiguousarray(table[c]).tobytes())
    for c in channel_columns(table).values():
        h.update(np.ascontiguousarray(table[c.column]).tobytes())
    return h.hexdigest()


class Loaded(NamedTuple):
    name: str
    table: RunTable
    source: object  # the RunTable or the path it came from


def _load_all(items, names, role: str, config_path) -> list:
    out = []
    for i, it in enumerate(items):
        if isinstance(it, RunTable):
            tb = it
            nm = (names[i] if names else None) or it.source or f"{role}{i + 1}"
        else:
            tb = load_table(it, config_path)
            nm = (names[i] if names else None) or os.fspath(it)
        out.append(Loaded(nm, tb, it))
    return out


def _check_distinct(train: list, test: list) -> None:
    """Train and test must be different runs, and no run given twice (same path or same data)."""
    seen = {}
    for role, items in (("train", train), ("test", test)):
        for item in items:
            keys = [("data", fingerprint(item.table))]
            if not isinstance(item.source, RunTable):
                keys.insert(0, ("path", os.path.realpath(item.source)))
            for k in keys:
                if k in seen:
                    other, orole = seen[k]
                    if orole != role:
                        raise InputError(
                            f"{item.name} is both a training and a test file (same data as {other}); "
                            f"the test files must be different runs"
                        )
                    raise InputError(
                        f"{item.name} is given twice as a {role} file (same data as {other}); give each run once"
                    )
                seen[k] = (item.name, role)


def prepare_runs(
    train_tables,
    test_tables,
    opts: Options,
    oil_is_input: bool,
    train_names=None,
    test_names=None,
    config_path=None,
    params=None,
) -> Runs:
    """Load (RunTables or paths), check that train and test differ, prepare every file; the test files may only
    measure channels that some training file measures. ``params``: the drive columns are also checked against its
    engine and gearbox (what the plant would refuse later), naming the file."""
    if not train_tables:
        raise InputError("give at least one training file (--train)")
    if not test_tables:
        raise InputError("give at least one test file (--test)")
    tr = _load_all(train_tables, train_names, "train", config_path)
    te = _load_all(test_tables, test_names, "test", config_path)
    _check_distinct(tr, te)
    if params is not None:
        from tools.plant.reference import validate_drive

        for x in tr + te:
            try:
                validate_drive(x.table, params)
            except InputError as exc:
                raise InputError(f"{x.name}: {exc}") from None
    # after each file's own checks: a copy with a broken row is told by the row
    check_held_out(tr, te, oil_is_input)
    train = [prepare(x.table, x.name, "train", opts, oil_is_input, params) for x in tr]
    test = [prepare(x.table, x.name, "test", opts, oil_is_input, params) for x in te]
    ch_tr = {c for ds in train for c in ds.channels}
    missing = sorted({c for ds in test for c in ds.channels} - ch_tr)
    if missing:
        raise InputError(
            f"channel(s) {', '.join(missing)} are measured in the test files but in no training file; "
            f"the diagnosis can only test what it was trained on"
        )
    return Runs(train, test)


# ----------------------------------------------------------------------------------------------------------------
# validation and the analysis grid


def _longest_nan_run(t, valid):
    """Longest time span [s] without a valid sample (start, length)."""
    tv = t[valid]
    if tv.size == 0:
        return t[0], t[-1] - t[0]
    edges = np.concatenate([[t[0]], tv, [t[-1]]])
    d = np.diff(edges)
    k = int(np.argmax(d))
    return float(edges[k]), float(d[k])


def _check_time(t: np.ndarray, name: str, opts: Options, fixed_ratio: bool = False) -> None:
    from tools.runtable import milliseconds_sentence

    if t.size < 10:
        raise InputError(f"{name}: has only {t.size} rows; the diagnosis needs at least 10 samples")
    ms = milliseconds_sentence(t, name, sparse_ok=fixed_ratio)
    if ms:
        raise InputError(ms)
    dt = np.diff(t)
    med = float(np.median(dt))
    gap_lim = max(opts.max_time_gap_s, 50 * med)
    k = int(np.argmax(dt))
    if dt[k] > gap_lim:
        raise InputError(
            f"{name}: column time_s jumps from {t[k]:.10g} s to {t[k + 1]:.10g} s (a gap of "
            f"{dt[k]:.0f} s, more than {gap_lim:.0f} s); split the file at the gap"
        )


class ValidSamples(NamedTuple):
    """The valid samples of a measured column, and a warning about it ('' when none)."""

    t_s: np.ndarray
    y_c: np.ndarray
    warning: str


#: a column with fewer valid values than a fifth of its rows is still alive when they come at least this often
#: (a thermocouple logged every 10 s in a 1 Hz table) [s]
SPARSE_ALIVE_GAP_S = 60.0


def _check_values(y: np.ndarray, ok: np.ndarray, name: str, col: str, dur_s: float, t: np.ndarray) -> None:
    """Refuse infinite, dead, stuck and implausible columns."""
    if np.any(np.isinf(y)):
        raise InputError(f'{name}: column "{col}" row {int(np.flatnonzero(np.isinf(y))[0]) + 1}: infinite value')
    if not ok.any():
        raise InputError(
            f'{name}: column "{col}" has no valid value (a dead sensor); remove the column or fix the logging'
        )
    if ok.sum() < max(10, 0.2 * y.size) and not (ok.sum() >= 10 and _longest_nan_run(t, ok)[1] <= SPARSE_ALIVE_GAP_S):
        raise InputError(
            f'{name}: column "{col}" has only {int(ok.sum())} valid values of {y.size}, with gaps '
            f"longer than {SPARSE_ALIVE_GAP_S:.0f} s (a dead sensor); remove the column or fix the "
            f"logging"
        )
    yv = y[ok]
    if np.any((yv < -60) | (yv > 300)):  # before the stuck check: a span of 1e308 overflows to inf
        bad = yv[(yv < -60) | (yv > 300)][0]
        # a column in kelvin throughout said so, as the oil's degF is (a trial's thermocouple logged in K)
        kelvin = bool(np.all((yv - 273.15 >= -60) & (yv - 273.15 <= 300)) and np.median(yv) > 213.15)
        hint = "; it looks like kelvin: give degC (the values - 273.15)" if kelvin else ""
        raise InputError(
            f'{name}: column "{col}" holds {bad:.5g} degC, outside -60..300 degC (not a plausible temperature){hint}'
        )
    if np.ptp(yv) <= J1939_RES_C * 1.01 and dur_s > 60:
        raise InputError(
            f'{name}: column "{col}" stays at {yv[0]:.5g} degC for the whole {dur_s:.0f} s (a stuck '
            f"sensor); remove the column or the file"
        )


#: a measured part sits at most this far above the sump on the median of a run [K] (bearings and wheels run up to
#: ~40 K over it); a reading further off that lies within UNIT_FIT_K of the sump in degF or kelvin is in that unit
PART_OVER_OIL_K, UNIT_FIT_K = 80.0, 40.0
#: a cold run in degF sits only 0.8 T + 32 over the sump (50 K at 23 degC: under PART_OVER_OIL_K). It is told by its
#: start: a gearbox that starts cold-soaked (its oil less than SOAKED_K over the ambient; without the ambient column:
#: another thermocouple starting within START_FIT_K of the oil) has every part at the oil, so a channel that starts
#: within START_FIT_K of it read as degF, at least COLD_OVER_K over it in degC, and stays COLD_OVER_K over it in
#: 95 % of the run (an honest part under load starts at the oil, and a degF reading's excess never fades) is degF.
#: The means over the first START_S of the run are read [K, K, K, s]
SOAKED_K, START_FIT_K, COLD_OVER_K, START_S = 15.0, 3.0, 15.0, 5.0


class UnitInputs(NamedTuple):
    """What the unit check of a part's column reads beside it: the sump, and the ambient and the other
    thermocouples (None, or an array per row) that tell a cold-soaked start."""

    oil_c: np.ndarray
    ambient_c: np.ndarray | None
    others_c: tuple


def _start_mean(y: np.ndarray, t: np.ndarray) -> float:
    """The mean of the valid values within START_S of the run's first row (nan when there is none)."""
    sel = (t <= t[0] + START_S) & np.isfinite(y)
    return float(np.mean(y[sel])) if sel.any() else float("nan")


def _soaked_start(ref: UnitInputs, t: np.ndarray) -> str:
    """Why the run starts cold-soaked, every part at the oil ('' when nothing says so): its oil starts less than
    SOAKED_K over the ambient, or (without the ambient) another thermocouple starts within START_FIT_K of it."""
    oil0 = _start_mean(ref.oil_c, t)
    amb0 = _start_mean(ref.ambient_c, t) if ref.ambient_c is not None else float("nan")
    if np.isfinite(amb0):
        return f"the oil starts {oil0 - amb0:.0f} K from the ambient" if oil0 - amb0 < SOAKED_K else ""
    for o in ref.others_c:
        if abs(_start_mean(o, t) - oil0) <= START_FIT_K:
            return "another thermocouple starts at the oil"
    return ""


def _cold_degf(y: np.ndarray, ref: UnitInputs, t: np.ndarray, name: str, col: str) -> None:
    """InputError for a part's column in degF on a cold run (module note above SOAKED_K)."""
    oil0, y0 = _start_mean(ref.oil_c, t), _start_mean(y, t)
    if not (np.isfinite(oil0) and np.isfinite(y0)):
        return
    over0, off_f0 = y0 - oil0, (y0 - 32.0) / 1.8 - oil0
    if over0 < COLD_OVER_K or abs(off_f0) > START_FIT_K:
        return
    both = np.isfinite(y) & np.isfinite(ref.oil_c)
    low = float(np.percentile(y[both] - ref.oil_c[both], 5.0))
    if low < COLD_OVER_K:
        return
    why = _soaked_start(ref, t)
    if why:
        raise InputError(
            f'{name}: column "{col}" starts {over0:.0f} K above the oil (oil_temp_c) on a cold-soaked start ({why}: '
            f"every part at the oil) and stays {low:.0f} K or more over it in 95 % of the run; as degF it starts "
            f"{abs(off_f0):.1f} K from the oil: the column looks like degF, not degC; give degC: (degF - 32) / 1.8"
        )


def _check_unit_against_oil(y: np.ndarray, ref: UnitInputs, t: np.ndarray, name: str, col: str) -> None:
    """InputError for a measured part's column in degF or kelvin, told by the sump beside it (a part in degF passes
    the range check: 130 degC reads 266), or on a cold run by its start (:func:`_cold_degf`)."""
    oil_c = ref.oil_c
    both = np.isfinite(y) & np.isfinite(oil_c)
    if both.sum() < 10:
        return
    over = float(np.median(y[both] - oil_c[both]))
    if over <= PART_OVER_OIL_K:
        _cold_degf(y, ref, t, name, col)
        return
    for unit, to_c, fix in (("degF", (y - 32.0) / 1.8, "(degF - 32) / 1.8"), ("kelvin", y - 273.15, "K - 273.15")):
        if abs(float(np.median(to_c[both] - oil_c[both]))) <= UNIT_FIT_K:
            raise InputError(
                f'{name}: column "{col}" reads a median {over:.0f} K above the oil (oil_temp_c), where a part runs '
                f"at most {PART_OVER_OIL_K:.0f} K over it; as {unit} it sits beside the oil: the column looks like "
                f"{unit}, not degC; give degC: {fix}"
            )


def _unit_inputs(table: RunTable, col: str) -> UnitInputs:
    """The sump, the ambient and the other thermocouples beside the column ``col``."""

    def col_of(c):
        return np.asarray(table[c], dtype=float)

    others = tuple(col_of(c.column) for c in channel_columns(table).values() if c.column not in (col, "oil_temp_c"))
    return UnitInputs(col_of("oil_temp_c"), col_of("ambient_temp_c") if table.has("ambient_temp_c") else None, others)


def _valid_samples(table: RunTable, t: np.ndarray, name: str, col: str, opts: Options) -> ValidSamples:
    """The valid samples of a measured column; refuses dead, stuck, implausible and long-missing ones and warns
    about a sensor frozen for a long stretch."""
    dur = t[-1] - t[0]
    y = np.asarray(table[col], dtype=float)
    ok = np.isfinite(y)
    _check_values(y, ok, name, col, dur, t)
    if col != "oil_temp_c" and table.has("oil_temp_c"):
        _check_unit_against_oil(y, _unit_inputs(table, col), t, name, col)
    yv = y[ok]
    g0, glen = _longest_nan_run(t, ok)
    limit_s = max(opts.max_channel_gap_frac * dur, 300.0)
    if glen > limit_s:
        raise InputError(
            f'{name}: column "{col}" has no valid value for {glen:.0f} s from t = {g0:.10g} s '
            f"(more than {limit_s:.0f} s: a quarter of the run or 300 s, the longer); cut the file or "
            f"drop the column"
        )
    tv = t[ok]
    keep, warning = _frozen_stretches(table, t, tv, yv, dur, name, col)
    return ValidSamples(tv[keep], yv[keep], warning)


#: a measured value bit-identical for longer than this while the drive moves is a frozen sensor, not a temperature
#: [s] (the onboard sensor's oil_frozen time: firmware_model.onboard.input_check)
FROZEN_S = 300.0
#: ... the drive moves: engine speed [rpm] or torque [Nm] spans more than this over the stretch (a gearbox held at
#: one load reaches a steady state that a noise-free or quantised log holds bit for bit: no fault)
FROZEN_DRIVE_SPAN = {"engine_speed_rpm": 100.0, "engine_torque_nm": 300.0}
#: ... on a channel whose smallest step between distinct values is under this [K] (J1939: 1/32 K; a logger that
#: rounds to 1 K holds one value at a thermostat's equilibrium while the drive moves)
FINE_RESOLUTION_C = 0.25


def _drive_moves(table: RunTable, t: np.ndarray, t0_s: float, t1_s: float) -> bool:
    """Whether engine speed or torque spans more than FROZEN_DRIVE_SPAN between t0 and t1."""
    sel = (t >= t0_s) & (t <= t1_s)
    for col, span in FROZEN_DRIVE_SPAN.items():
        if table.has(col):
            x = np.asarray(table[col], dtype=float)[sel]
            x = x[np.isfinite(x)]
            if x.size and float(np.ptp(x)) > span:
                return True
    return False


def _frozen_stretches(
    table: RunTable, t: np.ndarray, tv: np.ndarray, yv: np.ndarray, dur_s: float, name: str, col: str
) -> tuple:
    """(samples kept, warning): a reading bit-identical for more than FROZEN_S while the drive moves, on a channel
    of fine resolution (steps under FINE_RESOLUTION_C), is a frozen sensor: its first sample is kept, the rest left
    out of the fit and said in the warning (fitted as data, a sensor stuck for 400 s in each file reads as a
    load-dependent heat-flow effect, below the 600 s warning threshold). Under a steady drive a constant reading is
    a steady state (a plant log held at equilibrium for 40 min), and a coarse channel (1 K steps) holds one value
    at a thermostat's equilibrium while the drive moves:
    kept, with only the warning of a stretch longer than max(600 s, 30 % of the run). InputError when less than
    half the run is left."""
    keep = np.ones(yv.size, dtype=bool)
    change = np.flatnonzero(np.diff(yv) != 0)
    if not change.size:
        return keep, ""
    bounds = np.concatenate([[0], change + 1, [yv.size]])
    first, last = bounds[:-1], bounds[1:] - 1
    lens = tv[last] - tv[first]
    fine = float(np.min(np.diff(np.unique(yv)))) < FINE_RESOLUTION_C
    frozen = np.array(
        [
            j
            for j in np.flatnonzero(lens > FROZEN_S)
            if fine and _drive_moves(table, t, float(tv[first[j]]), float(tv[last[j]]))
        ],
        dtype=np.int64,
    )
    if not frozen.size:
        j = int(np.argmax(lens))
        if lens[j] > max(600.0, 0.3 * dur_s):
            return keep, (
                f'column "{col}" is frozen at {yv[first[j]]:.5g} degC for {lens[j]:.0f} s from t = '
                f"{tv[first[j]]:.0f} s (kept: the drive was steady or the channel coarse)"
            )
        return keep, ""
    for j in frozen:
        keep[first[j] + 1 : last[j] + 1] = False
    total_s = float(lens[frozen].sum())
    if total_s > 0.5 * dur_s:
        raise InputError(
            f'{name}: column "{col}" is frozen (one value repeated for more than {FROZEN_S:.0f} s) for '
            f"{total_s:.0f} s of its {dur_s:.0f} s: a stuck sensor; remove the column or the file"
        )
    j = int(frozen[np.argmax(lens[frozen])])
    more = f" and {frozen.size - 1} more stretch(es), {total_s:.0f} s in all" if frozen.size > 1 else ""
    return keep, (
        f'column "{col}" is frozen at {yv[first[j]]:.5g} degC for {lens[j]:.0f} s from t = '
        f"{tv[first[j]]:.0f} s{more} (a stuck sensor: left out of the fit)"
    )


def grid_channel(cid: str, cols: ChannelColumns, s: ValidSamples, t_start_s: float, grid_dt_s: float) -> Channel:
    """A channel with its samples averaged onto the analysis grid (cells of grid_dt_s from t_start_s)."""
    k = np.floor((s.t_s - t_start_s) / grid_dt_s + 0.5).astype(np.int64)
    _uk, inv, cnt = np.unique(k, return_inverse=True, return_counts=True)
    return Channel(
        cid,
        cols.column,
        cols.model_column,
        s.t_s,
        s.y_c,
        cell_t_s=np.bincount(inv, s.t_s) / cnt,
        cell_y_c=np.bincount(inv, s.y_c) / cnt,
        cell_n=cnt.astype(float),
    )


def _initial_temp_c(table: RunTable, t: np.ndarray, channels: dict, oil_is_input: bool) -> float:
    """The oil (or the earliest measured channel) at the start: a straight line through its first 5 s read at the
    first sample (noise averaged out, a warm-up ramp not; a first-order sensor starts at the sump's value); the
    remaining error is a nuisance fitted per file (see scoring.Scorer.adjust)."""
    src = channels.get(OIL)
    src_t, src_y = (src.t_s, src.y_c) if src is not None else (None, None)
    if oil_is_input and table.has("oil_temp_c"):
        y = np.asarray(table["oil_temp_c"], dtype=float)
        ok = np.isfinite(y)
        src_t, src_y = (t[ok], y[ok]) if ok.any() else (None, None)
    if src_t is None:
        first = min(channels.values(), key=lambda c: c.t_s[0])
        src_t, src_y = first.t_s, first.y_c
    sel = src_t <= src_t[0] + 5.0
    if np.count_nonzero(sel) >= 3 and np.ptp(src_t[sel]) > 0:
        # a straight line through the first 5 s, read at the start: their mean would be the value 2.5 s in, which
        # on a loaded cold start (the oil rising 0.5 K/s) is a kelvin warm, more than the fitted nuisance allows
        slope, intercept = np.polyfit(src_t[sel] - src_t[0], src_y[sel], 1)
        return float(intercept)
    return float(np.mean(src_y[sel])) if sel.any() else float(src_y[0])


def _refuse_implausible(table: RunTable, t: np.ndarray, name: str, gearbox=None) -> None:
    """InputError for a file whose whole record is implausible (firmware_model.service.plausibility: oil in degF
    or kelvin, torque negated, in percent or in kN m): a fit to it would explain a unit mistake by a gearbox effect.
    ``gearbox``: a fixed-ratio drive's parameter set (its drive's limits judge the kN m rule)."""
    from firmware_model.service.plausibility import record_findings

    engine = (getattr(table, "meta", None) or {}).get("drive") != "fixed_ratio"
    limits = None
    if not engine and gearbox is not None and hasattr(gearbox, "variant"):
        from firmware_model.description import description_of
        from tools.replay.table import drive_limits

        limits = drive_limits(description_of(gearbox))
    found = record_findings(table, float(np.median(np.diff(t))), engine=engine, drive_limits=limits)
    if found:
        raise InputError(f"{name}: {found[0].sentence}")


def _gear_warning(table: RunTable, t: np.ndarray, gearbox=None) -> str:
    """The gear-numbering warning replay and fleet give (firmware_model.service.plausibility.gear_ratio_finding: a
    truck whose gears are not this gearbox's), '' without one: the diagnosis fits the losses of other gears (it said
    nothing of it on a real capture whose truck is no GRS905; a review)."""
    from firmware_model.description import description_of
    from firmware_model.parameters import load_parameters
    from firmware_model.service.plausibility import gear_ratio_finding
    from tools.replay.table import gear_meta

    if not all(table.has(c) for c in ("engine_speed_rpm", "vehicle_speed_kmh", "gear")) or t.size < 2:
        return ""
    meta = gear_meta(description_of(gearbox if gearbox is not None else load_parameters("GRS905")))
    if not meta.get("gear_ratios"):
        return ""
    found = gear_ratio_finding(
        table["engine_speed_rpm"],
        table["vehicle_speed_kmh"],
        table["gear"],
        meta["gear_ratios"],
        meta["gearbox"],
        float(np.median(np.diff(t))),
        "can" if (getattr(table, "meta", None) or {}).get("source") == "can" else "table",
    )
    return found.sentence if found is not None else ""


def prepare(table: RunTable, name: str, role: str, opts: Options, oil_is_input: bool = False, gearbox=None) -> Dataset:
    """Validate a measured run table and put its channels on the analysis grid; a measured component must be one
    ``gearbox`` (a parameter set or description; None: the default gearbox) publishes, or one of its housings.
    Raises InputError (one sentence)."""
    from tools.published import housings, ids

    validate_run_table(table, REQUIRED, name)
    t = np.asarray(table["time_s"], dtype=float)
    _check_time(t, name, opts, (getattr(table, "meta", None) or {}).get("drive") == "fixed_ratio")
    _refuse_implausible(table, t, name, gearbox)
    cols = channel_columns(table)
    if oil_is_input:
        cols.pop(OIL, None)
    if not cols:
        raise InputError(
            f"{name}: has no measured channel; the diagnosis needs oil_temp_c or a meas_T_<id>_c column "
            f"to compare with the model"
        )
    channels = {}
    warn = []
    known = ids(gearbox) + housings(gearbox)
    for cid, cc in cols.items():
        if cid not in (OIL, OIL_RIG) and cid not in known:
            raise InputError(
                f'{name}: column "{cc.column}" names component "{cid}", which is not a component id '
                f"(the gearbox's published components and housings: {', '.join(known)})"
            )
        s = _valid_samples(table, t, name, cc.column, opts)
        if s.warning:
            warn.append(s.warning)
        channels[cid] = grid_channel(cid, cc, s, float(t[0]), opts.grid_dt_s)
    gears = _gear_warning(table, t, gearbox)
    warn += [gears] if gears else []
    # every node starts there, and the model's oil data span -40..200 degC: said here, with the file's name (the
    # plant refused it later without one)
    T0 = check_temperature_c(
        f"{name}: the start (the first measured temperature, read off its first 5 s)",
        float(_initial_temp_c(table, t, channels, oil_is_input)),
    )
    inputs = RunTable(
        {c: table[c] for c in INPUT_COLUMNS if table.has(c)}
        | ({"oil_temp_c": table["oil_temp_c"]} if oil_is_input and table.has("oil_temp_c") else {})
        | {c: table[c] for c in table.columns if c.startswith("bc_")},
        meta={"initial_temp_c": T0},
    )
    return Dataset(name, role, inputs, channels, T0, float(t[0]), float(t[-1]), tuple(warn))
