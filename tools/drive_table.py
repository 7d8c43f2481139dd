"""Run tables of a fixed-ratio drive (docs/interfaces.md section 3.2, "A fixed-ratio drive"), mapped onto the inputs
the plant and the sensor read.

A gearbox whose description's drive is ``fixed_ratio`` (one gear, driven by a motor or a turbine) is given by
``time_s, input_speed_rpm, input_torque_nm, ambient_temp_c`` and optionally ``oil_temp_c``, at any row spacing (a
SCADA system's 10-minute averages included). :func:`map_fixed_ratio` maps them onto the vehicle inputs of the code
(input speed as the engine speed, input torque as the engine torque, the description's single gear as the gear);
the table's ``meta`` says ``drive = "fixed_ratio"`` and its row period, which the replay uses to hold each row over
its interval and to write one output row per input row (tools.replay.table.replay_held). A table that mixes vehicle and
fixed-ratio columns, or whose drive is not the gearbox's, is one sentence.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from firmware_model.errors import InputError

#: the names a fixed-ratio drive's tables give the inputs the code reads as an engine's (its run table, simulate's
#: output, replay's est.csv)
FIXED_RATIO_NAMES = {"engine_speed_rpm": "input_speed_rpm", "engine_torque_nm": "input_torque_nm"}
#: the columns of a fixed-ratio drive's run table that must be there, and the optional one
FIXED_RATIO_REQUIRED = ("time_s", "input_speed_rpm", "input_torque_nm", "ambient_temp_c")
FIXED_RATIO_OPTIONAL = ("oil_temp_c",)
#: the columns that say a table is of a fixed-ratio drive, and those that say it is of a vehicle
FIXED_RATIO_COLUMNS = ("input_speed_rpm", "input_torque_nm")
VEHICLE_COLUMNS = ("engine_speed_rpm", "engine_torque_nm", "gear", "vehicle_speed_kmh", "retarder_torque_nm")
#: a gap between rows longer than this many row periods (the median spacing) is a time jump, not a held interval
GAP_PERIODS = 2.0


def table_drive(columns, name: str) -> str:
    """``"fixed_ratio"`` when the columns are a fixed-ratio drive's, else ``"vehicle"``; InputError for a table
    that mixes both."""
    fixed = [c for c in columns if c in FIXED_RATIO_COLUMNS]
    vehicle = [c for c in columns if c in VEHICLE_COLUMNS]
    if fixed and vehicle:
        raise InputError(
            f"{name}: mixes a vehicle's columns ({', '.join(vehicle)}) with a fixed-ratio drive's "
            f"({', '.join(fixed)}); a run table is of one drive: give {', '.join(FIXED_RATIO_REQUIRED)} for a "
            f"fixed-ratio drive or time_s, engine_speed_rpm, engine_torque_nm, gear for a vehicle"
        )
    return "fixed_ratio" if fixed else "vehicle"


#: how a SCADA record's run table is named (tools.scada.runtable: "SCADA of <unit>"): its fix is a --gearbox
SCADA_SOURCE = "SCADA of "


def check_drive(columns, description, name: str) -> str:
    """The table's drive (:func:`table_drive`), which must be the gearbox's; InputError otherwise."""
    kind = table_drive(columns, name)
    gearbox_kind = "vehicle" if description is None else description.drive.kind
    gearbox = "the GRS905" if description is None else f"gearbox {description.name}"
    if kind == "fixed_ratio" and gearbox_kind != "fixed_ratio" and name.startswith(SCADA_SOURCE):
        raise InputError(
            f"{name}: a SCADA record is a fixed-ratio drive's (input speed and torque), but {gearbox} has a "
            f"{gearbox_kind} drive: give --gearbox a fixed-ratio description (MM82 for ENGIE's Senvion MM82 "
            "turbines, the engie map's; or your own file)"
        )
    if kind == "fixed_ratio" and gearbox_kind != "fixed_ratio":
        raise InputError(
            f"{name}: its columns {', '.join(c for c in columns if c in FIXED_RATIO_COLUMNS)} are a fixed-ratio "
            f"drive's, but {gearbox} has a {gearbox_kind} drive: give time_s, engine_speed_rpm, engine_torque_nm, "
            f"gear (or --gearbox a fixed-ratio description)"
        )
    if kind == "vehicle" and gearbox_kind == "fixed_ratio":
        raise InputError(
            f"{name}: {gearbox} has a fixed-ratio drive: give {', '.join(FIXED_RATIO_REQUIRED)} (and optionally "
            f"oil_temp_c), not a vehicle's engine_speed_rpm, engine_torque_nm, gear"
        )
    return kind


def fixed_ratio_gear(description) -> int:
    """The number of the single gear of a fixed-ratio description (neutral aside)."""
    (gear,) = [g.number for g in description.gears if g.number != 0]
    return int(gear)


def row_period_s(t_s: np.ndarray) -> float:
    """The table's row period: the median spacing of its rows [s] (0 for a single row)."""
    return float(np.median(np.diff(t_s))) if t_s.size > 1 else 0.0


def _check_values(table, name: str, strict: bool) -> None:
    """The rules of the run-table contract on a fixed-ratio drive's columns, named as the user wrote them: speed
    finite and >= 0, torque finite (``strict``: the plant's; the sensor takes bad values as data)."""
    if not strict:
        return
    from tools.runtable import row_namer

    for col, what in (("input_speed_rpm", "input speed"), ("input_torque_nm", "input torque")):
        v = np.asarray(table[col], dtype=float)
        bad = np.flatnonzero(~np.isfinite(v) | ((v < 0) if col == "input_speed_rpm" else False))
        if bad.size:
            r = int(bad[0])
            rule = "finite and >= 0" if col == "input_speed_rpm" else "a finite number"
            raise InputError(
                f'{name}: column "{col}" {row_namer(table)(r)}: {v[r]:.10g} is not a valid {what}; it must be {rule}'
            )


def map_fixed_ratio(table, description, name: str | None = None, strict: bool = True):
    """A fixed-ratio drive's run table mapped onto the inputs of the code: ``engine_speed_rpm`` = input speed,
    ``engine_torque_nm`` = input torque, ``gear`` = the description's single gear, ``ambient_temp_c`` and
    ``oil_temp_c`` as given, ``vehicle_speed_kmh`` and ``retarder_torque_nm`` 0 (it stands still); ``meta``:
    ``drive`` = ``"fixed_ratio"`` and ``row_period_s`` (the median spacing). A pure function: the table is not
    changed. InputError for a missing column or a bad value (``strict``)."""
    from tools.runtable import RunTable

    name = name or getattr(table, "source", None) or "run table"
    check_drive(table.columns, description, name)
    missing = [c for c in FIXED_RATIO_REQUIRED if not table.has(c)]
    if missing:
        raise InputError(
            f'{name}: required column "{missing[0]}" of a fixed-ratio drive is missing; the columns are '
            f"{', '.join(table.columns)}"
        )
    _check_values(table, name, strict)
    t_s = np.asarray(table["time_s"], dtype=float)
    cols = {
        "time_s": t_s,
        "engine_speed_rpm": np.asarray(table["input_speed_rpm"], dtype=float),
        "engine_torque_nm": np.asarray(table["input_torque_nm"], dtype=float),
        "gear": np.full(t_s.size, float(fixed_ratio_gear(description))),
        "ambient_temp_c": np.asarray(table["ambient_temp_c"], dtype=float),
        # a fixed-ratio drive stands still: no headwind on the housing (not the plant's 50 km/h default), no retarder
        "vehicle_speed_kmh": np.zeros(t_s.size),
        "retarder_torque_nm": np.zeros(t_s.size),
    }
    cols.update({c: np.asarray(table[c], dtype=float) for c in FIXED_RATIO_OPTIONAL if table.has(c)})
    meta = {**(getattr(table, "meta", {}) or {}), "drive": "fixed_ratio"}
    # the period the table's maker knows (a SCADA record's column map: a one-row record has one), else the spacing
    meta["row_period_s"] = meta.get("row_period_s") or row_period_s(t_s)
    return RunTable(cols, meta=meta, source=getattr(table, "source", None))


def as_fixed_ratio_output(table):
    """A plant output table of a fixed-ratio drive with its inputs named as a fixed-ratio run table names them
    (``input_speed_rpm``, ``input_torque_nm``; the single gear, the zero vehicle speed and retarder torque left
    out), so that `simulate`'s output is a `replay` input as it is for a vehicle. The other columns as they are."""
    from tools.runtable import RunTable

    drop = {"gear", "vehicle_speed_kmh", "retarder_torque_nm"}
    cols = {FIXED_RATIO_NAMES.get(c, c): table[c] for c in table.columns if c not in drop}
    return RunTable(cols, meta=dict(getattr(table, "meta", {}) or {}), source=getattr(table, "source", None))


def read_drive_table(path: str | os.PathLike, description=None):
    """A run table (CSV) read for the plant: a vehicle's as before (tools.runtable.read_run_table), a fixed-ratio
    drive's mapped (:func:`map_fixed_ratio`) and checked as the contract checks a vehicle's. ``description``: the
    gearbox's (None: the GRS905, a vehicle)."""
    from tools import runtable as rt

    name = os.fspath(path)
    if check_drive(rt.read_header(Path(path), name), description, name) == "vehicle":
        return rt.read_run_table(path)
    table = rt.read_run_table(path, required=("time_s",))
    return rt.validate_run_table(map_fixed_ratio(table, description, name), name=name)


def held_plan(t_s: np.ndarray, dt_s: float, period_s: float | None = None, nearest: bool = False):
    """How a table slower than the step is stepped: each row holds its values over its interval (zero-order hold
    of the interval's mean, as a SCADA average stands for the interval that begins at its time stamp), up to the
    next row, or one row period for the last row and before a gap longer than GAP_PERIODS periods (a time jump).
    Returns ``(steps per row (N,) int, the end of each row's interval (N,) [s])``; every row has at least one step.
    ``nearest``: each row the nearest whole number of steps instead of the whole steps that fit (a coarse step: a
    row a few seconds off the period then ends at most dt/2 early or late, never a time jump or a step back)."""
    t_s = np.asarray(t_s, dtype=float)
    period_s = row_period_s(t_s) if period_s is None else period_s
    period_s = period_s if period_s > 0 else dt_s
    span_s = np.diff(t_s, append=t_s[-1] + period_s)
    span_s = np.where(span_s > GAP_PERIODS * period_s, period_s, span_s)
    n = np.maximum(1, np.floor(span_s / dt_s + (0.5 if nearest else 1e-9)).astype(np.int64))
    return n, t_s + n * dt_s
