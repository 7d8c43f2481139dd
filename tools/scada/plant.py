"""Planted effects in copies of real SCADA files: what a turbine's readings would have been had one of its gearbox's
effects changed from a date on (the fleet's detection test on real records; docs/real-data.md, "The fleet on
SCADA").

The planted rise of each measured channel is physical, the onboard model's own: the difference between its
estimates over the unit's record with the effect and without it, both with the oil modelled (the whole gearbox
moves: extra bearing heat also warms the oil a little, a weaker cooler warms the oil and the bearings on it). It
grows with the load as the effect's heat does. From the planted date on it is added to the channel's `_avg`, `_min`
and `_max` columns of each file row; before it nothing changes, and a file is otherwise copied as it is (every other
column, the empty cells, the rows the reader drops). The step at the date is immediate, not spread over the heat
paths' time constants (an hour or so): nothing at the scale of weeks.
"""

from __future__ import annotations

import csv
import gzip
import io
from pathlib import Path

import numpy as np

from tools.scada.diagnose import Setup
from tools.scada.reader import ScadaRecord, open_text, parse_time

#: the suffixes of a channel's columns that move with it (ENGIE: 10-minute mean, min, max; the std does not)
MOVED = ("_avg", "_min", "_max")


def planted_rise(setup: Setup, record: ScadaRecord, effect: str, value: float, from_s: float) -> dict:
    """{channel: the rise [K] of each record row}: the model's estimate with ``effect`` at ``value`` minus without
    it, the oil modelled, for the rows at or after ``from_s`` (UTC seconds); 0 before and where either is NaN."""
    from tools.scada.replay import replay_record

    def est(effects):
        t = replay_record(record, setup.config, {"oil_mode": "model"}, effects, setup.params).table
        return {ch: np.asarray(t[f"est_{ch}"], dtype=float) for ch in setup.channels}

    base, hot = est({}), est({effect: value})
    after = np.asarray(record.time_s, dtype=float) >= from_s
    return {ch: np.where(after & np.isfinite(hot[ch] - base[ch]), hot[ch] - base[ch], 0.0) for ch in setup.channels}


def write_planted(src: Path, dst: Path, record: ScadaRecord, rise: dict) -> int:
    """Copy the SCADA file ``src`` to ``dst`` (gzip when ``dst`` ends in .gz) with ``rise`` ({channel: per record
    row}, :func:`planted_rise`) added to the channel's columns of each row whose time stamp is a row of ``record``;
    the number of rows changed."""
    col = record.cmap.time_column
    kind = record.cmap.time_kind
    row_of = {int(round(t)): i for i, t in enumerate(np.asarray(record.time_s, dtype=float))}
    reader = csv.reader(open_text(Path(src)))
    header = next(reader)
    i_time = header.index(col)
    moved = []  # (file column index, channel, scale: the column's unit per K)
    for ch in rise:
        c = record.cmap.measured[ch]
        names = [c.column[: -len("_avg")] + s for s in MOVED] if c.column.endswith("_avg") else [c.column]
        moved += [(header.index(n), ch, c.scale) for n in names if n in header]
    out = io.StringIO(newline="")
    w = csv.writer(out, lineterminator="\n")
    w.writerow(header)
    changed = 0
    for cells in reader:
        t = parse_time(cells[i_time], kind) if len(cells) == len(header) else None
        k = row_of.get(int(round(t))) if t is not None else None
        if k is not None and any(rise[ch][k] for _, ch, _ in moved):
            for i, ch, scale in moved:
                if cells[i].strip():
                    try:
                        cells[i] = repr(float(cells[i]) + float(rise[ch][k]) / scale)
                    except ValueError:
                        pass  # a cell that is not a number stays as it is (the reader counts it)
            changed += 1
        w.writerow(cells)
    data = out.getvalue().encode()
    Path(dst).write_bytes(gzip.compress(data, compresslevel=1) if str(dst).endswith(".gz") else data)
    return changed
