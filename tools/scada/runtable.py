"""A SCADA record as the run table of a fixed-ratio drive (docs/real-data.md, "From a record to a run table").

The plant and the sensor read a fixed-ratio drive's run table (``time_s, input_speed_rpm, input_torque_nm,
ambient_temp_c`` and optionally ``oil_temp_c``; tools.drive_table); :func:`run_table_of` writes a record's inputs
and, when asked, its measured sump in those columns, one row per SCADA row. A SCADA row is the average over the
interval that ENDS at its time stamp, and the replay holds each row over the interval that BEGINS at its time: the
rows are therefore stamped at the start of their interval (time stamp - period). A rejected value stays NaN (the
sensor counts it as bad input and holds the last good one); a gap between stretches stays a gap in ``time_s`` (a
time jump for the sensor). ``time_s`` counts from the record's first interval; ``meta`` keeps the UTC time of that
origin (``t0_utc_s``), the unit and the stretch of every row.
"""

from __future__ import annotations

import numpy as np

from tools.drive_table import SCADA_SOURCE
from tools.runtable import RunTable
from tools.scada.reader import ScadaRecord

#: the run table's inputs, each from the column map's input of the same name
INPUTS = ("input_speed_rpm", "input_torque_nm", "ambient_temp_c")


def oil_channel(record: ScadaRecord) -> str | None:
    """The measured channel tied to the sump (node ``oil``), or None when the map has none."""
    for name, node in record.cmap.nodes.items():
        if node == "oil":
            return name
    return None


def run_table_of(record: ScadaRecord, with_oil: bool = True) -> RunTable:
    """The record as a fixed-ratio drive's run table: the map's inputs, and ``oil_temp_c`` from the channel tied to
    the sump when ``with_oil`` (and the map has one); stamped at the start of each row's interval."""
    period_s = float(record.cmap.period_s)
    if record.n == 0:
        raise ValueError(f"unit {record.unit}: the record has no rows")
    t0_s = float(record.time_s[0]) - period_s
    cols = {"time_s": np.asarray(record.time_s, dtype=float) - period_s - t0_s}
    for name in INPUTS:
        cols[name] = np.asarray(record.values[name], dtype=float)
    oil = oil_channel(record) if with_oil else None
    if oil is not None:
        cols["oil_temp_c"] = np.asarray(record.values[oil], dtype=float)
    meta = {"drive": "fixed_ratio", "unit": record.unit, "t0_utc_s": t0_s, "row_period_s": period_s}
    table = RunTable(cols, meta=meta, source=f"{SCADA_SOURCE}{record.unit}")
    table.meta["stretch"] = np.asarray(record.stretch).copy()
    return table
